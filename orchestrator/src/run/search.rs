//! An adaptive study (`model::adaptive`): from each point of its sweep a question (a boundary
//! search, a refinement, an error target) runs round by round on the worker pool, every probe an
//! ordinary point (planned, keyed, stored, skipped when stored). Each round replays every
//! question from its first with the records known, so a study interrupted at any moment resumes
//! from the store without running a probe twice, and ends where it would have.
//!
//! Each kind runs its questions through `searches` (`kinds::AdaptiveKind::search`).

use crate::model::adaptive::{Adaptive, Kind, ProbeRecord, Spent};
use crate::model::study::{Point, Study};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{self, Planned, ProbeOf};
use crate::store::{Fault, Index, Store};
use schema::record::Stored;
use std::collections::HashMap;

/// What a question found from one point of the sweep.
pub struct Searched<O> {
    pub origin: Point,
    pub outcome: O,
    /// The record of a probe that ran, for what the solver's theory says of the point.
    pub record: Option<Stored>,
}

/// What a study's questions found (None when interrupted), and every probe planned.
pub type Answers<F> = (Option<F>, Vec<Planned>);

/// Runs `question` from every point of `study`'s sweep to its end: `run_round` runs the
/// planned probes not stored (on the worker pool) and says whether it finished them all (false:
/// interrupted). Returns what each found (None when interrupted) and every probe planned, for
/// the study's tables.
pub fn searches<A: Adaptive>(
    study: &Study,
    question: &A,
    solver: &Nlsolve,
    store: &Store,
    options: &plan::Options,
    run_round: &mut impl FnMut(&[Planned]) -> Result<bool, Fault>,
) -> Result<Answers<Vec<Searched<A::Outcome>>>, Fault> {
    let origins = origins(study, A::ONE_SEARCH_PER_POINT)?;
    plan::origins_may_search(question, &origins).map_err(|e| Fault::Input(e.to_string()))?;
    // Every probe is planned: a job's `--only` applies to the round it ran (`probes_so_far`).
    let options = options.of_every_probe();
    // Each point's probes by their values (their bits).
    let mut probed: Vec<HashMap<Vec<u64>, ProbeRecord>> = vec![HashMap::new(); origins.len()];
    let bits = |probe: &[f64]| -> Vec<u64> { probe.iter().map(|v| v.to_bits()).collect() };
    let mut probes: Vec<Planned> = Vec::new();
    // Read again only after a round ran: the replay of the stored rounds plans against one
    // (a read each was about a tenth of the driver's CPU over the map).
    let mut index = store.index();
    loop {
        let mut pending: Vec<(usize, Vec<f64>)> = Vec::new();
        let mut outcomes = Vec::with_capacity(origins.len());
        for (s, known) in probed.iter().enumerate() {
            let (outcome, wanted) = question.replay(&mut |v| known.get(&bits(v)).cloned());
            pending.extend(wanted.into_iter().map(|v| (s, v)));
            outcomes.push(outcome);
        }
        // The study's budget, counted from the probes' records in hand: a round is cut to the
        // runs left, and none starts once it is spent.
        if let Some(budget) = &study.budget {
            let records = probed.iter().flat_map(|known| known.values());
            let spent = Spent::spent_by(records.filter_map(|r| Some(&**r.as_ref().ok()?)));
            if budget.is_spent(&spent) {
                // Questions that ended keep their end.
                for outcome in &mut outcomes {
                    question.out_of_budget(outcome);
                }
                pending.clear();
            } else if let Some(left) = budget.runs_left(&spent) {
                pending.truncate(left);
            }
        }
        if pending.is_empty() {
            let searched = origins
                .into_iter()
                .zip(outcomes)
                .zip(&probed)
                .map(|((origin, outcome), known)| Searched {
                    origin,
                    outcome,
                    record: known
                        .values()
                        .find_map(|r| Some(Stored::clone(r.as_ref().ok()?))),
                })
                .collect();
            return Ok((Some(searched), probes));
        }
        let fields = question.fields();
        let points = pending
            .iter()
            .map(|(s, v)| plan::probe(&fields, &origins[*s], v))
            .collect();
        let mut planned = plan::plan_points(points, solver, &index, &options)?;
        for (p, (s, v)) in planned.iter_mut().zip(&pending) {
            p.probe = Some(ProbeOf {
                origin: *s,
                at: v.clone(),
            });
        }
        // A probe refused in a way the question reads (a step above the stable one) is an
        // answer from `check`: it is neither run nor a refusal of the study's.
        let absorbed = |p: &Planned| matches!(&p.case, Err(why) if question.absorbs(why));
        let to_run: Vec<Planned> = planned.iter().filter(|p| !absorbed(p)).cloned().collect();
        if to_run.iter().any(Planned::runs) {
            if !run_round(&to_run)? {
                probes.extend(to_run);
                return Ok((None, probes));
            }
            index = store.index();
        }
        let ran = planned.iter().filter(|p| p.case.is_ok());
        let mut records = store.stored_shared(ran.map(|p| p.key.as_str())).into_iter();
        for ((s, v), probe) in pending.iter().zip(&planned) {
            let record = match &probe.case {
                Err(refusal) => Err(format!("the solver refused it: {refusal}")),
                Ok(_) => {
                    (records.next().flatten()).ok_or_else(|| "no record was stored".to_string())
                }
            };
            probed[*s].insert(bits(v), record);
        }
        probes.extend(to_run);
    }
}

/// The points of `study`'s sweep its question searches from: every point, or each point's
/// first repeat where its repeats are one question (`Adaptive::ONE_SEARCH_PER_POINT`).
pub fn origins(study: &Study, one_search_per_point: bool) -> Result<Vec<Point>, Fault> {
    let mut origins = study.expand().map_err(|e| Fault::Input(e.to_string()))?;
    if one_search_per_point {
        // Its repeats are one candidate: searched once, its answer timed over them.
        origins.retain(|origin| origin.repeat == 0);
    }
    Ok(origins)
}

/// The probes `given` planned as `searches` planned them, without replaying a search: what a
/// cluster job does with the probes its submit handed it (`cluster::probes`), each with the key
/// the driver planned it to. None when a probe is no longer what it was (no such origin, or
/// planned to another key: the study file or the solver changed since the submit), and the
/// job replays the searches instead.
pub fn plan_given(
    study: &Study,
    question: &dyn Kind,
    solver: &Nlsolve,
    index: &Index,
    options: &plan::Options,
    given: Vec<(String, ProbeOf)>,
) -> Result<Option<Vec<Planned>>, Fault> {
    let origins = origins(study, question.one_search_per_point())?;
    let fields = question.fields();
    let mut points = Vec::with_capacity(given.len());
    for (_, probe) in &given {
        match origins.get(probe.origin) {
            Some(origin) if probe.at.len() == fields.len() => {
                points.push(plan::probe(&fields, origin, &probe.at))
            }
            _ => return Ok(None),
        }
    }
    let options = options.of_every_probe();
    let mut planned = plan::plan_points(points, solver, index, &options)?;
    for (p, (key, probe)) in planned.iter_mut().zip(given) {
        if p.key.as_str() != key {
            return Ok(None);
        }
        p.probe = Some(probe);
    }
    Ok(Some(planned))
}

/// What the stored probes among `probes` spent (each key once).
pub fn spent(probes: &[Planned], store: &Store) -> Spent {
    let records = store.stored_shared(probes.iter().map(|p| p.key.as_str()));
    Spent::spent_by(records.iter().flatten().map(|r| &**r))
}
