//! Cases that used to give a record of values never measured, or a panic, and are now refused
//! with a sentence naming the field: an absurd diffusivity, a patch test with no interior node,
//! a tolerance below double precision, an overlap too thin for its controls, and outputs whose
//! size the case sets without bound.

use serde_json::{json, Value};
use solver::case::{CaseError, ValidCase};

/// The refusal of `fields`, by validation (what `nlsolve check` also applies) or by the run.
fn refusal(fields: Value) -> CaseError {
    match ValidCase::from_json(fields.clone()) {
        Err(refusal) => refusal,
        Ok(case) => match solver::run(&case) {
            Err(refusal) => refusal,
            Ok(outcome) => panic!(
                "{fields} ran, status {:?}: {}",
                outcome.record.status, outcome.record.message
            ),
        },
    }
}

fn assert_refused(fields: Value, field: &str) -> CaseError {
    let refusal = refusal(fields.clone());
    assert_eq!(refusal.field, field, "{fields}: {refusal}");
    refusal
}

/// Every method that takes a diffusivity, with `k`.
fn with_diffusivity(k: f64) -> Vec<Value> {
    vec![
        json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "diffusivity": k}),
        json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "dt": 1e-4, "diffusivity": k,
               "integrator": "backward_euler"}),
        json!({"method": "fd_explicit", "problem": "eigenmode", "dim": 2, "n": 16,
               "t_end": 0.01, "cfl": 0.5, "diffusivity": k}),
        json!({"method": "pse", "problem": "eigenmode", "dim": 1, "n": 16, "m": 2,
               "t_end": 0.01, "cfl": 0.5, "diffusivity": k}),
        json!({"method": "steady_cg", "dim": 2, "n": 16, "m": 2, "diffusivity": k}),
        json!({"method": "patch_test", "dim": 1, "n": 32, "eps": 0.1, "diffusivity": k}),
        json!({"method": "coupled_1d", "dim": 1, "n": 16, "eps": 0.065, "diffusivity": k}),
    ]
}

/// k = 1e308 was stored `ok` with error_max 0 and null norms (its weights overflow to a field of
/// NaN, which the divergence check let through); k = 1e300 was refused as a `t_end` problem.
#[test]
fn an_absurd_diffusivity_is_refused_naming_it() {
    for k in [1e308, 1e300, 1e101, 1e-101, 1e-320] {
        for fields in with_diffusivity(k) {
            assert_refused(fields, "diffusivity");
        }
    }
    // Within the range, a diffusivity whose stable step needs more steps than the limit is
    // still the field named, not the final time.
    let large = json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "diffusivity": 1e50});
    assert_refused(large, "diffusivity");
    for fields in with_diffusivity(1.0) {
        assert!(
            ValidCase::from_json(fields.clone()).is_ok(),
            "{fields}: {:?}",
            ValidCase::from_json(fields.clone())
        );
    }
}

/// A horizon so large that no node of D lies farther than it from both ends reported
/// `ghost_force` 0 (a maximum over no node).
#[test]
fn a_patch_test_with_no_interior_node_is_refused_naming_the_horizon() {
    let patch = |extra: Value| {
        let mut fields = json!({"method": "patch_test", "dim": 1, "n": 64});
        fields
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        fields
    };
    assert_refused(patch(json!({"eps": 0.5})), "eps");
    assert_refused(patch(json!({"eps": 0.495})), "eps");
    assert_refused(patch(json!({"m": 32})), "m");
    assert_refused(patch(json!({"n": 65, "eps": 0.5})), "eps");
    assert_refused(
        patch(json!({"horizon_profile": {"kind": "linear", "left": 0.1, "right": 0.5}})),
        "horizon_profile",
    );
    // Just below 1/2 − h/2 the middle nodes remain, and their ghost force is measured.
    let case = ValidCase::from_json(patch(json!({"eps": 0.49}))).unwrap();
    let record = solver::run(&case).unwrap().record;
    let ghost_force = record.patch.expect("a patch record").ghost_force;
    assert!(
        ghost_force.is_finite() && ghost_force < 1e-8,
        "{ghost_force:e}"
    );
}

