//! The local diffusion methods of \[HPCSE] (explicit FD, Peaceman–Rachford ADI and particle
//! strength exchange) against the exact eigenmode: measured orders in h, dt and ε, the stability
//! bounds, ADI far beyond the explicit one, PSE's pair count, the c_tot(t) series and histogram
//! of the seed's setup, and thread-count independence.

mod common;

use common::{case, observed_orders, same_bits, scientific};
use serde_json::json;
use solver::output::record::Status;
use solver::{run, Outcome};
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

/// \[HPCSE]'s setup (D = 1, L = 2, c = 1 on the inner square): mass leaves through the zero
/// boundary, so the sampled c_tot(t) falls strictly over t ∈ [0, 0.5], from the square's mass.
#[test]
fn total_concentration_of_the_seed_setup_decreases() {
    for (method, n) in [("fd_explicit", 100), ("adi", 100), ("pse", 50)] {
        let outcome = solve(json!({
            "method": method, "problem": "square", "dim": 2, "n": n, "m": (method == "pse").then_some(2),
            "t_end": 0.5, "cfl": 0.9, "diagnostics_every": 0.05,
        }));
        let record = &outcome.record;
        let series = record.c_tot.as_ref().expect("the case asks for c_tot");
        println!("{method} c_tot {}", scientific(&series.c_tot));
        assert_eq!(series.time.len(), 11, "t = 0, 0.05, …, 0.5");
        assert_eq!(series.time[0], 0.0);
        for (j, t) in series.time.iter().enumerate() {
            // The first step at or past each output time t_j = 0.05 j.
            let t_j = 0.05 * j as f64;
            assert!(
                *t >= t_j - 1e-12 && *t < t_j + record.resolved.dt,
                "{method}: t = {t} for {t_j}"
            );
        }
        // The nodes inside |x|, |y| < L/4 cover the square of side 1 up to a cell per side.
        assert!(
            (series.c_tot[0] - 1.0).abs() < 4.0 * record.resolved.h,
            "{method}: c_tot(0) = {}",
            series.c_tot[0]
        );
        // PSE sums its particles in cell order, the record in lattice order.
        let (last, mass) = (series.c_tot[10], record.mass.expect("finite mass"));
        assert!(
            (last - mass).abs() <= 1e-14 * mass,
            "the last sample {last} is the final mass {mass}"
        );
        assert!(
            series.c_tot.windows(2).all(|w| w[1] < w[0]),
            "{method}: {:?}",
            series.c_tot
        );
    }
}

/// The histogram counts every value once, in the bin a direct count puts it in.
#[test]
fn histogram_of_the_final_field_counts_every_node() {
    let outcome = solve(json!({
        "method": "fd_explicit", "problem": "square", "dim": 2, "n": 90,
        "t_end": 0.05, "cfl": 0.9, "histogram_bins": 7, "threads": 2,
    }));
    let histogram = outcome
        .record
        .histogram
        .as_ref()
        .expect("the case asks for one");
    let field = &outcome.field;
    assert_eq!(
        histogram.lo,
        field.iter().copied().fold(f64::INFINITY, f64::min)
    );
    assert_eq!(
        histogram.hi,
        field.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    );
    let width = (histogram.hi - histogram.lo) / 7.0;
    let mut expected = vec![0u64; 7];
    for &v in field {
        expected[(((v - histogram.lo) / width) as usize).min(6)] += 1;
    }
    assert_eq!(histogram.counts, expected);
    assert_eq!(histogram.counts.iter().sum::<u64>(), 90 * 90);
}

/// PSE with h/ε = 1/2 fixed: the kernel's second moment error and forward Euler's error are
/// both O(ε²) (dt ∝ ε²), and the lattice sum of the Gaussian is exact to rounding.
#[test]
fn pse_converges_at_order_2_as_eps_and_h_fall_together() {
    for (dim, sizes) in [(1, vec![16, 32, 64, 128]), (2, vec![16, 32, 64])] {
        let errors: Vec<f64> = sizes
            .iter()
            .map(|&n| {
                l2_error(&solve(json!({
                    "method": "pse", "problem": "eigenmode", "dim": dim, "n": n, "m": 2,
                    "t_end": 0.1, "cfl": 0.2,
                })))
            })
            .collect();
        let orders = observed_orders(&errors);
        println!(
            "pse {dim}D h/eps = 0.5 errors {} orders {orders:.3?}",
            scientific(&errors)
        );
        assert!(
            orders.iter().all(|&p| (1.9..2.1).contains(&p)),
            "{dim}D orders {orders:?}"
        );
    }
}

