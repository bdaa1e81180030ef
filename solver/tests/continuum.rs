//! The continuum operator L φ used by the `continuum` source: accurate to 1e-10 relative.

use solver::case::Kernel;
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::influence::scaling_constant;
use solver::problem::continuum::{ContinuumOperator, DEFAULT_ORDER};
use solver::problem::profile;

fn continuum(dim: usize, eps: f64, kernel: Kernel, order: usize) -> ContinuumOperator {
    let grid = Grid::new(dim, 10);
    let horizon = Horizon::from_eps(&grid, eps);
    let c = scaling_constant(dim, kernel, eps, 1.0);
    ContinuumOperator::new(dim, &horizon, kernel, c, order)
}

#[test]
fn quadrature_refinement_changes_l_phi_by_less_than_1e10() {
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            for eps in [0.05, 0.2, 0.5] {
                let grid = Grid::new(dim, if dim == 1 { 50 } else { 16 });
                let horizon = Horizon::from_eps(&grid, eps);
                let c = scaling_constant(dim, kernel, eps, 1.0);
                let coarse = ContinuumOperator::new(dim, &horizon, kernel, c, DEFAULT_ORDER)
                    .apply_to_profile(&grid);
                let fine = ContinuumOperator::new(dim, &horizon, kernel, c, 2 * DEFAULT_ORDER)
                    .apply_to_profile(&grid);
                let scale = fine.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let worst = coarse
                    .iter()
                    .zip(&fine)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst <= 1e-10 * scale,
                    "{dim}D {kernel:?} ε={eps}: refinement moved L φ by {worst:e} (scale {scale:e})"
                );
            }
        }
    }
}

#[test]
fn split_quadrature_equals_the_eigenvalue_where_the_ball_is_inside() {
    // Where H_ε(x) ⊂ D, L φ = λ φ with λ from a 1D integral (module docs); the general split
    // quadrature must agree.
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            let eps = 0.15;
            let op = continuum(dim, eps, kernel, DEFAULT_ORDER);
            let grid = Grid::new(dim, 10);
            let field = op.apply_to_profile(&grid);
            for (i, &fast) in field.iter().enumerate() {
                let x = grid.position(i);
                let inside = (0..dim).all(|a| x[a] >= eps && x[a] <= 1.0 - eps);
                if inside && profile(dim, x).abs() > 0.1 {
                    let general = op.at(x);
                    assert!(
                        (general - fast).abs() <= 1e-11 * fast.abs(),
                        "{dim}D {kernel:?} at {x:?}: split {general} vs λφ {fast}"
                    );
                }
            }
        }
    }
}

#[test]
fn l_phi_tends_to_the_laplacian_as_eps_shrinks() {
    // Appendix B: L φ = kΔφ + O(ε²) for smooth φ, with kΔφ = −d(2π)² φ at k = 1. At a point
    // whose ball stays inside D, the relative gap must shrink like ε² (ratio 4 per halving).
    let x = [0.3, 0.35];
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            let laplacian = -(dim as f64) * (2.0 * std::f64::consts::PI).powi(2) * profile(dim, x);
            let gaps: Vec<f64> = [0.08, 0.04, 0.02]
                .iter()
                .map(|&eps| (continuum(dim, eps, kernel, DEFAULT_ORDER).at(x) - laplacian).abs())
                .collect();
            assert!(
                gaps[0] < 0.05 * laplacian.abs(),
                "{dim}D {kernel:?}: L φ far from kΔφ: {gaps:?}"
            );
            for w in gaps.windows(2) {
                let ratio = w[0] / w[1];
                assert!(
                    (ratio - 4.0).abs() < 0.2,
                    "{dim}D {kernel:?}: gap ratio {ratio} per halving of ε"
                );
            }
        }
    }
}

/// ∫ sin(a y) dy over [lo, hi] ∩ [0, 1] for the profile's wavenumber a.
fn integral_of_sine(lo: f64, hi: f64) -> f64 {
    let a = solver::problem::WAVENUMBER;
    let (lo, hi) = (lo.max(0.0), hi.min(1.0));
    if lo >= hi {
        return 0.0;
    }
    ((a * lo).cos() - (a * hi).cos()) / a
}