/// `crank_nicolson` and `steady_cg` with an rtol below what double precision reaches ran to
/// their iteration cap and were labelled `diverged`.
#[test]
fn an_rtol_below_double_precision_is_refused_with_the_bound() {
    let cases = |rtol: f64| {
        [
            json!({"method": "steady_cg", "dim": 2, "n": 16, "m": 2, "rtol": rtol}),
            json!({"method": "feti", "dim": 2, "n": 16, "m": 2, "subdomains": 2, "rtol": rtol}),
            json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.01, "dt": 1e-3,
                   "integrator": "crank_nicolson", "rtol": rtol}),
        ]
    };
    for rtol in [1e-15, 2.2e-16, 1e-17, 1e-300, 0.0, -1e-6] {
        for fields in cases(rtol) {
            let refusal = assert_refused(fields, "rtol");
            if rtol > 0.0 {
                assert!(refusal.message.contains("1e-14"), "{refusal}");
            }
        }
    }
    for fields in cases(1e-14) {
        assert!(ValidCase::from_json(fields.clone()).is_ok(), "{fields}");
    }
}

/// `coupled_1d` with an overlap thinner than an element panicked in faer's least squares
/// (fewer Gauss points than controls).
#[test]
fn a_coupled_overlap_too_thin_for_its_controls_is_refused() {
    for (n, a) in [(64, 0.99), (8, 0.95), (128, 0.995)] {
        let fields = json!({
            "method": "coupled_1d", "dim": 1, "n": n, "eps": 0.065, "local_domain": [a, 1.75]
        });
        assert_refused(fields, "local_domain");
    }
    // An overlap of two elements runs.
    let case = ValidCase::from_json(json!({
        "method": "coupled_1d", "dim": 1, "n": 64, "eps": 0.065, "local_domain": [0.96, 1.75]
    }))
    .unwrap();
    assert!(solver::run(&case).is_ok());
}

/// `histogram_bins: 4e9` allocated 32 GB; a c_tot(t) interval far below dt sampled every step.
#[test]
fn outputs_sized_by_the_case_are_capped() {
    let base = |extra: Value| {
        let mut fields = json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5});
        fields
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        fields
    };
    for bins in [4_000_000_000u64, 65_537] {
        assert_refused(base(json!({"histogram_bins": bins})), "histogram_bins");
    }
    assert!(ValidCase::from_json(base(json!({"histogram_bins": 65_536}))).is_ok());
    assert_refused(
        base(json!({"diagnostics_every": 1e-9})),
        "diagnostics_every",
    );
    assert!(ValidCase::from_json(base(json!({"diagnostics_every": 1e-6}))).is_ok());
    // The coupled problem's set-up: n = 10⁶ at ε = 0.065 would take days.
    assert_refused(
        json!({"method": "coupled_1d", "dim": 1, "n": 1_000_000, "eps": 0.065}),
        "n",
    );
}

/// A build without the `mpi` feature (no Open MPI, no METIS) refuses a case over several ranks
/// when it is checked, saying how to build with MPI; the block partition's report still works.
#[cfg(not(feature = "mpi"))]
#[test]
fn a_build_without_mpi_refuses_ranks_saying_how_to_build_with_it() {
    let refusal = assert_refused(
        json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "ranks": 2}),
        "ranks",
    );
    assert!(refusal.message.contains("built without it"), "{refusal}");
    assert!(
        refusal.message.contains("cargo build --release"),
        "{refusal}"
    );
    let case = solver::Case::parse(json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5,
        "ranks": 4}))
    .unwrap();
    assert!(solver::partition_report(&case).is_ok());
    let graph = solver::Case::parse(json!({"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5,
        "ranks": 4, "partition": "graph"}))
    .unwrap();
    let refusal = solver::partition_report(&graph).unwrap_err();
    assert_eq!(refusal.field, "partition", "{refusal}");
}
