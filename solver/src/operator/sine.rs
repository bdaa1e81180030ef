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
//! **Which transform.** rustdct runs a DST-I of length n as an FFT of length 2(n + 1). For the
//! grids studies use, n = 2^k, n + 1 has large prime factors (257 is prime) and the DST-I is 2–3.4
//! times slower than at n − 1. There the preconditioner uses the DST-II algebra instead: the
//! matrices diagonalised by the DST-II C, whose modes θ_k = πk/n (k = 1 ..= n) are antisymmetric
//! about the half cells before the first node and after the last. With C' the DST-III,
//! (2/n) C'C = I and C' = Cᵀ W, W = diag(1, …, 1, ½), so
//!     M⁻¹ = (2/n)^d C' diag(1 / (1 + s σ(θ_k))) C
//! is symmetric positive definite, applied with FFTs of length n. It inverts the Toeplitz matrix
//! with the collar's values reflected with a change of sign (u₋₁₋ⱼ = −uⱼ) instead of zero, which
//! differs from −L_h by a Hankel correction of m rows at each end, as τ does. Measured (2D, ε = 4h,
//! dt = 100 dt_stable): CG takes at most one iteration more than with the DST-I, and a step is
//! 1.3–1.8 times faster for n = 128 … 1024. It is used when n is 5-smooth and n + 1 is not.
//!
//! Transforms come from rustdct (the DST-I's scratch is cleared before each use: see
//! `transform_rows`). Each row is transformed by one task, so results do not depend on the
//! thread count; 2D transposes between the two axes.

use super::linear::LinearOperator;
use crate::discretization::stability::Symbol;
use crate::discretization::stencil::Stencil;
use crate::threads::row_tasks;
use rayon::prelude::*;
use rustdct::{DctPlanner, Dst1, TransformType2And3};
use std::ops::Range;
use std::sync::Arc;

/// The sine transform along one axis.
#[derive(Clone)]
pub(crate) enum Transform {
    /// DST-I, its own inverse up to (n + 1)/2.
    SineI(Arc<dyn Dst1<f64>>),
    /// DST-II forward, DST-III back (their product is n/2).
    SineII(Arc<dyn TransformType2And3<f64>>),
}

impl Transform {
    /// The transform for n nodes per axis (module doc), with the period of its sine modes.
    fn for_nodes(n: usize) -> (Transform, usize) {
        let mut planner = DctPlanner::new();
        if !is_5_smooth(n + 1) && is_5_smooth(n) {
            (Transform::SineII(planner.plan_dst2(n)), n)
        } else {
            (Transform::SineI(planner.plan_dst1(n)), n + 1)
        }
    }

    pub(crate) fn scratch_len(&self) -> usize {
        match self {
            Transform::SineI(dst) => dst.get_scratch_len(),
            Transform::SineII(dst) => dst.get_scratch_len(),
        }
    }

    fn forward(&self, row: &mut [f64], scratch: &mut [f64]) {
        match self {
            Transform::SineI(dst) => {
                // rustdct 0.7.1's DST-I reads two cells of its scratch as zeros without writing
                // them, so a reused scratch must be cleared.
                scratch.fill(0.0);
                dst.process_dst1_with_scratch(row, scratch);
            }
            Transform::SineII(dst) => dst.process_dst2_with_scratch(row, scratch),
        }
    }

    fn backward(&self, row: &mut [f64], scratch: &mut [f64]) {
        match self {
            Transform::SineI(_) => self.forward(row, scratch),
            Transform::SineII(dst) => dst.process_dst3_with_scratch(row, scratch),
        }
    }
}

/// Whether k has no prime factor above 5 (FFTs of such lengths are fast).
fn is_5_smooth(mut k: usize) -> bool {
    for p in [2, 3, 5] {
        while k > 0 && k.is_multiple_of(p) {
            k /= p;
        }
    }
    k == 1
}

