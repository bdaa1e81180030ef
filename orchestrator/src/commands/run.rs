//! `nlstudy run`: the points not yet stored run on the worker pool, their records are stored,
//! and the study's tables, figures and report are made of them.

use super::failure::Failure;
use super::open::{
    figures_drawn, no_refusals, planned, tables_written, what_does_not_fit,
    what_refinement_cannot_show,
};
use crate::cli::args::RunArgs;
use crate::console::Reply;
use crate::kinds::{Asked, Found};
use crate::model::study::Study;
use crate::run::cluster::limits::History;
use crate::run::plan::{Decision, Planned};
use crate::run::pool::PoolOptions;
use crate::run::pool::Tally;
use crate::run::progress::{Mode, Progress};
use crate::run::search;
use crate::run::signals;
use crate::run::timeline::Timeline;
use crate::store::Store;
use schema::exit;
use std::process::ExitCode;
use std::time::Duration;

pub(super) fn run(args: &RunArgs) -> Result<Reply, Failure> {
    let stop = signals::Stop::on_signals().map_err(Failure::Io)?;
    signals::phase("plan");
    let (study, solver, store, planned) = planned(&args.plan.common, &args.plan.options(), true)?;
    // Said before the runs start, as they may take hours.
    if let Some(warning) = no_refusals(&planned, args.plan.allow_refused)? {
        log::warn!("{warning}");
    }
    for note in [
        what_does_not_fit(&planned),
        what_refinement_cannot_show(&planned),
    ] {
        note.inspect(|note| log::info!("{note}"));
    }
    // Inside a job, the mark its driver waits for, left however this run ends.
    let _ended = crate::run::cluster::ended::on_end(&store);
    let options = pool_options(args, &study)?;
    store.clear_abandoned_outputs()?;
    let mut tally = Tally::default();
    let mut workers = crate::run::worker::Workers::new(store.work_dir(), args.worker_memory);
    workers.dial_back_to(crate::run::allocation::this_nodes_address(&options.nodes));
    workers.timeline = Timeline::recorded(&store, crate::run::pool::run_id());
    // An adaptive study's rounds are numbered on each line, since each counts its own cases.
    let mut round = study.question().map(|_| 0);
    // Runs the planned points not stored, counting what happened into `tally`.
    let mut run_on_pool = |planned: &[Planned]| -> Result<bool, crate::store::Fault> {
        let (to_run, copies) = counts(planned);
        let stored = planned.len() - to_run - copies;
        round = round.map(|r| r + 1);
        let mut progress = Progress::new(Mode::detect(), to_run, stored).in_round(round);
        let costs = predicted_costs(planned, &store, &options);
        let ran = stop.asking(|| {
            let pool = crate::run::pool::run;
            pool(
                (planned, costs.as_deref()),
                &solver,
                &store,
                &options,
                &mut workers,
                &stop,
                &mut progress,
            )
        });
        progress.close();
        store.persist_catalog();
        let ran = ran.map_err(|e| {
            crate::store::Fault::Io(format!(
                "{e}; the cases that were running are not stored and run again next time"
            ))
        })?;
        tally.add(&ran);
        signals::phase("round");
        Ok(!ran.interrupted)
    };
    // A cluster job runs its share of the round it was given (`--only`); the questions of an
    // adaptive study go on in `run`.
    let options_of_probes = args.plan.options();
    let adaptive = match options_of_probes.only {
        Some(_) => None,
        None => {
            let asked = Asked {
                study: &study,
                solver: &solver,
                store: &store,
                options: &options_of_probes,
            };
            crate::kinds::answer(asked, &mut run_on_pool)?
        }
    };
    let (answered, planned) = match adaptive {
        Some(answers) => answers,
        None => {
            run_on_pool(&planned)?;
            (None, planned)
        }
    };
    let mut reply = Reply::default();
    for line in Ran::new(&study.name, &planned, &tally).lines() {
        reply.note(line);
    }
    if let Some(signal) = stop.signal().filter(|_| tally.interrupted) {
        let why = format!(
            "stopped by {}; what finished is stored, run again to resume",
            crate::run::signals::name(signal)
        );
        let code = stop.exit_code().unwrap_or(exit::INTERRUPTED);
        return Ok(reply.failed(why, ExitCode::from(code)));
    }
    let ending = Ending {
        collect: !args.no_collect,
        allow_mixed: args.allow_mixed,
    };
    let answered = answered.as_deref();
    match conclude(&mut reply, &study, &store, &planned, answered, ending) {
        Err(failure) => Ok(failure.after(reply)),
        Ok(()) if tally.failed > 0 => Ok(reply.ending(ExitCode::from(exit::CASE_FAILED))),
        Ok(()) => Ok(reply),
    }
}

