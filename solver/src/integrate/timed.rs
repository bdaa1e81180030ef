//! The timed loop every time-dependent method shares: each step's wall time, divergence caught
//! the step it happens at (every step returns max |u|, found in the update pass at no extra
//! cost), and untimed observers (error bookkeeping, c_tot(t), frames) kept out of the timings.

use super::checkpoint::{Carried, Checkpointer};
use crate::case::Case;
use crate::output::diagnostics::{self, Amplification, MassSampling, MassSeries, Schedule};
use crate::output::field::Frame;
use crate::output::record::ImplicitSolves;
use std::borrow::Cow;
use std::cell::RefCell;
use std::time::Instant;

/// Most step times kept for the median: longer runs time every k-th step. 2¹⁶ samples give the
/// median to a fraction of a percent, and bound what a checkpoint carries of them (the step
/// and communication times: 1 MiB at most, where 2²⁰ made a checkpoint of a long run 16 MiB
/// larger than its field).
pub(crate) const MAX_TIMED_STEPS: usize = 1 << 16;

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
    /// The times the loop applied the operator, where its stepper counts them.
    pub operator_applications: Option<usize>,
    /// The step's measured amplification (`integrate::amplification`), when the case asks.
    pub amplification: Option<Amplification>,
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
            operator_applications: None,
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
    /// The step the run resumed from, from a checkpoint (0: it started at step 0).
    pub resumed_from_step: usize,
    /// The solve time of each segment of a resumed run (empty for a run in one piece).
    pub segments_s: Vec<f64>,
}

/// A test's hook, `NLSOLVE_TEST_REPEAT_EVERY=k`: every k-th step's work is done twice (on a
/// copy of the state, whose result is let go), so the run does 1/k more work with the numbers of
/// the run without it. What the timing tests compare a build with: a build 1.25× slower (k = 4)
/// or 2 % slower (k = 50) whose records are otherwise the same. Read once per process.
fn extra_work() -> Option<usize> {
    static EVERY: std::sync::OnceLock<Option<usize>> = std::sync::OnceLock::new();
    *EVERY.get_or_init(|| {
        std::env::var("NLSOLVE_TEST_REPEAT_EVERY")
            .ok()
            .and_then(|k| k.parse().ok())
            .filter(|&k| k > 0)
    })
}

/// Is step k of `steps` one whose time is kept (every k-th in runs longer than `MAX_TIMED_STEPS`)?
pub(crate) fn is_sampled(steps: usize, k: usize) -> bool {
    k.is_multiple_of(steps.div_ceil(MAX_TIMED_STEPS).max(1))
}

/// A timed loop's checkpoints: the process's checkpointer (`checkpoint::take`) and the
/// caller's parts of what the run carries from step to step, its field first of all. The
/// caller has taken its parts back from `checkpointer.resume` before the loop starts.
pub(crate) struct Checkpoints<'a, S> {
    pub checkpointer: Checkpointer,
    pub carry: &'a mut dyn FnMut(&S, &mut Carried),
    /// Whether a condition holds on any rank (the condition itself for one process): every
    /// rank checkpoints, and stops, at the same step.
    pub on_any_rank: &'a dyn Fn(bool) -> bool,
}

