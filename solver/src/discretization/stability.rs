//! The stable time step of the explicit integrators for the nonlocal operator, from the stencil's
//! symbol.
//!
//! Forward Euler on u' = L_h u + b amplifies an eigenmode of −L_h with eigenvalue λ by 1 − Δt λ,
//! so it is stable iff Δt ≤ 2/λ_max. On the infinite lattice, L_h is a convolution with the symbol
//!     σ(ξ) = Σ_o w_o (1 − cos(o·ξ)),   ξ ∈ [−π, π]^d,
//! whose spectrum is the range of σ. −L_h on D (zero collar) is the compression of that operator to
//! the nodes of D, so its Rayleigh quotients, and thus λ_max, lie below max σ; as n grows the
//! compression's top eigenvalue tends to max σ. Hence
//!     dt_stable = 2 / max_ξ σ(ξ),
//! safe for every n and sharp for large n. The weights are symmetric in each axis, so
//! σ(ξ) = W − Σ_o w_o cos(o₁ξ₁) cos(o₂ξ₂) and it suffices to search ξ ∈ [0, π]^d. For a long horizon
//! the maximum is not at ξ = π (as it is for the local 5-point stencil), so we search: a grid fine
//! enough to resolve the degree-m trigonometric polynomial, then repeated local zooming.

use crate::case::Integrator;
use crate::discretization::stencil::Stencil;
use std::f64::consts::PI;
use std::ops::Range;

/// Zoom steps after the coarse search: each halves the spacing, far below round-off after 50.
const ZOOM_STEPS: usize = 50;
/// Coarse candidates refined, in case two basins are nearly as high.
const CANDIDATES: usize = 8;
/// Coarse samples per unit of reach: σ has degree m, so its features are ~π/m wide and a spacing
/// of π/(4m) puts several samples in each basin before zooming.
const SAMPLES_PER_CELL: usize = 4;

/// The symbol σ of a stencil, folded onto the quadrant dx, dy ≥ 0: with the stencil's mirror
/// symmetry, σ(ξ) = W − Σ_{dx,dy ≥ 0} f(dx, dy) cos(dx ξ₁) cos(dy ξ₂), f summing the mirror images.
pub struct Symbol {
    /// Largest |dx| or |dy| of a bond.
    reach: usize,
    dim: usize,
    /// f(dx, dy) at dy·(reach + 1) + dx.
    folded: Vec<f64>,
    total_weight: f64,
}

impl Symbol {
    pub fn new(stencil: &Stencil) -> Self {
        let reach = stencil.reach();
        let mut folded = vec![0.0; (reach + 1) * (reach + 1)];
        for row in &stencil.rows {
            for (dx, w) in row.bonds() {
                folded
                    [row.dy.unsigned_abs() as usize * (reach + 1) + dx.unsigned_abs() as usize] +=
                    w;
            }
        }
        Symbol {
            reach,
            dim: stencil.grid.dim,
            folded,
            total_weight: stencil.total_weight,
        }
    }

    /// g_dx = Σ_dy f(dx, dy) cos(dy ξ₂), from cos(dy ξ₂) for dy = 0 ..= reach.
    fn column_sums(&self, cos_xi2: &[f64], g: &mut [f64]) {
        g.iter_mut().for_each(|v| *v = 0.0);
        for (row, &cy) in self.folded.chunks(self.reach + 1).zip(cos_xi2) {
            for (gx, &f) in g.iter_mut().zip(row) {
                *gx += f * cy;
            }
        }
    }

    /// σ = W − Σ_dx g_dx cos(dx ξ₁), from cos(dx ξ₁) for dx = 0 ..= reach.
    fn value_with(&self, cos_xi1: &[f64], g: &[f64]) -> f64 {
        self.total_weight - g.iter().zip(cos_xi1).map(|(a, b)| a * b).sum::<f64>()
    }

    fn cosines(&self, xi: f64) -> Vec<f64> {
        (0..=self.reach).map(|d| (d as f64 * xi).cos()).collect()
    }

    /// σ(ξ₁, ξ₂).
    pub fn value(&self, xi1: f64, xi2: f64) -> f64 {
        let mut g = vec![0.0; self.reach + 1];
        self.column_sums(&self.cosines(xi2), &mut g);
        self.value_with(&self.cosines(xi1), &g)
    }

