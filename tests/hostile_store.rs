//! A results directory others can write to, as processes: what `nlstudy` reads from its own
//! store is trusted no more than a study file. Each test reproduces a finding of the reliability
//! review (docs/reliability.md): a record whose content would become a path, files that are not
//! plain files, a corrupt table, and the exit status of every I/O failure.

use nonlocal_study::{edit_records, records, text, Scratch};
#[path = "support/parquet.rs"]
mod parquet;
use serde_json::{json, Value};
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Two tiny 1D points (milliseconds each), with a figure.
fn tiny(name: &str) -> Value {
    json!({
        "name": name,
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": [16, 24]}}],
        "figures": [{"name": "error", "kind": "convergence", "x": "n", "y": "error_l2_norm"}]
    })
}

fn ran(scratch: &Scratch, name: &str) {
    let out = scratch.nlstudy("run", &[]);
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(records(&scratch.runs(name)).len(), 2);
}

fn assert_no_panic(out: &Output) {
    let said = text(out);
    assert!(!said.contains("panicked"), "{said}");
}

/// The reproduction: a stored record whose fingerprint is a path. The next run that
/// replaces it (here `--force`; a new build does the same) keeps the old record inside the
/// history, and the file the traversal aimed at is untouched; a fingerprint with a slash or of
/// 300 characters no longer stops every later run.
#[test]
fn a_fingerprint_that_is_a_path_moves_nothing_outside_the_results() {
    let scratch = Scratch::new("traversal", &tiny("traversal"));
    ran(&scratch, "traversal");
    let history = scratch.dir.join("results/traversal/history");
    let runs = scratch.runs("traversal");
    let key = records(&runs)[0]["key"].as_str().unwrap().to_string();
    // history/<key>./../../../../PWN_target.json is <scratch>/PWN_target.json.
    std::fs::create_dir_all(history.join(format!("{key}."))).unwrap();
    let target = scratch.dir.join("PWN_target.json");
    std::fs::write(&target, "precious").unwrap();
    for fingerprint in ["/../../../../PWN_target", "a/b", &"f".repeat(300)] {
        // Edited as files of the store's older layout, which supersede its segments' records.
        for mut record in records(&runs) {
            record["provenance"]["fingerprint"] = json!(fingerprint);
            let key = record["key"].as_str().unwrap().to_string();
            std::fs::write(runs.join(format!("{key}.json")), record.to_string()).unwrap();
        }
        let out = scratch.nlstudy("run", &["--force"]);
        assert!(out.status.success(), "{fingerprint}: {}", text(&out));
        assert!(text(&out).contains("2 ran (2 ok"), "{}", text(&out));
    }
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "precious");
    let kept: Vec<String> = std::fs::read_dir(&history)
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(kept.len(), 6, "every replaced result is kept: {kept:?}");
    assert!(kept.iter().all(|n| n.contains(".unknown")), "{kept:?}");
}

/// The reproduction: a folder of the study's results that is a link to elsewhere,
/// planted at `history`, `runs/.work`, `runs/segments`, `figures` or `jobs`, is named and refused
/// (exit 3) by the commands that write there, and nothing is written through it. A link for the
/// whole study folder stays allowed.
#[test]
fn a_folder_link_planted_inside_the_results_is_refused_and_nothing_goes_through_it() {
    let scratch = Scratch::new("planted", &tiny("planted"));
    ran(&scratch, "planted");
    assert!(scratch.nlstudy("report", &[]).status.success());
    let study = scratch.dir.join("results/planted");
    let elsewhere = scratch.dir.join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    let aside = scratch.dir.join("aside");
    for folder in ["history", "runs/.work", "runs/segments", "figures", "jobs"] {
        let at = study.join(folder);
        let existed = at.exists();
        if existed {
            std::fs::rename(&at, &aside).unwrap();
        }
        std::os::unix::fs::symlink(&elsewhere, &at).unwrap();
        for (verb, extra) in [
            ("run", &["--force"][..]),
            ("collect", &[]),
            ("report", &[]),
            ("plot", &[]),
        ] {
            let out = scratch.nlstudy(verb, extra);
            let said = text(&out);
            assert_eq!(out.status.code(), Some(3), "{folder}, {verb}: {said}");
            assert!(
                said.contains(&format!("{} is a symbolic link", at.display())),
                "{folder}, {verb}: {said}"
            );
            assert_no_panic(&out);
            let written: Vec<_> = std::fs::read_dir(&elsewhere).unwrap().collect();
            assert!(
                written.is_empty(),
                "{folder}, {verb} wrote through the link"
            );
        }
        std::fs::remove_file(&at).unwrap();
        if existed {
            std::fs::rename(&aside, &at).unwrap();
        }
    }
    // The whole study folder a link of the user's: allowed, and its records are found.
    let real = scratch.dir.join("real-planted");
    std::fs::rename(&study, &real).unwrap();
    std::os::unix::fs::symlink(&real, &study).unwrap();
    let out = scratch.nlstudy("run", &[]);
    assert!(text(&out).contains("2 already stored"), "{}", text(&out));
}

