//! Adaptive studies: from each point of the sweep, probes along one case field, each round's
//! values chosen from the records of the rounds before: a boundary search (`boundary`) or a
//! refinement that stops once its order is established (`refine`). Every probe is a point like
//! any other. A question is a function of its records: `replay` walks it from the first round
//! with the records known and stops at the first round with a probe not run yet, so an
//! interrupted study resumes from the store without running a probe twice.

use schema::record::Stored;
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

    /// A probe's value as its case holds it.
    fn value(&self, v: f64) -> Value;

    /// The most probes one point's question can take.
    fn worst_case_probes(&self) -> usize;

    /// The question as far as `record` knows it, and the values of the first round with a
    /// probe not run yet (none once it is answered).
    fn replay(&self, record: &mut Lookup) -> (Self::Outcome, Vec<f64>);
}
