//! The cheapest configuration for an error target: from each point of the sweep (a candidate
//! configuration: a method, an integrator, a backend …), the coarsest resolution whose error is
//! at most the target, found by predicting it from the convergence measured so far (e ≈ C·h^p,
//! p the order of the two finest levels run) and verifying each prediction with a run, then
//! narrowing between the finest level that missed and the coarsest that met the target to a
//! relative tolerance. The candidates are ranked by the measured cost of their answers.

use crate::model::adaptive::{check_start, counts_nodes, positive, Adaptive, Lookup};
use serde::Deserialize;

/// An error-target search as a study writes it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// The resolution field: `n` (finer upward) or a step such as `dt` (finer downward).
    pub field: String,
    /// The first resolution run.
    pub start: f64,
    /// The error to reach: at most this.
    pub below: f64,
    /// The error column (default `error_l2_norm`).
    #[serde(default = "error_l2_norm")]
    pub error: String,
    /// The column the candidates are ranked by (default `solve_s`, the measured solve time).
    #[serde(default = "solve_s")]
    pub cost: String,
    /// How close the answer is to the coarsest resolution that meets the target: the finest
    /// level that misses it lies within this relative distance (default 0.1), or for `n` one
    /// node.
    #[serde(default = "tenth")]
    pub rtol: f64,
    /// Most runs one candidate may spend (default 12).
    #[serde(default = "twelve")]
    pub max_probes: usize,
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
fn twelve() -> usize {
    12
}

/// A level run: its value of the field, its error and its cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub value: f64,
    pub error: f64,
    pub cost: f64,
}

/// Why a candidate's search stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum Reached {
    /// The coarsest resolution that meets the target, to the tolerance.
    Found,
    /// The coarsest resolution there is (n = 1) meets it already.
    AtCoarsest,
    /// `max_probes` were spent: the answer, if any, is the coarsest level run that meets it.
    Budget,
    /// The study's `budget` was spent first.
    StudyBudget,
    /// A level's record could not answer (the run failed, or lacks the error or cost column).
    Unanswered { value: f64, why: String },
}

/// A candidate's search as far as it went.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aimed {
    pub levels: Vec<Level>,
    pub reached: Option<Reached>,
}

/// The most a prediction may refine at once, and the least.
const MOST_STEP: f64 = 8.0;
const LEAST_STEP: f64 = 1.1;

impl TargetSpec {
    /// The spec's own rules, each refusal naming the field at fault (under `target.`).
    pub fn check(&self) -> Result<(), (String, String)> {
        let fail = |field: &str, why: String| Err((format!("target.{field}"), why));
        check_start(Self::SECTION, &self.field, self.start)?;
        if !(self.below.is_finite() && self.below > 0.0) {
            return fail(
                "below",
                format!("must be a positive error (got {})", self.below),
            );
        }
        if !(self.rtol > 0.0 && self.rtol < 1.0) {
            return fail("rtol", format!("must lie in (0, 1) (got {})", self.rtol));
        }
        if !(2..=50).contains(&self.max_probes) {
            return fail(
                "max_probes",
                format!("must be 2 to 50 (got {})", self.max_probes),
            );
        }
        Ok(())
    }

    fn is_grid(&self) -> bool {
        counts_nodes(&self.field)
    }

    /// How fine a value is: n itself, or 1/dt.
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