/// The time loop every solver shares: up to `steps` timed calls of `step(state, k)`, which
/// advances from step k and returns max |u| after it; the loop ends at the first step whose max
/// |u| exceeds `bound` or is not finite (whatever the bound). `after(state, k + 1)` runs untimed
/// after every step that did not diverge (error bookkeeping). With `checkpoints`, a resumed run
/// starts at the checkpoint's step with its timings, and each due step writes a checkpoint.
pub(crate) fn timed_steps<S: Clone>(
    state: &mut S,
    steps: usize,
    bound: f64,
    mut step: impl FnMut(&mut S, usize) -> f64,
    mut after: impl FnMut(&S, usize),
    mut checkpoints: Option<Checkpoints<S>>,
) -> Timing {
    let mut timing = Timing {
        steps_done: 0,
        diverged_at: None,
        solve_seconds: 0.0,
        step_seconds: Vec::with_capacity(steps.min(MAX_TIMED_STEPS)),
        peak_max_abs: 0.0,
        resumed_from_step: 0,
        segments_s: Vec::new(),
    };
    if let Some(resume) = checkpoints
        .as_ref()
        .and_then(|c| c.checkpointer.resume.as_ref())
    {
        timing.take_back(resume);
    }
    let segment_started = timing.solve_seconds;
    let mut reporter = super::progress::take();
    let solving = crate::output::usage::Solving::starts();
    let repeat_every = extra_work();
    for k in timing.steps_done..steps {
        let started = Instant::now();
        if repeat_every.is_some_and(|every| k % every == every - 1) {
            // A test's slower build: this step's work twice, the copy's result let go.
            std::hint::black_box(step(&mut state.clone(), k));
        }
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
        if let Some(reporter) = reporter.as_mut() {
            reporter.note(k + 1, steps);
        }
        if let Some(Checkpoints {
            checkpointer,
            carry,
            on_any_rank,
        }) = checkpoints.as_mut()
        {
            let stop = k + 1 < steps && on_any_rank(super::checkpoint::stop_requested());
            if stop || (k + 1 < steps && on_any_rank(checkpointer.due(k + 1))) {
                let mut carried = Carried::at(k + 1);
                carried.put_count("steps", steps);
                timing.carry(&mut carried, segment_started);
                carry(state, &mut carried);
                checkpointer.save(&carried, &[]);
            }
            // Every rank's file is written before any rank exits.
            if stop && on_any_rank(true) {
                checkpointer.stop("step", k + 1);
            }
        }
    }
    solving.ends();
    if timing.resumed_from_step > 0 {
        timing
            .segments_s
            .push(timing.solve_seconds - segment_started);
    }
    timing
}

impl Timing {
    /// Adds the timings so far to a checkpoint: this segment's time joins the earlier ones'.
    fn carry(&self, carried: &mut Carried, segment_started: f64) {
        carried.put_number("timing.solve_seconds", self.solve_seconds);
        carried.put("timing.step_seconds", self.step_seconds.clone());
        carried.put_number("timing.peak_max_abs", self.peak_max_abs);
        carried.put_count("timing.resumed_from_step", self.resumed_from_step);
        let mut segments = self.segments_s.clone();
        segments.push(self.solve_seconds - segment_started);
        carried.put("timing.segments_s", segments);
    }

    /// The timings of the run up to the checkpoint it resumes from.
    fn take_back(&mut self, resume: &Carried) {
        self.steps_done = resume.step;
        self.resumed_from_step = resume.step;
        self.solve_seconds = resume.number("timing.solve_seconds").unwrap_or(0.0);
        self.step_seconds = resume.values("timing.step_seconds").unwrap_or(&[]).to_vec();
        self.peak_max_abs = resume.number("timing.peak_max_abs").unwrap_or(0.0);
        self.segments_s = resume.values("timing.segments_s").unwrap_or(&[]).to_vec();
    }
}

/// What the untimed observers of a run kept: c_tot(t) and the field's frames.
pub(crate) struct Observed {
    pub c_tot: Option<MassSeries>,
    pub frames: Vec<Frame>,
}

