//! Which points of a study run, and why: make-style, against the record store.

use crate::model::adaptive::{Adaptive, Probe};
use crate::model::study::{Point, Study, StudyError};
use crate::run::nlsolve::{Checked, Nlsolve};
use crate::store::Fault;
use crate::store::{self, Id, Index};
use schema::record::Status;
use std::collections::{HashMap, HashSet};
use std::fmt;

/// What the command line asks beyond the study.
#[derive(Clone, Default)]
pub struct Options {
    /// Run every selected point, stored or not.
    pub force: bool,
    /// Run points whose stored record failed.
    pub rerun_failed: bool,
    /// Only these keys (how a cluster job runs its share of a study).
    pub only: Option<HashSet<String>>,
    /// The file of `only`'s probes its submit wrote beside the job (`cluster::probes`).
    pub probes: Option<std::path::PathBuf>,
    /// Reuse records another solver made (`--keep-stale`) instead of running them again.
    pub keep_stale: bool,
}

impl Options {
    /// These options for planning every probe of a study's searches: a job's `--only` and
    /// `--probes` select among those probes afterwards.
    pub fn of_every_probe(&self) -> Options {
        Options {
            only: None,
            probes: None,
            ..*self
        }
    }
}

/// Why a point runs.
#[derive(Clone, Debug, PartialEq)]
pub enum Reason {
    Missing,
    FailedBefore,
    Forced,
    /// (The versions and fingerprints are shared: at 10⁶ points a copy each was 10⁶ allocations.)
    SolverChanged {
        from: store::Shared,
    },
    /// Stored by a solver of another fingerprint.
    Stale {
        from: store::Shared,
        to: store::Shared,
    },
}

/// Why a point does not run. (Typed, not a sentence: at 10⁶ stored points a sentence each was
/// 10⁶ allocations; `plan` prints it.)
#[derive(Clone, Debug, PartialEq)]
pub enum Skipped {
    /// Stored with this status (`ok` or `diverged`: results, not failures), or failed and not
    /// asked to run again.
    Stored(Status),
    /// Stored by a solver of another fingerprint (`from`), kept by `--keep-stale`.
    StaleKept {
        status: Status,
        from: store::Shared,
        to: store::Shared,
    },
    /// Not among `--only` (another job's share).
    NotAmongOnly,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    Run(Reason),
    Skip(Skipped),
    /// The same case as an earlier point (of another branch): it runs once, for both.
    Duplicate,
}

/// A point, its case as the solver resolved it (or why the solver refused it), its key and
/// what happens to it.
#[derive(Clone)]
pub struct Planned {
    pub point: Point,
    pub case: Result<Checked, String>,
    pub key: Id,
    pub case_id: Id,
    pub decision: Decision,
    /// An adaptive question's probe: where its search starts and what it probes (what a
    /// cluster job is handed to plan its share without replaying the searches).
    pub probe: Option<ProbeOf>,
}

/// Where a probe comes from: the point of the sweep its question searches from (its index
/// among `search::origins`) and the values of the question's fields it probes.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeOf {
    pub origin: usize,
    pub at: Probe,
}

impl Planned {
    pub fn runs(&self) -> bool {
        matches!(self.decision, Decision::Run(_))
    }
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Reason::Missing => write!(f, "missing"),
            Reason::FailedBefore => write!(f, "failed before"),
            Reason::Forced => write!(f, "forced"),
            Reason::SolverChanged { from } => write!(f, "solver version changed (was {from})"),
            Reason::Stale { from, to } => {
                write!(f, "stale: solver changed ({} → {})", short(from), short(to))
            }
        }
    }
}

impl fmt::Display for Skipped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Skipped::Stored(status) => write!(f, "{status}"),
            Skipped::StaleKept { status, from, to } => {
                write!(
                    f,
                    "{status}, stale but kept: {} → {}",
                    short(from),
                    short(to)
                )
            }
            Skipped::NotAmongOnly => write!(f, "not among --only"),
        }
    }
}

/// A fingerprint as people read it: its first 8 digits, or `unknown`.
pub fn short(fingerprint: &str) -> &str {
    match fingerprint {
        "" => "unknown",
        f => schema::text::first_chars(f, 8),
    }
}

