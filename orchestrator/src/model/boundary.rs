//! A boundary search: where a condition over a probe's record (`amplification > 1`) starts to
//! hold along one numeric case field (`cfl`), found by bracketing and then k-section to a
//! relative tolerance. Pure rules: which values to probe next, given the answers so far.
//!
//! The search is a function of its answers: `replay` walks it from the first round, asking
//! `answer` for each probe, and stops at the first round with a probe not answered yet. So a
//! search killed at any moment and run again, with the records of its probes stored, asks for
//! exactly the probes it had not run, and reaches the same boundary.

use crate::model::adaptive::{ran, Adaptive, Lookup, Probe};
use crate::model::expression::{self, Scope};
use schema::case::{Case, Numeric};
use schema::record::{columns, Stored};
use schema::text::exact;
use serde::Deserialize;

/// A boundary search as a study writes it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// The numeric case field searched along (`cfl`, `dt`, `eps`, …).
    pub field: String,
    /// [below, above]: the condition must not hold at the first and must hold at the second.
    pub bracket: [f64; 2],
    /// The condition over a probe's record that holds past the boundary, in the study's
    /// expression language (`amplification > 1`, `status == 'diverged'`).
    pub flips: String,
    /// The bracket's relative width at which the search stops: (above − below) ≤ rtol·above.
    pub rtol: f64,
    /// Probes inside the bracket each round (k-section; 1 is bisection): more use more workers
    /// at once and take fewer rounds.
    #[serde(default = "one")]
    pub per_round: usize,
    /// Most probes one search may spend, the two ends included (default: what k-section to
    /// `rtol` needs).
    #[serde(default)]
    pub max_probes: Option<usize>,
    /// What `flips` said of each probe's record so far, by key: a round replays every search
    /// from its first probe, and reading a record as columns costs far more than the lookup.
    #[serde(skip)]
    pub verdicts: Verdicts,
}

/// `flips`'s verdicts by record (key and run), remembered for the searches' replays. A spec's
/// copy starts empty, and two specs are equal whatever they remember.
#[derive(Default)]
pub struct Verdicts(std::sync::Mutex<std::collections::HashMap<RecordAt, Result<bool, String>>>);

/// A record's key and the run that made it.
type RecordAt = (String, Option<String>);

impl Verdicts {
    fn of(&self, condition: &str, stored: &Stored) -> Result<bool, String> {
        let at = (stored.key.clone(), stored.run_id.clone());
        let mut known = self.0.lock().unwrap_or_else(|e| e.into_inner());
        known
            .entry(at)
            .or_insert_with(|| flips(condition, stored))
            .clone()
    }
}

impl Clone for Verdicts {
    fn clone(&self) -> Self {
        Verdicts::default()
    }
}

impl PartialEq for Verdicts {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for Verdicts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Verdicts")
    }
}

fn one() -> usize {
    1
}

/// The finest relative tolerance a search may ask: a few dozen of a double's relative spacing
/// (2.2e-16), so that the bracket can still be split into `per_round` + 1 distinct parts.
pub const FINEST_RTOL: f64 = 1e-14;

/// Why a search stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum Ended {
    /// The bracket is within the tolerance.
    Found,
    /// The condition already holds at the lower end: the boundary, if any, lies below it.
    FlipsBelow,
    /// The condition does not hold at the upper end: no boundary up to it.
    NoneUpTo,
    /// `max_probes` was spent before the tolerance was reached.
    Budget,
    /// The bracket cannot narrow further: its ends are neighbouring values the field can take
    /// (floating-point numbers, or whole ones), short of the tolerance.
    Resolution,
    /// The study's `budget` was spent first.
    StudyBudget,
    /// The study's `budget` was spent before the bracket's ends were probed: there is no
    /// estimate, only the bracket the study gave.
    Unprobed,
    /// A probe's record could not answer (the run failed, or lacks a field the condition reads).
    Unanswered { value: f64, why: String },
}

