//! Faults and concurrency, as processes: two `nlstudy run` of one study at once, `nlstudy run` and
//! `collect` killed (SIGKILL) at random moments and resumed, records that are not whole, and an
//! MPI rank killed mid-run. docs/reliability.md lists what each shows.

use nonlocal_study::{records, text, Scratch};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant, SystemTime};

/// A study of `n` short 2D points (tens of milliseconds each).
fn short_study(name: &str, sizes: &[u64]) -> Value {
    json!({
        "name": name,
        "base": {"dim": 2, "m": 2, "t_end": 0.002, "cfl": 0.5},
        "sweep": [{"product": {"n": sizes, "threads": [1, 2]}}]
    })
}

/// "N ran" of a run's closing line.
fn ran(stderr: &str) -> usize {
    let line = stderr
        .lines()
        .rev()
        .find(|l| l.contains(" ran ("))
        .unwrap_or_else(|| panic!("no closing line in {stderr}"));
    line.split(": ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count in {line}"))
}

/// Every file under `dir`, recursively.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            files.extend(files_under(&path));
        } else {
            files.push(path);
        }
    }
    files
}

/// The store holds one whole `ok` record per point and nothing half-written: no partial file, no
/// scratch file of a run (only the keys' lock files), and the Parquet tables, where present,
/// whole (a Parquet file starts and ends with `PAR1`).
fn assert_whole(scratch: &Scratch, study: &str, points: usize, context: &str) {
    let stored = records(&scratch.runs(study));
    assert_eq!(stored.len(), points, "{context}: one record per point");
    let mut keys: Vec<&str> = stored.iter().map(|r| r["key"].as_str().unwrap()).collect();
    keys.sort();
    keys.dedup();
    assert_eq!(keys.len(), points, "{context}: every key once");
    assert!(
        stored.iter().all(|r| r["status"] == "ok"),
        "{context}: {stored:?}"
    );
    for file in files_under(&scratch.dir.join("results")) {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            !name.ends_with(".partial"),
            "{context}: partial file {}",
            file.display()
        );
        if file.parent().is_some_and(|p| p.ends_with(".work")) {
            assert!(
                name.ends_with(".lock"),
                "{context}: scratch left behind: {}",
                file.display()
            );
        }
        if name.ends_with(".parquet") {
            let bytes = std::fs::read(&file).unwrap();
            assert!(
                bytes.len() >= 8 && bytes.starts_with(b"PAR1") && bytes.ends_with(b"PAR1"),
                "{context}: {} is not a whole Parquet file",
                file.display()
            );
        }
    }
}

/// The solver processes started for this scratch directory that are still alive.
fn solvers_of(scratch: &Scratch) -> Vec<u32> {
    let marker = scratch.dir.to_string_lossy().into_owned();
    let mut pids = Vec::new();
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmdline
            .split(|b| *b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let is_solver = args.first().is_some_and(|a| a.ends_with("/nlsolve"));
        let zombie = std::fs::read_to_string(entry.path().join("stat")).is_ok_and(|s| {
            s.rsplit(')')
                .next()
                .is_some_and(|r| r.trim_start().starts_with('Z'))
        });
        if is_solver && !zombie && args.iter().any(|a| a.contains(&marker)) {
            pids.push(pid);
        }
    }
    pids
}

/// Waits (polling, up to `limit`) until `done` holds; false when it never did.
fn eventually(limit: Duration, mut done: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + limit;
    while Instant::now() < deadline {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    done()
}

fn kill_9(child: &mut Child) {
    Command::new("kill")
        .args(["-9", &child.id().to_string()])
        .status()
        .unwrap();
    child.wait().unwrap();
}

/// A small xorshift generator; the seed is printed so that a failure can be replayed.
struct Random(u64);

impl Random {
    fn new() -> Random {
        let seed = std::env::var("RELIABILITY_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| {
                SystemTime::now()
                    .duration_since(SystemTime::UNIX_EPOCH)
                    .unwrap()
                    .as_nanos() as u64
                    | 1
            });
        eprintln!("reliability: RELIABILITY_SEED={seed}");
        Random(seed)
    }

    fn below(&mut self, bound: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % bound
    }
}

#[test]
fn two_runs_of_one_study_at_once_run_each_point_once_and_store_every_record_ok() {
    let sizes = [32, 40, 48, 56, 64, 72, 80, 88];
    let scratch = Scratch::new("concurrent", &short_study("concurrent", &sizes));
    let first = scratch.spawn("run", &["--no-collect"]);
    let second = scratch.spawn("run", &["--no-collect"]);
    let (first, second) = (
        first.wait_with_output().unwrap(),
        second.wait_with_output().unwrap(),
    );
    for out in [&first, &second] {
        assert!(out.status.success(), "{}", text(out));
    }
    let (a, b) = (
        String::from_utf8_lossy(&first.stderr),
        String::from_utf8_lossy(&second.stderr),
    );
    let points = 2 * sizes.len();
    assert_eq!(ran(&a) + ran(&b), points, "each point ran once:\n{a}\n{b}");
    assert_whole(&scratch, "concurrent", points, "two runs at once");
    let status = text(&scratch.nlstudy("status", &[]));
    assert!(
        status.contains(&format!("{points} records")) && status.contains(&format!("{points} ok")),
        "{status}"
    );
}

