//! Stability measured exactly, as a user's boundary search runs it: the searched limits against
//! the exact boundaries of the finite operator (its dense spectrum, computed here), on both
//! sides; searches that end honestly (a spent budget keeps its bracket, a tolerance no double
//! resolves is refused, a huge budget still ends).

#[path = "support/parquet.rs"]
mod parquet;
#[path = "../solver/tests/common/spectrum.rs"]
mod spectrum;

use nonlocal_study::{text, Scratch};
use parquet::{floats, read_parquet};
use serde_json::json;
use solver::case::{Integrator, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::stability::{dt_stable, forward_euler_dt_stable};
use solver::discretization::stencil::Stencil;
use spectrum::{dense_ends, real_stability_limit};

/// For forward Euler, Heun and RK4 × constant and gaussian kernels × 1D (n = 128, m = 4) and 2D
/// (n = 40, m = 3), zero collar, midpoint quadrature: the search along cfl at rtol 1e-5 ends with
/// a bracket that holds the exact boundary x/|λ_min| of the dense spectrum and lies within 1e-5
/// of it on both sides.
#[test]
fn the_searched_limits_hold_the_dense_spectrums_boundaries() {
    let study = json!({
        "name": "exact",
        "base": {"problem": "bump", "t_end": 1e-6, "allow_unstable": true,
                 "amplification_steps": 400, "quadrature": "midpoint"},
        "sweep": [
            {"product": {"integrator": ["forward_euler", "heun", "rk4"],
                         "kernel": ["constant", "gaussian"]}},
            {"zip": {"dim": [1, 2], "n": [128, 40], "m": [4, 3]}}
        ],
        "boundary": {"field": "cfl", "bracket": [0.5, 2], "flips": "amplification > 1",
                     "rtol": 1e-5}
    });
    let scratch = Scratch::new("exact", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = read_parquet(&scratch.dir.join("results/exact/exact-boundaries.parquet"));
    let (low, high) = (floats(&table, "boundary_lo"), floats(&table, "boundary_hi"));
    let mut row = 0;
    let mut largest_gap = 0.0_f64;
    for integrator in [Integrator::ForwardEuler, Integrator::Heun, Integrator::Rk4] {
        for kernel in [Kernel::Constant, Kernel::Gaussian] {
            for (dim, n, m) in [(1, 128, 4), (2, 40, 3)] {
                let grid = Grid::new(dim, n);
                let stencil = Stencil::new(
                    grid,
                    Horizon::from_m(&grid, m),
                    kernel,
                    Quadrature::Midpoint,
                    1.0,
                );
                let (lowest, _) = dense_ends(&stencil);
                let exact_dt = real_stability_limit(integrator) / lowest.abs();
                let symbol = dt_stable(integrator, forward_euler_dt_stable(&stencil)).unwrap();
                let exact = exact_dt / symbol;
                let (below, above) = (low[row], high[row]);
                let label = format!("{integrator:?} {kernel:?} {dim}D: [{below}, {above}] {exact}");
                assert!(below <= exact && exact <= above, "{label}");
                assert!(above / below - 1.0 <= 1e-5 * (1.0 + 1e-9), "{label}");
                largest_gap = largest_gap
                    .max(exact / below - 1.0)
                    .max(above / exact - 1.0);
                row += 1;
            }
        }
    }
    assert_eq!(row, low.len());
    eprintln!("largest gap between a bracket's end and the exact boundary: {largest_gap:e}");
}

/// A search stopped by its `max_probes` keeps its bracket in the table and its figure is drawn;
/// a tolerance below what a double resolves is refused at plan, naming the field; a huge budget
/// at the finest tolerance still ends, at the tolerance or at the field's resolution.
#[test]
fn searches_end_honestly_with_their_brackets() {
    let search = |name: &str, rtol: f64, max_probes: u64| {
        json!({
            "name": name,
            "base": {"dim": 1, "n": 64, "problem": "bump", "t_end": 1e-6,
                     "allow_unstable": true, "amplification_steps": 400},
            "sweep": [{"product": {"integrator": ["forward_euler", "rk4"], "m": [1, 2]}}],
            "boundary": {"field": "cfl", "bracket": [0.5, 2], "flips": "amplification > 1",
                         "rtol": rtol, "max_probes": max_probes},
            "figures": [{"name": "limits", "kind": "boundaries", "series": ["integrator"]}]
        })
    };
    let scratch = Scratch::new("spent", &search("spent", 1e-6, 5));
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = read_parquet(&scratch.dir.join("results/spent/spent-boundaries.parquet"));
    let (low, high) = (floats(&table, "boundary_lo"), floats(&table, "boundary_hi"));
    assert_eq!(floats(&table, "probes"), [5.0; 4]);
    assert!(
        low.iter()
            .zip(&high)
            .all(|(l, h)| l.is_finite() && h.is_finite() && l < h),
        "{low:?} {high:?}"
    );
    assert!(scratch
        .dir
        .join("results/spent/figures/limits.svg")
        .exists());

    let tiny = Scratch::new("tiny", &search("tiny", 1e-300, 1_000_000_000));
    let plan = tiny.nlstudy("plan", &[]);
    assert!(!plan.status.success());
    assert!(text(&plan).contains("boundary.rtol"), "{}", text(&plan));

    let finest = Scratch::new("finest", &search("finest", 1e-14, 1_000_000_000));
    let run = finest.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = read_parquet(&finest.dir.join("results/finest/finest-boundaries.parquet"));
    assert!(
        floats(&table, "probes").iter().all(|&p| p < 200.0),
        "{table}"
    );
}
