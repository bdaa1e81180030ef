//! An adaptive study (`model::adaptive`): from each point of its sweep a question (a boundary
//! search, a refinement, an error target) runs round by round on the worker pool, every probe an
//! ordinary point (planned, keyed, stored, skipped when stored). Each round replays every
//! question from its first with the records known, so a study interrupted at any moment resumes
//! from the store without running a probe twice, and ends where it would have.
//!
//! `answer` picks the study's question (`Answered`, one variant per kind). An error target's
//! answers are then timed, each run alone (`time_answers`). `probes_so_far` is what `plan`,
//! `submit` and a job's `run --only` see of an adaptive study: the probes stored and the next
//! round.

use crate::model::adaptive::{Adaptive, Spent};
use crate::model::boundary::{BoundarySpec, Search};
use crate::model::refine::{RefineSpec, Refinement};
use crate::model::study::{Point, Question, Study};
use crate::model::target::{Aimed, TargetSpec};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{self, Planned};
use crate::store::{Fault, Store};
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
    let mut origins = study.expand().map_err(|e| Fault::Input(e.to_string()))?;
    if A::ONE_SEARCH_PER_POINT {
        // Its repeats are one candidate: searched once, its answer timed over them.
        origins.retain(|origin| origin.repeat == 0);
    }
    plan::origins_may_search(question, &origins).map_err(|e| Fault::Input(e.to_string()))?;
    // Every probe is planned: a job's `--only` applies to the round it ran (`probes_so_far`).
    let options = plan::Options {
        only: None,
        ..*options
    };
    // Each point's probes by their values (their bits).
    let mut probed: Vec<HashMap<Vec<u64>, Result<Stored, String>>> =
        vec![HashMap::new(); origins.len()];
    let bits = |probe: &[f64]| -> Vec<u64> { probe.iter().map(|v| v.to_bits()).collect() };
    let mut probes: Vec<Planned> = Vec::new();
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
            let spent = Spent::spent_by(records.filter_map(|r| r.as_ref().ok()));
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
                    record: known.values().find_map(|r| r.as_ref().ok()).cloned(),
                })
                .collect();
            return Ok((Some(searched), probes));
        }
        let points = pending
            .iter()
            .map(|(s, v)| plan::probe(question, &origins[*s], v))
            .collect();
        let planned = plan::plan_points(points, solver, &store.index(), &options)?;
        // A probe refused in a way the question reads (a step above the stable one) is an
        // answer from `check`: it is neither run nor a refusal of the study's.
        let absorbed = |p: &Planned| matches!(&p.case, Err(why) if question.absorbs(why));
        let to_run: Vec<Planned> = planned.iter().filter(|p| !absorbed(p)).cloned().collect();
        if to_run.iter().any(Planned::runs) && !run_round(&to_run)? {
            probes.extend(to_run);
            return Ok((None, probes));
        }
        for ((s, v), probe) in pending.iter().zip(&planned) {
            let record = match &probe.case {
                Err(refusal) => Err(format!("the solver refused it: {refusal}")),
                Ok(_) => store
                    .stored(probe.key.as_str())
                    .ok_or_else(|| "no record was stored".to_string()),
            };
            probed[*s].insert(bits(v), record);
        }
        probes.extend(to_run);
    }
}

/// What the stored probes among `probes` spent (each key once).
pub fn spent(probes: &[Planned], store: &Store) -> Spent {
    let records: Vec<Stored> = probes
        .iter()
        .filter_map(|p| store.stored(p.key.as_str()))
        .collect();
    Spent::spent_by(&records)
}

/// What an adaptive study found from each point of its sweep, beside the question it asked.
pub enum Answered<'a> {
    Boundaries(&'a BoundarySpec, Vec<Searched<Search>>),
    Refinements(&'a RefineSpec, Vec<Searched<Refinement>>),
    Targets(&'a TargetSpec, Vec<Searched<Aimed>>),
}

/// Runs the study's adaptive question (`boundary`, `refine` or `target`) to its end, as
/// `searches` does; None for a study of a fixed sweep.
pub fn answer<'a>(
    study: &'a Study,
    solver: &Nlsolve,
    store: &Store,
    options: &plan::Options,
    mut run_round: impl FnMut(&[Planned]) -> Result<bool, Fault>,
) -> Result<Option<Answers<Answered<'a>>>, Fault> {
    let args = (study, solver, store, options);
    let answers = match study.question() {
        Some(Question::Boundary(q)) => {
            let (found, probes) = ask(args, q, &mut run_round)?;
            (found.map(|f| Answered::Boundaries(q, f)), probes)
        }
        Some(Question::Refine(q)) => {
            let (found, probes) = ask(args, q, &mut run_round)?;
            (found.map(|f| Answered::Refinements(q, f)), probes)
        }
        Some(Question::Target(q)) => {
            let (found, mut probes) = ask(args, q, &mut run_round)?;
            let found = match found {
                Some(mut searched) => {
                    let (timed, planned) = time_answers(args, q, &mut searched, &mut run_round)?;
                    probes.extend(planned);
                    timed.then_some(searched)
                }
                None => None,
            };
            (found.map(|f| Answered::Targets(q, f)), probes)
        }
        None => return Ok(None),
    };
    Ok(Some(answers))
}

