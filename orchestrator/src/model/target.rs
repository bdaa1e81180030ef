//! The cheapest configuration for an error target: from each point of the sweep (a candidate
//! configuration: a method, an integrator, a backend …), the resolution whose error is at most
//! the target at the least cost.
//!
//! Along one field (`n`, or a step such as `dt`): the coarsest value that meets the target,
//! predicted from the convergence measured so far (e ≈ C·h^p, p the order of the two finest
//! levels run), verified by a run, then narrowed between the finest level that missed and the
//! coarsest that met it to a relative tolerance. In space and time (`field` and `time`): the
//! runs' errors and costs fitted as e ≈ C·h^p + D·dt^q + F (or |C·h^p − D·dt^q| where the parts
//! cancel) and K·h^−a·dt^−b (`fit`), the cheapest (h, dt) whose parts at their worst are within
//! the target by a margin (the fit's own leave-one-out spread) predicted, verified by a run, and
//! the model fitted again until its prediction is no cheaper than a run that met the target, or
//! lies within the tolerance of one in both fields; then the cheaper neighbours of the cheapest
//! run that met it (`neighbours`), so that the answer is the cheapest run, not the model's. A run
//! that meets the target only by its parts cancelling is no answer.
//!
//! Either way an explicit step is never run where it is unstable: the solver's check refuses
//! it before it runs (`Adaptive::absorbs`), a search in space and time keeps below the stable
//! step the runs told (`dt_stable`, scaled as h^k to other spacings), and a step refused or
//! diverged narrows the search below it instead of ending it. A refinement whose error stops
//! falling (three levels within 10 % of each other) ends the candidate as unreachable, naming
//! the floor and what the search does not refine.

mod axes;
mod erratic;
mod fit;
mod neighbours;

use crate::model::adaptive::{
    check_start, core_seconds, counts_nodes, positive, ran, refused_for_its_step, Adaptive, Lookup,
    Probe, ProbeRecord, LARGEST_START,
};
use schema::record::{Status, Stored};
use schema::text::exact;
use serde::Deserialize;

use axes::Axes;
pub use fit::ErrorModel;

/// The smallest error a target may ask for: a few hundred ulps of an O(1) solution, the
/// round-off of a norm over a grid. Below it the search would refine without end.
const ROUND_OFF: f64 = 1e-13;

/// An error-target search as a study writes it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// The resolution field: `n` (finer upward) or a step such as `dt` (finer downward); with
    /// `time`, the spatial one (`n`, `eps`).
    pub field: String,
    /// The first resolution run.
    pub start: f64,
    /// The temporal field searched together with `field` (`dt` or `cfl`) and its first value.
    #[serde(default)]
    pub time: Option<TimeSpec>,
    /// The error to reach: at most this.
    pub below: f64,
    /// The error column (default `error_l2_norm`).
    #[serde(default = "error_l2_norm")]
    pub error: String,
    /// The column the candidates are ranked by (default `solve_s`, the measured solve time; also
    /// `solve_cpu_s`, `peak_memory_bytes`, `core_seconds`: set-up and solve × threads × ranks,
    /// `bond_evaluations`: operator applications × bonds, the same on any machine).
    #[serde(default = "solve_s")]
    pub cost: String,
    /// How close the answer is to the cheapest resolution that meets the target: along one
    /// field, the finest level that misses it lies within this relative distance (default 0.1),
    /// or for `n` one node; in space and time, the model's cheapest within it of a run.
    #[serde(default = "tenth")]
    pub rtol: f64,
    /// Most runs one candidate may spend (default 12, 20 in space and time).
    #[serde(default)]
    pub max_probes: Option<usize>,
}

/// The temporal field of a search in space and time.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    pub field: String,
    pub start: f64,
}

fn error_l2_norm() -> String {
    "error_l2_norm".into()
}
fn solve_s() -> String {
    "solve_s".into()
}
fn tenth() -> f64 {
    0.1
}

/// The fields a time step may be searched along.
const STEPS: [&str; 2] = ["dt", "cfl"];

/// The cost columns that are no record's: set-up and solve seconds × threads × ranks, and the
/// operator's applications × its bonds (the stencil's work, the same on any machine).
pub const CORE_SECONDS: &str = "core_seconds";
pub const BOND_EVALUATIONS: &str = "bond_evaluations";

