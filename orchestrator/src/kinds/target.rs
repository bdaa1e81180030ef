//! The cheapest configuration for an error target from each point of the sweep (a candidate):
//! the coarsest resolution that meets the target (`model::target`), its answer then timed, each
//! run alone, and the candidates ranked by cost.

use super::kind::{AdaptiveKind, Asked, Outcome, RunRound};
use crate::analysis::figure_columns::measured;
use crate::model::adaptive::Adaptive;
use crate::model::study::{Point, Study, StudyError};
use crate::model::target::{self, Aimed, TargetSpec};
use crate::run::plan::{self, Planned};
use crate::run::search::{Answers, Searched};
use crate::store::{Fault, Store};
use std::path::PathBuf;

pub struct Target;

impl AdaptiveKind for Target {
    type Spec = TargetSpec;

    fn rules(spec: &TargetSpec) -> Result<(), StudyError> {
        spec.check()
            .map_err(|(field, why)| StudyError::new(field, why))
    }

    /// The error and the cost it reads are numbers of the record (or a cost it counts).
    fn check(spec: &TargetSpec, _: &Study) -> Result<(), StudyError> {
        measured("target.error", &spec.error)?;
        match spec.cost.as_str() {
            target::CORE_SECONDS | target::BOND_EVALUATIONS => Ok(()),
            cost => measured("target.cost", cost),
        }
    }

    /// The searches, then each answer timed (`time_answers`).
    fn search(
        spec: &TargetSpec,
        asked: Asked,
        run_round: &mut RunRound,
    ) -> Result<Answers<Vec<Searched<Aimed>>>, Fault> {
        let (found, mut probes) = asked.searches(spec, run_round)?;
        let Some(mut searched) = found else {
            return Ok((None, probes));
        };
        let (timed, planned) = time_answers(asked, spec, &mut searched, run_round)?;
        probes.extend(planned);
        Ok((timed.then_some(searched), probes))
    }

    fn write(
        spec: &TargetSpec,
        searched: &[Searched<Outcome<Self>>],
        study: &Study,
        store: &Store,
    ) -> Result<PathBuf, Fault> {
        crate::analysis::target::write(study, store, spec, searched)
    }

    fn lines(spec: &TargetSpec, searched: &[Searched<Outcome<Self>>]) -> Vec<String> {
        crate::output::answers::target_lines(spec, searched)
    }
}

/// How many times an answer's timing run found noisy runs again.
const NOISY_RERUNS: usize = 2;

/// Each candidate's answer timed after the searches, where its cost is a timing: the study's `repeat` runs of its probe (as repeats 1, 2, …: the probe
/// itself, repeat 0, ran beside the search's other probes), each alone on the machine (a round
/// of one); a run timed on a busy machine (`noisy`) runs again, `NOISY_RERUNS` times at most,
/// where `run_round` runs it.
/// The answer's cost over them goes to the ranking; a count is the probe's own, never repeated.
/// Returns whether every run finished (false: interrupted) and the runs planned.
fn time_answers(
    Asked {
        study,
        solver,
        store,
        options,
    }: Asked,
    spec: &TargetSpec,
    searched: &mut [Searched<Aimed>],
    run_round: &mut RunRound,
) -> Result<(bool, Vec<Planned>), Fault> {
    // A count (`bond_evaluations`, `steps_done`) is the same every time: the probe's own.
    let repeats = match spec.cost_is_timed() {
        false => 0,
        true => study.repeat.max(1),
    };
    let mut points: Vec<(usize, Point)> = Vec::new();
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
        let point = plan::probe(&Adaptive::fields(spec), &s.origin, &probe);
        points.extend((1..=repeats).map(|r| {
            let mut repeated = point.clone();
            repeated.repeat = r;
            (k, repeated)
        }));
    }
    let options = options.of_every_probe();
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
        let stored = store.stored_shared(planned.iter().map(|p| p.key.as_str()));
        let noisy: Vec<Point> = (planned.iter().zip(stored))
            .filter(|(_, s)| s.as_ref().is_some_and(|s| s.noisy()))
            .map(|(p, _)| p.point.clone())
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
