//! The stencil backend: L_h u_i = Σ_o w_o u_{i+o} − W u_i with precomputed weights.
//!
//! The serial kernel copies u once per application into a buffer with a zero collar of width
//! `reach`, so no bond needs a bounds check, and then register-blocks: a block of `LANES`
//! consecutive outputs of a row stays in registers while every bond of the stencil is added to it
//! (one load, one multiply and one add per bond and lane, no store). The distributed solver's
//! windows use `row_segment`, which sums in the same order, so both agree bit for bit.

use super::interface::NonlocalOperator;
use crate::discretization::grid::RowRun;
use crate::discretization::grid::Window;
use crate::discretization::stencil::Stencil;
use crate::threads::BLOCK;
use rayon::prelude::*;
use std::sync::Mutex;

/// Outputs summed together in registers: enough independent accumulators to hide the latency of
/// the additions (8 vectors of the widest unit the build targets).
const LANES: usize = if cfg!(target_feature = "avx512f") {
    64
} else if cfg!(target_feature = "avx") {
    32
} else {
    16
};

/// Rows per task in 2D, and the width of the column tiles each task sweeps its rows by.
const BAND: usize = 16;
const TILE: usize = 1024;

pub struct StencilOperator {
    stencil: Stencil,
    /// Every bond in summation order (rows by dy, then dx), as its weight and the distance from a
    /// node to its neighbour in `padded`.
    weights: Vec<f64>,
    shifts: Vec<isize>,
    /// dy of each bond, for finding the bonds whose row lies in D.
    bond_dy: Vec<i64>,
    /// Largest |dx| or |dy| of a bond: the width of the zero collar in `padded`.
    reach: usize,
    /// u on D, surrounded by `reach` zeros on every side (in 1D only along x).
    padded: Mutex<Vec<f64>>,
}

impl StencilOperator {
    pub fn new(stencil: Stencil) -> Self {
        let reach = stencil.reach();
        let grid = stencil.grid;
        let width = (grid.n + 2 * reach) as isize;
        let (mut weights, mut shifts, mut bond_dy) = (Vec::new(), Vec::new(), Vec::new());
        for row in &stencil.rows {
            for (dx, w) in row.bonds() {
                weights.push(w);
                shifts.push(row.dy as isize * width + dx as isize);
                bond_dy.push(row.dy);
            }
        }
        let padded_rows = if grid.dim == 2 { grid.n + 2 * reach } else { 1 };
        let padded = vec![0.0; (grid.n + 2 * reach) * padded_rows];
        StencilOperator {
            stencil,
            weights,
            shifts,
            bond_dy,
            reach,
            padded: Mutex::new(padded),
        }
    }
}

impl NonlocalOperator for StencilOperator {
    fn apply(&self, u: &[f64], out: &mut [f64]) {
        let grid = self.stencil.grid;
        let (n, reach) = (grid.n, self.reach);
        let width = n + 2 * reach;
        let mut padded = self
            .padded
            .lock()
            .unwrap_or_else(|poison| poison.into_inner());
        // Only the interior changes: the collar was zeroed when the buffer was made.
        let first_row = if grid.dim == 2 { reach } else { 0 };
        padded[first_row * width..]
            .par_chunks_mut(width)
            .zip(u.par_chunks(n))
            .for_each(|(padded_row, u_row)| padded_row[reach..reach + n].copy_from_slice(u_row));
        let padded = &padded[..];
        if grid.dim == 1 {
            out.par_chunks_mut(BLOCK)
                .enumerate()
                .for_each(|(b, segment)| {
                    self.padded_segment(padded, 0, b * BLOCK, segment);
                });
            return;
        }
        // Each task takes a band of rows and sweeps it one column tile at a time, so the source
        // rows a tile reads (2·reach + 1 of them) stay in cache from one output row to the next.
        let tile = TILE.min(n);
        out.par_chunks_mut(BAND * n)
            .enumerate()
            .for_each(|(b, band)| {
                for x0 in (0..n).step_by(tile) {
                    for (r, row) in band.chunks_mut(n).enumerate() {
                        let width = tile.min(n - x0);
                        self.padded_segment(padded, b * BAND + r, x0, &mut row[x0..x0 + width]);
                    }
                }
            });
    }
}