/// Where a search stands: the bracket, the probes spent and, once over, why it ended.
#[derive(Clone, Debug, PartialEq)]
pub struct Search {
    /// The largest value probed where the condition does not hold (the lower end at first).
    pub below: f64,
    /// The smallest value probed where it holds (the upper end at first).
    pub above: f64,
    pub probes: usize,
    pub rounds: usize,
    pub ended: Option<Ended>,
}

impl BoundarySpec {
    /// The spec's own rules, each refusal naming the field at fault (under `boundary.`).
    pub fn check(&self) -> Result<(), (String, String)> {
        let fail = |field: &str, why: String| Err((format!("boundary.{field}"), why));
        if Case::numeric(&self.field) == Numeric::No {
            return fail(
                "field",
                format!(
                    "`{}` is no numeric case field; search along a number such as cfl, dt, eps or m",
                    self.field
                ),
            );
        }
        let [below, above] = self.bracket;
        let given = format!("[{}, {}]", exact(below), exact(above));
        if !(below.is_finite() && above.is_finite()) {
            return fail("bracket", "must be two finite numbers".into());
        }
        if self.whole() && (below.fract() != 0.0 || above.fract() != 0.0) {
            return fail(
                "bracket",
                format!(
                    "`{}` takes whole numbers: give whole ends (got {given})",
                    self.field
                ),
            );
        }
        if below >= above {
            return fail(
                "bracket",
                format!("{given} is empty; give [below, above] with below < above"),
            );
        }
        if !(self.rtol >= FINEST_RTOL && self.rtol < 1.0) {
            return fail(
                "rtol",
                format!(
                    "must lie in [{FINEST_RTOL:e}, 1) (got {}): a double resolves no finer; 1e-3 finds a boundary to 0.1 %",
                    exact(self.rtol)
                ),
            );
        }
        if !(1..=64).contains(&self.per_round) {
            return fail(
                "per_round",
                format!("must be 1 to 64 (got {})", self.per_round),
            );
        }
        match self.max_probes {
            Some(probes) if probes < 2 => fail(
                "max_probes",
                format!("must be at least 2, the bracket's ends (got {probes})"),
            ),
            _ => Ok(()),
        }
    }

    /// Whether the field takes whole numbers only (`m`, `n`): then the search probes whole
    /// values and ends once its bracket's ends are neighbours.
    pub fn whole(&self) -> bool {
        Case::numeric(&self.field) == Numeric::Whole
    }

    /// The probes a search spends at most: its two ends and, each round, `per_round` more,
    /// for as many rounds as the bracket takes to narrow to `rtol` (or `max_probes`).
    pub fn worst_case_probes(&self) -> usize {
        let [below, above] = self.bracket;
        // Each round divides the bracket by per_round + 1; the boundary lies above `below`,
        // so a width of rtol·below is narrow enough wherever it is (and 1 for whole values).
        let mut narrowest = self.rtol * below.abs().max(f64::MIN_POSITIVE);
        if self.whole() {
            narrowest = narrowest.max(1.0);
        }
        let narrowing = (above - below) / narrowest;
        let rounds = narrowing.ln() / ((self.per_round + 1) as f64).ln();
        let needed = 2 + self.per_round * rounds.max(0.0).ceil() as usize;
        self.max_probes.map_or(needed, |most| most.min(needed))
    }

    /// The rounds a search takes at most: the bracket's ends, then `per_round` probes a round.
    pub fn worst_case_rounds(&self) -> usize {
        1 + (self.worst_case_probes().saturating_sub(2)).div_ceil(self.per_round)
    }

