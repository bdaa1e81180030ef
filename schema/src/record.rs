//! The parts of a run's record that both sides interpret: what became of the run and which fields
//! are timings. Every other field of a record is written by the solver and passes through the
//! orchestrator's tables as it is.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::fmt;

/// nlsolve's exit status when it computed a result but could not write it (standard output
/// closed or full, a broken pipe, a `--write-*` path): sysexits' EX_IOERR. The orchestrator
/// reads it as the file system's fault, not the case's, and stores nothing for the run.
pub const NLSOLVE_EXIT_IO: u8 = 74;

/// What became of a run: `nlsolve` writes `ok` or `diverged`; nlstudy stores `failed` for a run
/// the solver refused, or that crashed or timed out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Ok,
    Diverged,
    Failed,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Diverged => "diverged",
            Status::Failed => "failed",
        }
    }

    pub fn parse(text: &str) -> Option<Status> {
        [Status::Ok, Status::Diverged, Status::Failed]
            .into_iter()
            .find(|s| s.as_str() == text)
    }

    /// The status of a record; `None` when it has none that both sides know.
    pub fn of(record: &Value) -> Option<Status> {
        record.get("status")?.as_str().and_then(Status::parse)
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The record's timings in seconds (setup, time loop, median step, communication per step):
/// the fields whose repeats the orchestrator's summary reduces to min, median and max.
pub const TIMINGS: [&str; 4] = ["setup_s", "solve_s", "step_s", "comm_s"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_status_reads_back_as_its_serde_name() {
        for status in [Status::Ok, Status::Diverged, Status::Failed] {
            let json = serde_json::to_value(status).unwrap();
            assert_eq!(json, Value::from(status.as_str()));
            assert_eq!(Status::parse(status.as_str()), Some(status));
            assert_eq!(
                Status::of(&serde_json::json!({ "status": json })),
                Some(status)
            );
        }
        assert_eq!(Status::parse("mixed"), None);
    }
}
