//! The sine-transform preconditioner of the implicit integrators: an approximate inverse of
//! A = I − s L_h (s = θ dt) applied with two fast sine transforms per axis.
//!
//! With a zero collar, −L_h is the symmetric Toeplitz matrix (Toeplitz blocks in 2D) of the
//! stencil's symbol σ (`discretization::stability::Symbol`). Its τ approximation, the matrix of the
//! same symbol sampled at the sine modes θ_k = πk/(n + 1), is diagonalised by the discrete sine
//! transform S (DST-I, S² = (n + 1)/2 · I). So
//!     M⁻¹ = (2/(n + 1))^d S diag(1 / (1 + s σ(θ_k))) S
//! inverts I + s τ(−L_h) exactly. For the 3-point Laplacian τ(T) = T; for a horizon of m cells the
//! two differ by a Hankel correction of m rows at each end, so M⁻¹A is the identity plus a
//! perturbation near the boundary and CG needs a few iterations whatever n (Chan & Ng, SIAM
//! Review 38, 1996, on τ and circulant preconditioners for Toeplitz systems).
//!
//! DST-I comes from rustdct (its scratch is cleared before each use: see `transform_rows`). Each row is transformed by one task, so results do not depend on
//! the thread count; 2D transposes between the two axes.

use super::linear::LinearOperator;
use crate::discretization::stability::Symbol;
use crate::discretization::stencil::Stencil;
use crate::threads::row_tasks;
use rayon::prelude::*;
use rustdct::{DctPlanner, Dst1};
use std::sync::Arc;

pub struct SinePreconditioner {
    dim: usize,
    n: usize,
    dst: Arc<dyn Dst1<f64>>,
    /// (2/(n + 1))^d / (1 + s σ(θ_k)), at [k₁][k₂] in 2D (the transposed layout it is applied in).
    scaled_inverse: Vec<f64>,
}

/// A transposed copy (2D) and one DST scratch buffer per task.
pub struct SineWork {
    transposed: Vec<f64>,
    scratch: Vec<Vec<f64>>,
}

impl SinePreconditioner {
    /// Preconditions I − shift · L_h for the grid and weights of `stencil`.
    pub fn new(stencil: &Stencil, shift: f64) -> Self {
        let grid = stencil.grid;
        let (dim, n) = (grid.dim, grid.n);
        let normalisation = (2.0 / (n + 1) as f64).powi(dim as i32);
        let sigma = Symbol::new(stencil).on_sine_modes(n);
        let inverse = |k: usize| normalisation / (1.0 + shift * sigma[k]);
        let scaled_inverse = if dim == 2 {
            // σ is at [k₂][k₁]; store at [k₁][k₂].
            (0..n * n).map(|t| inverse((t % n) * n + t / n)).collect()
        } else {
            (0..n).map(inverse).collect()
        };
        SinePreconditioner {
            dim,
            n,
            dst: DctPlanner::new().plan_dst1(n),
            scaled_inverse,
        }
    }

    /// The DST-I of every row of `rows`, one task per block of rows.
    fn transform_rows(&self, rows: &mut [f64], scratch: &mut [Vec<f64>]) {
        let n = self.n;
        let rows_per_task = (rows.len() / n).div_ceil(scratch.len());
        rows.par_chunks_mut(rows_per_task * n)
            .zip(scratch.par_iter_mut())
            .for_each(|(block, scratch)| {
                for row in block.chunks_mut(n) {
                    // rustdct 0.7.1's DST-I reads two cells of its scratch as zeros without
                    // writing them, so a reused scratch must be cleared.
                    scratch.fill(0.0);
                    self.dst.process_dst1_with_scratch(row, scratch);
                }
            });
    }
}

/// to[x][y] = from[y][x] for n × n arrays.
fn transpose(from: &[f64], to: &mut [f64], n: usize) {
    to.par_chunks_mut(n).enumerate().for_each(|(x, row)| {
        for (y, value) in row.iter_mut().enumerate() {
            *value = from[y * n + x];
        }
    });
}

impl LinearOperator for SinePreconditioner {
    type Workspace = SineWork;

