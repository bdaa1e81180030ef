//! `nlsolve` when what it writes cannot be written. A record on a full disk, on a standard output
//! closed at start or on a broken pipe, `check`'s verdicts and the partition report likewise, and
//! a `--write-*` path that cannot be written: each exits with status 74 (EX_IOERR) and one line
//! saying what failed, never with a panic and never with success. A full standard error loses
//! only the summary.

mod common;

use common::nlsolve;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::process::{Command, Output, Stdio};

const NLSOLVE: &str = env!("CARGO_BIN_EXE_nlsolve");

/// nlsolve's status for an output it could not write (the table both binaries share).
const EXIT_IO: i32 = schema::exit::IO as i32;

/// A case that runs in milliseconds.
const TINY: &[&str] = &[
    "run", "--dim", "1", "--n", "16", "--m", "2", "--t-end", "0.001", "--cfl", "0.5",
];

/// The same case as JSON, for `--case -` and `check`.
const TINY_JSON: &str = r#"{"dim": 1, "n": 16, "m": 2, "t_end": 0.001, "cfl": 0.5}"#;

fn dev_full() -> File {
    OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full")
}

/// Exit status 3, one line on stderr naming what could not be written, no panic.
fn assert_output_failed(out: &Output, what: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(EXIT_IO), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains(what),
        "the message must name {what}: {stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "one line: {stderr}");
}

#[test]
fn a_record_written_to_a_full_disk_exits_74() {
    let out = nlsolve(TINY, None, Stdio::from(dev_full()));
    assert_output_failed(&out, "cannot write the record to standard output");
}

#[test]
fn a_record_written_to_a_closed_standard_output_exits_74() {
    // The shell closes descriptor 1 before nlsolve starts.
    let out = Command::new("sh")
        .arg("-c")
        .arg(r#"exec "$0" "$@" >&-"#)
        .arg(NLSOLVE)
        .args(TINY)
        .stdin(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .expect("sh starts");
    assert_output_failed(&out, "cannot write the record to standard output");
}

#[test]
fn a_record_written_to_a_broken_pipe_exits_74() {
    let mut child = Command::new(NLSOLVE)
        .args(["run", "--case", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("nlsolve starts");
    // The reader goes away before nlsolve has its case, so before it can write the record.
    drop(child.stdout.take());
    let mut stdin = child.stdin.take().expect("a pipe");
    stdin
        .write_all(TINY_JSON.as_bytes())
        .expect("nlsolve reads its case");
    drop(stdin);
    let out = child.wait_with_output().expect("nlsolve ends");
    assert_output_failed(&out, "cannot write the record to standard output");
}

#[test]
fn a_record_sent_to_dev_null_on_purpose_is_a_success() {
    let null = File::create("/dev/null").expect("/dev/null");
    let out = nlsolve(TINY, None, Stdio::from(null));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A worker driven from Python (a workflow tool, a notebook) that discards the record with
/// `subprocess.DEVNULL`, which opens /dev/null for reading and writing: a place to write.
#[test]
fn a_record_sent_to_devnull_from_python_is_a_success() {
    let script = format!(
        "import subprocess, sys\nsys.exit(subprocess.run([{NLSOLVE:?}] + sys.argv[1:], stdout=subprocess.DEVNULL, stdin=subprocess.DEVNULL).returncode)"
    );
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(TINY)
        .stderr(Stdio::piped())
        .output()
        .expect("python3 starts");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn verdicts_that_cannot_be_written_exit_3() {
    let cases = format!("{TINY_JSON}\n{TINY_JSON}\n");
    let out = nlsolve(&["check"], Some(&cases), Stdio::from(dev_full()));
    assert_output_failed(&out, "cannot write the verdicts to standard output");
}

#[test]
fn a_partition_report_that_cannot_be_written_exits_74() {
    let args = [
        "partition",
        "--dim",
        "2",
        "--n",
        "16",
        "--m",
        "2",
        "--ranks",
        "4",
    ];
    let out = nlsolve(&args, None, Stdio::from(dev_full()));
    assert_output_failed(&out, "cannot write the partition report to standard output");
}

#[test]
fn an_output_file_that_cannot_be_written_exits_74_naming_its_path() {
    let scratch = tempfile::tempdir().unwrap();
    let missing = scratch.path().join("missing");
    let path = missing.join("field.bin");
    let path_text = path.to_str().expect("a UTF-8 path");
    let mut args = TINY.to_vec();
    args.extend(["--write-field", path_text]);
    let out = nlsolve(&args, None, Stdio::piped());
    assert_output_failed(&out, path_text);
    assert!(out.stdout.is_empty(), "no record when an output is lost");
    assert!(!missing.exists());
}

#[test]
fn a_full_standard_error_loses_only_the_summary() {
    let out = Command::new(NLSOLVE)
        .args(TINY)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(dev_full()))
        .output()
        .expect("nlsolve starts");
    assert!(out.status.success(), "status {:?}", out.status);
    let record: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("one JSON record on stdout");
    assert_eq!(record["status"], "ok");
    // Bad input still exits 2 (its message is lost), not with a panic's 101.
    let out = Command::new(NLSOLVE)
        .args(["run", "--dim", "3", "--n", "16"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::from(dev_full()))
        .output()
        .expect("nlsolve starts");
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn help_lists_the_exit_statuses() {
    let out = nlsolve(&["--help"], None, Stdio::piped());
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(help.contains("Exit status"), "{help}");
    // clap wraps long lines: compared with every run of whitespace as one space.
    let words = |text: &str| text.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        words(&help).contains(&words(&schema::exit::nlsolve_help())),
        "{help}"
    );
}
