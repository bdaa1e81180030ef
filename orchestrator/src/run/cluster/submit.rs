//! Cluster jobs: Slurm or LSF scripts for the points of a study not yet stored. Each job (or
//! array element) packs several cases into one allocation and runs `nlstudy run --only KEYS`
//! inside it, so the same record store and the same make-style skipping serve the cluster and
//! the workstation, and a requeued job runs only what is missing.

use super::balance::predicted_costs;
use super::forecast;
use super::ledger::{self, LedgerEntry};
use super::limits::{self, History, SAFETY, START_S};
use super::pack::{self, pack};
use super::scheduler::{self, Scheduler};
use super::script::{write_jobs, Job, JobCommand, Settings};
use crate::model::adaptive::Kind;
use crate::model::launcher::Launcher;
use crate::model::resources::{Resources, WallTime};
use crate::model::site::Site;
use crate::model::study::Study;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::Planned;
use crate::store::{Fault, FileError};
use crate::store::{Index, Store};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where and how `nlstudy submit` sends a study: the scheduler and site, the resources (the
/// site's defaults, the study's, then the flags'), the results directory and study file as
/// given, and whether to stop after writing the scripts.
pub struct Target {
    pub scheduler: Scheduler,
    pub site: Site,
    pub resources: Resources,
    /// The time limit the study or a flag gave (it wins over stored timings).
    pub time: Option<WallTime>,
    /// One job array per allocation shape rather than one job per pack.
    pub array: bool,
    /// Elements of an array running at once.
    pub throttle: Option<std::num::NonZeroUsize>,
    pub results: PathBuf,
    pub study_file: PathBuf,
    pub dry_run: bool,
    /// `nlstudy run --retries` inside each job.
    pub retries: usize,
    /// The MPI launcher inside each job (the site's, else the scheduler's own, when `None`).
    pub launcher: Option<Launcher>,
    /// One job that runs the whole study, every round of an adaptive one, and writes its
    /// tables, figures and report (`submit --whole`).
    pub whole: bool,
    /// The whole study's job tabulates runs of several hosts or builds (`--allow-mixed`).
    pub allow_mixed: bool,
}

/// What one `submit_study` did: the jobs it wrote (and submitted, unless a dry run), the points
/// in them, and the points left to jobs the scheduler still holds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sent {
    pub jobs: usize,
    pub points: usize,
    pub held: usize,
    /// The round's predicted length in seconds (`forecast::round`), when its points' costs
    /// are timed ones.
    pub round_s: Option<f64>,
}

