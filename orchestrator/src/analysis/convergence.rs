//! The refinement table, `<study>-convergence.parquet`: one row per refinement, with the swept
//! fields that tell them apart, the levels run, the finest level's value and error, the orders
//! of the finest pair and fitted over the asymptotic levels, where the asymptotic regime began
//! and why the refinement stopped.

use crate::analysis::answer_table::{self, measured, origin_rows, text};
use crate::model::adaptive::Adaptive as _;
use crate::model::refine::{RefineSpec, Refinement};
use crate::model::study::Study;
use crate::run::search::Searched;
use crate::store::table::Row;
use crate::store::{Fault, Store};
use serde_json::Value;
use std::path::PathBuf;

/// The table's rows, in the order of the sweep.
pub fn rows(field: &str, searched: &[Searched<Refinement>]) -> Vec<Row> {
    origin_rows(searched)
        .into_iter()
        .zip(searched)
        .map(|(mut row, s)| {
            let refinement = &s.outcome;
            let finest = refinement.levels.last();
            row.set("field", Value::from(field));
            row.set("levels", Value::from(refinement.levels.len()));
            row.set("finest", measured(finest.map(|l| l.0)));
            row.set("error", measured(finest.map(|l| l.1)));
            row.set("order_finest", measured(refinement.finest_order()));
            row.set("order_fitted", measured(refinement.fitted_order()));
            row.set("asymptotic_from", measured(refinement.asymptotic_from()));
            row.set(
                "stopped",
                text(refinement.stopped.as_ref().map(ToString::to_string)),
            );
            row
        })
        .collect()
}

/// What the columns hold, in the file's metadata.
const NOTES: &[(&str, &str)] = &[
    ("field", "the case field refined"),
    ("levels", "levels run, the coarsest included"),
    ("finest", "the finest level's value"),
    ("error", "the finest level's error"),
    (
        "order_finest",
        "the observed order of the two finest levels",
    ),
    (
        "order_fitted",
        "least-squares order over the levels from asymptotic_from (all when not established)",
    ),
    (
        "asymptotic_from",
        "the level at which the three agreeing orders begin; null if not established",
    ),
    ("stopped", "why the refinement stopped"),
];

/// Writes the table beside the study's others and returns its path.
pub fn write(
    study: &Study,
    store: &Store,
    field: &str,
    searched: &[Searched<Refinement>],
) -> Result<PathBuf, Fault> {
    answer_table::write(
        study,
        store,
        RefineSpec::TABLE,
        &rows(field, searched),
        NOTES,
    )
}
