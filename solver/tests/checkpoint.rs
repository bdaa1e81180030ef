//! `nlsolve run --checkpoint`: a run stopped by SIGTERM at whatever step it is in writes its
//! checkpoint and exits 143; started again, it resumes there and its record is the record of a
//! run never stopped, bit for bit but for its timings, for every integrator and method, on 1
//! and 2 threads (and resumed on the other count). A checkpoint of another build, another
//! case, or a damaged one is refused, named, and the run starts at step 0; a run killed
//! (SIGKILL) at random moments, even mid-write, always leaves a checkpoint that resumes.

mod common;

use serde_json::{json, Value};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `nlsolve run --case - EXTRA…` started, with `case` written to its standard input.
fn start(case: &Value, extra: &[&str], stdout: Stdio) -> Child {
    start_as(
        Command::new(env!("CARGO_BIN_EXE_nlsolve")),
        case,
        extra,
        stdout,
    )
}

/// The same, `nlsolve` started by `command` (under `nice`, say).
fn start_as(mut command: Command, case: &Value, extra: &[&str], stdout: Stdio) -> Child {
    let mut child = command
        .args(["run", "--case", "-"])
        .args(extra)
        .stdin(Stdio::piped())
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    let mut input = child.stdin.take().unwrap();
    input.write_all(case.to_string().as_bytes()).unwrap();
    child
}

/// nlsolve at the lowest priority: on a loaded machine a test's thread watching its files then
/// runs as soon as it wakes.
fn lowest_priority() -> Command {
    let mut nice = Command::new("nice");
    nice.args(["-n", "19", env!("CARGO_BIN_EXE_nlsolve")]);
    nice
}

/// Runs nlsolve on `case` with `extra` flags, to its end.
fn run(case: &Value, extra: &[&str]) -> Output {
    start(case, extra, Stdio::piped())
        .wait_with_output()
        .unwrap()
}

fn record(output: &Output) -> Value {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

/// The numbers of a record (`common::numbers_of`), its case's thread count left out: the two
/// halves of a run may differ in it, and so in the memory estimate of the threads' buffers
/// (FETI's).
fn numbers_of(record: Value) -> Value {
    let mut record = common::numbers_of(record);
    record["case"].as_object_mut().unwrap().remove("threads");
    record
        .as_object_mut()
        .unwrap()
        .remove("memory_estimate_bytes");
    record
}

/// How far a run goes: its time steps, or a steady solve's iterations (which it checkpoints).
fn length(record: &Value) -> u64 {
    record["iterations"]
        .as_u64()
        .or(record["steps"].as_u64())
        .unwrap()
}

/// A scratch directory for one test's checkpoints, removed however the test ends.
fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix(&format!("nlsolve-checkpoint-{name}-"))
        .tempdir()
        .unwrap()
}

