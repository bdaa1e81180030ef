//! `nlsolve serve`: one process answering case after case. Each answer is the record `nlsolve
//! run` writes for the case in a process of its own, bit for bit but for what measures the
//! run itself (its timings, the machine's load, its peak memory); bad input is an error line
//! naming the field, and the worker goes on to the next case.

mod common;

use common::{nlsolve, numbers_of};
use serde_json::{json, Value};
use std::process::Stdio;

#[test]
fn a_served_case_has_the_record_of_its_own_process_and_bad_input_is_an_answer() {
    let cases = [
        json!({"dim": 1, "n": 64, "m": 3, "problem": "bump", "t_end": 1e-4, "cfl": 0.5}),
        json!({"dim": 2, "n": 32, "m": 2, "problem": "manufactured", "t_end": 1e-3, "cfl": 0.9,
               "integrator": "rk4", "threads": 2, "amplification_steps": 50}),
        json!({"dim": 1, "n": 64, "m": 4, "problem": "manufactured", "t_end": 1e-3, "cfl": 4,
               "integrator": "crank_nicolson"}),
        json!({"method": "fd_explicit", "dim": 2, "n": 32, "problem": "square", "t_end": 1e-3, "cfl": 0.4}),
        json!({"method": "adi", "dim": 2, "n": 32, "problem": "eigenmode", "t_end": 1e-2, "cfl": 4}),
        json!({"method": "pse", "dim": 1, "n": 64, "m": 2, "problem": "square", "t_end": 1e-3, "cfl": 0.5}),
        json!({"method": "steady_cg", "dim": 2, "n": 16, "m": 2}),
    ];
    let mut input: String = cases.iter().map(|c| format!("{c}\n")).collect();
    input += "{\"dim\": 1, \"n\": 16}\n\nnot json\n";
    input += &format!("{}\n", cases[0]);
    let served = nlsolve(&["serve"], Some(&input), Stdio::piped());
    assert!(
        served.status.success(),
        "{}",
        String::from_utf8_lossy(&served.stderr)
    );
    let answers: Vec<Value> = String::from_utf8(served.stdout)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).expect("one JSON answer per line"))
        .collect();
    assert_eq!(
        answers.len(),
        cases.len() + 3,
        "one answer per case; blank lines none"
    );
    for (case, answer) in cases.iter().zip(&answers) {
        let alone = nlsolve(
            &["run", "--case", "-"],
            Some(&case.to_string()),
            Stdio::piped(),
        );
        assert!(
            alone.status.success(),
            "{case}: {}",
            String::from_utf8_lossy(&alone.stderr)
        );
        let alone: Value = serde_json::from_slice(&alone.stdout).unwrap();
        assert!(answer.get("error").is_none(), "{case}: {answer}");
        assert_eq!(numbers_of(answer.clone()), numbers_of(alone), "{case}");
    }
    let errors: Vec<&str> = answers[cases.len()..cases.len() + 2]
        .iter()
        .map(|a| a["error"].as_str().expect("an error"))
        .collect();
    assert!(errors[0].contains("case field `m`"), "{}", errors[0]);
    assert!(errors[1].starts_with("not valid JSON"), "{}", errors[1]);
    // The worker goes on after bad input: the first case again, the same numbers.
    assert_eq!(
        numbers_of(answers[cases.len() + 2].clone()),
        numbers_of(answers[0].clone())
    );
}

/// A line may wrap its case as `{"case": …, "progress": FILE}`: the time loop keeps FILE up to
/// date while it runs and removes it at its end, and the record is the bare case's. Another key
/// beside `case` is an error naming it.
#[test]
fn a_served_case_may_name_its_progress_file() {
    let dir = tempfile::tempdir().unwrap();
    let progress = dir.path().join("case.progress");
    let case = json!({"dim": 1, "n": 64, "m": 3, "problem": "bump", "t_end": 1e-3, "cfl": 0.5});
    let wrapped = json!({"case": case, "progress": progress.to_str().unwrap()});
    let input = format!("{wrapped}\n{case}\n{}\n", json!({"case": case, "every": 1}));
    let served = nlsolve(&["serve"], Some(&input), Stdio::piped());
    assert!(served.status.success());
    let answers: Vec<Value> = String::from_utf8(served.stdout)
        .unwrap()
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    assert_eq!(
        numbers_of(answers[0].clone()),
        numbers_of(answers[1].clone())
    );
    assert!(!progress.exists(), "the progress file outlived its loop");
    let error = answers[2]["error"].as_str().unwrap();
    assert!(
        error.contains("unknown field `every`") && error.contains("a line is a case, or"),
        "{error}"
    );
}

/// `serve --connect HOST:PORT` (how a worker on another node of an allocation answers): it
/// dials the pool, says the token of `$NLSOLVE_SERVE_TOKEN` first, then answers each case
/// line of the connection with the record it prints on standard output, and exits at the
/// connection's end. Without the token it refuses to start, naming the variable.
#[test]
fn a_worker_may_serve_over_a_connection_it_opens_with_its_token() {
    use std::io::{BufRead, BufReader, Write};
    let pool = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = pool.local_addr().unwrap().to_string();
    let case = json!({"dim": 1, "n": 64, "m": 3, "problem": "bump", "t_end": 1e-4, "cfl": 0.5});
    let worker = std::process::Command::new(env!("CARGO_BIN_EXE_nlsolve"))
        .args(["serve", "--connect", &address])
        .env("NLSOLVE_SERVE_TOKEN", "a1b2")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (mut stream, _) = pool.accept().unwrap();
    let mut lines = BufReader::new(stream.try_clone().unwrap()).lines();
    assert_eq!(lines.next().unwrap().unwrap(), "a1b2");
    stream.write_all(format!("{case}\n").as_bytes()).unwrap();
    let answer: Value = serde_json::from_str(&lines.next().unwrap().unwrap()).unwrap();
    stream.shutdown(std::net::Shutdown::Write).unwrap();
    let ended = worker.wait_with_output().unwrap();
    assert!(
        ended.status.success(),
        "{}",
        String::from_utf8_lossy(&ended.stderr)
    );
    assert!(ended.stdout.is_empty(), "it printed on standard output too");
    let alone = nlsolve(
        &["run", "--case", "-"],
        Some(&case.to_string()),
        Stdio::piped(),
    );
    let alone: Value = serde_json::from_slice(&alone.stdout).unwrap();
    assert_eq!(numbers_of(answer.clone()), numbers_of(alone));
    assert!(answer["wall_s"].as_f64().unwrap() >= answer["solve_s"].as_f64().unwrap());

    let untokened = std::process::Command::new(env!("CARGO_BIN_EXE_nlsolve"))
        .args(["serve", "--connect", &address])
        .env_remove("NLSOLVE_SERVE_TOKEN")
        .output()
        .unwrap();
    assert_eq!(untokened.status.code(), Some(2));
    let said = String::from_utf8_lossy(&untokened.stderr);
    assert!(said.contains("NLSOLVE_SERVE_TOKEN"), "{said}");
}
