//! The parts of a run's record that both sides interpret: what became of the run and which fields
//! are timings. Every other field of a record is written by the solver and passes through the
//! orchestrator's tables as it is.

use serde::{Deserialize, Serialize};
use serde_json::Value;
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

    /// The status of a record; `None` when it has none that both sides know.
    pub fn of_record(record: &Value) -> Option<Status> {
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

/// The columns a record gives the tables, flattened (`field.values`): the solver's fields, then
/// the ones nlstudy adds. A name ending in `.*` stands for a group whose members vary (a
/// method's outcome, the provenance). Figures and tables are checked against these before
/// anything runs; a test of nlsolve checks that every record it writes keeps to them.
pub const COLUMNS: &[&str] = &[
    // What became of the run, and its case.
    "status",
    "message",
    "case.*",
    // The discretization as resolved (`Resolved`).
    "h",
    "eps",
    "m",
    "c",
    "dt",
    "dt_stable",
    "steps",
    "nodes",
    "bonds",
    "pair_visits",
    "quadrature",
    "collar",
    "patch_error",
    "backend",
    "integrator",
    // Results and timings.
    "steps_done",
    "setup_s",
    "solve_s",
    "step_s",
    "error_l2",
    "error_l2_norm",
    "error_max",
    "error_total",
    "mass",
    "mass_drift",
    "max_abs",
    "growth",
    "diverged_step",
    "diverged_time",
    "c_tot.*",
    "histogram.*",
    "field.*",
    "patch.*",
    "coupling.*",
    // The distribution over ranks.
    "ranks",
    "partition",
    "px",
    "py",
    "halo_nodes",
    "halo_bytes",
    "imbalance",
    "comm_s",
    "hosts",
    "traffic.*",
    // Steady and implicit solves.
    "iterations",
    "relative_residual",
    "dual_residual",
    "subdomains",
    "floating_subdomains",
    "multipliers",
    "factor_nonzeros_max",
    "feti_phases.*",
    "solve_iterations_mean",
    "solve_iterations_max",
    "solves_unconverged",
    "solve_rtol",
    "peak_memory_bytes",
    "memory_estimate_bytes",
    "provenance.*",
    // Added by nlstudy.
    "key",
    "case_id",
    "repeat",
    "solver_version",
    "attempt",
    "oversubscribed",
    "run_id",
    "threads",
];

/// Whether `name` is a column of records (see `COLUMNS`).
pub fn is_column(name: &str) -> bool {
    COLUMNS.iter().any(|c| match c.strip_suffix('*') {
        Some(group) => name.starts_with(group) && name.len() > group.len(),
        None => *c == name,
    })
}

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
                Status::of_record(&serde_json::json!({ "status": json })),
                Some(status)
            );
        }
        assert_eq!(Status::parse("mixed"), None);
    }

    #[test]
    fn a_column_is_a_name_or_a_member_of_a_group() {
        assert!(is_column("error_l2_norm") && is_column("c_tot.time"));
        assert!(is_column("feti_phases.coarse_s") && is_column("case.n"));
        assert!(!is_column("c_tot.") && !is_column("error_l2norm") && !is_column("c_tot"));
    }
}
