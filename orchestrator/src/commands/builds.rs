//! How the commands that look across runs of a study (`compare`, `history`) find their
//! records: the current store, its history (the superseded records), or a build named by its
//! fingerprint.

use super::failure::Failure;
use crate::model::study::Study;
use crate::run::plan::Planned;
use crate::store::{fingerprint_of, Store};
use schema::record::Stored;
use std::collections::HashMap;

/// Records by key, as one side of a comparison holds them.
pub(super) type Side = HashMap<String, Stored>;

/// The study's superseded records; the history's files that are not whole records are named
/// and left out.
pub(super) fn superseded(store: &Store) -> Vec<Stored> {
    let history = store.history();
    for unreadable in &history.unreadable {
        log::warn!(
            "{} is not a whole superseded record ({}); it is left out",
            unreadable.path.display(),
            unreadable.problem
        );
    }
    history.records
}

/// Each key's most recent superseded record: what the current runs replaced, whether a new
/// build or `run --force` replaced it.
pub(super) fn latest_superseded(history: Vec<Stored>) -> Option<Side> {
    let mut latest: Side = HashMap::new();
    for record in history {
        // A record whose time does not read is never the latest.
        let time =
            |r: &Stored| crate::store::timestamp::record_time(r).unwrap_or(f64::NEG_INFINITY);
        let newer = latest
            .get(&record.key)
            .is_none_or(|kept| time(&record) >= time(kept));
        if newer {
            latest.insert(record.key.clone(), record);
        }
    }
    (!latest.is_empty()).then_some(latest)
}

/// Each point's label and the keys of its repeats, in the study's order.
pub(super) fn repeats_by_point(planned: &[Planned]) -> Vec<(String, Vec<String>)> {
    let mut points: Vec<(String, Vec<String>)> = Vec::new();
    for p in planned {
        let label = p.point.label_without_repeat();
        match points.iter_mut().find(|(l, _)| *l == label) {
            Some((_, keys)) => keys.push(p.key.to_string()),
            None => points.push((label, vec![p.key.to_string()])),
        }
    }
    points
}

/// The stored or superseded records of the one build whose fingerprint starts with `prefix`,
/// by key; `flag` names where the prefix came from, for the message.
pub(super) fn of_build(
    prefix: &str,
    flag: &str,
    study: &Study,
    store: &Store,
) -> Result<Side, Failure> {
    if prefix.is_empty() || !prefix.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(Failure::BadInput(format!(
            "{flag} fingerprint:{prefix:?}: a fingerprint is hex digits (`nlsolve fingerprint`, `nlstudy history`)"
        )));
    }
    let mut records = superseded(store);
    records.extend(store.records());
    records.retain(|r| fingerprint_of(r).starts_with(prefix));
    let mut builds: Vec<&str> = records.iter().map(fingerprint_of).collect();
    builds.sort_unstable();
    builds.dedup();
    match builds.len() {
        0 => Err(Failure::BadInput(format!(
            "{flag} fingerprint:{prefix}: no stored or superseded record of study {} was made by a solver whose fingerprint starts with {prefix}; `nlstudy history` shows the builds",
            study.name
        ))),
        1 => Ok(latest_superseded(records).unwrap_or_default()),
        n => Err(Failure::BadInput(format!(
            "{flag} fingerprint:{prefix}: {n} builds start so ({}); give more of the fingerprint",
            builds.iter().map(|b| schema::text::first_chars(b, 12)).collect::<Vec<_>>().join(", ")
        ))),
    }
}
