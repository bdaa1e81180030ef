//! `nlstudy status`: the stored records of a study counted by status, the failures with the
//! first line of their messages, the files of the store that are not whole records, the points
//! still missing, and, for a submitted study, each job's state and how many of its points are
//! stored.

use crate::run::cluster::ledger::{self, LedgerEntry};
use crate::run::cluster::scheduler::{self, Scheduler};
use crate::run::plan::Planned;
use crate::store::{Index, Store, CHECKPOINT, PROGRESS};
use schema::record::{Status, Stored};
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;

/// The records counted by status, as `3 ok`, `1 failed`, … (statuses in name order).
pub fn counts_by_status(records: &[Stored]) -> Vec<String> {
    counts(records.iter().map(|r| r.status().as_str()))
}

fn counts<'a>(statuses: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for status in statuses {
        *counts.entry(status).or_default() += 1;
    }
    counts.iter().map(|(s, n)| format!("{n} {s}")).collect()
}

/// How many runs were timed on a busy machine (their provenance says `noisy`), as a sentence;
/// `None` when none was.
pub fn noisy_runs(records: &[Stored]) -> Option<String> {
    let noisy = records.iter().filter(|r| r.noisy()).count();
    noisy_sentence(noisy, records.len())
}

fn noisy_sentence(noisy: usize, runs: usize) -> Option<String> {
    (noisy > 0).then(|| {
        format!(
            "{noisy} of {runs} runs are noisy: timed while other tasks wanted the cores the run left free; rerun them (`--force`) on a quiet machine before trusting their timings"
        )
    })
}

/// The report, from the store's index: one line of counts, one line per failed run, the
/// missing points, their checkpoints (read as the solver of `fingerprint` reads them), the
/// jobs.
pub fn render(
    study: &str,
    store: &Store,
    index: &Index,
    planned: &[Planned],
    fingerprint: Option<&str>,
) -> String {
    let summary = counts(index.stored.values().map(|s| s.status.as_str()));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "study {study}: {} records in {}: {}",
        index.stored.len(),
        store.runs.display(),
        if summary.is_empty() {
            "none".to_string()
        } else {
            summary.join(", ")
        }
    );
    for (key, message) in &index.failed {
        let _ = writeln!(out, "failed {key}: {}", schema::text::printable(message));
    }
    if let Some(noisy) = noisy_sentence(index.noisy, index.stored.len()) {
        let _ = writeln!(out, "{noisy}");
    }
    for unreadable in &index.unreadable {
        let _ = writeln!(out, "unreadable: {unreadable}");
    }
    let missing = planned.iter().filter(|p| p.runs()).count();
    let _ = writeln!(out, "{missing} of {} points to run", planned.len());
    running_report(&mut out, store, planned);
    checkpoints_report(&mut out, store, planned, fingerprint);
    jobs_report(&mut out, store, index);
    out
}

/// The simulated time a point's case runs to; `None` for a steady case.
fn t_end(point: &Planned) -> Option<f64> {
    point.case.as_ref().ok()?.case()?.t_end
}

/// One line per point running now (its key locked by a run) whose time loop says how far it is
/// (`runs/.work/<key>.progress`): its step of steps, simulated time and the time left.
fn running_report(out: &mut String, store: &Store, planned: &[Planned]) {
    for (point, progress) in with_scratch(store, planned, PROGRESS) {
        if !store.running(&point.key) {
            continue; // left by a run that was killed; the next run clears it
        }
        let Some(progress) = crate::store::progress_of(&progress) else {
            continue;
        };
        let (step, steps) = (progress.said.step, progress.said.steps);
        let time = t_end(point)
            .map(|t| format!(", t = {:.4} of {t}", t * step as f64 / steps.max(1) as f64))
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "running {}: {}{time}, {}",
            point.point.shown(),
            progress.steps_done(),
            progress.left()
        );
    }
}

/// The points to run that have the scratch file `name`, with its path: the work directory is
/// listed once (it holds a few files per running or stopped point).
fn with_scratch<'a>(
    store: &Store,
    planned: &'a [Planned],
    name: &str,
) -> Vec<(&'a Planned, std::path::PathBuf)> {
    let keys = store.scratch_keys(name);
    planned
        .iter()
        .filter(|p| p.runs() && keys.contains(p.key.as_str()))
        .map(|p| (p, store.scratch(&p.key, name)))
        .collect()
}

