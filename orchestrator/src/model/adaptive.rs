//! Adaptive studies: from each point of the sweep, probes along one case field, each round's
//! values chosen from the records of the rounds before: a boundary search (`boundary`) or a
//! refinement that stops once its order is established (`refine`). Every probe is a point like
//! any other. A question is a function of its records: `replay` walks it from the first round
//! with the records known and stops at the first round with a probe not run yet, so an
//! interrupted study resumes from the store without running a probe twice.

use schema::record::{column, Stored};
use serde_json::Value;

/// The record of a probe that ran (Err: the solver refused it or it stored nothing), None
/// for a probe not run yet.
pub type Lookup<'a> = dyn FnMut(f64) -> Option<Result<Stored, String>> + 'a;

pub trait Adaptive {
    /// What a question found from one point.
    type Outcome;

    /// The study file's name for the question (`boundary`, `refine`), for messages.
    const SECTION: &'static str;

    /// The case field probed.
    fn field(&self) -> &str;

    /// A probe's value as its case holds it: a whole number of nodes for `n`, else the number.
    fn value(&self, v: f64) -> Value {
        match self.field() {
            "n" => Value::from(v.round() as u64),
            _ => Value::from(v),
        }
    }

    /// The most probes one point's question can take.
    fn worst_case_probes(&self) -> usize;

    /// The question as far as `record` knows it, and the values of the first round with a
    /// probe not run yet (none once it is answered).
    fn replay(&self, record: &mut Lookup) -> (Self::Outcome, Vec<f64>);
}

/// Column `name` of a probe's record (an error, a cost), a positive finite number: what a
/// question reads as a measurement. A failed run has none.
pub fn positive(name: &str, stored: &Stored) -> Result<f64, String> {
    if stored.record().is_none() {
        return Err(format!("the run failed: {}", stored.message()));
    }
    match column(stored, name).and_then(|v| v.as_f64()) {
        Some(x) if x.is_finite() && x > 0.0 => Ok(x),
        Some(x) => Err(format!("`{name}` is {x}, not a positive number")),
        None => Err(format!("its record has no `{name}`")),
    }
}
