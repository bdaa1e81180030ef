//! The timed loop every time-dependent method shares: each step's wall time, divergence caught
//! the step it happens at (every step returns max |u|, found in the update pass at no extra
//! cost), and untimed observers (error bookkeeping, c_tot(t), frames) kept out of the timings.

use crate::case::Case;
use crate::output::diagnostics::{self, MassSampling, MassSeries, Schedule};
use crate::output::field::Frame;
use crate::output::record::ImplicitSolves;
use std::borrow::Cow;
use std::time::Instant;

/// Most step times kept for the median: longer runs time every k-th step.
pub(crate) const MAX_TIMED_STEPS: usize = 1 << 20;

pub struct Stepping {
    pub dt: f64,
    pub steps: usize,
    /// A step whose max |u| exceeds this (or is not finite) ends the run as diverged.
    pub divergence_bound: f64,
    pub track_total_error: bool,
    /// h^d, for the error norms and c_tot.
    pub volume: f64,
    /// Time between samples of c_tot(t), when the case asks for the series.
    pub diagnostics_every: Option<f64>,
    /// Time between frames of the field, when the case asks for them.
    pub vtk_every: Option<f64>,
}

impl Stepping {
    /// The stepping a case asks for, once its dt, step count and divergence bound are resolved.
    pub fn of_case(case: &Case, dt: f64, steps: usize, divergence_bound: f64, volume: f64) -> Self {
        Stepping {
            dt,
            steps,
            divergence_bound,
            track_total_error: case.error_total,
            volume,
            diagnostics_every: case.diagnostics_every,
            vtk_every: case.vtk_every,
        }
    }
}

pub struct Trajectory {
    pub u: Vec<f64>,
    pub timing: Timing,
    /// e = Σₖ eᵏ over k = 0 ..= steps_done, when tracked.
    pub error_total: Option<f64>,
    pub c_tot: Option<MassSeries>,
    /// The field at t = 0 and at each due step (when the case sets `vtk_every`).
    pub frames: Vec<Frame>,
    /// Median seconds a step spent communicating (halo and reductions; 0 on one process).
    pub step_comm_s: f64,
    pub implicit: ImplicitSolves,
    /// The step's measured amplification (`integrate::amplification`), when the case asks.
    pub amplification: Option<f64>,
    /// The step's measured positivity (`integrate::amplification::positivity`), with it.
    pub positivity: Option<f64>,
}

impl Trajectory {
    /// The trajectory of what a timed loop observed, with no total error.
    pub(crate) fn observed(u: Vec<f64>, timing: Timing, observed: Observed) -> Self {
        Trajectory {
            u,
            timing,
            error_total: None,
            c_tot: observed.c_tot,
            frames: observed.frames,
            step_comm_s: 0.0,
            implicit: ImplicitSolves::default(),
            amplification: None,
            positivity: None,
        }
    }
}

/// What a timed loop of steps measured.
pub struct Timing {
    pub steps_done: usize,
    /// The step after which the solution exceeded the bound.
    pub diverged_at: Option<usize>,
    /// Wall time of the time loop, untimed bookkeeping excluded.
    pub solve_seconds: f64,
    /// Wall time of every step, or of every k-th step in runs longer than `MAX_TIMED_STEPS`.
    pub step_seconds: Vec<f64>,
    /// The largest max |u| of any step (finite ones): how far the run grew, diverged or not.
    pub peak_max_abs: f64,
}

/// Is step k of `steps` one whose time is kept (every k-th in runs longer than `MAX_TIMED_STEPS`)?
pub(crate) fn is_sampled(steps: usize, k: usize) -> bool {
    k.is_multiple_of(steps.div_ceil(MAX_TIMED_STEPS).max(1))
}

