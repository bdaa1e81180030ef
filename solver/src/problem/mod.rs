//! The problems a case can solve: the manufactured solution of \[JD]'s Appendix A with its
//! three source modes, and a source-free Gaussian bump for demonstrations.
//!
//! The manufactured solution is w(t, x) = cos(2πt) φ(x) with φ = sin(2πx₁)[sin(2πx₂)] in D and 0
//! outside. Since w separates, its source b = ∂ₜw − L w = −2π sin(2πt) φ − cos(2πt) ψ needs only
//! two fields fixed in time, φ and ψ = L φ, where L is
//! - `discrete`: the scheme's own L_h (the scheme then reproduces w up to the time error);
//! - `continuum`: the integral operator of eq. 1.1 (the error is the spatial discretization's);
//! - `local`: kΔ, so ψ = −d (2π)² k φ (the error is the distance to the local limit, Appendix B).

pub mod continuum;
pub mod polynomial;
pub(crate) mod source;

use crate::discretization::grid::Grid;
use std::f64::consts::PI;

/// The wavenumber 2π of the manufactured profile.
pub const WAVENUMBER: f64 = 2.0 * PI;
/// Width of the Gaussian bump.
const BUMP_WIDTH: f64 = 0.1;

/// φ(x): sin(2πx₁)[sin(2πx₂)] in D, 0 outside.
#[inline]
pub fn profile(dim: usize, x: [f64; 2]) -> f64 {
    let inside = |s: f64| (0.0..=1.0).contains(&s);
    let mut value = if inside(x[0]) {
        (WAVENUMBER * x[0]).sin()
    } else {
        0.0
    };
    if dim == 2 {
        value *= if inside(x[1]) {
            (WAVENUMBER * x[1]).sin()
        } else {
            0.0
        };
    }
    value
}

/// sin(2πx₁)[sin(2πx₂)] everywhere: φ's smooth continuation into the collar.
#[inline]
pub fn continued_profile(dim: usize, x: [f64; 2]) -> f64 {
    let value = (WAVENUMBER * x[0]).sin();
    if dim == 2 {
        value * (WAVENUMBER * x[1]).sin()
    } else {
        value
    }
}

/// The Gaussian bump's initial value at x.
pub fn bump(dim: usize, x: [f64; 2]) -> f64 {
    let r2: f64 = (0..dim).map(|a| (x[a] - 0.5).powi(2)).sum();
    (-r2 / (2.0 * BUMP_WIDTH * BUMP_WIDTH)).exp()
}

/// Source fields of b(t) = α(t) φ + β(t) ψ, with α = −2π sin(2πt) and β = −cos(2πt).
pub struct Source {
    pub phi: Vec<f64>,
    pub psi: Vec<f64>,
}

impl Source {
    pub fn coefficients(t: f64) -> (f64, f64) {
        let (sin, cos) = (2.0 * PI * t).sin_cos();
        (-2.0 * PI * sin, -cos)
    }
}

/// The exact solution of the manufactured problem at time t, node by node: i ↦ cos(2πt) φᵢ.
pub fn manufactured_solution(phi: &[f64], t: f64) -> impl Fn(usize) -> f64 + Sync + '_ {
    let amplitude = (2.0 * PI * t).cos();
    move |i| amplitude * phi[i]
}

/// ψ/φ for the `local` source: kΔφ = −d (2π)² k φ.
pub fn local_laplacian_factor(dim: usize, diffusivity: f64) -> f64 {
    -(dim as f64) * WAVENUMBER * WAVENUMBER * diffusivity
}

/// φ or the bump at every node.
pub fn sample(grid: &Grid, f: impl Fn(usize, [f64; 2]) -> f64) -> Vec<f64> {
    (0..grid.nodes())
        .map(|i| f(grid.dim, grid.position(i)))
        .collect()
}
