//! A study with a `boundary`: each point of its sweep starts a search along the boundary's
//! field, and the searches run round by round, every probe an ordinary point (planned, keyed,
//! stored, skipped when stored). Each round replays every search from the first with the
//! answers known (`BoundarySpec::replay`), so a search interrupted at any moment resumes from
//! the store without running a probe twice, and ends where it would have.

use crate::model::boundary::{BoundarySpec, Search};
use crate::model::expression::{self, Scope};
use crate::model::study::{Point, Study};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{self, Planned};
use crate::store::{Fault, Store};
use schema::record::{columns, Stored};
use std::collections::HashMap;

/// A search from one point of the sweep, as far as it went.
pub struct Searched {
    pub origin: Point,
    pub search: Search,
    /// The boundary the solver's theory predicts, in the field's units, where it has one.
    pub predicted: Option<f64>,
}

/// Runs the searches of `study` to their ends: `run_round` runs the planned probes not stored
/// (on the worker pool) and says whether it finished them all (false: interrupted). Returns
/// the searches (None when interrupted) and every probe planned, for the study's tables.
pub fn searches(
    study: &Study,
    spec: &BoundarySpec,
    solver: &Nlsolve,
    store: &Store,
    options: &plan::Options,
    mut run_round: impl FnMut(&[Planned]) -> Result<bool, Fault>,
) -> Result<(Option<Vec<Searched>>, Vec<Planned>), Fault> {
    let origins = study.expand().map_err(|e| Fault::Input(e.to_string()))?;
    spec.origins_may_search(&origins)
        .map_err(|e| Fault::Input(e.to_string()))?;
    // Each search's answers by the probe's value (its bits), and its theory's prediction.
    let mut answers: Vec<HashMap<u64, Result<bool, String>>> = vec![HashMap::new(); origins.len()];
    let mut predicted: Vec<Option<f64>> = vec![None; origins.len()];
    let mut probes: Vec<Planned> = Vec::new();
    loop {
        let mut pending: Vec<(usize, f64)> = Vec::new();
        let mut searches = Vec::with_capacity(origins.len());
        for (s, known) in answers.iter().enumerate() {
            let (search, wanted) = spec.replay(|v| known.get(&v.to_bits()).cloned());
            pending.extend(wanted.into_iter().map(|v| (s, v)));
            searches.push(search);
        }
        if pending.is_empty() {
            let searched = origins
                .into_iter()
                .zip(searches)
                .zip(predicted)
                .map(|((origin, search), predicted)| Searched {
                    origin,
                    search,
                    predicted,
                })
                .collect();
            return Ok((Some(searched), probes));
        }
        let points = pending
            .iter()
            .map(|&(s, v)| spec.probe(&origins[s], v))
            .collect();
        let planned = plan::plan_points(points, solver, &store.index(), options)?;
        if planned.iter().any(Planned::runs) && !run_round(&planned)? {
            probes.extend(planned);
            return Ok((None, probes));
        }
        for (&(s, v), probe) in pending.iter().zip(&planned) {
            let stored = store.stored(probe.key.as_str());
            let answer = match (&probe.case, &stored) {
                (Err(refusal), _) => Err(format!("the solver refused it: {refusal}")),
                (Ok(_), None) => Err("no record was stored".into()),
                (Ok(_), Some(stored)) => flips(&spec.flips, stored),
            };
            if let Some(stored) = &stored {
                predicted[s] = predicted[s].or_else(|| prediction(&spec.field, stored));
            }
            answers[s].insert(v.to_bits(), answer);
        }
        probes.extend(planned);
    }
}

/// Whether `condition` holds over a probe's record, its fields named as the run table's
/// columns (`amplification`, `status`, `resolved.dt_stable`, `case.m`). A failed run cannot
/// answer.
pub fn flips(condition: &str, stored: &Stored) -> Result<bool, String> {
    if stored.record().is_none() {
        return Err(format!("the run failed: {}", stored.message()));
    }
    let value = stored.to_value();
    let mut fields = serde_json::Map::new();
    columns::flatten("", &value, &mut |name, value| {
        fields.insert(name, value.clone());
    });
    expression::condition(condition, &Scope::from_fields(&fields))
}

/// The boundary the solver's theory gives along `field`, from a probe's record: an explicit
/// integrator's dt_stable (from the operator's symbol for the nonlocal method, the classical
/// bound for finite differences) is the boundary of `dt`, and 1 that of `cfl`, which is dt
/// over it. Implicit integrators and other fields have none.
fn prediction(field: &str, stored: &Stored) -> Option<f64> {
    let record = stored.record()?;
    let method = record.case.get("method").and_then(|m| m.as_str());
    let explicit = match method {
        None | Some("nonlocal") => record.resolved.integrator.is_none_or(|i| !i.is_implicit()),
        Some("fd_explicit") => true,
        _ => false,
    };
    match field {
        _ if !explicit => None,
        "cfl" => Some(1.0),
        "dt" => Some(record.resolved.dt_stable),
        _ => None,
    }
}
