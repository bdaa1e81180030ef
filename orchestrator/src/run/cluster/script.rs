//! Job scripts: one Slurm or LSF script per submission (a job, or an array whose elements each
//! run a bundle of points), whose directives ask for the allocation and whose body loads the
//! site's modules, runs its prologue, then becomes `nlstudy run --only KEYS` (`exec`, so the
//! warning signal the scheduler sends the batch shell reaches nlstudy, which stops cleanly).

use super::pack::{Pack, Shape};
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
        let job = Spec {
            name: &pack.name,
            bundles: &bundles,
            array: pack.array,
            shape: pack.shape,
            time: *time,
        };
        let script = script(&job, settings, command)?;
        let path = command
            .jobs
            .join(format!("{}.{}", pack.name, extension(settings.scheduler)));
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
/// Moves the job scripts in `jobs` to `jobs/archive/<seconds since the epoch>-<name>`: a
/// script of an earlier submit holds keys this one may no longer have, and is kept, not lost.
fn archive_earlier_scripts(jobs: &Path) -> Result<(), FileError> {
    let earlier: Vec<PathBuf> = std::fs::read_dir(jobs)
        .map_err(FileError::on("read", jobs))?
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "sbatch" || x == "bsub"))
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
    text.push_str(&body(&keys, job.shape, &launcher, command)?);
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
/// they are done.
fn body(keys: &str, shape: Shape, launcher: &str, command: &JobCommand) -> Result<String, String> {
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
        "--no-collect".into(),
    ];
    if command.retries > 0 {
        words.extend(["--retries".into(), command.retries.to_string()]);
    }
    words.extend([
        "-j".into(),
        shape.cores().to_string(),
        "--only".into(),
        keys.to_string(),
    ]);
    Ok(words.join(" ") + "\n")
}