/// `timed_steps` over `stepping`'s steps, also sampling c_tot = h^d Σ field(state) and frames of
/// `field(state)` (in lattice order) when the case asks for them; their series so far go into
/// the checkpoints, and a resumed run takes them back.
pub(crate) fn timed_steps_observed<S: Clone>(
    state: &mut S,
    stepping: &Stepping,
    field: impl Fn(&S) -> Cow<'_, [f64]>,
    step: impl FnMut(&mut S, usize) -> f64,
    mut after: impl FnMut(&S, usize),
    checkpoints: Option<Checkpoints<S>>,
) -> (Timing, Observed) {
    let mass = |state: &S| diagnostics::total_mass(&field(state), stepping.volume);
    let c_tot = MassSampling::start(
        stepping.diagnostics_every,
        stepping.dt,
        stepping.steps,
        mass(state),
    );
    let mut frames = Vec::new();
    let frame_schedule = stepping.vtk_every.map(|every| {
        let schedule = Schedule::new(every, stepping.dt, stepping.steps);
        frames.push(Frame {
            time: 0.0,
            values: field(state).into_owned(),
        });
        schedule
    });
    // Shared by the observer after each step and the checkpoints' parts.
    let observers = RefCell::new((c_tot, frames, frame_schedule));
    if let Some(resume) = checkpoints
        .as_ref()
        .and_then(|c| c.checkpointer.resume.as_ref())
    {
        take_back_observers(&mut observers.borrow_mut(), resume);
    }
    let mut carry_observed;
    let checkpoints = match checkpoints {
        Some(Checkpoints {
            checkpointer,
            carry,
            on_any_rank,
        }) => {
            carry_observed = |state: &S, carried: &mut Carried| {
                carry_observers(&observers.borrow(), carried);
                carry(state, carried);
            };
            Some(Checkpoints {
                checkpointer,
                carry: &mut carry_observed,
                on_any_rank,
            })
        }
        None => None,
    };
    let timing = timed_steps(
        state,
        stepping.steps,
        stepping.divergence_bound,
        step,
        |state, k| {
            after(state, k);
            let (c_tot, frames, frame_schedule) = &mut *observers.borrow_mut();
            MassSampling::observe_if(c_tot, k, || mass(state));
            if let Some(schedule) = frame_schedule.as_mut() {
                if schedule.due(k) {
                    frames.push(Frame {
                        time: schedule.time(k),
                        values: field(state).into_owned(),
                    });
                }
            }
        },
        checkpoints,
    );
    let (c_tot, frames, _) = observers.into_inner();
    let c_tot = c_tot.map(|sampling| sampling.series);
    (timing, Observed { c_tot, frames })
}

/// The observers' state: the c_tot sampling, the frames, and the frames' schedule.
type Observers = (Option<MassSampling>, Vec<Frame>, Option<Schedule>);

fn carry_observers((c_tot, frames, _): &Observers, carried: &mut Carried) {
    if let Some(sampling) = c_tot {
        carried.put("c_tot.time", sampling.series.time.clone());
        carried.put("c_tot.c_tot", sampling.series.c_tot.clone());
    }
    carried.put("frames.time", frames.iter().map(|f| f.time).collect());
    carried.put(
        "frames.values",
        frames
            .iter()
            .flat_map(|f| f.values.iter().copied())
            .collect(),
    );
}

fn take_back_observers((c_tot, frames, schedule): &mut Observers, resume: &Carried) {
    if let (Some(sampling), Some(time), Some(values)) = (
        c_tot.as_mut(),
        resume.values("c_tot.time"),
        resume.values("c_tot.c_tot"),
    ) {
        sampling.series.time = time.to_vec();
        sampling.series.c_tot = values.to_vec();
        sampling.resume(time.len() - 1);
    }
    if let (Some(schedule), Some(times), Some(values)) = (
        schedule.as_mut(),
        resume.values("frames.time"),
        resume.values("frames.values"),
    ) {
        let len = values.len() / times.len().max(1);
        *frames = times
            .iter()
            .zip(values.chunks(len.max(1)))
            .map(|(&time, values)| Frame {
                time,
                values: values.to_vec(),
            })
            .collect();
        schedule.resume(times.len() - 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps that return the given max |u|, in turn: where does the loop stop?
    fn diverged_at(maxima: &[f64], bound: f64) -> Option<usize> {
        let mut state = 0;
        timed_steps(
            &mut state,
            maxima.len(),
            bound,
            |_, k| maxima[k],
            |_, _| {},
            None,
        )
        .diverged_at
    }

    /// However long the run, at most `MAX_TIMED_STEPS` step times are kept (and carried by a
    /// checkpoint), spread over the whole run.
    #[test]
    fn the_step_times_kept_are_bounded_whatever_the_steps() {
        for steps in [
            1,
            1000,
            MAX_TIMED_STEPS,
            MAX_TIMED_STEPS + 1,
            10_000_000,
            100_000_000,
        ] {
            let stride = steps.div_ceil(MAX_TIMED_STEPS).max(1);
            let kept = steps.div_ceil(stride);
            assert!(kept <= MAX_TIMED_STEPS, "{steps}: {kept}");
            assert_eq!(
                kept,
                (0..steps)
                    .step_by(stride)
                    .filter(|&k| is_sampled(steps, k))
                    .count()
            );
            assert!(kept >= MAX_TIMED_STEPS.min(steps) / 2, "{steps}: {kept}");
        }
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
