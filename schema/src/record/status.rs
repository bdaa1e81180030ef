//! What became of a run, and when a run that did not diverge still counts as growing.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Decades of `growth` (log₁₀ of a run's largest max |u| over the problem's scale) that mark a
/// run `ok` by its divergence bound as growing: a stable diffusion never grows past its scale.
/// The solver says so in the record's message and the stability figure crosses such runs.
pub const GROWING: f64 = 1.0;

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
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_status_reads_back_as_its_serde_name() {
        for status in [Status::Ok, Status::Diverged, Status::Failed] {
            let json = serde_json::to_value(status).unwrap();
            assert_eq!(json, serde_json::Value::from(status.as_str()));
            assert_eq!(Status::parse(status.as_str()), Some(status));
        }
        assert_eq!(Status::parse("mixed"), None);
    }
}
