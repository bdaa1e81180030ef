//! Adaptive studies: from each point of the sweep, probes along one case field (two for an
//! error target in space and time), each round's values chosen from the records of the rounds
//! before: a boundary search (`boundary`), a refinement that stops once its order is
//! established (`refine`), the cheapest configuration for an error target (`target`). Every
//! probe is a point like any other. A question is a function of its records: `replay` walks it from the first round
//! with the records known and stops at the first round with a probe not run yet, so an
//! interrupted study resumes from the store without running a probe twice.

use schema::case::{Case, Numeric};
use schema::record::{column, columns, Stored};
use serde::Deserialize;
use serde_json::Value;
use std::sync::Arc;

/// A probe: the values of the question's fields, in the order of `Adaptive::fields`.
pub type Probe = Vec<f64>;

/// The record of a probe that ran (Err: the solver refused it or it stored nothing). Shared:
/// every round replays every search through it.
pub type ProbeRecord = Result<Arc<Stored>, String>;

/// A probe's record, None for a probe not run yet.
pub type Lookup<'a> = dyn FnMut(&[f64]) -> Option<ProbeRecord> + 'a;

pub trait Adaptive {
    /// What a question found from one point.
    type Outcome;

    /// The study file's name for the question (`boundary`, `refine`), for messages.
    const SECTION: &'static str;

    /// What its questions from the sweep's points are called: `searches`, `candidates`.
    const SEARCHES: &'static str;

    /// The table of its answers: `<study>-<table>.parquet`.
    const TABLE: &'static str;

    /// The title of its answers in the report.
    const TITLE: &'static str;

    /// Whether a point's repeats are one question, searched once (an error target, whose
    /// answer is timed over the repeats), rather than a question each.
    const ONE_SEARCH_PER_POINT: bool = false;

    /// The case fields probed: one, or a spatial and a temporal one.
    fn fields(&self) -> Vec<&str>;

    /// The first field probed, which names the question in messages.
    fn field(&self) -> &str {
        self.fields()[0]
    }

    /// The most probes one point's question can take.
    fn worst_case_probes(&self) -> usize;

    /// The rounds of probes its questions take at most, where that is known before they run.
    fn worst_case_rounds(&self) -> Option<usize> {
        None
    }

    /// The round from which no later round is longer than the one before it (the same probes
    /// or fewer, each of about the same cost), so that a round's length times the rounds left
    /// bounds the time left; `None` when its rounds grow (a finer grid each).
    fn rounds_no_longer_from(&self) -> Option<usize> {
        None
    }

    /// Whether the solver's refusal of a probe (`nlsolve check`'s sentence) is an answer the
    /// question reads, such as a step above the stable one, rather than a fault of the study:
    /// such a probe is not run, and not counted among the study's refusals.
    fn absorbs(&self, _refusal: &str) -> bool {
        false
    }

    /// Ends an outcome not ended yet because the study's budget is spent.
    fn out_of_budget(&self, outcome: &mut Self::Outcome);

    /// The question as far as `record` knows it, and the probes of the first round not run yet
    /// (none once it is answered).
    fn replay(&self, record: &mut Lookup) -> (Self::Outcome, Vec<Probe>);
}

/// An adaptive question whatever its kind, as a study holds it (`Study::question`): the
/// object-safe face of `Adaptive`, which every kind's spec has. `as_any` gives the spec back to
/// the code of its own kind (`kinds`), and to a figure that draws one kind's answers.
pub trait Kind: std::fmt::Debug + Send + Sync {
    fn section(&self) -> &'static str;
    fn searches(&self) -> &'static str;
    fn table(&self) -> &'static str;
    fn title(&self) -> &'static str;
    fn field(&self) -> &str;
    fn fields(&self) -> Vec<&str>;
    fn worst_case_probes(&self) -> usize;
    fn worst_case_rounds(&self) -> Option<usize>;
    fn rounds_no_longer_from(&self) -> Option<usize>;
    fn one_search_per_point(&self) -> bool;
    fn as_any(&self) -> &dyn std::any::Any;
}