    /// The next value to run, or why the search ends, given the levels so far (at least one).
    fn next(&self, levels: &[Level]) -> Result<f64, Reached> {
        let r = |l: &Level| self.fineness(l.value);
        let meets = |l: &&Level| l.error <= self.below;
        let coarsest_meeting = levels
            .iter()
            .filter(meets)
            .min_by(|a, b| r(a).total_cmp(&r(b)));
        let finest_missing = levels
            .iter()
            .filter(|l| !meets(l) && coarsest_meeting.is_none_or(|m| r(l) < r(m)))
            .max_by(|a, b| r(a).total_cmp(&r(b)));
        if levels.len() >= self.max_probes {
            return Err(Reached::Budget);
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
            // Coarser, until a level misses.
            (None, Some(meet)) => {
                if self.is_grid() && meet.value <= 1.0 {
                    return Err(Reached::AtCoarsest);
                }
                r(meet) / 2.0
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
        let value = self.value_of(next);
        // A whole n that rounds back onto a level run: the neighbours are known, it is found.
        match levels.iter().any(|l| l.value == value) {
            true => Err(Reached::Found),
            false => Ok(value),
        }
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

    /// The search as far as `level_of` knows it: each level's error and cost (None for a
    /// level not run yet, Err for a record that cannot answer). Returns it and the next value.
    pub fn replay_levels(
        &self,
        mut level_of: impl FnMut(f64) -> Option<Result<(f64, f64), String>>,
    ) -> (Aimed, Vec<f64>) {
        let mut aimed = Aimed::default();
        let mut value = self.start;
        loop {
            match level_of(value) {
                None => return (aimed, vec![value]),
                Some(Err(why)) => {
                    aimed.reached = Some(Reached::Unanswered { value, why });
                    return (aimed, Vec::new());
                }
                Some(Ok((error, cost))) => aimed.levels.push(Level { value, error, cost }),
            }
            match self.next(&aimed.levels) {
                Ok(next) => value = next,
                Err(reached) => {
                    aimed.reached = Some(reached);
                    return (aimed, Vec::new());
                }
            }
        }
    }
}

impl Aimed {
    /// The coarsest level run that meets `below`: the candidate's answer.
    pub fn answer(&self, spec: &TargetSpec) -> Option<Level> {
        self.levels
            .iter()
            .filter(|l| l.error <= spec.below)
            .min_by(|a, b| spec.fineness(a.value).total_cmp(&spec.fineness(b.value)))
            .copied()
    }
}

impl Adaptive for TargetSpec {
    type Outcome = Aimed;
    const SECTION: &'static str = "target";

    fn field(&self) -> &str {
        &self.field
    }

    fn worst_case_probes(&self) -> usize {
        self.max_probes
    }

    fn out_of_budget(&self, aimed: &mut Aimed) {
        aimed.reached.get_or_insert(Reached::StudyBudget);
    }

    fn replay(&self, record: &mut Lookup) -> (Aimed, Vec<f64>) {
        self.replay_levels(|v| {
            record(v).map(|stored| {
                stored.and_then(|s| Ok((positive(&self.error, &s)?, positive(&self.cost, &s)?)))
            })
        })
    }
}

impl std::fmt::Display for Reached {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reached::Found => write!(f, "found"),
            Reached::AtCoarsest => write!(f, "met at the coarsest resolution"),
            Reached::Budget => write!(f, "max_probes spent"),
            Reached::StudyBudget => write!(f, "the study's budget spent"),
            Reached::Unanswered { value, why } => {
                write!(f, "the level at {value} cannot answer: {why}")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(below: f64) -> TargetSpec {
        TargetSpec {
            field: "n".into(),
            start: 16.0,
            below,
            error: "error_l2_norm".into(),
            cost: "solve_s".into(),
            rtol: 0.1,
            max_probes: 12,
        }
    }

    /// Runs a search to its end against an error law (cost n), each level once.
    fn aim(spec: &TargetSpec, error: impl Fn(f64) -> f64) -> Aimed {
        let mut ran: Vec<f64> = Vec::new();
        loop {
            let (aimed, next) = spec.replay_levels(|v| ran.contains(&v).then(|| Ok((error(v), v))));
            match next.first() {
                None => return aimed,
                Some(&v) => {
                    assert!(!ran.contains(&v), "{v} run twice");
                    ran.push(v);
                }
            }
        }
    }

    /// The answer meets the target, and within the tolerance no coarser n does: against every
    /// n of a dense grid. A second-order law takes a handful of runs.
    #[test]
    fn the_answer_is_the_coarsest_n_meeting_the_target_to_the_tolerance() {
        type Law = fn(f64) -> f64;
        let laws: [(&str, Law); 3] = [
            ("second order", |n| 3.0 / (n * n)),
            ("with a pre-asymptotic term", |n| {
                3.0 / (n * n) * (1.0 + 20.0 / n)
            }),
            ("first order", |n| 0.5 / n),
        ];
        for (name, law) in laws {
            for below in [1e-3, 3e-5, 1e-6] {
                let spec = spec(below);
                let aimed = aim(&spec, law);
                let answer = aimed
                    .answer(&spec)
                    .unwrap_or_else(|| panic!("{name}: {aimed:?}"));
                assert!(answer.error <= below);
                let cheapest = (1..10_000_000).find(|&n| law(n as f64) <= below).unwrap() as f64;
                assert!(
                    answer.value >= cheapest
                        && answer.value <= (cheapest * 1.1).max(cheapest + 1.0),
                    "{name} {below}: {} against {cheapest}",
                    answer.value
                );
                assert_eq!(aimed.reached, Some(Reached::Found), "{name}");
                assert!(
                    aimed.levels.len() <= 9,
                    "{name} {below}: {} runs",
                    aimed.levels.len()
                );
            }
        }
    }

    #[test]
    fn a_start_that_meets_the_target_goes_coarser_and_dt_goes_down() {
        let aimed = aim(&spec(1e-2), |n| 1.0 / (n * n));
        let answer = aimed.answer(&spec(1e-2)).unwrap();
        assert_eq!(answer.value, 10.0);
        let dt = TargetSpec {
            field: "dt".into(),
            start: 0.1,
            ..spec(1e-4)
        };
        let aimed = aim(&dt, |dt| dt * dt);
        let answer = aimed.answer(&dt).unwrap();
        assert!(
            answer.error <= 1e-4 && answer.value >= 0.01 / 1.1,
            "{answer:?}"
        );
    }

    #[test]
    fn the_budget_and_a_failed_level_end_the_search() {
        let few = TargetSpec {
            max_probes: 3,
            ..spec(1e-12)
        };
        let aimed = aim(&few, |n| 1.0 / n);
        assert_eq!(
            (aimed.levels.len(), aimed.reached.clone()),
            (3, Some(Reached::Budget))
        );
        assert!(aimed.answer(&few).is_none());
        let (failed, next) = spec(1e-3).replay_levels(|_| Some(Err("failed".into())));
        assert!(next.is_empty() && matches!(failed.reached, Some(Reached::Unanswered { .. })));
    }

    #[test]
    fn bad_specs_are_refused_naming_the_field() {
        let refused = |change: fn(&mut TargetSpec)| {
            let mut s = spec(1e-6);
            change(&mut s);
            s.check().unwrap_err().0
        };
        assert_eq!(refused(|s| s.below = 0.0), "target.below");
        assert_eq!(refused(|s| s.start = 8.5), "target.start");
        assert_eq!(refused(|s| s.rtol = 0.0), "target.rtol");
        assert_eq!(refused(|s| s.max_probes = 0), "target.max_probes");
        assert!(spec(1e-6).check().is_ok());
    }
}