/// How far inside the target the model aims, in space and time, until a run has met it, while
/// the fit has too few runs (four) to tell its own spread: its error at most below/1.25. With
/// them, the margin is the fit's leave-one-out spread (`TargetSpec::margin`), at most
/// `MOST_MARGIN`.
const PRIOR_MARGIN: f64 = 1.25;
const MOST_MARGIN: f64 = 2.0;

/// How far a run's modelled parts, each at its worst, may lie above the target for the run to
/// count as meeting it: beyond, it meets only by its parts cancelling.
const CANCELLING: f64 = 1.25;

/// A level run: its values of the fields, its error and cost, and what the models read of its
/// record.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// The first field's value.
    pub value: f64,
    /// The temporal field's value, in a search in space and time.
    pub time: Option<f64>,
    pub error: f64,
    pub cost: f64,
    /// The run's grid spacing and time step, as its record says (`h`, `dt`).
    pub h: f64,
    pub dt: f64,
    /// The time its steps reach (steps × dt).
    pub t_end: f64,
    /// Its explicit integrator's stable step, where it binds (none for implicit ones, or with
    /// `allow_unstable`).
    pub stable: Option<f64>,
    /// What the search does not refine, as its record says (`n = 128`, `dt = 0.001`).
    pub fixed: String,
    /// The integrator's order in dt, where the record names one.
    pub order: Option<f64>,
    pub dim: f64,
}

/// Why a candidate's search stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum Reached {
    /// The cheapest resolution that meets the target, to the tolerance.
    Found,
    /// The coarsest resolution there is (n = 1, or the largest stable step) meets it already.
    AtCoarsest,
    /// `max_probes` were spent: the answer, if any, is the cheapest level run that meets it.
    Budget,
    /// The study's `budget` was spent first.
    StudyBudget,
    /// A level's record could not answer (the run failed, or lacks the error or cost column).
    Unanswered { value: f64, why: String },
    /// The error stopped falling above the target: a floor of what the search does not refine.
    Unreachable { floor: f64, from: String },
    /// Finer resolutions are unstable at the step the study holds fixed.
    Unstable,
}

/// A candidate's search as far as it went.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aimed {
    pub levels: Vec<Level>,
    /// Probes refused as unstable, or that diverged.
    pub unstable: Vec<Probe>,
    /// How many of them the solver refused for their step, so that they never ran.
    pub refused: usize,
    pub reached: Option<Reached>,
    /// The error model of a search in space and time, as last fitted.
    pub model: Option<ErrorModel>,
    /// The answer's cost over its repeats, timed once the searches ended (`run::search`).
    pub answer_costs: Vec<f64>,
}

/// What a probe's record gave.
enum Seen {
    Level(Level),
    /// Refused for its step (`ran` false), or diverged.
    Unstable {
        ran: bool,
    },
}

/// The most a probe in space and time may cost, over the costliest run so far.
const COSTLIER: f64 = 16.0;

/// The most a prediction may refine at once, and the least.
const MOST_STEP: f64 = 8.0;
const LEAST_STEP: f64 = 1.1;

/// A refinement that lowers the error by less than this factor has not refined it.
const PLATEAU: f64 = 0.9;

