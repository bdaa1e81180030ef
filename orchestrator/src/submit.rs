//! Cluster jobs: Slurm or LSF scripts for the points of a study not yet stored. Each job packs
//! several cases into one allocation and runs `nlstudy run --only KEYS` inside it, so the same
//! record store and the same make-style skipping serve the cluster and the workstation.

use crate::jobs::{self, LedgerEntry, Scheduler};
use crate::plan::Planned;
use crate::solver::Solver;
use crate::store::Store;
use crate::study::{Resources, Study};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{SystemTime, UNIX_EPOCH};

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
}

/// Writes the job scripts for the planned points that run (those the solver refuses are named
/// and left out, and so are those of jobs the scheduler still holds), prints one line per job,
/// and submits them unless `dry_run`, recording each job in the study's ledger.
pub fn submit_study(
    study: &Study,
    solver: &Solver,
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
        eprintln!(
            "nlstudy: {} points are in jobs still queued or running ({}); not submitted again",
            planned
                .iter()
                .filter(|p| p.runs() && in_flight.contains_key(&p.key))
                .count(),
            holding.join(", ")
        );
    }
    for p in &refused {
        eprintln!(
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
        println!("study {}: nothing to submit, {why}", study.name);
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
        println!(
            "{} ({} cases): {}",
            job.name,
            job.keys.len(),
            job.script.display()
        );
        if !target.dry_run {
            let id = submit(target.scheduler, &job.script)?;
            let submitted = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            jobs::record(
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
    let entries = jobs::entries(store);
    if entries.is_empty() {
        return HashMap::new();
    }
    let live = match jobs::live_jobs(scheduler) {
        Ok(live) => live,
        Err(message) => {
            eprintln!("nlstudy: warning: cannot ask the scheduler which jobs are queued ({message}); points of earlier jobs may be submitted again");
            return HashMap::new();
        }
    };
    entries
        .into_iter()
        .filter(|e| e.scheduler == scheduler && live.contains_key(&e.id))
        .flat_map(|e| e.keys.into_iter().map(move |k| (k, e.id.clone())))
        .collect()
}

/// What a job runs: the absolute paths it needs (it starts in the scheduler's working
/// directory) and the options of its `nlstudy run`.
pub struct JobCommand {
    pub nlstudy: PathBuf,
    pub nlsolve: PathBuf,
    pub study: PathBuf,
    pub results: PathBuf,
    pub jobs: PathBuf,
    pub retries: usize,
}

/// A written job script.
pub struct Job {
    pub name: String,
    pub script: PathBuf,
    pub keys: Vec<String>,
}

/// Writes one script per pack of runnable points into `command.jobs`.
pub fn write_jobs(
    study_name: &str,
    runnable: &[&Planned],
    scheduler: Scheduler,
    resources: &Resources,
    command: &JobCommand,
) -> std::io::Result<Vec<Job>> {
    std::fs::create_dir_all(&command.jobs)?;
    let per_job = resources.cases_per_job.unwrap_or(runnable.len()).max(1);
    let mut jobs = Vec::new();
    for (k, pack) in runnable.chunks(per_job).enumerate() {
        let name = format!("nlstudy-{study_name}-{k}");
        let keys: Vec<String> = pack.iter().map(|p| p.key.clone()).collect();
        let largest = |field: &str| {
            pack.iter()
                .filter_map(|p| p.case.as_ref().ok()?.get(field)?.as_u64())
                .max()
                .unwrap_or(1) as usize
        };
        let shape = Shape {
            tasks: resources.tasks.unwrap_or(largest("ranks")),
            threads: largest("threads"),
        };
        let script = match scheduler {
            Scheduler::Slurm => slurm(&name, &keys, shape, resources, command),
            Scheduler::Lsf => lsf(&name, &keys, shape, resources, command),
        };
        let extension = match scheduler {
            Scheduler::Slurm => "sbatch",
            Scheduler::Lsf => "bsub",
        };
        let path = command.jobs.join(format!("{name}.{extension}"));
        crate::store::write_atomically(&path, script.as_bytes())?;
        jobs.push(Job {
            name,
            script: path,
            keys,
        });
    }
    Ok(jobs)
}

/// The allocation of one job: MPI tasks and threads per task.
#[derive(Clone, Copy)]
struct Shape {
    tasks: usize,
    threads: usize,
}

fn slurm(name: &str, keys: &[String], shape: Shape, r: &Resources, command: &JobCommand) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let mut directive = |text: String| writeln!(s, "#SBATCH {text}").expect("a String");
    directive(format!("--job-name={name}"));
    directive(format!("--nodes={}", r.nodes.unwrap_or(1)));
    directive(format!("--ntasks={}", shape.tasks));
    directive(format!("--cpus-per-task={}", shape.threads));
    if let Some(time) = &r.time {
        directive(format!("--time={time}"));
    }
    if let Some(queue) = &r.queue {
        directive(format!("--partition={queue}"));
    }
    if let Some(account) = &r.account {
        directive(format!("--account={account}"));
    }
    directive(format!(
        "--output={}",
        command.jobs.join(format!("{name}.%j.out")).display()
    ));
    // Debian's Open MPI 4.1 starts under srun through PMIx (PMI-2 aborts in MPI_Init).
    s + &body(keys, shape, "srun --mpi=pmix -n {ranks}", command)
}

fn lsf(name: &str, keys: &[String], shape: Shape, r: &Resources, command: &JobCommand) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let mut directive = |text: String| writeln!(s, "#BSUB {text}").expect("a String");
    directive(format!("-J {name}"));
    // LSF counts slots: every task's threads.
    directive(format!("-n {}", shape.tasks * shape.threads));
    if let Some(nodes) = r.nodes {
        directive(format!(
            "-R \"span[ptile={}]\"",
            (shape.tasks * shape.threads).div_ceil(nodes)
        ));
    }
    if let Some(time) = &r.time {
        // LSF's -W is [HH:]MM.
        let minutes: Vec<&str> = time.split(':').collect();
        let hh_mm = match minutes.as_slice() {
            [h, m, _] => format!("{h}:{m}"),
            _ => time.clone(),
        };
        directive(format!("-W {hh_mm}"));
    }
    if let Some(queue) = &r.queue {
        directive(format!("-q {queue}"));
    }
    if let Some(account) = &r.account {
        directive(format!("-P {account}"));
    }
    directive(format!(
        "-o {}",
        command.jobs.join(format!("{name}.%J.out")).display()
    ));
    s + &body(keys, shape, "mpirun -n {ranks}", command)
}

/// The commands of a job: run its keys of the study inside the allocation. Jobs of one study
/// may run at once, so none writes the study's tables: `nlstudy collect` does, once they are done.
fn body(keys: &[String], shape: Shape, launcher: &str, command: &JobCommand) -> String {
    let retries = match command.retries {
        0 => String::new(),
        n => format!(" --retries {n}"),
    };
    format!(
        "set -euo pipefail\n{} run {} --results {} --solver {} --launcher '{launcher}' --no-collect{retries} -j {} --only {}\n",
        quote(&command.nlstudy),
        quote(&command.study),
        quote(&command.results),
        quote(&command.nlsolve),
        shape.tasks * shape.threads,
        keys.join(","),
    )
}

/// A path in single quotes for the shell.
fn quote(path: &Path) -> String {
    format!("'{}'", path.display().to_string().replace('\'', r"'\''"))
}

/// Hands a script to the scheduler (`sbatch SCRIPT` or `bsub < SCRIPT`) and returns the job's id.
pub fn submit(scheduler: Scheduler, script: &Path) -> Result<String, String> {
    let (program, output) = match scheduler {
        Scheduler::Slurm => ("sbatch", Command::new("sbatch").arg(script).output()),
        Scheduler::Lsf => (
            "bsub",
            std::fs::File::open(script).and_then(|file| Command::new("bsub").stdin(file).output()),
        ),
    };
    let output = output.map_err(|e| {
        format!("cannot run {program}: {e}; on a machine without the scheduler use --dry-run to write the scripts only")
    })?;
    let printed = String::from_utf8_lossy(&output.stdout);
    print!("{printed}");
    if !output.status.success() {
        return Err(format!(
            "{program} refused {}: {}",
            script.display(),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    jobs::submitted_id(scheduler, &printed).ok_or_else(|| {
        format!(
            "{program} accepted {} but printed no job id: {printed}",
            script.display()
        )
    })
}
