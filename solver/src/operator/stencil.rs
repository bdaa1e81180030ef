//! The stencil backend: L_h u_i = Σ_o w_o u_{i+o} − W u_i with precomputed weights, accumulated a
//! whole row segment at a time per offset, so the inner loop is a contiguous axpy the compiler
//! vectorises.

use super::NonlocalOperator;
use crate::stencil::Stencil;
use rayon::prelude::*;

/// Work unit in 1D, where there are no rows to split the work by.
const SEGMENT_1D: usize = 4096;

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
        // A block never straddles two rows: a whole row in 2D, a fixed-length segment in 1D, so the
        // blocks (and therefore the rounding) do not depend on the thread count.
        let block = if grid.dim == 2 { n } else { SEGMENT_1D.min(n) };
        let total_weight = self.stencil.total_weight;
        out.par_chunks_mut(block)
            .enumerate()
            .for_each(|(b, out_block)| {
                let start = b * block;
                let (iy, x0) = (start / n, start % n);
                let x1 = x0 + out_block.len();
                let own_row = &u[iy * n..(iy + 1) * n];
                for (o, &ui) in out_block.iter_mut().zip(&own_row[x0..x1]) {
                    *o = -total_weight * ui;
                }
                for row in &self.stencil.rows {
                    let jy = iy as i64 + row.dy;
                    if jy < 0 || jy >= n as i64 {
                        continue; // a collar row: u = 0 there
                    }
                    let source = &u[jy as usize * n..(jy as usize + 1) * n];
                    for (dx, w) in row.bonds() {
                        // Columns whose neighbour ix + dx lies in D; the collar adds nothing.
                        let lo = (x0 as i64).max(-dx);
                        let hi = (x1 as i64).min(n as i64 - dx);
                        if lo >= hi {
                            continue;
                        }
                        let target =
                            &mut out_block[(lo - x0 as i64) as usize..(hi - x0 as i64) as usize];
                        let shifted = &source[(lo + dx) as usize..(hi + dx) as usize];
                        for (o, &s) in target.iter_mut().zip(shifted) {
                            *o += w * s;
                        }
                    }
                }
            });
    }
}
