//! Forward Euler (eq. 2.1) for u' = L u + b(t), on one process or over ranks.
//!
//! Each step applies the operator once and then updates u in one pass that adds the source and
//! finds max |u|. Nothing is allocated inside the loop. The update splits u at fixed blocks, so
//! the field does not depend on the thread count, and it is the same per node on any number of
//! ranks.

use super::stepper::{Rhs, Stepper};
use crate::operator::LinearOperator;
use crate::output::diagnostics;
use crate::parallel::exchange::Ranks;
use crate::problem::Source;
use crate::threads::BLOCK;
use rayon::prelude::*;

pub struct ForwardEuler<'a, Op: LinearOperator> {
    rhs: Rhs<'a, Op>,
    lu: Vec<f64>,
}

impl<'a, Op: LinearOperator> ForwardEuler<'a, Op> {
    /// For vectors of `len` values (a rank's own nodes).
    pub fn new(operator: &'a Op, source: Option<&'a Source>, ranks: Ranks<'a>, len: usize) -> Self {
        ForwardEuler {
            rhs: Rhs::new(operator, source, ranks),
            lu: vec![0.0; len],
        }
    }
}

impl<Op: LinearOperator> Stepper for ForwardEuler<'_, Op> {
    fn step(&mut self, u: &mut [f64], t: f64, dt: f64) -> f64 {
        self.rhs.apply(u, &mut self.lu);
        let (lu, source, ranks) = (&self.lu[..], self.rhs.source, self.rhs.ranks);
        let local_max = ranks.on(|| match source {
            Some(source) => {
                let (alpha, beta) = Source::coefficients(t);
                update(u, lu, dt, |i, l| {
                    l + alpha * source.phi[i] + beta * source.psi[i]
                })
            }
            None => update(u, lu, dt, |_, l| l),
        });
        ranks.max(local_max)
    }

    fn applications(&self) -> Option<usize> {
        Some(self.rhs.applications)
    }
}

/// uᵢ += dt · rate(i, (L u)ᵢ); returns max |uᵢ| after the update (+∞ if any is NaN).
fn update(u: &mut [f64], lu: &[f64], dt: f64, rate: impl Fn(usize, f64) -> f64 + Sync) -> f64 {
    u.par_chunks_mut(BLOCK)
        .zip(lu.par_chunks(BLOCK))
        .enumerate()
        .map(|(b, (u_block, lu_block))| {
            for (k, (ui, &l)) in u_block.iter_mut().zip(lu_block).enumerate() {
                *ui += dt * rate(b * BLOCK + k, l);
            }
            diagnostics::block_max_abs(u_block)
        })
        .reduce(|| 0.0, f64::max)
}
