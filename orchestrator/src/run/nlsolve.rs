//! The `nlsolve` process, the orchestrator's only way to the numerics: its version, the check
//! that turns a point into a canonical case, and the command line of one run.

use crate::model::study::Point;
use crate::store::Fault;
use serde_json::{Map, Value};
use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;

pub struct Nlsolve {
    pub binary: PathBuf,
    /// `nlsolve --version`: part of every run's key, so a new solver version runs again.
    pub version: String,
    /// `nlsolve fingerprint`: what made the numbers (sources, compiler, flags); a stored record
    /// of another fingerprint is stale. `None` for a solver from before fingerprints.
    pub fingerprint: Option<String>,
}

/// A case the solver accepted, in its two forms. The canonical one is kept as its compact JSON
/// (a study of 10⁶ points holds 10⁶ of them; a parsed map is eight times larger); the resolved
/// one as what it adds, which most points share.
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// Keys sorted, some defaults left out: what a run's key is taken from (stable across
    /// versions that fill in more defaults). Printed by nlstudy from the parsed answer.
    canonical: Box<str>,
    /// Every field the method uses, defaults filled in: what tables and messages show.
    resolved: Resolved,
    /// Why this machine could not run it (memory, cores), when it could not: said by a plan
    /// that runs here, never a refusal (the case may run on a cluster).
    pub machine: Option<Box<str>>,
}

#[derive(Clone, Debug, PartialEq)]
enum Resolved {
    /// The canonical case and these fields (the defaults filled in), as a JSON object.
    Adds(Arc<str>),
    /// A resolved case that drops a canonical field, whole.
    Whole(Box<str>),
}

impl Checked {
    /// The canonical case as text: what keys hash and what `nlsolve run` reads.
    pub fn canonical_text(&self) -> &str {
        &self.canonical
    }

    /// What the resolved case adds to the canonical one (or the resolved case whole, where it
    /// drops a field), as text: with `canonical_text`, all a checked case says.
    pub fn resolution_text(&self) -> &str {
        match &self.resolved {
            Resolved::Adds(adds) => adds,
            Resolved::Whole(whole) => whole,
        }
    }

    pub fn canonical(&self) -> Value {
        serde_json::from_str(&self.canonical).expect("nlstudy printed it")
    }

    pub fn resolved(&self) -> Value {
        match &self.resolved {
            Resolved::Whole(text) => serde_json::from_str(text).expect("nlstudy printed it"),
            Resolved::Adds(adds) => {
                let mut resolved = self.canonical();
                let adds: Map<String, Value> =
                    serde_json::from_str(adds).expect("nlstudy printed it");
                resolved
                    .as_object_mut()
                    .expect("a case is an object")
                    .extend(adds);
                resolved
            }
        }
    }

    /// A whole-number field of the resolved case (`threads`, `ranks`).
    pub fn resolved_count(&self, field: &str) -> Option<u64> {
        self.resolved().get(field)?.as_u64()
    }
}

impl Nlsolve {
    /// The solver at `explicit`, else `$NLSOLVE`, else `nlsolve` beside this executable.
    /// A solver that cannot be started or asked its version is `Fault::Io`: a program that
    /// could not be started (exit 3).
    pub fn locate(explicit: Option<&Path>) -> Result<Nlsolve, Fault> {
        let binary = match explicit {
            Some(path) => path.to_path_buf(),
            None => match std::env::var_os("NLSOLVE") {
                Some(path) => PathBuf::from(path),
                None => std::env::current_exe()
                    .map_err(|e| Fault::Io(format!("cannot find this executable: {e}")))?
                    .with_file_name("nlsolve"),
            },
        };
        let output = Command::new(&binary).arg("--version").output().map_err(|e| {
            Fault::Io(format!(
                "cannot start the solver {}: {e}; build it (`cargo build --release`) or give --solver",
                binary.display()
            ))
        })?;
        let version = String::from_utf8_lossy(&output.stdout).trim().to_string();
        if !output.status.success() || version.is_empty() {
            return Err(Fault::Io(format!("{} --version failed", binary.display())));
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
    pub fn check<'a>(
        &self,
        points: impl ExactSizeIterator<Item = &'a Point> + Send,
    ) -> Result<Vec<Result<Checked, String>>, Fault> {
        let count = points.len();
        let mut child = Command::new(&self.binary)
            .arg("check")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| Fault::Io(format!("cannot start {}: {e}", self.binary.display())))?;
        let stdin = child.stdin.take().expect("stdin is piped");
        let stdout = child.stdout.take().expect("stdout is piped");
        let (verdicts, written) = std::thread::scope(|scope| {
            // Written from a thread, so that a full stdout pipe cannot stall both processes.
            let writer = scope.spawn(move || {
                let mut stdin = std::io::BufWriter::with_capacity(1 << 16, stdin);
                for point in points {
                    point.write_fields(&mut stdin)?;
                    stdin.write_all(b"\n")?;
                }
                stdin.flush()
            });
            let mut shared = HashMap::new();
            let verdicts: Vec<Result<Checked, String>> = std::io::BufReader::new(stdout)
                .lines()
                .map(|line| {
                    let line = line.map_err(|e| format!("cannot read nlsolve check: {e}"))?;
                    verdict(&line, &mut shared)
                })
                .collect();
            (
                verdicts,
                writer.join().expect("the writer thread does not panic"),
            )
        });
        let output = child
            .wait_with_output()
            .map_err(|e| Fault::Io(format!("nlsolve check failed: {e}")))?;
        if !output.status.success() {
            return Err(Fault::Io(format!(
                "nlsolve check failed: {}",
                String::from_utf8_lossy(&output.stderr).trim()
            )));
        }
        written.map_err(|e| Fault::Io(format!("cannot send cases to nlsolve check: {e}")))?;
        if verdicts.len() != count {
            return Err(Fault::Io(format!(
                "nlsolve check answered {} of {count} cases",
                verdicts.len(),
            )));
        }
        Ok(verdicts)
    }
}

