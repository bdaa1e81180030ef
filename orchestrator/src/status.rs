//! `nlstudy status`: the stored records of a study counted by status, the failures with the
//! first line of their messages, and the files of the store that are not whole records.

use crate::store::Store;
use schema::record::Status;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// The report, one line of counts and one line per failed run.
pub fn report(study: &str, store: &Store) -> String {
    let scan = store.scan();
    let records = scan.records;
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for record in &records {
        let status = record["status"].as_str().unwrap_or("unknown");
        *counts.entry(status).or_default() += 1;
    }
    let summary: Vec<String> = counts.iter().map(|(s, n)| format!("{n} {s}")).collect();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "study {study}: {} records in {}: {}",
        records.len(),
        store.runs.display(),
        if summary.is_empty() {
            "none".to_string()
        } else {
            summary.join(", ")
        }
    );
    for record in records
        .iter()
        .filter(|r| Status::of(r) == Some(Status::Failed))
    {
        let message = record["message"].as_str().unwrap_or("");
        let _ = writeln!(
            out,
            "failed {}: {}",
            record["key"].as_str().unwrap_or("?"),
            message.lines().next().unwrap_or("")
        );
    }
    for unreadable in &scan.unreadable {
        let _ = writeln!(out, "unreadable: {unreadable}");
    }
    out
}
