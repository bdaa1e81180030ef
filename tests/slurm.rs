//! A real cluster in the test suite: `scripts/slurm-local` starts Debian's munge, slurmctld and
//! slurmd on this machine, `nlstudy submit` packs a study into jobs that `sbatch` queues, the jobs
//! run `nlstudy run --only …` (an MPI case through `srun --mpi=pmix`) into the record store, and
//! `nlstudy collect` builds the tables. A job past its time limit is killed by Slurm; its
//! unfinished point stays missing and the next `submit` packs only that point.
//!
//! One test, one Slurm: the daemons listen on fixed ports. It is skipped, saying so, only where
//! the packages cannot be installed.

use nonlocal_study::{planned_keys, records, stored_keys, text, Scratch};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scripts")
        .join(name)
}

/// The local Slurm, stopped when dropped, also when the test fails.
struct LocalSlurm {
    dir: PathBuf,
}

impl LocalSlurm {
    fn conf(&self) -> PathBuf {
        self.dir.join("slurm.conf")
    }

    /// A Slurm command (`squeue`, …) against this cluster.
    fn command(&self, program: &str) -> Command {
        let mut command = Command::new(program);
        command.env("SLURM_CONF", self.conf());
        command
    }

    /// Waits until no job is queued or running.
    fn wait_for_jobs(&self, limit: Duration) {
        let started = Instant::now();
        loop {
            let out = self
                .command("squeue")
                .args(["-h", "-o", "%i %T"])
                .output()
                .unwrap();
            let queue = String::from_utf8_lossy(&out.stdout).trim().to_string();
            if out.status.success() && queue.is_empty() {
                return;
            }
            assert!(
                started.elapsed() < limit,
                "jobs still queued after {limit:?}: {queue}"
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }
}

impl Drop for LocalSlurm {
    fn drop(&mut self) {
        let _ = Command::new(script("slurm-local"))
            .arg("stop")
            .arg(&self.dir)
            .status();
    }
}

/// `nlstudy <verb> …` against the local Slurm.
fn nlstudy(scratch: &Scratch, slurm: &LocalSlurm, verb: &str, extra: &[&str]) -> Output {
    scratch
        .command(verb, extra)
        .env("SLURM_CONF", slurm.conf())
        .output()
        .unwrap()
}

/// `nlstudy submit --scheduler slurm …` against the local Slurm.
fn submit(scratch: &Scratch, slurm: &LocalSlurm, extra: &[&str]) -> Output {
    let mut args = vec!["--scheduler", "slurm"];
    args.extend(extra);
    nlstudy(scratch, slurm, "submit", &args)
}

#[test]
fn studies_submitted_to_a_local_slurm_run_store_and_collect() {
    let setup = Command::new(script("setup.sh"))
        .arg("--slurm")
        .output()
        .unwrap();
    if !setup.status.success() {
        eprintln!(
            "skipped: Debian's Slurm packages cannot be installed here ({})",
            text(&setup).trim()
        );
        return;
    }
    let dir = std::env::temp_dir().join(format!("nlstudy-slurm-test-{}", std::process::id()));
    let slurm = LocalSlurm { dir: dir.clone() };
    let started = Command::new(script("slurm-local"))
        .arg("start")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        started.status.success(),
        "slurm-local start: {}",
        text(&started)
    );

    // Four points in two jobs; the second job holds a 2-rank case, launched by srun.
    let study = json!({
        "name": "cluster",
        "base": {"m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"zip": {"dim": [1, 1, 1, 2], "n": [16, 32, 64, 64], "ranks": [1, 1, 1, 2]}}]
    });
    let scratch = Scratch::new("slurm", &study);
    let out = submit(
        &scratch,
        &slurm,
        &["--cases-per-job", "2", "--time", "00:05:00"],
    );
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(
        text(&out).matches("submitted as job ").count(),
        2,
        "{}",
        text(&out)
    );
    slurm.wait_for_jobs(Duration::from_secs(300));
    let stored = records(&scratch.runs("cluster"));
    let logs = || {
        let jobs = scratch.dir.join("results/cluster/jobs");
        std::fs::read_dir(&jobs)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| e.path().extension().is_some_and(|x| x == "out"))
            .map(|e| std::fs::read_to_string(e.path()).unwrap_or_default())
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(stored.len(), 4, "job output: {}", logs());
    assert!(stored.iter().all(|r| r["status"] == "ok"), "{stored:?}");
    assert_eq!(
        stored_keys(&stored),
        planned_keys(&scratch),
        "the study's points"
    );
    assert!(
        stored.iter().any(|r| r["ranks"] == 2),
        "the MPI case ran on 2 ranks"
    );
    let collected = scratch.nlstudy("collect", &[]);
    assert!(collected.status.success(), "{}", text(&collected));
    assert!(scratch.dir.join("results/cluster/cluster.parquet").exists());
    let again = submit(&scratch, &slurm, &["--dry-run"]);
    assert!(
        text(&again).contains("nothing to submit"),
        "{}",
        text(&again)
    );

    // A job past its one-minute limit: its quick points are stored, the slow one (about
    // 10 000 steps at n = 1024) is killed and left missing, and only it is packed again.
    let study = json!({
        "name": "limit",
        "base": {"m": 2, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"zip": {
            "dim": [1, 1, 2],
            "n": [16, 32, 1024],
            "m": [2, 2, 8],
            "t_end": [0.001, 0.001, 1e-4],
            "cfl": [0.5, 0.5, null],
            "dt": [null, null, 1e-8]
        }}]
    });
    scratch.write_study(&study);
    let out = submit(&scratch, &slurm, &["--time", "00:01:00"]);
    assert!(out.status.success(), "{}", text(&out));
    // While the slow point runs: the job is running, and a second submit packs nothing.
    let waiting = Instant::now();
    while records(&scratch.runs("limit")).len() < 2 {
        assert!(
            waiting.elapsed() < Duration::from_secs(60),
            "the quick points never ran: {}",
            logs()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let status = |scratch: &Scratch| text(&nlstudy(scratch, &slurm, "status", &[]));
    let running = status(&scratch);
    assert!(
        running.contains("nlstudy-limit-0: running, 2 of 3 points stored"),
        "{running}"
    );
    let twice = submit(&scratch, &slurm, &["--time", "00:01:00"]);
    assert!(twice.status.success(), "{}", text(&twice));
    assert!(
        text(&twice).contains("1 points are in jobs still queued or running")
            && text(&twice).contains("nothing to submit"),
        "{}",
        text(&twice)
    );
    slurm.wait_for_jobs(Duration::from_secs(300));
    let ended = status(&scratch);
    assert!(
        ended.contains("nlstudy-limit-0: ended, 2 of 3 points stored")
            && ended.contains("1 of 3 points to run"),
        "{ended}"
    );
    let runs = scratch.runs("limit");
    let stored = records(&runs);
    assert_eq!(
        stored.len(),
        2,
        "the two quick points: {stored:?}\n{}",
        logs()
    );
    let stray: Vec<String> = std::fs::read_dir(&runs)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| name != ".work" && !name.ends_with(".json"))
        .collect();
    assert!(stray.is_empty(), "half-written files: {stray:?}");
    let again = submit(&scratch, &slurm, &["--dry-run"]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        text(&again).contains("nlstudy-limit-0 (1 cases, "),
        "{}",
        text(&again)
    );
}