/// At dt = ε²/(4D) a forward Euler step of PSE is the convolution with the heat kernel of that
/// time step (the Gaussian's symbol is 4D/ε² (e^{−k²ε²/4} − 1)), so the eigenmode decays
/// exactly: a check of the kernel's normalisation to rounding.
#[test]
fn pse_at_a_quarter_eps_squared_steps_the_heat_kernel_exactly() {
    for dim in [1, 2] {
        let outcome = solve(json!({
            "method": "pse", "problem": "eigenmode", "dim": dim, "n": 40, "m": 2,
            "t_end": 0.1, "dt": 0.1f64.powi(2) / 4.0, // ε = m·h = 2 · 2/40
        }));
        let error = l2_error(&outcome);
        println!("pse {dim}D at dt = eps^2/4: {error:.3e}");
        assert!(error < 1e-13, "{dim}D: {error:e}");
    }
}

/// Doubling n per side at fixed ε/h quadruples N and the pairs visited (not 16×, as all pairs
/// would); the pairs within the cutoff are about π r_c²/(2h²) per particle.
#[test]
fn pse_pair_count_grows_linearly_with_the_particles() {
    let counts: Vec<(usize, usize, usize)> = [64, 128, 256]
        .iter()
        .map(|&n| {
            let record = solve(json!({
                "method": "pse", "problem": "square", "dim": 2, "n": n, "m": 2,
                "t_end": 1e-9, "dt": 1e-9,
            }))
            .record;
            let visits = record.resolved.pair_visits.expect("pse counts its pairs");
            (record.resolved.nodes, visits, record.resolved.bonds)
        })
        .collect();
    println!("pse (particles, pairs visited, pairs within cutoff): {counts:?}");
    let half_disc = PI * 16.0 * std::f64::consts::LN_10 * 4.0 / 2.0; // π r_c²/(2h²), r_c² = 4h²·16 ln 10
    for window in counts.windows(2) {
        let ((n0, v0, _), (n1, v1, _)) = (window[0], window[1]);
        assert_eq!(n1, 4 * n0);
        let growth = v1 as f64 / v0 as f64;
        assert!(
            (3.0..4.5).contains(&growth),
            "visits grew {growth}× for 4× particles"
        );
    }
    for &(particles, visits, within) in &counts {
        assert!(within < visits);
        let per_particle = within as f64 / particles as f64;
        assert!(
            (0.9 * half_disc..1.6 * half_disc).contains(&per_particle),
            "{per_particle} pairs per particle, half disc {half_disc}"
        );
    }
}

/// PSE's forward Euler bound 2/λ_max (the checkerboard's rate) is sharp: just below it the run
/// stays bounded, just above it the seed's setup diverges.
#[test]
fn pse_is_stable_up_to_its_bound_and_diverges_beyond() {
    let status = |cfl: f64| {
        solve(json!({
            "method": "pse", "problem": "square", "dim": 2, "n": 40, "m": 2,
            "t_end": 3.0, "cfl": cfl, "allow_unstable": true,
        }))
        .record
        .status
    };
    assert_eq!(status(0.99), Status::Ok);
    assert_eq!(status(1.02), Status::Diverged);
}

#[test]
fn cases_name_the_field_at_fault() {
    let field = |fields: serde_json::Value| {
        solver::ValidCase::from_json(fields)
            .map(|_| ())
            .expect_err("refused")
            .field
    };
    let base = || json!({"problem": "square", "dim": 2, "n": 32, "t_end": 0.1, "cfl": 0.5});
    let with = |extra: serde_json::Value| {
        let mut fields = base();
        fields
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        fields
    };
    assert_eq!(field(with(json!({"method": "pse"}))), "eps");
    assert_eq!(field(with(json!({"method": "pse", "eps": 1.5}))), "eps");
    assert_eq!(
        field(with(json!({"method": "pse", "m": 2, "eps": 0.1}))),
        "eps"
    );
    assert_eq!(field(with(json!({"method": "adi", "m": 2}))), "m");
    assert_eq!(
        field(with(json!({"method": "adi", "histogram_bins": 0}))),
        "histogram_bins"
    );
    assert_eq!(
        field(with(json!({"method": "adi", "diagnostics_every": -1.0}))),
        "diagnostics_every"
    );
    // A kernel narrower than the particle spacing is refused before its cell lists are sized.
    assert_eq!(field(with(json!({"method": "pse", "eps": 0.001}))), "eps");
}

#[test]
fn one_and_two_threads_give_identical_fields() {
    for method in ["fd_explicit", "adi", "pse"] {
        for dim in [1, 2] {
            let fields: Vec<Vec<f64>> = [1, 2]
                .iter()
                .map(|&threads| {
                    solve(json!({
                        "method": method, "problem": "square", "dim": dim, "n": 70,
                        "m": (method == "pse").then_some(2),
                        "t_end": 0.01, "cfl": 0.9, "threads": threads,
                    }))
                    .field
                })
                .collect();
            assert!(same_bits(&fields[0], &fields[1]), "{method} {dim}D");
        }
    }
}
