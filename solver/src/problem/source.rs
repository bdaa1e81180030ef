//! ψ of the manufactured problem's source b = α(t) φ + β(t) ψ at one node, for the source modes
//! computed node by node (`continuum`, `local`), with what the collar contributes.
//!
//! With the collar holding g = cos(2πt) φ̃ (φ̃: φ continued, `collar: exact`), the scheme reads
//! ∂ₜu = L_h⁰ u + cos(2πt) γ + b, where L_h⁰ takes u = 0 on the collar and
//! γᵢ = Σ_{o: i+o ∈ D_c} w_o φ̃(x_{i+o}). For w to solve the mode's equation (L̃ the continuum
//! operator or kΔ, applied to φ̃), b = ∂ₜw − cos(2πt) L̃φ̃, so ψ = L̃φ̃ − γ: the collar's known part
//! moves into the source. The `discrete` mode needs no change: L_h φ̃ − γ = L_h⁰ φ.

use crate::case::{Case, Collar, SourceMode};
use crate::discretization::stencil::Stencil;
use crate::problem::continuum::{ContinuumOperator, DEFAULT_ORDER};
use crate::problem::{self};

pub(crate) struct PointwiseSource<'a> {
    stencil: &'a Stencil,
    collar: Collar,
    /// The continuum operator (`continuum`), or None for `local`.
    continuum: Option<ContinuumOperator>,
    /// kΔφ = (this) φ.
    local_factor: f64,
}

impl<'a> PointwiseSource<'a> {
    /// None for the modes that are not computed node by node (`discrete`, `none`).
    pub fn new(case: &Case, stencil: &'a Stencil) -> Option<Self> {
        let continuum = match case.source() {
            SourceMode::Continuum => Some(
                ContinuumOperator::new(
                    case.dim,
                    &stencil.horizon,
                    case.kernel,
                    stencil.c,
                    DEFAULT_ORDER,
                )
                .for_grid(&stencil.grid),
            ),
            SourceMode::Local => None,
            SourceMode::Discrete | SourceMode::None => return None,
        };
        Some(PointwiseSource {
            stencil,
            collar: case.collar,
            continuum,
            local_factor: problem::local_laplacian_factor(case.dim, case.diffusivity),
        })
    }

    /// ψ at node i of D.
    pub fn psi(&self, i: usize) -> f64 {
        let grid = &self.stencil.grid;
        let phi = || problem::profile(grid.dim, grid.position(i));
        match self.collar {
            Collar::Zero => match &self.continuum {
                Some(continuum) => continuum.at_node(grid, i),
                None => self.local_factor * phi(),
            },
            Collar::Exact => {
                // φ̃ is an eigenfunction of both operators on the whole lattice.
                let eigenvalue = match &self.continuum {
                    Some(continuum) => continuum.eigenvalue(),
                    None => self.local_factor,
                };
                eigenvalue * phi() - self.stencil.collar_sum(i, problem::continued_profile)
            }
        }
    }
}