impl TargetSpec {
    /// The spec's own rules, each refusal naming the field at fault (under `target.`).
    pub fn check(&self) -> Result<(), (String, String)> {
        let fail = |field: &str, why: String| Err((format!("target.{field}"), why));
        check_start(Self::SECTION, &self.field, self.start)?;
        if !(self.below.is_finite() && self.below > 0.0) {
            return fail(
                "below",
                format!(
                    "must be a positive, finite error (got {})",
                    exact(self.below)
                ),
            );
        }
        if self.below < ROUND_OFF {
            return fail(
                "below",
                format!(
                    "{} is below round-off: no run in double precision measures an error under {ROUND_OFF:e}; give a larger target",
                    self.below
                ),
            );
        }
        if !(self.rtol > 0.0 && self.rtol < 1.0) {
            return fail(
                "rtol",
                format!("must lie in (0, 1) (got {})", exact(self.rtol)),
            );
        }
        if let Some(time) = &self.time {
            if !STEPS.contains(&time.field.as_str()) {
                return fail(
                    "time.field",
                    format!("`{}` is no time step; give `dt` or `cfl`", time.field),
                );
            }
            if STEPS.contains(&self.field.as_str()) {
                return fail(
                    "field",
                    format!(
                        "`{}` is a time step too; with `time`, `field` is the spatial resolution (`n`, `eps`)",
                        self.field
                    ),
                );
            }
            if !(time.start.is_finite() && time.start > 0.0 && time.start <= LARGEST_START) {
                return fail(
                    "time.start",
                    format!(
                        "must be a positive number at most {LARGEST_START:e} (got {})",
                        exact(time.start)
                    ),
                );
            }
        }
        match self.max_probes {
            Some(most) if !(2..=50).contains(&most) => {
                fail("max_probes", format!("must be 2 to 50 (got {most})"))
            }
            _ => Ok(()),
        }
    }

    /// Most runs a candidate may spend.
    pub fn most_probes(&self) -> usize {
        self.max_probes
            .unwrap_or(if self.time.is_some() { 20 } else { 12 })
    }

    fn is_grid(&self) -> bool {
        counts_nodes(&self.field)
    }

    /// How fine a value of the first field is: n itself, or 1/dt.
    fn fineness(&self, value: f64) -> f64 {
        match self.is_grid() {
            true => value,
            false => 1.0 / value,
        }
    }

    /// The value of a fineness: a whole n, or dt = 1/fineness.
    fn value_of(&self, fineness: f64) -> f64 {
        match self.is_grid() {
            true => fineness.round().max(1.0),
            false => 1.0 / fineness,
        }
    }

    /// Whether the first (only) field is a time step, whose coarse side is unstable.
    fn is_step(&self) -> bool {
        STEPS.contains(&self.field.as_str())
    }

    /// The first probe.
    fn first(&self) -> Probe {
        let mut probe = vec![self.start];
        probe.extend(self.time.as_ref().map(|t| t.start));
        probe
    }

    /// What a probe's record gives: a level, a probe found unstable (refused for its step, or
    /// diverged), or why it cannot answer.
    fn seen(&self, probe: &[f64], stored: ProbeRecord) -> Result<Seen, String> {
        let stored = match stored {
            Ok(stored) => stored,
            Err(why) if refused_for_its_step(&why) => return Ok(Seen::Unstable { ran: false }),
            Err(why) => return Err(why),
        };
        if stored.status() == Status::Diverged {
            return Ok(Seen::Unstable { ran: true });
        }
        let error = positive(&self.error, &stored)?;
        let cost = cost_of(&self.cost, &stored)?;
        let record = stored.record().ok_or("the run failed")?;
        let resolved = &record.resolved;
        let explicit = match record.case.get("method").and_then(|m| m.as_str()) {
            None | Some("nonlocal") => resolved.integrator.is_none_or(|i| !i.is_implicit()),
            Some("fd_explicit" | "pse") => true,
            _ => false,
        };
        let allowed = record.case.get("allow_unstable") == Some(&serde_json::Value::Bool(true));
        let stable = (explicit && !allowed)
            .then(|| resolved.dt_stable_spectrum.unwrap_or(resolved.dt_stable))
            .filter(|s| *s > 0.0 && s.is_finite());
        let fixed = match (self.is_step(), record.case.get("n")) {
            (true, Some(n)) => format!("the spatial error at n = {n}"),
            (true, None) => format!(
                "the spatial error at h = {}",
                schema::text::number(resolved.h)
            ),
            (false, _) => format!(
                "the temporal error at dt = {}",
                schema::text::number(resolved.dt)
            ),
        };
        Ok(Seen::Level(Level {
            value: probe[0],
            time: probe.get(1).copied(),
            error,
            cost,
            h: resolved.h,
            dt: resolved.dt,
            t_end: resolved.steps as f64 * resolved.dt,
            stable,
            fixed,
            order: resolved.integrator.map(|i| f64::from(i.order())),
            dim: record
                .case
                .get("dim")
                .and_then(|d| d.as_f64())
                .unwrap_or(1.0),
        }))
    }

