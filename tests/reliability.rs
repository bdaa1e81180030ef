//! Faults and concurrency, as processes: two `nlstudy run` of one study at once, `nlstudy run` and
//! `collect` killed (SIGKILL) at random moments and resumed, records that are not whole, and an
//! MPI rank killed mid-run. docs/reliability.md lists what each shows.

use nonlocal_study::{
    frames, numbers_of, planned_keys, records, segment_files, stored_keys, text, Scratch,
};
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
    assert_eq!(
        stored_keys(&stored),
        planned_keys(scratch),
        "{context}: a record of every point of the study"
    );
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

/// The solver processes (and workers) started for this scratch directory that are still alive.
fn solvers_of(scratch: &Scratch) -> Vec<u32> {
    let marker = scratch.dir.to_string_lossy().into_owned();
    let mut pids = Vec::new();
    for (pid, _, state) in nonlocal_study::processes() {
        let Ok(cmdline) = std::fs::read(format!("/proc/{pid}/cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmdline
            .split(|b| *b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let is_solver = args.first().is_some_and(|a| a.ends_with("/nlsolve"));
        // A process of its own names its case file; a worker runs in the store's work directory.
        let ours = args.iter().any(|a| a.contains(&marker))
            || std::fs::read_link(format!("/proc/{pid}/cwd"))
                .is_ok_and(|cwd| cwd.starts_with(&scratch.dir));
        if is_solver && state != 'Z' && ours {
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

/// A seeded generator; the seed is printed so that a failure can be replayed.
fn random() -> fastrand::Rng {
    let seed = std::env::var("RELIABILITY_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .unwrap()
                .as_nanos() as u64
        });
    eprintln!("reliability: RELIABILITY_SEED={seed}");
    fastrand::Rng::with_seed(seed)
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
    let mut random = random();
    let mut delays = Vec::new();
    for trial in 0..10 {
        let mut run = scratch.spawn("run", &[]);
        let delay = random.u64(..800);
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
        let delay = random.u64(..400);
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
    // Whatever the killed collects left (tables of one, what another said it made), the tables
    // `run` stands by or splices are those a collect from scratch makes.
    let study = scratch.dir.join("results/killed");
    let tables = || {
        ["killed.parquet", "killed-summary.parquet"].map(|t| std::fs::read(study.join(t)).unwrap())
    };
    let kept = tables();
    std::fs::remove_file(study.join(".collected.json")).unwrap();
    let afresh = scratch.nlstudy("collect", &[]);
    assert!(afresh.status.success(), "{}", text(&afresh));
    assert!(kept == tables(), "collects killed after {delays:?} ms");
}

#[test]
fn records_that_are_not_whole_are_reported_and_their_points_run_again() {
    let scratch = Scratch::new("corrupt", &short_study("corrupt", &[32, 40]));
    let first = scratch.nlstudy("run", &["--no-collect"]);
    assert!(first.status.success(), "{}", text(&first));
    let runs = scratch.runs("corrupt");
    let segments = segment_files(&runs);
    assert_eq!(segments.len(), 1, "one run, one segment: {segments:?}");
    let segment = &segments[0];
    let mut bytes = std::fs::read(segment).unwrap();
    assert_eq!(frames(&bytes).len(), 4);
    // A byte of the second record flipped (a bad disk block), and a record of the older
    // layout cut short, and a file that is no record at all.
    let second = bytes
        .windows(9)
        .enumerate()
        .filter(|(_, w)| *w == b"nlrecord ")
        .nth(1)
        .unwrap()
        .0;
    bytes[second + 200] ^= 0x01;
    std::fs::write(segment, &bytes).unwrap();
    let mut last = records(&runs).pop().unwrap();
    let key = last["key"].as_str().unwrap().to_string();
    last["message"] = json!("edited");
    let old_layout = runs.join(format!("{key}.json"));
    let whole = last.to_string();
    std::fs::write(&old_layout, &whole[..whole.len() / 2]).unwrap();
    let stray = runs.join("notes.json");
    std::fs::write(&stray, "{\"mine\": true}").unwrap();
    // `plan` and `status` read the catalog; whatever reads the records checks every frame, and
    // a frame found changed makes the next reader read all again.
    let collect = scratch.nlstudy("collect", &[]);
    assert!(
        text(&collect).contains(&segment.display().to_string()),
        "{}",
        text(&collect)
    );
    for verb in ["status", "plan"] {
        let out = text(&scratch.nlstudy(verb, &[]));
        for path in [segment, &old_layout, &stray] {
            assert!(
                out.contains(&path.display().to_string()),
                "{verb} does not name {}:\n{out}",
                path.display()
            );
        }
    }
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(plan.contains("1 to run, 3 stored"), "{plan}");
    let rerun = scratch.nlstudy("run", &[]);
    assert!(rerun.status.success(), "{}", text(&rerun));
    assert!(text(&rerun).contains("1 ran (1 ok"), "{}", text(&rerun));
    assert!(
        stray.exists() && old_layout.exists() && segment.exists(),
        "what is not a whole record is the user's to look at: reported, never removed"
    );
    std::fs::remove_file(&stray).unwrap();
    std::fs::remove_file(&old_layout).unwrap();
    std::fs::remove_file(segment).unwrap();
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(
        plan.contains("3 to run, 1 stored"),
        "the segment's records went with it: {plan}"
    );
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

/// `--retries`: a case whose process was killed from outside, or whose launcher failed after
/// the record was printed, runs again and its record keeps the attempt; a case past its timeout
/// is tried once more and then stored failed; a diverged case is a result and never runs again.
#[test]
fn failures_outside_the_case_are_retried_and_results_are_not() {
    let study = json!({
        "name": "retry",
        "base": {"dim": 2, "n": 32, "m": 2, "t_end": 0.001, "cfl": 0.5, "ranks": 2}
    });
    let scratch = Scratch::new("retries", &study);
    // A launcher whose first start fails as `first` says, and whose second runs the case.
    let retried_once = |study: &str, first: &str| {
        let body = format!(
            "marker=\"$(dirname \"$0\")/{study}-once\"\n\
             if [ ! -e \"$marker\" ]; then touch \"$marker\"; {first}; fi\n\
             exec mpirun --oversubscribe \"$@\"\n"
        );
        let launcher = launcher_script(&scratch, &format!("{study}-launcher"), &body);
        let out = scratch.nlstudy(
            "run",
            &["--no-collect", "--launcher", &launcher, "--retries", "1"],
        );
        assert!(out.status.success(), "{}", text(&out));
        assert!(text(&out).contains("(attempt 2)"), "{}", text(&out));
        let stored = records(&scratch.runs(study));
        let first = &stored[0];
        assert_eq!(stored.len(), 1);
        assert_eq!(
            (&first["status"], &first["attempt"]),
            (&json!("ok"), &json!(2))
        );
    };
    // Killed (as by an out-of-memory killer or a node failure).
    retried_once("retry", "kill -9 $$");
    // Failed after the solver printed its record (as Open MPI 4.1's mpirun now and then reports
    // a finished rank "exiting improperly"): the case ran, its launcher did not.
    scratch.write_study(&json!({
        "name": "teardown",
        "base": {"dim": 2, "n": 32, "m": 3, "t_end": 0.001, "cfl": 0.5, "ranks": 2}
    }));
    retried_once("teardown", "mpirun --oversubscribe \"$@\"; exit 1");

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

/// A case that kills the solver running it: on a worker, the worker is replaced and the case
/// runs again alone, in a process of its own, where it fails by itself; the other points run on
/// workers and are stored `ok`.
#[test]
fn a_case_that_kills_its_worker_fails_alone_and_the_others_run_on() {
    let study = json!({
        "name": "poison",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": [16, 20, 24, 28, 32, 36]}}]
    });
    let scratch = Scratch::new("poison", &study);
    // nlsolve, except that n = 24 kills the process running it, worker or not.
    let solver = executable(
        &scratch,
        "nlsolve-poisoned",
        &format!(
            "real='{}'\n\
             if [ \"$1\" = serve ]; then\n\
               while IFS= read -r line; do\n\
                 case \"$line\" in *'\"n\":24,'*) kill -9 $$ ;; esac\n\
                 printf '%s\\n' \"$line\" | \"$real\" serve || exit\n\
               done\n\
               exit 0\n\
             fi\n\
             [ \"$1\" = run ] && grep -q '\"n\":24,' \"$3\" && kill -9 $$\n\
             exec \"$real\" \"$@\"\n",
            nonlocal_study::binary("nlsolve").display()
        ),
    );
    let out = scratch.nlstudy("run", &["--no-collect", "--solver", &solver]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let said = text(&out);
    assert_eq!(
        said.matches("again in a process of its own: its worker ended with signal: 9")
            .count(),
        1,
        "{said}"
    );
    let stored = records(&scratch.runs("poison"));
    assert_eq!(stored.len(), 6);
    for record in &stored {
        let poisoned = record["case"]["n"] == 24;
        assert_eq!(
            record["status"],
            if poisoned { "failed" } else { "ok" },
            "{record}"
        );
        assert_eq!(record["attempt"], 1, "{record}");
        if poisoned {
            let message = record["message"].as_str().unwrap();
            assert!(
                message.starts_with("nlsolve exited with signal: 9"),
                "{message}"
            );
        }
    }
    assert!(solvers_of(&scratch).is_empty(), "a worker outlived the run");
}

/// A worker killed (SIGKILL) in the middle of a case: the case runs again in a process of its
/// own and is stored `ok`, as if nothing had happened.
#[test]
fn a_worker_killed_mid_case_is_replaced_and_its_case_runs_again() {
    let study = json!({
        "name": "killed",
        "base": {"dim": 2, "n": 256, "m": 3, "t_end": 0.02, "cfl": 0.5}
    });
    let scratch = Scratch::new("worker-killed", &study);
    let run = scratch.spawn("run", &["--no-collect"]);
    // The one point is sent to a worker as soon as it starts.
    assert!(
        eventually(Duration::from_secs(60), || !solvers_of(&scratch).is_empty()),
        "no worker started"
    );
    for pid in solvers_of(&scratch) {
        Command::new("kill")
            .args(["-9", &pid.to_string()])
            .status()
            .unwrap();
    }
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("again in a process of its own: its worker ended with signal: 9"),
        "{}",
        text(&out)
    );
    let stored = records(&scratch.runs("killed"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "ok", "{}", stored[0]);
    assert!(solvers_of(&scratch).is_empty());
}

/// A worker that holds more than `--worker-memory` MiB once it has answered is replaced: with
/// a bound below a fresh worker's size, every case gets a new worker; with the default, one
/// worker answers every case of a study run one case at a time.
#[test]
fn a_worker_past_its_memory_bound_is_replaced() {
    let scratch = Scratch::new("worker-memory", &short_study("grown", &[16, 20, 24]));
    let starts = scratch.dir.join("serve-starts");
    let solver = executable(
        &scratch,
        "nlsolve-counted",
        &format!(
            "[ \"$1\" = serve ] && echo started >> '{}'\nexec '{}' \"$@\"\n",
            starts.display(),
            nonlocal_study::binary("nlsolve").display()
        ),
    );
    let started = |extra: &[&str]| {
        let _ = std::fs::remove_file(&starts);
        let mut args = vec!["--no-collect", "--force", "--solver", &solver];
        args.extend_from_slice(extra);
        let out = scratch.nlstudy("run", &args);
        assert!(out.status.success(), "{}", text(&out));
        assert_whole(&scratch, "grown", 6, "every point on workers");
        std::fs::read_to_string(&starts).unwrap().lines().count()
    };
    assert_eq!(started(&["--worker-memory", "1"]), 6);
    assert_eq!(started(&[]), 1);
}

/// A solver that does not know `serve` (one from before it): its first worker exits 2 without
/// an answer, and every point runs as a process of its own, stored `ok`, with no message.
#[test]
fn a_solver_that_does_not_serve_runs_every_case_as_a_process() {
    let scratch = Scratch::new("no-serve", &short_study("old", &[16, 20, 24]));
    let solver = executable(
        &scratch,
        "nlsolve-old",
        &format!(
            "[ \"$1\" = serve ] && {{ echo \"error: unrecognized subcommand 'serve'\" >&2; exit 2; }}\n\
             exec '{}' \"$@\"\n",
            nonlocal_study::binary("nlsolve").display()
        ),
    );
    let out = scratch.nlstudy("run", &["--no-collect", "--solver", &solver]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(!text(&out).contains("process of its own"), "{}", text(&out));
    assert_whole(&scratch, "old", 6, "an old solver");
}

/// The records a study's points get on workers are those they get in processes of their own
/// (`--isolate`), bit for bit, but for what measures the run itself: its timings, peak memory,
/// when it ran and the machine's load.
#[test]
fn a_point_run_by_a_worker_has_the_record_of_its_own_process() {
    let study = json!({
        "name": "same",
        "base": {"dim": 1, "n": 64, "t_end": 0.001, "cfl": 0.5, "amplification_steps": 20},
        "sweep": [{"branches": {
            "nonlocal": [{"product": {"m": [1, 3], "threads": [1, 2],
                                      "integrator": ["forward_euler", "rk4", "crank_nicolson"]}}],
            "grid": [{"product": {"method": ["fd_explicit", "adi"], "problem": ["square"], "dim": [2], "n": [32], "cfl": [0.4]}}],
            "particles": [{"product": {"method": ["pse"], "problem": ["square"], "m": [2]}}],
            "steady": [{"product": {"method": ["steady_cg"], "dim": [2], "n": [16], "m": [2],
                                    "t_end": [null], "cfl": [null], "amplification_steps": [null]}}],
            "unstable": [{"product": {"m": [2], "cfl": [1.5], "t_end": [0.05], "allow_unstable": [true]}}]
        }}]
    });
    let scratch = Scratch::new("served", &study);
    let run_into = |results: &str, extra: &[&str]| {
        let out = Command::new(nonlocal_study::binary("nlstudy"))
            .args(["run", "--no-collect", "--results"])
            .arg(scratch.dir.join(results))
            .arg(scratch.study())
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", text(&out));
        let mut by_key: Vec<Value> = records(&scratch.dir.join(results).join("same/runs"))
            .into_iter()
            .map(|record| numbers_of(&record))
            .collect();
        by_key.sort_by(|a, b| a["key"].as_str().cmp(&b["key"].as_str()));
        by_key
    };
    let served = run_into("served", &[]);
    let alone = run_into("alone", &["--isolate"]);
    assert_eq!(served.len(), 17);
    assert!(served.iter().any(|r| r["status"] == "diverged"));
    for (served, alone) in served.iter().zip(&alone) {
        assert_eq!(served, alone);
    }
}

/// The records of the scratch's study run whole into results of their own, `whole/`: what a
/// stopped and resumed run must store.
fn run_uninterrupted(scratch: &Scratch, study: &str) -> Vec<Value> {
    let whole = Command::new(nonlocal_study::binary("nlstudy"))
        .args(["run", "--no-collect", "--results"])
        .arg(scratch.dir.join("whole"))
        .arg(scratch.study())
        .output()
        .unwrap();
    assert!(whole.status.success(), "{}", text(&whole));
    records(&scratch.dir.join(format!("whole/{study}/runs")))
}

/// A checkpointing study's point over two MPI ranks, `nlstudy run` stopped by SIGTERM after the
/// ranks' first checkpoints: each rank is asked to stop and writes its share at one step; the
/// next `run` resumes the point over two ranks and stores the record an uninterrupted run
/// stores, and the ranks' files go with it.
#[test]
fn a_stopped_run_resumes_its_point_over_two_ranks_from_their_checkpoints() {
    let study = json!({
        "name": "ranked",
        "checkpoint_every_s": 0.05,
        "base": {"dim": 2, "n": 128, "m": 3, "t_end": 0.5, "cfl": 0.5, "ranks": 2,
                 "source": "discrete"}
    });
    let scratch = Scratch::new("ranked", &study);
    let work = scratch.runs("ranked").join(".work");
    let checkpoints = || -> Vec<String> {
        let mut names: Vec<String> = files_under(&work)
            .iter()
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.') && n.contains(".checkpoint"))
            .collect();
        names.sort();
        names
    };
    let run = scratch.spawn("run", &["--no-collect"]);
    assert!(
        eventually(Duration::from_secs(120), || checkpoints().len() == 2),
        "no checkpoint of both ranks: {:?}",
        checkpoints()
    );
    stopped_by_sigterm(run);
    assert!(records(&scratch.runs("ranked")).is_empty());
    let files = checkpoints();
    assert_eq!(files.len(), 2, "both ranks' checkpoints stay: {files:?}");
    assert!(files[1].ends_with(".checkpoint.rank1"), "{files:?}");
    let step = |name: &str| -> u64 {
        let bytes = std::fs::read(work.join(name)).unwrap();
        let header = bytes.split(|&b| b == b'\n').nth(1).unwrap();
        serde_json::from_slice::<Value>(header).unwrap()["step"]
            .as_u64()
            .unwrap()
    };
    let stopped_at = step(&files[0]);
    assert_eq!(stopped_at, step(&files[1]), "the ranks stopped at one step");

    let stored = resumed_record(&scratch, "ranked");
    assert_eq!(
        stored["resumed_from_step"].as_u64(),
        Some(stopped_at),
        "{stored}"
    );
    assert!(
        checkpoints().is_empty(),
        "the ranks' checkpoints outlived the record"
    );
    let whole = run_uninterrupted(&scratch, "ranked");
    assert_eq!(numbers_of(&stored), numbers_of(&whole[0]));
}

/// A study that checkpoints (`checkpoint_every_s`): `nlstudy run` stopped by SIGTERM while its
/// long point runs (`status` says how far it is) asks the solver to stop, which writes the
/// point's checkpoint; the run exits 143 and stores nothing for the point. `run` again resumes the point from its checkpoint
/// (`resumed_from_step`), removes it, and stores the record an uninterrupted run stores.
#[test]
fn a_stopped_run_resumes_its_long_point_from_its_checkpoint() {
    let study = json!({
        "name": "long",
        "checkpoint_every_s": 0.05,
        "base": {"dim": 2, "n": 128, "m": 3, "problem": "manufactured", "t_end": 0.2, "cfl": 1.0,
                 "integrator": "crank_nicolson", "error_total": true, "diagnostics_every": 0.01}
    });
    let scratch = Scratch::new("checkpointed", &study);
    let work = scratch.runs("long").join(".work");
    let checkpoints = || -> Vec<PathBuf> {
        files_under(&work)
            .into_iter()
            .filter(|f| f.extension().is_some_and(|e| e == "checkpoint"))
            .collect()
    };
    let run = scratch.spawn("run", &["--no-collect"]);
    assert!(
        eventually(Duration::from_secs(120), || !checkpoints().is_empty()),
        "no checkpoint was written"
    );
    // While it runs, `status` says how far it is.
    let said = status_line(&scratch, "running ");
    assert!(
        said.contains(": step ") && said.contains(" of 1694, t = ") && said.contains(" s left"),
        "{said}"
    );
    stopped_by_sigterm(run);
    assert!(records(&scratch.runs("long")).is_empty());
    assert_eq!(
        checkpoints().len(),
        1,
        "the stopped point's checkpoint stays"
    );
    let said = status_line(&scratch, "checkpoint ");
    assert!(
        said.contains(": step ") && said.contains(" of 1694; the next run resumes it"),
        "{said}"
    );
    // Damaged, it is said not to be resumed, and why (as the solver would refuse it).
    let file = &checkpoints()[0];
    let whole_file = std::fs::read(file).unwrap();
    let mut damaged = whole_file.clone();
    let last = damaged.len() - 1;
    damaged[last] ^= 1;
    std::fs::write(file, &damaged).unwrap();
    let said = status_line(&scratch, "checkpoint ");
    assert!(
        said.contains("not resumed, it does not match its checksum")
            && said.ends_with("the next run starts it afresh")
            && !said.contains("resumes it"),
        "{said}"
    );
    std::fs::write(file, &whole_file).unwrap();

    let stored = resumed_record(&scratch, "long");
    assert!(
        stored["resumed_from_step"].as_u64().unwrap() > 0,
        "{stored}"
    );
    assert!(
        checkpoints().is_empty(),
        "the checkpoint outlived its record"
    );

    let whole = run_uninterrupted(&scratch, "long");
    assert!(whole[0].get("resumed_from_step").is_none());
    assert_eq!(numbers_of(&stored), numbers_of(&whole[0]));

    // `clean` removes the checkpoints no run will resume: a stored point's (as
    // `--keep-checkpoints` leaves it) and one of no point of the study.
    let key = stored["key"].as_str().unwrap();
    for stale in [key, "0123456789abcdef0123456789abcdef"] {
        std::fs::write(work.join(format!("{stale}.checkpoint")), "kept").unwrap();
    }
    let cleaned = scratch.nlstudy("clean", &[]);
    assert!(cleaned.status.success(), "{}", text(&cleaned));
    assert_eq!(
        text(&cleaned).matches("removed runs/.work/").count(),
        2,
        "{}",
        text(&cleaned)
    );
    assert!(checkpoints().is_empty());
}

/// The one record `nlstudy run` stores when it resumes the stopped point of the study `name`.
fn resumed_record(scratch: &Scratch, name: &str) -> Value {
    let resumed = scratch.nlstudy("run", &["--no-collect"]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    let stored = records(&scratch.runs(name));
    assert_eq!(stored.len(), 1);
    stored.into_iter().next().unwrap()
}

/// A checkpointing study's steady point (FETI's projected CG): `nlstudy run` stopped by SIGTERM
/// after the solve's first checkpoint leaves it, `status` says at which iteration, and the next
/// `run` resumes the solve there and stores the record an uninterrupted run stores.
#[test]
fn a_stopped_run_resumes_its_steady_point_at_its_iteration() {
    let study = json!({
        "name": "steady",
        "checkpoint_every_s": 0.02,
        "base": {"method": "feti", "dim": 2, "n": 256, "m": 3, "subdomains": 8, "rtol": 1e-12}
    });
    let scratch = Scratch::new("steady-checkpointed", &study);
    let work = scratch.runs("steady").join(".work");
    let checkpoint = || {
        files_under(&work)
            .into_iter()
            .find(|f| f.extension().is_some_and(|e| e == "checkpoint"))
    };
    let run = scratch.spawn("run", &["--no-collect"]);
    assert!(
        eventually(Duration::from_secs(120), || checkpoint().is_some()),
        "no checkpoint was written"
    );
    stopped_by_sigterm(run);
    assert!(records(&scratch.runs("steady")).is_empty());
    let said = status_line(&scratch, "checkpoint ");
    assert!(
        said.contains(": iteration ") && said.ends_with("; the next run resumes it"),
        "{said}"
    );

    let stored = resumed_record(&scratch, "steady");
    let from = stored["resumed_from_step"].as_u64().unwrap_or(0);
    assert!(
        from > 0 && from < stored["iterations"].as_u64().unwrap(),
        "{stored}"
    );
    assert!(checkpoint().is_none(), "the checkpoint outlived its record");
    let whole = run_uninterrupted(&scratch, "steady");
    assert_eq!(numbers_of(&stored), numbers_of(&whole[0]));
}

/// Stops `nlstudy run` as a scheduler's warning does (SIGTERM): it exits 143.
fn stopped_by_sigterm(run: std::process::Child) {
    Command::new("kill")
        .args(["-TERM", &run.id().to_string()])
        .status()
        .unwrap();
    let stopped = run.wait_with_output().unwrap();
    assert_eq!(stopped.status.code(), Some(143), "{}", text(&stopped));
}

/// The line of `nlstudy status` that starts with `start` (`running `, `checkpoint `).
fn status_line(scratch: &Scratch, start: &str) -> String {
    let status = text(&scratch.nlstudy("status", &[]));
    status
        .lines()
        .find(|l| l.starts_with(start))
        .unwrap_or_else(|| panic!("status has no line `{start}…`: {status}"))
        .to_string()
}

/// An executable shell script `name` in the scratch directory; returns its path.
fn executable(scratch: &Scratch, name: &str, body: &str) -> String {
    use std::os::unix::fs::PermissionsExt;
    let path = scratch.dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path.to_str().unwrap().to_string()
}

/// An executable shell script in the scratch directory, to stand in for an MPI launcher that
/// misbehaves the way a real one can; returns the launcher line that starts it.
fn launcher_script(scratch: &Scratch, name: &str, body: &str) -> String {
    // Launchers say where the rank count goes; these take it as mpirun does.
    format!("'{}' -n {{ranks}}", executable(scratch, name, body))
}

/// No panic text in what a process printed.
fn assert_no_panic(out: &std::process::Output) {
    let said = text(out);
    assert!(
        !said.contains("panicked") && !said.contains("RUST_BACKTRACE"),
        "{said}"
    );
}

/// `nlstudy run S 2>&1 | head -1`, a `tee` that died, `plan | head -1`: output nobody reads
/// never stops a study nor panics; a broken pipe ends a listing quietly with exit 0, and a full
/// stdout (/dev/full) is reported with the I/O exit status.
#[test]
fn output_nobody_reads_never_stops_a_study_nor_panics() {
    let scratch = Scratch::new("closed-output", &short_study("closed", &[16, 24]));
    let mut run = scratch.spawn("run", &[]);
    // Both ends closed before the first case finishes.
    drop(run.stdout.take());
    drop(run.stderr.take());
    let status = run.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    assert_whole(&scratch, "closed", 4, "run into a closed pipe");
    for verb in ["plan", "collect", "status", "table"] {
        let extra: &[&str] = match verb {
            "table" => &["--rows", "n,threads", "--value", "error_l2_norm"],
            _ => &[],
        };
        let mut child = scratch
            .command(verb, extra)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        assert_eq!(out.status.code(), Some(0), "{verb}: {}", text(&out));
        assert_no_panic(&out);
        let full = scratch
            .command(verb, extra)
            .stdout(
                std::fs::File::options()
                    .write(true)
                    .open("/dev/full")
                    .unwrap(),
            )
            .output()
            .unwrap();
        assert_eq!(full.status.code(), Some(3), "{verb}: {}", text(&full));
        assert!(
            text(&full).contains("cannot write to standard output"),
            "{}",
            text(&full)
        );
        assert_no_panic(&full);
    }
}

/// A tmpfs of `size` mounted at `dir` for the life of the value. The tests run as root (the
/// set-up needs it): a mount that fails fails the test rather than skip what it shows.
struct Tmpfs(PathBuf);

impl Tmpfs {
    fn mount(dir: &Path, size: &str) -> Tmpfs {
        std::fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .output()
            .expect("mount starts");
        assert!(
            out.status.success(),
            "mounting a tmpfs (the tests run as root): {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Tmpfs(dir.to_path_buf())
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// Fills the file system under `dir` with `filler` until it is full.
fn fill(filler: &Path) {
    use std::io::Write;
    let mut file = std::fs::File::create(filler).unwrap();
    let block = vec![0u8; 4096];
    while file.write_all(&block).is_ok() {}
    let _ = file.sync_all();
}

/// A store on a full disk: the run stops with the I/O exit status, names the path, stores no
/// point as failed, and once space is freed the next run runs every point.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_full_disk_stores_nothing_failed_and_the_next_run_resumes() {
    let scratch = Scratch::new("full-disk", &short_study("full", &[16]));
    let results = scratch.dir.join("results");
    let _mounted = Tmpfs::mount(&results, "1m");
    let filler = results.join("filler");
    fill(&filler);
    let out = scratch.nlstudy("run", &[]);
    assert_eq!(out.status.code(), Some(3), "{}", text(&out));
    assert!(
        text(&out).contains(&results.display().to_string()),
        "the message names the path: {}",
        text(&out)
    );
    assert_no_panic(&out);
    assert!(records(&scratch.runs("full")).is_empty());
    std::fs::remove_file(&filler).unwrap();
    let again = scratch.nlstudy("run", &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert_whole(&scratch, "full", 2, "after space is freed");
}

/// A full disk while each command writes its outputs: the Parquet tables (`collect`), the report
/// (`report`) and a figure (`plot`) each exit 3 naming the results, panic not, leave no partial
/// file, and lose no stored record; with space again each succeeds.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_full_disk_while_writing_tables_the_report_or_a_figure_exits_3() {
    let mut study = short_study("outputs", &[16]);
    study["figures"] = json!([{"name": "threads", "kind": "strong_scaling"}]);
    let scratch = Scratch::new("full-outputs", &study);
    let results = scratch.dir.join("results");
    let _mounted = Tmpfs::mount(&results, "2m");
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let stored = records(&scratch.runs("outputs")).len();
    let figures = results.join("outputs").join("figures");
    let filler = results.join("filler");
    for verb in ["collect", "report", "plot"] {
        // Stale figures, so that `plot` has one to write, and a table gone, so that `collect`
        // has one to write (with its tables whole and nothing new it writes none).
        let _ = std::fs::remove_dir_all(&figures);
        if verb == "collect" {
            std::fs::remove_file(results.join("outputs/outputs-summary.parquet")).unwrap();
        }
        fill(&filler);
        let out = scratch.nlstudy(verb, &[]);
        assert_eq!(out.status.code(), Some(3), "{verb}: {}", text(&out));
        assert!(
            text(&out).contains(&results.display().to_string()),
            "{verb} names the path: {}",
            text(&out)
        );
        // The file system's own words, not a Parquet writer's ("Invalid thrift").
        assert!(
            text(&out).contains("No space left on device") && !text(&out).contains("thrift"),
            "{verb} says why: {}",
            text(&out)
        );
        assert_no_panic(&out);
        let partials: Vec<PathBuf> = files_under(&results)
            .into_iter()
            .filter(|p| p.to_string_lossy().ends_with(".partial"))
            .collect();
        assert!(partials.is_empty(), "{verb} left {partials:?}");
        assert_eq!(records(&scratch.runs("outputs")).len(), stored, "{verb}");
        std::fs::remove_file(&filler).unwrap();
        let again = scratch.nlstudy(verb, &[]);
        assert!(
            again.status.success(),
            "{verb} with space: {}",
            text(&again)
        );
    }
}

/// nlsolve's exit 3 (it computed a record but could not write it): the file system's fault, not
/// the case's. The run stops with the I/O exit status naming the file, stores nothing, and the
/// point runs again next time.
#[test]
fn a_record_nlsolve_could_not_write_is_not_stored_as_a_failure() {
    let scratch = Scratch::new("unwritten", &short_study("unwritten", &[16]));
    let solver = scratch.dir.join("nlsolve-disk-full");
    std::fs::write(
        &solver,
        format!(
            "#!/bin/sh\nif [ \"$1\" = run ] || [ \"$1\" = serve ]; then echo 'nlsolve: cannot write the record to standard output: No space left on device (os error 28)' >&2; exit 3; fi\nexec '{}' \"$@\"\n",
            nonlocal_study::binary("nlsolve").display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&solver, std::fs::Permissions::from_mode(0o755)).unwrap();
    // On a worker, then in a process of its own (whose output file is named).
    for (flags, names) in [(&[][..], "nlsolve-disk-full"), (&["--isolate"][..], ".out")] {
        let mut args = vec!["--solver", solver.to_str().unwrap()];
        args.extend_from_slice(flags);
        let out = scratch.nlstudy("run", &args);
        assert_eq!(out.status.code(), Some(3), "{flags:?}: {}", text(&out));
        assert!(
            text(&out).contains(names) && text(&out).contains("No space left"),
            "{flags:?}: {}",
            text(&out)
        );
        assert!(records(&scratch.runs("unwritten")).is_empty());
    }
    let again = scratch.nlstudy("run", &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert_whole(&scratch, "unwritten", 2, "with a working solver");
}

/// Hostile or careless input, each refused before anything runs: exit 2, a sentence naming the
/// field or flag, no panic, no job script written.
#[test]
fn hostile_input_is_refused_naming_the_field() {
    let base = json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.001, "cfl": 0.5});
    let with = |extra: Value| {
        let mut study = json!({"name": "hostile", "base": base});
        study
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        study
    };
    let deep = format!("{}n{} > 1", "(".repeat(10_000), ")".repeat(10_000));
    let minus = format!("{}n > 1", "-".repeat(100_000));
    let big: Vec<u64> = (0..1000).collect();
    let cases: Vec<(Value, &str, Vec<&str>, &str)> = vec![
        (
            with(json!({"resources": {"queue": "debug\ntouch /tmp/pwned"}})),
            "submit",
            vec!["--scheduler", "slurm", "--dry-run"],
            "resources.queue",
        ),
        (
            with(json!({"resources": {"account": "x;touch /tmp/pwned"}})),
            "submit",
            vec!["--scheduler", "lsf", "--dry-run"],
            "resources.account",
        ),
        (
            with(json!({"resources": {"time": "01:00:00\ntouch /tmp/pwned"}})),
            "submit",
            vec!["--scheduler", "slurm", "--dry-run"],
            "resources.time",
        ),
        (
            with(json!({})),
            "submit",
            vec![
                "--scheduler",
                "slurm",
                "--dry-run",
                "--queue",
                "a\ntouch /tmp/pwned",
            ],
            "--queue",
        ),
        (
            with(json!({})),
            "submit",
            vec!["--scheduler", "slurm", "--dry-run", "--time", "30x"],
            "--time",
        ),
        (
            with(json!({})),
            "submit",
            vec!["--scheduler", "lsf", "--dry-run", "--nodes", "0"],
            "--nodes",
        ),
        (
            with(json!({})),
            "run",
            vec!["--timeout", "inf"],
            "--timeout",
        ),
        (
            with(json!({"timeout_s": 1e300})),
            "run",
            vec![],
            "timeout_s",
        ),
        (
            with(json!({"where": [deep]})),
            "plan",
            vec![],
            "nested deeper",
        ),
        (
            with(json!({"where": [minus]})),
            "plan",
            vec![],
            "nested deeper",
        ),
        (
            with(json!({"sweep": [{"product": {"a": big, "b": big, "c": big}}]})),
            "plan",
            vec![],
            "expands to",
        ),
        (
            with(json!({})),
            "run",
            vec!["--only", "0123456789abcdef"],
            "0123456789abcdef",
        ),
        (
            with(json!({})),
            "run",
            vec!["--only", "k\u{1b}]0;title\u{7}"],
            "\\u{1b}",
        ),
        (
            with(json!({})),
            "run",
            vec!["--launcher", "mpirun -n 2"],
            "{ranks}",
        ),
        (
            with(json!({"sweep": [{"branches": {"a\u{1b}[2J": [{"product": {"n": [8]}}]}}]})),
            "plan",
            vec![],
            "control character",
        ),
    ];
    for (k, (study, verb, extra, names)) in cases.into_iter().enumerate() {
        let scratch = Scratch::new(&format!("hostile-{k}"), &study);
        let out = scratch.nlstudy(verb, &extra);
        assert_eq!(out.status.code(), Some(2), "case {k}: {}", text(&out));
        assert!(text(&out).contains(names), "case {k}: {}", text(&out));
        assert_no_panic(&out);
        assert!(
            !text(&out).contains('\u{1b}'),
            "case {k}: a raw escape reached the terminal"
        );
        let jobs = scratch.dir.join("results/hostile/jobs");
        assert!(
            files_under(&jobs)
                .iter()
                .all(|f| f.extension().is_none_or(|x| x != "sbatch" && x != "bsub")),
            "case {k}: a script was written"
        );
    }
    assert!(!Path::new("/tmp/pwned").exists());
}

/// A busy process at the machine's normal priority, ended when dropped: the background load
/// under which stops land at other moments than on a quiet machine.
struct Busy(Child);

impl Busy {
    fn start() -> Busy {
        Busy(
            Command::new("sh")
                .args(["-c", "while :; do :; done"])
                .spawn()
                .unwrap(),
        )
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Points stopped through `nlstudy run` at 200 random moments and more, under a background load:
/// SIGTERM, SIGINT or SIGHUP, to `nlstudy` alone or to its process group (as Ctrl-C and
/// `scancel` reach it), in its set-up, its pool or a solver's time loop, with and without a
/// checkpoint period. Each time-dependent point stopped in its loop writes a checkpoint, and
/// every point's stored record, however many times it was stopped and resumed, is the record of
/// a run never stopped, bit for bit (errors, max |u|, mass, every number but the timings).
#[test]
fn points_stopped_at_random_moments_resume_with_the_bits_of_a_run_never_stopped() {
    use std::os::unix::process::CommandExt;
    let study = |period: bool| {
        let mut study = json!({
            "name": "stops",
            "base": {"dim": 2, "n": 80, "m": 3, "source": "discrete", "t_end": 0.3, "cfl": 0.5,
                     "diagnostics_every": 0.05, "error_total": true},
            "sweep": [{"branches": {
                "explicit": [{"product": {"integrator": ["forward_euler", "heun", "rk4"]}}],
                "implicit": [{"zip": {"integrator": ["crank_nicolson"], "cfl": [4.0]}}]
            }}]
        });
        if period {
            study["checkpoint_every_s"] = json!(0.02);
        }
        study
    };
    let scratch = Scratch::new("stops", &study(false));
    let whole: std::collections::HashMap<String, Value> = run_uninterrupted(&scratch, "stops")
        .into_iter()
        .map(|r| (r["key"].as_str().unwrap().to_string(), numbers_of(&r)))
        .collect();
    assert_eq!(whole.len(), 4);
    let mut rng = random();
    let _load = Busy::start();
    let (mut stops, mut round) = (0, 0);
    // Records stored, and those resumed from a checkpoint, in rounds without a checkpoint period
    // and with one (at least a round of each).
    let (mut stored_in, mut resumed) = ([0, 0], [0, 0]);
    while stops < 200 || round < 2 {
        round += 1;
        let period = round % 2 == 0;
        scratch.write_study(&study(period));
        let results = scratch.dir.join(format!("round{round}"));
        for attempt in 1.. {
            assert!(attempt < 200, "round {round} never finished");
            let mut run = Command::new(nonlocal_study::binary("nlstudy"));
            run.args(["run", "--no-collect", "--results"])
                .arg(&results)
                .arg(scratch.study())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .process_group(0);
            let child = run.spawn().unwrap();
            // 0.3 s reach a quiet machine's time loops; a busy one's set-up takes longer.
            let window = (300.0 * busy_factor()) as u64;
            std::thread::sleep(Duration::from_millis(rng.u64(0..window)));
            let signal = ["TERM", "INT", "HUP"][rng.usize(0..3)];
            let whom = match rng.bool() {
                true => format!("-{}", child.id()),
                false => child.id().to_string(),
            };
            Command::new("kill")
                .args([format!("-{signal}"), "--".into(), whom])
                .stderr(std::process::Stdio::null())
                .status()
                .unwrap();
            let out = child.wait_with_output().unwrap();
            // Ended by the signal itself when it came before nlstudy caught it.
            use std::os::unix::process::ExitStatusExt;
            match (out.status.code(), out.status.signal()) {
                (Some(0), _) => break,
                (Some(129 | 130 | 143), _) | (_, Some(1 | 2 | 15)) => stops += 1,
                _ => panic!(
                    "round {round}: a stopped run ended with {}: {}",
                    out.status,
                    text(&out)
                ),
            }
        }
        let stored = records(&results.join("stops/runs"));
        assert_eq!(stored.len(), 4, "round {round}");
        for record in &stored {
            let key = record["key"].as_str().unwrap();
            stored_in[usize::from(period)] += 1;
            resumed[usize::from(period)] += usize::from(record.get("resumed_from_step").is_some());
            assert_eq!(
                numbers_of(record),
                whole[key],
                "round {round}: a stopped point came back with other bits: {record}"
            );
        }
        std::fs::remove_dir_all(&results).unwrap();
    }
    eprintln!(
        "{stops} stops over {round} rounds; records resumed from a checkpoint: {} of {} without a period, {} of {} with one",
        resumed[0], stored_in[0], resumed[1], stored_in[1]
    );
    // Points were stopped in their loop and came back from a checkpoint, in both kinds of
    // round: on a quiet machine most of them; at a load of 8 on 2 cores, with a window of 0.3 s
    // whatever the load, 40 % and 20 % (`make test` beside two busy processes). (A share, not a
    // count: a slow machine takes more stops to end a round, so 200 stops may be as few as four
    // rounds, 16 records.)
    assert!(
        (0..2).all(|k| 4 * resumed[k] >= stored_in[k]),
        "too few resumed: {resumed:?} of {stored_in:?}, load {}",
        std::fs::read_to_string("/proc/loadavg").unwrap_or_default()
    );
}

/// How much slower than a quiet machine this one runs now, from 1 to 4: its load over its cores.
fn busy_factor() -> f64 {
    let load: f64 = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|text| text.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (load / cores as f64).clamp(1.0, 4.0)
}

/// `nlstudy run` answers SIGTERM within a second in each of its phases: the plan, between an
/// adaptive study's rounds, the pool (its solvers asked to checkpoint first), the tables, the
/// figures and the report. A test hook (`NLSTUDY_PAUSE_IN`) holds it in a phase until the
/// signal comes; in the pool a long point is running.
#[test]
fn sigterm_is_answered_within_a_second_in_every_phase_of_a_run() {
    use std::io::BufRead;
    let study = json!({
        "name": "phases",
        "base": {"dim": 1, "n": 64, "m": 2, "t_end": 1e-6, "allow_unstable": true,
                 "amplification_steps": 50},
        "sweep": [{"product": {"integrator": ["forward_euler", "heun"]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 1e-2},
        "figures": [{"name": "limits", "kind": "boundaries", "series": ["integrator"]}]
    });
    let long = json!({
        "name": "long",
        "base": {"dim": 2, "n": 128, "m": 3, "source": "discrete", "t_end": 2.0, "cfl": 0.5}
    });
    for (phase, study) in [
        ("plan", &study),
        ("round", &study),
        ("pool", &long),
        ("collect", &study),
        ("figures", &study),
        ("report", &study),
    ] {
        let scratch = Scratch::new("phases", study);
        let mut run = scratch.command("run", &[]);
        run.env("NLSTUDY_PAUSE_IN", phase)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped());
        let mut child = run.spawn().unwrap();
        let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
        let mut said = String::new();
        if phase == "pool" {
            // The point is in its time loop once its progress file is there.
            let work = scratch.runs("long").join(".work");
            let running = || {
                files_under(&work)
                    .iter()
                    .any(|f| f.extension().is_some_and(|e| e == "progress"))
            };
            assert!(
                eventually(Duration::from_secs(60), running),
                "the point never ran"
            );
        } else {
            let paused = format!("nlstudy: paused in {phase}");
            while !said.contains(&paused) {
                let mut line = String::new();
                let read = stderr.read_line(&mut line).unwrap();
                assert!(read > 0, "{phase}: ended without pausing: {said}");
                said.push_str(&line);
            }
        }
        let sent = Instant::now();
        Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        let status = child.wait().unwrap();
        let took = sent.elapsed();
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut stderr, &mut rest);
        assert_eq!(status.code(), Some(143), "{phase}: {status}: {said}{rest}");
        assert!(rest.contains("stopped by SIGTERM"), "{phase}: {rest}");
        assert!(took < Duration::from_secs(1), "{phase}: {took:?}");
    }
}