pub struct SinePreconditioner {
    dim: usize,
    n: usize,
    transform: Transform,
    /// (2/period)^d / (1 + s σ(θ_k)), at [k₁][k₂] in 2D (the transposed layout it is applied in).
    scaled_inverse: Vec<f64>,
}

/// The transform for the grid of `stencil`, and (2/period)^d / (1 + s σ(θ_k)) for the modes k₁
/// in `columns` and every k₂, at [k₁ − columns.start][k₂] (the transposed layout the
/// preconditioner scales in; 1D: `columns` is every mode).
pub(crate) fn transform_and_scaled_inverse(
    stencil: &Stencil,
    shift: f64,
    columns: Range<usize>,
) -> (Transform, Vec<f64>) {
    let grid = stencil.grid;
    let (dim, n) = (grid.dim, grid.n);
    let (transform, period) = Transform::for_nodes(n);
    let normalisation = (2.0 / period as f64).powi(dim as i32);
    let width = columns.len();
    let sigma = Symbol::new(stencil).on_sine_modes(n, period, columns);
    let inverse = |k: usize| normalisation / (1.0 + shift * sigma[k]);
    let scaled_inverse = if dim == 2 {
        // σ is at [k₂][k₁]; store at [k₁][k₂].
        (0..width * n)
            .map(|t| inverse((t % n) * width + t / n))
            .collect()
    } else {
        (0..width).map(inverse).collect()
    };
    (transform, scaled_inverse)
}

/// Transforms every row (of `n` values) of `rows` forward (or back), one task per block of rows
/// with a scratch buffer each: a row's result does not depend on the task that transforms it.
pub(crate) fn transform_rows(
    transform: &Transform,
    n: usize,
    rows: &mut [f64],
    scratch: &mut [Vec<f64>],
    forward: bool,
) {
    if rows.is_empty() {
        return;
    }
    let rows_per_task = (rows.len() / n).div_ceil(scratch.len());
    rows.par_chunks_mut(rows_per_task * n)
        .zip(scratch.par_iter_mut())
        .for_each(|(block, scratch)| {
            for row in block.chunks_mut(n) {
                if forward {
                    transform.forward(row, scratch);
                } else {
                    transform.backward(row, scratch);
                }
            }
        });
}

/// A transposed copy (2D) and one transform scratch buffer per task.
pub struct SineWorkspace {
    transposed: Vec<f64>,
    scratch: Vec<Vec<f64>>,
}