    /// The values the next round probes: the two ends first, then `per_round` values evenly
    /// inside the bracket (fewer when the budget is nearly spent); none once the search ended.
    pub fn round(&self, search: &Search) -> Vec<f64> {
        if search.ended.is_some() {
            return Vec::new();
        }
        if search.rounds == 0 {
            return self.bracket.to_vec();
        }
        let left = self
            .max_probes
            .map_or(usize::MAX, |most| most - search.probes);
        let k = self.per_round.min(left);
        let width = search.above - search.below;
        let inside = (1..=k).map(|j| search.below + width * j as f64 / (k + 1) as f64);
        let inside = inside.map(|v| if self.whole() { v.round() } else { v });
        // Values strictly inside the bracket, each once: none when its ends are neighbours
        // (`observe` then ends the search at the field's resolution).
        let mut values: Vec<f64> = inside
            .filter(|v| *v > search.below && *v < search.above)
            .collect();
        values.dedup();
        values
    }

    /// The search after a round's answers, `(value, holds)` in the order of `round`.
    pub fn observe(&self, search: &Search, answers: &[(f64, bool)]) -> Search {
        let mut next = Search {
            probes: search.probes + answers.len(),
            rounds: search.rounds + 1,
            ..search.clone()
        };
        if search.rounds == 0 {
            let holds = |end: f64| answers.iter().any(|&(v, holds)| v == end && holds);
            let [below, above] = self.bracket;
            next.ended = match (holds(below), holds(above)) {
                (true, _) => Some(Ended::FlipsBelow),
                (false, false) => Some(Ended::NoneUpTo),
                (false, true) => None,
            };
        } else {
            // The first value (in order) where the condition holds bounds it from above; the
            // largest below that where it does not, from below. A condition that holds, stops
            // and holds again is read at its first flip, as a stability limit is.
            let first_holding = answers.iter().find(|(_, holds)| *holds).map(|(v, _)| *v);
            next.above = first_holding.unwrap_or(search.above);
            next.below = answers
                .iter()
                .filter(|&&(v, holds)| !holds && v < next.above)
                .map(|(v, _)| *v)
                .fold(search.below, f64::max);
        }
        if next.ended.is_none() {
            let width = next.above - next.below;
            if width <= self.rtol * next.above.abs() || (self.whole() && width <= 1.0) {
                next.ended = Some(Ended::Found);
            } else if self.max_probes.is_some_and(|most| next.probes >= most) {
                next.ended = Some(Ended::Budget);
            }
        }
        next
    }

    /// The search as far as `answer` knows it: each probe's answer (None for one not run yet,
    /// Err for a record that cannot answer), walked from the first round. Returns the search
    /// and the probes of the first round not answered yet (none when it has ended).
    pub fn replay(
        &self,
        mut answer: impl FnMut(f64) -> Option<Result<bool, String>>,
    ) -> (Search, Vec<f64>) {
        let [below, above] = self.bracket;
        let mut search = Search {
            below,
            above,
            probes: 0,
            rounds: 0,
            ended: None,
        };
        loop {
            let round = self.round(&search);
            if round.is_empty() {
                // Nothing lies strictly inside a bracket that has not ended: it cannot narrow.
                search.ended.get_or_insert(Ended::Resolution);
                return (search, Vec::new());
            }
            let mut answers = Vec::with_capacity(round.len());
            let mut pending = Vec::new();
            for &value in &round {
                match answer(value) {
                    None => pending.push(value),
                    Some(Ok(holds)) => answers.push((value, holds)),
                    Some(Err(why)) => {
                        search.ended = Some(Ended::Unanswered { value, why });
                        return (search, Vec::new());
                    }
                }
            }
            if !pending.is_empty() {
                return (search, pending);
            }
            search = self.observe(&search, &answers);
        }
    }
}

impl Adaptive for BoundarySpec {
    type Outcome = Search;
    const SECTION: &'static str = "boundary";
    const SEARCHES: &'static str = "searches";
    const TABLE: &'static str = "boundaries";
    const TITLE: &'static str = "Boundaries";

    fn fields(&self) -> Vec<&str> {
        vec![&self.field]
    }

    fn worst_case_probes(&self) -> usize {
        BoundarySpec::worst_case_probes(self)
    }

