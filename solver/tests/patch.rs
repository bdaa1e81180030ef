//! Patch tests (seed 003's idea, for diffusion): L_h of a linear field vanishes and L_h of |x|²
//! is 2dk, checked on the operators themselves (both backends) at the nodes whose ball lies in D,
//! for every quadrature, kernel and m from 1 to 10.

use solver::case::{Backend, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::stencil::Stencil;
use solver::operator::{plan, LinearOperator};

const DIFFUSIVITY: f64 = 0.7;

/// The stencils of every dimension, kernel, quadrature and m = 1..=10 (on n = 2m + 5 nodes per
/// side, so that 5 nodes per side see no collar), leaving out those that vanish (J = 1 − r, m = 1).
fn patches() -> Vec<Stencil> {
    let mut stencils = Vec::new();
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            for quadrature in Quadrature::ALL {
                for m in 1..=10 {
                    let grid = Grid::new(dim, 2 * m + 5);
                    let horizon = Horizon::from_m(&grid, m);
                    let stencil = Stencil::new(grid, horizon, kernel, quadrature, DIFFUSIVITY);
                    if stencil.total_weight > 0.0 {
                        stencils.push(stencil);
                    }
                }
            }
        }
    }
    stencils
}

/// L_h u at the nodes whose ball lies in D, by each backend.
fn interior_values(stencil: &Stencil, u: &[f64]) -> Vec<Vec<f64>> {
    let (grid, m) = (stencil.grid, stencil.horizon.m);
    let interior = |i: usize| {
        let (ix, iy) = (i % grid.n, i / grid.n);
        let inside = |k: usize| k >= m && k + m < grid.n;
        inside(ix) && (grid.dim == 1 || inside(iy))
    };
    [Backend::Stencil, Backend::NeighbourList]
        .iter()
        .map(|&backend| {
            let mut out = vec![0.0; u.len()];
            plan(backend, stencil).apply_once(u, &mut out);
            (0..u.len())
                .filter(|&i| interior(i))
                .map(|i| out[i])
                .collect()
        })
        .collect()
}

fn label(s: &Stencil) -> String {
    format!(
        "{}D {:?} {:?} m={}",
        s.grid.dim, s.kernel, s.quadrature, s.horizon.m
    )
}

#[test]
fn linear_fields_give_zero_to_round_off() {
    for stencil in patches() {
        let grid = stencil.grid;
        let u: Vec<f64> = (0..grid.nodes())
            .map(|i| {
                let x = grid.position(i);
                0.3 + 1.7 * x[0] - 0.9 * x[1]
            })
            .collect();
        // Each term w_o (u_{i+o} − u_i) is at most w_o · 2.6 ε; their sum cancels exactly.
        let scale = stencil.total_weight * 2.6 * stencil.horizon.eps;
        for values in interior_values(&stencil, &u) {
            assert!(!values.is_empty());
            let worst = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(
                worst <= 1e-14 * scale,
                "{}: L_h(linear) = {worst:e}, scale {scale:e}",
                label(&stencil)
            );
        }
    }
}

#[test]
fn quadratic_fields_give_2dk_times_one_plus_the_patch_error() {
    for stencil in patches() {
        let grid = stencil.grid;
        // Centred in D so that |x − x_c|² stays O(ε²) where it is evaluated (no cancellation).
        let centre = grid.position(grid.nodes() / 2);
        let u: Vec<f64> = (0..grid.nodes())
            .map(|i| {
                let x = grid.position(i);
                (0..grid.dim).map(|a| (x[a] - centre[a]).powi(2)).sum()
            })
            .collect();
        let exact = 2.0 * grid.dim as f64 * DIFFUSIVITY;
        let expected = exact * (1.0 + stencil.patch_error());
        for values in interior_values(&stencil, &u) {
            for value in values {
                assert!(
                    (value - expected).abs() <= 1e-12 * exact,
                    "{}: L_h|x|² = {value}, the record's patch error says {expected}",
                    label(&stencil)
                );
                if stencil.quadrature == Quadrature::Ac {
                    assert!(
                        (value / exact - 1.0).abs() <= 1e-12,
                        "{}: `ac` gives L_h|x|² = {value}, not 2dk = {exact}",
                        label(&stencil)
                    );
                }
            }
        }
    }
}

/// 1D patch errors in closed form, from the sums Σⱼ jᵖ over the bonds j = 1..m (ε = m h):
/// `midpoint`, J = 1: Σ 2j² h³ / (2ε³/3) − 1 = (m + 1)(2m + 1)/(2m²) − 1;
/// `partial_volume`, J = 1 (the trapezoid rule: the end bond has half a cell): 1/(2m²);
/// J = 1 − r, either rule (the end bond has J = 0): Σ 2(1 − j/m) j² h³ / (ε³/6) − 1 = −1/m²;
/// J = 1/r, `partial_volume`: J s² = ε s is linear, which the trapezoid rule integrates exactly.
fn closed_form_1d(kernel: Kernel, quadrature: Quadrature, m: f64) -> Option<f64> {
    match (kernel, quadrature) {
        (_, Quadrature::Ac) => Some(0.0),
        (Kernel::Constant, Quadrature::Midpoint) => {
            Some((m + 1.0) * (2.0 * m + 1.0) / (2.0 * m * m) - 1.0)
        }
        (Kernel::Constant, Quadrature::PartialVolume) => Some(0.5 / (m * m)),
        (Kernel::Linear, _) => Some(-1.0 / (m * m)),
        (Kernel::InverseDistance, Quadrature::PartialVolume) => Some(0.0),
        _ => None,
    }
}

#[test]
fn patch_errors_match_their_closed_forms_and_only_ac_is_exact_in_2d() {
    for stencil in patches() {
        let error = stencil.patch_error();
        // Printed for the docs' table (`cargo test --test patch -- --nocapture`).
        println!("{}: {error:+.3e}", label(&stencil));
        let (kernel, quadrature) = (stencil.kernel, stencil.quadrature);
        if stencil.grid.dim == 1 {
            if let Some(exact) = closed_form_1d(kernel, quadrature, stencil.horizon.m as f64) {
                assert!(
                    (error - exact).abs() < 1e-13,
                    "{}: {error} vs {exact}",
                    label(&stencil)
                );
            }
        } else if quadrature != Quadrature::Ac {
            // The lattice's discs and cells never give the second moment exactly (the closest
            // is J = 1, midpoint, m = 6: +1.2e-4).
            assert!(error.abs() > 1e-5, "{}: {error:e}", label(&stencil));
        }
    }
    for quadrature in [Quadrature::Midpoint, Quadrature::PartialVolume] {
        let error = |m: usize| {
            let grid = Grid::new(2, 64);
            let horizon = Horizon::from_m(&grid, m);
            Stencil::new(grid, horizon, Kernel::Gaussian, quadrature, 1.0).patch_error()
        };
        assert!(
            error(20).abs() < 0.2 * error(2).abs(),
            "2D {quadrature:?}: the patch error does not shrink with m: {} at m = 2, {} at m = 20",
            error(2),
            error(20)
        );
    }
}
