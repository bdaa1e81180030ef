//! Job scripts: one Slurm or LSF script per submission (a job, or an array whose elements each
//! run a bundle of points), whose directives ask for the allocation and whose body loads the
//! site's modules, runs its prologue, then becomes `nlstudy run --only KEYS` (`exec`, so the
//! warning signal the scheduler sends the batch shell reaches nlstudy, which stops cleanly).

use super::pack::{Pack, Shape};
use super::probes;
use super::scheduler::Scheduler;
use crate::model::launcher::Launcher;
use crate::model::resources::{Resources, WallTime};
use crate::model::site::Site;
use crate::store::fs::{create_dir, Fault, FileError};
use crate::store::write_atomically;
use schema::json::is_unsafe_char;
use std::fmt::Write as _;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};

/// What a job runs: the absolute paths it needs (it starts in the scheduler's working
/// directory) and the options of its `nlstudy run`.
pub struct JobCommand {
    pub nlstudy: PathBuf,
    pub nlsolve: PathBuf,
    pub study: PathBuf,
    pub results: PathBuf,
    pub jobs: PathBuf,
    pub retries: usize,
    /// The MPI launcher inside the job (`submit --launcher`, else the site's); the scheduler's
    /// own by default.
    pub launcher: Option<Launcher>,
    /// The job runs the whole study (no `--only`) and, being its only job, writes its tables.
    pub whole: bool,
    /// The whole study's tables take runs of several hosts or builds (`run --allow-mixed`).
    pub allow_mixed: bool,
}

/// What every script of one submit asks of the scheduler besides its points' allocation.
pub struct Settings<'a> {
    pub scheduler: Scheduler,
    /// The partition, account and nodes (the time limit is each job's own).
    pub resources: &'a Resources,
    pub site: &'a Site,
    /// Whole nodes: the default unless the study shares the machine.
    pub exclusive: bool,
    /// How many elements of an array run at once.
    pub throttle: Option<NonZeroUsize>,
}

/// The warning before the time limit when the site gives none.
const DEFAULT_WARNING_S: u64 = 60;
/// A job is warned only if its limit is at least this many times the warning.
const WARNED_LIMITS: u64 = 4;

/// A written job script.
pub struct Job {
    pub name: String,
    pub script: PathBuf,
    /// The keys of each element (one bundle for a job that is not an array).
    pub bundles: Vec<Vec<String>>,
    pub array: bool,
}

/// Writes one script per pack into `command.jobs`, each with its time limit; the scripts of an
/// earlier submit move to `jobs/archive/` first, so the folder holds only the jobs of this one.
pub fn write_jobs(
    packs: &[(&Pack, Option<WallTime>)],
    settings: &Settings,
    command: &JobCommand,
) -> Result<Vec<Job>, Fault> {
    create_dir(&command.jobs)?;
    archive_earlier_scripts(&command.jobs)?;
    let mut jobs = Vec::new();
    for (pack, time) in packs {
        let bundles: Vec<Vec<String>> = pack
            .bundles
            .iter()
            .map(|b| b.iter().map(|p| p.key.to_string()).collect())
            .collect();
        let path = command
            .jobs
            .join(format!("{}.{}", pack.name, extension(settings.scheduler)));
        // A whole study's job runs every round: it has no probes of one to be handed.
        let probes = probes::beside(&path);
        let handed =
            !command.whole && probes::write(&probes, pack.bundles.iter().flatten().copied())?;
        let job = Spec {
            name: &pack.name,
            bundles: &bundles,
            array: pack.array,
            shape: pack.shape,
            time: *time,
            probes: handed.then_some(probes.as_path()),
        };
        let script = script(&job, settings, command).map_err(Fault::Input)?;
        write_atomically(&path, script.as_bytes())?;
        jobs.push(Job {
            name: pack.name.clone(),
            script: path,
            bundles,
            array: pack.array,
        });
    }
    Ok(jobs)
}

