//! `nlstudy collect`: the stored records of the study's current points as two Parquet tables,
//! `<study>.parquet` (one row per run and repeat) and `<study>-summary.parquet` (one row per
//! point; see `summary`). Records of points the study no longer has (removed from the sweep,
//! or run by another solver version) stay stored but are left out.

use crate::analysis::summary;
use crate::run::plan::Planned;
use crate::store::table::{self, Row};
use crate::store::Store;
use polars::prelude::DataFrame;
use serde_json::{json, Value};
use std::collections::{HashMap, HashSet};
use std::path::PathBuf;

pub struct Collected {
    pub runs: PathBuf,
    pub summary: PathBuf,
    pub rows: usize,
    pub points: usize,
    /// Runs (points and repeats) with no stored record yet.
    pub missing: usize,
    /// Stored records that are not points of the study now.
    pub left_out: usize,
    /// The summary table, for printing.
    pub table: DataFrame,
}

/// The fields that lead a run's row; the case follows, then the results, then provenance.
const LEADING: &[&str] = &["key", "case_id", "repeat", "status", "message"];

/// One run's row: the point's label and series, then the record, flattened.
fn run_row(planned: &Planned, record: &Value) -> Row {
    let mut row = Row::default();
    let series = &planned.point.series;
    row.set("point", json!(planned.point.label_without_repeat()));
    if let Some(branch) = &planned.point.branch {
        row.set("branch", json!(branch));
    }
    row.set("refinement_series", json!(series.refinement));
    row.set("scaling_series", json!(series.scaling));
    let Some(record) = record.as_object() else {
        return row;
    };
    for field in LEADING {
        row.set(field, record.get(*field).cloned().unwrap_or(Value::Null));
    }
    let rank = |name: &str| match name {
        "case" => 0,
        "provenance" => 2,
        _ => 1,
    };
    let mut rest: Vec<(&String, &Value)> = record
        .iter()
        .filter(|(name, _)| !LEADING.contains(&name.as_str()))
        .collect();
    rest.sort_by_key(|(name, _)| rank(name)); // stable: names stay sorted within a rank
    for (name, value) in rest {
        // The case with its defaults filled in, as the solver resolves it now (records keep
        // the case as keyed, which leaves some defaults out).
        let value = match (name.as_str(), &planned.case) {
            ("case", Ok(checked)) => &checked.resolved,
            _ => value,
        };
        row.set_flattened(name, value);
    }
    row
}

/// Writes the tables; `None` when no run of the study is stored yet.
pub fn collect(planned: &[Planned], store: &Store) -> Result<Option<Collected>, String> {
    let records: HashMap<String, Value> = store
        .records()
        .into_iter()
        .filter_map(|r| Some((r.get("key")?.as_str()?.to_string(), r)))
        .collect();
    let mut rows = Vec::new();
    let mut missing = 0;
    // Points of different branches may be one case: each gets its row from the one record.
    for p in planned {
        match records.get(&p.key) {
            Some(record) => rows.push(run_row(p, record)),
            None => missing += 1,
        }
    }
    let used: HashSet<&str> = planned.iter().map(|p| p.key.as_str()).collect();
    let left_out = records
        .keys()
        .filter(|k| !used.contains(k.as_str()))
        .count();
    if rows.is_empty() {
        return Ok(None);
    }
    let summary_rows = summary::summarize(&rows);
    let _outputs = store
        .lock_outputs()
        .map_err(|e| format!("cannot lock the tables of {}: {e}", store.study))?;
    let runs = store.table(&format!("{}.parquet", store.study));
    let summary = store.table(&format!("{}-summary.parquet", store.study));
    let mut frames = table::write_parquet(&[(&runs, &rows), (&summary, &summary_rows)])?;
    Ok(Some(Collected {
        runs,
        summary,
        rows: rows.len(),
        points: summary_rows.len(),
        missing,
        left_out,
        table: frames.pop().expect("two tables written"),
    }))
}

/// polars reads its display settings from the environment: a compact table of every row,
/// unless the user chose otherwise. Called first thing, before any thread could read the
/// environment.
pub fn set_display_defaults() {
    for (name, value) in [
        ("POLARS_FMT_MAX_ROWS", "-1"),
        ("POLARS_FMT_MAX_COLS", "-1"),
        ("POLARS_TABLE_WIDTH", "400"),
        ("POLARS_FMT_TABLE_FORMATTING", "ASCII_MARKDOWN"),
        ("POLARS_FMT_TABLE_HIDE_COLUMN_DATA_TYPES", "1"),
        ("POLARS_FMT_TABLE_HIDE_DATAFRAME_SHAPE_INFORMATION", "1"),
    ] {
        if std::env::var_os(name).is_none() {
            std::env::set_var(name, value);
        }
    }
}

/// The summary's headline columns: the swept fields (as `(column, shown name)`: from the case,
/// or derived by the solver), then the headline results the study has.
pub fn headline_columns(has: impl Fn(&str) -> bool, swept: &[String]) -> Vec<(String, String)> {
    const RESULTS: &[&str] = &[
        "status",
        "solve_s_median",
        "solve_s_iqr",
        "error_l2_norm",
        "order_l2",
        "speedup",
        "efficiency",
    ];
    let mut shown: Vec<(String, String)> = swept
        .iter()
        .filter_map(|field| {
            let column = [format!("case.{field}"), field.clone()]
                .into_iter()
                .find(|c| has(c))?;
            Some((column, field.clone()))
        })
        .collect();
    shown.extend(
        RESULTS
            .iter()
            .filter(|name| has(name))
            .map(|name| (name.to_string(), name.to_string())),
    );
    shown
}

/// The summary at a glance, for the terminal: the headline columns, every row.
pub fn overview(summary: &DataFrame, swept: &[String]) -> String {
    let shown = headline_columns(|name| summary.column(name).is_ok(), swept);
    let selected = summary.select(shown.iter().map(|(column, _)| column.as_str()));
    let renamed = selected.and_then(|mut frame| {
        for (column, name) in &shown {
            if column != name {
                frame.rename(column, name.as_str().into())?;
            }
        }
        Ok(frame)
    });
    match renamed {
        Ok(frame) => frame.to_string(),
        Err(e) => format!("(cannot show the summary: {e})"),
    }
}
