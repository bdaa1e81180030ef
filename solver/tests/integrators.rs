//! The time integrators of the nonlocal method: their orders in dt, measured with the discrete
//! source (whose semi-discrete solution cos(2πt)φ is exact, so the error is the time error
//! alone); thread independence bit for bit; the implicit solves' iteration counts, which the
//! sine-transform preconditioner keeps small whatever n; and the refusals.

mod common;

use common::{case, observed_orders, same_bits, scientific};
use serde_json::json;
use solver::run;

/// The final-time L2 error of `integrator` at each time step of `dts` on a coarse grid (1D, n = 8,
/// ε = 1/4: dt_stable = 0.0133, so every explicit step below is stable and large enough to keep
/// RK4's error above round-off).
fn time_errors(integrator: &str, dts: &[f64]) -> Vec<f64> {
    dts.iter()
        .map(|&dt| {
            let outcome = run(&case(json!({
                "dim": 1, "n": 8, "m": 2, "source": "discrete", "t_end": 0.5, "dt": dt,
                "integrator": integrator,
            })))
            .expect("the case runs");
            outcome.record.error_l2_norm.expect("a manufactured error")
        })
        .collect()
}

#[test]
fn each_integrator_converges_at_its_order_in_dt() {
    let dts = [0.0025, 0.00125, 0.000625];
    for (integrator, order) in [
        ("forward_euler", 1.0),
        ("heun", 2.0),
        ("rk4", 4.0),
        ("backward_euler", 1.0),
        ("crank_nicolson", 2.0),
    ] {
        let errors = time_errors(integrator, &dts);
        let orders = observed_orders(&errors);
        assert!(
            orders.iter().all(|p| (p - order).abs() < 0.1),
            "{integrator}: errors {} give orders {orders:?}, expected {order}",
            scientific(&errors)
        );
    }
}

#[test]
fn every_integrator_gives_the_same_bits_on_any_thread_count() {
    for integrator in ["heun", "rk4", "backward_euler", "crank_nicolson"] {
        let fields: Vec<Vec<f64>> = [1, 3]
            .iter()
            .map(|&threads| {
                run(&case(json!({
                    "dim": 2, "n": 70, "m": 3, "kernel": "linear", "t_end": 0.01, "cfl": 0.9,
                    "integrator": integrator, "threads": threads,
                })))
                .expect("the case runs")
                .field
            })
            .collect();
        assert!(same_bits(&fields[0], &fields[1]), "{integrator}");
    }
}

/// At a step 100 times forward Euler's limit (five steps), preconditioned CG needs a handful of
/// iterations per step, and no more on a grid 16 times finer (ε = 4h in 1D and 2D), with either
/// sine transform (DST-I where n + 1 is 5-smooth, DST-II at n = 2^k).
#[test]
fn implicit_solves_take_a_few_iterations_whatever_n() {
    for (dim, sizes) in [(1, [255, 256, 1024, 4096]), (2, [31, 32, 64, 128])] {
        for integrator in ["backward_euler", "crank_nicolson"] {
            let most: Vec<usize> = sizes
                .iter()
                .map(|&n| {
                    let fields = |t_end: f64, cfl: f64| {
                        json!({
                            "dim": dim, "n": n, "m": 4, "kernel": "linear", "source": "discrete",
                            "t_end": t_end, "cfl": cfl, "integrator": integrator,
                        })
                    };
                    let euler = run(&case(fields(1e-9, 1.0))).expect("the case runs");
                    let dt_stable = euler.record.resolved.dt_stable;
                    let outcome = run(&case(fields(500.0 * dt_stable, 100.0))).expect("runs");
                    let implicit = outcome.record.implicit;
                    assert_eq!(outcome.record.resolved.steps, 5);
                    assert_eq!(implicit.solves_unconverged, Some(0));
                    implicit.solve_iterations_max.expect("implicit solves")
                })
                .collect();
            assert!(
                most.iter().all(|&k| k <= 8),
                "{dim}D {integrator}: most iterations per step {most:?} for n = {sizes:?}"
            );
        }
    }
}

/// At 100 times forward Euler's stable step, 40 steps, the implicit schemes stay bounded where
/// forward Euler would blow up within a few steps: without a source, the bump's L2 norm never
/// grows (both are contractive in the 2-norm, −L_h being symmetric positive semi-definite), and
/// backward Euler's maximum never grows either ((I − dt L_h)⁻¹ is an M-matrix inverse with row
/// sums ≤ 1).
#[test]
fn implicit_schemes_stay_bounded_at_a_hundred_stable_steps() {
    let fields = |integrator: &str, t_end: f64, cfl: f64| {
        let mut fields = json!({
            "dim": 2, "n": 40, "m": 4, "kernel": "linear", "problem": "bump",
            "t_end": t_end, "cfl": cfl, "integrator": integrator,
        });
        if integrator != "forward_euler" {
            fields["rtol"] = json!(1e-12);
        }
        fields
    };
    let norm = |field: &[f64]| field.iter().map(|v| v * v).sum::<f64>().sqrt();
    let start = run(&case(fields("forward_euler", 1e-12, 1.0))).expect("runs");
    let dt_stable = start.record.resolved.dt_stable;
    let (norm_0, max_0) = (norm(&start.field), start.record.max_abs.unwrap());
    for integrator in ["backward_euler", "crank_nicolson"] {
        let outcome = run(&case(fields(integrator, 4000.0 * dt_stable, 100.0))).expect("runs");
        assert_eq!(outcome.record.resolved.steps, 40);
        assert_eq!(
            outcome.record.status,
            solver::output::record::Status::Ok,
            "{integrator}"
        );
        let (norm_t, max_t) = (norm(&outcome.field), outcome.record.max_abs.unwrap());
        assert!(
            norm_t <= norm_0,
            "{integrator}: L2 norm {norm_0} → {norm_t}"
        );
        assert!(norm_t > 0.0 && max_t.is_finite(), "{integrator}");
        if integrator == "backward_euler" {
            assert!(max_t <= max_0, "backward Euler: max {max_0} → {max_t}");
        }
    }
}

#[test]
fn integrators_are_refused_where_they_do_not_apply() {
    let refused = |fields: serde_json::Value| {
        let error = solver::ValidCase::from_json(fields).expect_err("refused");
        error.field
    };
    assert_eq!(
        refused(
            json!({"method": "adi", "dim": 1, "n": 16, "problem": "eigenmode",
                       "t_end": 0.1, "cfl": 1, "integrator": "rk4"})
        ),
        "integrator"
    );
    assert_eq!(
        refused(json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.1, "cfl": 1, "rtol": 1e-8})),
        "rtol"
    );
    // An explicit step beyond the integrator's own bound is refused when the stencil is known.
    let beyond = run(&case(
        json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.1, "cfl": 1.5,
                                   "integrator": "rk4"}),
    ));
    assert_eq!(beyond.err().map(|e| e.field), Some("cfl".to_string()));
    // The implicit ones take any step, and their solves' tolerance.
    let outcome = run(&case(
        json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.1, "cfl": 100,
                                   "integrator": "backward_euler", "rtol": 1e-9}),
    ))
    .expect("runs");
    assert_eq!(outcome.record.implicit.solve_rtol, Some(1e-9));
}