/// `text` as one shell word: in single quotes, each `'` closed, escaped and reopened. Control
/// characters are refused: a job script is no place for them.
fn shell_word(text: &str) -> Result<String, String> {
    if let Some(c) = text.chars().find(|&c| is_unsafe_char(c)) {
        return Err(format!(
            "{text:?} holds {}, which a job script does not carry",
            schema::json::describe_char(c)
        ));
    }
    Ok(format!("'{}'", text.replace('\'', r"'\''")))
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
mod tests {
    use super::*;
    use crate::model::resources::SchedulerName;
    use std::process::Command;
    use std::str::FromStr;

    /// Strings a hostile study file or flag might carry.
    const HOSTILE: &[&str] = &[
        "debug\ntouch MARK",
        "x; touch MARK",
        "$(touch MARK)",
        "`touch MARK`",
        "a' ; touch MARK; '",
        "a\" ; touch MARK; \"",
        "a\\\ntouch MARK",
        "x\r\ntouch MARK",
        "a b",
        "q # comment",
        "%j",
        "\u{1b}]0;title\u{7}",
    ];

    const SCHEDULERS: [Scheduler; 2] = [Scheduler::Slurm, Scheduler::Lsf];

    fn sandbox(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("script-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Runs the script at `path` with bash in `dir` (and `env`), asserting it succeeds.
    fn run_script(path: &Path, dir: &Path, env: &[(&str, String)]) {
        let run = Command::new("bash")
            .arg(path)
            .current_dir(dir)
            .envs(env.iter().map(|(k, v)| (k, v)))
            .output()
            .unwrap();
        let text = std::fs::read_to_string(path).unwrap();
        assert!(
            run.status.success(),
            "{text}\n{}",
            String::from_utf8_lossy(&run.stderr)
        );
    }

    /// A stub `nlstudy` at `path` that writes its arguments, one per line, to `args`.
    fn stub(path: &Path, args: &Path) {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let quoted = shell_word(args.to_str().unwrap()).unwrap();
        let text = format!("#!/bin/bash\nprintf '%s\\n' \"$@\" > {quoted}\n");
        std::fs::write(path, text).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    #[test]
    fn hostile_resource_values_are_refused_naming_the_field_and_the_flag() {
        for value in HOSTILE {
            for field in ["queue", "account", "time"] {
                let study = format!(
                    r#"{{"name": "s", "base": {{}}, "resources": {{"{field}": {}}}}}"#,
                    serde_json::Value::from(*value)
                );
                let accepted = crate::model::study::Study::parse(&study);
                let safe_anyway = field != "time" && SchedulerName::from_str(value).is_ok();
                match accepted {
                    Ok(_) => assert!(safe_anyway, "resources.{field} = {value:?} accepted"),
                    Err(e) => assert!(e.to_string().contains(&format!("resources.{field}")), "{e}"),
                }
            }
            assert!(WallTime::from_str(value).is_err());
            assert!(SchedulerName::from_str(value).is_err(), "{value:?}");
        }
    }

    /// Every path and argument a script carries, each with a hostile value in turn: either the
    /// script is refused with a sentence, or it passes `bash -n`, has only the directives it
    /// should (all before the first command), and run by bash it executes nothing but the stub
    /// `nlstudy`, which receives exactly the job's arguments.
    #[test]
    fn hostile_paths_and_values_never_reach_a_shell_unquoted() {
        let root = sandbox("hostile");
        let resources = Resources {
            nodes: NonZeroUsize::new(2),
            tasks: NonZeroUsize::new(2),
            time: None,
            queue: Some(SchedulerName::from_str("debug").unwrap()),
            account: Some(SchedulerName::from_str("proj-1").unwrap()),
            cases_per_job: NonZeroUsize::new(3),
        };
        let shape = Shape {
            nodes: 2,
            tasks: 2,
            threads: 2,
        };
        let mut ran = 0;
        for (v, value) in HOSTILE.iter().enumerate() {
            for slot in 0..5 {
                let case = root.join(format!("{v}-{slot}"));
                let args = case.join("args");
                let mut dirs = [
                    case.join("bin"),
                    case.join("study"),
                    case.join("results"),
                    case.join("solver"),
                ];
                if slot < 4 {
                    dirs[slot] = dirs[slot].join(value);
                }
                let keys = match slot {
                    4 => vec!["00ff".to_string(), value.to_string()],
                    _ => vec!["00ff".to_string(), "11ee".to_string()],
                };
                let command = JobCommand {
                    nlstudy: dirs[0].join("nlstudy"),
                    study: dirs[1].join("s.json"),
                    results: dirs[2].clone(),
                    jobs: dirs[2].join("s").join("jobs"),
                    nlsolve: dirs[3].join("nlsolve"),
                    retries: 1,
                    launcher: None,
                };
                for scheduler in SCHEDULERS {
                    let job = Spec {
                        name: "nlstudy-s-0",
                        bundles: std::slice::from_ref(&keys),
                        array: false,
                        shape,
                        time: Some(WallTime::from_str("1-00:30:00").unwrap()),
                    };
                    let settings = Settings {
                        scheduler,
                        resources: &resources,
                        site: &Site::default(),
                        exclusive: true,
                        throttle: None,
                    };
                    let Ok(text) = script(&job, &settings, &command) else {
                        let has_control = value.chars().any(is_unsafe_char);
                        let refused_in_directive = slot == 2 && value.contains(['"', '\\', '%']);
                        assert!(
                            has_control || refused_in_directive,
                            "{value:?} in slot {slot} refused"
                        );
                        continue;
                    };
                    check_structure(scheduler, &text);
                    std::fs::create_dir_all(&case).unwrap();
                    let path = case.join("job.sh");
                    std::fs::write(&path, &text).unwrap();
                    let syntax = Command::new("bash").arg("-n").arg(&path).status().unwrap();
                    assert!(syntax.success(), "bash -n refuses:\n{text}");
                    stub(&command.nlstudy, &args);
                    run_script(&path, &case, &[]);
                    let got = std::fs::read_to_string(&args).unwrap();
                    let expected = [
                        "run",
                        command.study.to_str().unwrap(),
                        "--results",
                        command.results.to_str().unwrap(),
                        "--solver",
                        command.nlsolve.to_str().unwrap(),
                        "--launcher",
                        default_launcher(scheduler),
                        "--no-collect",
                        "--retries",
                        "1",
                        "-j",
                        "4",
                        "--only",
                        &keys.join(","),
                    ];
                    assert_eq!(got, expected.join("\n") + "\n", "{text}");
                    let marks: Vec<_> = walk(&root)
                        .into_iter()
                        .filter(|p| p.file_name().is_some_and(|n| n == "MARK"))
                        .collect();
                    assert!(marks.is_empty(), "{value:?} ran a command:\n{text}");
                    std::fs::remove_file(&args).unwrap();
                    ran += 1;
                }
            }
        }
        assert!(ran > 60, "only {ran} scripts ran");
        let _ = std::fs::remove_dir_all(&root);
    }

    /// `submit --launcher` reaches the job's `nlstudy run` as one argument that splits back
    /// into the launcher's words, whatever they hold; an LSF job on one node keeps its slots on
    /// one host.
    #[test]
    fn a_sites_launcher_reaches_the_job_whole_and_lsf_keeps_a_job_on_one_host() {
        let root = sandbox("launcher");
        let given = "env \"A=$(touch MARK) b\" srun --mpi=pmi2 -n {ranks}";
        let launcher: Launcher = given.parse().unwrap();
        let command = JobCommand {
            nlstudy: root.join("bin/nlstudy"),
            study: root.join("s.json"),
            results: root.join("results"),
            jobs: root.join("results/s/jobs"),
            nlsolve: root.join("bin/nlsolve"),
            retries: 0,
            launcher: Some(launcher),
        };
        let job = Spec {
            name: "j",
            bundles: &[vec!["00ff".to_string()]],
            array: false,
            shape: Shape {
                nodes: 1,
                tasks: 1,
                threads: 2,
            },
            time: None,
        };
        for scheduler in SCHEDULERS {
            let settings = Settings {
                scheduler,
                resources: &Resources::default(),
                site: &Site::default(),
                exclusive: false,
                throttle: None,
            };
            let text = script(&job, &settings, &command).unwrap();
            if scheduler == Scheduler::Lsf {
                assert!(
                    text.contains(
                        "#BSUB -n 1\n#BSUB -R \"affinity[core(2)]\"\n#BSUB -R \"span[hosts=1]\"\n"
                    ),
                    "each task's threads on cores of their own, on one host: {text}"
                );
            }
            let path = root.join("job.sh");
            std::fs::write(&path, &text).unwrap();
            let args = root.join("args");
            stub(&command.nlstudy, &args);
            run_script(&path, &root, &[]);
            let got = std::fs::read_to_string(&args).unwrap();
            let lines: Vec<&str> = got.lines().collect();
            let at = lines.iter().position(|l| *l == "--launcher").unwrap();
            assert_eq!(
                shlex::split(lines[at + 1]).unwrap(),
                shlex::split(given).unwrap(),
                "{text}"
            );
            assert!(
                !root.join("MARK").exists(),
                "the launcher ran a command:\n{text}"
            );
        }
        let _ = std::fs::remove_dir_all(&root);
    }

    /// Every field of a site profile lands in both schedulers' scripts in its place: checked
    /// values as directives, modules as quoted words, the prologue as its own lines before the
    /// command; and the script still runs only the stub with the job's arguments.
    #[test]
    fn every_site_profile_field_lands_in_both_schedulers_scripts() {
        let root = sandbox("site");
        let profile = |scheduler: &str, slurm_only: &str| {
            format!(
                r#"
                scheduler = "{scheduler}"
                queue = "compute"
                account = "proj42"
                {slurm_only}
                exclusive = true
                memory = "4G"
                cores_per_node = 4
                time = "01:00:00"
                warning = "00:02:00"
                requeue = false
                launcher = "srun --mpi=pmi2 -n {{ranks}}"
                modules = ["openmpi/4.1.6", "gcc@12"]
                prologue = ["export SITE_MARK=1 # a comment", "test -n \"$SITE_MARK\""]
                directives = ["--hint=nomultithread"]
                "#
            )
        };
        let command = |site: &Site| JobCommand {
            nlstudy: root.join("bin/nlstudy"),
            study: root.join("s.json"),
            results: root.join("results"),
            jobs: root.join("results/s/jobs"),
            nlsolve: root.join("bin/nlsolve"),
            retries: 0,
            launcher: site.launcher.clone(),
        };
        let job = Spec {
            name: "nlstudy-s-0",
            bundles: &[vec!["00ff".to_string()]],
            array: false,
            shape: Shape {
                nodes: 2,
                tasks: 2,
                threads: 3,
            },
            time: Some(WallTime::from_str("00:10:00").unwrap()),
        };
        let cases = [
            (
                Scheduler::Slurm,
                profile("slurm", "qos = \"normal\"\nconstraint = \"cpu&ib\""),
                &[
                    "#SBATCH --nodes=2",
                    "#SBATCH --time=00:10:00",
                    "#SBATCH --partition=compute",
                    "#SBATCH --account=proj42",
                    "#SBATCH --qos=normal",
                    "#SBATCH --constraint=cpu&ib",
                    "#SBATCH --exclusive",
                    "#SBATCH --mem=4096M",
                    "#SBATCH --signal=B:TERM@120",
                    "#SBATCH --no-requeue",
                    "#SBATCH --hint=nomultithread",
                ][..],
            ),
            (
                Scheduler::Lsf,
                profile("lsf", ""),
                &[
                    // Two tasks of three threads: two slots, each three cores of its own.
                    "#BSUB -n 2",
                    "#BSUB -R \"affinity[core(3)]\"",
                    "#BSUB -R \"span[ptile=1]\"",
                    "#BSUB -W 0:10",
                    "#BSUB -q compute",
                    "#BSUB -P proj42",
                    "#BSUB -x",
                    "#BSUB -R \"rusage[mem=4096]\"",
                    "#BSUB -wa TERM",
                    "#BSUB -wt 2",
                    "#BSUB --hint=nomultithread",
                ][..],
            ),
        ];
        for (scheduler, toml, directives) in cases {
            let site = Site::parse(&toml, true).unwrap();
            let settings = Settings {
                scheduler,
                resources: &site.defaults(),
                site: &site,
                exclusive: site.exclusive.unwrap(),
                throttle: None,
            };
            let command = command(&site);
            let text = script(&job, &settings, &command).unwrap();
            for directive in directives {
                assert!(
                    text.contains(&format!("{directive}\n")),
                    "{directive}:\n{text}"
                );
            }
            assert!(
                !text.contains("#SBATCH --requeue\n") && !text.contains("#BSUB -r\n"),
                "requeue = false: {text}"
            );
            let after = |line: &str| text.lines().position(|l| l == line).unwrap();
            assert!(
                after("module load 'openmpi/4.1.6'") < after("module load 'gcc@12'")
                    && after("module load 'gcc@12'") < after("export SITE_MARK=1 # a comment")
                    && after("test -n \"$SITE_MARK\"") < after("set -u"),
                "{text}"
            );
            // Run with a `module` that records its arguments: the job loads both, then runs.
            let path = root.join("job.sh");
            let module = root.join("modules");
            let text = text.replacen(
                "set -eo pipefail\n",
                &format!(
                    "set -eo pipefail\nmodule() {{ echo \"$*\" >> {}; }}\n",
                    shell_word(module.to_str().unwrap()).unwrap()
                ),
                1,
            );
            std::fs::write(&path, &text).unwrap();
            let args = root.join("args");
            stub(&command.nlstudy, &args);
            run_script(&path, &root, &[]);
            assert_eq!(
                std::fs::read_to_string(&module).unwrap(),
                "load openmpi/4.1.6\nload gcc@12\n"
            );
            let got = std::fs::read_to_string(&args).unwrap();
            assert!(got.ends_with("-j\n6\n--only\n00ff\n"), "{got}");
            let lines: Vec<&str> = got.lines().collect();
            let at = lines.iter().position(|l| *l == "--launcher").unwrap();
            assert_eq!(
                shlex::split(lines[at + 1]).unwrap(),
                ["srun", "--mpi=pmi2", "-n", "{ranks}"],
                "the site's launcher"
            );
            std::fs::remove_file(&module).unwrap();
        }
        let _ = std::fs::remove_dir_all(&root);
    }

    /// An array's element runs its own bundle: Slurm's index from 0, LSF's from 1.
    #[test]
    fn each_array_element_runs_its_own_bundle() {
        let root = sandbox("array");
        let command = JobCommand {
            nlstudy: root.join("bin/nlstudy"),
            study: root.join("s.json"),
            results: root.join("results"),
            jobs: root.join("results/s/jobs"),
            nlsolve: root.join("bin/nlsolve"),
            retries: 0,
            launcher: None,
        };
        let bundles = [
            vec!["aa".to_string(), "bb".to_string()],
            vec!["cc".to_string()],
            vec!["dd".to_string()],
        ];
        let job = Spec {
            name: "nlstudy-s-0",
            bundles: &bundles,
            array: true,
            shape: Shape {
                nodes: 1,
                tasks: 1,
                threads: 1,
            },
            time: None,
        };
        let args = root.join("args");
        stub(&command.nlstudy, &args);
        for (scheduler, directive, index, first) in [
            (
                Scheduler::Slurm,
                "#SBATCH --array=0-2%2",
                "SLURM_ARRAY_TASK_ID",
                0,
            ),
            (
                Scheduler::Lsf,
                "#BSUB -J \"nlstudy-s-0[1-3]%2\"",
                "LSB_JOBINDEX",
                1,
            ),
        ] {
            let settings = Settings {
                scheduler,
                resources: &Resources::default(),
                site: &Site::default(),
                exclusive: false,
                throttle: NonZeroUsize::new(2),
            };
            let text = script(&job, &settings, &command).unwrap();
            assert!(text.contains(directive), "{text}");
            let path = root.join("job.sh");
            std::fs::write(&path, &text).unwrap();
            for (element, bundle) in bundles.iter().enumerate() {
                run_script(&path, &root, &[(index, (element + first).to_string())]);
                let got = std::fs::read_to_string(&args).unwrap();
                assert!(
                    got.ends_with(&format!("--only\n{}\n", bundle.join(","))),
                    "{got}"
                );
            }
        }
        let _ = std::fs::remove_dir_all(&root);
    }

    /// A shebang, then only directives (one option each), then the shell options and one
    /// command: no line a value could have added.
    fn check_structure(scheduler: Scheduler, text: &str) {
        let prefix = match scheduler {
            Scheduler::Slurm => "#SBATCH ",
            Scheduler::Lsf => "#BSUB ",
        };
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "#!/bin/bash");
        let directives = lines[1..]
            .iter()
            .take_while(|l| l.starts_with(prefix))
            .count();
        // Slurm's steps take the job's cores per task from SRUN_CPUS_PER_TASK.
        let (expected, exported) = match scheduler {
            Scheduler::Slurm => (12, 1),
            Scheduler::Lsf => (12, 0),
        };
        assert_eq!(directives, expected, "{text}");
        assert_eq!(
            &lines[1 + directives..][..2],
            ["set -eo pipefail", "set -u"],
            "{text}"
        );
        if exported == 1 {
            assert_eq!(
                lines[directives + 3],
                "export SRUN_CPUS_PER_TASK=\"${SLURM_CPUS_PER_TASK:-1}\""
            );
        }
        assert_eq!(lines.len(), directives + 4 + exported, "{text}");
        assert!(
            lines[directives + 3 + exported].starts_with("exec "),
            "{text}"
        );
    }

    fn walk(dir: &Path) -> Vec<PathBuf> {
        let mut found = Vec::new();
        for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let path = entry.path();
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                found.extend(walk(&path));
            }
            found.push(path);
        }
        found
    }

    #[test]
    fn an_earlier_submits_scripts_are_archived_not_left_beside_the_new_ones() {
        let root = sandbox("archive");
        let jobs = root.join("jobs");
        std::fs::create_dir_all(&jobs).unwrap();
        std::fs::write(jobs.join("nlstudy-s-0.sbatch"), "old").unwrap();
        std::fs::write(jobs.join("nlstudy-s-0.42.out"), "log").unwrap();
        archive_earlier_scripts(&jobs).unwrap();
        assert!(!jobs.join("nlstudy-s-0.sbatch").exists());
        assert!(jobs.join("nlstudy-s-0.42.out").exists(), "job output stays");
        let archived: Vec<_> = std::fs::read_dir(jobs.join("archive"))
            .unwrap()
            .flatten()
            .collect();
        assert_eq!(archived.len(), 1);
        let _ = std::fs::remove_dir_all(&root);
    }
}
