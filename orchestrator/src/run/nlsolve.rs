//! The `nlsolve` process, the orchestrator's only way to the numerics: its version, the check
//! that turns a point into a canonical case, and the command line of one run.

use crate::model::study::Point;
use serde_json::Value;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

pub struct Nlsolve {
    pub binary: PathBuf,
    /// `nlsolve --version`: part of every run's key, so a new solver version runs again.
    pub version: String,
    /// `nlsolve fingerprint`: what made the numbers (sources, compiler, flags); a stored record
    /// of another fingerprint is stale. `None` for a solver from before fingerprints.
    pub fingerprint: Option<String>,
}

/// A case the solver accepted, in its two forms, each kept as its compact JSON (a study of 10⁵
/// points holds 10⁵ of them; a parsed map is eight times larger).
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// Keys sorted, some defaults left out: what a run's key is taken from (stable across
    /// versions that fill in more defaults). Printed by nlstudy from the parsed answer.
    canonical: Box<str>,
    /// Every field the method uses, defaults filled in: what tables and messages show.
    resolved: Box<str>,
}

impl Checked {
    /// The canonical case as text: what keys hash and what `nlsolve run` reads.
    pub fn canonical_text(&self) -> &str {
        &self.canonical
    }

    pub fn canonical(&self) -> Value {
        serde_json::from_str(&self.canonical).expect("nlstudy printed it")
    }

    pub fn resolved(&self) -> Value {
        serde_json::from_str(&self.resolved).expect("nlstudy printed it")
    }

    /// A whole-number field of the resolved case (`threads`, `ranks`).
    pub fn resolved_count(&self, field: &str) -> Option<u64> {
        self.resolved().get(field)?.as_u64()
    }
}

impl Nlsolve {
    /// The solver at `explicit`, else `$NLSOLVE`, else `nlsolve` beside this executable.
    pub fn locate(explicit: Option<&Path>) -> Result<Nlsolve, String> {
        let binary = match explicit {
            Some(path) => path.to_path_buf(),
            None => match std::env::var_os("NLSOLVE") {
                Some(path) => PathBuf::from(path),
                None => std::env::current_exe()
                    .map_err(|e| format!("cannot find this executable: {e}"))?
                    .with_file_name("nlsolve"),
            },
        };
        let output = Command::new(&binary).arg("--version").output().map_err(|e| {
            format!(
                "cannot start the solver {}: {e}; build it (`cargo build --release`) or give --solver",
                binary.display()
            )
        })?;
        let version = String::from_utf8_lossy(&output.stdout).trim().to_string();
        if !output.status.success() || version.is_empty() {
            return Err(format!("{} --version failed", binary.display()));
        }
        let fingerprint = Command::new(&binary)
            .arg("fingerprint")
            .output()
            .ok()
            .filter(|out| out.status.success())
            .map(|out| String::from_utf8_lossy(&out.stdout).trim().to_string())
            .filter(|f| !f.is_empty() && f.chars().all(|c| c.is_ascii_hexdigit()));
        Ok(Nlsolve {
            binary,
            version,
            fingerprint,
        })
    }

    /// Each point's case as the solver reads it, or the solver's sentence saying which field is
    /// wrong; one `nlsolve check` for all points, its answers read as they come.
    pub fn check(&self, points: &[Point]) -> Result<Vec<Result<Checked, String>>, String> {
        let mut child = Command::new(&self.binary)
            .arg("check")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", self.binary.display()))?;
        let stdin = child.stdin.take().expect("stdin is piped");
        let stdout = child.stdout.take().expect("stdout is piped");
        let (verdicts, written) = std::thread::scope(|scope| {
            // Written from a thread, so that a full stdout pipe cannot stall both processes.
            let writer = scope.spawn(move || {
                let mut stdin = std::io::BufWriter::with_capacity(1 << 16, stdin);
                for point in points {
                    serde_json::to_writer(&mut stdin, &point.fields)?;
                    stdin.write_all(b"\n")?;
                }
                stdin.flush()
            });
            let verdicts: Vec<Result<Checked, String>> = std::io::BufReader::new(stdout)
                .lines()
                .map(|line| verdict(&line.map_err(|e| format!("cannot read nlsolve check: {e}"))?))
                .collect();
            (
                verdicts,
                writer.join().expect("the writer thread does not panic"),
            )
        });
        let output = child
            .wait_with_output()
            .map_err(|e| format!("nlsolve check failed: {e}"))?;
        if !output.status.success() {
            return Err(format!(
                "nlsolve check failed: {}",
                String::from_utf8_lossy(&output.stderr).trim()
            ));
        }
        written.map_err(|e| format!("cannot send cases to nlsolve check: {e}"))?;
        if verdicts.len() != points.len() {
            return Err(format!(
                "nlsolve check answered {} of {} cases",
                verdicts.len(),
                points.len()
            ));
        }
        Ok(verdicts)
    }
}

/// One line of `nlsolve check`: the case in its two forms, or the refusal.
#[derive(serde::Deserialize)]
struct Verdict {
    case: Option<Value>,
    resolved: Option<Value>,
    error: Option<String>,
}

fn verdict(line: &str) -> Result<Checked, String> {
    let verdict: Verdict = serde_json::from_str(line)
        .map_err(|e| format!("nlsolve check printed an unreadable line: {e}"))?;
    match verdict {
        Verdict {
            case: Some(canonical),
            resolved,
            ..
        } => {
            let canonical = canonical.to_string();
            Ok(Checked {
                // A solver from before `resolved` was printed: its case as it is.
                resolved: resolved
                    .map_or_else(|| canonical.clone(), |r| r.to_string())
                    .into(),
                canonical: canonical.into(),
            })
        }
        Verdict {
            error: Some(error), ..
        } => Err(error),
        _ => Err("nlsolve check printed neither a case nor an error".to_string()),
    }
}