/// Waits, polling, for `path` to exist; false after a minute.
fn appears(path: &Path) -> bool {
    let deadline = Instant::now() + Duration::from_secs(60);
    while Instant::now() < deadline {
        if path.exists() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    false
}

/// Runs `case` on `threads`, checkpointing every `every` steps, stops it with SIGTERM once its
/// first checkpoint is written (at whatever step it has reached then), resumes it on
/// `then_threads`, and checks the resumed record against `whole`'s numbers. Returns the step
/// it resumed from.
fn stopped_and_resumed(
    case: &Value,
    whole: &Value,
    every: u64,
    (threads, then_threads): (u64, u64),
) -> u64 {
    // A directory of its own: tests stop and resume cases at once.
    static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let run_number = RUNS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let scratch = scratch(&format!("stopped-{run_number}"));
    let dir = scratch.path();
    let file = dir.join("run.checkpoint");
    let path = file.to_str().unwrap();
    let with_threads = |threads: u64| {
        let mut case = case.clone();
        case["threads"] = json!(threads);
        case
    };
    let first = with_threads(threads);
    // The signal must reach the run inside its time loop, as its first checkpoint says it is.
    // The run has the lowest priority, so that this thread sees the file at once on a loaded
    // machine; a run that still ends before the signal is started again (not the run's fault).
    let every = every.to_string();
    let extra = ["--checkpoint", path, "--checkpoint-every-steps", &every];
    let mut stopped = None;
    for _attempt in 0..5 {
        let mut child = start_as(lowest_priority(), &first, &extra, Stdio::piped());
        let mut ended = false;
        while !file.exists() && !ended {
            ended = child.try_wait().unwrap().is_some();
            std::thread::sleep(Duration::from_millis(1));
        }
        if !ended {
            // Not yet reaped, so its pid is still its own.
            Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status()
                .unwrap();
        }
        let output = child.wait_with_output().unwrap();
        if !output.status.success() {
            stopped = Some(output);
            break;
        }
    }
    let stopped =
        stopped.unwrap_or_else(|| panic!("{case}: five runs ended before the signal came"));
    let said = String::from_utf8_lossy(&stopped.stderr);
    assert_eq!(stopped.status.code(), Some(143), "{case}: {said}");
    assert!(
        stopped.stdout.is_empty(),
        "{case}: a stopped run prints no record"
    );
    assert!(said.contains("stopped at"), "{case}: {said}");
    let resumed = record(&run(&with_threads(then_threads), &["--checkpoint", path]));
    assert!(
        !file.exists(),
        "{case}: the checkpoint stays after the record"
    );
    let step = resumed["resumed_from_step"]
        .as_u64()
        .unwrap_or_else(|| panic!("{case}: not resumed: {resumed}"));
    assert!(
        step > 0 && step < length(whole),
        "{case}: resumed from {step}"
    );
    let segments = resumed["solve_s_segments"].as_array().unwrap();
    assert_eq!(segments.len(), 2, "{resumed}");
    assert_eq!(
        numbers_of(resumed),
        numbers_of(whole.clone()),
        "{case}: the resumed run's record differs from the whole run's"
    );
    step
}

/// Every integrator of the nonlocal method and the grid and particle methods, with the
/// observers a checkpoint must carry (c_tot, the total error, the implicit solves' counts).
fn cases() -> Vec<Value> {
    let nonlocal = |integrator: &str, cfl: f64| {
        json!({"dim": 2, "n": 128, "m": 3, "problem": "manufactured", "t_end": 0.1, "cfl": cfl,
               "integrator": integrator, "diagnostics_every": 0.005, "error_total": true,
               "field_snapshot": 8})
    };
    vec![
        nonlocal("forward_euler", 0.5),
        nonlocal("heun", 0.5),
        nonlocal("rk4", 0.9),
        nonlocal("backward_euler", 1.0),
        nonlocal("crank_nicolson", 1.0),
        json!({"method": "fd_explicit", "dim": 2, "n": 96, "problem": "square", "t_end": 0.05,
               "cfl": 0.4, "diagnostics_every": 0.005}),
        json!({"method": "adi", "dim": 2, "n": 128, "problem": "eigenmode", "t_end": 0.2,
               "cfl": 0.5, "diagnostics_every": 0.01}),
        json!({"method": "pse", "dim": 2, "n": 48, "m": 2, "problem": "square", "t_end": 0.5,
               "cfl": 0.5, "diagnostics_every": 0.05}),
    ]
}

#[test]
fn a_run_stopped_by_sigterm_resumes_with_the_record_of_a_run_never_stopped() {
    for case in cases() {
        let whole = record(&run(&case, &[]));
        assert!(
            whole["steps"].as_u64().unwrap() >= 200,
            "{case}: too short to be stopped midway ({} steps)",
            whole["steps"]
        );
        let steps: Vec<u64> = [(1, 1), (2, 2), (1, 2)]
            .into_iter()
            .map(|threads| stopped_and_resumed(&case, &whole, 25, threads))
            .collect();
        let what = case.get("integrator").unwrap_or(&case["method"]);
        eprintln!("{what}: resumed from steps {steps:?} of {}", whole["steps"]);
    }
}

/// The steady solves checkpoint CG's state between iterations (the iterate, residual, search
/// direction and scalars): steady CG and FETI's projected CG stopped by SIGTERM resume at their
/// iteration with the record of a solve never stopped.
#[test]
fn a_steady_solve_stopped_by_sigterm_resumes_at_its_iteration_with_the_same_bits() {
    let cases = [
        (
            json!({"method": "steady_cg", "dim": 2, "n": 512, "m": 4, "rtol": 1e-12}),
            25,
        ),
        (
            json!({"method": "feti", "dim": 2, "n": 192, "m": 3, "subdomains": 8, "rtol": 1e-12}),
            4,
        ),
    ];
    for (case, every) in cases {
        let whole = record(&run(&case, &[]));
        assert!(
            length(&whole) >= 40,
            "{case}: too short to be stopped midway"
        );
        let iterations: Vec<u64> = [(1, 1), (2, 2), (1, 2)]
            .into_iter()
            .map(|threads| stopped_and_resumed(&case, &whole, every, threads))
            .collect();
        eprintln!(
            "{}: resumed from iterations {iterations:?} of {}",
            case["method"],
            length(&whole)
        );
    }
}

/// While a steady solve runs, its progress file (`--progress`) says its iteration and the
/// iterations its residual's decay says it needs (within the cap, 10⁵), and is gone once the
/// solve is over.
#[test]
fn a_steady_solve_says_how_far_it_is_in_iterations() {
    let scratch = scratch("progress");
    let dir = scratch.path();
    let file = dir.join("run.progress");
    let case = json!({"method": "steady_cg", "dim": 2, "n": 512, "m": 4, "rtol": 1e-12});
    // At the lowest priority, so that this thread reads the file before the solve is over.
    let progress_flag = ["--progress", file.to_str().unwrap()];
    let child = start_as(lowest_priority(), &case, &progress_flag, Stdio::piped());
    assert!(appears(&file), "no progress file was written");
    let progress: Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    let whole = record(&child.wait_with_output().unwrap());
    assert_eq!(progress["unit"], "iteration", "{progress}");
    let (step, steps) = (
        progress["step"].as_u64().unwrap(),
        progress["steps"].as_u64().unwrap(),
    );
    assert!(
        step >= 1 && steps > step && steps <= 100_000,
        "{progress}: iteration {step} of about {steps}"
    );
    assert!(step < length(&whole), "{progress}");
    assert!(!file.exists(), "the progress file stays after the solve");
}

#[test]
fn a_checkpoint_of_another_build_or_case_or_a_damaged_one_is_refused_and_the_run_starts_afresh() {
    let scratch = scratch("refused");
    let dir = scratch.path();
    let file = dir.join("run.checkpoint");
    let path = file.to_str().unwrap();
    let case = json!({"dim": 1, "n": 256, "m": 3, "problem": "manufactured", "t_end": 0.02,
                      "cfl": 0.5, "error_total": true});
    let whole = record(&run(&case, &[]));
    // A checkpoint of this case, kept after its run.
    let kept = |file: &Path| {
        let out = run(
            &case,
            &[
                "--checkpoint",
                file.to_str().unwrap(),
                "--checkpoint-every-steps",
                "100",
                "--keep-checkpoint",
            ],
        );
        record(&out);
        std::fs::read(file).unwrap()
    };
    let good = kept(&file);
    // Resumed from that last checkpoint, the record is the whole run's.
    let resumed = record(&run(&case, &["--checkpoint", path]));
    assert!(resumed["resumed_from_step"].as_u64().unwrap() > 0);
    assert_eq!(numbers_of(resumed), numbers_of(whole.clone()));

    let refused_with = |bytes: &[u8], against: &Value, why: &str| {
        std::fs::write(&file, bytes).unwrap();
        let out = run(against, &["--checkpoint", path]);
        let said = String::from_utf8_lossy(&out.stderr).into_owned();
        let record = record(&out);
        assert!(
            said.contains("refused") && said.contains(why) && said.contains("starts at step 0"),
            "{why}: {said}"
        );
        assert!(record.get("resumed_from_step").is_none(), "{why}: {record}");
        record
    };
    // The header edited, one digit of its step: the checksum covers it.
    let text = String::from_utf8_lossy(&good).into_owned();
    let at = text.find("\"step\":").unwrap() + 7;
    let mut stepped = good.clone();
    stepped[at] = if stepped[at] == b'1' { b'2' } else { b'1' };
    refused_with(&stepped, &case, "checksum");
    // Rewritten whole with another header, under a checksum that matches it.
    let rewritten = |edit: &dyn Fn(&mut schema::checkpoint::Header)| {
        let read = schema::checkpoint::parse(good.clone()).unwrap();
        let mut header = read.header.clone();
        edit(&mut header);
        let mut bytes = Vec::new();
        let values: Vec<f64> = read.parts().flat_map(|(_, v)| v).collect();
        schema::checkpoint::write(&mut bytes, &header, values).unwrap();
        bytes
    };
    let other = rewritten(&|h| h.identity.fingerprint = "0".repeat(64));
    let afresh = refused_with(&other, &case, "another solver build");
    assert_eq!(numbers_of(afresh), numbers_of(whole.clone()));
    let past = rewritten(&|h| h.step = h.steps.unwrap() + 1);
    refused_with(&past, &case, "of a run of");
    let fewer = rewritten(&|h| h.steps = Some(h.step));
    refused_with(&fewer, &case, "its header says");
    let mut other_case = case.clone();
    other_case["n"] = json!(128);
    refused_with(&good, &other_case, "another case");
    refused_with(&good[..good.len() - 5], &case, "cut short");
    let mut flipped = good.clone();
    let last = flipped.len() - 1;
    flipped[last] ^= 0x10;
    refused_with(&flipped, &case, "checksum");
    // A checkpoint larger than any of the case can be is not read; since the run neither wrote
    // it nor resumed from it, it is left in place.
    let big = std::fs::File::create(&file).unwrap();
    std::io::Write::write_all(&mut &big, schema::checkpoint::MAGIC).unwrap();
    big.set_len(1 << 40).unwrap();
    let out = run(&case, &["--checkpoint", path]);
    let said = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        said.contains("bytes a checkpoint of this case may hold") && said.contains("step 0"),
        "{said}"
    );
    assert_eq!(numbers_of(record(&out)), numbers_of(whole.clone()));
    assert_eq!(
        std::fs::metadata(&file).unwrap().len(),
        1 << 40,
        "refused, yet removed"
    );
}

