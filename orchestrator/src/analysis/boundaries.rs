//! The boundary table, `<study>-boundaries.parquet`: one row per search, with the swept fields
//! that tell the searches apart, the boundary and its bracket, the theory's prediction, the
//! probes and rounds spent, and why the search ended.

use crate::analysis::answer_table::{self, measured, origin_rows, text};
use crate::model::adaptive::Adaptive as _;
use crate::model::boundary::{BoundarySpec, Search};
use crate::model::expression;
use crate::model::study::Study;
use crate::run::search::Searched;
use crate::store::table::Row;
use crate::store::{Fault, Store};
use schema::choices::Method;
use schema::record::Stored;
use serde::Deserialize as _;
use serde_json::Value;
use std::path::PathBuf;

/// The table's rows, in the order of the sweep.
pub fn rows(spec: &BoundarySpec, searched: &[Searched<Search>]) -> Vec<Row> {
    origin_rows(searched)
        .into_iter()
        .zip(searched)
        .map(|(mut row, s)| {
            let search = &s.outcome;
            let predicted = s.record.as_ref().and_then(|r| prediction(spec, r));
            // The bracket was narrowed by probes, whether or not to the tolerance.
            let bracketed = search.bracketed();
            row.set("field", Value::from(spec.field.as_str()));
            row.set("boundary", measured(search.boundary()));
            row.set("boundary_lo", measured(bracketed.then_some(search.below)));
            row.set("boundary_hi", measured(bracketed.then_some(search.above)));
            row.set("predicted", measured(predicted));
            row.set(
                "gap",
                measured(search.boundary().zip(predicted).map(|(b, p)| b / p - 1.0)),
            );
            row.set("probes", Value::from(search.probes));
            row.set("rounds", Value::from(search.rounds));
            row.set(
                "ended",
                text(search.ended.as_ref().map(ToString::to_string)),
            );
            row
        })
        .collect()
}

/// Whether a row's boundary lies below the prediction by more than the search's tolerance, its
/// whole bracket below it: the theory calls that value stable and the measurement finds it
/// unstable.
pub fn below_theory(row: &Row, rtol: f64) -> bool {
    let bracket_below = (row.number("boundary_hi").zip(row.number("predicted")))
        .is_none_or(|(high, predicted)| high < predicted);
    row.number("gap").is_some_and(|gap| gap < -rtol) && bracket_below
}

/// What the columns hold, in the file's metadata; the columns before them are the swept fields.
pub const NOTES: &[(&str, &str)] = &[
    ("field", "the case field searched along"),
    ("boundary", "the middle of the final bracket, where the condition starts to hold (to the tolerance, or as far as a budget let the probes narrow it: see boundary_lo, boundary_hi); null if the search found none"),
    ("boundary_lo", "the largest value probed where the condition does not hold, once the bracket narrowed (found, at the field's resolution, or a budget spent)"),
    ("boundary_hi", "the smallest value probed where it holds, likewise"),
    ("predicted", "the boundary the solver's theory gives for what the condition reads: the symbol's dt_stable for stability, dt_positive for `positivity`; null where it has none"),
    ("gap", "boundary / predicted - 1"),
    ("probes", "runs the search spent, the bracket's ends included"),
    ("rounds", "rounds of probes, each run at once on the pool"),
    ("ended", "why the search stopped"),
];

/// Writes the table beside the study's others and returns its path.
pub fn write(
    study: &Study,
    store: &Store,
    spec: &BoundarySpec,
    searched: &[Searched<Search>],
) -> Result<PathBuf, Fault> {
    answer_table::write(
        study,
        store,
        BoundarySpec::TABLE,
        &rows(spec, searched),
        NOTES,
    )
}