#[test]
fn constant_kernel_matches_an_independent_integral_up_to_the_boundary() {
    // For J = 1, L φ(x) = c (∫_{H_ε(x) ∩ D} φ dy − |H_ε| φ(x)). In 1D the integral is closed form;
    // in 2D it is a 1D integral of closed-form chords, y₁ = x₁ + ε sin θ, taken on a fine uniform
    // composite rule that knows nothing of the split points (accurate to ~1e-8).
    let eps = 0.3;
    let c1 = scaling_constant(1, Kernel::Constant, eps, 1.0);
    let op1 = continuum(1, eps, Kernel::Constant, DEFAULT_ORDER);
    for x in [0.01, 0.1, 0.29, 0.5, 0.77, 0.95, 0.999] {
        let exact = c1 * (integral_of_sine(x - eps, x + eps) - 2.0 * eps * profile(1, [x, 0.0]));
        let got = op1.at([x, 0.0]);
        assert!(
            (got - exact).abs() <= 1e-12 * exact.abs().max(1.0),
            "1D x={x}: {got} vs {exact}"
        );
    }

    let c2 = scaling_constant(2, Kernel::Constant, eps, 1.0);
    let op2 = continuum(2, eps, Kernel::Constant, DEFAULT_ORDER);
    let rule = gauss_quad::legendre::GaussLegendre::new(8.try_into().unwrap());
    let panels = 4000;
    let half_pi = std::f64::consts::FRAC_PI_2;
    for x in [
        [0.02, 0.1],
        [0.2, 0.9],
        [0.5, 0.97],
        [0.4, 0.6],
        [0.99, 0.99],
    ] {
        let chords: f64 = (0..panels)
            .map(|k| {
                let a = -half_pi + std::f64::consts::PI * k as f64 / panels as f64;
                let b = a + std::f64::consts::PI / panels as f64;
                rule.integrate(a, b, |theta| {
                    let y1 = x[0] + eps * theta.sin();
                    let half_chord = eps * theta.cos();
                    profile(1, [y1, 0.0])
                        * integral_of_sine(x[1] - half_chord, x[1] + half_chord)
                        * eps
                        * theta.cos()
                })
            })
            .sum();
        let disc = std::f64::consts::PI * eps * eps;
        let exact = c2 * (chords - disc * profile(2, x));
        let got = op2.at(x);
        let scale = c2 * disc;
        assert!(
            (got - exact).abs() <= 1e-8 * scale,
            "2D x={x:?}: {got} vs {exact}"
        );
    }
}

/// Along an edge, L φ = sin(a x_∥) G(x_⊥): the tabulated edge profile gives, at every node whose
/// ball crosses one side, the value the node-by-node quadrature gives.
#[test]
fn the_edge_profile_equals_the_quadrature_node_by_node() {
    for kernel in Kernel::ALL {
        for (n, eps) in [(64, 0.125), (60, 0.25), (40, 0.05)] {
            let grid = Grid::new(2, n);
            let horizon = Horizon::from_eps(&grid, eps);
            let c = scaling_constant(2, kernel, eps, 1.0);
            let direct = ContinuumOperator::new(2, &horizon, kernel, c, DEFAULT_ORDER);
            let tabulated =
                ContinuumOperator::new(2, &horizon, kernel, c, DEFAULT_ORDER).for_grid(&grid);
            let scale = direct.eigenvalue().abs();
            let mut edge_nodes = 0;
            for i in 0..grid.nodes() {
                let x = grid.position(i);
                let clear = |a: usize| x[a].min(1.0 - x[a]) >= eps;
                if clear(0) == clear(1) {
                    continue;
                }
                edge_nodes += 1;
                let (a, b) = (tabulated.at_node(&grid, i), direct.at(x));
                assert!(
                    (a - b).abs() <= 1e-11 * scale,
                    "{kernel:?} n={n} ε={eps} at {x:?}: {a} against {b}"
                );
            }
            assert!(edge_nodes > 0);
        }
    }
}
