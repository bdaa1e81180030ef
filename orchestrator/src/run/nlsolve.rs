//! The `nlsolve` process, the orchestrator's only way to the numerics: its version, the check
//! that turns a point into a canonical case, and the command line of one run.

use crate::model::study::Point;
use serde_json::Value;
use std::io::Write;
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

/// A case the solver accepted, in its two forms.
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// Keys sorted, some defaults left out: what a run's key is taken from (stable across
    /// versions that fill in more defaults).
    pub canonical: Value,
    /// Every field the method uses, defaults filled in: what tables and messages show.
    pub resolved: Value,
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
    /// wrong; one `nlsolve check` for all points.
    pub fn check(&self, points: &[Point]) -> Result<Vec<Result<Checked, String>>, String> {
        let mut child = Command::new(&self.binary)
            .arg("check")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", self.binary.display()))?;
        let mut input = String::new();
        for point in points {
            input.push_str(&Value::Object(point.fields.clone()).to_string());
            input.push('\n');
        }
        let mut stdin = child.stdin.take().expect("stdin is piped");
        // Written from a thread, so that a full stdout pipe cannot stall both processes.
        let writer = std::thread::spawn(move || stdin.write_all(input.as_bytes()));
        let output = child
            .wait_with_output()
            .map_err(|e| format!("nlsolve check failed: {e}"))?;
        writer
            .join()
            .expect("the writer thread does not panic")
            .map_err(|e| format!("cannot send cases to nlsolve check: {e}"))?;
        if !output.status.success() {
            return Err(format!(
                "nlsolve check failed: {}",
                String::from_utf8_lossy(&output.stderr).trim()
            ));
        }
        let verdicts: Vec<Result<Checked, String>> = String::from_utf8_lossy(&output.stdout)
            .lines()
            .map(|line| {
                let mut verdict: Value = serde_json::from_str(line)
                    .map_err(|e| format!("nlsolve check printed an unreadable line: {e}"))?;
                if let Some(case) = verdict.get_mut("case") {
                    let canonical = case.take();
                    // A solver from before `resolved` was printed: its case as it is.
                    let resolved = match verdict.get_mut("resolved") {
                        Some(resolved) => resolved.take(),
                        None => canonical.clone(),
                    };
                    return Ok(Checked {
                        canonical,
                        resolved,
                    });
                }
                match verdict.get("error").and_then(Value::as_str) {
                    Some(error) => Err(error.to_string()),
                    None => Err("nlsolve check printed neither a case nor an error".to_string()),
                }
            })
            .collect();
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