fn extension(scheduler: Scheduler) -> &'static str {
    match scheduler {
        Scheduler::Slurm => "sbatch",
        Scheduler::Lsf => "bsub",
    }
}
/// Moves the job scripts in `jobs`, and their probes, to `jobs/archive/<seconds since the
/// epoch>-<name>`: a script of an earlier submit holds keys this one may no longer have, and is
/// kept, not lost.
fn archive_earlier_scripts(jobs: &Path) -> Result<(), FileError> {
    let script = |p: &Path| p.extension().is_some_and(|x| x == "sbatch" || x == "bsub");
    let earlier: Vec<PathBuf> = std::fs::read_dir(jobs)
        .map_err(FileError::on("read", jobs))?
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .map(|e| e.path())
        .filter(|p| script(p) || probes::is_probes_file(p))
        .collect();
    if earlier.is_empty() {
        return Ok(());
    }
    let archive = jobs.join("archive");
    create_dir(&archive)?;
    let now = super::unix_seconds();
    for path in earlier {
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        let to = archive.join(format!("{now}-{name}"));
        std::fs::rename(&path, &to).map_err(FileError::on("archive", &path))?;
    }
    Ok(())
}

/// One job to render: its name, bundles (one unless an array), allocation and limit.
struct Spec<'a> {
    name: &'a str,
    bundles: &'a [Vec<String>],
    array: bool,
    shape: Shape,
    time: Option<WallTime>,
    /// The file of its points' probes (`probes`), when they are an adaptive study's.
    probes: Option<&'a Path>,
}

/// The whole script of one job. Every value from a study file, a site profile or a flag reaches
/// it either checked against what its directive accepts or quoted; the profile's prologue lines
/// are its own shell code, one line each.
fn script(job: &Spec, settings: &Settings, command: &JobCommand) -> Result<String, String> {
    let (prefix, directives) = match settings.scheduler {
        Scheduler::Slurm => ("#SBATCH", slurm_directives(job, settings, command)?),
        Scheduler::Lsf => ("#BSUB", lsf_directives(job, settings, command)?),
    };
    let site = settings.site;
    let mut text = String::from("#!/bin/bash\n");
    for directive in &directives {
        // The schedulers stop reading directives at the first command: all of them come first.
        writeln!(text, "{prefix} {directive}").expect("a String");
    }
    // Module scripts often read unset variables: `-u` only once they have run.
    text.push_str("set -eo pipefail\n");
    for module in &site.modules {
        writeln!(text, "module load {}", shell_word(&module.0)?).expect("a String");
    }
    for line in &site.prologue {
        writeln!(text, "{}", line.0).expect("a String");
    }
    text.push_str("set -u\n");
    if settings.scheduler == Scheduler::Slurm {
        // A launcher of the user's without `-c`: since Slurm 22.05 srun takes the job's
        // --cpus-per-task only from this.
        text.push_str("export SRUN_CPUS_PER_TASK=\"${SLURM_CPUS_PER_TASK:-1}\"\n");
    }
    let keys = match job.array {
        false => shell_word(&job.bundles[0].join(","))?,
        true => {
            text.push_str("bundles=(\n");
            for bundle in job.bundles {
                writeln!(text, "{}", shell_word(&bundle.join(","))?).expect("a String");
            }
            text.push_str(")\n");
            match settings.scheduler {
                Scheduler::Slurm => "\"${bundles[$SLURM_ARRAY_TASK_ID]}\"".to_string(),
                Scheduler::Lsf => "\"${bundles[$((LSB_JOBINDEX - 1))]}\"".to_string(),
            }
        }
    };
    let launcher = command.launcher.as_ref().map_or(
        default_launcher(settings.scheduler).to_string(),
        Launcher::text,
    );
    text.push_str(&body(&keys, job, &launcher, command)?);
    Ok(text)
}

/// The launcher of MPI cases when neither `--launcher` nor the site names one. Each rank asks
/// for its threads' cores: since Slurm 22.05 a step no longer inherits the job's
/// `--cpus-per-task`, so without `-c` two threads of a rank could share one core; Open MPI under
/// LSF maps each rank to `{threads}` cores of its slots.
fn default_launcher(scheduler: Scheduler) -> &'static str {
    match scheduler {
        // Debian's Open MPI 4.1 starts under srun through PMIx (PMI-2 aborts in MPI_Init).
        Scheduler::Slurm => "srun --mpi=pmix -n {ranks} -c {threads}",
        Scheduler::Lsf => "mpirun -n {ranks} --map-by slot:PE={threads} --bind-to core",
    }
}

