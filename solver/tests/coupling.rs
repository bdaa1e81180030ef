//! \[LSSM]'s optimization-based local–nonlocal coupling (`coupled_1d`), run through the
//! library as a user's case: the patch test to round-off, the seed's two examples at second
//! order and near the seed's own numbers, and the optimality system's first-order condition.

use solver::case::ValidCase;
use solver::methods;
use solver::output::record::Coupling;

/// The seed's ε (as printed in its tables).
const EPS: f64 = 0.065;

fn coupled(n: usize, field: &str, kernel: &str) -> Coupling {
    coupled_by("optimization", n, field, kernel)
}

fn coupled_by(coupling: &str, n: usize, field: &str, kernel: &str) -> Coupling {
    let case = ValidCase::from_json(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": n, "eps": EPS, "kernel": kernel, "patch": field,
        "coupling": coupling
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
        assert!(
            c.mismatch.unwrap() < 1e-12,
            "n={n}: mismatch {:?}",
            c.mismatch
        );
        assert!(
            c.control_error.unwrap() < 1e-9,
            "n={n}: controls off by {:?}",
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
            runs[2].control_error.unwrap() < 0.5 * runs[0].control_error.unwrap(),
            "{field}: controls {:?} → {:?}",
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
                c.gradient.unwrap() < bound,
                "{field} n={n}: ‖∇J‖/‖∇J(0)‖ = {:?}",
                c.gradient
            );
            assert!(
                c.hessian_condition
                    .is_some_and(|h| h.is_finite() && h < 1e10),
                "{field} n={n}: cond {:?}",
                c.hessian_condition
            );
        }
    }
}

/// The seamless coupling (one model whose horizon shrinks to h over the overlap, x-centred):
/// exact at the nodes on linear and quadratic fields (its operator passes the patch tests for
/// any δ(x), so only the P1 interpolation's error h²/√30 per unit length is left for u = x²),
/// and second order on Example 2 on both parts, with no controls in its record.
#[test]
fn the_seamless_coupling_passes_the_patch_tests_and_converges_at_second_order() {
    for n in [8, 16, 32, 64, 128] {
        let linear = coupled_by("seamless", n, "linear", "inverse_distance");
        assert!(
            linear.error_nonlocal < 1e-12 && linear.error_local < 1e-12,
            "n={n}: {linear:?}"
        );
        let quadratic = coupled_by("seamless", n, "quadratic", "inverse_distance");
        let h = 1.0 / n as f64;
        let interpolation = h * h / 30f64.sqrt();
        for error in [quadratic.error_nonlocal, quadratic.error_local] {
            assert!(
                (error - interpolation).abs() < 1e-8 * interpolation,
                "n={n}: {error:e} against P1's {interpolation:e}"
            );
        }
        assert!(linear.mismatch.is_none() && linear.control_nodes.is_empty());
    }
    let errors: Vec<Coupling> = [32, 64, 128]
        .iter()
        .map(|&n| coupled_by("seamless", n, "quartic", "inverse_distance"))
        .collect();
    for (part, error) in [
        (
            "nonlocal",
            errors.iter().map(|c| c.error_nonlocal).collect::<Vec<_>>(),
        ),
        ("local", errors.iter().map(|c| c.error_local).collect()),
    ] {
        // Over h = 2⁻⁵ … 2⁻⁷; each halving at least 1.5 (ε/h = 2.1, 4.2, 8.3 changes the
        // lattice's ball).
        let overall = (error[0] / error[2]).log2() / 2.0;
        assert!(
            (1.8..2.2).contains(&overall),
            "{part}: order {overall} from {error:?}"
        );
        for pair in error.windows(2) {
            let order = (pair[0] / pair[1]).log2();
            assert!(order > 1.5, "{part}: order {order} from {error:?}");
        }
    }
}

/// The seamless coupling needs a whole number of cells on (0, b): a `local_domain` that is not
/// is refused naming it; so is a kernel that vanishes at r = 1 (its one-cell horizon would have
/// no bond), naming `kernel`; `coupling` on another method is refused naming `coupling`.
#[test]
fn the_seamless_coupling_refuses_a_domain_of_partial_cells() {
    let refused = ValidCase::from_json(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": 8, "eps": EPS, "coupling": "seamless",
        "local_domain": [0.75, 1.7]
    }))
    .expect_err("1.7 · 8 cells is not whole");
    assert_eq!(refused.field, "local_domain", "{refused}");
    assert!(refused.message.contains("whole"), "{refused}");
    let refused = ValidCase::from_json(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": 8, "eps": EPS, "coupling": "seamless",
        "kernel": "linear"
    }))
    .expect_err("J = 1 − r vanishes at the one-cell horizon");
    assert_eq!(refused.field, "kernel", "{refused}");
    let refused = ValidCase::from_json(serde_json::json!({
        "method": "nonlocal", "dim": 1, "n": 8, "m": 2, "t_end": 0.1, "coupling": "seamless"
    }))
    .expect_err("not a coupled case");
    assert_eq!(refused.field, "coupling", "{refused}");
}
