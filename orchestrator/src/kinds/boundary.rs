//! A boundary search from each point of the sweep: where `flips` starts to hold along one
//! numeric field (`model::boundary`), against the theory's boundary where it has one.

use super::kind::{AdaptiveKind, Outcome};
use crate::analysis::figure_columns::guess;
use crate::model::boundary::BoundarySpec;
use crate::model::expression;
use crate::model::study::{Study, StudyError};
use crate::run::search::Searched;
use crate::store::{Fault, Store};
use schema::case::Case;
use schema::record::columns;
use std::path::PathBuf;

pub struct Boundary;

impl AdaptiveKind for Boundary {
    type Spec = BoundarySpec;

    fn rules(spec: &BoundarySpec) -> Result<(), StudyError> {
        spec.check()
            .map_err(|(field, why)| StudyError::new(field, why))?;
        expression::check_syntax(&spec.flips).map_err(|why| StudyError::new("boundary.flips", why))
    }

    /// `flips` reads only case fields and record columns, and is a condition (true or false).
    fn check(spec: &BoundarySpec, study: &Study) -> Result<(), StudyError> {
        let place = "boundary.flips";
        let names = expression::names(&spec.flips).map_err(|e| StudyError::new(place, e))?;
        for name in &names {
            let field = name.split('.').next().unwrap_or(name);
            if !(Case::field_names().contains(&field) || columns::is_column(name)) {
                let guess = guess(name).map_or(String::new(), |g| format!("; did you mean `{g}`?"));
                return Err(StudyError::new(
                    place,
                    format!("no field `{name}` in a probe's record{guess}"),
                ));
            }
        }
        // With a value for every name it reads (a probe's record of every field, the study's
        // first point's case), it must be true or false.
        let mut probe = columns::every_field();
        if let (Some(record), Ok(points)) = (probe.record_mut(), study.expand()) {
            if let Some(point) = points.first() {
                record.case = serde_json::Value::Object(point.fields());
            }
        }
        let mut cells = Vec::new();
        columns::flatten("", probe.to_value(), &mut |name, value| {
            cells.push((name.to_string(), value))
        });
        let fields = expression::fields_of_columns(&cells);
        if names.iter().all(|n| fields.contains_key(n)) {
            let scope = expression::Scope::from_fields(&fields);
            expression::condition(&spec.flips, &scope).map_err(|e| {
                StudyError::new(
                    place,
                    format!("{e}; write a condition such as `amplification > 1`"),
                )
            })?;
        }
        Ok(())
    }

    fn write(
        spec: &BoundarySpec,
        searched: &[Searched<Outcome<Self>>],
        study: &Study,
        store: &Store,
    ) -> Result<PathBuf, Fault> {
        crate::analysis::boundaries::write(study, store, spec, searched)
    }

    fn lines(spec: &BoundarySpec, searched: &[Searched<Outcome<Self>>]) -> Vec<String> {
        crate::output::answers::boundary_lines(spec, searched)
    }
}