    /// The search as far as `record` knows it, and the next probe (none once it ended).
    pub fn replay_levels(
        &self,
        mut record: impl FnMut(&[f64]) -> Option<ProbeRecord>,
    ) -> (Aimed, Vec<Probe>) {
        let mut aimed = Aimed::default();
        let mut probe = self.first();
        loop {
            match record(&probe).map(|stored| self.seen(&probe, stored)) {
                None => return (aimed, vec![probe]),
                Some(Err(why)) => {
                    let value = probe[0];
                    aimed.reached = Some(Reached::Unanswered { value, why });
                    return (aimed, Vec::new());
                }
                Some(Ok(Seen::Level(level))) => aimed.levels.push(level),
                Some(Ok(Seen::Unstable { ran })) => {
                    aimed.unstable.push(probe.clone());
                    aimed.refused += usize::from(!ran);
                }
            }
            let next = match self.time {
                None => (self.next_along_one(&aimed))
                    .or_else(|reached| self.robust_along_one(&aimed, reached)),
                Some(_) => self.next_in_space_and_time(&mut aimed),
            };
            match next {
                Ok(next) => probe = next,
                Err(reached) => {
                    aimed.reached = Some(reached);
                    return (aimed, Vec::new());
                }
            }
        }
    }

    /// The next value along one field, or why the search ends.
    ///
    /// Long because its stopping rules and its next value are one decision over the same levels, as
    /// in `next_in_space_and_time`.
    fn next_along_one(&self, aimed: &Aimed) -> Result<Probe, Reached> {
        let levels = &aimed.levels;
        if levels.len() + aimed.unstable.len() >= self.most_probes() {
            return Err(Reached::Budget);
        }
        let r = |l: &Level| self.fineness(l.value);
        // The coarsest fineness that may run: above every step found unstable, and above the
        // stable step the runs told (a time step; `cfl` is the step over it).
        let unstable = aimed.unstable.iter().map(|p| self.fineness(p[0]));
        let stable = levels.iter().filter_map(|l| {
            let step = l.stable?;
            match self.field.as_str() {
                "dt" => Some(1.0 / step),
                "cfl" => Some(1.0),
                _ => None,
            }
        });
        let limit = unstable
            .clone()
            .chain(stable)
            .fold(None, |m: Option<f64>, f| Some(m.map_or(f, |m| m.max(f))));
        if !self.is_step() && !aimed.unstable.is_empty() {
            // Finer n at a fixed step is unstable.
            return Err(Reached::Unstable);
        }
        if levels.is_empty() {
            // Only unstable probes so far: halve the step.
            let finest = unstable.fold(0.0, f64::max);
            return Ok(vec![self.value_of(2.0 * finest)]);
        }
        let meets = |l: &&Level| l.error <= self.below;
        let coarsest_meeting = levels
            .iter()
            .filter(meets)
            .min_by(|a, b| r(a).total_cmp(&r(b)));
        let finest_missing = levels
            .iter()
            .filter(|l| !meets(l) && coarsest_meeting.is_none_or(|m| r(l) < r(m)))
            .max_by(|a, b| r(a).total_cmp(&r(b)));
        if coarsest_meeting.is_none() {
            if let Some(floor) = self.floor(levels) {
                return Err(floor);
            }
        }
        let next = match (finest_missing, coarsest_meeting) {
            // Finer, by the prediction from the two finest levels (doubling without one).
            (Some(miss), None) => {
                let step = self
                    .predicted_step(levels, miss)
                    .unwrap_or(2.0)
                    .clamp(LEAST_STEP, MOST_STEP);
                r(miss) * step
            }
            // Coarser, until a level misses, never where a step is unstable.
            (None, Some(meet)) => {
                if self.is_grid() && meet.value <= 1.0 {
                    return Err(Reached::AtCoarsest);
                }
                match limit {
                    Some(limit) if r(meet) <= limit * (1.0 + self.rtol) => {
                        return Err(Reached::AtCoarsest)
                    }
                    Some(limit) => (r(meet) / 2.0).max(limit * (1.0 + self.rtol / 2.0)),
                    None => r(meet) / 2.0,
                }
            }
            (Some(miss), Some(meet)) => {
                let (lo, hi) = (r(miss), r(meet));
                let close = hi / lo <= 1.0 + self.rtol
                    || (self.is_grid() && meet.value - miss.value <= 1.0);
                if close {
                    return Err(Reached::Found);
                }
                // The crossing the two predict (log–log), kept in the middle half of the
                // interval so that a poor prediction still narrows it.
                let p = (miss.error / meet.error).ln() / (hi / lo).ln();
                let guess = lo * (miss.error / self.below).powf(1.0 / p.max(1e-3));
                let span = (hi / lo).ln();
                guess.clamp(lo * (0.25 * span).exp(), lo * (0.75 * span).exp())
            }
            (None, None) => unreachable!("a level either meets the target or misses it"),
        };
        let value = match (self.field.as_str(), levels.first()) {
            ("dt", Some(first)) => whole_steps(self.value_of(next), first.t_end),
            _ => self.value_of(next),
        };
        // A whole n, or a whole number of steps, that rounds back onto a level run or past the
        // coarsest that met: the neighbours are known, it is found.
        let found = match finest_missing {
            Some(_) => Reached::Found,
            None => Reached::AtCoarsest,
        };
        if let Some(meet) = coarsest_meeting {
            if self.fineness(value) >= r(meet) {
                return Err(found);
            }
        }
        match levels.iter().any(|l| l.value == value) {
            true => Err(found),
            false => Ok(vec![value]),
        }
    }

