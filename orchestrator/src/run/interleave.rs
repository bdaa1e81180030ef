//! Interleaved reruns of two solver builds (`nlstudy compare --against solver:PATH`): each chosen
//! point runs once per round with each build, in turns (A B, then B A, …: ABBA), one case at a
//! time, so that a drift of the machine (a neighbour's burst, the clock) hits both builds of a
//! pair alike and cancels in their ratio. Each build's runs are records in a store of its own,
//! beside the study's (`results/<study>/interleaved/<A>-<B>/{a,b}/<study>/runs`, so that `nlstudy
//! show STUDY --results …/a` prints them), keyed as repeats (the round is the repeat): a rerun
//! killed half-way and started again runs only the runs it lacks.
//!
//! With `instructions`, each point also runs once per build under Valgrind's cachegrind, which
//! counts the instructions the process executed (its 20–50× slowdown leaves those runs' timings
//! meaningless, so they are stores of their own too, `{a,b}-count`): the same count on any machine
//! however busy, for one thread (several threads' spinning depends on timing).

use crate::model::study::Point;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{Decision, Planned, Reason};
use crate::run::pool::{PoolOptions, Tally};
use crate::run::progress::Progress;
use crate::run::signals::Stop;
use crate::run::worker::Workers;
use crate::store::{case_id_and_key, FileError, Store};
use schema::record::{Status, Stored};
use std::path::Path;

/// One side of the comparison: its solver and where its runs are stored.
pub struct Side {
    pub solver: Nlsolve,
    pub store: Store,
    pub workers: Workers,
}

impl Side {
    /// The side named `name` (`a`, `b`, `a-count`, …) of the comparison of `study` kept in `dir`.
    pub fn open(solver: Nlsolve, dir: &Path, name: &str, study: &str) -> Side {
        let store = Store::open(&dir.join(name), study);
        let workers = Workers::new(store.work_dir(), crate::run::worker::MEMORY_BOUND_MIB);
        Side {
            solver,
            store,
            workers,
        }
    }

    /// `point` as this side runs it in round `round`: its case, keyed by this side's solver
    /// version with the round as its repeat.
    pub fn planned(&self, point: &Planned, round: usize) -> Option<Planned> {
        let case = point.case.as_ref().ok()?;
        let (case_id, key) = case_id_and_key(case.canonical_text(), &self.solver.version, round);
        let mut repeated: Point = point.point.clone();
        repeated.repeat = round;
        Some(Planned {
            point: repeated,
            case: Ok(case.clone()),
            key,
            case_id,
            decision: Decision::Run(Reason::Missing),
            probe: None,
        })
    }

    /// The record this side stored of `point` in round `round`, if a result.
    pub fn stored(&self, point: &Planned, round: usize) -> Option<Stored> {
        self.record(point, round)
            .filter(|s| s.status() != Status::Failed)
    }

    /// Why this side's run of `point` in round `round` failed (timed out, crashed, refused),
    /// the first line of its message, if it failed.
    pub fn failure(&self, point: &Planned, round: usize) -> Option<String> {
        let failed = self
            .record(point, round)
            .filter(|s| s.status() == Status::Failed)?;
        Some(failed.message().lines().next().unwrap_or("").to_string())
    }

    fn record(&self, point: &Planned, round: usize) -> Option<Stored> {
        let planned = self.planned(point, round)?;
        self.store.stored(planned.key.as_str())
    }
}

/// The order the two sides run in round `round`: A then B, then B then A, … (ABBA), so that a
/// drift along the run favours neither.
pub fn order(round: usize) -> [usize; 2] {
    match round % 2 {
        0 => [0, 1],
        _ => [1, 0],
    }
}

/// Runs what `sides` lack of `points` over `rounds` rounds, in turns; returns the work done and
/// whether it ran to its end (a stop leaves the rest for the next call). Each case runs alone
/// (`options.exclusive`), so the two builds are never timed against each other.
pub fn run(
    points: &[Planned],
    rounds: usize,
    sides: &mut [Side; 2],
    options: &PoolOptions,
    stop: &Stop,
    progress: &mut Progress,
) -> Result<(Tally, bool), FileError> {
    let mut tally = Tally::default();
    for round in 0..rounds {
        for point in points {
            for s in order(round) {
                let side = &mut sides[s];
                if side.stored(point, round).is_some() {
                    continue;
                }
                let Some(planned) = side.planned(point, round) else {
                    continue;
                };
                let ran = stop.asking(|| {
                    crate::run::pool::run(
                        (std::slice::from_ref(&planned), None),
                        &side.solver,
                        &side.store,
                        options,
                        &mut side.workers,
                        stop,
                        progress,
                    )
                })?;
                side.store.persist_catalog();
                tally.add(&ran);
                if ran.interrupted {
                    return Ok((tally, false));
                }
            }
        }
    }
    Ok((tally, true))
}

/// How many runs `sides` lack of `points` over `rounds` rounds.
pub fn missing(points: &[Planned], rounds: usize, sides: &[Side; 2]) -> usize {
    (0..rounds)
        .flat_map(|round| points.iter().map(move |p| (round, p)))
        .map(|(round, p)| {
            sides
                .iter()
                .filter(|s| s.stored(p, round).is_none())
                .count()
        })
        .sum()
}