    /// max over ξ of σ(ξ), i.e. the bound on λ_max(−L_h).
    pub fn maximum(&self) -> f64 {
        let samples = SAMPLES_PER_CELL * self.reach + 9;
        let spacing = PI / (samples - 1) as f64;
        let table: Vec<Vec<f64>> = (0..samples)
            .map(|a| self.cosines(a as f64 * spacing))
            .collect();
        let xi2_samples = if self.dim == 2 { samples } else { 1 };
        let mut g = vec![0.0; self.reach + 1];
        let mut coarse = Vec::with_capacity(samples * xi2_samples);
        for (b, cos_xi2) in table.iter().take(xi2_samples).enumerate() {
            self.column_sums(cos_xi2, &mut g);
            for (a, cos_xi1) in table.iter().enumerate() {
                coarse.push((
                    self.value_with(cos_xi1, &g),
                    a as f64 * spacing,
                    b as f64 * spacing,
                ));
            }
        }
        coarse.sort_by(|p, q| q.0.total_cmp(&p.0));
        coarse
            .iter()
            .take(CANDIDATES)
            .map(|&(value, xi1, xi2)| self.zoom(value, xi1, xi2, spacing))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// σ at the n sine modes θ_k = πk/period for k = 1 ..= n along y and those of `columns`
    /// along x (in 2D at [k₂ − 1][k₁ − 1 − columns.start]): with period n + 1 the eigenvalues of
    /// −L_h's τ approximation (DST-I), with period n those of its DST-II approximation; the
    /// sine-transform preconditioner's (`operator::sine`), of which a rank holds some columns.
    pub fn on_sine_modes(&self, n: usize, period: usize, columns: Range<usize>) -> Vec<f64> {
        let angle = |k: usize| PI * (k + 1) as f64 / period as f64;
        let cosines: Vec<Vec<f64>> = (0..n).map(|k| self.cosines(angle(k))).collect();
        let rows = if self.dim == 2 { n } else { 1 };
        let mut g = vec![0.0; self.reach + 1];
        let mut values = Vec::with_capacity(rows * n);
        for k2 in 0..rows {
            let cos_xi2 = if self.dim == 2 {
                &cosines[k2][..]
            } else {
                &[1.0][..]
            };
            self.column_sums(cos_xi2, &mut g);
            values.extend(
                cosines[columns.clone()]
                    .iter()
                    .map(|cos_xi1| self.value_with(cos_xi1, &g)),
            );
        }
        values
    }

    /// Hill-climbs from a coarse sample on ever finer 5 × 5 (or 5 in 1D) patterns. Each
    /// pattern's column sums are made once per ξ₂ (once in 1D) and the cosines into buffers
    /// kept for the climb: σ is `value`'s, bit for bit, at a third of its cost (this search was
    /// a fifth of a tiny case's time in a worker).
    fn zoom(&self, mut best: f64, mut xi1: f64, mut xi2: f64, mut spacing: f64) -> f64 {
        let steps2: &[f64] = if self.dim == 2 {
            &[-1.0, -0.5, 0.0, 0.5, 1.0]
        } else {
            &[0.0]
        };
        let mut cosines = vec![0.0; self.reach + 1];
        let mut g = vec![0.0; self.reach + 1];
        let fill = |cosines: &mut [f64], xi: f64| {
            (cosines.iter_mut().enumerate()).for_each(|(d, c)| *c = (d as f64 * xi).cos())
        };
        for _ in 0..ZOOM_STEPS {
            let (c1, c2) = (xi1, xi2);
            for &s2 in steps2 {
                let t2 = (c2 + s2 * spacing).clamp(0.0, PI);
                fill(&mut cosines, t2);
                self.column_sums(&cosines, &mut g);
                for s1 in [-1.0, -0.5, 0.0, 0.5, 1.0] {
                    let t1 = (c1 + s1 * spacing).clamp(0.0, PI);
                    fill(&mut cosines, t1);
                    let v = self.value_with(&cosines, &g);
                    if v > best {
                        (best, xi1, xi2) = (v, t1, t2);
                    }
                }
            }
            spacing *= 0.5;
        }
        best
    }
}

/// A floor under forward Euler's dt_stable for one pass over the weights: σ(ξ) = Σ_o w_o (1 −
/// cos(o·ξ)) ≤ 2 Σ_o |w_o|, so dt_stable = 2 / max σ ≥ 1 / Σ_o |w_o|. None unless W = Σ_o w_o
/// is positive (σ averages W over ξ, so then max σ ≥ W > 0 and dt_stable is finite too) and the
/// floor is a positive finite number.
pub fn forward_euler_dt_stable_floor(stencil: &Stencil) -> Option<f64> {
    let absolute: f64 = stencil
        .rows
        .iter()
        .flat_map(|row| row.bonds())
        .map(|(_, w)| w.abs())
        .sum();
    let floor = 1.0 / absolute;
    (stencil.total_weight > 0.0 && floor > 0.0 && floor.is_finite()).then_some(floor)
}

/// dt_stable = 2 / max σ for forward Euler.
pub fn forward_euler_dt_stable(stencil: &Stencil) -> f64 {
    2.0 / Symbol::new(stencil).maximum()
}

/// Where the explicit Runge–Kutta methods' stability regions meet the negative real axis (the
/// spectrum of L_h lies on it): |R(z)| ≤ 1 for z ∈ [−x, 0]. R(z) = 1 + z + z²/2 for Heun gives
/// x = 2; RK4's R(z) = Σ_{j ≤ 4} z^j/j! gives x = 2.7852935634… (the root of R(z) = 1 on z < 0).
const RK4_REAL_STABILITY: f64 = 2.785_293_563_405_282;

/// The largest stable dt of `integrator` for L_h: x / λ_max, with [−x, 0] its real stability
/// interval; None for the unconditionally stable implicit schemes.
pub fn dt_stable(integrator: Integrator, forward_euler_dt_stable: f64) -> Option<f64> {
    match integrator {
        Integrator::ForwardEuler | Integrator::Heun => Some(forward_euler_dt_stable),
        Integrator::Rk4 => Some(forward_euler_dt_stable * RK4_REAL_STABILITY / 2.0),
        Integrator::BackwardEuler | Integrator::CrankNicolson => None,
    }
}

/// The largest step whose explicit part I + (1 − θ) dt L_h has no negative entry. L_h's
/// diagonal is −W and its other entries are the weights, so with every weight ≥ 0 that is
/// dt ≤ 1 / ((1 − θ) W) (`positive_step`).
pub fn dt_positive(integrator: Integrator, stencil: &Stencil) -> Option<f64> {
    let mut weights = stencil.rows.iter().flat_map(|row| row.bonds());
    let nonnegative = weights.all(|(_, w)| w >= 0.0);
    positive_step(integrator, stencil.total_weight, nonnegative)
}

/// The largest step whose explicit part I + (1 − θ) dt L has no negative entry, for an L whose
/// largest |L_ii| is `largest_diagonal` and whose other entries are ≥ 0 when
/// `off_diagonal_nonnegative`: dt ≤ 1 / ((1 − θ) max |L_ii|). Forward Euler's step is that part,
/// so there it is the positivity limit exactly; Crank–Nicolson's multiplies it by
/// (I − dt/2 L)⁻¹, an M-matrix's non-negative inverse, so there it is sufficient. None for
/// backward Euler (positive for every step), for Heun and RK4 (not derived), and for
/// off-diagonal entries of either sign.
pub fn positive_step(
    integrator: Integrator,
    largest_diagonal: f64,
    off_diagonal_nonnegative: bool,
) -> Option<f64> {
    let explicit_part = match integrator {
        Integrator::ForwardEuler => 1.0,
        Integrator::CrankNicolson => 0.5,
        Integrator::BackwardEuler | Integrator::Heun | Integrator::Rk4 => return None,
    };
    let dt = 1.0 / (explicit_part * largest_diagonal);
    (off_diagonal_nonnegative && dt.is_finite() && dt > 0.0).then_some(dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};

    /// The climb as first written: σ by `value` at each of the pattern's points.
    fn zoom_by_value(
        symbol: &Symbol,
        mut best: f64,
        mut xi1: f64,
        mut xi2: f64,
        mut spacing: f64,
    ) -> f64 {
        let steps2: &[f64] = if symbol.dim == 2 {
            &[-1.0, -0.5, 0.0, 0.5, 1.0]
        } else {
            &[0.0]
        };
        for _ in 0..ZOOM_STEPS {
            let (c1, c2) = (xi1, xi2);
            for &s2 in steps2 {
                for s1 in [-1.0, -0.5, 0.0, 0.5, 1.0] {
                    let t1 = (c1 + s1 * spacing).clamp(0.0, PI);
                    let t2 = (c2 + s2 * spacing).clamp(0.0, PI);
                    let v = symbol.value(t1, t2);
                    if v > best {
                        (best, xi1, xi2) = (v, t1, t2);
                    }
                }
            }
            spacing *= 0.5;
        }
        best
    }

    #[test]
    fn the_climb_finds_the_maximum_of_sigma_by_value_bit_for_bit() {
        for (dim, n, m) in [(1, 64, 1), (1, 100, 3), (1, 200, 8), (2, 32, 2), (2, 48, 5)] {
            for kernel in Kernel::ALL {
                let grid = Grid::new(dim, n);
                let horizon = Horizon::from_m(&grid, m);
                let stencil = Stencil::new(grid, horizon, kernel, Quadrature::Midpoint, 1.0);
                let symbol = Symbol::new(&stencil);
                let spacing = PI / (SAMPLES_PER_CELL * symbol.reach + 8) as f64;
                for (xi1, xi2) in [(0.0, 0.0), (1.0, 0.5), (PI, PI), (2.5, 0.1)] {
                    let xi2 = if dim == 2 { xi2 } else { 0.0 };
                    let start = symbol.value(xi1, xi2);
                    let climbed = symbol.zoom(start, xi1, xi2, spacing);
                    let by_value = zoom_by_value(&symbol, start, xi1, xi2, spacing);
                    assert_eq!(
                        climbed.to_bits(),
                        by_value.to_bits(),
                        "{dim}D m={m} {kernel:?}"
                    );
                }
            }
        }
    }
}
