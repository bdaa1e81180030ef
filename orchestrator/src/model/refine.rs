//! A refinement that stops when its answer is established: from each point of the sweep, a
//! resolution field (`n`, or `dt`) is refined by a fixed factor one level at a time, and the
//! observed order of each pair of levels read from an error column, until the last three
//! orders agree (with the expected order, where the study names one), the error reaches a
//! target, the error stops falling (round-off: a plateau), or the levels run out. Never beyond.

use crate::model::adaptive::{check_start, counts_nodes, positive, Adaptive, Lookup, Probe};
use crate::statistics::fitted_slope;
use schema::text::exact;
use serde::Deserialize;

/// A refinement as a study writes it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RefineSpec {
    /// The case field refined: `n` (multiplied by `factor`) or a step such as `dt` (divided).
    pub field: String,
    /// The coarsest level's value.
    pub start: f64,
    /// How much finer each level is: n × factor, or dt / factor (default 2).
    #[serde(default = "two")]
    pub factor: f64,
    /// The error column the orders are read from (default `error_l2_norm`).
    #[serde(default = "error_l2_norm")]
    pub error: String,
    /// The order theory expects; the orders must agree with it too.
    #[serde(default)]
    pub order: Option<f64>,
    /// How far the last three orders may spread (and lie from `order`): default 0.05.
    #[serde(default = "agree")]
    pub agree: f64,
    /// Stop once the error is at most this.
    #[serde(default)]
    pub target: Option<f64>,
    /// Most levels, the coarsest included (default 8).
    #[serde(default = "eight")]
    pub max_levels: usize,
}

fn two() -> f64 {
    2.0
}
fn error_l2_norm() -> String {
    "error_l2_norm".into()
}
fn agree() -> f64 {
    0.05
}
fn eight() -> usize {
    8
}

/// Why a refinement stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum Stopped {
    /// The last three observed orders agree (and with the expected order).
    Established,
    /// The error reached the target.
    Target,
    /// The error stopped falling: the floor of round-off (or of another error source), reached
    /// at the value given.
    Plateau { error: f64, from: f64 },
    /// `max_levels` were run.
    Budget,
    /// The study's `budget` was spent first.
    StudyBudget,
    /// A level's record could not answer (the run failed, or lacks the error column).
    Unanswered { value: f64, why: String },
}

/// A refinement as far as it went: each level's value and error.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refinement {
    pub levels: Vec<(f64, f64)>,
    pub stopped: Option<Stopped>,
}

/// An order that has fallen below this after the first pair means the error no longer falls
/// with the resolution.
const PLATEAU_ORDER: f64 = 0.3;

impl RefineSpec {
    /// The spec's own rules, each refusal naming the field at fault (under `refine.`).
    pub fn check(&self) -> Result<(), (String, String)> {
        let fail = |field: &str, why: String| Err((format!("refine.{field}"), why));
        check_start(Self::SECTION, &self.field, self.start)?;
        if !(self.factor.is_finite() && self.factor > 1.0) {
            return fail(
                "factor",
                format!(
                    "must be above 1 (got {}); 2 doubles n or halves dt",
                    exact(self.factor)
                ),
            );
        }
        if !(self.agree > 0.0 && self.agree.is_finite()) {
            return fail(
                "agree",
                format!("must be a positive number (got {})", exact(self.agree)),
            );
        }
        if let Some(target) = self.target.filter(|t| !(t.is_finite() && *t > 0.0)) {
            return fail(
                "target",
                format!("must be a positive number (got {})", exact(target)),
            );
        }
        if !(1..=30).contains(&self.max_levels) {
            return fail(
                "max_levels",
                format!("must be 1 to 30 (got {})", self.max_levels),
            );
        }
        Ok(())
    }

    fn is_grid(&self) -> bool {
        counts_nodes(&self.field)
    }

    /// The value of level `k`.
    fn level(&self, k: usize) -> f64 {
        match self.is_grid() {
            true => (self.start * self.factor.powi(k as i32)).round(),
            false => self.start / self.factor.powi(k as i32),
        }
    }