type Asked<'a> = (&'a Study, &'a Nlsolve, &'a Store, &'a plan::Options);

/// How many times an answer's timing run found noisy runs again.
const NOISY_RERUNS: usize = 2;

/// Each candidate's answer timed after the searches, where its cost is a timing or the study
/// asks for repeats: the study's `repeat` runs of its probe (as repeats 1, 2, …: the probe
/// itself, repeat 0, ran beside the search's other probes), each alone on the machine (a round
/// of one); a run timed on a busy machine (`noisy`) runs again, `NOISY_RERUNS` times at most,
/// where `run_round` runs it.
/// The answer's cost over them goes to the ranking; a count asked once is the probe's own.
/// Returns whether every run finished (false: interrupted) and the runs planned.
fn time_answers(
    (study, solver, store, options): Asked,
    spec: &TargetSpec,
    searched: &mut [Searched<Aimed>],
    run_round: &mut impl FnMut(&[Planned]) -> Result<bool, Fault>,
) -> Result<(bool, Vec<Planned>), Fault> {
    let repeats = match (study.repeat, spec.cost_is_timed()) {
        (0 | 1, false) => 0,
        (repeats, _) => repeats.max(1),
    };
    let mut points: Vec<(usize, crate::model::study::Point)> = Vec::new();
    for (k, s) in searched.iter_mut().enumerate() {
        let Some(answer) = s.outcome.answer(spec) else {
            continue;
        };
        if repeats == 0 {
            s.outcome.answer_costs.push(answer.cost);
            continue;
        }
        let mut probe = vec![answer.value];
        probe.extend(answer.time);
        let point = plan::probe(spec, &s.origin, &probe);
        points.extend((1..=repeats).map(|r| {
            let mut repeated = point.clone();
            repeated.repeat = r;
            (k, repeated)
        }));
    }
    let options = plan::Options {
        only: None,
        ..*options
    };
    let planned = plan::plan_points(
        points.iter().map(|(_, p)| p.clone()).collect(),
        solver,
        &store.index(),
        &options,
    )?;
    let alone = |planned: &[Planned],
                 run_round: &mut dyn FnMut(&[Planned]) -> Result<bool, Fault>| {
        for one in planned.iter().filter(|p| p.runs()) {
            if !run_round(std::slice::from_ref(one))? {
                return Ok(false);
            }
        }
        Ok::<_, Fault>(true)
    };
    if !alone(&planned, run_round)? {
        return Ok((false, planned));
    }
    for _ in 0..NOISY_RERUNS {
        let noisy: Vec<crate::model::study::Point> = (planned.iter())
            .filter(|p| store.stored(p.key.as_str()).is_some_and(|s| s.noisy()))
            .map(|p| p.point.clone())
            .collect();
        if noisy.is_empty() {
            break;
        }
        let forced = plan::Options {
            force: true,
            ..options.clone()
        };
        let again = plan::plan_points(noisy, solver, &store.index(), &forced)?;
        if !alone(&again, run_round)? {
            // Not run again: a plan, or the cluster's driver, which runs nothing (its jobs' own
            // `run` retimes them), or a stop, after which `run` writes no answer. The noisy
            // timings stand, marked noisy in the tables.
            break;
        }
    }
    for ((k, _), p) in points.iter().zip(&planned) {
        let cost = store
            .stored(p.key.as_str())
            .and_then(|s| spec.cost_of(&s).ok());
        searched[*k].outcome.answer_costs.extend(cost);
    }
    Ok((true, planned))
}

fn ask<A: Adaptive>(
    (study, solver, store, options): Asked,
    question: &A,
    run_round: &mut impl FnMut(&[Planned]) -> Result<bool, Fault>,
) -> Result<Answers<Vec<Searched<A::Outcome>>>, Fault> {
    searches(study, question, solver, store, options, run_round)
}

/// The probes of an adaptive study so far: those stored (skipped) and the next round's (to
/// run), as `plan` shows them, `submit` sends them to the scheduler and a job's `run --only`
/// runs its share of them. None for a study of a fixed sweep.
pub fn probes_so_far(
    study: &Study,
    solver: &Nlsolve,
    store: &Store,
    options: &plan::Options,
) -> Result<Option<Vec<Planned>>, Fault> {
    let Some((_, mut probes)) = answer(study, solver, store, options, |_| Ok(false))? else {
        return Ok(None);
    };
    if let Some(only) = &options.only {
        plan::restrict(&mut probes, only)?;
    }
    Ok(Some(probes))
}
