//! One kind of adaptive question behind one trait (`AdaptiveKind`), and the object-safe face
//! the registry holds (`Registered`), whose answers are `Found`.

use crate::model::adaptive::{Adaptive, Kind};
use crate::model::study::{Study, StudyError};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{self, Planned};
use crate::run::search::{searches, Answers, Searched};
use crate::store::{Fault, Store};
use serde::de::DeserializeOwned;
use serde_json::Value;
use std::marker::PhantomData;
use std::path::PathBuf;

/// What a question is asked with: the study, its solver and store, and how its probes are
/// planned.
#[derive(Clone, Copy)]
pub struct Asked<'a> {
    pub study: &'a Study,
    pub solver: &'a Nlsolve,
    pub store: &'a Store,
    pub options: &'a plan::Options,
}

impl Asked<'_> {
    /// `question` from every point of the sweep, run to its end (`search::searches`).
    pub fn searches<A: Adaptive>(
        &self,
        question: &A,
        run_round: &mut RunRound,
    ) -> Result<Answers<Vec<Searched<A::Outcome>>>, Fault> {
        let Asked {
            study,
            solver,
            store,
            options,
        } = *self;
        searches(
            study,
            question,
            solver,
            store,
            options,
            &mut &mut *run_round,
        )
    }
}

/// Runs the planned probes not stored (on the worker pool, or nowhere for a plan) and says
/// whether it finished them all (false: interrupted).
pub type RunRound<'r> = dyn FnMut(&[Planned]) -> Result<bool, Fault> + 'r;

/// The outcome of one point's question of kind `K`.
pub type Outcome<K> = <<K as AdaptiveKind>::Spec as Adaptive>::Outcome;

/// One kind of adaptive question, above its spec's search.
pub trait AdaptiveKind: Sync + 'static {
    /// The study file's section, and the search (`Adaptive::SECTION` names the section).
    type Spec: Adaptive + DeserializeOwned + std::fmt::Debug + Send + Sync + 'static;

    /// The section's own rules beyond its types, a refusal naming the field at fault.
    fn rules(spec: &Self::Spec) -> Result<(), StudyError>;

    /// The question checked against the record every probe will have (the columns it reads),
    /// before anything runs.
    fn check(spec: &Self::Spec, study: &Study) -> Result<(), StudyError>;

    /// Every point's question run to its end (None when interrupted), and every probe planned.
    fn search(
        spec: &Self::Spec,
        asked: Asked,
        run_round: &mut RunRound,
    ) -> Result<Answers<Vec<Searched<Outcome<Self>>>>, Fault> {
        asked.searches(spec, run_round)
    }

    /// Writes the table of the answers, `<study>-<Adaptive::TABLE>.parquet`; returns its path.
    fn write(
        spec: &Self::Spec,
        searched: &[Searched<Outcome<Self>>],
        study: &Study,
        store: &Store,
    ) -> Result<PathBuf, Fault>;

    /// A line for the terminal per point of the sweep.
    fn lines(spec: &Self::Spec, searched: &[Searched<Outcome<Self>>]) -> Vec<String>;
}

/// A kind as the registry holds it: `AdaptiveKind` made object-safe, on a question as the study
/// holds it.
pub trait Registered: Sync {
    fn section(&self) -> &'static str;

    /// The section read into its question: typed, then held to its rules.
    fn read(&self, section: Value) -> Result<Box<dyn Kind>, StudyError>;

    fn check(&self, question: &dyn Kind, study: &Study) -> Result<(), StudyError>;

    fn answer<'a>(
        &self,
        question: &'a dyn Kind,
        asked: Asked,
        run_round: &mut RunRound,
    ) -> Result<Answers<Box<dyn Found + 'a>>, Fault>;
}

/// What a question found from every point of the sweep.
pub trait Found {
    /// Writes the table of the answers; returns its path.
    fn write(&self, study: &Study, store: &Store) -> Result<PathBuf, Fault>;

    /// A line for the terminal per point.
    fn lines(&self) -> Vec<String>;
}

impl<K: AdaptiveKind> Registered for K {
    fn section(&self) -> &'static str {
        K::Spec::SECTION
    }

    fn read(&self, section: Value) -> Result<Box<dyn Kind>, StudyError> {
        let name = K::Spec::SECTION;
        let spec: K::Spec = serde_path_to_error::deserialize(section).map_err(|e| {
            let path = match e.path().to_string() {
                inner if inner == "." || inner.is_empty() => name.to_string(),
                inner => format!("{name}.{inner}"),
            };
            StudyError::from_serde(path, e.into_inner().to_string())
        })?;
        K::rules(&spec)?;
        Ok(Box::new(spec))
    }

    fn check(&self, question: &dyn Kind, study: &Study) -> Result<(), StudyError> {
        K::check(spec_of::<K>(question), study)
    }

    fn answer<'a>(
        &self,
        question: &'a dyn Kind,
        asked: Asked,
        run_round: &mut RunRound,
    ) -> Result<Answers<Box<dyn Found + 'a>>, Fault> {
        let spec = spec_of::<K>(question);
        let (searched, probes) = K::search(spec, asked, run_round)?;
        let found = searched.map(|searched| {
            Box::new(FoundBy::<K> {
                spec,
                searched,
                kind: PhantomData,
            }) as Box<dyn Found>
        });
        Ok((found, probes))
    }
}

/// The spec of a question of kind `K`: what `K` read it into.
fn spec_of<K: AdaptiveKind>(question: &dyn Kind) -> &K::Spec {
    (question.as_any().downcast_ref()).expect("a question is asked by the kind that read it")
}

/// What a question of kind `K` found.
struct FoundBy<'a, K: AdaptiveKind> {
    spec: &'a K::Spec,
    searched: Vec<Searched<Outcome<K>>>,
    kind: PhantomData<K>,
}

impl<K: AdaptiveKind> Found for FoundBy<'_, K> {
    fn write(&self, study: &Study, store: &Store) -> Result<PathBuf, Fault> {
        K::write(self.spec, &self.searched, study, store)
    }

    fn lines(&self) -> Vec<String> {
        K::lines(self.spec, &self.searched)
    }
}
