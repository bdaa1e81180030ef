//! The `nlsolve` process, the orchestrator's only way to the numerics: its version, the check
//! that turns a point into a canonical case, and the command line of one run.

mod kept;

use crate::model::study::Point;
use crate::store::{Fault, Shared};
use rayon::prelude::*;
use schema::case::Case;
use schema::protocol::{self, Machine, Needs};
use serde_json::{Map, Value};
use std::collections::HashMap;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;

#[derive(Clone)]
pub struct Nlsolve {
    pub binary: PathBuf,
    /// `nlsolve --version`: part of every run's key, so a new solver version runs again.
    pub version: String,
    /// `nlsolve fingerprint`: what made the numbers (sources, compiler, flags); a stored record
    /// of another fingerprint is stale. `None` for a solver from before fingerprints.
    pub fingerprint: Option<String>,
    /// Where the solver's verdicts on the study's cases are kept (`keep_verdicts_in`).
    verdicts: Option<PathBuf>,
    /// Whether the solver takes a directory of shared spectra (`nlsolve run --spectra`, the
    /// serve line's `spectra`): a solver from before them would refuse the flag.
    pub shares_spectra: bool,
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
    /// that runs here, never a refusal (the case may run on a cluster). Shared: points on the
    /// same threads repeat it.
    pub machine: Option<Shared>,
}

/// How the solver resolves a case: what it adds to the canonical one.
#[derive(Clone, Debug, PartialEq)]
pub enum Resolved {
    /// The canonical case and these fields (the defaults filled in), as a JSON object.
    Adds(Arc<str>),
    /// A resolved case that drops a canonical field, whole.
    Whole(Box<str>),
}

impl Resolved {
    /// What the resolved case adds to the canonical one (or the resolved case whole), as text.
    pub fn text(&self) -> &str {
        match self {
            Resolved::Adds(adds) => adds,
            Resolved::Whole(whole) => whole,
        }
    }

