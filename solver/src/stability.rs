//! The stable time step of forward Euler for the nonlocal operator, from the stencil's symbol.
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

use crate::stencil::Stencil;
use std::f64::consts::PI;

/// Zoom steps after the coarse search: each halves the spacing, far below round-off after 50.
const ZOOM_STEPS: usize = 50;
/// Coarse candidates refined, in case two basins are nearly as high.
const CANDIDATES: usize = 8;

/// The symbol σ of a stencil with its weights on a dense (2m+1)^d array.
pub struct Symbol {
    reach: i64,
    dim: usize,
    /// Weight of offset (dx, dy) at (dy + reach)·(2·reach + 1) + dx + reach.
    weights: Vec<f64>,
    total_weight: f64,
}

impl Symbol {
    pub fn new(stencil: &Stencil) -> Self {
        let reach = stencil
            .rows
            .iter()
            .map(|row| -row.dx_min)
            .max()
            .unwrap_or(0);
        let width = (2 * reach + 1) as usize;
        let mut weights = vec![0.0; width * width];
        for row in &stencil.rows {
            for (dx, w) in row.bonds() {
                weights[(row.dy + reach) as usize * width + (dx + reach) as usize] = w;
            }
        }
        Symbol {
            reach,
            dim: stencil.grid.dim,
            weights,
            total_weight: stencil.total_weight,
        }
    }

    fn width(&self) -> usize {
        (2 * self.reach + 1) as usize
    }

    /// g_dx(ξ₂) = Σ_dy w(dx, dy) cos(dy ξ₂), so that σ(ξ) = W − Σ_dx cos(dx ξ₁) g_dx(ξ₂).
    fn column_sums(&self, xi2: f64, g: &mut [f64]) {
        let width = self.width();
        g.iter_mut().for_each(|v| *v = 0.0);
        for (row, dy) in self.weights.chunks(width).zip(-self.reach..) {
            let cy = (dy as f64 * xi2).cos();
            for (gx, &w) in g.iter_mut().zip(row) {
                *gx += w * cy;
            }
        }
    }

    fn value_with(&self, xi1: f64, g: &[f64]) -> f64 {
        let s: f64 = g
            .iter()
            .zip(-self.reach..)
            .map(|(&gx, dx)| gx * (dx as f64 * xi1).cos())
            .sum();
        self.total_weight - s
    }

    /// σ(ξ₁, ξ₂).
    pub fn value(&self, xi1: f64, xi2: f64) -> f64 {
        let mut g = vec![0.0; self.width()];
        self.column_sums(xi2, &mut g);
        self.value_with(xi1, &g)
    }

    /// max over ξ of σ(ξ), i.e. the bound on λ_max(−L_h).
    pub fn maximum(&self) -> f64 {
        let samples = 16 * self.reach as usize + 17;
        let spacing = PI / (samples - 1) as f64;
        let xi2_samples = if self.dim == 2 { samples } else { 1 };
        let mut g = vec![0.0; self.width()];
        let mut coarse = Vec::with_capacity(samples * xi2_samples);
        for b in 0..xi2_samples {
            let xi2 = b as f64 * spacing;
            self.column_sums(xi2, &mut g);
            for a in 0..samples {
                let xi1 = a as f64 * spacing;
                coarse.push((self.value_with(xi1, &g), xi1, xi2));
            }
        }
        coarse.sort_by(|p, q| q.0.total_cmp(&p.0));
        coarse
            .iter()
            .take(CANDIDATES)
            .map(|&(value, xi1, xi2)| self.zoom(value, xi1, xi2, spacing))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Hill-climbs from a coarse sample on ever finer 5 × 5 (or 5 in 1D) patterns.
    fn zoom(&self, mut best: f64, mut xi1: f64, mut xi2: f64, mut spacing: f64) -> f64 {
        let steps2: &[f64] = if self.dim == 2 {
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
                    let v = self.value(t1, t2);
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

/// dt_stable = 2 / max σ for forward Euler.
pub fn forward_euler_dt_stable(stencil: &Stencil) -> f64 {
    2.0 / Symbol::new(stencil).maximum()
}
