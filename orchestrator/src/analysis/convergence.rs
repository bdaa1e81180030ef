//! The refinement table, `<study>-convergence.parquet`: one row per refinement, with the swept
//! fields that tell them apart, the levels run, the finest level's value and error, the orders
//! of the finest pair and fitted over the asymptotic levels, where the asymptotic regime began
//! and why the refinement stopped.

use crate::model::refine::Refinement;
use crate::model::study::{fields_telling_apart, Study};
use crate::run::search::Searched;
use crate::store::table::{self, Row};
use crate::store::{Fault, Store};
use serde_json::Value;
use std::path::PathBuf;

/// A number that was measured, or null: a value that is not finite is never stored.
fn number(x: Option<f64>) -> Value {
    x.filter(|x| x.is_finite()).map_or(Value::Null, Value::from)
}

/// The table's rows, in the order of the sweep.
pub fn rows(field: &str, searched: &[Searched<Refinement>]) -> Vec<Row> {
    let swept = fields_telling_apart(searched.iter().map(|s| &s.origin));
    searched
        .iter()
        .map(|s| {
            let mut row = Row::default();
            for name in &swept {
                row.set(name, s.origin.get(name).cloned().unwrap_or(Value::Null));
            }
            let refinement = &s.outcome;
            let finest = refinement.levels.last();
            row.set("field", Value::from(field));
            row.set("levels", Value::from(refinement.levels.len()));
            row.set("finest", number(finest.map(|l| l.0)));
            row.set("error", number(finest.map(|l| l.1)));
            row.set("order_finest", number(refinement.finest_order()));
            row.set("order_fitted", number(refinement.fitted_order()));
            row.set("asymptotic_from", number(refinement.asymptotic_from()));
            let stopped = refinement.stopped.as_ref().map(ToString::to_string);
            row.set("stopped", stopped.map_or(Value::Null, Value::from));
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
    let path = store.table(&format!("{}-convergence.parquet", store.study));
    let rows = rows(field, searched);
    let about = table::About {
        description: &study.description,
        notes: NOTES,
    };
    let _outputs = store.lock_outputs()?;
    table::write_parquet_about(&[(&path, &rows)], &about)?;
    Ok(path)
}
