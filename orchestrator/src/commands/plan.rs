//! `nlstudy plan`: every point of the study, whether it would run and why; nothing runs.

use super::failure::Failure;
use super::open::{no_refusals, planned, what_does_not_fit, what_refinement_cannot_show};
use super::open::{open_store, read_study};
use crate::analysis::simulate::{parse_shape, Measured};
use crate::cli::args::PlanCommandArgs;
use crate::console::{counted, Reply, Said};
use crate::run::plan::{Decision, Planned};
use std::fmt::Write as _;

pub(super) fn plan(args: &PlanCommandArgs) -> Result<Reply, Failure> {
    if let Some(shapes) = &args.simulate {
        return simulate(args, shapes);
    }
    let args = &args.plan;
    let (study, solver, _, planned) = planned(&args.common, &args.options(), false)?;
    let mut reply = Reply::default();
    reply.line(format!(
        "study {}: {} points, solver {}",
        study.name,
        planned.len(),
        solver.version
    ));
    if !study.description.is_empty() {
        reply.line(study.description.clone());
    }
    // One part of the reply a point each would be an allocation and a system call each.
    let mut listing = String::new();
    for p in &planned {
        // A refused point never starts: `run --allow-refused` stores it failed with the
        // solver's sentence (said once per distinct sentence below).
        let what = match (&p.decision, &p.case) {
            (Decision::Run(_), Err(_)) => "refused (stored as failed, not run)".into(),
            (Decision::Run(reason), Ok(_)) => format!("run   ({reason})"),
            (Decision::Skip(why), _) => format!("skip  ({why})"),
            (Decision::Duplicate, _) => "skip  (the same case as an earlier point)".into(),
        };
        let _ = writeln!(listing, "{}  {what:<40} {}", p.key, p.point.label());
    }
    reply.result(listing);
    let count = |which: &dyn Fn(&Planned) -> bool| planned.iter().filter(|p| which(p)).count();
    let refused = count(&|p| p.runs() && p.case.is_err());
    let runs = count(&|p| p.runs()) - refused;
    let duplicates = count(&|p| p.decision == Decision::Duplicate);
    let also = |n: usize, what: &str| match n {
        0 => String::new(),
        n => format!(", {n} {what}"),
    };
    reply.line(format!(
        "{runs} to run{}, {} stored{}",
        also(refused, "refused"),
        planned.len() - runs - refused - duplicates,
        also(duplicates, "the same case as an earlier point")
    ));
    // What an adaptive study's plan shows: the probes so far and the next round, and the most
    // runs its questions can take.
    if let Some(question) = study.question() {
        // A point's repeats are one question where it is searched once (an error target).
        let one = question.one_search_per_point();
        let questions = study.expand().map_or(0, |points| {
            points.iter().filter(|p| !one || p.repeat == 0).count()
        });
        let most = question.worst_case_probes();
        let rounds = question
            .worst_case_rounds()
            .map_or(String::new(), |n| format!(" in at most {n} rounds"));
        reply.line(format!(
            "{} along `{}`: {questions} {}; the points above are the probes stored and the next round, {most} runs each at most ({} in all){rounds}",
            question.section(),
            question.field(),
            question.searches(),
            questions * most
        ));
    }
    let notes = [
        what_does_not_fit(&planned),
        what_refinement_cannot_show(&planned),
    ];
    for note in notes.into_iter().flatten() {
        reply.note(format!("nlstudy: {note}"));
    }
    // Refused points fail the plan after its listing, which names them.
    match no_refusals(&planned, args.allow_refused) {
        Ok(warning) => {
            reply.said.extend(warning.map(Said::Warning));
            Ok(reply)
        }
        Err(failure) => Ok(failure.after(reply)),
    }
}

/// `plan --simulate`: the study's latest run replayed on each shape (`analysis::simulate`).
fn simulate(args: &PlanCommandArgs, shapes: &[String]) -> Result<Reply, Failure> {
    let cores = crate::run::pool::machine_cores();
    let shapes = shapes
        .iter()
        .map(|shape| parse_shape(shape, cores))
        .collect::<Result<Vec<_>, _>>()
        .map_err(Failure::BadInput)?;
    let study = read_study(&args.plan.common.study)?;
    let store = open_store(&args.plan.common, &study, false)?;
    let (_, runs) = crate::store::timeline::latest(&store, 1);
    let Some((run, measured)) = runs.iter().find_map(|run| Some((run, Measured::of(run)?))) else {
        return Err(Failure::BadInput(format!(
            "--simulate: study {} has no timeline yet; `nlstudy run` it (or a smaller sweep of it) once, and the prediction replays that run",
            study.name
        )));
    };
    let mut reply = Reply::default();
    let cases: usize = measured.batches.iter().map(Vec::len).sum();
    reply.line(format!(
        "from run {}: {} in {} on {}, {:.2} s (the model replays it: {:.2} s)",
        run.run,
        counted(cases, "case"),
        counted(measured.batches.len(), "round"),
        counted(measured.lanes, "lane"),
        measured.length,
        measured.on(measured.lanes)
    ));
    reply.line(format!(
        "measured: the driver's {:.3} ms per case, a worker's start {:.0} ms, {:.2} s between rounds in all",
        measured.driver_s * 1e3,
        measured.start_s * 1e3,
        measured.between_rounds()
    ));
    for (nodes, per_node) in shapes {
        let lanes = nodes * per_node;
        let predicted = measured.on(lanes);
        reply.line(format!(
            "on {nodes}x{per_node} ({}): {predicted:.2} s, {:.2}x the run measured",
            counted(lanes, "lane"),
            predicted / measured.length
        ));
    }
    reply.line(
        "assumed: one case a lane, longest first; one driver storing every answer in turn; the rounds as measured; not counted: the queue, the job's start, the plan before and the tables after, contention between lanes",
    );
    Ok(reply)
}
