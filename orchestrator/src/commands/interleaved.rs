//! `nlstudy compare --against solver:PATH`: the study's points rerun now with two builds in
//! turns (`run::interleave`), each pair's ratio judged (`analysis::compare::paired`), and with
//! `--instructions` each point's instruction count by each build (`run::instructions`).

use super::failure::Failure;
use super::open::{claim, planned};
use super::verdicts::report;
use crate::analysis::compare::paired::{self, Rounds};
use crate::cli::args::CompareArgs;
use crate::console::{Reply, NOTE};
use crate::run::interleave::{self, Side};
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{Decision, Options, Planned};
use crate::run::pool::PoolOptions;
use crate::run::progress::{Mode, Progress};
use crate::run::signals;
use schema::record::Stored;
use std::path::Path;
use std::process::ExitCode;

pub(super) fn compare(args: &CompareArgs, baseline: &Path) -> Result<Reply, Failure> {
    let most = rounds_asked(args)?;
    let stop = signals::Stop::on_signals().map_err(Failure::Io)?;
    let (study, solver_b, store, planned) = planned(&args.common, &Options::default(), false)?;
    let solver_a = Nlsolve::locate(Some(baseline))?;
    let points = chosen(&planned, args.only.as_deref())?;
    let names = format!("{}-{}", solver_a.build_name()?, solver_b.build_name()?);
    let dir = store.table("interleaved").join(names);
    claim(&args.common, &study, &store, true)?;
    let mut counted = args
        .instructions
        .then(|| [(solver_a.clone(), "a-count"), (solver_b.clone(), "b-count")]);
    let mut sides = [
        Side::open(solver_a, &dir, "a", &study.name),
        Side::open(solver_b, &dir, "b", &study.name),
    ];
    let timeout = super::run::timeout(args.timeout, study.timeout_s)?;
    let options = alone_on_this_machine(timeout);
    let mut counts = None;
    // Each point's rounds: --rounds, then more for those whose CPU time is still undecided.
    let mut reach = vec![args.rounds; points.len()];
    let mut chosen: Vec<usize> = (0..points.len()).collect();
    let comparison = loop {
        let subset: Vec<Planned> = chosen.iter().map(|&k| points[k].clone()).collect();
        let rounds = chosen
            .iter()
            .map(|&k| reach[k])
            .max()
            .unwrap_or(args.rounds);
        let missing = interleave::missing(&subset, rounds, &sides);
        let stored = 2 * rounds * subset.len() - missing;
        if rounds == args.rounds {
            log::info!(
                target: NOTE,
                "interleaved: {} points × {rounds} rounds × 2 builds, {missing} runs to go ({stored} stored in {})",
                points.len(),
                dir.display()
            );
        }
        let mut progress = Progress::new(Mode::detect(), missing, stored);
        let (_, finished) =
            interleave::run(&subset, rounds, &mut sides, &options, &stop, &mut progress)?;
        progress.close();
        if !finished {
            let signal = stop.signal().unwrap_or(libc::SIGTERM);
            let why = format!(
                "stopped by {}; the pairs that finished are stored, run again to resume",
                signals::name(signal)
            );
            let code = stop.exit_code().unwrap_or(schema::exit::INTERRUPTED);
            return Ok(Reply::default().failed(why, ExitCode::from(code)));
        }
        failed_runs(&subset, rounds, &sides)?;
        if let Some(solvers) = counted.take() {
            counts = Some(count(&points, solvers, &dir, &study.name)?);
        }
        let rounds = stored_rounds(&points, &reach, &sides, counts.as_ref());
        let comparison = paired::judge(&rounds, args.threshold);
        chosen = (0..points.len())
            .filter(|&k| reach[k] < most)
            .filter(|&k| {
                let label = points[k].point.label();
                (comparison.changes.iter())
                    .any(|c| c.point == label && paired::undecided(c, args.threshold))
            })
            .collect();
        if chosen.is_empty() {
            break comparison;
        }
        for &k in &chosen {
            reach[k] = (reach[k] + args.rounds).min(most);
        }
        log::info!(
            target: NOTE,
            "interleaved: {} points whose CPU time is undecided run to {} rounds",
            chosen.len(),
            chosen.iter().map(|&k| reach[k]).max().unwrap_or(0)
        );
    };
    let rounds = rounds_run(args.rounds, &reach);
    let title = format!(
        "study {}: B = this build against A = {} (interleaved, {rounds})",
        study.name,
        baseline.display(),
    );
    let mut reply = Reply::default();
    reply.note(format!(
        "noise: each point's pairs of runs, one right after the other ({rounds}, A B then B A): their spread is the interval; no history needed"
    ));
    report(
        reply,
        &comparison,
        &study,
        &store,
        &args.against,
        &title,
        args.threshold,
        points.len(),
    )
}

