//! Forward Euler's stable step dt_stable = 2 / max σ (see `stability`): tested from both sides.

mod common;

use common::spectrum::{dense_ends, growth_of, real_stability_limit};
use common::{case, random_field};
use serde_json::json;
use solver::case::{Backend, Integrator, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::stability::{dt_stable, forward_euler_dt_stable, Symbol};
use solver::discretization::stencil::Stencil;
use solver::operator::{plan, LinearOperator};
use solver::output::record::Status;
use solver::run;

fn stencil(dim: usize, n: usize, m: usize, kernel: Kernel) -> Stencil {
    stencil_with(dim, n, m, kernel, Quadrature::Midpoint)
}

fn stencil_with(dim: usize, n: usize, m: usize, kernel: Kernel, quadrature: Quadrature) -> Stencil {
    let grid = Grid::new(dim, n);
    let horizon = Horizon::from_m(&grid, m);
    Stencil::new(grid, horizon, kernel, quadrature, 1.0)
}

fn l2_norm(u: &[f64]) -> f64 {
    u.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// The largest eigenvalue of −L_h on D by power iteration (−L_h is symmetric positive definite).
fn largest_eigenvalue(stencil: &Stencil) -> f64 {
    let grid = stencil.grid;
    let op = plan(Backend::Stencil, stencil);
    let mut v = random_field(grid.nodes(), 3);
    let mut w = vec![0.0; v.len()];
    let mut lambda = 0.0;
    for _ in 0..3000 {
        let norm = l2_norm(&v);
        v.iter_mut().for_each(|x| *x /= norm);
        op.apply_once(&v, &mut w);
        lambda = -v.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>();
        v.iter_mut().zip(&w).for_each(|(x, y)| *x = -y);
    }
    lambda
}

#[test]
fn symbol_maximum_bounds_the_spectrum_and_is_nearly_attained() {
    for (dim, n, m) in [(1, 200, 1), (1, 200, 5), (2, 48, 1), (2, 48, 3), (2, 64, 6)] {
        for (kernel, quadrature) in Kernel::ALL
            .into_iter()
            .flat_map(|k| Quadrature::ALL.map(|q| (k, q)))
        {
            let stencil = stencil_with(dim, n, m, kernel, quadrature);
            if stencil.total_weight == 0.0 {
                continue; // J = 1 − r with m = 1: every bond has r = 1; such cases are refused
            }
            let bound = Symbol::new(&stencil).maximum();
            let lambda = largest_eigenvalue(&stencil);
            assert!(
                lambda <= bound * (1.0 + 1e-9),
                "{dim}D m={m} {kernel:?} {quadrature:?}: λ_max {lambda} above the bound {bound}"
            );
            assert!(
                lambda >= 0.97 * bound,
                "{dim}D m={m} {kernel:?} {quadrature:?}: λ_max {lambda} far below the bound {bound}"
            );
        }
    }
}

#[test]
fn local_stencil_limit_is_the_classical_bound() {
    // m = 1, J = 1 in 1D: two neighbours of weight c h with c = 3/h³, so σ(π) = 4 c h = 12/h² and
    // dt_stable = h²/6 (the 3-point Laplacian's h²/2, scaled by the nonlocal constant).
    let s = stencil(1, 50, 1, Kernel::Constant);
    let h = 1.0 / 50.0;
    let dt = forward_euler_dt_stable(&s);
    assert!((dt - h * h / 6.0).abs() <= 1e-14 * dt, "dt_stable = {dt}");
}

fn stability_case(dim: usize, n: usize, m: usize, ratio: f64, steps: usize) -> serde_json::Value {
    let dt_stable = forward_euler_dt_stable(&stencil(dim, n, m, Kernel::Linear));
    let dt = ratio * dt_stable;
    json!({"dim": dim, "n": n, "m": m, "kernel": "linear", "problem": "bump",
           "t_end": dt * steps as f64, "dt": dt, "allow_unstable": ratio > 1.0})
}

/// The step's measured amplification crosses 1 where the symbol says: at 0.995 of each explicit
/// integrator's dt_stable every mode decays, at 1.005 one grows, for m = 1, 2, 4, 8 in 1D and
/// 2D. The grid's largest eigenvalue lies under the symbol's maximum by a gap that grows as
/// (m/n)² (at m = 8 in 1D: 1.3 % at n = 64, 0.2 % at n = 128), so n = 32m keeps it inside the
/// margin. A wrong stability interval (RK4's 2.785 taken as 2.95) fails here.
#[test]
fn the_measured_amplification_crosses_1_at_the_symbols_dt_stable() {
    for dim in [1, 2] {
        for m in [1, 2, 4, 8] {
            let n = (32 * m).max(64);
            let euler = forward_euler_dt_stable(&stencil(dim, n, m, Kernel::Constant));
            for integrator in [Integrator::ForwardEuler, Integrator::Heun, Integrator::Rk4] {
                let dt_stable = dt_stable(integrator, euler).expect("an explicit integrator");
                for ratio in [0.995, 1.005] {
                    let dt = ratio * dt_stable;
                    let record = run(&case(json!({"dim": dim, "n": n, "m": m,
                        "problem": "bump", "t_end": dt, "dt": dt, "integrator": integrator,
                        "allow_unstable": true, "amplification_steps": 400})))
                    .unwrap()
                    .record;
                    let amplification = record.amplification.expect("measured");
                    assert_eq!(
                        amplification > 1.0,
                        ratio > 1.0,
                        "{dim}D m = {m} {integrator:?} at {ratio} dt_stable: {amplification}"
                    );
                }
            }
        }
    }
}

/// The grid and particle methods of [HPCSE] measure their amplification too: explicit FD
/// crosses 1 at its classical dt_stable = h²/(2dD) and PSE at 2/λ_max of its lattice (within
/// 0.5 %), and ADI stays below 1 at 16 times the explicit step.
#[test]
fn the_grid_and_particle_methods_amplification_meets_the_classical_bound() {
    for dim in [1, 2] {
        for (method, cfl, unstable) in [
            ("fd_explicit", 0.995, false),
            ("fd_explicit", 1.005, true),
            ("pse", 0.995, false),
            ("pse", 1.005, true),
            ("adi", 16.0, false),
        ] {
            let mut fields = json!({"method": method, "dim": dim, "n": 64,
                "problem": "square", "t_end": 1e-7, "cfl": cfl, "allow_unstable": true,
                "amplification_steps": 400});
            if method == "pse" {
                // A particle has ~(2·3.4 m)^d neighbours: a coarser lattice keeps it quick.
                fields["m"] = json!(2);
                fields["n"] = json!(32);
            }
            let record = run(&case(fields)).unwrap().record;
            let amplification = record.amplification.expect("measured");
            assert_eq!(
                amplification > 1.0,
                unstable,
                "{dim}D {method} at {cfl}: {amplification}"
            );
        }
    }
}

/// The step's measured positivity against the theory's dt_positive: forward Euler keeps a unit
/// spike non-negative up to 1/|L_ii| exactly and no further (every kernel, m = 1, 2, 4, 8, 1D
/// and 2D); Crank–Nicolson's bound 2/|L_ii| is sufficient (non-negative at it, and at 0.995 of
/// it), and the step loses positivity at a large enough step; backward Euler never does.
#[test]
fn the_measured_positivity_meets_the_theorys_dt_positive() {
    let positivity = |dim: usize, n: usize, m: usize, kernel: Kernel, integrator, dt: f64| {
        let record = run(&case(json!({"dim": dim, "n": n, "m": m, "kernel": kernel,
            "problem": "bump", "t_end": dt, "dt": dt, "integrator": integrator,
            "allow_unstable": true, "amplification_steps": 2})))
        .unwrap()
        .record;
        let limit = record.resolved.dt_positive;
        (record.positivity.expect("measured"), limit)
    };
    for dim in [1, 2] {
        for m in [1, 2, 4, 8] {
            let n = (32 * m).max(64);
            for kernel in [Kernel::Constant, Kernel::Linear] {
                let stencil = stencil(dim, n, m, kernel);
                if stencil.total_weight == 0.0 {
                    continue; // J = 1 − r with m = 1: every bond has r = 1 (refused)
                }
                let euler = 1.0 / stencil.total_weight;
                let (below, limit) =
                    positivity(dim, n, m, kernel, Integrator::ForwardEuler, 0.999 * euler);
                assert_eq!(limit, Some(euler));
                let (above, _) =
                    positivity(dim, n, m, kernel, Integrator::ForwardEuler, 1.001 * euler);
                assert!(
                    below == 0.0 && above < 0.0,
                    "{dim}D m = {m} {kernel:?}: {below} {above}"
                );
                let crank = Integrator::CrankNicolson;
                let (at, limit) = positivity(dim, n, m, kernel, crank, 2.0 * euler);
                assert_eq!(limit, Some(2.0 * euler));
                let (far, _) = positivity(dim, n, m, kernel, crank, 50.0 * euler);
                assert!(
                    at == 0.0 && far < 0.0,
                    "{dim}D m = {m} {kernel:?}: CN {at} {far}"
                );
                let backward = Integrator::BackwardEuler;
                let (never, limit) = positivity(dim, n, m, kernel, backward, 50.0 * euler);
                assert!(
                    never >= 0.0 && limit.is_none(),
                    "{dim}D m = {m}: BE {never}"
                );
            }
        }
    }
}

/// A varying horizon has no symbol: its explicit steps are predicted by L_h's computed spectrum
/// (`dt_stable_spectrum`; its `dt_stable` is Gershgorin's floor), forward Euler's positivity by
/// its largest |L_ii|, and the measurements cross at both (the standard form, 1D and 2D).
#[test]
fn a_varying_horizons_measurements_cross_at_its_spectrum_and_its_diagonal() {
    for (dim, n, left, right) in [(1, 200, 0.02, 0.1), (2, 32, 0.07, 0.15)] {
        for integrator in [Integrator::ForwardEuler, Integrator::Rk4] {
            let record = |dt: f64| {
                run(&case(
                    json!({"dim": dim, "n": n, "problem": "bump", "t_end": dt, "dt": dt,
                    "horizon_profile": {"kind": "linear", "left": left, "right": right},
                    "integrator": integrator, "allow_unstable": true,
                    "amplification_steps": 400}),
                ))
                .unwrap()
                .record
            };
            let first = record(1e-9);
            let stable = first
                .resolved
                .dt_stable_spectrum
                .expect("a computed spectrum");
            assert!(
                stable > first.resolved.dt_stable,
                "the spectrum's step is above the floor"
            );
            for ratio in [0.995, 1.005] {
                let amplification = record(ratio * stable).amplification.unwrap();
                assert_eq!(
                    amplification > 1.0,
                    ratio > 1.0,
                    "{dim}D {integrator:?} {ratio}: {amplification}"
                );
            }
            if integrator == Integrator::ForwardEuler {
                let positive = first.resolved.dt_positive.expect("non-negative weights");
                let below = record(0.999 * positive).positivity.unwrap();
                let above = record(1.001 * positive).positivity.unwrap();
                assert!(below == 0.0 && above < 0.0, "{dim}D: {below} {above}");
            }
        }
    }
}

#[test]
fn just_below_dt_stable_stays_bounded_for_10000_steps() {
    for (dim, n, m) in [(1, 256, 4), (2, 48, 2)] {
        let c = case(stability_case(dim, n, m, 0.99, 10_000));
        let outcome = run(&c).unwrap();
        assert_eq!(outcome.record.status, Status::Ok);
        assert_eq!(outcome.record.steps_done, 10_000);
        // |1 − dt λ| ≤ 1 for every eigenvalue: the l² norm cannot grow.
        let grid = Grid::new(dim, n);
        let u0 = solver::problem::sample(&grid, solver::problem::bump);
        assert!(
            l2_norm(&outcome.field) <= l2_norm(&u0),
            "{dim}D: the l² norm grew"
        );
    }
}

#[test]
fn just_above_dt_stable_diverges_and_says_where() {
    for (dim, n, m) in [(1, 256, 4), (2, 48, 2)] {
        let record = run(&case(stability_case(dim, n, m, 1.05, 10_000)))
            .unwrap()
            .record;
        assert_eq!(record.status, Status::Diverged, "{dim}D: {record:?}");
        let step = record.diverged_step.expect("diverged step");
        assert!(step < 10_000 && step == record.steps_done);
        assert!((record.diverged_time.unwrap() - step as f64 * record.resolved.dt).abs() < 1e-12);
        assert!(
            record.message.contains(&format!("step {step}")),
            "{}",
            record.message
        );
        assert!(
            record.error_l2.is_none(),
            "no error is reported for a blown-up run"
        );
    }
}

/// A run above dt_stable that ends before its unstable mode passes the divergence bound is `ok`
/// by the bound, but its `growth` (decades past the problem's scale) tells, and its message says
/// so; below dt_stable the bump only decays.
#[test]
fn a_run_that_grew_without_diverging_says_so() {
    let bump = |cfl: f64| {
        json!({"dim": 1, "n": 64, "m": 4, "problem": "bump", "t_end": 0.3, "cfl": cfl,
               "allow_unstable": true})
    };
    let grown = run(&case(bump(1.05))).unwrap().record;
    assert_eq!(grown.status, Status::Ok, "{grown:?}");
    let growth = grown
        .growth
        .expect("a time-dependent run measures its growth");
    assert!((2.0..6.0).contains(&growth), "{growth}");
    assert!(
        grown.message.contains("likely unstable"),
        "{}",
        grown.message
    );
    let decayed = run(&case(bump(0.99))).unwrap().record;
    assert!(
        decayed.growth.unwrap() <= 0.0 && decayed.message.is_empty(),
        "{decayed:?}"
    );
}

#[test]
fn above_dt_stable_is_refused_unless_allowed() {
    let mut refused = stability_case(2, 32, 2, 1.05, 10);
    refused["allow_unstable"] = json!(false);
    let err = run(&case(refused)).err().expect("refused");
    assert_eq!(err.field, "dt");
    assert!(
        err.message.contains("dt_stable") && err.message.contains("allow_unstable"),
        "{err}"
    );

    let by_cfl = case(json!({"dim": 1, "n": 32, "m": 2, "t_end": 0.01, "cfl": 1.2}));
    assert_eq!(run(&by_cfl).err().expect("refused").field, "cfl");
}

#[test]
fn a_vanishing_operator_is_refused() {
    let c = case(json!({"dim": 2, "n": 16, "m": 1, "kernel": "linear", "t_end": 0.01, "cfl": 0.5}));
    let err = run(&c).err().expect("refused");
    assert_eq!(err.field, "m");
    assert!(err.message.contains("m ≥ 2"), "{err}");
}

/// Against the dense spectrum, for forward Euler, Heun and RK4 × constant and gaussian kernels ×
/// 1D (n = 128, m = 4) and 2D (n = 40, m = 3), zero collar, midpoint quadrature: the step's
/// amplification is on the right side of 1 a millionth either side of the exact boundary
/// x/|λ_min| (which the rough field of 400 steps misplaced by up to 0.14 %), and its interval
/// holds the exact spectral radius max |R(dt·λ)| over the ends in at least 95 % of the probes
/// around the boundary (here: all of them).
#[test]
fn the_amplification_meets_the_dense_spectrums_boundary_on_both_sides() {
    let (mut probes, mut covered, mut widest) = (0, 0, 0.0_f64);
    for (dim, n, m) in [(1, 128, 4), (2, 40, 3)] {
        for kernel in [Kernel::Constant, Kernel::Gaussian] {
            let (lowest, highest) = dense_ends(&stencil(dim, n, m, kernel));
            for integrator in [Integrator::ForwardEuler, Integrator::Heun, Integrator::Rk4] {
                let exact = real_stability_limit(integrator) / lowest.abs();
                let measure = |ratio: f64| {
                    let dt = ratio * exact;
                    let record = run(&case(json!({"dim": dim, "n": n, "m": m,
                        "kernel": kernel, "quadrature": "midpoint", "problem": "bump",
                        "t_end": dt, "dt": dt, "integrator": integrator,
                        "allow_unstable": true, "amplification_steps": 400})))
                    .unwrap()
                    .record;
                    let radius =
                        growth_of(integrator, dt * lowest).max(growth_of(integrator, dt * highest));
                    (record, radius)
                };
                let label = format!("{dim}D {kernel:?} {integrator:?}");
                for (ratio, unstable) in [(1.0 - 1e-6, false), (1.0 + 1e-6, true)] {
                    let (record, _) = measure(ratio);
                    let amplification = record.amplification.unwrap();
                    assert_eq!(amplification > 1.0, unstable, "{label} at {ratio}");
                }
                for k in -5..=5 {
                    let (record, radius) = measure(1.0 + k as f64 * 2e-4);
                    let (low, high) = (record.amplification_low, record.amplification_high);
                    let (low, high) = (low.unwrap(), high.unwrap());
                    probes += 1;
                    covered += usize::from(
                        low <= radius * (1.0 + 1e-13) && radius <= high * (1.0 + 1e-13),
                    );
                    widest = widest.max(high - low);
                    assert!(
                        record.amplification_applications.unwrap() <= 1600,
                        "{label}"
                    );
                }
            }
        }
    }
    assert!(
        covered * 100 >= 95 * probes,
        "{covered} of {probes} probes covered"
    );
    // 400 steps' applications (forward Euler's 400 the fewest) leave the 2D intervals ~2e-7 wide.
    assert!(widest < 1e-6, "an interval {widest} wide");
}
