//! Shared helpers of the end-to-end tests: locate the workspace's binaries and run them as a user
//! or a cluster job would.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

/// Path of a workspace binary built in the same profile as this test (target/<profile>/<name>).
pub fn binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let profile_dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target/<profile>/deps");
    let path = profile_dir.join(name);
    assert!(
        path.exists(),
        "{} is not built; run the tests with `cargo test --release --workspace`",
        path.display()
    );
    path
}

/// Runs `nlsolve` with `args`, feeding `stdin` if given.
pub fn nlsolve(args: &[&str], stdin: Option<&str>) -> Output {
    let mut child = Command::new(binary("nlsolve"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("nlsolve starts");
    if let Some(text) = stdin {
        child
            .stdin
            .take()
            .unwrap()
            .write_all(text.as_bytes())
            .unwrap();
    }
    drop(child.stdin.take());
    child.wait_with_output().expect("nlsolve finishes")
}

/// The record `nlsolve` printed: exactly one JSON line on stdout.
pub fn record(output: &Output) -> serde_json::Value {
    let stdout = String::from_utf8_lossy(&output.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 1, "expected one record line, got: {stdout}");
    serde_json::from_str(lines[0]).expect("the record is JSON")
}
