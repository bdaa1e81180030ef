//! The stencil backend: L_h u_i = Σ_o w_o u_{i+o} − W u_i with precomputed weights, accumulated a
//! whole row segment at a time per offset, so the inner loop is a contiguous axpy the compiler
//! vectorises.

use super::NonlocalOperator;
use crate::grid::Window;
use crate::stencil::Stencil;
use crate::subdomain::Run;
use rayon::prelude::*;

/// Work unit in 1D, where there are no rows to split the work by.
pub(crate) const SEGMENT_1D: usize = 4096;

pub struct StencilOperator {
    stencil: Stencil,
}

impl StencilOperator {
    pub fn new(stencil: Stencil) -> Self {
        StencilOperator { stencil }
    }
}

impl NonlocalOperator for StencilOperator {
    fn apply(&self, u: &[f64], out: &mut [f64]) {
        let grid = self.stencil.grid;
        let n = grid.n;
        let whole = Window::whole(&grid);
        // A block never straddles two rows: a whole row in 2D, a fixed-length segment in 1D, so the
        // blocks (and therefore the rounding) do not depend on the thread count.
        let block = if grid.dim == 2 { n } else { SEGMENT_1D.min(n) };
        out.par_chunks_mut(block)
            .enumerate()
            .for_each(|(b, out_block)| {
                let start = b * block;
                let (y, x0) = (start / n, start % n);
                row_segment(&self.stencil, u, &whole, y, x0, out_block);
            });
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
    runs: &[Run],
    u: &[f64],
    out: &mut [f64],
) {
    let Some(first) = runs.first() else { return };
    if runs.len() == 1 || out.len() <= SEGMENT_1D {
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
