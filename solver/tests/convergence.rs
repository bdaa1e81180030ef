//! Measured convergence orders of the manufactured solution (seed 000, Appendix A).

mod common;

use common::{case, observed_orders, scientific};
use serde_json::json;
use solver::run::run;

fn error_l2(case_json: serde_json::Value) -> f64 {
    let record = run(&case(case_json)).expect("case runs").record;
    record.error_l2.expect("manufactured problem has an error")
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