    /// The resolved case from the canonical one, parsed already (a stored record whose key is
    /// the case's carries it: the key is the hash of its text): what `Checked::resolved`
    /// gives, without parsing the canonical text again at every row of a table.
    pub fn resolve(&self, canonical: Value) -> Value {
        match self {
            Resolved::Whole(text) => serde_json::from_str(text).expect("nlstudy printed it"),
            Resolved::Adds(adds) => {
                let mut resolved = canonical;
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
}

impl Checked {
    /// A case as if the solver had checked it: `canonical` as it is, resolved to itself.
    #[cfg(test)]
    pub fn unresolved(canonical: &Value) -> Checked {
        Checked {
            canonical: canonical.to_string().into(),
            resolved: Resolved::Adds("{}".into()),
            machine: None,
        }
    }

    /// The canonical case as text: what keys hash and what `nlsolve run` reads.
    pub fn canonical_text(&self) -> &str {
        &self.canonical
    }

    /// What the resolved case adds to the canonical one (or the resolved case whole, where it
    /// drops a field), as text: with `canonical_text`, all a checked case says.
    pub fn resolution_text(&self) -> &str {
        self.resolved.text()
    }

    /// How the solver resolves the case.
    pub fn resolution(&self) -> &Resolved {
        &self.resolved
    }

    pub fn canonical(&self) -> Value {
        serde_json::from_str(&self.canonical).expect("nlstudy printed it")
    }

    #[cfg(test)]
    pub fn resolved(&self) -> Value {
        self.resolved.resolve(self.canonical())
    }

    /// The case typed, as the schema both binaries share reads it: what the orchestrator reads of
    /// a checked case, so that a renamed field fails to compile. `None` for a case of fields
    /// this build does not know (a solver given with `--solver` of another version).
    pub fn case(&self) -> Option<Case> {
        serde_json::from_str(&self.canonical).ok()
    }

    /// Threads on each rank and ranks, read at once (1 each where `case` cannot read it).
    pub fn threads_and_ranks(&self) -> (usize, usize) {
        self.case()
            .map_or((1, 1), |case| (case.threads.max(1), case.ranks.max(1)))
    }

    /// Threads on each rank (1 where `case` cannot read it).
    pub fn threads(&self) -> usize {
        self.threads_and_ranks().0
    }

    /// Ranks (1 where `case` cannot read it).
    pub fn ranks(&self) -> usize {
        self.threads_and_ranks().1
    }
}

impl Nlsolve {
    /// The solver at `explicit`, else `$NLSOLVE`, else `nlsolve` beside this executable.
    /// A solver that cannot be started or asked its version is `Fault::Io`: a program that
    /// could not be started (exit 3).
    pub fn locate(explicit: Option<&Path>) -> Result<Nlsolve, Fault> {
        let binary = match explicit {
            // Absolute: workers run in the store's work directory, not here.
            Some(path) => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
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
        // Asked as `help run`: a solver's `run` is what a wrapper may hold up or fake.
        let shares_spectra = Command::new(&binary)
            .args(["help", "run"])
            .output()
            .is_ok_and(|out| String::from_utf8_lossy(&out.stdout).contains("--spectra"));
        Ok(Nlsolve {
            binary,
            version,
            fingerprint,
            verdicts: None,
            shares_spectra,
        })
    }

    /// A name for this build that is safe as one folder's name: the first 8 digits of its
    /// fingerprint (hex, checked when read), or, for a solver that prints none, of the SHA-256 of
    /// its binary's bytes, never of text it prints (a `--version` of `../..` or `/tmp/x` named a
    /// folder outside the study's once).
    pub fn build_name(&self) -> Result<String, Fault> {
        use sha2::{Digest, Sha256};
        if let Some(fingerprint) = &self.fingerprint {
            return Ok(schema::text::first_chars(fingerprint, 8).to_string());
        }
        // Read whole and digested, as a table's sum is: one binary, once per comparison.
        let binary = std::fs::read(&self.binary).map_err(|e| {
            Fault::Io(format!(
                "cannot read the solver {}: {e}",
                self.binary.display()
            ))
        })?;
        let digest = crate::store::hex(&Sha256::digest(&binary));
        Ok(format!("binary-{}", &digest[..8]))
    }

    /// Keeps the solver's verdicts on cases in `path` (beside a study's store), so that a
    /// later `check` of the same cases by this solver build need not ask it (`kept`).
    pub fn keep_verdicts_in(&mut self, path: PathBuf) {
        self.verdicts = Some(path);
    }

    /// What this machine offers a run, as the solver finds it (`nlsolve machine`); `None` from
    /// a solver that cannot say.
    fn offer(&self) -> Option<Machine> {
        let output = Command::new(&self.binary).arg("machine").output().ok()?;
        match output.status.success() {
            true => serde_json::from_slice(&output.stdout).ok(),
            false => None,
        }
    }

    /// Each point's case as the solver reads it, or the solver's sentence saying which field is
    /// wrong: the verdicts kept for this solver where they stand, the others asked of
    /// `nlsolve check` (and kept).
    pub fn check(&self, points: &[&Point]) -> Result<Vec<Result<Checked, String>>, Fault> {
        let (Some(path), Some(fingerprint)) = (&self.verdicts, &self.fingerprint) else {
            return Ok(self.ask(points)?.into_iter().map(|(v, _)| v).collect());
        };
        // The file read on one core while the points' keys are hashed on the other.
        let (mut kept, keys) = rayon::join(
            || kept::Kept::load(path.clone(), &self.version, fingerprint),
            || {
                let key = |point: &&Point| {
                    let mut line = Vec::with_capacity(256);
                    point.write_fields(&mut line).expect("a map prints");
                    kept::fields_key(&line)
                };
                points.par_iter().map(key).collect::<Vec<_>>()
            },
        );
        let offer = self.offer();
        // Points of the same fields (repeats, branches that meet) share the first one's verdict.
        let mut first: kept::KeyMap<usize> =
            kept::KeyMap::with_capacity_and_hasher(keys.len(), Default::default());
        let mut verdicts: Vec<Option<Result<Checked, String>>> = Vec::with_capacity(keys.len());
        for (i, key) in keys.iter().enumerate() {
            let verdict = match first.entry(*key) {
                std::collections::hash_map::Entry::Occupied(at) => verdicts[*at.get()].clone(),
                std::collections::hash_map::Entry::Vacant(at) => {
                    at.insert(i);
                    kept.take(key, offer.as_ref())
                }
            };
            verdicts.push(verdict);
        }
        let asked: Vec<usize> = (0..points.len())
            .filter(|&i| verdicts[i].is_none())
            .collect();
        let answers = self.ask(&asked.iter().map(|&i| points[i]).collect::<Vec<_>>())?;
        for (i, (verdict, needs)) in asked.into_iter().zip(answers) {
            kept.keep(&keys[i], &verdict, needs, offer.as_ref());
            verdicts[i] = Some(verdict);
        }
        kept.save();
        Ok(verdicts
            .into_iter()
            .map(|v| v.expect("each point answered"))
            .collect())
    }

    /// Each point's verdict and what it needs of a machine, asked of one `nlsolve check` for
    /// all points, its answers read as they come.
    fn ask(&self, points: &[&Point]) -> Result<Vec<Answer>, Fault> {
        let count = points.len();
        if count == 0 {
            return Ok(Vec::new());
        }
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
            let verdicts: Vec<Answer> = std::io::BufReader::new(stdout)
                .lines()
                .map(|line| match line {
                    Ok(line) => verdict(&line, &mut shared),
                    Err(e) => (Err(format!("cannot read nlsolve check: {e}")), None),
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

/// A verdict, and what its case needs of a machine.
type Answer = (Result<Checked, String>, Option<Needs>);

/// The verdict on one line; `shared` holds the distinct sets of filled-in defaults seen so far.
fn verdict(line: &str, shared: &mut HashMap<String, Arc<str>>) -> Answer {
    // A checked case first, read straight into its type: `Verdict` is untagged, and serde
    // buffers an untagged value whole to try each form (a third of `plan`'s time at 10⁵ cases).
    let verdict = match serde_json::from_str::<protocol::Checked>(line) {
        Ok(checked) => Ok(protocol::Verdict::Checked(checked)),
        Err(_) => serde_json::from_str::<protocol::Verdict>(line),
    };
    let verdict = match verdict {
        Ok(verdict) => verdict,
        Err(e) => {
            return (
                Err(format!(
                    "nlsolve check printed a line that is neither a checked case nor a refusal: {e}"
                )),
                None,
            )
        }
    };
    let protocol::Checked {
        case: canonical,
        resolved,
        needs,
        machine,
    } = match verdict {
        protocol::Verdict::Checked(checked) => checked,
        protocol::Verdict::Refused(refusal) => return (Err(refusal.error), None),
    };
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
    let checked = Checked {
        canonical: Value::Object(canonical).to_string().into(),
        resolved,
        machine: machine.as_deref().map(crate::store::shared),
    };
    (Ok(checked), Some(needs))
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
                let needs = json!({"threads": 1, "bytes": 4096});
                let line = json!({"case": canonical, "resolved": resolved, "needs": needs});
                let line = line.to_string();
                verdict(&line, &mut shared).0.unwrap()
            })
            .collect();
        for (checked, resolved) in checked.iter().zip(&lines) {
            assert_eq!(checked.canonical(), canonical);
            assert_eq!(checked.canonical_text(), canonical.to_string());
            assert_eq!(&checked.resolved(), resolved);
        }
        assert_eq!((checked[0].threads(), checked[0].ranks()), (1, 1));
        assert_eq!(shared.len(), 1, "the two alike share one text");
        // A line of neither form (here: a solver from before `resolved` and `needs`) is said so.
        let old_solver = json!({"case": canonical}).to_string();
        let said = verdict(&old_solver, &mut shared).0.unwrap_err();
        assert!(
            said.contains("neither a checked case nor a refusal"),
            "{said}"
        );
        let refused = json!({"error": "case field `m`: too big"}).to_string();
        assert_eq!(
            verdict(&refused, &mut shared).0,
            Err("case field `m`: too big".into())
        );
    }
}
