//! Seed 003's optimization-based local–nonlocal coupling (`coupled_1d`), run through the
//! library as a user's case: the patch test to round-off, the seed's two examples at second
//! order and near the seed's own numbers, and the optimality system's first-order condition.

use solver::case::ValidCase;
use solver::methods;
use solver::output::record::Coupling;

/// The seed's ε (as printed in its tables).
const EPS: f64 = 0.065;

fn coupled(n: usize, field: &str, kernel: &str) -> Coupling {
    let case = ValidCase::from_json(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": n, "eps": EPS, "kernel": kernel, "patch": field
    }))
    .unwrap();
    let outcome = methods::run(&case).unwrap();
    outcome.record.coupling.expect("a coupled record")
}

#[test]
fn the_patch_test_is_exact_to_round_off() {
    for n in [8, 16, 32, 64, 128, 256] {
        let c = coupled(n, "linear", "inverse_distance");
        assert!(
            c.error_nonlocal < 1e-11,
            "n={n}: e(u_n) = {:e}",
            c.error_nonlocal
        );
        assert!(c.error_local < 1e-11, "n={n}: e(u_l) = {:e}", c.error_local);
        assert!(c.mismatch < 1e-12, "n={n}: mismatch {:e}", c.mismatch);
        assert!(
            c.control_error < 1e-9,
            "n={n}: controls off by {:e}",
            c.control_error
        );
    }
}

/// Observed orders over the last three refinements of the seed's h = 2⁻³ … 2⁻⁷, and the finest
/// errors against the seed's table (its e(u_n), e(u_l) at h = 2⁻⁷).
#[test]
fn the_seeds_examples_converge_at_second_order() {
    let seed_finest = [
        ("quadratic", 1.14e-5, 1.10e-5),
        ("quartic", 4.48e-5, 1.19e-4),
    ];
    for (field, seed_n, seed_l) in seed_finest {
        let runs: Vec<Coupling> = [32, 64, 128]
            .iter()
            .map(|&n| coupled(n, field, "inverse_distance"))
            .collect();
        for pair in runs.windows(2) {
            let order_n = (pair[0].error_nonlocal / pair[1].error_nonlocal).log2();
            let order_l = (pair[0].error_local / pair[1].error_local).log2();
            assert!(order_n >= 1.8, "{field}: order of e(u_n) {order_n}");
            assert!(order_l >= 1.8, "{field}: order of e(u_l) {order_l}");
        }
        let finest = &runs[2];
        let near = |ours: f64, seed: f64| (ours / seed - 1.0).abs() < 0.2;
        assert!(
            near(finest.error_nonlocal, seed_n),
            "{field}: e(u_n) {:e} vs the seed's {seed_n:e}",
            finest.error_nonlocal
        );
        assert!(
            near(finest.error_local, seed_l),
            "{field}: e(u_l) {:e} vs the seed's {seed_l:e}",
            finest.error_local
        );
        // The controls converge to the exact solution's values too.
        assert!(
            runs[2].control_error < 0.5 * runs[0].control_error,
            "{field}: controls {:e} → {:e}",
            runs[0].control_error,
            runs[2].control_error
        );
    }
}

/// Any of the project's kernels: the form is scaled by c of eq. 1.5, so L x² = 2k and the
/// quadratic example converges to the same solution.
#[test]
fn every_kernel_converges_at_second_order() {
    for kernel in ["constant", "linear", "gaussian"] {
        let (coarse, fine) = (
            coupled(32, "quartic", kernel),
            coupled(64, "quartic", kernel),
        );
        let order = (coarse.error_nonlocal / fine.error_nonlocal).log2();
        assert!(order >= 1.8, "{kernel}: order {order}");
    }
}

/// The first-order condition Ψᵀ W (d⁰ + Ψ θ) = 0 of the reduced problem, relative to its value
/// at θ = 0; the smoothness term that decides J's unresolved directions pulls it off zero by
/// far less than round-off of the fit.
#[test]
fn the_optimum_satisfies_the_first_order_conditions() {
    for field in ["linear", "quadratic", "quartic"] {
        for n in [8, 32, 128] {
            let c = coupled(n, field, "inverse_distance");
            let bound = if field == "linear" { 1e-13 } else { 1e-8 };
            assert!(
                c.gradient < bound,
                "{field} n={n}: ‖∇J‖/‖∇J(0)‖ = {:e}",
                c.gradient
            );
            assert!(
                c.hessian_condition.is_finite() && c.hessian_condition < 1e10,
                "{field} n={n}: cond {:e}",
                c.hessian_condition
            );
        }
    }
}