/// A gate fails when a build cannot run the study: the runs of `points` over `rounds` rounds
/// that failed (crashed, timed out, refused) on either side, named, as a `CaseFailed`. Without
/// this a build that crashed on every case was "0 worse" and passed.
fn failed_runs(points: &[Planned], rounds: usize, sides: &[Side; 2]) -> Result<(), Failure> {
    const SHOWN: usize = 5;
    let mut failed = Vec::new();
    for point in points {
        for round in 0..rounds {
            for (side, name) in sides.iter().zip(["A", "B"]) {
                if let Some(why) = side.failure(point, round) {
                    failed.push(format!(
                        "{} by {name} in round {}: {}",
                        point.point.label(),
                        round + 1,
                        schema::text::printable(&why)
                    ));
                }
            }
        }
    }
    if failed.is_empty() {
        return Ok(());
    }
    let more = match failed.len() {
        n if n > SHOWN => format!("; and {} more", n - SHOWN),
        _ => String::new(),
    };
    Err(Failure::CaseFailed(format!(
        "{} runs failed, so the builds cannot be compared: {}{more}",
        failed.len(),
        failed[..failed.len().min(SHOWN)].join("; ")
    )))
}

/// The rounds run: `--rounds`, and the most for the points whose CPU time they left undecided.
fn rounds_run(asked: usize, reach: &[usize]) -> String {
    let extended = reach.iter().filter(|&&r| r > asked).count();
    match reach.iter().max() {
        Some(&most) if extended > 0 => format!(
            "{asked} rounds, {most} for the {extended} points whose CPU time they left undecided"
        ),
        _ => format!("{asked} rounds"),
    }
}

/// The rounds asked for (`--rounds`, at least 2), and the most a point may run
/// (`--max-rounds`, at least `--rounds`; three times it by default).
fn rounds_asked(args: &CompareArgs) -> Result<usize, Failure> {
    if args.rounds < 2 {
        return Err(Failure::BadInput(format!(
            "--rounds {}: give at least 2, so that each point has an interval",
            args.rounds
        )));
    }
    let most = args.max_rounds.unwrap_or(3 * args.rounds);
    if most < args.rounds {
        return Err(Failure::BadInput(format!(
            "--max-rounds {most}: give at least --rounds ({})",
            args.rounds
        )));
    }
    Ok(most)
}

/// Each run alone on this machine, as timings want, stopped past `timeout`, with no retry or
/// checkpoint.
fn alone_on_this_machine(timeout: Option<std::time::Duration>) -> PoolOptions {
    let cores = crate::run::pool::machine_cores();
    PoolOptions {
        cores,
        nodes: crate::run::allocation::this_machine(cores),
        exclusive: true,
        timeout,
        launcher: (crate::model::launcher::DEFAULT_LAUNCHER.parse())
            .expect("the default launcher parses"),
        retries: 0,
        isolate: false,
        checkpoint_every: None,
        keep_checkpoints: false,
    }
}

/// Each point's pairs stored so far, its first `reach` rounds, with its instruction counts.
fn stored_rounds(
    points: &[Planned],
    reach: &[usize],
    sides: &[Side; 2],
    counts: Option<&Vec<Option<(Stored, Stored)>>>,
) -> Vec<Rounds> {
    let pairs = |k: usize, point: &Planned| -> Vec<_> {
        (0..reach[k])
            .map(|r| (sides[0].stored(point, r), sides[1].stored(point, r)))
            .collect()
    };
    (points.iter().enumerate())
        .map(|(k, point)| Rounds {
            point: point.point.label(),
            pairs: pairs(k, point),
            counted: counts.and_then(|c| c[k].clone()),
        })
        .collect()
}

/// The study's points to rerun: one per case (repeats and the same case on another branch run
/// once), those the solver accepts, among `only` when given.
fn chosen(planned: &[Planned], only: Option<&[String]>) -> Result<Vec<Planned>, Failure> {
    if let Some(unknown) = only.and_then(|keys| {
        keys.iter()
            .find(|k| !planned.iter().any(|p| p.key.as_str() == k.as_str()))
    }) {
        return Err(Failure::BadInput(format!(
            "--only {unknown:?}: no point of the study has that key; `nlstudy plan` lists them"
        )));
    }
    Ok(planned
        .iter()
        .filter(|p| p.point.repeat == 0 && p.case.is_ok() && p.decision != Decision::Duplicate)
        .filter(|p| only.is_none_or(|keys| keys.iter().any(|k| k == p.key.as_str())))
        .cloned()
        .collect())
}

/// Each point's instruction count by each build, counted once and kept (`a-count`, `b-count`).
fn count(
    points: &[Planned],
    solvers: [(Nlsolve, &str); 2],
    dir: &Path,
    study: &str,
) -> Result<Vec<Option<(Stored, Stored)>>, Failure> {
    let sides: Vec<Side> = solvers
        .into_iter()
        .map(|(solver, name)| Side::open(solver, dir, name, study))
        .collect();
    let mut counted = Vec::with_capacity(points.len());
    for point in points {
        let mut both = Vec::new();
        for side in &sides {
            if let Some(stored) = side.stored(point, 0) {
                both.push(stored);
                continue;
            }
            let scratch = side.store.work_dir();
            crate::store::fs::create_dir(&scratch)?;
            let planned = side.planned(point, 0).expect("a chosen point has its case");
            log::info!(
                target: NOTE,
                "counting the instructions of {} ({})",
                point.point.label(),
                side.solver.binary.display()
            );
            match crate::run::instructions::count(&planned, &side.solver, &scratch) {
                Ok(stored) => {
                    side.store.save(planned.key.as_str(), &stored)?;
                    side.store.persist_catalog();
                    both.push(stored);
                }
                Err(why) => return Err(Failure::Io(format!("{}: {why}", point.point.label()))),
            }
        }
        let mut both = both.into_iter();
        counted.push(both.next().zip(both.next()));
    }
    Ok(counted)
}