/// What stands at `--checkpoint`'s path and is not a checkpoint of nlsolve (a file of the user's,
/// a FIFO, a link, a device node, a folder) is refused before the run, named, and left exactly as
/// it was: nlsolve writes no checkpoint over it and removes nothing at the end (a run as root
/// once removed `/dev/zero` this way). The device is one this test makes, never a system one.
#[test]
fn what_is_not_a_checkpoint_of_nlsolve_is_refused_and_left_in_place() {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let scratch = scratch("foreign");
    let dir = scratch.path();
    let case = json!({"dim": 1, "n": 64, "m": 3, "problem": "manufactured", "t_end": 0.01,
                      "cfl": 0.5});
    let thesis = dir.join("thesis.tex");
    std::fs::write(&thesis, "years of work").unwrap();
    let fifo = dir.join("fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    // A character device like /dev/null (1, 3), made here (root only, as CI runs).
    let device = dir.join("null");
    let made = Command::new("mknod")
        .arg(&device)
        .args(["c", "1", "3"])
        .status();
    assert!(
        made.is_ok_and(|s| s.success()),
        "mknod failed: this test makes a device node of its own, which needs root"
    );
    let link = dir.join("link");
    std::os::unix::fs::symlink(&thesis, &link).unwrap();
    let folder = dir.join("folder");
    std::fs::create_dir(&folder).unwrap();
    let what = |path: &Path| {
        let meta = std::fs::symlink_metadata(path).unwrap();
        let kind = meta.file_type();
        let contents = kind.is_file().then(|| std::fs::read(path).unwrap());
        (
            meta.ino(),
            kind.is_fifo(),
            kind.is_char_device(),
            kind.is_symlink(),
            contents,
        )
    };
    for (path, named) in [
        (&thesis, "not a checkpoint of nlsolve"),
        (&fifo, "a FIFO"),
        (&device, "a device"),
        (&link, "a symbolic link"),
        (&folder, "a directory"),
    ] {
        let before = what(path);
        let flag = path.to_str().unwrap();
        for extra in [
            &["--checkpoint", flag][..],
            &["--checkpoint", flag, "--checkpoint-every-steps", "1"],
        ] {
            let out = run(&case, extra);
            let said = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{named}: {said}");
            assert!(
                said.contains(named) && said.contains("writes no checkpoint over it"),
                "{named}: {said}"
            );
            assert_eq!(what(path), before, "{named} changed");
        }
        // The same through `serve`: the case is refused, the path left as it was.
        let line = json!({"case": case, "checkpoint": flag}).to_string();
        let out = serve(&line);
        assert!(
            out.contains("\"error\"") && out.contains(named),
            "{named}: {out}"
        );
        assert_eq!(what(path), before, "{named} changed by serve");
    }
    assert_eq!(std::fs::read(&thesis).unwrap(), b"years of work");
}

/// `nlsolve serve`'s answer to the one line `line`.
fn serve(line: &str) -> String {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_nlsolve"))
        .arg("serve")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    writeln!(child.stdin.take().unwrap(), "{line}").unwrap();
    String::from_utf8(child.wait_with_output().unwrap().stdout).unwrap()
}

/// SIGKILL at random moments of a run that checkpoints every step (so that most kills land in
/// or near a write): the file is always a whole checkpoint of the run (the next run resumes
/// from it, never refuses it), and the run resumed last has the whole run's record.
#[test]
fn a_run_killed_at_random_moments_always_leaves_a_checkpoint_that_resumes() {
    let scratch = scratch("killed");
    let dir = scratch.path();
    let file = dir.join("run.checkpoint");
    let path = file.to_str().unwrap();
    let case = json!({"dim": 2, "n": 64, "m": 3, "problem": "manufactured", "t_end": 0.02,
                      "cfl": 0.5, "integrator": "heun", "error_total": true});
    let whole = record(&run(&case, &[]));
    let seed = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    eprintln!("kill delays from seed {seed}");
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut last_step = 0;
    for _ in 0..8 {
        let mut child = start(
            &case,
            &["--checkpoint", path, "--checkpoint-every-steps", "1"],
            Stdio::null(),
        );
        // A fault's moment, not a timing: 0–60 ms into the run.
        std::thread::sleep(Duration::from_micros(rng.u64(..60_000)));
        let _ = child.kill();
        let out = child.wait_with_output().unwrap();
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(
            !said.contains("refused"),
            "a kill left a checkpoint that is refused: {said}"
        );
        if out.status.success() {
            // It ran to its end before the kill: its checkpoint went with its record.
            last_step = 0;
        } else if file.exists() {
            let bytes = std::fs::read(&file).unwrap();
            let size = bytes.len();
            let step = schema::checkpoint::parse(bytes)
                .unwrap_or_else(|e| {
                    panic!("a checkpoint of {size} bytes, status {}: {e}", out.status)
                })
                .header
                .step as u64;
            assert!(
                step >= last_step,
                "the checkpoint went back from {last_step} to {step}"
            );
            last_step = step;
        } else {
            // No checkpoint after a kill: none was written yet, or the run had finished and
            // removed it when the kill landed, before it exited. Either way the next run
            // starts afresh.
            last_step = 0;
        }
    }
    let resumed = record(&run(&case, &["--checkpoint", path]));
    let said_steps = resumed["resumed_from_step"].as_u64().unwrap_or(0);
    assert_eq!(said_steps, last_step, "{resumed}");
    assert_eq!(numbers_of(resumed), numbers_of(whole));
}