/// Writes the job scripts for the planned points that run (those the solver refuses are named
/// and left out, and so are those of jobs the scheduler still holds), says one line per job,
/// and submits them unless `dry_run`, recording each job in the study's ledger.
pub fn submit_study(
    study: &Study,
    solver: &Nlsolve,
    planned: &[Planned],
    store: &Store,
    index: &Index,
    target: &Target,
    say: &mut dyn FnMut(String),
) -> Result<Sent, Fault> {
    let in_flight = in_flight(store, target.scheduler, planned);
    let (runnable, refused): (Vec<&Planned>, Vec<&Planned>) = planned
        .iter()
        .filter(|p| p.runs() && !in_flight.contains_key(p.key.as_str()))
        .partition(|p| p.case.is_ok());
    let held = planned
        .iter()
        .filter(|p| p.runs() && in_flight.contains_key(p.key.as_str()))
        .count();
    let holding = say_held(&in_flight, held);
    for p in &refused {
        log::info!(
            "not submitted, the solver refuses {}: {}",
            p.point.label(),
            p.case.as_ref().err().map_or("", String::as_str)
        );
    }
    if runnable.is_empty() {
        let why = match holding.is_empty() {
            true => "every point is stored",
            false => "every point is stored or in a job still queued or running",
        };
        say(format!("study {}: nothing to submit, {why}", study.name));
        return Ok(Sent {
            held,
            ..Sent::default()
        });
    }
    crate::store::fs::create_dir(&target.results)?;
    let command = job_command(study, solver, target)?;
    let history = History::from_index(planned, index, study.question().map(|q| q.field()))
        .resuming(store, planned, solver.fingerprint.as_deref());
    let predicted = predicted_costs(&runnable, &history);
    let packs = match target.whole {
        true => vec![pack::whole(
            &study.name,
            &runnable,
            &target.resources,
            target.site.cores_per_node,
        )],
        false => pack(
            &study.name,
            &runnable,
            &predicted.costs,
            &target.resources,
            target.site.cores_per_node,
            target.array,
        ),
    };
    let cost: HashMap<&str, f64> = runnable
        .iter()
        .zip(&predicted.costs)
        .map(|(p, c)| (p.key.as_str(), *c))
        .collect();
    let round_s = predicted.seconds.then(|| forecast::round(&packs, &cost));
    let packs: Vec<_> = packs
        .into_iter()
        .map(|pack| {
            let (time, from) = match (target.whole, study.question()) {
                (true, Some(question)) if target.time.is_none() => {
                    whole_limit(question, round_s, target)
                }
                _ => time_limit(&pack.bundles, &history, target),
            };
            (pack, time, from)
        })
        .collect();
    let settings = Settings {
        scheduler: target.scheduler,
        resources: &target.resources,
        site: &target.site,
        exclusive: target.site.exclusive.unwrap_or(!study.share_machine),
        throttle: target.throttle,
    };
    let timed: Vec<_> = packs.iter().map(|(p, t, _)| (p, *t)).collect();
    let jobs = write_jobs(&timed, &settings, &command)
        .map_err(|e| e.within("cannot write the job scripts"))?;
    for (job, (_, time, from)) in jobs.iter().zip(&packs) {
        say(job_line(job, *time, from));
        if !target.dry_run {
            let id = submit_job(job, target, store)?;
            say(format!("  submitted as job {id}"));
        }
    }
    Ok(Sent {
        jobs: jobs.len(),
        points: runnable.len(),
        held,
        round_s,
    })
}

/// Says which jobs still hold `held` planned points (they are not submitted again); returns
/// their ids.
fn say_held(in_flight: &HashMap<String, String>, held: usize) -> Vec<&str> {
    let mut holding: Vec<&str> = in_flight.values().map(String::as_str).collect();
    holding.sort_unstable();
    holding.dedup();
    if !holding.is_empty() {
        // An array's elements each have an id: a few name the rest.
        let named = match holding.len() {
            n if n > 5 => format!("{} and {} more", holding[..5].join(", "), n - 5),
            _ => holding.join(", "),
        };
        log::info!(
            "{held} points are in jobs still queued or running ({named}); not submitted again"
        );
    }
    holding
}

/// What each job runs: this nlstudy, the study's solver and file, the results, by absolute path.
fn job_command(study: &Study, solver: &Nlsolve, target: &Target) -> Result<JobCommand, Fault> {
    let absolute =
        |path: &Path| std::fs::canonicalize(path).map_err(FileError::on("resolve", path));
    let results = absolute(&target.results)?;
    Ok(JobCommand {
        nlstudy: std::env::current_exe()
            .map_err(|e| Fault::Io(format!("cannot find nlstudy: {e}")))?,
        nlsolve: absolute(&solver.binary)?,
        study: absolute(&target.study_file)?,
        jobs: results.join(&study.name).join("jobs"),
        results,
        retries: target.retries,
        launcher: target
            .launcher
            .clone()
            .or_else(|| target.site.launcher.clone()),
        whole: target.whole,
        allow_mixed: target.allow_mixed,
    })
}

/// The line that says a job: its name, cases, time limit and where that came from, its script.
fn job_line(job: &Job, time: Option<WallTime>, from: &str) -> String {
    let limit = time.map_or("time".to_string(), |t| format!("time {}", t.slurm()));
    match job.array {
        false => format!(
            "{} ({} cases, {limit}: {from}): {}",
            job.name,
            job.bundles[0].len(),
            job.script.display()
        ),
        true => format!(
            "{} (array of {} elements, {} cases, {limit}: {from}): {}",
            job.name,
            job.bundles.len(),
            job.bundles.iter().map(Vec::len).sum::<usize>(),
            job.script.display()
        ),
    }
}

