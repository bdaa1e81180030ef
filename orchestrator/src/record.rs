//! The fields of an `nlsolve` record that nlstudy interprets, typed in one place: its status and
//! its timings. Every other field passes through to the tables as it is.

use serde_json::Value;
use std::fmt;

/// What became of a run: `nlsolve` writes `ok` or `diverged`; nlstudy stores `failed` for a run
/// the solver refused, or that crashed or timed out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
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

    /// The status of a record; `None` when it has none that nlstudy knows.
    pub fn of(record: &Value) -> Option<Status> {
        record.get("status")?.as_str().and_then(Status::parse)
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The status of a summary row whose repeats ended differently.
pub const MIXED: &str = "mixed";

/// The record's timings in seconds (setup, time loop, median step, communication per step):
/// the fields whose repeats the summary reduces to min, median and max.
pub const TIMINGS: [&str; 4] = ["setup_s", "solve_s", "step_s", "comm_s"];
