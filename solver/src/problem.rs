//! The problems a case can solve: the manufactured solution of seed 000's Appendix A with its
//! three source modes, and a source-free Gaussian bump for demonstrations.
//!
//! The manufactured solution is w(t, x) = cos(2πt) φ(x) with φ = sin(2πx₁)[sin(2πx₂)] in D and 0
//! outside. Since w separates, its source b = ∂ₜw − L w = −2π sin(2πt) φ − cos(2πt) ψ needs only
//! two fields fixed in time, φ and ψ = L φ, where L is
//! - `discrete`: the scheme's own L_h (the scheme then reproduces w up to the time error);
//! - `continuum`: the integral operator of eq. 1.1 (the error is the spatial discretization's);
//! - `local`: kΔ, so ψ = −d (2π)² k φ (the error is the distance to the local limit, Appendix B).

use crate::grid::Grid;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The wavenumber 2π of the manufactured profile.
pub const WAVENUMBER: f64 = 2.0 * PI;
/// Width of the Gaussian bump.
const BUMP_WIDTH: f64 = 0.1;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Problem {
    /// w = cos(2πt) sin(2πx₁)[sin(2πx₂)], exact solution known (Appendix A).
    #[default]
    Manufactured,
    /// u₀ = exp(−|x − ½|²/(2·0.1²)), no source, no exact solution: for demonstrations.
    Bump,
    /// Local methods: c = Π_a cos(π x_a / L) on (−L/2, L/2)^d, decaying as exp(−dπ²Dt/L²).
    Eigenmode,
    /// Local methods, seed 004's setup: c = 1 where every |x_a| < L/4, else 0.
    Square,
}

/// What the collar D_c holds: the data of the volume constraint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Collar {
    /// u = 0 (eq. 2.2). Then even the continuum nonlocal solution differs from the local one by
    /// O(ε) in a layer of width ε along ∂D.
    #[default]
    Zero,
    /// The manufactured solution's smooth continuation cos(2πt) sin(2πx₁)[sin(2πx₂)], which is
    /// odd about ∂D: the local solution's own values, so that no boundary layer forms and the
    /// error against the local solution is the interior consistency error alone.
    Exact,
}

impl Collar {
    pub fn is_zero(&self) -> bool {
        *self == Collar::Zero
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceMode {
    Discrete,
    Continuum,
    Local,
    None,
}

impl Problem {
    /// Does the problem belong to the local methods' domain (−L/2, L/2)^d?
    pub fn is_local(self) -> bool {
        matches!(self, Problem::Eigenmode | Problem::Square)
    }

    pub fn default_source(self) -> SourceMode {
        match self {
            Problem::Manufactured => SourceMode::Continuum,
            Problem::Bump | Problem::Eigenmode | Problem::Square => SourceMode::None,
        }
    }
}

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