    /// An error that stopped falling above the target: the three finest levels each within
    /// `PLATEAU` of the one before, none meeting it.
    fn floor(&self, levels: &[Level]) -> Option<Reached> {
        let mut finest: Vec<&Level> = levels.iter().collect();
        finest.sort_by(|a, b| self.fineness(b.value).total_cmp(&self.fineness(a.value)));
        let [fine, mid, coarse] = [finest.first()?, finest.get(1)?, finest.get(2)?];
        let stalled = fine.error > PLATEAU * mid.error && mid.error > PLATEAU * coarse.error;
        (stalled && fine.error > self.below).then(|| Reached::Unreachable {
            floor: fine.error.min(mid.error).min(coarse.error),
            from: fine.fixed.clone(),
        })
    }

    /// e ≈ C h^p through the two finest levels, solved for the fineness that reaches the
    /// target, as a factor over `miss`'s (a little beyond it, so the run lands under it).
    fn predicted_step(&self, levels: &[Level], miss: &Level) -> Option<f64> {
        let mut finest: Vec<&Level> = levels.iter().collect();
        finest.sort_by(|a, b| self.fineness(b.value).total_cmp(&self.fineness(a.value)));
        let [fine, coarse] = [finest.first()?, finest.get(1)?];
        let ratio = self.fineness(fine.value) / self.fineness(coarse.value);
        let p = (coarse.error / fine.error).ln() / ratio.ln();
        let step = (miss.error / self.below).powf(1.0 / p) * 1.05;
        (p > 0.1 && step.is_finite()).then_some(step)
    }