impl SinePreconditioner {
    /// Preconditions I − shift · L_h for the grid and weights of `stencil`.
    pub fn new(stencil: &Stencil, shift: f64) -> Self {
        let (dim, n) = (stencil.grid.dim, stencil.grid.n);
        let (transform, scaled_inverse) = transform_and_scaled_inverse(stencil, shift, 0..n);
        SinePreconditioner {
            dim,
            n,
            transform,
            scaled_inverse,
        }
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
    type Workspace = SineWorkspace;

    fn workspace(&self) -> SineWorkspace {
        let transposed = if self.dim == 2 { self.n * self.n } else { 0 };
        SineWorkspace {
            transposed: vec![0.0; transposed],
            scratch: (0..row_tasks(self.dim, self.n))
                .map(|_| vec![0.0; self.transform.scratch_len()])
                .collect(),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], work: &mut SineWorkspace) {
        let SineWorkspace {
            transposed,
            scratch,
        } = work;
        let tasks = row_tasks(self.dim, self.n);
        while scratch.len() < tasks {
            scratch.push(vec![0.0; self.transform.scratch_len()]);
        }
        let scratch = &mut scratch[..tasks];
        let scale = |v: &mut [f64]| {
            v.par_iter_mut()
                .zip(&self.scaled_inverse)
                .for_each(|(v, &d)| *v *= d)
        };
        out.copy_from_slice(u);
        if self.dim == 1 {
            transform_rows(&self.transform, self.n, out, scratch, true);
            scale(out);
            transform_rows(&self.transform, self.n, out, scratch, false);
            return;
        }
        let n = self.n;
        transform_rows(&self.transform, self.n, out, scratch, true);
        transpose(out, transposed, n);
        transform_rows(&self.transform, self.n, transposed, scratch, true);
        scale(transposed);
        transform_rows(&self.transform, self.n, transposed, scratch, false);
        transpose(transposed, out, n);
        transform_rows(&self.transform, self.n, out, scratch, false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};
    use crate::operator::StencilOperator;

    /// For m = 1 the stencil is the 3-point (1D) or 5-point (2D) Laplacian. Where n + 1 is
    /// 5-smooth (n = 9, 7, 15) the preconditioner's DST-I τ approximation is L_h itself. Where n
    /// is 5-smooth and n + 1 is not (n = 16, 30), the DST-II algebra's matrix is L' = L_h with the
    /// collar's values reflected with a change of sign, u₋₁ = −u₀: one bond weight w more on the
    /// diagonal per side of D a node touches. Either way M⁻¹ (I − s L') u = u to rounding.
    #[test]
    fn inverts_the_nearest_neighbour_operator_of_its_algebra_exactly() {
        for (dim, n, sine_ii) in [
            (1, 9, false),
            (2, 7, false),
            (2, 15, false),
            (1, 16, true),
            (2, 16, true),
            (2, 30, true),
        ] {
            let chosen = Transform::for_nodes(n).0;
            assert_eq!(matches!(chosen, Transform::SineII(_)), sine_ii, "n = {n}");
            let grid = Grid::new(dim, n);
            let stencil = Stencil::new(
                grid,
                Horizon::from_m(&grid, 1),
                Kernel::Constant,
                Quadrature::Midpoint,
                1.0,
            );
            let reflected = if sine_ii {
                stencil.total_weight / (2 * dim) as f64
            } else {
                0.0
            };
            let shift = 0.3 / stencil.total_weight;
            let u = sample(grid.nodes(), 0);
            let mut lu = vec![0.0; u.len()];
            StencilOperator::new(&stencil).apply_once(&u, &mut lu);
            let sides = |i: usize| -> f64 {
                let at_end = |k: usize| usize::from(k == 0) + usize::from(k == n - 1);
                let (x, y) = (i % n, i / n);
                (at_end(x) + if dim == 2 { at_end(y) } else { 0 }) as f64
            };
            let au: Vec<f64> = (0..u.len())
                .map(|i| u[i] - shift * (lu[i] - reflected * sides(i) * u[i]))
                .collect();
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

    fn sample(len: usize, seed: usize) -> Vec<f64> {
        (0..len)
            .map(|i| (((i + 31 * seed) * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect()
    }

    /// A workspace reused for another vector gives the bits of a fresh one (the DST-I's scratch
    /// is cleared before each transform), and M is symmetric positive definite with the bounds
    /// 1/(1 + s max σ) ≤ rᵀMr/rᵀr ≤ 1, with either transform (DST-I at n = 199 and 29, DST-II
    /// at n = 200 and 30).
    #[test]
    fn a_reused_workspace_gives_the_bits_of_a_fresh_one() {
        for (dim, n) in [(1, 199), (2, 29), (1, 200), (2, 30)] {
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
                let r = sample(grid.nodes(), seed);
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
                let other = sample(grid.nodes(), seed + 7);
                let mut m_other = vec![0.0; r.len()];
                preconditioner.apply_once(&other, &mut m_other);
                let dot =
                    |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(a, b)| a * b).sum() };
                let (r_m_other, other_m_r) = (dot(&r, &m_other), dot(&other, &fresh));
                assert!(
                    (r_m_other - other_m_r).abs() <= 1e-12 * rr,
                    "dim {dim} n {n}: M is not symmetric: {r_m_other} vs {other_m_r}"
                );
            }
        }
    }
}