    /// The refinement after the levels answered so far.
    fn judged(&self, levels: Vec<(f64, f64)>) -> Refinement {
        let orders = observed_orders(&levels);
        let (_, error) = *levels.last().expect("a level");
        let stopped = if self.target.is_some_and(|target| error <= target) {
            Some(Stopped::Target)
        } else if let Some(&last) = orders.last().filter(|_| orders.len() >= 2) {
            // The error stopped falling after it had fallen: the floor.
            let fell = orders[..orders.len() - 1]
                .iter()
                .any(|&p| p >= PLATEAU_ORDER);
            let (floor_value, floor_error) = levels[levels.len() - 2];
            match last < PLATEAU_ORDER && fell {
                true => Some(Stopped::Plateau {
                    error: floor_error.min(error),
                    from: floor_value,
                }),
                false => None,
            }
        } else {
            None
        };
        let stopped = stopped.or_else(|| {
            let last = orders
                .get(orders.len().saturating_sub(3)..)
                .filter(|o| o.len() == 3)?;
            let (low, high) = last
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &p| {
                    (l.min(p), h.max(p))
                });
            let mean = last.iter().sum::<f64>() / 3.0;
            let agree = high - low <= self.agree
                && self.order.is_none_or(|p| (mean - p).abs() <= self.agree);
            agree.then_some(Stopped::Established)
        });
        let stopped = stopped.or((levels.len() >= self.max_levels).then_some(Stopped::Budget));
        Refinement { levels, stopped }
    }

    /// The refinement as far as `error_of` knows it: each level's error (None for a level not
    /// run yet, Err for a record that cannot answer), from the coarsest. Returns it and the
    /// level to run next, if any.
    pub fn replay_errors(
        &self,
        mut error_of: impl FnMut(f64) -> Option<Result<f64, String>>,
    ) -> (Refinement, Vec<f64>) {
        let mut levels = Vec::new();
        loop {
            let value = self.level(levels.len());
            match error_of(value) {
                None => return (self.judged_or_empty(levels), vec![value]),
                Some(Err(why)) => {
                    let mut refinement = self.judged_or_empty(levels);
                    refinement.stopped = Some(Stopped::Unanswered { value, why });
                    return (refinement, Vec::new());
                }
                Some(Ok(error)) => {
                    levels.push((value, error));
                    let refinement = self.judged(levels);
                    if refinement.stopped.is_some() {
                        return (refinement, Vec::new());
                    }
                    levels = refinement.levels;
                }
            }
        }
    }

    fn judged_or_empty(&self, levels: Vec<(f64, f64)>) -> Refinement {
        match levels.is_empty() {
            true => Refinement::default(),
            false => Refinement {
                stopped: None,
                ..self.judged(levels)
            },
        }
    }
}

/// log(e_{k−1}/e_k) / log(ratio) for each pair of levels, the ratio read from the values (so a
/// rounded n is measured as it ran).
fn observed_orders(levels: &[(f64, f64)]) -> Vec<f64> {
    levels
        .windows(2)
        .map(|w| {
            let ((v0, e0), (v1, e1)) = (w[0], w[1]);
            (e0 / e1).ln() / (v1 / v0).ln().abs()
        })
        .collect()
}

impl Refinement {
    /// The order of the finest pair of levels.
    pub fn finest_order(&self) -> Option<f64> {
        observed_orders(&self.levels).last().copied()
    }

    /// The least-squares slope of log error against log resolution over the levels from
    /// `asymptotic_from` (the last three when established), or all of them.
    pub fn fitted_order(&self) -> Option<f64> {
        let from = self.asymptotic_level().unwrap_or(0);
        // Errors fall as n grows (or dt shrinks): the order is the slope's magnitude.
        fitted_slope(&self.levels[from..]).map(f64::abs)
    }

    /// The level at which the asymptotic regime began: the first of the three agreeing pairs.
    fn asymptotic_level(&self) -> Option<usize> {
        (self.stopped == Some(Stopped::Established)).then(|| self.levels.len() - 4)
    }

    /// The value at which the asymptotic regime began, once established.
    pub fn asymptotic_from(&self) -> Option<f64> {
        self.asymptotic_level().map(|k| self.levels[k].0)
    }
}

impl Adaptive for RefineSpec {
    type Outcome = Refinement;
    const SECTION: &'static str = "refine";
    const SEARCHES: &'static str = "refinements";
    const TABLE: &'static str = "convergence";
    const TITLE: &'static str = "Refinements";

    fn fields(&self) -> Vec<&str> {
        vec![&self.field]
    }

    fn worst_case_probes(&self) -> usize {
        self.max_levels
    }

    /// A level a round.
    fn worst_case_rounds(&self) -> Option<usize> {
        Some(self.max_levels)
    }

    fn out_of_budget(&self, refinement: &mut Refinement) {
        refinement.stopped.get_or_insert(Stopped::StudyBudget);
    }

