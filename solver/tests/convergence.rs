//! Measured convergence orders of the manufactured solution (\[JD], Appendix A).

mod common;

use common::{case, observed_orders, scientific};
use serde_json::json;
use solver::run;

/// The discrete L² error √(eᵏ) at the final time; checks on the way that eᵏ is its square.
fn error_l2(case_json: serde_json::Value) -> f64 {
    let record = run(&case(case_json)).expect("case runs").record;
    let (ek, norm) = (record.error_l2.unwrap(), record.error_l2_norm.unwrap());
    assert!((norm * norm - ek).abs() <= 1e-14 * ek);
    norm
}

#[test]
fn discrete_source_error_is_first_order_in_dt() {
    // With b = ∂ₜw − L_h w the scheme reproduces w but for forward Euler's O(dt) error.
    for (dim, n, m) in [(1, 64, 4), (2, 32, 3)] {
        let errors: Vec<f64> = [4e-4, 2e-4, 1e-4, 5e-5]
            .iter()
            .map(|dt| {
                error_l2(
                    json!({"dim": dim, "n": n, "m": m, "kernel": "linear", "source": "discrete",
                                "t_end": 0.1, "dt": dt}),
                )
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "{dim}D discrete source: errors {}, orders in dt {orders:.3?}",
            scientific(&errors)
        );
        for order in orders {
            assert!(
                (order - 1.0).abs() <= 0.1,
                "{dim}D: order {order} in dt, expected 1 ± 0.1"
            );
        }
    }
}

#[test]
fn continuum_source_error_falls_with_h_at_fixed_eps() {
    // ε = 0.1 fixed, h → 0: the error measures the quadrature of the integral by the nodes
    // (time error kept below it with a small dt). The midpoint sum over the nodes in the ball is
    // second order for J = 1 − r, which vanishes continuously at r = 1, and first order for J = 1,
    // whose jump at r = 1 the lattice resolves only to O(h) in 1D. In 2D the jump makes the error
    // follow the lattice-point count of the disc of radius m (the Gauss circle problem), which
    // approaches πm² irregularly: the error still falls but with no steady order (observed
    // 0.9 then 0.3 for n = 20, 40, 80), so only the fall is asserted there.
    let paths = [
        (1, vec![40, 80, 160, 320], 1e-5, [1.8, 0.8]),
        (2, vec![20, 40, 80], 2e-5, [1.8, 0.0]),
    ];
    for (dim, sizes, dt, least_orders) in paths {
        for (kernel, least_order) in ["linear", "constant"].into_iter().zip(least_orders) {
            let errors: Vec<f64> = sizes
                .iter()
                .map(|n| {
                    error_l2(json!({"dim": dim, "n": n, "eps": 0.1, "kernel": kernel,
                                    "source": "continuum", "t_end": 0.05, "dt": dt}))
                })
                .collect();
            let orders = observed_orders(&errors);
            println!(
                "{dim}D {kernel}, ε = 0.1, n = {sizes:?}: errors {}, orders in h {orders:.3?}",
                scientific(&errors)
            );
            for order in orders {
                assert!(
                    order > least_order,
                    "{dim}D {kernel}: order {order} in h at fixed ε, expected > {least_order}"
                );
            }
        }
    }
}

#[test]
fn total_error_sums_the_squared_errors_of_every_step() {
    // e = Σₖ eᵏ: runs of 1, 2 and 3 steps with the same dt follow the same trajectory, so the total
    // of the 3-step run must equal the sum of their final eᵏ (e⁰ = 0 since u⁰ = w(0) exactly).
    let run_steps = |steps: usize| {
        let dt = 1e-4;
        let c = case(
            json!({"dim": 2, "n": 24, "m": 3, "kernel": "gaussian", "source": "continuum",
                            "t_end": dt * steps as f64, "dt": dt, "error_total": true}),
        );
        run(&c).unwrap().record
    };
    let records: Vec<_> = (1..=3).map(run_steps).collect();
    assert_eq!(
        records[0].error_total, records[0].error_l2,
        "one step: e = e⁰ + e¹ = e¹"
    );
    let sum: f64 = records.iter().map(|r| r.error_l2.unwrap()).sum();
    let total = records[2].error_total.unwrap();
    assert!(
        (total - sum).abs() <= 1e-14 * sum,
        "e = {total} vs Σ eᵏ = {sum}"
    );
}

#[test]
fn local_source_error_falls_as_eps_shrinks() {
    // With b = ∂ₜw − kΔw the error is the distance between the nonlocal scheme and the local limit.
    // Appendix B's O(ε²) holds where the ball misses the collar; within ε of ∂D the zero collar
    // (φ extended by 0, not by its odd continuation) makes L φ − kΔφ = O(k|∇φ|/ε) on a layer of
    // width ε. The error therefore falls like ε¹, not ε² (observed ≈ 0.85–0.9 at ε = 0.2 … 0.05).
    for (dim, sizes) in [(1, [40, 80, 160]), (2, [40, 80, 160])] {
        let errors: Vec<f64> = sizes
            .iter()
            .map(|n| {
                error_l2(
                    json!({"dim": dim, "n": n, "m": 8, "kernel": "linear", "source": "local",
                                "t_end": 0.02, "dt": 5e-6}),
                )
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "{dim}D local source, m = 8: errors {}, orders in ε {orders:.3?}",
            scientific(&errors)
        );
        for order in orders {
            assert!(
                order > 0.6,
                "{dim}D: order {order} in ε toward the local limit, expected ≈ 1"
            );
        }
    }
}