/// The predicted cost of each planned point (`balance::predicted_costs`), from the timings
/// stored so far, for the pool to start the costliest first; none for a pool that runs one case
/// at a time, which keeps plan order.
fn predicted_costs(planned: &[Planned], store: &Store, options: &PoolOptions) -> Option<Vec<f64>> {
    if !options.side_by_side() {
        return None;
    }
    // Not by searches: the pool orders a round's probes by their work, ties by key, which
    // keeps two workers off one operator's spectrum at once (docs/performance.md).
    let history = History::from_index(planned, &store.index(), None);
    let points: Vec<&Planned> = planned.iter().collect();
    Some(crate::run::cluster::balance::predicted_costs(&points, &history).costs)
}

/// What a pool is given from the flags and the study: the nodes (inside a Slurm job of several
/// nodes, every node of it; else this machine), the cores, the timeout and checkpoint period.
fn pool_options(args: &RunArgs, study: &Study) -> Result<PoolOptions, Failure> {
    let nodes =
        crate::run::allocation::nodes(args.jobs.unwrap_or(crate::run::pool::machine_cores()));
    if nodes.len() > 1 {
        log::info!("{}", crate::run::allocation::describe(&nodes));
    }
    let timeout = timeout(args.timeout, study.timeout_s)?;
    let checkpoint_every = given(
        args.checkpoint_every,
        "--checkpoint-every",
        study.checkpoint_every_s,
        "checkpoint_every_s",
    )?;
    Ok(PoolOptions {
        cores: args
            .jobs
            .unwrap_or_else(|| nodes.iter().map(|n| n.cores).sum()),
        nodes,
        exclusive: !study.share_machine,
        timeout,
        launcher: args.launcher.clone(),
        retries: args.retries,
        isolate: args.isolate,
        checkpoint_every,
        keep_checkpoints: args.keep_checkpoints,
    })
}

/// A period from its flag, else from the study's field (each named when it is not one).
fn given(
    flag: Option<f64>,
    flag_name: &str,
    field: Option<f64>,
    field_name: &str,
) -> Result<Option<Duration>, Failure> {
    match flag {
        Some(seconds) => Some(period(seconds, flag_name)).transpose(),
        None => field.map(|s| period(s, field_name)).transpose(),
    }
}

/// A case's timeout: `--timeout`, else the study's `timeout_s`.
pub(super) fn timeout(flag: Option<f64>, field: Option<f64>) -> Result<Option<Duration>, Failure> {
    given(flag, "--timeout", field, "timeout_s")
}

/// What a study's `run` did, as its summary says it.
struct Ran<'a> {
    study: &'a str,
    tally: &'a Tally,
    skipped: usize,
    duplicates: usize,
}

impl<'a> Ran<'a> {
    fn new(study: &'a str, planned: &[Planned], tally: &'a Tally) -> Ran<'a> {
        let (runs, duplicates) = counts(planned);
        Ran {
            study,
            tally,
            skipped: planned.len() - runs - duplicates,
            duplicates,
        }
    }

    /// `study quick: 12 ran (12 ok, 0 diverged, 0 failed), 3 already stored`, and how many of
    /// them were timed noisy.
    fn lines(&self) -> Vec<String> {
        let Ran {
            study,
            tally,
            skipped,
            duplicates,
        } = self;
        let also = |n: usize, what: &str| match n {
            0 => String::new(),
            n => format!(", {n} {what}"),
        };
        let ran = tally.ok + tally.diverged + tally.failed;
        let mut lines = vec![format!(
            "study {study}: {ran} ran ({} ok, {} diverged, {} failed), {skipped} already stored{}{}",
            tally.ok,
            tally.diverged,
            tally.failed,
            also(tally.passed, "run by another nlstudy"),
            also(*duplicates, "the same case as an earlier point"),
        )];
        if tally.noisy > 0 {
            lines.push(format!(
                "  {} of them noisy: timed while other tasks wanted the cores they left free; their timings measure contention too (`nlstudy run --force` them on a quiet machine)",
                tally.noisy
            ));
        }
        lines
    }
}