impl<A: Adaptive + std::fmt::Debug + Send + Sync + 'static> Kind for A {
    fn section(&self) -> &'static str {
        A::SECTION
    }

    fn searches(&self) -> &'static str {
        A::SEARCHES
    }

    fn table(&self) -> &'static str {
        A::TABLE
    }

    fn title(&self) -> &'static str {
        A::TITLE
    }

    fn field(&self) -> &str {
        Adaptive::field(self)
    }

    fn fields(&self) -> Vec<&str> {
        Adaptive::fields(self)
    }

    fn worst_case_probes(&self) -> usize {
        Adaptive::worst_case_probes(self)
    }

    fn worst_case_rounds(&self) -> Option<usize> {
        Adaptive::worst_case_rounds(self)
    }

    fn rounds_no_longer_from(&self) -> Option<usize> {
        Adaptive::rounds_no_longer_from(self)
    }

    fn one_search_per_point(&self) -> bool {
        A::ONE_SEARCH_PER_POINT
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// A probe's value of `field` as its case holds it: a whole number for a field that takes only
/// whole ones (`n`, `m`), else the number.
pub fn value(field: &str, v: f64) -> Value {
    match Case::numeric(field) {
        Numeric::Whole => Value::from(v.round() as u64),
        Numeric::Real | Numeric::No => Value::from(v),
    }
}

/// Whether `field` counts nodes (`n`: whole, finer upward) rather than being a step (`dt`:
/// finer downward).
pub fn counts_nodes(field: &str) -> bool {
    field == "n"
}

/// The largest first value of a searched field: no grid has more nodes along a side, and no
/// time step is longer (in the problems' units, where t_end is O(1)).
pub const LARGEST_START: f64 = 1e9;

/// A question's first resolution `start` along `field`: a positive number up to
/// `LARGEST_START`, whole for `n`; a refusal names `<section>.start`.
pub fn check_start(section: &str, field: &str, start: f64) -> Result<(), (String, String)> {
    let place = format!("{section}.start");
    let given = schema::text::exact(start);
    if !(start.is_finite() && start > 0.0) {
        return Err((place, format!("must be a positive number (got {given})")));
    }
    if start > LARGEST_START {
        return Err((
            place,
            format!("{given} is past any run (at most {LARGEST_START:e}); give the first value a run can have"),
        ));
    }
    if counts_nodes(field) && start.fract() != 0.0 {
        return Err((
            place,
            format!("`n` counts nodes: give a whole number (got {given})"),
        ));
    }
    Ok(())
}

/// Whether the solver refused a case for its time step (above the integrator's stable one).
pub fn refused_for_its_step(refusal: &str) -> bool {
    refusal.contains("above dt_stable")
}

/// Whether a probe ran: a failed run answers no question, and says why (its message made
/// printable: a stored record may come from elsewhere, and this text reaches the answer lines,
/// the boundaries table and the report).
pub fn ran(stored: &Stored) -> Result<(), String> {
    match stored.record() {
        Some(_) => Ok(()),
        None => Err(format!(
            "the run failed: {}",
            schema::text::printable(stored.message())
        )),
    }
}

/// Column `name` of a probe's record (an error, a cost), a positive finite number: what a
/// question reads as a measurement. A failed run has none.
pub fn positive(name: &str, stored: &Stored) -> Result<f64, String> {
    ran(stored)?;
    match column(stored, name).and_then(|v| v.as_f64()) {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        Some(x) => Err(format!(
            "`{name}` is {}, not a positive number",
            schema::text::exact(x)
        )),
        None => Err(format!("its record has no `{name}`")),
    }
}

/// What a study may spend on its adaptive question over all its points: runs, and
/// core-seconds (set-up and solve time × threads × ranks, as the records measured them). No
/// round starts once either is spent, and a round is cut to the runs left; the core-seconds of
/// a round are known once it ran, so they may pass the budget by that round.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    #[serde(default)]
    pub runs: Option<usize>,
    #[serde(default)]
    pub core_seconds: Option<f64>,
}

/// What the probes stored so far spent.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spent {
    pub runs: usize,
    pub core_seconds: f64,
}

impl Budget {
    /// The budget's own rules, each refusal naming the field at fault.
    pub fn check(&self) -> Result<(), (String, String)> {
        if self.runs == Some(0) {
            return Err(("budget.runs".into(), "must be at least 1 (got 0)".into()));
        }
        match self.core_seconds {
            Some(s) if !(s.is_finite() && s > 0.0) => Err((
                "budget.core_seconds".into(),
                format!(
                    "must be a positive number of seconds (got {})",
                    schema::text::exact(s)
                ),
            )),
            _ => Ok(()),
        }
    }

    /// Whether `spent` leaves nothing to start a round with.
    pub fn is_spent(&self, spent: &Spent) -> bool {
        self.runs.is_some_and(|runs| spent.runs >= runs)
            || self.core_seconds.is_some_and(|s| spent.core_seconds >= s)
    }

    /// The runs left, if the budget counts runs.
    pub fn runs_left(&self, spent: &Spent) -> Option<usize> {
        self.runs.map(|runs| runs.saturating_sub(spent.runs))
    }
}

impl Spent {
    /// What `records` spent, each key once (two questions may share a probe).
    pub fn spent_by<'a>(records: impl IntoIterator<Item = &'a Stored>) -> Spent {
        let mut spent = Spent::default();
        let mut seen = std::collections::HashSet::new();
        for stored in records.into_iter().filter(|s| seen.insert(s.key.as_str())) {
            spent.add(stored);
        }
        spent
    }

    /// `stored` counted in: a run, and its core-seconds.
    fn add(&mut self, stored: &Stored) {
        self.runs += 1;
        self.core_seconds += core_seconds(stored);
    }
}

/// A run's core-seconds: its set-up and solve seconds × threads × ranks (0 for a run that
/// failed before it timed anything).
pub fn core_seconds(stored: &Stored) -> f64 {
    let number = |name: &str| column(stored, name).and_then(|v| v.as_f64());
    let seconds = number(columns::SETUP_S).unwrap_or(0.0) + number(columns::SOLVE_S).unwrap_or(0.0);
    let cores = number(columns::THREADS).unwrap_or(1.0) * number(columns::RANKS).unwrap_or(1.0);
    seconds * cores
}
