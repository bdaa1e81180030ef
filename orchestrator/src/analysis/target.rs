//! The error-target table, `<study>-target.parquet`: one row per candidate configuration (a
//! point of the sweep), with the swept fields that tell them apart, the coarsest resolution
//! found to meet the target, its error and measured cost, the candidates' rank by that cost
//! (1: the cheapest), the runs spent and how each search ended.

use crate::analysis::answer_table::{self, measured, origin_rows, text};
use crate::model::study::Study;
use crate::model::target::{Aimed, Level, TargetSpec};
use crate::run::search::Searched;
use crate::store::table::Row;
use crate::store::{Fault, Store};
use serde_json::Value;
use std::path::PathBuf;

/// Each candidate's answer and its rank by cost (1: the cheapest), in the order of the sweep;
/// a candidate that found none has no rank.
pub fn ranked(
    spec: &TargetSpec,
    searched: &[Searched<Aimed>],
) -> Vec<(Option<Level>, Option<usize>)> {
    let answers: Vec<Option<Level>> = searched.iter().map(|s| s.outcome.answer(spec)).collect();
    let mut order: Vec<usize> = (0..answers.len())
        .filter(|&k| answers[k].is_some())
        .collect();
    order.sort_by(|&a, &b| {
        let cost = |k: usize| answers[k].map_or(f64::INFINITY, |l| l.cost);
        cost(a).total_cmp(&cost(b))
    });
    let mut rank = vec![None; answers.len()];
    for (place, &k) in order.iter().enumerate() {
        rank[k] = Some(place + 1);
    }
    answers.into_iter().zip(rank).collect()
}

/// The table's rows, in the order of the sweep.
pub fn rows(spec: &TargetSpec, searched: &[Searched<Aimed>]) -> Vec<Row> {
    origin_rows(searched)
        .into_iter()
        .zip(searched.iter().zip(ranked(spec, searched)))
        .map(|(mut row, (s, (answer, rank)))| {
            row.set("field", Value::from(spec.field.as_str()));
            row.set("target", Value::from(spec.below));
            row.set("resolution", measured(answer.map(|l| l.value)));
            row.set("error", measured(answer.map(|l| l.error)));
            row.set("cost", measured(answer.map(|l| l.cost)));
            row.set("rank", rank.map_or(Value::Null, Value::from));
            row.set("probes", Value::from(s.outcome.levels.len()));
            let reached = s.outcome.reached.as_ref().map(ToString::to_string);
            row.set("reached", text(reached));
            row
        })
        .collect()
}

/// What the columns hold, in the file's metadata; the columns before them are the swept fields.
pub const NOTES: &[(&str, &str)] = &[
    ("field", "the resolution field searched"),
    ("target", "the error to reach (at most)"),
    (
        "resolution",
        "the coarsest value run that meets the target; null if none was found",
    ),
    ("error", "its error"),
    (
        "cost",
        "its measured cost (the study's `cost` column, solve_s by default)",
    ),
    ("rank", "the candidates' order by cost, 1 the cheapest"),
    ("probes", "runs the candidate's search spent"),
    ("reached", "how the search ended"),
];

/// Writes the table beside the study's others and returns its path.
pub fn write(
    study: &Study,
    store: &Store,
    spec: &TargetSpec,
    searched: &[Searched<Aimed>],
) -> Result<PathBuf, Fault> {
    answer_table::write(study, store, "target", &rows(spec, searched), NOTES)
}
