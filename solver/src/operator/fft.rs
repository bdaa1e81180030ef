//! The FFT backend: with u = 0 on the collar (eq. 2.2), L_h u = K ∗ u − W u is a linear
//! convolution of u with the stencil's weights K (w_o at offset o), which costs O(P^d log P)
//! whatever the horizon, against O(N m^d) for the stencil.
//!
//! It runs on a window of D, nx × ny nodes: all of D, or a rank's owned nodes and ghosts (zero
//! outside the window). Each axis is zero-padded to P ≥ nx + r (r the stencil's reach, capped at
//! nx − 1 since longer bonds join no two window nodes), so the circular convolution of size P
//! equals the linear one on the window: a neighbour index i + o with −r ≤ i + o < 0 wraps to
//! P + i + o ≥ nx, where u is zero. The weights are even in dx and in dy, so K's transform is
//! real; it is computed once, scaled by 1/(px py), and each application is: real-to-complex
//! transforms of the rows, complex transforms of the columns, one product, and the same back.
//! Every buffer is in the workspace.
//!
//! In 2D the row spectra (ny rows × px/2 + 1 frequencies) are regrouped into columns block by
//! block: each task gathers `BLOCK` columns, transforms them zero-padded to py, multiplies and
//! transforms back, and keeps their first ny values; the final pass gathers `BLOCK` rows at a
//! time. Each value is computed by one task whatever the thread count, so results do not depend on
//! it.

use super::linear::LinearOperator;
use crate::discretization::grid::Window;
use crate::discretization::stencil::Stencil;
use crate::threads::row_tasks;
use rayon::prelude::*;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};
pub(crate) use schema::transform::transform_length;
use std::sync::Arc;

type C64 = Complex<f64>;

/// Columns (or rows) a task regroups at once: long enough contiguous reads (BLOCK · 16 bytes).
const BLOCK: usize = 8;

pub struct FftOperator {
    dim: usize,
    /// The window's nodes per row and its rows (1 in 1D).
    nx: usize,
    ny: usize,
    /// Transform lengths along x and y.
    px: usize,
    py: usize,
    total_weight: f64,
    /// K's transform over 1/(px py); in 2D indexed [frequency along x][frequency along y].
    symbol: Vec<f64>,
    rows_forward: Arc<dyn RealToComplex<f64>>,
    rows_inverse: Arc<dyn ComplexToReal<f64>>,
    columns_forward: Arc<dyn Fft<f64>>,
    columns_inverse: Arc<dyn Fft<f64>>,
}

/// The spectra between passes, and one set of scratch buffers per task.
pub struct FftWorkspace {
    /// Row spectra, ny × (px/2 + 1), row-major.
    rows: Vec<C64>,
    /// The filtered spectra by column, (px/2 + 1) × ny, column-major (2D only).
    columns: Vec<C64>,
    lanes: Vec<Lane>,
}

struct Lane {
    real: Vec<f64>,
    /// BLOCK rows of spectra, or BLOCK zero-padded columns of length py.
    block: Vec<C64>,
    scratch: Vec<C64>,
}

impl FftOperator {
    /// L_h on all of D.
    pub fn new(stencil: &Stencil) -> Self {
        Self::on_window(stencil, Window::whole(&stencil.grid))
    }

    /// K ∗ v − W v on the nodes of `window`, for v given on the window and zero outside it: on
    /// all of D, L_h; on a rank's window of owned nodes and ghosts, L_h at its owned nodes.
    pub fn on_window(stencil: &Stencil, window: Window) -> Self {
        let dim = stencil.grid.dim;
        let (nx, ny) = (window.nx, window.ny);
        let reach = stencil.reach();
        // Bonds longer than the window reach no node of it from another.
        let length = |nodes: usize| transform_length(nodes + reach.min(nodes - 1));
        let (px, py) = (length(nx), if dim == 2 { length(ny) } else { 1 });
        let mut real_planner = RealFftPlanner::<f64>::new();
        let mut planner = FftPlanner::<f64>::new();
        let mut operator = FftOperator {
            dim,
            nx,
            ny,
            px,
            py,
            total_weight: stencil.total_weight,
            symbol: Vec::new(),
            rows_forward: real_planner.plan_fft_forward(px),
            rows_inverse: real_planner.plan_fft_inverse(px),
            columns_forward: planner.plan_fft_forward(py),
            columns_inverse: planner.plan_fft_inverse(py),
        };
        operator.symbol = operator.kernel_symbol(stencil);
        operator
    }