/// Seconds before the limit at which the job is warned: the site's or a minute; none for a
/// limit under `WARNED_LIMITS` × that, since Slurm may send it up to a minute early and a short
/// job would be stopped at its start.
fn warning_s(job: &Spec, site: &Site) -> Option<u64> {
    let warning = site.warning.map_or(DEFAULT_WARNING_S, |w| w.seconds());
    match job.time {
        Some(limit) if limit.seconds() < WARNED_LIMITS * warning.max(DEFAULT_WARNING_S) => None,
        _ => Some(warning),
    }
}

fn slurm_directives(
    job: &Spec,
    settings: &Settings,
    command: &JobCommand,
) -> Result<Vec<String>, String> {
    let (r, site) = (settings.resources, settings.site);
    let mut d = vec![format!("--job-name={}", job.name)];
    if job.array {
        let throttle = settings.throttle.map_or(String::new(), |t| format!("%{t}"));
        d.push(format!("--array=0-{}{throttle}", job.bundles.len() - 1));
    }
    d.push(format!("--nodes={}", job.shape.nodes));
    d.push(format!("--ntasks={}", job.shape.tasks));
    d.push(format!("--cpus-per-task={}", job.shape.threads));
    if let Some(time) = job.time {
        d.push(format!("--time={}", time.slurm()));
    }
    if let Some(queue) = &r.queue {
        d.push(format!("--partition={queue}"));
    }
    if let Some(account) = &r.account {
        d.push(format!("--account={account}"));
    }
    if let Some(qos) = &site.qos {
        d.push(format!("--qos={qos}"));
    }
    if let Some(constraint) = &site.constraint {
        d.push(format!("--constraint={}", constraint.0));
    }
    if settings.exclusive {
        d.push("--exclusive".into());
    }
    match site.memory.map(|m| m.megabytes) {
        // Slurm's "all of the node's memory".
        Some(0) => d.push("--mem=0".into()),
        Some(megabytes) => d.push(format!("--mem={megabytes}M")),
        None => {}
    }
    let log = match job.array {
        false => format!("{}.%j.out", job.name),
        true => format!("{}.%A_%a.out", job.name),
    };
    d.push(format!("--output={}", directive_path(&command.jobs, &log)?));
    // A requeued job appends to its log rather than erasing the first run's.
    d.push("--open-mode=append".into());
    if let Some(warning) = warning_s(job, site) {
        d.push(format!("--signal=B:TERM@{warning}"));
    }
    d.push(match site.requeue.unwrap_or(true) {
        true => "--requeue".into(),
        false => "--no-requeue".into(),
    });
    d.extend(site.directives.iter().map(|x| x.0.clone()));
    Ok(d)
}

fn lsf_directives(
    job: &Spec,
    settings: &Settings,
    command: &JobCommand,
) -> Result<Vec<String>, String> {
    let (r, site) = (settings.resources, settings.site);
    let mut d = vec![match job.array {
        false => format!("-J {}", job.name),
        true => {
            let throttle = settings.throttle.map_or(String::new(), |t| format!("%{t}"));
            format!("-J \"{}[1-{}]{throttle}\"", job.name, job.bundles.len())
        }
    }];
    // LSF counts slots: one per core when each task runs one thread; with more, one per task,
    // whose `affinity[core(threads)]` gives it that many cores of its own (with an affinity
    // request LSF reads -n as tasks, and -n of every core would ask threads² per task).
    let slots = match job.shape.threads {
        1 => job.shape.cores(),
        threads => {
            d.push(format!("-n {}", job.shape.tasks));
            d.push(format!("-R \"affinity[core({threads})]\""));
            job.shape.tasks
        }
    };
    if job.shape.threads == 1 {
        d.push(format!("-n {slots}"));
    }
    match job.shape.nodes {
        // A job of one node: its slots may not spread over hosts.
        1 => d.push("-R \"span[hosts=1]\"".into()),
        nodes => d.push(format!("-R \"span[ptile={}]\"", slots.div_ceil(nodes))),
    }
    if let Some(time) = job.time {
        d.push(format!("-W {}", time.lsf()));
    }
    if let Some(queue) = &r.queue {
        d.push(format!("-q {queue}"));
    }
    if let Some(account) = &r.account {
        d.push(format!("-P {account}"));
    }
    if settings.exclusive {
        d.push("-x".into());
    }
    // `0` (Slurm's "all of it") has no LSF form: an exclusive job has the node's memory.
    if let Some(memory) = site.memory.filter(|m| m.megabytes > 0) {
        d.push(format!("-R \"rusage[mem={}]\"", memory.megabytes));
    }
    let log = match job.array {
        false => format!("{}.%J.out", job.name),
        true => format!("{}.%J_%I.out", job.name),
    };
    d.push(format!("-o {}", directive_path(&command.jobs, &log)?));
    if let Some(warning) = warning_s(job, site) {
        d.push("-wa TERM".into());
        d.push(format!("-wt {}", warning.div_ceil(60)));
    }
    if site.requeue.unwrap_or(true) {
        d.push("-r".into());
    }
    d.extend(site.directives.iter().map(|x| x.0.clone()));
    Ok(d)
}