/// The boundary the solver's theory gives for what `spec`'s condition reads, from a probe's
/// record. Of stability (a condition on `amplification`, `status` …): an explicit integrator's
/// dt_stable (from the operator's symbol for the nonlocal method, from its computed spectrum
/// where the horizon varies, the classical bound for finite differences, the lattice's symbol
/// for PSE); implicit integrators have none. Of positivity (a condition on `positivity`
/// alone): the record's `dt_positive`, where the theory has one. It is the boundary of `dt`,
/// and of `cfl` over dt_stable; other fields have none.
pub fn prediction(spec: &BoundarySpec, stored: &Stored) -> Option<f64> {
    let record = stored.record()?;
    let resolved = &record.resolved;
    let names = expression::names(&spec.flips).unwrap_or_default();
    let reads = |name: &str| names.iter().any(|n| n == name);
    let limit = match (reads("positivity"), reads("amplification")) {
        (true, false) => resolved.dt_positive?,
        (true, true) => return None,
        (false, _) => {
            let case = schema::case::Case::deserialize(&record.case).ok()?;
            let explicit = match case.method {
                Method::Nonlocal => resolved.integrator.is_none_or(|i| !i.is_implicit()),
                Method::FdExplicit | Method::Pse => true,
                _ => false,
            };
            // Where no symbol exists (a varying horizon), the computed spectrum's.
            let theory = resolved.dt_stable_spectrum.unwrap_or(resolved.dt_stable);
            explicit.then_some(theory)?
        }
    };
    match spec.field.as_str() {
        "cfl" => Some(limit / resolved.dt_stable),
        "dt" => Some(limit),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_prediction_is_the_theory_of_what_the_condition_reads() {
        // A forward-Euler record: dt_stable 2e-3, dt_positive 1e-3.
        let mut record = schema::record::columns::every_field();
        fn resolved(r: &mut Stored) -> &mut schema::record::Resolved {
            &mut r.record_mut().unwrap().resolved
        }
        resolved(&mut record).dt_stable_spectrum = None;
        let predicted = |record: &Stored, field: &str, flips: &str| {
            let spec = json!({"field": field, "bracket": [0.5, 2], "flips": flips, "rtol": 1e-3});
            prediction(&serde_json::from_value(spec).unwrap(), record)
        };
        assert_eq!(predicted(&record, "cfl", "amplification > 1"), Some(1.0));
        assert_eq!(predicted(&record, "cfl", "status == 'diverged'"), Some(1.0));
        assert_eq!(predicted(&record, "dt", "amplification > 1"), Some(2e-3));
        assert_eq!(predicted(&record, "cfl", "positivity < 0"), Some(0.5));
        assert_eq!(predicted(&record, "dt", "positivity < 0"), Some(1e-3));
        assert_eq!(
            predicted(&record, "cfl", "positivity < 0 || amplification > 1"),
            None
        );
        assert_eq!(predicted(&record, "m", "amplification > 1"), None);
        // A varying horizon: no symbol, and dt_stable a floor; its spectrum's step is the theory.
        resolved(&mut record).dt_stable_spectrum = Some(3e-3);
        assert_eq!(predicted(&record, "cfl", "amplification > 1"), Some(1.5));
        assert_eq!(predicted(&record, "dt", "amplification > 1"), Some(3e-3));
    }

    /// A finding is a boundary below the theory by more than the tolerance with its whole
    /// bracket below the prediction: a bracket that still holds the prediction is no finding.
    #[test]
    fn a_finding_needs_the_whole_bracket_below_the_theory() {
        let row = |gap: f64, high: Option<f64>| {
            let mut row = Row::default();
            row.set("predicted", Value::from(1.0));
            row.set("gap", Value::from(gap));
            row.set("boundary_hi", high.map_or(Value::Null, Value::from));
            row
        };
        assert!(below_theory(&row(-0.01, Some(0.995)), 1e-3));
        assert!(!below_theory(&row(-0.01, Some(1.001)), 1e-3));
        assert!(!below_theory(&row(-5e-4, Some(0.9996)), 1e-3));
        assert!(!below_theory(&row(0.01, Some(1.02)), 1e-3));
        assert!(below_theory(&row(-0.01, None), 1e-3));
    }
}
