//! The record a case ended with, as the store keeps it: the line a worker answered or the
//! last JSON object a process printed, else a failed record with why.

use super::options::machine_cores;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::Planned;
use schema::exit;
use schema::record::{Failure, Outcome, Record, Stored};
use serde_json::Value;

/// The record in what nlsolve printed: its last line that is a JSON object.
pub(super) fn last_object(printed: &str) -> Option<Value> {
    (printed.lines().rev()).find_map(|line| {
        serde_json::from_str::<Value>(line)
            .ok()
            .filter(Value::is_object)
    })
}

/// The stored record of a worker's answer: the record, or its error as the failed record of
/// the same case run as a process says it (`nlsolve run` exits 2 with the error on stderr).
pub(super) fn answer_record(
    planned: &Planned,
    solver: &Nlsolve,
    cores: usize,
    line: &str,
) -> Stored {
    use std::os::unix::process::ExitStatusExt;
    let answer = serde_json::from_str::<Value>(line)
        .ok()
        .filter(Value::is_object);
    let Some(mut answer) = answer else {
        let message =
            format!("nlsolve serve answered with a line that is no JSON object: {line:.200}");
        return failed_record(planned, solver, message);
    };
    match answer.get_mut("error").map(Value::take) {
        Some(Value::String(error)) => {
            let as_a_process = std::process::ExitStatus::from_raw(i32::from(exit::BAD_INPUT) << 8);
            failed_record(
                planned,
                solver,
                format!("nlsolve exited with {as_a_process}: nlsolve: {error}"),
            )
        }
        _ => printed_record(planned, solver, cores, answer),
    }
}

/// The stored record of the JSON object nlsolve printed for `planned`; it must keep to the
/// schema.
pub(super) fn printed_record(
    planned: &Planned,
    solver: &Nlsolve,
    cores: usize,
    object: Value,
) -> Stored {
    match serde_path_to_error::deserialize::<_, Record<Value>>(object) {
        Ok(mut record) => {
            // Its timings measure contention, not scaling; figures and tables say so. Over
            // ranks, the solver judges it from each rank's affinity; here, from the cores.
            let oversubscribed = cores > machine_cores();
            record
                .distribution
                .oversubscribed
                .get_or_insert(oversubscribed);
            stored(planned, solver, Outcome::Ran(Box::new(record)))
        }
        Err(e) => failed_record(
            planned,
            solver,
            format!(
                "nlsolve printed a record that does not keep to the schema (field `{}`: {}); is the solver of another version?",
                e.path(),
                e.inner()
            ),
        ),
    }
}

/// The record of `outcome` with the fields the orchestrator adds: its key, case id, repeat and
/// version, and the `nlstudy` process that ran it (`run_id`: the runs of one invocation share
/// the machine's state, which is what `compare`'s noise model tells apart from each point's own
/// noise).
pub(super) fn stored(planned: &Planned, solver: &Nlsolve, outcome: Outcome) -> Stored {
    Stored {
        key: planned.key.to_string(),
        case_id: Some(planned.case_id.to_string()),
        repeat: planned.point.repeat,
        solver_version: solver.version.clone(),
        run_id: Some(run_id().to_string()),
        attempt: None,
        outcome,
    }
}

/// This `nlstudy` process: its host, its start in nanoseconds since the epoch and its process
/// id (the jobs of a cluster start processes of the same id on many hosts, in namespaces).
pub(crate) fn run_id() -> &'static str {
    static ID: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ID.get_or_init(|| {
        let start = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        format!("{}-{start}-{}", host.trim(), std::process::id())
    })
}

/// The record of a point that ran to no record of its own (crashed, timed out, lost with its job).
pub(crate) fn failed_record(planned: &Planned, solver: &Nlsolve, message: String) -> Stored {
    let case = match &planned.case {
        Ok(case) => case.canonical(),
        Err(_) => Value::Object(planned.point.fields()),
    };
    stored(planned, solver, Outcome::Failed(Failure { case, message }))
}