    fn frequencies(&self) -> usize {
        self.px / 2 + 1
    }

    fn new_lane(&self) -> Lane {
        let scratch = [
            self.rows_forward.get_scratch_len(),
            self.rows_inverse.get_scratch_len(),
            self.columns_forward.get_inplace_scratch_len(),
            self.columns_inverse.get_inplace_scratch_len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        let block = if self.dim == 2 {
            BLOCK * self.py.max(self.frequencies())
        } else {
            0
        };
        Lane {
            real: vec![0.0; self.px],
            block: vec![C64::default(); block],
            scratch: vec![C64::default(); scratch],
        }
    }

    /// The transform of the weights placed at their offsets modulo the transform lengths,
    /// scaled by 1/(px py). Bonds reaching further than the window are left out: they join no
    /// two of its nodes.
    fn kernel_symbol(&self, stencil: &Stencil) -> Vec<f64> {
        let (px, py, k) = (self.px, self.py, self.frequencies());
        let scale = 1.0 / (px * py) as f64;
        let wrap = |offset: i64, p: usize| offset.rem_euclid(p as i64) as usize;
        let (reach_x, reach_y) = ((self.nx - 1) as i64, (self.ny - 1) as i64);
        let mut lane = self.new_lane();
        let mut row_spectra = vec![C64::default(); py * k];
        for row in stencil.rows.iter().filter(|row| row.dy.abs() <= reach_y) {
            lane.real.fill(0.0);
            for (dx, w) in row.bonds().filter(|(dx, _)| dx.abs() <= reach_x) {
                lane.real[wrap(dx, px)] = w;
            }
            let spectrum = &mut row_spectra[wrap(row.dy, py) * k..][..k];
            self.rows_forward
                .process_with_scratch(&mut lane.real, spectrum, &mut lane.scratch)
                .expect("buffer lengths come from the plan");
        }
        if self.dim == 1 {
            return row_spectra[..k].iter().map(|z| z.re * scale).collect();
        }
        let mut symbol = vec![0.0; k * py];
        let mut column = vec![C64::default(); py];
        for (f, symbol_column) in symbol.chunks_mut(py).enumerate() {
            for (y, value) in column.iter_mut().enumerate() {
                *value = row_spectra[y * k + f];
            }
            self.columns_forward
                .process_with_scratch(&mut column, &mut lane.scratch);
            for (s, z) in symbol_column.iter_mut().zip(&column) {
                *s = z.re * scale;
            }
        }
        symbol
    }

    fn apply_1d(&self, u: &[f64], out: &mut [f64], spectrum: &mut [C64], lane: &mut Lane) {
        self.forward_row(u, &mut lane.real, spectrum, &mut lane.scratch);
        for (z, &s) in spectrum.iter_mut().zip(&self.symbol) {
            *z *= s;
        }
        self.inverse_row(spectrum, u, out, &mut lane.real, &mut lane.scratch);
    }

    fn apply_2d(
        &self,
        u: &[f64],
        out: &mut [f64],
        rows: &mut [C64],
        columns: &mut [C64],
        lanes: &mut [Lane],
    ) {
        let (nx, ny, py, k) = (self.nx, self.ny, self.py, self.frequencies());
        let tasks = lanes.len();
        // Rows: u zero-padded to px, to their spectra.
        let rows_per_task = ny.div_ceil(tasks);
        rows.par_chunks_mut(rows_per_task * k)
            .zip(u.par_chunks(rows_per_task * nx))
            .zip(lanes.par_iter_mut())
            .for_each(|((spectra, u_rows), lane)| {
                for (spectrum, u_row) in spectra.chunks_mut(k).zip(u_rows.chunks(nx)) {
                    self.forward_row(u_row, &mut lane.real, spectrum, &mut lane.scratch);
                }
            });
        // Columns: BLOCK at a time gathered, zero-padded, filtered, and their first ny values
        // kept.
        let rows = &rows[..];
        let blocks_per_task = k.div_ceil(BLOCK).div_ceil(tasks);
        columns
            .par_chunks_mut(blocks_per_task * BLOCK * ny)
            .zip(lanes.par_iter_mut())
            .enumerate()
            .for_each(|(t, (task_columns, lane))| {
                let first = t * blocks_per_task * BLOCK;
                for (b, kept) in task_columns.chunks_mut(BLOCK * ny).enumerate() {
                    let f0 = first + b * BLOCK;
                    let width = kept.len() / ny;
                    let block = &mut lane.block[..width * py];
                    for (c, column) in block.chunks_mut(py).enumerate() {
                        for (y, value) in column[..ny].iter_mut().enumerate() {
                            *value = rows[y * k + f0 + c];
                        }
                        column[ny..].fill(C64::default());
                    }
                    self.columns_forward
                        .process_with_scratch(block, &mut lane.scratch);
                    for (column, symbol) in
                        block.chunks_mut(py).zip(self.symbol[f0 * py..].chunks(py))
                    {
                        for (z, &s) in column.iter_mut().zip(symbol) {
                            *z *= s;
                        }
                    }
                    self.columns_inverse
                        .process_with_scratch(block, &mut lane.scratch);
                    for (column, kept) in block.chunks(py).zip(kept.chunks_mut(ny)) {
                        kept.copy_from_slice(&column[..ny]);
                    }
                }
            });
        // Rows again: BLOCK rows gathered from the columns, back to real values, minus W u.
        let columns = &columns[..];
        let blocks_per_task = ny.div_ceil(BLOCK).div_ceil(tasks);
        out.par_chunks_mut(blocks_per_task * BLOCK * nx)
            .zip(u.par_chunks(blocks_per_task * BLOCK * nx))
            .zip(lanes.par_iter_mut())
            .enumerate()
            .for_each(|(t, ((out_rows, u_rows), lane))| {
                let first = t * blocks_per_task * BLOCK;
                for (b, (out_block, u_block)) in out_rows
                    .chunks_mut(BLOCK * nx)
                    .zip(u_rows.chunks(BLOCK * nx))
                    .enumerate()
                {
                    let y0 = first + b * BLOCK;
                    let height = out_block.len() / nx;
                    let spectra = &mut lane.block[..height * k];
                    for (f, column) in columns.chunks(ny).enumerate() {
                        for (r, value) in column[y0..y0 + height].iter().enumerate() {
                            spectra[r * k + f] = *value;
                        }
                    }
                    for ((spectrum, u_row), out_row) in spectra
                        .chunks_mut(k)
                        .zip(u_block.chunks(nx))
                        .zip(out_block.chunks_mut(nx))
                    {
                        self.inverse_row(
                            spectrum,
                            u_row,
                            out_row,
                            &mut lane.real,
                            &mut lane.scratch,
                        );
                    }
                }
            });
    }

    /// The spectrum of one row of u, zero-padded to px.
    fn forward_row(
        &self,
        u_row: &[f64],
        real: &mut [f64],
        spectrum: &mut [C64],
        scratch: &mut [C64],
    ) {
        real[..self.nx].copy_from_slice(u_row);
        real[self.nx..].fill(0.0);
        self.rows_forward
            .process_with_scratch(real, spectrum, scratch)
            .expect("buffer lengths come from the plan");
    }

    /// out = (K ∗ u on the row, from its filtered spectrum) − W u.
    fn inverse_row(
        &self,
        spectrum: &mut [C64],
        u_row: &[f64],
        out: &mut [f64],
        real: &mut [f64],
        scratch: &mut [C64],
    ) {
        // The transform of a real row has real end values; round-off left imaginary parts there.
        spectrum[0].im = 0.0;
        if self.px.is_multiple_of(2) {
            spectrum[self.px / 2].im = 0.0;
        }
        self.rows_inverse
            .process_with_scratch(spectrum, real, scratch)
            .expect("buffer lengths come from the plan");
        for ((o, &convolved), &ui) in out.iter_mut().zip(&real[..self.nx]).zip(u_row) {
            *o = convolved - self.total_weight * ui;
        }
    }
}

impl LinearOperator for FftOperator {
    type Workspace = FftWorkspace;