/// Runs `nlstudy verb` and waits at most a minute: `None` when it is still running then (it
/// hangs), and it is killed.
fn within_a_minute(scratch: &Scratch, verb: &str, extra: &[&str]) -> Option<(Output, Duration)> {
    let started = Instant::now();
    let mut child = scratch
        .command(verb, extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    while started.elapsed() < Duration::from_secs(60) {
        if child.try_wait().unwrap().is_some() {
            return Some((child.wait_with_output().unwrap(), started.elapsed()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

/// The reproduction: a record that is a link to /dev/zero and FIFOs in `runs/` and
/// `history/`. `plan`, `status`, `run` and `history` name each and return at once: nothing is
/// read to its end, followed or waited on.
#[test]
fn files_that_are_not_plain_files_are_named_never_read_or_waited_on() {
    let scratch = Scratch::new("fifo", &tiny("fifo"));
    ran(&scratch, "fifo");
    let runs = scratch.runs("fifo");
    let history = scratch.dir.join("results/fifo/history");
    std::fs::create_dir_all(&history).unwrap();
    let zero = runs.join(format!("{}.json", "a".repeat(32)));
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let fifos = [
        runs.join(format!("{}.json", "b".repeat(32))),
        history.join(format!("{}.unknown.json", "c".repeat(32))),
    ];
    for fifo in &fifos {
        let made = Command::new("mkfifo").arg(fifo).status().unwrap();
        assert!(made.success());
    }
    for (verb, extra) in [
        ("plan", vec![]),
        ("status", vec![]),
        ("history", vec!["--metric", "solve_s"]),
        ("run", vec![]),
    ] {
        let (out, took) = within_a_minute(&scratch, verb, &extra)
            .unwrap_or_else(|| panic!("`nlstudy {verb}` hangs on a FIFO"));
        assert_no_panic(&out);
        let said = text(&out);
        println!("nlstudy {verb} returned in {took:?}");
        let named = match verb {
            "history" => fifos[1].clone(),
            _ => fifos[0].clone(),
        };
        assert!(
            said.contains(&named.display().to_string()),
            "{verb}: {said}"
        );
        assert!(said.contains("FIFO"), "{verb}: {said}");
        if verb != "history" {
            assert!(said.contains("symbolic link"), "{verb}: {said}");
        }
    }
    assert!(
        std::fs::symlink_metadata(&zero).is_ok(),
        "reported, not removed"
    );
}

/// A table whose bytes were changed (one byte of the footer, the fixture) makes `table`,
/// `plot` and `report` exit 3 naming it and the fix, never panic; `collect` rebuilds it.
#[test]
fn a_corrupt_table_exits_3_naming_it_and_collect_rebuilds_it() {
    let scratch = Scratch::new("corrupt-table", &tiny("broken"));
    ran(&scratch, "broken");
    let summary = scratch.dir.join("results/broken/broken-summary.parquet");
    let mut bytes = std::fs::read(&summary).unwrap();
    let at = bytes.len() - 20;
    bytes[at] ^= 0x5a;
    std::fs::write(&summary, &bytes).unwrap();
    for (verb, extra) in [
        ("table", vec!["--rows", "n", "--value", "error_l2_norm"]),
        ("plot", vec![]),
        ("report", vec![]),
    ] {
        let out = scratch.nlstudy(verb, &extra);
        assert_eq!(out.status.code(), Some(3), "{verb}: {}", text(&out));
        assert_no_panic(&out);
        let said = text(&out);
        assert!(
            said.contains("broken-summary.parquet") && said.contains("nlstudy collect"),
            "{verb}: {said}"
        );
    }
    let collect = scratch.nlstudy("collect", &[]);
    assert!(collect.status.success(), "{}", text(&collect));
    let table = scratch.nlstudy("table", &["--rows", "n", "--value", "error_l2_norm"]);
    assert!(table.status.success(), "{}", text(&table));
}

/// Every I/O failure exits 3 (README's table): a table, a report or a lock that cannot be
/// written, and a scheduler that refuses the job.
#[test]
fn io_failures_exit_3() {
    let scratch = Scratch::new("io-exit", &tiny("io"));
    ran(&scratch, "io");
    let study = scratch.dir.join("results/io");
    let in_the_way = |path: PathBuf| {
        let _ = std::fs::remove_file(&path);
        std::fs::create_dir_all(path.join("x")).unwrap();
        path
    };
    let tables = in_the_way(study.join("io.parquet"));
    let out = scratch.nlstudy("collect", &[]);
    assert_eq!(out.status.code(), Some(3), "collect: {}", text(&out));
    let out = scratch.nlstudy("run", &[]);
    assert_eq!(out.status.code(), Some(3), "run's tables: {}", text(&out));
    std::fs::remove_dir_all(&tables).unwrap();
    let report = in_the_way(study.join("report.html"));
    let out = scratch.nlstudy("report", &[]);
    assert_eq!(out.status.code(), Some(3), "report: {}", text(&out));
    std::fs::remove_dir_all(&report).unwrap();
    let figure = in_the_way(study.join("figures/error.svg"));
    std::fs::remove_file(study.join("figures/.error.stamp")).unwrap();
    let out = scratch.nlstudy("plot", &[]);
    assert_eq!(out.status.code(), Some(3), "plot: {}", text(&out));
    std::fs::remove_dir_all(&figure).unwrap();
    let lock = in_the_way(study.join(".outputs.lock"));
    for verb in ["collect", "plot"] {
        let out = scratch.nlstudy(verb, &[]);
        assert_eq!(out.status.code(), Some(3), "{verb}: {}", text(&out));
        assert!(text(&out).contains(".outputs.lock"), "{}", text(&out));
    }
    std::fs::remove_dir_all(&lock).unwrap();
    let everything = scratch.nlstudy("run", &[]);
    assert!(everything.status.success(), "{}", text(&everything));
    // A scheduler that refuses: a stub sbatch on the PATH, for a study with points to submit.
    let scratch = Scratch::new("io-exit-submit", &tiny("submitted"));
    let bin = scratch.dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let sbatch = bin.join("sbatch");
    std::fs::write(
        &sbatch,
        "#!/bin/sh\necho 'sbatch: error: Batch job submission failed' >&2\nexit 1\n",
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&sbatch, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = scratch
        .command("submit", &["--scheduler", "slurm"])
        .env("PATH", path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "submit: {}", text(&out));
    assert!(text(&out).contains("submission failed"), "{}", text(&out));
}

/// Exit 1, for each command that can end so (README's table): `run` when a case fails or a
/// figure cannot be made of the runs, `plot` when a figure cannot be made (a field figure of a
/// study that asked for no snapshot). `compare`'s 1 (a metric worse beyond the noise floor)
/// needs calibrated runs: tests/nlstudy.rs's comparison test checks it. `history` draws only
/// what it has checked, so no data makes it exit 1: a metric no record has is bad input (2).
#[test]
fn a_failed_case_or_a_figure_that_cannot_be_made_exits_1() {
    let study = json!({
        "name": "one",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": [16, 24]}}],
        "figures": [{"name": "u", "kind": "field", "where": ["n == 16"]}]
    });
    let scratch = Scratch::new("exit-1", &study);
    let refused = {
        let mut refused = study.clone();
        refused["name"] = json!("one-refused");
        // m = 40 nodes per horizon at n = 16: ε = 2.5, past the largest horizon.
        refused["sweep"] = json!([{"product": {"n": [16], "m": [40]}}]);
        refused["figures"] = json!([]);
        Scratch::new("exit-1-refused", &refused)
    };
    let cases: [(&str, &Scratch, &[&str], &str); 4] = [
        (
            "run",
            &refused,
            &["--no-collect", "--allow-refused"],
            "failed",
        ),
        ("run", &scratch, &[], "not drawn"),
        ("plot", &scratch, &[], "not drawn"),
        (
            "history",
            &scratch,
            &["--metric", "no_such_field"],
            "no_such_field",
        ),
    ];
    for (verb, scratch, extra, said) in cases {
        let out = scratch.nlstudy(verb, extra);
        let expected = if verb == "history" { 2 } else { 1 };
        assert_eq!(out.status.code(), Some(expected), "{verb}: {}", text(&out));
        assert!(text(&out).contains(said), "{verb}: {}", text(&out));
        assert_no_panic(&out);
    }
    let stored = records(&refused.runs("one-refused"));
    assert_eq!(stored.len(), 1);
    assert_eq!(stored[0]["status"], "failed", "{:?}", stored[0]);
}

/// A TOML study's `nan` and `inf` were "not given" (two points with the key of no dt): refused
/// naming their place, as is a TOML date where a number belongs.
#[test]
fn numbers_that_are_not_finite_are_refused_in_a_toml_study() {
    let scratch = Scratch::new("toml-nan", &tiny("nan"));
    let study = scratch.dir.join("study.toml");
    for (text_of, names) in [
        (
            "name = \"nan\"\n[base]\ndim = 1\nm = 2\nt_end = 0.001\n[[sweep]]\nproduct = { n = [16], dt = [nan, inf] }\n",
            "sweep[0].product.dt[0]",
        ),
        (
            "name = \"nan\"\ntimeout_s = inf\n[base]\ndim = 1\n",
            "timeout_s",
        ),
        ("name = \"nan\"\n[base]\ndim = 1\nt_end = 2026-11-25\n", "quote it"),
    ] {
        std::fs::write(&study, text_of).unwrap();
        let out = Command::new(nonlocal_study::binary("nlstudy"))
            .arg("plan")
            .arg(&study)
            .arg("--results")
            .arg(scratch.dir.join("results"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{}", text(&out));
        assert!(text(&out).contains(names), "{names}: {}", text(&out));
        if names != "quote it" {
            assert!(text(&out).contains("not a finite number"), "{}", text(&out));
        }
    }
}

/// Every command's bad-input status: a study file that is not there, and a flag value that is
/// no number, each exit 2 with one line naming what is wrong, and write nothing.
#[test]
fn every_command_exits_2_on_a_missing_study_file_and_a_flag_that_is_no_number() {
    let scratch = Scratch::new("bad-input-every-command", &tiny("bad"));
    let missing = scratch.dir.join("no-such-study.json");
    let commands: [(&str, &[&str]); 11] = [
        ("plan", &[]),
        ("run", &[]),
        ("collect", &[]),
        ("plot", &[]),
        ("status", &[]),
        ("report", &[]),
        ("table", &["--value", "error_l2_norm"]),
        ("submit", &["--scheduler", "slurm", "--dry-run"]),
        ("clean", &[]),
        ("compare", &["--against", "history"]),
        ("history", &[]),
    ];
    let results = scratch.dir.join("results");
    for (verb, extra) in commands {
        let out = Command::new(nonlocal_study::binary("nlstudy"))
            .arg(verb)
            .arg(&missing)
            .args(["--results", results.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{verb}: {}", text(&out));
        assert!(
            text(&out).contains("no-such-study.json"),
            "{verb} names the file: {}",
            text(&out)
        );
        // A value clap must parse as a number.
        let flag = match verb {
            "run" => Some(["--timeout", "soon"]),
            "compare" => Some(["--threshold", "ten"]),
            _ => None,
        };
        if let Some(flag) = flag {
            let out = Command::new(nonlocal_study::binary("nlstudy"))
                .arg(verb)
                .arg(scratch.study())
                .args(["--results", results.to_str().unwrap()])
                .args(extra)
                .args(flag)
                .output()
                .unwrap();
            assert_eq!(
                out.status.code(),
                Some(2),
                "{verb} {flag:?}: {}",
                text(&out)
            );
            assert!(text(&out).contains(flag[0]), "{verb}: {}", text(&out));
        }
    }
    assert!(
        !results.exists(),
        "a refused command wrote {}",
        results.display()
    );
}

/// The keys `nlstudy plan` says are stored (skipped), and those it runs.
fn planned_split(scratch: &Scratch) -> (BTreeSet<String>, BTreeSet<String>) {
    let plan = scratch.nlstudy("plan", &[]);
    assert!(plan.status.success(), "{}", text(&plan));
    let (mut stored, mut to_run) = (BTreeSet::new(), BTreeSet::new());
    for line in String::from_utf8_lossy(&plan.stdout).lines().skip(1) {
        let mut words = line.split_whitespace();
        let (Some(key), Some(decision)) = (words.next(), words.next()) else {
            continue;
        };
        match decision {
            "run" => to_run.insert(key.to_string()),
            "skip" => stored.insert(key.to_string()),
            _ => false, // the closing count
        };
    }
    (stored, to_run)
}

/// The keys of the rows of the study's run table (`show --from-table`).
fn tabled_keys(scratch: &Scratch) -> BTreeSet<String> {
    let show = scratch.nlstudy("show", &["--from-table"]);
    assert!(show.status.success(), "{}", text(&show));
    String::from_utf8_lossy(&show.stdout)
        .lines()
        .map(|line| {
            serde_json::from_str::<Value>(line).unwrap()["key"]
                .as_str()
                .unwrap()
                .to_string()
        })
        .collect()
}

/// The catalog is a cache: whatever is damaged (a byte of the catalog, a digit of an entry's
/// span, a byte of a segment, a segment cut short), the tables, `plan`, `status` and `run`
/// agree on which points are stored whole, and each point missing from the tables runs again,
/// after which every point is in them. (A segment changed in place with its size and its
/// modification time kept, as bit rot would, is found only by a command that reads its
/// records: docs/reliability.md.)
#[test]
fn tables_plan_status_and_run_agree_on_what_is_stored_whatever_is_damaged() {
    let sizes: Vec<u64> = (4..16).map(|k| 4 * k).collect();
    let study = json!({
        "name": "damaged",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": sizes}}]
    });
    let scratch = Scratch::new("damaged", &study);
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let results = scratch.dir.join("results");
    let pristine = scratch.dir.join("pristine");
    let copy = |from: &PathBuf, to: &PathBuf| {
        let _ = std::fs::remove_dir_all(to);
        assert!(Command::new("cp")
            .arg("-a")
            .arg(from)
            .arg(to)
            .status()
            .unwrap()
            .success());
    };
    copy(&results, &pristine);
    let seed = std::env::var("RELIABILITY_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos() as u64
        });
    eprintln!("hostile_store: RELIABILITY_SEED={seed}");
    let mut rng = fastrand::Rng::with_seed(seed);
    let segments = results.join("damaged/runs/segments");
    let mut damaged_points = 0;
    for trial in 0..24 {
        copy(&pristine, &results);
        let mut files: Vec<PathBuf> = std::fs::read_dir(&segments)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "seg"))
            .collect();
        files.sort();
        let catalog = segments.join("catalog");
        let what = trial % 4;
        let path = match what {
            0 | 1 => catalog.clone(),
            _ => files[rng.usize(0..files.len())].clone(),
        };
        let mut bytes = std::fs::read(&path).unwrap();
        match what {
            // A byte of the catalog, or of a segment.
            0 | 2 => {
                let at = rng.usize(0..bytes.len());
                bytes[at] ^= 1 << rng.u8(0..8);
            }
            // A digit of an entry's span.
            1 => {
                let digits: Vec<usize> = (0..bytes.len())
                    .filter(|&i| {
                        bytes[i].is_ascii_digit()
                            && i > bytes.iter().position(|&b| b == b'\n').unwrap()
                    })
                    .collect();
                let at = digits[rng.usize(0..digits.len())];
                bytes[at] = if bytes[at] == b'9' {
                    b'0'
                } else {
                    bytes[at] + 1
                };
            }
            // A segment cut short.
            _ => bytes.truncate(rng.usize(0..bytes.len())),
        }
        // (A second later: the store tells a segment written over by its time.)
        std::fs::write(&path, &bytes).unwrap();
        let later = std::time::SystemTime::now() + Duration::from_secs(1);
        let file = std::fs::File::options().write(true).open(&path).unwrap();
        file.set_modified(later).unwrap();
        let collect = scratch.nlstudy("collect", &[]);
        assert!(
            collect.status.success(),
            "trial {trial}: {}",
            text(&collect)
        );
        let tabled = tabled_keys(&scratch);
        let (stored, to_run) = planned_split(&scratch);
        assert_eq!(stored.len() + to_run.len(), 12);
        assert_eq!(
            tabled, stored,
            "trial {trial} ({what}): the tables and plan disagree"
        );
        let status = text(&scratch.nlstudy("status", &[]));
        let missing = format!("{} of 12 points to run", to_run.len());
        assert!(status.contains(&missing), "trial {trial}: {status}");
        damaged_points += to_run.len();
        let run = scratch.nlstudy("run", &[]);
        assert!(run.status.success(), "trial {trial}: {}", text(&run));
        let ran = format!("{} ran (", to_run.len());
        assert!(text(&run).contains(&ran), "trial {trial}: {}", text(&run));
        assert_eq!(tabled_keys(&scratch).len(), 12, "trial {trial}");
        assert!(planned_split(&scratch).1.is_empty(), "trial {trial}");
    }
    eprintln!("24 damages, {damaged_points} points lost and run again");
}

/// A solver whose stderr holds escape sequences (clear the screen, retitle the window): none
/// reaches the terminal through `run` or `status`, nor the stored record, where they are kept
/// escaped (`\u{1b}`), so the message still says what the solver said.
#[test]
fn a_solvers_escape_sequences_reach_neither_the_terminal_nor_the_store() {
    use std::os::unix::fs::PermissionsExt;
    let scratch = Scratch::new("escapes", &tiny("escapes"));
    let wrapper = scratch.dir.join("nlsolve");
    let real = nonlocal_study::binary("nlsolve");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\ncase \"$1\" in run|serve) printf '\\033[2Jboom\\033]0;pwned\\007\\n' >&2; exit 1;; esac\nexec {} \"$@\"\n",
            real.display()
        ),
    )
    .unwrap();
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let solver = wrapper.to_str().unwrap();
    let run = scratch.nlstudy("run", &["--solver", solver, "--retries", "0"]);
    assert_eq!(run.status.code(), Some(1), "{}", text(&run));
    let status = scratch.nlstudy("status", &["--solver", solver]);
    for out in [&run, &status] {
        assert!(!text(out).contains('\u{1b}'), "{:?}", text(out));
        assert!(text(out).contains("\\u{1b}[2Jboom"), "{}", text(out));
    }
    for record in records(&scratch.runs("escapes")) {
        let message = record["message"].as_str().unwrap();
        assert!(
            !message.contains('\u{1b}') && message.contains("\\u{1b}]0;pwned\\u{7}"),
            "{message}"
        );
    }
}

/// A segment's last frame whose length was changed reads as a frame cut short (as a write torn
/// by a crash would): its point runs again, and the writer that cuts the bytes off says so.
#[test]
fn a_last_frame_cut_short_is_cut_off_with_a_warning_and_its_point_runs_again() {
    let scratch = Scratch::new("torn", &tiny("torn"));
    ran(&scratch, "torn");
    let segments = scratch.runs("torn").join("segments");
    let segment = std::fs::read_dir(&segments)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "seg"))
        .unwrap();
    let mut bytes = std::fs::read(&segment).unwrap();
    let last = bytes.windows(9).rposition(|w| w == b"nlrecord ").unwrap();
    let header_end = last + bytes[last..].iter().position(|&b| b == b'\n').unwrap();
    let header = String::from_utf8(bytes[last..header_end].to_vec()).unwrap();
    let fields: Vec<&str> = header.split(' ').collect();
    let longer = format!(
        "{} {} {} {}",
        fields[0],
        fields[1],
        fields[2].parse::<u64>().unwrap() + 10,
        fields[3]
    );
    bytes.splice(last..header_end, longer.into_bytes());
    std::fs::write(&segment, &bytes).unwrap();
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let said = text(&run);
    assert!(said.contains("1 ran (1 ok"), "{said}");
    assert!(
        said.contains("bytes of a frame cut short") && said.contains("cut off"),
        "{said}"
    );
    assert_eq!(records(&scratch.runs("torn")).len(), 2);
}

/// A solver for `compare --against`'s B side: a shell script that answers `--version` with
/// `version` and `fingerprint` with nothing (a solver from before fingerprints), and runs cases
/// as `runs` says (`exec <real nlsolve> "$@"` for the real runs).
fn solver_script(scratch: &Scratch, name: &str, version: &str, runs: &str) -> String {
    use std::os::unix::fs::PermissionsExt;
    let path = scratch.dir.join(name);
    let real = nonlocal_study::binary("nlsolve");
    let script = format!(
        "#!/bin/sh\ncase \"$1\" in\n  --version) printf '%s\\n' '{version}' ;;\n  fingerprint) exit 1 ;;\n  run|serve) {runs} ;;\n  *) exec {} \"$@\" ;;\nesac\n",
        real.display()
    );
    std::fs::write(&path, script).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path.to_str().unwrap().to_string()
}

/// `nlstudy compare --against solver:<this build> --solver B --rounds 2`, at most two minutes
/// (a hang fails the test rather than the suite).
fn interleaved(scratch: &Scratch, b: &str, extra: &[&str]) -> Output {
    let against = format!("solver:{}", nonlocal_study::binary("nlsolve").display());
    let mut args = vec!["--against", &against, "--solver", b, "--rounds", "2"];
    args.extend_from_slice(extra);
    let mut child = scratch
        .command("compare", &args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("compare against {b} still ran after two minutes");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

/// The reproductions: the interleaved store of a B side that prints no fingerprint is
/// named by the hash of its binary, never by its `--version` (`/tmp/x`, `../..` and a multi-byte
/// string each once named a folder outside the study or panicked), so its runs are stored under
/// the study; a B that crashes on every case, or hangs past `--timeout`, fails the gate (exit 1)
/// naming its points, where it once passed as "0 worse".
#[test]
fn interleaved_compare_stores_under_the_study_and_fails_a_crashing_or_hanging_build() {
    let scratch = Scratch::new("gate", &tiny("gate"));
    let interleaved_dir = scratch.dir.join("results/gate/interleaved");
    let outside = scratch.dir.join("x");
    for (name, version) in [
        ("slash", outside.to_str().unwrap()),
        ("up", "../.."),
        ("wide", "ééééééé€"),
    ] {
        let b = solver_script(
            &scratch,
            name,
            version,
            &format!(
                "exec {} \"$@\"",
                nonlocal_study::binary("nlsolve").display()
            ),
        );
        let out = interleaved(&scratch, &b, &[]);
        assert!(out.status.success(), "{version}: {}", text(&out));
        assert_no_panic(&out);
        assert!(!outside.exists(), "{version}: stored outside the study");
        let names: Vec<String> = std::fs::read_dir(&interleaved_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(
            names
                .iter()
                .all(|n| n.contains("-binary-") && n.is_ascii() && !n.contains('.')),
            "{version}: {names:?}"
        );
        std::fs::remove_dir_all(&interleaved_dir).unwrap();
    }
    assert!(!scratch.dir.join("results/x").exists() && !scratch.dir.join("x").exists());

    let crashing = solver_script(&scratch, "crashing", "crashing 1", "kill -SEGV $$");
    let out = interleaved(&scratch, &crashing, &[]);
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("runs failed, so the builds cannot be compared")
            && said.contains("by B in round 1"),
        "{said}"
    );
    assert!(
        said.contains("n=16") && said.contains("n=24"),
        "both points named: {said}"
    );

    let hanging = solver_script(&scratch, "hanging", "hanging 1", "exec sleep 600");
    let out = interleaved(&scratch, &hanging, &["--timeout", "2"]);
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(
        said.contains("by B in round 1") && said.contains("timed out"),
        "{said}"
    );
}

/// A record rewritten in place with a field that does not parse (`"error_l2_norm": "abcabc…"`
/// under a CRC that holds, the segment grown where its frame stood): `status` names the
/// field, and the next `run` counts the point as not run and runs it again, the first time
/// (the catalog's offsets from before the edit point inside a frame and are not trusted).
#[test]
fn a_record_edited_in_place_to_a_field_that_does_not_parse_runs_again() {
    let scratch = Scratch::new("edited", &tiny("edited"));
    ran(&scratch, "edited");
    // A second run reads the store through the catalog the first left.
    let again = scratch.nlstudy("run", &[]);
    assert!(text(&again).contains("0 ran"), "{}", text(&again));
    let mut first = true;
    let edited = edit_records(&scratch.runs("edited"), |record| {
        let edit = std::mem::take(&mut first);
        if edit {
            record["error_l2_norm"] = json!("abc".repeat(10));
        }
        edit
    });
    assert_eq!(edited, 1);
    let status = scratch.nlstudy("status", &[]);
    assert!(text(&status).contains("error_l2_norm"), "{}", text(&status));
    let run = scratch.nlstudy("run", &[]);
    let said = text(&run);
    assert!(run.status.success(), "{said}");
    assert!(
        said.contains("1 ran (1 ok") && said.contains("1 already stored"),
        "{said}"
    );
    assert!(said.contains("error_l2_norm"), "{said}");
    for record in records(&scratch.runs("edited")) {
        assert!(record["error_l2_norm"].is_f64(), "{record}");
    }
}

/// A stored record from elsewhere whose message holds escape sequences (a failed probe of a
/// boundary search): the answer lines, the boundaries table and the report show them as their
/// codes (`\u{1b}`), never the raw bytes a terminal or a reader would act on (`table`'s cells:
/// `analysis::pivot`'s unit test).
#[test]
fn a_stored_messages_escape_sequences_reach_no_answer_table_or_report() {
    let study = json!({
        "name": "esc",
        "base": {"dim": 1, "problem": "bump", "t_end": 1e-6, "allow_unstable": true,
                 "amplification_steps": 400, "m": 2, "n": 32},
        "sweep": [{"product": {"integrator": ["forward_euler", "heun"]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 4], "flips": "amplification > 1", "rtol": 1e-2}
    });
    let scratch = Scratch::new("esc", &study);
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let edited = edit_records(&scratch.runs("esc"), |record| {
        let edit = record["case"]["cfl"] == json!(0.5) && record["case"]["integrator"].is_null();
        if edit {
            record["status"] = json!("failed");
            record["message"] = json!("boom \u{1b}[31mRED\u{1b}]0;pwned\u{7}");
        }
        edit
    });
    assert_eq!(edited, 1);
    let run = scratch.nlstudy("run", &[]);
    let dir = scratch.dir.join("results/esc");
    let boundaries = parquet::read_parquet(&dir.join("esc-boundaries.parquet"));
    let ended = boundaries.column("ended").unwrap().str().unwrap();
    let ended: Vec<&str> = (0..ended.len()).filter_map(|i| ended.get(i)).collect();
    // The other point's search still answers.
    let answered = parquet::floats(&boundaries, "boundary");
    assert_eq!(
        answered.iter().filter(|b| b.is_finite()).count(),
        1,
        "{boundaries}"
    );
    let report = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let shown = [
        ("run", text(&run)),
        ("boundaries", ended.join("\n")),
        ("report", report),
    ];
    for (what, shown) in shown {
        assert!(
            !shown.contains('\u{1b}') && !shown.contains('\u{7}'),
            "{what}: {shown:?}"
        );
        assert!(shown.contains("boom \\u{1b}[31mRED"), "{what}: {shown}");
    }
}

/// A study file that is a FIFO, written once: `run` reads it once (the study and its owner's
/// hash from the same text) and runs its points, instead of blocking on a second open with no
/// writer left.
#[test]
fn a_study_file_that_is_a_fifo_is_read_once() {
    let scratch = Scratch::new("piped", &tiny("piped"));
    let written = std::fs::read_to_string(scratch.study()).unwrap();
    std::fs::remove_file(scratch.study()).unwrap();
    let made = Command::new("mkfifo")
        .arg(scratch.study())
        .status()
        .unwrap();
    assert!(made.success());
    let fifo = scratch.study();
    std::thread::spawn(move || std::fs::write(fifo, written));
    let (out, _) = within_a_minute(&scratch, "run", &[])
        .expect("`nlstudy run` waits on a second open of its FIFO study file");
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("2 ran"), "{}", text(&out));
}

/// A damaged store and `show --key`: a key whose record cannot be read is refused naming the
/// damage that may have held it, not as if it had never been stored.
#[test]
fn show_names_the_damage_where_a_key_is_not_found() {
    let scratch = Scratch::new("shown", &tiny("shown"));
    ran(&scratch, "shown");
    let segment = nonlocal_study::segment_files(&scratch.runs("shown"))[0].clone();
    let mut bytes = std::fs::read(&segment).unwrap();
    let (_, first) = &nonlocal_study::frames(&bytes)[0];
    let first: Value = serde_json::from_slice(first).unwrap();
    let key = first["key"].as_str().unwrap().to_string();
    // A byte of the first frame's body changed: its CRC no longer holds.
    let body = bytes.iter().position(|&b| b == b'{').unwrap();
    bytes[body + 1] ^= 0x20;
    std::fs::write(&segment, &bytes).unwrap();
    let out = scratch.nlstudy("show", &["--key", &key]);
    let said = text(&out);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(
        said.contains("damaged") && said.contains(&segment.display().to_string()),
        "{said}"
    );
}

/// A number given as 1e-300 where it is refused is quoted in a few characters, as given
/// (`exact`), not in Rust's fixed notation of 300 digits: a flag, a study's bracket, a target.
#[test]
fn a_refused_tiny_number_is_quoted_short() {
    let scratch = Scratch::new("tinynumber", &tiny("tinynumber"));
    let mut said = Vec::new();
    for extra in [
        vec!["--timeout=-1e-300"],
        vec!["--checkpoint-every=-1e-300"],
    ] {
        said.push(text(&scratch.nlstudy("run", &extra)));
    }
    said.push(text(&scratch.nlstudy(
        "compare",
        &["--against", "history", "--threshold=-1e-300"],
    )));
    let mut bracketed = tiny("tinynumber");
    bracketed["boundary"] = json!({"field": "cfl", "bracket": [1e-300, 1e-300],
        "flips": "amplification > 1", "rtol": 1e-3});
    scratch.write_study(&bracketed);
    said.push(text(&scratch.nlstudy("plan", &[])));
    let mut target = tiny("tinynumber");
    target["target"] = json!({"field": "n", "start": -1e-300, "below": 1e-3});
    scratch.write_study(&target);
    said.push(text(&scratch.nlstudy("plan", &[])));
    for said in said {
        assert!(said.contains("1e-300"), "{said}");
        assert!(said.lines().all(|l| l.len() < 300), "{said}");
    }
}
