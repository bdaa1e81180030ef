//! The kinds of adaptive question, each behind one trait (`AdaptiveKind`) and registered once
//! (`SHIPPED`): a boundary search (`boundary`), a refinement that stops once its order is
//! established (`refine`), the cheapest configuration for an error target (`target`).
//!
//! A kind is its spec (the study file's section, deserialized, with its search in
//! `model::adaptive::Adaptive`: the probes of each round from the records of the rounds before)
//! and what this trait adds above it: the section's rules, its check against the records its
//! probes will have, its search from every point of the sweep, the table of its answers and
//! their lines. A new kind is a module here and a line in `SHIPPED`; the study file then takes
//! its section, and `plan`, `run`, `submit` and the report ask it like the others
//! (`tests::a_fourth_kind_is_one_module_and_its_registration` sketches one).
//!
//! This layer sits above `output` because a kind writes its table (`analysis`) and says its
//! lines (`output`); the study keeps its question as the object-safe `model::adaptive::Kind`,
//! which `Registry::of` maps back to the code of its kind.

pub mod boundary;
pub mod kind;
pub mod refine;
pub mod target;

pub use kind::{Asked, Found};
use kind::{Registered, RunRound};

use crate::model::adaptive::Kind;
use crate::model::study::{Sections, Study, StudyError};
use crate::run::cluster::probes;
use crate::run::plan::{self, Planned};
use crate::run::search::{self, Answers};
use crate::store::Fault;
use serde_json::Value;
use std::path::Path;

/// The kinds a study file may ask, by their sections.
pub const SHIPPED: Registry = Registry(&[&boundary::Boundary, &refine::Refine, &target::Target]);

/// Kinds by their sections.
pub struct Registry(pub &'static [&'static dyn Registered]);

impl Registry {
    /// The kind that read `question`.
    pub fn of(&self, question: &dyn Kind) -> &'static dyn Registered {
        let kind = self.0.iter().find(|k| k.section() == question.section());
        *kind.expect("a question is read by a registered kind")
    }
}

impl Sections for Registry {
    fn read(&self, name: &str, value: Value) -> Option<Result<Box<dyn Kind>, StudyError>> {
        let kind = self.0.iter().find(|k| k.section() == name)?;
        Some(kind.read(value))
    }

    fn names(&self) -> Vec<&'static str> {
        self.0.iter().map(|k| k.section()).collect()
    }
}

/// Reads a study file, its adaptive sections by the shipped kinds (`Study::read`).
pub fn read(path: &Path) -> Result<Study, StudyError> {
    Study::read(path, &SHIPPED)
}

/// A study from JSON with comments (`Study::parse`).
#[cfg(test)]
pub fn parse(text: &str) -> Result<Study, StudyError> {
    Study::parse(text, &SHIPPED)
}

/// A study from TOML (`Study::parse_toml`).
#[cfg(test)]
pub fn parse_toml(text: &str) -> Result<Study, StudyError> {
    Study::parse_toml(text, &SHIPPED)
}

/// The study's question checked against the records its probes will have.
pub fn check(study: &Study) -> Result<(), StudyError> {
    match study.question() {
        Some(question) => SHIPPED.of(question).check(question, study),
        None => Ok(()),
    }
}

/// Runs the study's adaptive question to its end: what it found from every point of the sweep
/// (None when interrupted) and every probe planned; None for a study of a fixed sweep.
pub fn answer<'a>(
    asked: Asked<'a>,
    run_round: &mut RunRound,
) -> Result<Option<Answers<Box<dyn Found + 'a>>>, Fault> {
    let Some(question) = asked.study.question() else {
        return Ok(None);
    };
    SHIPPED
        .of(question)
        .answer(question, asked, run_round)
        .map(Some)
}

/// The probes of an adaptive study so far: those stored (skipped) and the next round's (to
/// run), as `plan` shows them, `submit` sends them to the scheduler and a job's `run --only`
/// runs its share of them: a job handed its probes (`--probes`) plans those alone. None for a
/// study of a fixed sweep.
pub fn probes_so_far(asked: Asked) -> Result<Option<Vec<Planned>>, Fault> {
    if let Some(given) = probes_given(asked)? {
        return Ok(Some(given));
    }
    let Some((_, mut probes)) = answer(asked, &mut |_| Ok(false))? else {
        return Ok(None);
    };
    if let Some(only) = &asked.options.only {
        plan::restrict(&mut probes, only)?;
    }
    Ok(Some(probes))
}

/// A job's `--only` probes planned from the file its submit wrote (`--probes`), without
/// replaying the study's searches; None, said, where the file does not give them as they are
/// now, and the searches are replayed.
fn probes_given(asked: Asked) -> Result<Option<Vec<Planned>>, Fault> {
    let options = asked.options;
    let (Some(file), Some(only), Some(question)) =
        (&options.probes, &options.only, asked.study.question())
    else {
        return Ok(None);
    };
    let replayed = |why: &str| {
        log::info!(
            "--probes {file:?} does not give this job's probes as the study is now ({why}): its searches are replayed to find them"
        )
    };
    let given = match probes::read(file, only) {
        Ok(given) => given,
        Err(why) => {
            replayed(&why);
            return Ok(None);
        }
    };
    let (study, solver) = (asked.study, asked.solver);
    let index = asked.store.index();
    let planned = search::plan_given(study, question, solver, &index, options, given)?;
    if planned.is_none() {
        replayed("a probe plans to another key");
    }
    Ok(planned)
}

#[cfg(test)]
mod tests;
