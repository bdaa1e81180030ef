//! What the tables of adaptive studies share: a row per point of the sweep, led by the fields
//! that tell the points apart; a number only where one was measured; the file written beside the
//! study's other tables, with the study's description and what each column holds.

use crate::model::study::{fields_telling_apart, Study};
use crate::run::search::Searched;
use crate::store::table::{self, Row};
use crate::store::{Fault, Store};
use serde_json::Value;
use std::path::PathBuf;

/// A row per point, in the order of the sweep, holding the fields that tell the points apart.
pub fn origin_rows<O>(searched: &[Searched<O>]) -> Vec<Row> {
    let swept = fields_telling_apart(searched.iter().map(|s| &s.origin));
    searched
        .iter()
        .map(|s| {
            let mut row = Row::default();
            for name in &swept {
                row.set(name, s.origin.column(name).unwrap_or(Value::Null));
            }
            row
        })
        .collect()
}

/// A number that was measured, or null: a value that is not finite is never stored.
pub fn measured(x: Option<f64>) -> Value {
    x.filter(|x| x.is_finite()).map_or(Value::Null, Value::from)
}

/// Text, or null.
pub fn text(x: Option<String>) -> Value {
    x.map_or(Value::Null, Value::from)
}

/// Where the answer table `name` of the store's study lies: `<study>-<name>.parquet` beside the
/// study's other tables.
pub fn path(store: &Store, name: &str) -> PathBuf {
    store.table(&format!("{}-{name}.parquet", store.study))
}

/// The swept fields of an answer table's `rows`: their columns other than the answer's (named
/// by the table's `notes`), in first-seen order.
pub fn swept<'a>(rows: impl IntoIterator<Item = &'a Row>, notes: &[(&str, &str)]) -> Vec<String> {
    let answer = |name: &str| notes.iter().any(|(column, _)| *column == name);
    let mut swept: Vec<String> = Vec::new();
    for row in rows {
        for (name, _) in row.cells() {
            if !answer(name) && !swept.iter().any(|s| s == name) {
                swept.push(name.to_string());
            }
        }
    }
    swept
}

/// Writes `rows` as `<study>-<name>.parquet` and returns its path.
pub fn write(
    study: &Study,
    store: &Store,
    name: &str,
    rows: &[Row],
    notes: &[(&str, &str)],
) -> Result<PathBuf, Fault> {
    let path = path(store, name);
    let about = table::About {
        description: &study.description,
        notes,
    };
    let _outputs = store.lock_outputs()?;
    table::write_parquet_about(&[(&path, rows)], &about)?;
    Ok(path)
}