/// Plans every point of `study`'s sweep against what the store holds (`index`); a bad study is
/// `Fault::Input`, a solver that cannot be asked `Fault::Io`. (An adaptive study's probes are
/// planned round by round: `run::search`.)
pub fn plan(
    study: &Study,
    solver: &Nlsolve,
    index: &Index,
    options: &Options,
) -> Result<Vec<Planned>, Fault> {
    let points = study.expand().map_err(|e| Fault::Input(e.to_string()))?;
    plan_points(points, solver, index, options)
}

/// Keeps only the points among `only` (a cluster job's share): the others are skipped, and a
/// key that is no point of `planned` is refused.
pub fn restrict(planned: &mut [Planned], only: &HashSet<String>) -> Result<(), Fault> {
    unknown_keys(only, planned).map_err(|e| Fault::Input(e.to_string()))?;
    for p in planned
        .iter_mut()
        .filter(|p| !only.contains(p.key.as_str()))
    {
        p.decision = Decision::Skip(Skipped::NotAmongOnly);
    }
    Ok(())
}

/// The probe of `origin` at `probe`, the values of the question's `fields`: a point like any
/// other.
pub fn probe(fields: &[&str], origin: &Point, probe: &[f64]) -> Point {
    (fields.iter().zip(probe)).fold(origin.clone(), |point, (field, &v)| {
        point.with(field, crate::model::adaptive::value(field, v))
    })
}

/// Refuses a question along a field the sweep sets too: the question sets it.
pub fn origins_may_search<A: Adaptive>(question: &A, origins: &[Point]) -> Result<(), StudyError> {
    for field in question.fields() {
        if origins.iter().any(|origin| origin.sweeps(field)) {
            return Err(StudyError::new(
                format!("{}.field", A::SECTION),
                format!(
                    "`{field}` is swept (or derived) too; the {} sets it, so take it out of the sweep",
                    A::SECTION
                ),
            ));
        }
    }
    Ok(())
}

/// Plans `points` against what the store holds (`index`).
pub fn plan_points(
    points: Vec<Point>,
    solver: &Nlsolve,
    index: &Index,
    options: &Options,
) -> Result<Vec<Planned>, Fault> {
    // Each point becomes its plan at once, so the points' own list is gone before the
    // solver's answers arrive (at 10⁶ points both lists together are a third of a gigabyte).
    let mut planned: Vec<Planned> = points
        .into_iter()
        .map(|point| Planned {
            point,
            case: Err(String::new()),
            key: Id::default(),
            case_id: Id::default(),
            decision: Decision::Duplicate,
            probe: None,
        })
        .collect();
    let points: Vec<&Point> = planned.iter().map(|p| &p.point).collect();
    let cases = solver.check(&points).map_err(|e| e.within("solver"))?;
    // Keys seen so far, as their 128 bits.
    let mut seen = HashSet::with_capacity(planned.len());
    let fingerprint = solver.fingerprint.as_deref().map(store::shared);
    for (p, case) in planned.iter_mut().zip(cases) {
        // A refused case is keyed by its fields as written.
        let written;
        let identity = match &case {
            Ok(checked) => checked.canonical_text(),
            Err(_) => {
                let mut text = Vec::new();
                p.point.write_fields(&mut text).expect("a map prints");
                written = String::from_utf8(text).expect("JSON is UTF-8");
                written.as_str()
            }
        };
        let (case_id, key) = store::case_id_and_key(identity, &solver.version, p.point.repeat);
        let stored = index.stored.get(key.as_str());
        let first = seen.insert(key.bits());
        p.decision = match stored.map(|s| &s.status) {
            // Another point (of another branch) is the same case: it runs once.
            _ if !first => Decision::Duplicate,
            _ if options.force => Decision::Run(Reason::Forced),
            None => match index.version_by_case.get(case_id.as_str()) {
                Some(from) if **from != *solver.version => {
                    Decision::Run(Reason::SolverChanged { from: from.clone() })
                }
                _ => Decision::Run(Reason::Missing),
            },
            Some(Status::Failed) if options.rerun_failed => Decision::Run(Reason::FailedBefore),
            Some(status) => match (&fingerprint, stored.map(|s| &s.fingerprint)) {
                (Some(now), Some(then)) if now != then && *status != Status::Failed => {
                    let (from, to) = (then.clone(), now.clone());
                    match options.keep_stale {
                        true => Decision::Skip(Skipped::StaleKept {
                            status: *status,
                            from,
                            to,
                        }),
                        false => Decision::Run(Reason::Stale { from, to }),
                    }
                }
                _ => Decision::Skip(Skipped::Stored(*status)),
            },
        };
        (p.case, p.key, p.case_id) = (case, key, case_id);
    }
    if let Some(only) = &options.only {
        restrict(&mut planned, only)?;
    }
    Ok(planned)
}

