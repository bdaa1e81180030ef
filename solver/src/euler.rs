//! Forward Euler (eq. 2.1) for u' = L_h u + b: the timed loop.
//!
//! Each step applies the operator once and then updates u in one pass that also finds max |u|,
//! so that divergence is caught the step it happens at no extra cost. Nothing is allocated inside
//! the loop. Error bookkeeping (the total error e = Σₖ eᵏ, when asked) is kept out of the timings.

use crate::diagnostics;
use crate::operator::NonlocalOperator;
use crate::problem::{manufactured_solution, Source};
use rayon::prelude::*;
use std::time::Instant;

/// Update block; fixed so the update never depends on the thread count.
const BLOCK: usize = 4096;
/// Most step times kept for the median: longer runs time every k-th step.
pub(crate) const MAX_TIMED_STEPS: usize = 1 << 20;

pub struct Stepping {
    pub dt: f64,
    pub steps: usize,
    /// A step whose max |u| exceeds this (or is not finite) ends the run as diverged.
    pub divergence_bound: f64,
    pub track_total_error: bool,
    /// h^d, for the error norms.
    pub volume: f64,
}

pub struct Trajectory {
    pub u: Vec<f64>,
    pub steps_done: usize,
    /// The step after which the solution exceeded the bound.
    pub diverged_at: Option<usize>,
    /// Wall time of the time loop, error bookkeeping excluded.
    pub solve_seconds: f64,
    /// Wall time of every step, or of every k-th step in runs longer than `MAX_TIMED_STEPS`.
    pub step_seconds: Vec<f64>,
    /// e = Σₖ eᵏ over k = 0 ..= steps_done, when tracked.
    pub error_total: Option<f64>,
}

pub fn forward_euler(
    operator: &dyn NonlocalOperator,
    mut u: Vec<f64>,
    source: Option<&Source>,
    stepping: &Stepping,
) -> Trajectory {
    let dt = stepping.dt;
    let mut lu = vec![0.0; u.len()];
    let total_error_source = source.filter(|_| stepping.track_total_error);
    let squared_error = |u: &[f64], t: f64| {
        total_error_source.map_or(0.0, |s| {
            diagnostics::squared_l2_error(manufactured_solution(&s.phi, t), u, stepping.volume)
        })
    };
    let mut error_total = squared_error(&u, 0.0);

    let stride = stepping.steps.div_ceil(MAX_TIMED_STEPS).max(1);
    let mut step_seconds = Vec::with_capacity(stepping.steps.min(MAX_TIMED_STEPS));
    let mut solve_seconds = 0.0;
    let mut steps_done = 0;
    let mut diverged_at = None;
    for k in 0..stepping.steps {
        let t = k as f64 * dt;
        let started = Instant::now();
        operator.apply(&u, &mut lu);
        let max_abs = match source {
            Some(source) => {
                let (alpha, beta) = Source::coefficients(t);
                update(&mut u, &lu, dt, |i, l| {
                    l + alpha * source.phi[i] + beta * source.psi[i]
                })
            }
            None => update(&mut u, &lu, dt, |_, l| l),
        };
        let seconds = started.elapsed().as_secs_f64();
        solve_seconds += seconds;
        if k % stride == 0 {
            step_seconds.push(seconds);
        }
        steps_done = k + 1;
        if !(max_abs <= stepping.divergence_bound) {
            diverged_at = Some(steps_done);
            break;
        }
        error_total += squared_error(&u, steps_done as f64 * dt);
    }
    Trajectory {
        u,
        steps_done,
        diverged_at,
        solve_seconds,
        step_seconds,
        error_total: (total_error_source.is_some() && diverged_at.is_none()).then_some(error_total),
    }
}

/// uᵢ += dt · rate(i, (L_h u)ᵢ); returns max |uᵢ| after the update (+∞ if any is NaN).
fn update(u: &mut [f64], lu: &[f64], dt: f64, rate: impl Fn(usize, f64) -> f64 + Sync) -> f64 {
    u.par_chunks_mut(BLOCK)
        .zip(lu.par_chunks(BLOCK))
        .enumerate()
        .map(|(b, (u_block, lu_block))| {
            let mut block_max: f64 = 0.0;
            for (k, (ui, &l)) in u_block.iter_mut().zip(lu_block).enumerate() {
                *ui += dt * rate(b * BLOCK + k, l);
                block_max = block_max.max(diagnostics::magnitude(*ui));
            }
            block_max
        })
        .reduce(|| 0.0, f64::max)
}