    fn replay(&self, record: &mut Lookup) -> (Refinement, Vec<Probe>) {
        let (refinement, pending) = self.replay_errors(|v| {
            record(&[v]).map(|stored| stored.and_then(|s| positive(&self.error, &s)))
        });
        (refinement, pending.into_iter().map(|v| vec![v]).collect())
    }
}

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stopped::Established => write!(f, "order established"),
            Stopped::Target => write!(f, "target reached"),
            Stopped::Plateau { error, from } => {
                write!(
                    f,
                    "plateau at {} from {}",
                    schema::text::number(*error),
                    schema::text::number(*from)
                )
            }
            Stopped::Budget => write!(f, "max_levels run"),
            Stopped::StudyBudget => write!(f, "the study's budget spent"),
            Stopped::Unanswered { value, why } => {
                write!(f, "the level at {} cannot answer: {why}", exact(*value))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> RefineSpec {
        RefineSpec {
            field: "n".into(),
            start: 8.0,
            factor: 2.0,
            error: "error_l2_norm".into(),
            order: None,
            agree: 0.05,
            target: None,
            max_levels: 12,
        }
    }

    /// Runs a refinement to its end against an error law, each level once.
    fn refine(spec: &RefineSpec, error: impl Fn(f64) -> f64) -> Refinement {
        let mut ran: Vec<f64> = Vec::new();
        loop {
            let (refinement, next) = spec.replay_errors(|v| ran.contains(&v).then(|| Ok(error(v))));
            match next.first() {
                None => return refinement,
                Some(&v) => {
                    assert!(!ran.contains(&v), "{v} run twice");
                    ran.push(v);
                }
            }
        }
    }

    #[test]
    fn a_known_order_stops_established_with_that_order() {
        // e = C h² (1 + h): the pre-asymptotic term fades; stopped once three orders agree.
        let law = |n: f64| 3.0 / (n * n) * (1.0 + 4.0 / n);
        let found = refine(&spec(), law);
        assert_eq!(found.stopped, Some(Stopped::Established));
        assert!((found.finest_order().unwrap() - 2.0).abs() <= 0.05);
        assert!((found.fitted_order().unwrap() - 2.0).abs() <= 0.05);
        let from = found.asymptotic_from().unwrap();
        assert!(from > 8.0, "{from}");
        // Expecting order 1 instead, the orders never agree with it: the budget stops it.
        let wrong = RefineSpec {
            order: Some(1.0),
            max_levels: 6,
            ..spec()
        };
        assert_eq!(refine(&wrong, law).stopped, Some(Stopped::Budget));
    }

    /// A fourth-order error whose pre-asymptotic term fades too slowly for three orders to
    /// agree to 1e-6 before it meets a floor of 1e-12 (at n = 1024).
    #[test]
    fn a_round_off_floor_stops_at_the_plateau_and_says_where() {
        let law = |n: f64| (1.0 / n.powi(4) * (1.0 + 8.0 / n)).max(1e-12);
        let strict = RefineSpec {
            agree: 1e-6,
            ..spec()
        };
        let found = refine(&strict, law);
        let Some(stopped @ Stopped::Plateau { error, from }) = found.stopped.clone() else {
            panic!("{found:?}")
        };
        assert_eq!((error, from), (1e-12, 1024.0));
        assert_eq!(found.levels.last().unwrap().0, 2048.0);
        assert_eq!(stopped.to_string(), "plateau at 1e-12 from 1024");
    }

    #[test]
    fn a_budget_of_three_runs_three_and_a_target_stops_on_reaching_it() {
        let law = |n: f64| 1.0 / n;
        let three = RefineSpec {
            max_levels: 3,
            agree: 1e-9,
            ..spec()
        };
        let found = refine(&three, |n| law(n) * (1.0 + 1.0 / n));
        assert_eq!(
            (found.levels.len(), found.stopped),
            (3, Some(Stopped::Budget))
        );
        let target = RefineSpec {
            target: Some(0.01),
            ..three
        };
        let found = refine(
            &RefineSpec {
                max_levels: 12,
                ..target
            },
            |n| law(n) * (1.0 + 1.0 / n),
        );
        assert_eq!(found.stopped, Some(Stopped::Target));
        assert_eq!(found.levels.last().unwrap().0, 128.0);
    }

    #[test]
    fn dt_is_halved_and_n_stays_whole() {
        let dt = RefineSpec {
            field: "dt".into(),
            start: 0.1,
            ..spec()
        };
        assert_eq!(dt.level(2), 0.025);
        assert_eq!(
            crate::model::adaptive::value(&dt.field, 0.025),
            serde_json::json!(0.025)
        );
        let n = RefineSpec {
            start: 10.0,
            factor: 1.5,
            ..spec()
        };
        assert_eq!(
            crate::model::adaptive::value(&n.field, n.level(3)),
            serde_json::json!(34)
        );
        let found = refine(&dt, |dt| 5.0 * dt);
        assert!((found.finest_order().unwrap() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_specs_are_refused_naming_the_field() {
        let refused = |change: fn(&mut RefineSpec)| {
            let mut s = spec();
            change(&mut s);
            s.check().unwrap_err().0
        };
        assert_eq!(refused(|s| s.factor = 1.0), "refine.factor");
        assert_eq!(refused(|s| s.start = 0.0), "refine.start");
        assert_eq!(refused(|s| s.start = 8.5), "refine.start");
        assert_eq!(refused(|s| s.max_levels = 0), "refine.max_levels");
        assert_eq!(refused(|s| s.agree = 0.0), "refine.agree");
        assert_eq!(refused(|s| s.target = Some(-1.0)), "refine.target");
        assert!(spec().check().is_ok());
    }
}