/// Points the solver refused that share one sentence: a typo in `base` refuses every point
/// with the same words, and is said once.
#[derive(Debug, PartialEq)]
pub struct Refusal {
    pub message: String,
    /// Points (repeats counted once) refused with it.
    pub points: usize,
    /// The first of them, by its label.
    pub first: String,
}

/// The solver's refusals, one per distinct sentence, in the order they first appear.
pub fn refusals(planned: &[Planned]) -> Vec<Refusal> {
    let mut refusals: Vec<Refusal> = Vec::new();
    let mut at: HashMap<&str, usize> = HashMap::new();
    for p in planned.iter().filter(|p| p.point.repeat == 0) {
        let Err(message) = &p.case else { continue };
        match at.get(message.as_str()) {
            Some(&k) => refusals[k].points += 1,
            None => {
                at.insert(message, refusals.len());
                refusals.push(Refusal {
                    message: message.clone(),
                    points: 1,
                    first: p.point.label_without_repeat(),
                });
            }
        }
    }
    refusals
}

/// The most distinct refusals said; a sweep past the solver's limits can refuse thousands of
/// points each in its own words (`m = 9 with n = 16 …`), and the plan listing marks each.
const MOST_REFUSALS_SAID: usize = 10;

/// The refusals as lines for people: `60 points (first: n=8 m=2): case field …`, the first
/// `MOST_REFUSALS_SAID` of them, then how many more.
pub fn describe_refusals(refusals: &[Refusal]) -> String {
    let count = |points: usize| match points {
        1 => "1 point".to_string(),
        n => format!("{n} points"),
    };
    let mut lines: Vec<String> = refusals
        .iter()
        .take(MOST_REFUSALS_SAID)
        .map(|r| {
            let first = match r.first.as_str() {
                "" => String::new(),
                label => format!(" (first: {label})"),
            };
            format!("  {}{first}: {}", count(r.points), r.message)
        })
        .collect();
    let rest = &refusals[refusals.len().min(MOST_REFUSALS_SAID)..];
    if !rest.is_empty() {
        let points = rest.iter().map(|r| r.points).sum();
        lines.push(format!(
            "  and {} more refusals of {}: `nlstudy plan` marks every refused point",
            rest.len(),
            count(points)
        ));
    }
    lines.join("\n")
}

/// Refuses `--only` keys that are no point of the study: a job script written before the study
/// was edited would otherwise run nothing and report success.
fn unknown_keys(only: &HashSet<String>, planned: &[Planned]) -> Result<(), StudyError> {
    let known: HashSet<&str> = planned.iter().map(|p| p.key.as_str()).collect();
    let mut unknown: Vec<&str> = only
        .iter()
        .map(String::as_str)
        .filter(|k| !known.contains(k))
        .collect();
    if unknown.is_empty() {
        return Ok(());
    }
    unknown.sort_unstable();
    // Quoted: a key comes from the command line and goes to a terminal.
    let unknown: Vec<String> = unknown.iter().map(|k| format!("{k:?}")).collect();
    Err(StudyError::new(
        "--only",
        format!(
            "{} of the {} keys are no point of the study (was it edited after the job was written? `nlstudy submit` again): {}",
            unknown.len(),
            only.len(),
            unknown.join(", ")
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_said_once_each_and_past_ten_counted() {
        let refusal = |k: usize| Refusal {
            message: format!("case field `m`: m = {k} is too big"),
            points: k,
            first: format!("m={k}"),
        };
        let few: Vec<Refusal> = (1..=2).map(refusal).collect();
        assert_eq!(
            describe_refusals(&few),
            "  1 point (first: m=1): case field `m`: m = 1 is too big\n  2 points (first: m=2): case field `m`: m = 2 is too big"
        );
        let many: Vec<Refusal> = (1..=13).map(refusal).collect();
        let text = describe_refusals(&many);
        assert_eq!(text.lines().count(), 11);
        assert!(text.contains("(first: m=10)") && !text.contains("m=11"));
        assert!(text.ends_with(
            "and 3 more refusals of 36 points: `nlstudy plan` marks every refused point"
        ));
    }
}