    fn workspace(&self) -> SineWork {
        let transposed = if self.dim == 2 { self.n * self.n } else { 0 };
        SineWork {
            transposed: vec![0.0; transposed],
            scratch: (0..row_tasks(self.dim, self.n))
                .map(|_| vec![0.0; self.dst.get_scratch_len()])
                .collect(),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], work: &mut SineWork) {
        let SineWork {
            transposed,
            scratch,
        } = work;
        let tasks = row_tasks(self.dim, self.n);
        while scratch.len() < tasks {
            scratch.push(vec![0.0; self.dst.get_scratch_len()]);
        }
        let scratch = &mut scratch[..tasks];
        out.copy_from_slice(u);
        if self.dim == 1 {
            self.transform_rows(out, scratch);
            out.iter_mut()
                .zip(&self.scaled_inverse)
                .for_each(|(v, &d)| *v *= d);
            self.transform_rows(out, scratch);
            return;
        }
        let n = self.n;
        self.transform_rows(out, scratch);
        transpose(out, transposed, n);
        self.transform_rows(transposed, scratch);
        transposed
            .par_iter_mut()
            .zip(&self.scaled_inverse)
            .for_each(|(v, &d)| *v *= d);
        self.transform_rows(transposed, scratch);
        transpose(transposed, out, n);
        self.transform_rows(out, scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};
    use crate::operator::StencilOperator;

    /// For m = 1 the stencil is the 3-point (1D) or 5-point (2D) Laplacian, whose τ approximation
    /// is itself: M⁻¹ (I − s L_h) u = u to rounding.
    #[test]
    fn inverts_the_nearest_neighbour_operator_exactly() {
        for (dim, n) in [(1, 9), (2, 7), (2, 16)] {
            let grid = Grid::new(dim, n);
            let stencil = Stencil::new(
                grid,
                Horizon::from_m(&grid, 1),
                Kernel::Constant,
                Quadrature::Midpoint,
                1.0,
            );
            let shift = 0.3 / stencil.total_weight;
            let u: Vec<f64> = (0..grid.nodes())
                .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
                .collect();
            let mut lu = vec![0.0; u.len()];
            StencilOperator::new(&stencil).apply_once(&u, &mut lu);
            let au: Vec<f64> = u.iter().zip(&lu).map(|(u, l)| u - shift * l).collect();
            let mut back = vec![0.0; u.len()];
            SinePreconditioner::new(&stencil, shift).apply_once(&au, &mut back);
            for (i, (b, u)) in back.iter().zip(&u).enumerate() {
                assert!(
                    (b - u).abs() < 1e-12,
                    "dim {dim} n {n} node {i}: {b} vs {u}"
                );
            }
        }
    }

    /// A workspace reused for another vector gives the bits of a fresh one (the DST's scratch
    /// is cleared before each transform), and M is symmetric positive definite with the bounds
    /// 1/(1 + s max σ) ≤ rᵀMr/rᵀr ≤ 1.
    #[test]
    fn a_reused_workspace_gives_the_bits_of_a_fresh_one() {
        for (dim, n) in [(1, 200), (2, 30)] {
            let grid = Grid::new(dim, n);
            let stencil = Stencil::new(
                grid,
                Horizon::from_m(&grid, 4),
                Kernel::Constant,
                Quadrature::Midpoint,
                1.0,
            );
            let preconditioner = SinePreconditioner::new(&stencil, 1e-4);
            let mut workspace = preconditioner.workspace();
            for seed in 0..3 {
                let r: Vec<f64> = (0..grid.nodes())
                    .map(|i| (((i + 31 * seed) * 7919) % 101) as f64 / 50.0 - 1.0)
                    .collect();
                let (mut reused, mut fresh) = (vec![0.0; r.len()], vec![0.0; r.len()]);
                preconditioner.apply(&r, &mut reused, &mut workspace);
                preconditioner.apply_once(&r, &mut fresh);
                assert!(reused
                    .iter()
                    .zip(&fresh)
                    .all(|(a, b)| a.to_bits() == b.to_bits()));
                let rz: f64 = r.iter().zip(&fresh).map(|(a, b)| a * b).sum();
                let rr: f64 = r.iter().map(|a| a * a).sum();
                assert!(
                    rz > 0.0 && rz <= rr * (1.0 + 1e-12),
                    "dim {dim}: {rz} vs {rr}"
                );
            }
        }
    }
}