/// How a study's end is made (`conclude`).
#[derive(Clone, Copy)]
pub(super) struct Ending {
    /// Gather the tables, figures and report (`run --no-collect` does not).
    pub collect: bool,
    pub allow_mixed: bool,
}

/// A study's end, from what is stored: an adaptive study's answers (their table and lines), then
/// its tables, figures and report, each said in `reply`; a failure when a table or figure could
/// not be made.
pub(super) fn conclude(
    reply: &mut Reply,
    study: &Study,
    store: &Store,
    planned: &[Planned],
    answered: Option<&dyn Found>,
    ending: Ending,
) -> Result<(), Failure> {
    if let Some(answered) = answered {
        let path = answered.write(study, store)?;
        for line in answered.lines() {
            reply.note(format!("  {line}"));
        }
        if let Some(budget) = &study.budget {
            let spent = search::spent(planned, store);
            let line = crate::output::answers::budget_line(budget, &spent);
            reply.note(format!("  {line}"));
        }
        reply.note(format!("table: {}", path.display()));
    }
    if ending.collect {
        signals::phase("collect");
        let to_collect = crate::analysis::collect::ToCollect::from_planned(planned);
        let swept = to_collect.swept().to_vec();
        let collected =
            crate::analysis::collect::collect(to_collect, store, study, ending.allow_mixed);
        let tables = collected.and_then(|collected| match collected {
            Some(collected) => {
                signals::phase("figures");
                let figures = crate::output::plot::plot(&study.figures, study.question(), store)?;
                signals::phase("report");
                let page = crate::output::report::write(study, store, &swept)?;
                tables_written(reply, &collected);
                figures_drawn(reply, &figures);
                reply.note(format!("report: {}", page.display()));
                Ok(crate::output::plot::all_drawn(&figures).err())
            }
            None => Ok(None),
        });
        // A table or figure that cannot be made of these runs exits 1; a file that cannot be
        // read or written, 3.
        let stored = |message| format!("{message}; the runs are stored");
        return match tables {
            Ok(None) => Ok(()),
            Ok(Some(m)) | Err(crate::store::Fault::Input(m)) => Err(Failure::CaseFailed(stored(m))),
            Err(crate::store::Fault::Io(m)) => Err(Failure::Io(stored(m))),
        };
    }
    Ok(())
}

/// The points of `planned` that run, and those that are the same case as an earlier point.
fn counts(planned: &[Planned]) -> (usize, usize) {
    let runs = planned.iter().filter(|p| p.runs()).count();
    let copies = planned
        .iter()
        .filter(|p| p.decision == Decision::Duplicate)
        .count();
    (runs, copies)
}

/// The longest timeout taken: about 31 years, past any allocation.
const LONGEST_TIMEOUT_S: f64 = 1e9;

/// A case's timeout from `field`: a positive, finite number of seconds.
/// A period of wall time given in seconds (a timeout, a checkpoint period), checked.
fn period(seconds: f64, field: &str) -> Result<Duration, Failure> {
    let given = schema::text::exact(seconds);
    if !seconds.is_finite() {
        return Err(Failure::BadInput(format!(
            "{field}: {given} is not a finite number; give a number of seconds, or none"
        )));
    }
    if !(seconds > 0.0 && seconds <= LONGEST_TIMEOUT_S) {
        return Err(Failure::BadInput(format!(
            "{field}: {given} is not a period; give a number of seconds above 0 and at most {LONGEST_TIMEOUT_S:e}, or none"
        )));
    }
    Ok(Duration::from_secs_f64(seconds))
}