    fn worst_case_rounds(&self) -> Option<usize> {
        Some(BoundarySpec::worst_case_rounds(self))
    }

    /// Each search probes its bracket's two ends, then `per_round` a round until it ends: the
    /// first round is the longest when `per_round` is at most 2, else the second.
    fn rounds_no_longer_from(&self) -> Option<usize> {
        Some(if self.per_round <= 2 { 1 } else { 2 })
    }

    fn out_of_budget(&self, search: &mut Search) {
        let ended = match search.rounds {
            0 => Ended::Unprobed,
            _ => Ended::StudyBudget,
        };
        search.ended.get_or_insert(ended);
    }

    fn replay(&self, record: &mut Lookup) -> (Search, Vec<Probe>) {
        let (search, pending) = BoundarySpec::replay(self, |v| {
            record(&[v]).map(|stored| stored.and_then(|s| self.verdicts.of(&self.flips, &s)))
        });
        (search, pending.into_iter().map(|v| vec![v]).collect())
    }
}

/// Whether `condition` holds over a probe's record, read as a figure's `where` reads its run
/// row (`expression::fields_of_columns`: `amplification`, `status`, `resolved.dt_stable`, the
/// case's `m`). A failed run cannot answer.
pub fn flips(condition: &str, stored: &Stored) -> Result<bool, String> {
    ran(stored)?;
    let mut cells = Vec::new();
    columns::flatten("", stored.to_value(), &mut |name, value| {
        cells.push((name.to_string(), value))
    });
    let fields = expression::fields_of_columns(&cells);
    expression::condition(condition, &Scope::from_fields(&fields))
}

impl Search {
    /// The boundary's estimate: the middle of the final bracket, once the probes narrowed it
    /// (to the tolerance, to the field's resolution, or as far as a budget let them: the
    /// bracket then says how far the estimate may be off).
    pub fn boundary(&self) -> Option<f64> {
        self.bracketed().then_some(0.5 * (self.below + self.above))
    }

    /// Whether probes narrowed the bracket, to the tolerance or not: its ends are then
    /// measured values, not the study's guess.
    pub fn bracketed(&self) -> bool {
        matches!(
            self.ended,
            Some(Ended::Found | Ended::Resolution | Ended::Budget | Ended::StudyBudget)
        )
    }
}

