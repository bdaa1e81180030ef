//! The memory estimate `nlsolve run` checks before it allocates holds within a factor 2 of the
//! peak resident memory each method then measures (VmHWM), from a trivial case (the process's
//! own base dominates) to ones of tens to hundreds of MiB. Each case runs as its own nlsolve
//! process, one after the other, so that no other run's memory counts in its peak.

mod common;

use common::nlsolve;
use serde_json::{json, Value};
use std::process::Stdio;

/// (peak, estimate) in bytes of one run of `case`.
fn peak_and_estimate(case: &Value) -> (f64, f64) {
    let input = case.to_string();
    let out = nlsolve(&["run", "--case", "-"], Some(&input), Stdio::piped());
    assert!(
        out.status.success(),
        "{case}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let record: Value = serde_json::from_slice(&out.stdout).expect("a record");
    let bytes = |field: &str| record[field].as_f64().unwrap_or_else(|| panic!("{field}"));
    (bytes("peak_memory_bytes"), bytes("memory_estimate_bytes"))
}

#[test]
fn the_estimate_is_within_a_factor_2_of_the_measured_peak_for_every_method() {
    let cases = [
        json!({"dim": 1, "n": 8, "m": 2, "t_end": 0.001, "cfl": 0.5}),
        json!({"dim": 2, "n": 1024, "m": 4, "t_end": 1e-6, "cfl": 0.5}),
        json!({"dim": 2, "n": 512, "m": 4, "t_end": 1e-4, "cfl": 20,
               "integrator": "crank_nicolson", "source": "discrete"}),
        json!({"method": "steady_cg", "dim": 2, "n": 1024, "m": 4}),
        json!({"method": "feti", "dim": 2, "n": 256, "m": 4, "subdomains": 2}),
        json!({"method": "feti", "dim": 2, "n": 256, "m": 4, "subdomains": 4,
               "preconditioner": "dirichlet_cg"}),
        json!({"method": "pse", "problem": "eigenmode", "dim": 2, "n": 512, "m": 3,
               "t_end": 1e-4, "cfl": 0.5}),
        json!({"method": "pse", "problem": "eigenmode", "dim": 1, "n": 100_000, "m": 3,
               "t_end": 1e-12, "dt": 1e-13}),
        json!({"method": "coupled_1d", "dim": 1, "n": 1024, "eps": 0.065}),
        json!({"method": "patch_test", "dim": 1, "n": 4000, "eps": 0.05}),
        json!({"method": "fd_explicit", "problem": "eigenmode", "dim": 2, "n": 1024,
               "t_end": 1e-6, "cfl": 0.5}),
    ];
    for case in &cases {
        let (peak, estimate) = peak_and_estimate(case);
        let ratio = peak / estimate;
        eprintln!(
            "{case}: peak {:.1} MiB, estimate {:.1} MiB, ratio {ratio:.2}",
            peak / 1048576.0,
            estimate / 1048576.0
        );
        assert!(
            (0.5..=2.0).contains(&ratio),
            "{case}: peak/estimate {ratio:.2}"
        );
    }
}