/// Submits `job`, entered in the ledger before the scheduler has it and settled under its id
/// after (a submission killed in between is settled by the next look at the ledger); returns
/// the id.
fn submit_job(job: &Job, target: &Target, store: &Store) -> Result<String, Fault> {
    let mut entry = LedgerEntry {
        scheduler: target.scheduler,
        id: String::new(),
        name: job.name.clone(),
        keys: job.bundles.concat(),
        elements: match job.array {
            true => job.bundles.clone(),
            false => Vec::new(),
        },
        submitted: super::unix_seconds(),
        whole: target.whole,
    };
    let token = ledger::token();
    ledger::intend(store, &entry, &token)?;
    entry.id = match scheduler::submit(target.scheduler, &job.script, &token) {
        Ok(id) => id,
        Err(refused) => {
            let _ = ledger::forget(store, &token);
            return Err(refused);
        }
    };
    ledger::settle(store, &entry, &token)?;
    Ok(entry.id)
}

/// A job's time limit and where it came from: `--time` or the study's; else its points'
/// stored timings (an array's longest element); else the site's default; else none.
fn time_limit(
    bundles: &[Vec<&Planned>],
    history: &History,
    target: &Target,
) -> (Option<WallTime>, String) {
    if let Some(time) = target.time {
        return (Some(time), "as given".into());
    }
    let limits: Result<Vec<(WallTime, String)>, String> =
        bundles.iter().map(|b| history.limit(b)).collect();
    match limits {
        Ok(limits) => match limits.into_iter().max_by_key(|(t, _)| t.seconds()) {
            Some((time, from)) => (Some(time), format!("from {from}")),
            None => fallback(target, "no points".into()),
        },
        Err(why) => fallback(target, why),
    }
}

/// The time limit of a job running every round of an adaptive study (`--whole`): the plan's
/// worst case of rounds, each as long as this one's predicted length on the job's lanes, × the
/// margin; without both, the site's default, saying which is unknown.
fn whole_limit(
    question: &dyn Kind,
    round_s: Option<f64>,
    target: &Target,
) -> (Option<WallTime>, String) {
    let Some(rounds) = question.worst_case_rounds() else {
        return fallback(target, "the question does not bound its rounds".into());
    };
    if question.rounds_no_longer_from() != Some(1) {
        return fallback(
            target,
            "its later rounds may be longer than its first (a finer grid, more probes), so the first bounds none".into(),
        );
    }
    let Some(round_s) = round_s else {
        return fallback(
            target,
            "no point of the study is timed yet, nor a smaller grid of its series, so the length of its rounds is not known".into(),
        );
    };
    match limits::wall_time(rounds as f64 * round_s * SAFETY + START_S) {
        Ok(time) => (
            Some(time),
            format!(
                "from the plan's worst case, {rounds} rounds × {} (this round's points, predicted from stored timings, on the job's cores) × {SAFETY} + {START_S} s",
                forecast::seconds(round_s)
            ),
        ),
        Err(why) => fallback(target, why),
    }
}

/// The site's default time limit, else the scheduler's, saying why stored timings gave none.
fn fallback(target: &Target, why: String) -> (Option<WallTime>, String) {
    match target.site.time {
        Some(time) => (Some(time), format!("the site's default ({why})")),
        None => (None, format!("the scheduler's default ({why})")),
    }
}

/// The keys of the ledger's jobs that the scheduler still holds, each with its job's id (every
/// point of `planned` while a job of the whole study is held). Where the scheduler cannot be
/// asked (a workstation writing scripts), nothing is held.
fn in_flight(store: &Store, scheduler: Scheduler, planned: &[Planned]) -> HashMap<String, String> {
    match ledger::held(store, scheduler) {
        Ok(held) => match held.iter().find(|h| h.whole) {
            Some(whole) => planned
                .iter()
                .map(|p| (p.key.to_string(), whole.id.clone()))
                .collect(),
            None => held
                .into_iter()
                .flat_map(|h| h.keys.into_iter().map(move |k| (k, h.id.clone())))
                .collect(),
        },
        Err(message) => {
            log::warn!("cannot ask the scheduler which jobs are queued ({message}); points of earlier jobs may be submitted again");
            HashMap::new()
        }
    }
}