/// One line per point to run that has a checkpoint: how far its stopped run got, where the
/// next run resumes it, or why the next run starts it afresh.
fn checkpoints_report(
    out: &mut String,
    store: &Store,
    planned: &[Planned],
    fingerprint: Option<&str>,
) {
    for (point, path) in with_scratch(store, planned, CHECKPOINT) {
        let Ok(case) = &point.case else { continue };
        let ranks = case.ranks();
        let line = match crate::store::checkpoint_of(&path, &case.canonical(), ranks, fingerprint) {
            None => continue,
            Some(Ok((step, steps))) => {
                let how_far = match steps {
                    Some(steps) => format!("step {step} of {steps}"),
                    // A steady case (no t_end) checkpoints its CG iterations.
                    None if t_end(point).is_none() => format!("iteration {step}"),
                    None => format!("step {step}"),
                };
                format!("{how_far}; the next run resumes it")
            }
            Some(Err(why)) => format!("not resumed, {why}; the next run starts it afresh"),
        };
        let _ = writeln!(out, "checkpoint {}: {line}", point.point.shown());
    }
}

/// One line per job of the ledger: its id, name, state (an array's elements counted by state)
/// and stored points.
fn jobs_report(out: &mut String, store: &Store, index: &Index) {
    let entries = ledger::entries(store);
    let Some(scheduler) = entries.first().map(|e| e.scheduler) else {
        return;
    };
    let states = job_states(scheduler, &entries);
    if let Err(message) = &states {
        let _ = writeln!(out, "jobs: cannot ask the scheduler ({message})");
    }
    for entry in &entries {
        let state_of = |id: &str| match &states {
            Ok(states) => states.get(id).map_or("ended".to_string(), |s| described(s)),
            Err(_) => "unknown".to_string(),
        };
        let stored = entry
            .keys
            .iter()
            .filter(|k| {
                index
                    .stored
                    .get(*k)
                    .is_some_and(|s| s.status != Status::Failed)
            })
            .count();
        let (what, state) = match entry.elements.is_empty() {
            true => (String::new(), state_of(&entry.id)),
            false => {
                let states: Vec<String> =
                    entry.parts().iter().map(|(id, _)| state_of(id)).collect();
                (
                    format!(" (array of {})", entry.elements.len()),
                    counts(states.iter().map(String::as_str)).join(", "),
                )
            }
        };
        let _ = writeln!(
            out,
            "job {} {}{what}: {state}, {stored} of {} points stored",
            entry.id,
            entry.name,
            entry.keys.len()
        );
    }
}

/// The state of each job and element: the queue's for the jobs in it, and for the others Slurm's
/// accounting when the cluster keeps it (one `sacct` call; it knows how ended jobs ended). The
/// queue wins where both know a job: accounting lags behind the controller, and a job allocated
/// a moment ago (its first points already stored) was still `pending` there.
fn job_states(
    scheduler: Scheduler,
    entries: &[LedgerEntry],
) -> Result<HashMap<String, String>, String> {
    let live = scheduler::live_jobs(scheduler);
    if scheduler == Scheduler::Slurm {
        let ids: Vec<&str> = entries.iter().map(|e| e.id.as_str()).collect();
        if let Ok(mut states) = scheduler::accounted_states(&ids) {
            states.extend(live.unwrap_or_default());
            return Ok(states);
        }
    }
    live
}

/// `timeout (ended at its time limit: …)`; `running`, not `running (running)`.
fn described(state: &str) -> String {
    match scheduler::state_meaning(state) {
        same if same.eq_ignore_ascii_case(state) => same.to_string(),
        meaning => format!("{} ({meaning})", state.to_lowercase()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record;
    use serde_json::json;

    #[test]
    fn noisy_runs_are_counted_and_a_quiet_study_says_nothing() {
        let run = |noisy: bool| record(json!({"provenance": {"noisy": noisy}}));
        let failed = record(json!({"status": "failed"}));
        assert_eq!(noisy_runs(&[run(false), failed]), None);
        let said = noisy_runs(&[run(true), run(false), run(true)]).unwrap();
        assert!(said.starts_with("2 of 3 runs are noisy"), "{said}");
    }
}