impl StencilOperator {
    /// out[k] = (L_h u) at node (x0 + k, y), from the zero-collared copy of u.
    fn padded_segment(&self, padded: &[f64], y: usize, x0: usize, out: &mut [f64]) {
        let grid = &self.stencil.grid;
        let (n, reach) = (grid.n, self.reach);
        let width = n + 2 * reach;
        // The bonds whose row lies in D (collar rows add nothing); bonds are sorted by dy.
        let rows = grid.rows() as i64;
        let in_d = |dy: &i64| (0..rows).contains(&(y as i64 + dy));
        let first = self.bond_dy.partition_point(|dy| !in_d(dy) && *dy < 0);
        let last = first + self.bond_dy[first..].partition_point(in_d);
        let (weights, shifts) = (&self.weights[first..last], &self.shifts[first..last]);
        let centre = if grid.dim == 2 {
            (y + reach) * width
        } else {
            0
        } + reach
            + x0;
        let total_weight = self.stencil.total_weight;
        let mut x = 0;
        while x + LANES <= out.len() {
            let own = centre + x;
            let mut acc = [0.0; LANES];
            for (a, &ui) in acc.iter_mut().zip(&padded[own..own + LANES]) {
                *a = -total_weight * ui;
            }
            for (&w, &shift) in weights.iter().zip(shifts) {
                let from = own.wrapping_add_signed(shift);
                let s: &[f64; LANES] = padded[from..from + LANES].try_into().unwrap();
                for l in 0..LANES {
                    acc[l] += w * s[l];
                }
            }
            out[x..x + LANES].copy_from_slice(&acc);
            x += LANES;
        }
        // The last partial block, one output at a time in the same order.
        for (k, o) in out.iter_mut().enumerate().skip(x) {
            let own = centre + k;
            *o = -total_weight * padded[own];
            for (&w, &shift) in weights.iter().zip(shifts) {
                *o += w * padded[own.wrapping_add_signed(shift)];
            }
        }
    }
}

/// out[k] = (L_h u) at node (x0 + k, y) of D, where `u` holds the values on `window`, which must
/// contain every node of D within reach of the segment. Each value is summed in the same order
/// (−W uᵢ first, then the stencil rows and columns in order) whatever the window or segment, so
/// serial, threaded and distributed runs agree bit for bit.
pub(crate) fn row_segment(
    stencil: &Stencil,
    u: &[f64],
    window: &Window,
    y: usize,
    x0: usize,
    out: &mut [f64],
) {
    let n = stencil.grid.n as i64;
    let rows = stencil.grid.rows() as i64;
    let x1 = x0 + out.len();
    let own_row = window.index(x0, y);
    for (o, &ui) in out.iter_mut().zip(&u[own_row..own_row + (x1 - x0)]) {
        *o = -stencil.total_weight * ui;
    }
    for row in &stencil.rows {
        let jy = y as i64 + row.dy;
        if jy < 0 || jy >= rows {
            continue; // a collar row: u = 0 there
        }
        let jy = jy as usize;
        for (dx, w) in row.bonds() {
            // Columns whose neighbour x + dx lies in D; the collar adds nothing.
            let lo = (x0 as i64).max(-dx);
            let hi = (x1 as i64).min(n - dx);
            if lo >= hi {
                continue;
            }
            let target = &mut out[(lo - x0 as i64) as usize..(hi - x0 as i64) as usize];
            let from = window.index((lo + dx) as usize, jy);
            let shifted = &u[from..from + target.len()];
            for (o, &s) in target.iter_mut().zip(shifted) {
                *o += w * s;
            }
        }
    }
}

/// out = L_h u on the nodes of `runs`, whose compact offsets start at `runs[0].offset` with
/// out[0]; `u` holds the values on `window`. Runs are split between threads, each value still
/// summed by `row_segment` alone.
pub(crate) fn apply_on_runs(
    stencil: &Stencil,
    window: &Window,
    runs: &[RowRun],
    u: &[f64],
    out: &mut [f64],
) {
    let Some(first) = runs.first() else { return };
    if runs.len() == 1 || out.len() <= BLOCK {
        for run in runs {
            let at = run.offset - first.offset;
            row_segment(
                stencil,
                u,
                window,
                run.y,
                run.x0,
                &mut out[at..at + run.len()],
            );
        }
        return;
    }
    let mid = runs.len() / 2;
    let (left, right) = out.split_at_mut(runs[mid].offset - first.offset);
    rayon::join(
        || apply_on_runs(stencil, window, &runs[..mid], u, left),
        || apply_on_runs(stencil, window, &runs[mid..], u, right),
    );
}