    /// The next probe of a search in space and time, or why it ends: first the start and a
    /// finer level along each field (an exploration the model is fitted from), then the model's
    /// cheapest configuration, verified by a run and fitted again, until it is no cheaper than
    /// a run that met the target or lies within the tolerance of a run in both fields.
    ///
    /// Long because its stopping rules and its next probe are one decision over the same levels and
    /// model, each rule reading what the ones before it established; split, they would pass that
    /// state between them.
    fn next_in_space_and_time(&self, aimed: &mut Aimed) -> Result<Probe, Reached> {
        let time = self.time.as_ref().expect("a search in space and time");
        if aimed.levels.len() + aimed.unstable.len() >= self.most_probes() {
            return Err(Reached::Budget);
        }
        let space = |fineness_factor: f64, value: f64| -> f64 {
            self.value_of(self.fineness(value) * fineness_factor)
        };
        let [s0, t0] = [self.start, time.start];
        // A start found unstable: halve its step until one runs.
        let Some(axes) = Axes::of(self, aimed) else {
            let finest = (aimed.unstable.iter().map(|p| p[1])).fold(t0, f64::min);
            return Ok(vec![s0, finest / 2.0]);
        };
        let first = &aimed.levels[0];
        let t_start = aimed.levels[0].time.unwrap_or(t0);
        // The exploration: a level finer in space (at the start's step, or the stable step of
        // the finer grid where an explicit integrator cannot take it: found from the start's
        // and the order h^k), and one finer in time. Each is asked once, by its spatial value
        // (the stable step, fitted again as runs come in, would move its step).
        let s1 = space(2.0, s0);
        let explored = (aimed.levels.iter().map(|l| l.value))
            .chain(aimed.unstable.iter().map(|p| p[0]))
            .any(|value| value == s1);
        if !explored {
            let h1 = axes.h(s1);
            let step = match axes.stable(h1) {
                Some(stable) if axes.step(t_start, h1) > stable => {
                    axes.value_of_step(stable * 0.9, h1)
                }
                _ => t_start,
            };
            return Ok(vec![s1, step]);
        }
        let finer_in_time = vec![s0, t_start / 2.0];
        if !aimed.has_run(&finer_in_time) {
            return Ok(finer_in_time);
        }
        let points: Vec<fit::Point> = aimed.levels.iter().map(Level::point).collect();
        let q_prior = first.order.unwrap_or(1.0);
        let model = fit::error_model(&points, q_prior).ok_or(Reached::Budget)?;
        let meeting: Vec<bool> = (aimed.levels.iter())
            .map(|l| self.meets(l, Some(&model)))
            .collect();
        aimed.model = Some(model);
        let cost = fit::cost_model(&points, first.dim).ok_or(Reached::Budget)?;
        let margin = self.margin(&model);
        if model.floor > self.below / margin && self.floor_seen(aimed) {
            return Err(Reached::Unreachable {
                floor: model.floor,
                from: "neither the grid nor the step (round-off, or the method's own)".into(),
            });
        }
        // Inside the target by a margin until a run has met it (and not by its parts
        // cancelling); then at the target itself (the model is checked where it predicts, and a
        // run that meets is in hand).
        let met = meeting.iter().any(|&meets| meets);
        let aim = match met {
            true => self.below / (1.0 + self.rtol / 4.0),
            false => self.below / margin,
        };
        // The cheapest (h, dt) of the model within the aim: for each h on a fine log grid, the
        // largest dt its temporal part allows (capped by the stable step, and by t_end: one
        // step), then its cost. A probe costs at most `COSTLIER` times the costliest run so far
        // (by the cost model): where the aim lies beyond, the search goes as far towards it as
        // that allows, to the (h, dt) of least modelled error with the two parts balanced.
        let cap = COSTLIER * (points.iter().map(|p| cost.cost(p.h, p.dt))).fold(0.0, f64::max);
        let h0 = first.h;
        let mut best: Option<(f64, f64, f64)> = None;
        let mut closest: Option<(f64, f64, f64)> = None;
        for k in -40..=160 {
            let h = h0 * 2f64.powf(-k as f64 / 20.0);
            let spatial = model.error(h, 0.0);
            let reaches = spatial < aim;
            let temporal = match reaches {
                true => aim - spatial,
                false => model.c * h.powf(model.p),
            };
            let mut dt = match model.d > 0.0 {
                true => (temporal / model.d).powf(1.0 / model.q),
                false => f64::INFINITY,
            };
            if let Some(stable) = axes.stable(h) {
                dt = dt.min(stable * (1.0 - 1e-9));
            }
            let dt = dt.min(first.t_end);
            let predicted = cost.cost(h, dt);
            if predicted.is_nan() || predicted > cap {
                continue;
            }
            match reaches {
                true if best.is_none_or(|(_, _, c)| predicted < c) => {
                    best = Some((h, dt, predicted))
                }
                false if closest.is_none_or(|(h, dt, _)| model.error(h, dt) > spatial) => {
                    closest = Some((h, dt, predicted))
                }
                _ => {}
            }
        }
        let Some((h, dt, predicted)) = best.or(closest) else {
            return Err(Reached::Budget);
        };
        // The cheapest run that met the target, by the cost model (a measured cost is noisy).
        let modelled = |l: &Level| cost.cost(l.h, l.dt);
        let cheapest = (aimed.levels.iter().zip(&meeting))
            .filter_map(|(l, &meets)| meets.then_some(l))
            .min_by(|a, b| modelled(a).total_cmp(&modelled(b)));
        let spatial = self.value_of(self.fineness(s0) * h0 / h);
        // A whole n rounds up: the grid meets the aim at least.
        let spatial = match self.is_grid() {
            true => spatial.max((self.fineness(s0) * h0 / h).ceil()),
            false => spatial,
        };
        // The grid as rounded (a whole n is finer than the model's h): its step capped again.
        let h = axes.h(spatial);
        let dt = match axes.stable(h) {
            Some(stable) => dt.min(stable * (1.0 - 1e-9)),
            None => dt,
        };
        let probe = vec![spatial, axes.value_of_step(whole_steps(dt, first.t_end), h)];
        if let Some(cheapest) = cheapest {
            let near = |a: f64, b: f64| (a / b - 1.0).abs() <= self.rtol;
            let close =
                near(probe[0], cheapest.value) && near(probe[1], cheapest.time.unwrap_or(probe[1]));
            if close || predicted >= modelled(cheapest) * (1.0 - self.rtol) {
                return self
                    .cheaper_neighbour(aimed, &model, &axes, margin)
                    .ok_or(Reached::Found);
            }
        }
        if aimed.has_run(&probe) {
            // The model predicts a run already made: with one that met, it cannot do better
            // than the runs beside it; without, finer in both, by the tolerance.
            if met {
                return self
                    .cheaper_neighbour(aimed, &model, &axes, margin)
                    .ok_or(Reached::Found);
            }
            let step = 1.0 + 2.0 * self.rtol;
            return Ok(vec![space(step, probe[0]), probe[1] / step]);
        }
        Ok(probe)
    }