    fn workspace(&self) -> FftWorkspace {
        let (ny, k) = (self.ny, self.frequencies());
        FftWorkspace {
            rows: vec![C64::default(); ny * k],
            columns: vec![C64::default(); if self.dim == 2 { ny * k } else { 0 }],
            lanes: (0..row_tasks(self.dim, self.ny))
                .map(|_| self.new_lane())
                .collect(),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], work: &mut FftWorkspace) {
        let FftWorkspace {
            rows,
            columns,
            lanes,
        } = work;
        // One lane per task; more are made if the workspace moved to a larger pool.
        let tasks = row_tasks(self.dim, self.ny);
        while lanes.len() < tasks {
            lanes.push(self.new_lane());
        }
        if self.dim == 2 {
            self.apply_2d(u, out, rows, columns, &mut lanes[..tasks]);
        } else {
            self.apply_1d(u, out, rows, &mut lanes[0]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};

    /// Convolving a window of D (values zero outside it) gives L_h of the whole field at every
    /// window node whose ball lies inside the window or crosses only D's boundary: a rank's
    /// owned nodes, whose ghosts its window holds. Windows on an edge, in a corner, inside, and
    /// spanning D along y.
    #[test]
    fn a_window_convolution_is_l_h_where_the_window_holds_the_ball() {
        let grid = Grid::new(2, 40);
        let stencil = Stencil::new(
            grid,
            Horizon::from_m(&grid, 5),
            Kernel::Linear,
            Quadrature::Midpoint,
            1.0,
        );
        let reach = stencil.reach();
        let u: Vec<f64> = (0..grid.nodes())
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let mut whole = vec![0.0; u.len()];
        FftOperator::new(&stencil).apply_once(&u, &mut whole);
        for (x0, y0, nx, ny) in [
            (0, 0, 40, 17),
            (0, 23, 21, 17),
            (7, 9, 25, 20),
            (12, 0, 16, 40),
        ] {
            let window = Window { x0, y0, nx, ny };
            let values: Vec<f64> = (0..window.len())
                .map(|w| {
                    let (x, y) = window.column_row(w);
                    u[y * grid.n + x]
                })
                .collect();
            let mut convolved = vec![0.0; window.len()];
            FftOperator::on_window(&stencil, window).apply_once(&values, &mut convolved);
            // The ball of (x, y) within the window along each axis, or past D's edge.
            let held = |at: usize, start: usize, len: usize| {
                (at >= start + reach || start == 0)
                    && (at + reach < start + len || start + len == grid.n)
            };
            let mut checked = 0;
            for (w, value) in convolved.iter().enumerate() {
                let (x, y) = window.column_row(w);
                if held(x, x0, nx) && held(y, y0, ny) {
                    let expected = whole[y * grid.n + x];
                    assert!(
                        (value - expected).abs() < 1e-12 * stencil.total_weight,
                        "window {window:?}, node ({x}, {y}): {value} vs {expected}"
                    );
                    checked += 1;
                }
            }
            assert!(checked > 0, "window {window:?} holds a ball");
        }
    }
}