/// The time loop every solver shares: up to `steps` timed calls of `step(state, k)`, which
/// advances from step k and returns max |u| after it; the loop ends at the first step whose max
/// |u| exceeds `bound` or is not finite (whatever the bound). `after(state, k + 1)` runs untimed
/// after every step that did not diverge (error bookkeeping).
pub(crate) fn timed_steps<S>(
    state: &mut S,
    steps: usize,
    bound: f64,
    mut step: impl FnMut(&mut S, usize) -> f64,
    mut after: impl FnMut(&S, usize),
) -> Timing {
    let mut timing = Timing {
        steps_done: 0,
        diverged_at: None,
        solve_seconds: 0.0,
        step_seconds: Vec::with_capacity(steps.min(MAX_TIMED_STEPS)),
        peak_max_abs: 0.0,
    };
    for k in 0..steps {
        let started = Instant::now();
        let max_abs = step(state, k);
        let seconds = started.elapsed().as_secs_f64();
        timing.solve_seconds += seconds;
        if is_sampled(steps, k) {
            timing.step_seconds.push(seconds);
        }
        timing.steps_done = k + 1;
        if max_abs.is_finite() {
            timing.peak_max_abs = timing.peak_max_abs.max(max_abs);
        }
        // A non-finite max |u| is diverged whatever the bound (a NaN compares false, and an
        // infinite bound would let +∞ through).
        if !(max_abs.is_finite() && max_abs <= bound) {
            timing.diverged_at = Some(k + 1);
            break;
        }
        after(state, k + 1);
    }
    timing
}

/// What the untimed observers of a run kept: c_tot(t) and the field's frames.
pub(crate) struct Observed {
    pub c_tot: Option<MassSeries>,
    pub frames: Vec<Frame>,
}

/// `timed_steps` over `stepping`'s steps, also sampling c_tot = h^d Σ field(state) and frames of
/// `field(state)` (in lattice order) when the case asks for them.
pub(crate) fn timed_steps_observed<S>(
    state: &mut S,
    stepping: &Stepping,
    field: impl Fn(&S) -> Cow<'_, [f64]>,
    step: impl FnMut(&mut S, usize) -> f64,
    mut after: impl FnMut(&S, usize),
) -> (Timing, Observed) {
    let mass = |state: &S| diagnostics::total_mass(&field(state), stepping.volume);
    let mut c_tot = MassSampling::start(
        stepping.diagnostics_every,
        stepping.dt,
        stepping.steps,
        mass(state),
    );
    let mut frames = Vec::new();
    let mut frame_schedule = stepping.vtk_every.map(|every| {
        let schedule = Schedule::new(every, stepping.dt, stepping.steps);
        frames.push(Frame {
            time: 0.0,
            values: field(state).into_owned(),
        });
        schedule
    });
    let timing = timed_steps(
        state,
        stepping.steps,
        stepping.divergence_bound,
        step,
        |state, k| {
            after(state, k);
            MassSampling::observe_if(&mut c_tot, k, || mass(state));
            if let Some(schedule) = frame_schedule.as_mut() {
                if schedule.due(k) {
                    frames.push(Frame {
                        time: schedule.time(k),
                        values: field(state).into_owned(),
                    });
                }
            }
        },
    );
    let c_tot = c_tot.map(|sampling| sampling.series);
    (timing, Observed { c_tot, frames })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps that return the given max |u|, in turn: where does the loop stop?
    fn diverged_at(maxima: &[f64], bound: f64) -> Option<usize> {
        let mut state = 0;
        timed_steps(&mut state, maxima.len(), bound, |_, k| maxima[k], |_, _| {}).diverged_at
    }

    #[test]
    fn a_field_that_is_not_finite_diverges_whatever_the_bound() {
        for bound in [1e6, f64::MAX, f64::INFINITY] {
            assert_eq!(
                diverged_at(&[1.0, f64::INFINITY, 1.0], bound),
                Some(2),
                "{bound}"
            );
            assert_eq!(
                diverged_at(&[1.0, 2.0, f64::NAN], bound),
                Some(3),
                "{bound}"
            );
        }
        assert_eq!(diverged_at(&[1.0, 2.0, 3.0], f64::MAX), None);
        assert_eq!(diverged_at(&[1.0, 2e6], 1e6), Some(2));
    }
}