    /// Whether a level meets the target: its error at most `below`, and in space and time the
    /// model's parts, each at its worst, within `CANCELLING` of it. A run far below its parts meets
    /// the target by their cancelling, a coincidence of the problem that a finer grid or a
    /// smaller step does not keep: no answer to bet on.
    fn meets(&self, level: &Level, model: Option<&ErrorModel>) -> bool {
        level.error <= self.below
            && model.is_none_or(|m| m.error(level.h, level.dt) <= self.below * CANCELLING)
    }

    /// How far inside the target the model aims before a run has met it: what its predictions
    /// missed runs they were not fitted to by (e^rms of the leave-one-out log ratios), at least
    /// a quarter of `rtol`.
    fn margin(&self, model: &ErrorModel) -> f64 {
        (model.spread)
            .map_or(PRIOR_MARGIN, f64::exp)
            .clamp(1.0 + self.rtol / 4.0, MOST_MARGIN)
    }

    /// Whether a floor shows in the runs: the finest run in space and the finest in time each
    /// within `PLATEAU` of a coarser one.
    fn floor_seen(&self, aimed: &Aimed) -> bool {
        let levels = &aimed.levels;
        levels.len() >= 4
            && levels.iter().all(|l| l.error > self.below)
            && self.floor(levels).is_some()
    }
}

impl Level {
    /// The run as the models read it.
    fn point(&self) -> fit::Point {
        fit::Point {
            h: self.h,
            dt: self.dt,
            error: self.error,
            cost: self.cost,
        }
    }
}

/// The step the solver takes for `dt` towards `t_end`: lowered so that a whole number of steps
/// lands on it (`nlsolve`'s rule), so that two steps that make the same run are one probe.
fn whole_steps(dt: f64, t_end: f64) -> f64 {
    let steps = ((t_end / dt) * (1.0 - 1e-12)).ceil().max(1.0);
    t_end / steps
}

impl Aimed {
    /// Whether `probe` (a value, and a step in space and time) was run already: a level there,
    /// or a probe found unstable.
    pub fn has_run(&self, probe: &[f64]) -> bool {
        (self.levels.iter()).any(|l| l.value == probe[0] && l.time == probe.get(1).copied())
            || self.unstable.iter().any(|p| p.as_slice() == probe)
    }

    /// The runs its search made (a probe refused for its step never ran).
    pub fn runs(&self) -> usize {
        self.levels.len() + self.unstable.len() - self.refused
    }