/// One line of `nlsolve check`: the case in its two forms, or the refusal.
#[derive(serde::Deserialize)]
struct CheckLine {
    case: Option<Map<String, Value>>,
    resolved: Option<Map<String, Value>>,
    error: Option<String>,
    machine: Option<String>,
}

/// The verdict on one line; `shared` holds the distinct sets of filled-in defaults seen so far.
fn verdict(line: &str, shared: &mut HashMap<String, Arc<str>>) -> Result<Checked, String> {
    let verdict: CheckLine = serde_json::from_str(line)
        .map_err(|e| format!("nlsolve check printed an unreadable line: {e}"))?;
    match verdict {
        CheckLine {
            case: Some(canonical),
            resolved,
            machine,
            ..
        } => {
            // A solver from before `resolved` was printed: its case as it is.
            let resolved = resolved.unwrap_or_else(|| canonical.clone());
            let resolved = match canonical.keys().all(|k| resolved.contains_key(k)) {
                true => {
                    let adds: Map<String, Value> = resolved
                        .into_iter()
                        .filter(|(k, v)| canonical.get(k) != Some(v))
                        .collect();
                    let adds = Value::Object(adds).to_string();
                    let shared = shared
                        .entry(adds)
                        .or_insert_with_key(|adds| adds.as_str().into());
                    Resolved::Adds(shared.clone())
                }
                false => Resolved::Whole(Value::Object(resolved).to_string().into()),
            };
            Ok(Checked {
                canonical: Value::Object(canonical).to_string().into(),
                resolved,
                machine: machine.map(String::into_boxed_str),
            })
        }
        CheckLine {
            error: Some(error), ..
        } => Err(error),
        _ => Err("nlsolve check printed neither a case nor an error".to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_verdict_keeps_both_forms_of_the_case_and_shares_what_the_resolved_one_adds() {
        let mut shared = HashMap::new();
        let canonical = json!({"m": 2, "n": 16, "threads": 1});
        let lines = [
            // Defaults filled in, and a value the resolution changed.
            json!({"m": 2, "n": 16, "threads": 2, "integrator": "forward_euler"}),
            json!({"m": 2, "n": 16, "threads": 2, "integrator": "forward_euler"}),
            // A canonical field the resolved case drops.
            json!({"m": 2, "n": 16}),
        ];
        let checked: Vec<Checked> = lines
            .iter()
            .map(|resolved| {
                let line = json!({"case": canonical, "resolved": resolved}).to_string();
                verdict(&line, &mut shared).unwrap()
            })
            .collect();
        for (checked, resolved) in checked.iter().zip(&lines) {
            assert_eq!(checked.canonical(), canonical);
            assert_eq!(checked.canonical_text(), canonical.to_string());
            assert_eq!(&checked.resolved(), resolved);
        }
        assert_eq!(checked[0].resolved_count("threads"), Some(2));
        assert_eq!(shared.len(), 1, "the two alike share one text");
        let old_solver = json!({"case": canonical}).to_string();
        assert_eq!(
            verdict(&old_solver, &mut shared).unwrap().resolved(),
            canonical
        );
        let refused = json!({"error": "case field `m`: too big"}).to_string();
        assert_eq!(
            verdict(&refused, &mut shared),
            Err("case field `m`: too big".into())
        );
    }
}
