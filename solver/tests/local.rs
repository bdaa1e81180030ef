//! The local diffusion methods of seed 004 (explicit FD and Peaceman–Rachford ADI) against the
//! exact eigenmode: measured orders in h and dt, the von Neumann bound, ADI far beyond it, the
//! decay of the total concentration of the seed's setup, and thread-count independence.

mod common;

use common::{case, observed_orders, scientific};
use serde_json::json;
use solver::record::Status;
use solver::run::{run, Outcome};
use std::f64::consts::PI;

fn solve(fields: serde_json::Value) -> Outcome {
    run(&case(fields)).expect("case runs")
}

fn l2_error(outcome: &Outcome) -> f64 {
    outcome.record.error_l2_norm.expect("eigenmode errors")
}

#[test]
fn explicit_fd_converges_at_order_2_in_h_with_dt_proportional_to_h_squared() {
    for dim in [1, 2] {
        let errors: Vec<f64> = [16, 32, 64, 128]
            .iter()
            .map(|&n| {
                l2_error(&solve(json!({
                    "method": "fd_explicit", "problem": "eigenmode", "dim": dim, "n": n,
                    "t_end": 0.1, "cfl": 0.5,
                })))
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "fd_explicit {dim}D errors {} orders {orders:.3?}",
            scientific(&errors)
        );
        assert!(
            orders.iter().all(|&p| (1.9..2.1).contains(&p)),
            "{dim}D orders {orders:?}"
        );
    }
}

#[test]
fn adi_converges_at_order_2_in_h() {
    for dim in [1, 2] {
        let errors: Vec<f64> = [16, 32, 64, 128]
            .iter()
            .map(|&n| {
                l2_error(&solve(json!({
                    "method": "adi", "problem": "eigenmode", "dim": dim, "n": n,
                    "t_end": 0.1, "dt": 1e-4,
                })))
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "adi {dim}D errors {} orders {orders:.3?}",
            scientific(&errors)
        );
        assert!(
            orders.iter().all(|&p| (1.9..2.1).contains(&p)),
            "{dim}D orders {orders:?}"
        );
    }
}

/// The grid's eigenmode φ = Π cos(π x_a / L) is an eigenvector of the discrete Laplacian with
/// λ_h = −(4/h²) sin²(πh/(2L)) per axis, so exp(d λ_h D t) φ is the exact solution of the
/// semi-discrete problem and the distance to it is the time error alone.
#[test]
fn adi_converges_at_order_2_in_dt() {
    let (n, length, t_end) = (48usize, 2.0, 0.2);
    let h = length / (n + 1) as f64;
    let lambda = -4.0 / (h * h) * (PI * h / (2.0 * length)).sin().powi(2);
    for dim in [1usize, 2] {
        let errors: Vec<f64> = [0.02, 0.01, 0.005, 0.0025]
            .iter()
            .map(|&dt| {
                let outcome = solve(json!({
                    "method": "adi", "problem": "eigenmode", "dim": dim, "n": n,
                    "t_end": t_end, "dt": dt,
                }));
                let decay = (dim as f64 * lambda * t_end).exp();
                let x = |i: usize| -length / 2.0 + (i + 1) as f64 * h;
                let squared: f64 = (0..outcome.field.len())
                    .map(|k| {
                        let phi: f64 = [k % n, k / n][..dim]
                            .iter()
                            .map(|&i| (PI * x(i) / length).cos())
                            .product();
                        (decay * phi - outcome.field[k]).powi(2)
                    })
                    .sum();
                (squared * h.powi(dim as i32)).sqrt()
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "adi {dim}D time errors {} orders {orders:.3?}",
            scientific(&errors)
        );
        assert!(
            orders.iter().all(|&p| (1.9..2.1).contains(&p)),
            "{dim}D orders {orders:?}"
        );
    }
}

#[test]
fn explicit_fd_beyond_its_bound_diverges_and_adi_at_100_times_it_does_not() {
    let beyond = solve(json!({
        "method": "fd_explicit", "problem": "square", "dim": 2, "n": 64,
        "t_end": 2.0, "cfl": 1.01, "allow_unstable": true,
    }));
    assert_eq!(
        beyond.record.status,
        Status::Diverged,
        "{}",
        beyond.record.message
    );
    assert!(beyond.record.diverged_step.is_some());
    let refused = run(&case(json!({
        "method": "fd_explicit", "problem": "square", "dim": 2, "n": 64, "t_end": 0.1, "cfl": 1.01,
    })));
    assert_eq!(refused.map(|_| ()).unwrap_err().field, "cfl");

    let adi = solve(json!({
        "method": "adi", "problem": "eigenmode", "dim": 2, "n": 64, "t_end": 0.5, "cfl": 100.0,
    }));
    assert_eq!(adi.record.status, Status::Ok);
    let explicit_error = l2_error(&solve(json!({
        "method": "fd_explicit", "problem": "eigenmode", "dim": 2, "n": 64, "t_end": 0.5, "cfl": 0.5,
    })));
    // At 100× the explicit step, ADI is still as accurate as the space discretization allows.
    println!(
        "adi at 100x: {:.3e}, explicit at 0.5x: {explicit_error:.3e}",
        l2_error(&adi)
    );
    assert!(l2_error(&adi) < 2.0 * explicit_error);
}

/// Seed 004's setup (D = 1, L = 2, c = 1 on the inner square): mass leaves through the zero
/// boundary, so c_tot(t) falls strictly over t ∈ [0, 0.5].
#[test]
fn total_concentration_of_the_seed_setup_decreases() {
    for method in ["fd_explicit", "adi"] {
        let masses: Vec<f64> = (1..=10)
            .map(|k| {
                let outcome = solve(json!({
                    "method": method, "problem": "square", "dim": 2, "n": 100,
                    "t_end": 0.05 * k as f64, "cfl": 0.9,
                }));
                outcome.record.mass.expect("finite mass")
            })
            .collect();
        println!("{method} c_tot {}", scientific(&masses));
        assert!(
            masses[0] < 1.0 && masses[0] > 0.9,
            "initial mass is 1 (the square of side 1)"
        );
        assert!(
            masses.windows(2).all(|w| w[1] < w[0]),
            "{method}: {masses:?}"
        );
    }
}

#[test]
fn one_and_two_threads_give_identical_fields() {
    for method in ["fd_explicit", "adi"] {
        for dim in [1, 2] {
            let fields: Vec<Vec<f64>> = [1, 2]
                .iter()
                .map(|&threads| {
                    solve(json!({
                        "method": method, "problem": "square", "dim": dim, "n": 70,
                        "t_end": 0.01, "cfl": 0.9, "threads": threads,
                    }))
                    .field
                })
                .collect();
            assert!(
                fields[0]
                    .iter()
                    .zip(&fields[1])
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{method} {dim}D"
            );
        }
    }
}
