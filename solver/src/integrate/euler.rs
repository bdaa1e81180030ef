//! Forward Euler (eq. 2.1) for u' = L_h u + b: the timed loop.
//!
//! Each step applies the operator once and then updates u in one pass that also finds max |u|,
//! so that divergence is caught the step it happens at no extra cost. Nothing is allocated inside
//! the loop. Error bookkeeping (the total error e = Σₖ eᵏ, when asked) is kept out of the timings.

use crate::case::Case;
use crate::discretization::grid::Lattice;
use crate::operator::NonlocalOperator;
use crate::output::diagnostics::median;
use crate::output::diagnostics::{self, MassSeries, Schedule};
use crate::output::field::{FieldSnapshot, Frame};
use crate::output::outcome::{record, Measured, Outcome};
use crate::output::record::{Distribution, Resolved};
use crate::problem::{manufactured_solution, Source};
use crate::threads::BLOCK;
use rayon::prelude::*;
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
}

/// Is step k of `steps` one whose time is kept (every k-th in runs longer than `MAX_TIMED_STEPS`)?
pub(crate) fn is_sampled(steps: usize, k: usize) -> bool {
    k % steps.div_ceil(MAX_TIMED_STEPS).max(1) == 0
}

/// The time loop every solver shares: up to `steps` timed calls of `step(state, k)`, which
/// advances from step k and returns max |u| after it; the loop ends at the first step whose max
/// |u| exceeds `bound` or is not finite. `after(state, k + 1)` runs untimed after every step that
/// did not diverge (error bookkeeping).
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
        if !(max_abs <= bound) {
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
    let mut c_tot = MassSeries::start(
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
            MassSeries::observe_if(&mut c_tot, k, || mass(state));
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
    (timing, Observed { c_tot, frames })
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
    let (timing, observed) = timed_steps_observed(
        &mut u,
        stepping,
        |u| Cow::Borrowed(u),
        |u, k| {
            operator.apply(u, &mut lu);
            match source {
                Some(source) => {
                    let (alpha, beta) = Source::coefficients(k as f64 * dt);
                    update(u, &lu, dt, |i, l| {
                        l + alpha * source.phi[i] + beta * source.psi[i]
                    })
                }
                None => update(u, &lu, dt, |_, l| l),
            }
        },
        |u, steps_done| error_total += squared_error(u, steps_done as f64 * dt),
    );
    let tracked = total_error_source.is_some() && timing.diverged_at.is_none();
    Trajectory {
        error_total: tracked.then_some(error_total),
        ..Trajectory::observed(u, timing, observed)
    }
}

/// uᵢ += dt · rate(i, (L_h u)ᵢ); returns max |uᵢ| after the update (+∞ if any is NaN).
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

/// The outcome of a run in one process: its trajectory measured and recorded, with the errors
/// against `exact` (the exact solution at the final time, by node, when the problem has one).
pub(crate) fn serial_outcome(
    case: &Case,
    resolved: Resolved,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: Trajectory,
    lattice: Lattice,
    exact: Option<&(dyn Fn(usize) -> f64 + Sync)>,
) -> Outcome {
    let Trajectory {
        u,
        timing,
        error_total,
        c_tot,
        frames,
    } = trajectory;
    // A diverged field has no meaningful error.
    let exact = exact.filter(|_| timing.diverged_at.is_none());
    let errors = exact.map(|exact| {
        (
            diagnostics::squared_l2_error(exact, &u, stepping.volume),
            diagnostics::max_error(exact, &u),
        )
    });
    let measured = Measured {
        setup_s,
        solve_s: timing.solve_seconds,
        step_s: median(timing.step_seconds),
        steps_done: timing.steps_done,
        diverged_at: timing.diverged_at,
        divergence_bound: stepping.divergence_bound,
        errors,
        error_total,
        mass: diagnostics::total_mass(&u, stepping.volume),
        max_abs: diagnostics::max_abs(&u),
        c_tot,
        histogram: case
            .histogram_bins
            .and_then(|bins| diagnostics::histogram(&u, bins)),
        field: case
            .field_snapshot
            .map(|side| FieldSnapshot::of(&lattice, &u, exact, side)),
        distribution: Distribution::serial(case),
    };
    Outcome {
        record: record(case, resolved, measured),
        field: u,
        lattice,
        frames,
    }
}
