//! Forward Euler (eq. 2.1) for u' = L u + b(t), on one process or over ranks.
//!
//! Each step applies the operator once and then updates u in one pass that also finds max |u|.
//! Nothing is allocated inside the loop. The update splits u at fixed blocks, so the field does
//! not depend on the thread count, and it is the same per node on any number of ranks.

use super::timed::{is_sampled, timed_steps_observed, Stepping, Trajectory, MAX_TIMED_STEPS};
use crate::operator::LinearOperator;
use crate::output::diagnostics;
use crate::parallel::exchange::Ranks;
use crate::problem::{manufactured_solution, Source};
use crate::threads::BLOCK;
use rayon::prelude::*;
use std::borrow::Cow;

/// One forward Euler step after another, with the operator's workspace and L u kept between
/// steps.
pub struct ForwardEuler<'a, Op: LinearOperator> {
    operator: &'a Op,
    workspace: Op::Workspace,
    source: Option<&'a Source>,
    ranks: Ranks<'a>,
    lu: Vec<f64>,
}

impl<'a, Op: LinearOperator> ForwardEuler<'a, Op> {
    /// For vectors of `len` values (a rank's own nodes).
    pub fn new(operator: &'a Op, source: Option<&'a Source>, ranks: Ranks<'a>, len: usize) -> Self {
        ForwardEuler {
            workspace: operator.workspace(),
            operator,
            source,
            ranks,
            lu: vec![0.0; len],
        }
    }

    /// u ← u + dt (L u + b(t)); returns max |u| after the step over all ranks (+∞ if any is NaN).
    pub fn step(&mut self, u: &mut [f64], t: f64, dt: f64) -> f64 {
        self.operator.apply(u, &mut self.lu, &mut self.workspace);
        let (lu, source) = (&self.lu[..], self.source);
        let local_max = self.ranks.on(|| match source {
            Some(source) => {
                let (alpha, beta) = Source::coefficients(t);
                update(u, lu, dt, |i, l| {
                    l + alpha * source.phi[i] + beta * source.psi[i]
                })
            }
            None => update(u, lu, dt, |_, l| l),
        });
        self.ranks.max(local_max)
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

/// The timed forward Euler run of `stepping` from u, with the total error e = Σₖ eᵏ against the
/// manufactured solution of `source` when the case tracks it (summed over ranks).
pub fn forward_euler<Op: LinearOperator>(
    operator: &Op,
    ranks: Ranks,
    mut u: Vec<f64>,
    source: Option<&Source>,
    stepping: &Stepping,
) -> Trajectory {
    let (dt, volume) = (stepping.dt, stepping.volume);
    let mut euler = ForwardEuler::new(operator, source, ranks, u.len());
    let total_error_source = source.filter(|_| stepping.track_total_error);
    let squared_error = |u: &[f64], t: f64| {
        total_error_source.map_or(0.0, |s| {
            let local = ranks
                .on(|| diagnostics::squared_l2_error(manufactured_solution(&s.phi, t), u, volume));
            ranks.sum(local)
        })
    };
    let mut error_total = squared_error(&u, 0.0);
    let mut comm_seconds = Vec::with_capacity(stepping.steps.min(MAX_TIMED_STEPS));
    let (timing, observed) = timed_steps_observed(
        &mut u,
        stepping,
        |u| Cow::Borrowed(u),
        |u, k| {
            let comm_before = ranks.exchange.seconds();
            let max_abs = euler.step(u, k as f64 * dt, dt);
            if is_sampled(stepping.steps, k) {
                comm_seconds.push(ranks.exchange.seconds() - comm_before);
            }
            max_abs
        },
        |u, steps_done| error_total += squared_error(u, steps_done as f64 * dt),
    );
    let tracked = total_error_source.is_some() && timing.diverged_at.is_none();
    Trajectory {
        error_total: tracked.then_some(error_total),
        step_comm_s: diagnostics::median(comm_seconds),
        ..Trajectory::observed(u, timing, observed)
    }
}