#[test]
fn runs_and_collects_killed_at_random_moments_resume_with_every_record_once_and_whole() {
    let sizes = [32, 48, 64, 80, 96, 112];
    let scratch = Scratch::new("killed", &short_study("killed", &sizes));
    let points = 2 * sizes.len();
    let mut random = Random::new();
    let mut delays = Vec::new();
    for trial in 0..10 {
        let mut run = scratch.spawn("run", &[]);
        let delay = random.below(800);
        delays.push(delay);
        std::thread::sleep(Duration::from_millis(delay));
        kill_9(&mut run);
        assert!(
            eventually(Duration::from_secs(10), || solvers_of(&scratch).is_empty()),
            "trial {trial}: solver processes outlived the killed nlstudy: {:?}",
            solvers_of(&scratch)
        );
        let stored = records(&scratch.runs("killed"));
        assert!(
            stored.iter().all(|r| r["status"] == "ok"),
            "trial {trial}: {stored:?}"
        );
    }
    let resumed = scratch.nlstudy("run", &["--no-collect"]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    assert_whole(
        &scratch,
        "killed",
        points,
        &format!("runs killed after {delays:?} ms"),
    );
    // Collect killed midway: the tables are the old ones or whole new ones, never torn.
    let collected = scratch.nlstudy("collect", &[]);
    assert!(collected.status.success(), "{}", text(&collected));
    for _ in 0..5 {
        let mut collect = scratch.spawn("collect", &[]);
        let delay = random.below(400);
        delays.push(delay);
        std::thread::sleep(Duration::from_millis(delay));
        kill_9(&mut collect);
        let runs = scratch.dir.join("results/killed");
        for table in ["killed.parquet", "killed-summary.parquet"] {
            let bytes = std::fs::read(runs.join(table)).unwrap();
            assert!(
                bytes.starts_with(b"PAR1") && bytes.ends_with(b"PAR1"),
                "{table} torn after {delays:?}"
            );
        }
    }
    let again = scratch.nlstudy("run", &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        text(&again).contains(&format!(
            "0 ran (0 ok, 0 diverged, 0 failed), {points} already stored"
        )),
        "{}",
        text(&again)
    );
    assert_whole(
        &scratch,
        "killed",
        points,
        &format!("collects killed after {delays:?} ms"),
    );
}

#[test]
fn records_that_are_not_whole_are_reported_and_their_points_run_again() {
    let scratch = Scratch::new("corrupt", &short_study("corrupt", &[32, 40]));
    let first = scratch.nlstudy("run", &["--no-collect"]);
    assert!(first.status.success(), "{}", text(&first));
    let runs = scratch.runs("corrupt");
    let mut paths: Vec<PathBuf> = files_under(&runs)
        .into_iter()
        .filter(|p| {
            p.extension().is_some_and(|x| x == "json") && !p.to_string_lossy().contains(".work")
        })
        .collect();
    paths.sort();
    assert_eq!(paths.len(), 4);
    let whole = std::fs::read_to_string(&paths[0]).unwrap();
    std::fs::write(&paths[0], &whole[..whole.len() / 2]).unwrap(); // truncated
    std::fs::write(&paths[1], "\u{0}\u{7}garbage").unwrap();
    let stray = runs.join("notes.json");
    std::fs::write(&stray, "{\"mine\": true}").unwrap();
    for verb in ["status", "plan"] {
        let out = text(&scratch.nlstudy(verb, &[]));
        for path in [&paths[0], &paths[1], &stray] {
            assert!(
                out.contains(&path.display().to_string()),
                "{verb} does not name {}:\n{out}",
                path.display()
            );
        }
    }
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(plan.contains("2 to run, 2 stored"), "{plan}");
    let rerun = scratch.nlstudy("run", &[]);
    assert!(rerun.status.success(), "{}", text(&rerun));
    assert!(text(&rerun).contains("2 ran (2 ok"), "{}", text(&rerun));
    assert!(
        stray.exists(),
        "a file that is not a record is the user's: reported, never removed"
    );
    std::fs::remove_file(&stray).unwrap();
    assert_whole(&scratch, "corrupt", 4, "after the rerun");
}

#[test]
fn a_rank_killed_mid_run_ends_the_job_and_its_point_is_stored_failed() {
    let study = json!({
        "name": "rank",
        "base": {"dim": 2, "n": 512, "m": 4, "t_end": 0.05, "cfl": 0.5, "ranks": 2}
    });
    let scratch = Scratch::new("rank", &study);
    let run = scratch.spawn("run", &["--no-collect"]);
    assert!(
        eventually(Duration::from_secs(60), || solvers_of(&scratch).len() == 2),
        "the two ranks never started"
    );
    let killed = Instant::now();
    let rank = solvers_of(&scratch)[0];
    Command::new("kill")
        .args(["-9", &rank.to_string()])
        .status()
        .unwrap();
    assert!(
        eventually(Duration::from_secs(60), || solvers_of(&scratch).is_empty()),
        "the other rank was left running"
    );
    let out = run.wait_with_output().unwrap();
    eprintln!(
        "the job ended {:?} after the rank was killed",
        killed.elapsed()
    );
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let stored = records(&scratch.runs("rank"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "failed");
    let message = stored[0]["message"].as_str().unwrap();
    // Usually mpirun reaps the dead rank and exits non-zero; now and then Open MPI 4.1 hangs
    // instead, and the pool's watchdog ends it.
    assert!(
        message.contains("nlsolve exited with") || message.contains("MPI launcher had not ended"),
        "{message}"
    );
}

/// The pool's answer to that hang, made certain: a launcher that starts a "rank" which exits at
/// once and is never reaped, then waits forever, as Open MPI 4.1's mpirun sometimes does.
#[test]
fn a_launcher_that_leaves_a_dead_rank_unreaped_is_killed_and_its_point_stored_failed() {
    let study = json!({
        "name": "hang",
        "base": {"dim": 2, "n": 64, "m": 2, "t_end": 0.001, "cfl": 0.5, "ranks": 2}
    });
    let scratch = Scratch::new("hung-launcher", &study);
    // The subshell exits at once; `exec` keeps the pid, and sleep never waits for children.
    let launcher = launcher_script(&scratch, "hanging-launcher", "(exit 1) &\nexec sleep 600\n");
    let started = Instant::now();
    let out = scratch.nlstudy("run", &["--no-collect", "--launcher", &launcher]);
    eprintln!("the hung launcher was ended after {:?}", started.elapsed());
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let stored = records(&scratch.runs("hang"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "failed");
    let message = stored[0]["message"].as_str().unwrap();
    assert!(
        message.contains("a rank exited and the MPI launcher had not ended"),
        "{message}"
    );
}

#[test]
fn a_case_past_its_timeout_is_killed_and_stored_failed() {
    let study = json!({
        "name": "slow",
        "timeout_s": 1,
        "base": {"dim": 2, "n": 512, "m": 4, "t_end": 0.05, "cfl": 0.5}
    });
    let scratch = Scratch::new("timeout", &study);
    let out = scratch.nlstudy("run", &["--no-collect"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let stored = records(&scratch.runs("slow"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "failed");
    assert!(
        stored[0]["message"]
            .as_str()
            .unwrap()
            .starts_with("timed out after"),
        "{}",
        stored[0]
    );
    assert!(
        solvers_of(&scratch).is_empty(),
        "the timed-out solver still runs"
    );
}

/// `--retries`: a case whose process was killed from outside runs again and its record keeps the
/// attempt; a case past its timeout is tried once more and then stored failed; a diverged case is
/// a result and never runs again.
#[test]
fn failures_outside_the_case_are_retried_and_results_are_not() {
    let study = json!({
        "name": "retry",
        "base": {"dim": 2, "n": 32, "m": 2, "t_end": 0.001, "cfl": 0.5, "ranks": 2}
    });
    let scratch = Scratch::new("retries", &study);
    // A launcher whose first start is killed (as by an out-of-memory killer or a node failure).
    let launcher = launcher_script(
        &scratch,
        "flaky-launcher",
        "marker=\"$(dirname \"$0\")/killed-once\"\n\
         if [ ! -e \"$marker\" ]; then touch \"$marker\"; kill -9 $$; fi\n\
         exec mpirun --oversubscribe \"$@\"\n",
    );
    let out = scratch.nlstudy(
        "run",
        &["--no-collect", "--launcher", &launcher, "--retries", "1"],
    );
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("(attempt 2)"), "{}", text(&out));
    let stored = records(&scratch.runs("retry"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "ok");
    assert_eq!(stored[0]["attempt"], 2);

    scratch.write_study(&json!({
        "name": "slow",
        "timeout_s": 1,
        "base": {"dim": 2, "n": 512, "m": 4, "t_end": 0.05, "cfl": 0.5}
    }));
    let out = scratch.nlstudy("run", &["--no-collect", "--retries", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    assert_eq!(text(&out).matches("retrying").count(), 1, "{}", text(&out));
    let stored = records(&scratch.runs("slow"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "failed");
    assert_eq!(stored[0]["attempt"], 2);

    scratch.write_study(&json!({
        "name": "unstable",
        "base": {"dim": 1, "n": 64, "m": 2, "t_end": 0.05, "cfl": 1.5, "allow_unstable": true}
    }));
    let out = scratch.nlstudy("run", &["--no-collect", "--retries", "3"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(!text(&out).contains("retrying"), "{}", text(&out));
    let stored = records(&scratch.runs("unstable"));
    assert_eq!(stored[0]["status"], "diverged");
    assert_eq!(stored[0]["attempt"], 1);
}

/// An executable shell script in the scratch directory, to stand in for an MPI launcher that
/// misbehaves the way a real one can; returns the launcher line that starts it.
fn launcher_script(scratch: &Scratch, name: &str, body: &str) -> String {
    use std::os::unix::fs::PermissionsExt;
    let path = scratch.dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    // Launchers say where the rank count goes; these take it as mpirun does.
    format!("'{}' -n {{ranks}}", path.display())
}