    /// The candidate's answer: along one field the coarsest level run that meets `below` (where
    /// the error is erratic, the coarsest whose finer runs all meet it: `Aimed::robust`); in
    /// space and time the cheapest that meets it by the runs' measured cost.
    pub fn answer(&self, spec: &TargetSpec) -> Option<Level> {
        let meeting = (self.levels.iter()).filter(|l| spec.meets(l, self.model.as_ref()));
        match spec.time {
            None if self.erratic(spec).is_some() => self.robust(spec).cloned(),
            None => meeting
                .min_by(|a, b| spec.fineness(a.value).total_cmp(&spec.fineness(b.value)))
                .cloned(),
            Some(_) => meeting.min_by(|a, b| a.cost.total_cmp(&b.cost)).cloned(),
        }
    }
}

impl TargetSpec {
    /// A run's cost: the study's `cost` column of its record.
    pub fn cost_of(&self, stored: &Stored) -> Result<f64, String> {
        cost_of(&self.cost, stored)
    }
}

/// A probe's cost: `column` of its record, a positive number, or one of the derived costs.
fn cost_of(column: &str, stored: &Stored) -> Result<f64, String> {
    let derived = match column {
        CORE_SECONDS => {
            ran(stored)?;
            core_seconds(stored)
        }
        BOND_EVALUATIONS => {
            let record = stored.record().ok_or("the run failed")?;
            let applications = record.operator_applications.ok_or(
                "its record counts no `operator_applications` (a method that does not count them)",
            )?;
            applications as f64 * record.resolved.bonds as f64
        }
        _ => return positive(column, stored),
    };
    match derived {
        c if c.is_finite() && c > 0.0 => Ok(c),
        c => Err(format!("`{column}` is {c}, not a positive number")),
    }
}

impl TargetSpec {
    /// Whether the cost is a timing, which varies from run to run and with the machine's load
    /// (a count such as `steps_done` or `bond_evaluations` is the same every time).
    pub fn cost_is_timed(&self) -> bool {
        self.cost == CORE_SECONDS || self.cost.ends_with("_s")
    }
}

impl Adaptive for TargetSpec {
    type Outcome = Aimed;
    const SECTION: &'static str = "target";
    const SEARCHES: &'static str = "candidates";
    const TABLE: &'static str = "target";
    const TITLE: &'static str = "The cheapest configuration for the error target";
    const ONE_SEARCH_PER_POINT: bool = true;

    fn fields(&self) -> Vec<&str> {
        let mut fields = vec![self.field.as_str()];
        fields.extend(self.time.as_ref().map(|t| t.field.as_str()));
        fields
    }

    fn worst_case_probes(&self) -> usize {
        self.most_probes()
    }

    /// A round runs one probe of each candidate: as many rounds as probes, at most (then each
    /// timed answer, alone).
    fn worst_case_rounds(&self) -> Option<usize> {
        Some(self.most_probes())
    }

    fn absorbs(&self, refusal: &str) -> bool {
        refused_for_its_step(refusal)
    }

    fn out_of_budget(&self, aimed: &mut Aimed) {
        aimed.reached.get_or_insert(Reached::StudyBudget);
    }

    fn replay(&self, record: &mut Lookup) -> (Aimed, Vec<Probe>) {
        self.replay_levels(|v| record(v))
    }
}

impl std::fmt::Display for Reached {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reached::Found => write!(f, "found"),
            Reached::AtCoarsest => write!(f, "met at the coarsest resolution (or the largest stable step)"),
            Reached::Budget => write!(f, "max_probes spent"),
            Reached::StudyBudget => write!(f, "the study's budget spent"),
            Reached::Unanswered { value, why } => {
                write!(f, "the level at {} cannot answer: {why}", exact(*value))
            }
            Reached::Unreachable { floor, from } => write!(
                f,
                "unreachable: error floor {} from {from}",
                schema::text::number(*floor)
            ),
            Reached::Unstable => write!(
                f,
                "unstable: a finer grid needs a smaller step than the one held fixed (search `time` too)"
            ),
        }
    }
}

#[cfg(test)]
mod tests;
