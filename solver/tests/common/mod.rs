//! Helpers shared by the solver's tests.
#![allow(dead_code)]

pub mod spectrum;

use solver::case::Case;
use solver::ValidCase;
use std::io::Write;
use std::process::{Command, Output, Stdio};

/// Do two fields hold the same values bit for bit (and as many)?
pub fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// A deterministic pseudo-random field in [−1, 1) (seeded), so failures reproduce.
pub fn random_field(len: usize, seed: u64) -> Vec<f64> {
    let mut rng = fastrand::Rng::with_seed(seed);
    (0..len).map(|_| 2.0 * rng.f64() - 1.0).collect()
}

/// A case from JSON text, panicking with serde's message if the text is not a valid case.
pub fn case(json: serde_json::Value) -> Case {
    ValidCase::from_json(json)
        .map(ValidCase::into_case)
        .unwrap_or_else(|e| panic!("test case is invalid: {e}"))
}

/// Observed orders log2(e_i / e_{i+1}) of a sequence of errors under halving.
pub fn observed_orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// Errors printed as `[1.234e-3, …]`.
pub fn scientific(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|v| format!("{v:.3e}")).collect();
    format!("[{}]", items.join(", "))
}

/// `case` as validated, for the APIs that take only a validated case.
pub fn valid(case: Case) -> ValidCase {
    ValidCase::new(case).unwrap_or_else(|e| panic!("test case is invalid: {e}"))
}

/// Runs nlsolve with `args`, standard output `stdout` and, when given, `input` on standard
/// input (else none).
pub fn nlsolve(args: &[&str], input: Option<&str>, stdout: Stdio) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_nlsolve"))
        .args(args)
        .stdin(if input.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(stdout)
        .stderr(Stdio::piped())
        .spawn()
        .expect("nlsolve starts");
    if let Some(input) = input {
        let mut stdin = child.stdin.take().expect("a pipe");
        stdin
            .write_all(input.as_bytes())
            .expect("nlsolve reads its input");
    }
    child.wait_with_output().expect("nlsolve ends")
}

/// A record without what measures the run itself (its timings, peak memory and provenance) or
/// says it was resumed: the numbers of the case, which two runs of it share bit for bit.
pub fn numbers_of(mut record: serde_json::Value) -> serde_json::Value {
    let fields = record.as_object_mut().expect("a record is an object");
    for measured in schema::record::columns::TIMINGS.iter().chain(&[
        "peak_memory_bytes",
        "provenance",
        "resumed_from_step",
        "solve_s_segments",
        "feti_phases",
    ]) {
        fields.remove(*measured);
    }
    record
}
