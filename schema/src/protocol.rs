//! The messages between the binaries besides the case and the record: typed once here, written
//! by one side and read by the other, so that a renamed field fails to compile instead of
//! breaking at run time.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// A line `nlsolve serve` reads: a case, or a case with what the worker does beside it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServeLine {
    /// The case's fields.
    pub case: Value,
    /// Where its time loop says how far it is (as `nlsolve run --progress`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub progress: Option<String>,
    /// Where it checkpoints its time loop, on a stopping signal and at `checkpoint_every_s`, and
    /// resumes from (as `nlsolve run --checkpoint`); removed once the record is written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint_every_s: Option<f64>,
    /// Keep the checkpoint after the record is written.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub keep_checkpoint: bool,
    /// The study's directory of spectra, shared by its workers (as `nlsolve run --spectra`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectra: Option<String>,
}

/// How far a running case is: the file `nlsolve run --progress` (and a served case's
/// `progress`) keeps up to date, at most once a second, and `nlstudy status` and the pool's bar
/// read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Steps done (a steady solve's: CG iterations).
    pub step: u64,
    /// The steps in all; a steady solve's iterations in all are an estimate.
    pub steps: u64,
    /// Wall seconds since the loop began.
    pub elapsed_s: f64,
    /// Wall seconds left, at the pace so far.
    pub left_s: f64,
    pub unit: ProgressUnit,
}

/// What a case's progress counts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProgressUnit {
    /// Time steps.
    Step,
    /// A steady solve's CG iterations.
    Iteration,
}

/// What a worker or `nlsolve check` answers to a line it cannot take: one sentence naming the
/// field at fault.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Refusal {
    pub error: String,
}

/// What `nlsolve machine` prints: what this machine offers a run, which a plan weighs each
/// case's needs against.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// Cores the process may use.
    pub cores: u64,
    /// The most threads a case may ask here.
    pub most_threads: u64,
    /// Memory available to a run, where the system says.
    pub available_bytes: Option<u64>,
}

/// `nlsolve check`'s answer to one line: the case checked, or why it is refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Verdict {
    Checked(Checked),
    Refused(Refusal),
}

/// What a checked case asks of a machine: its threads, and the memory it needs available.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Needs {
    pub threads: u64,
    pub bytes: u64,
}

/// A case whose fields and time step `nlsolve check` accepted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Checked {
    /// The canonical case (keys sorted, some defaults left out): what a run's key is taken from.
    pub case: Map<String, Value>,
    /// The same case with every default filled in, as people read it.
    pub resolved: Map<String, Value>,
    /// What the case asks of a machine.
    pub needs: Needs,
    /// Why this machine could not run it, when it could not: reported, not refused (the case
    /// may run elsewhere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine: Option<String>,
}

/// The environment variable that gives `nlsolve serve --connect` the token it opens its
/// connection with: the pool it dials accepts only the workers it started (a token in the
/// environment, which only its own user reads, rather than on the command line, which anyone
/// on the node sees).
pub const SERVE_TOKEN_ENV: &str = "NLSOLVE_SERVE_TOKEN";

/// The longest token a pool accepts as a connection's first line, its newline included.
pub const SERVE_TOKEN_MOST_BYTES: usize = 128;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_serve_line_reads_back_as_written() {
        let line = ServeLine {
            case: serde_json::json!({"dim": 1, "n": 16}),
            progress: Some("/w/k.progress".into()),
            checkpoint: Some("/w/k.checkpoint".into()),
            checkpoint_every_s: Some(0.5),
            keep_checkpoint: true,
            spectra: Some("/r/study/spectra".into()),
        };
        let text = serde_json::to_string(&line).unwrap();
        assert_eq!(serde_json::from_str::<ServeLine>(&text).unwrap(), line);
        let bare: ServeLine = serde_json::from_str(r#"{"case": {"n": 8}}"#).unwrap();
        assert_eq!(
            (bare.progress, bare.checkpoint, bare.keep_checkpoint),
            (None, None, false)
        );
        let unknown = serde_json::from_str::<ServeLine>(r#"{"case": {}, "progres": "x"}"#);
        assert!(unknown.unwrap_err().to_string().contains("progres"));
    }

    #[test]
    fn a_verdict_reads_back_as_the_variant_written() {
        let object = |value: Value| value.as_object().unwrap().clone();
        let checked = Verdict::Checked(Checked {
            case: object(serde_json::json!({"dim": 1, "n": 16})),
            resolved: object(serde_json::json!({"dim": 1, "n": 16, "threads": 1})),
            needs: Needs {
                threads: 1,
                bytes: 4096,
            },
            machine: Some("needs 2 threads, this machine has 1".into()),
        });
        let refused = Verdict::Refused(Refusal {
            error: "n: must be at least 2".into(),
        });
        for verdict in [checked, refused] {
            let text = serde_json::to_string(&verdict).unwrap();
            assert_eq!(serde_json::from_str::<Verdict>(&text).unwrap(), verdict);
        }
        // Neither a case nor an error is no verdict.
        assert!(serde_json::from_str::<Verdict>(r#"{"cases": {}}"#).is_err());
    }

    #[test]
    fn a_machine_line_reads_back_and_refuses_a_misspelt_field() {
        let machine = Machine {
            cores: 2,
            most_threads: 2,
            available_bytes: None,
        };
        let text = serde_json::to_string(&machine).unwrap();
        assert_eq!(serde_json::from_str::<Machine>(&text).unwrap(), machine);
        let misspelt = r#"{"cores": 2, "most_thread": 2, "available_bytes": null}"#;
        assert!(serde_json::from_str::<Machine>(misspelt).is_err());
    }
}
