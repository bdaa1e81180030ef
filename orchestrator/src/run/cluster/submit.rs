//! Cluster jobs: Slurm or LSF scripts for the points of a study not yet stored. Each job packs
//! several cases into one allocation and runs `nlstudy run --only KEYS` inside it, so the same
//! record store and the same make-style skipping serve the cluster and the workstation.

use super::ledger::{self, LedgerEntry};
use super::scheduler::{self, Scheduler};
use super::script::{write_jobs, JobCommand};
use crate::model::resources::Resources;
use crate::model::study::Study;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::Planned;
use crate::store::Store;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where and how `nlstudy submit` sends a study: the scheduler, the resources (the study's,
/// overridden by flags), the results directory and study file as given, and whether to stop
/// after writing the scripts.
pub struct Target {
    pub scheduler: Scheduler,
    pub resources: Resources,
    pub results: PathBuf,
    pub study_file: PathBuf,
    pub dry_run: bool,
    /// `nlstudy run --retries` inside each job.
    pub retries: usize,
    /// The MPI launcher inside each job (the scheduler's own when `None`).
    pub launcher: Option<crate::run::pool::Launcher>,
}

/// Writes the job scripts for the planned points that run (those the solver refuses are named
/// and left out, and so are those of jobs the scheduler still holds), prints one line per job,
/// and submits them unless `dry_run`, recording each job in the study's ledger.
pub fn submit_study(
    study: &Study,
    solver: &Nlsolve,
    planned: &[Planned],
    store: &Store,
    target: &Target,
) -> Result<(), String> {
    let in_flight = in_flight(store, target.scheduler);
    let (runnable, refused): (Vec<&Planned>, Vec<&Planned>) = planned
        .iter()
        .filter(|p| p.runs() && !in_flight.contains_key(&p.key))
        .partition(|p| p.case.is_ok());
    let mut holding: Vec<&str> = in_flight.values().map(String::as_str).collect();
    holding.sort_unstable();
    holding.dedup();
    if !holding.is_empty() {
        say!(
            "nlstudy: {} points are in jobs still queued or running ({}); not submitted again",
            planned
                .iter()
                .filter(|p| p.runs() && in_flight.contains_key(&p.key))
                .count(),
            holding.join(", ")
        );
    }
    for p in &refused {
        say!(
            "nlstudy: not submitted, the solver refuses {}: {}",
            p.point.label(),
            p.case.as_ref().err().map_or("", String::as_str)
        );
    }
    if runnable.is_empty() {
        let why = match holding.is_empty() {
            true => "every point is stored",
            false => "every point is stored or in a job still queued or running",
        };
        tell!("study {}: nothing to submit, {why}", study.name);
        return Ok(());
    }
    std::fs::create_dir_all(&target.results)
        .map_err(|e| format!("cannot create {}: {e}", target.results.display()))?;
    let absolute = |path: &Path| {
        std::fs::canonicalize(path).map_err(|e| format!("cannot resolve {}: {e}", path.display()))
    };
    let results = absolute(&target.results)?;
    let command = JobCommand {
        nlstudy: std::env::current_exe().map_err(|e| format!("cannot find nlstudy: {e}"))?,
        nlsolve: absolute(&solver.binary)?,
        study: absolute(&target.study_file)?,
        jobs: results.join(&study.name).join("jobs"),
        results,
        retries: target.retries,
        launcher: target.launcher.clone(),
    };
    let jobs = write_jobs(
        &study.name,
        &runnable,
        target.scheduler,
        &target.resources,
        &command,
    )
    .map_err(|e| format!("cannot write the job scripts: {e}"))?;
    for job in &jobs {
        tell!(
            "{} ({} cases): {}",
            job.name,
            job.keys.len(),
            job.script.display()
        );
        if !target.dry_run {
            let id = scheduler::submit(target.scheduler, &job.script)?;
            tell!("  submitted as job {id}");
            let submitted = super::unix_seconds();
            ledger::add(
                store,
                &LedgerEntry {
                    scheduler: target.scheduler,
                    id,
                    name: job.name.clone(),
                    keys: job.keys.clone(),
                    submitted,
                },
            )?;
        }
    }
    Ok(())
}

/// The keys of the ledger's jobs that the scheduler still holds, each with its job's id. Where
/// the scheduler cannot be asked (a workstation writing scripts), nothing is held.
fn in_flight(store: &Store, scheduler: Scheduler) -> HashMap<String, String> {
    let entries = ledger::entries(store);
    if entries.is_empty() {
        return HashMap::new();
    }
    let live = match scheduler::live_jobs(scheduler) {
        Ok(live) => live,
        Err(message) => {
            say!("nlstudy: warning: cannot ask the scheduler which jobs are queued ({message}); points of earlier jobs may be submitted again");
            return HashMap::new();
        }
    };
    entries
        .into_iter()
        .filter(|e| e.scheduler == scheduler && live.contains_key(&e.id))
        .flat_map(|e| e.keys.into_iter().map(move |k| (k, e.id.clone())))
        .collect()
}
