//! A refinement from each point of the sweep that stops once its order is established
//! (`model::refine`).

use super::kind::{AdaptiveKind, Outcome};
use crate::analysis::figure_columns::measured;
use crate::model::refine::RefineSpec;
use crate::model::study::{Study, StudyError};
use crate::run::search::Searched;
use crate::store::{Fault, Store};
use std::path::PathBuf;

pub struct Refine;

impl AdaptiveKind for Refine {
    type Spec = RefineSpec;

    fn rules(spec: &RefineSpec) -> Result<(), StudyError> {
        spec.check()
            .map_err(|(field, why)| StudyError::new(field, why))
    }

    /// The error it reads is a number of the record.
    fn check(spec: &RefineSpec, _: &Study) -> Result<(), StudyError> {
        measured("refine.error", &spec.error)
    }

    fn write(
        spec: &RefineSpec,
        searched: &[Searched<Outcome<Self>>],
        study: &Study,
        store: &Store,
    ) -> Result<PathBuf, Fault> {
        crate::analysis::convergence::write(study, store, &spec.field, searched)
    }

    fn lines(spec: &RefineSpec, searched: &[Searched<Outcome<Self>>]) -> Vec<String> {
        crate::output::answers::refinement_lines(&spec.field, searched)
    }
}