/// The command of a job: run its keys of the study inside the allocation, every argument a
/// quoted shell word (`keys` is one already: a bundle, or the array's element of them). Jobs of
/// one study may run at once, so none writes the study's tables: `nlstudy collect` does, once
/// they are done. A job of the whole study runs all of it, every round, and writes them.
fn body(keys: &str, job: &Spec, launcher: &str, command: &JobCommand) -> Result<String, String> {
    let shape = job.shape;
    let mut words = vec![
        "exec".to_string(),
        path_word(&command.nlstudy)?,
        "run".into(),
        path_word(&command.study)?,
        "--results".into(),
        path_word(&command.results)?,
        "--solver".into(),
        path_word(&command.nlsolve)?,
        "--launcher".into(),
        shell_word(launcher)?,
    ];
    if !command.whole {
        words.push("--no-collect".into());
    }
    if command.retries > 0 {
        words.extend(["--retries".into(), command.retries.to_string()]);
    }
    // A whole study on several nodes uses every core the allocation gives each node, which
    // `run` reads from the job (a step per case on every node).
    if !(command.whole && shape.nodes > 1) {
        words.extend(["-j".into(), shape.cores().to_string()]);
    }
    if command.whole && (command.allow_mixed || shape.nodes > 1) {
        words.push("--allow-mixed".into());
    }
    if !command.whole {
        words.extend(["--only".into(), keys.to_string()]);
    }
    if let Some(probes) = job.probes {
        words.extend(["--probes".into(), path_word(probes)?]);
    }
    Ok(words.join(" ") + "\n")
}

/// `text` as one shell word, quoted by shlex (as the launcher is split). Control characters
/// are refused: a job script is no place for them.
fn shell_word(text: &str) -> Result<String, String> {
    if let Some(c) = text.chars().find(|&c| is_unsafe_char(c)) {
        return Err(format!(
            "{text:?} holds {}, which a job script does not carry",
            schema::json::describe_char(c)
        ));
    }
    shlex::try_quote(text)
        .map(String::from)
        .map_err(|e| format!("{text:?} cannot be one shell word: {e}"))
}

/// A path as one shell word (see `shell_word`); it must be UTF-8.
fn path_word(path: &Path) -> Result<String, String> {
    let text = path.to_str().ok_or_else(|| {
        format!(
            "the path {} is not UTF-8, which a job script does not carry",
            path.display()
        )
    })?;
    shell_word(text).map_err(|e| format!("the path {}: {e}", path.display()))
}

/// The file `name` of the folder `dir` in a directive, in double quotes as sbatch and bsub read
/// them. Those read no escapes and replace `%j`-like patterns, so a folder holding `"`, `\`, `%`
/// or a control character is refused rather than changed.
fn directive_path(dir: &Path, name: &str) -> Result<String, String> {
    let text = dir.to_str().unwrap_or("\u{0}");
    match text.chars().find(|&c| is_unsafe_char(c) || "\"\\%".contains(c)) {
        Some(c) => Err(format!(
            "the job output folder {} holds {c:?}, which a scheduler directive cannot carry; choose a results directory (--results) without it",
            dir.display()
        )),
        None => Ok(format!("\"{}\"", dir.join(name).display())),
    }
}

#[cfg(test)]
mod tests;