impl std::fmt::Display for Ended {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Ended::Found => write!(f, "found"),
            Ended::FlipsBelow => write!(f, "holds at the lower end already"),
            Ended::NoneUpTo => write!(f, "does not hold at the upper end: no boundary up to it"),
            Ended::Budget => write!(f, "max_probes spent before the tolerance"),
            Ended::Resolution => write!(
                f,
                "at the field's resolution: the bracket's ends are neighbouring values"
            ),
            Ended::StudyBudget => write!(f, "the study's budget spent before the tolerance"),
            Ended::Unprobed => write!(
                f,
                "the study's budget spent before the bracket's ends were probed"
            ),
            Ended::Unanswered { value, why } => {
                write!(f, "the probe at {} cannot answer: {why}", exact(*value))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(per_round: usize) -> BoundarySpec {
        BoundarySpec {
            field: "cfl".into(),
            bracket: [0.5, 2.0],
            flips: "amplification > 1".into(),
            rtol: 1e-3,
            per_round,
            max_probes: None,
            verdicts: Verdicts::default(),
        }
    }

    /// Runs a search to its end against a condition, counting rounds and probes.
    fn search(spec: &BoundarySpec, holds: impl Fn(f64) -> bool) -> Search {
        let mut asked = Vec::new();
        loop {
            let (search, pending) =
                spec.replay(|v| asked.contains(&v.to_bits()).then(|| Ok(holds(v))));
            if pending.is_empty() {
                return search;
            }
            for v in pending {
                assert!(!asked.contains(&v.to_bits()), "{v} probed twice");
                asked.push(v.to_bits());
            }
        }
    }

    /// A condition with a known boundary is found to the tolerance, in the rounds k-section
    /// promises, never below the boundary's bracket.
    #[test]
    fn a_known_boundary_is_found_to_the_tolerance_in_the_promised_rounds() {
        for boundary in [0.5000001, 0.73, 1.0, 1.2345, 1.999] {
            for per_round in [1, 2, 3, 7] {
                let spec = spec(per_round);
                let found = search(&spec, |v| v >= boundary);
                assert_eq!(found.ended, Some(Ended::Found), "{boundary} {per_round}");
                assert!(found.below < boundary && boundary <= found.above);
                let estimate = found.boundary().unwrap();
                assert!(
                    (estimate - boundary).abs() <= spec.rtol * boundary,
                    "{estimate}"
                );
                // Rounds after the first: log_{k+1} of the narrowing, rounded up.
                let promised = ((1.5 / (spec.rtol * boundary)).ln() / ((per_round + 1) as f64).ln())
                    .ceil() as usize;
                assert!(
                    found.rounds <= 1 + promised,
                    "{} > 1 + {promised}",
                    found.rounds
                );
                assert!(found.probes <= spec.worst_case_probes());
            }
        }
    }

    #[test]
    fn a_condition_that_never_flips_or_flips_at_once_ends_at_the_first_round() {
        let spec = spec(1);
        let none = search(&spec, |_| false);
        assert_eq!((none.ended, none.probes), (Some(Ended::NoneUpTo), 2));
        let below = search(&spec, |_| true);
        assert_eq!(below.boundary(), None);
        assert_eq!((below.ended, below.probes), (Some(Ended::FlipsBelow), 2));
    }

    #[test]
    fn the_budget_is_honoured() {
        let five = BoundarySpec {
            max_probes: Some(5),
            verdicts: Verdicts::default(),
            ..spec(2)
        };
        let found = search(&five, |v| v >= 1.2345);
        assert_eq!(found.ended, Some(Ended::Budget));
        assert_eq!(found.probes, 5);
        // Stopped short of the tolerance, the answer is its bracket's middle, the truth inside.
        let (below, above) = (found.below, found.above);
        assert!(below < 1.2345 && 1.2345 <= above, "[{below}, {above}]");
        assert_eq!(found.boundary(), Some(0.5 * (below + above)));
        assert_eq!(five.worst_case_probes(), 5);
        let three = BoundarySpec {
            max_probes: Some(3),
            verdicts: Verdicts::default(),
            ..spec(1)
        };
        assert_eq!(search(&three, |v| v >= 1.2345).probes, 3);
    }

    /// Killed after any number of probes and run again, the search asks only for what it has
    /// not run (the helper panics on a repeat) and ends where an uninterrupted one does.
    #[test]
    fn a_replay_with_some_answers_asks_only_for_the_rest() {
        let spec = spec(3);
        let whole = search(&spec, |v| v >= 1.2345);
        let (part, pending) = spec.replay(|v| (v == 0.5 || v == 2.0).then_some(Ok(v >= 1.2345)));
        assert_eq!(part.rounds, 1);
        assert_eq!(pending, [0.875, 1.25, 1.625]);
        let failed = spec.replay(|v| {
            Some(if v == 2.0 {
                Err("failed".into())
            } else {
                Ok(false)
            })
        });
        assert!(matches!(failed.0.ended, Some(Ended::Unanswered { value, .. }) if value == 2.0));
        assert_eq!(whole.boundary(), search(&spec, |v| v >= 1.2345).boundary());
    }

    /// A study's budget spent before a search's first round was answered leaves no estimate
    /// (the middle of a bracket never probed is no measurement); spent after it, the estimate
    /// stands with its measured bracket.
    #[test]
    fn a_budget_spent_before_the_ends_were_probed_gives_no_boundary() {
        let spec = spec(3);
        let (mut unprobed, _) = spec.replay(|v| (v == 0.5).then_some(Ok(false)));
        assert_eq!(unprobed.rounds, 0);
        Adaptive::out_of_budget(&spec, &mut unprobed);
        assert_eq!(unprobed.ended, Some(Ended::Unprobed));
        assert_eq!(unprobed.boundary(), None);
        let (mut probed, _) = spec.replay(|v| (v == 0.5 || v == 2.0).then_some(Ok(v >= 1.2345)));
        Adaptive::out_of_budget(&spec, &mut probed);
        assert_eq!(probed.ended, Some(Ended::StudyBudget));
        assert_eq!(probed.boundary(), Some(1.25));
    }

    /// A tolerance finer than the field can resolve (a study's `rtol` is refused below
    /// `FINEST_RTOL`, but a bracket can still meet neighbouring doubles) ends the search there,
    /// in bounded probes, with a boundary.
    #[test]
    fn a_search_ends_at_the_fields_resolution() {
        for (rtol, per_round) in [(1e-300, 1), (f64::MIN_POSITIVE, 3), (1e-17, 2)] {
            let spec = BoundarySpec {
                rtol,
                max_probes: Some(usize::MAX),
                verdicts: Verdicts::default(),
                ..spec(per_round)
            };
            let found = search(&spec, |v| v >= 1.2345);
            assert_eq!(found.ended, Some(Ended::Resolution), "{rtol}");
            assert!(found.probes < 200, "{} probes", found.probes);
            assert_eq!(found.above, f64::from_bits(found.below.to_bits() + 1));
            assert!(found.below < 1.2345 && 1.2345 <= found.above);
            assert!(found.boundary().is_some());
        }
    }

    #[test]
    fn bad_specs_are_refused_naming_the_field() {
        let refused = |change: fn(&mut BoundarySpec)| {
            let mut s = spec(1);
            change(&mut s);
            s.check().unwrap_err().0
        };
        assert_eq!(refused(|s| s.bracket = [1.0, 1.0]), "boundary.bracket");
        assert_eq!(refused(|s| s.bracket = [f64::NAN, 1.0]), "boundary.bracket");
        assert_eq!(refused(|s| s.rtol = 0.0), "boundary.rtol");
        assert_eq!(refused(|s| s.rtol = 1e-17), "boundary.rtol");
        assert_eq!(refused(|s| s.rtol = 1e-300), "boundary.rtol");
        assert_eq!(refused(|s| s.per_round = 0), "boundary.per_round");
        assert_eq!(refused(|s| s.max_probes = Some(0)), "boundary.max_probes");
        assert_eq!(refused(|s| s.field = "integrator".into()), "boundary.field");
        assert_eq!(
            refused(|s| s.field = "horizon_profile".into()),
            "boundary.field"
        );
        // `m` takes whole numbers: the bracket's ends must be whole.
        assert_eq!(refused(|s| s.field = "m".into()), "boundary.bracket");
        assert!(spec(1).check().is_ok());
    }

    /// Along a field of whole numbers (`m`) every probe is whole, none twice, and the search
    /// ends once its bracket's ends are neighbours, in the rounds bisection of the integers
    /// takes.
    #[test]
    fn a_whole_field_is_searched_on_whole_values_to_neighbours() {
        for per_round in [1, 3] {
            for boundary in [2.0, 7.0, 20.0] {
                let spec = BoundarySpec {
                    field: "m".into(),
                    bracket: [1.0, 20.0],
                    rtol: 1e-3,
                    ..spec(per_round)
                };
                assert!(spec.check().is_ok());
                let found = search(&spec, |v| {
                    assert_eq!(v.fract(), 0.0, "a whole probe");
                    v >= boundary
                });
                assert_eq!(found.ended, Some(Ended::Found), "{boundary}");
                assert_eq!((found.below, found.above), (boundary - 1.0, boundary));
                assert!(found.probes <= spec.worst_case_probes(), "{found:?}");
            }
        }
    }
}
