//! Job scripts: one Slurm or LSF script per pack of points, whose directives ask for the
//! allocation and whose body runs `nlstudy run --only KEYS` inside it.

use super::scheduler::Scheduler;
use crate::model::resources::Resources;
use crate::run::plan::Planned;
use crate::store::fs::{create_dir, FileError};
use crate::store::write_atomically;
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
    /// The MPI launcher inside the job (`submit --launcher`); the scheduler's own by default.
    pub launcher: Option<crate::run::pool::Launcher>,
}

/// A written job script.
pub struct Job {
    pub name: String,
    pub script: PathBuf,
    pub keys: Vec<String>,
}

/// Writes one script per pack of runnable points into `command.jobs`; the scripts of an earlier
/// submit move to `jobs/archive/` first, so the folder holds only the jobs of this one.
pub fn write_jobs(
    study_name: &str,
    runnable: &[&Planned],
    scheduler: Scheduler,
    resources: &Resources,
    command: &JobCommand,
) -> Result<Vec<Job>, String> {
    create_dir(&command.jobs)?;
    archive_earlier_scripts(&command.jobs)?;
    let per_job = resources
        .cases_per_job
        .map_or(runnable.len(), NonZeroUsize::get)
        .max(1);
    let mut jobs = Vec::new();
    for (k, pack) in runnable.chunks(per_job).enumerate() {
        let name = format!("nlstudy-{study_name}-{k}");
        let keys: Vec<String> = pack.iter().map(|p| p.key.clone()).collect();
        let largest = |field: &str| {
            pack.iter()
                .filter_map(|p| p.case.as_ref().ok()?.resolved.get(field)?.as_u64())
                .max()
                .unwrap_or(1)
                .max(1) as usize
        };
        let shape = Shape {
            tasks: resources.tasks.map_or(largest("ranks"), NonZeroUsize::get),
            threads: largest("threads"),
        };
        let script = script(scheduler, &name, &keys, shape, resources, command)?;
        let path = command
            .jobs
            .join(format!("{name}.{}", extension(scheduler)));
        write_atomically(&path, script.as_bytes())?;
        jobs.push(Job {
            name,
            script: path,
            keys,
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
fn archive_earlier_scripts(jobs: &Path) -> Result<(), String> {
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

/// The allocation of one job: MPI tasks and threads per task.
#[derive(Clone, Copy)]
struct Shape {
    tasks: usize,
    threads: usize,
}

/// The whole script of one job. Every value from a study file or a flag reaches it either
/// checked against what its directive accepts (`Resources` holds only such values) or quoted.
fn script(
    scheduler: Scheduler,
    name: &str,
    keys: &[String],
    shape: Shape,
    r: &Resources,
    command: &JobCommand,
) -> Result<String, String> {
    let mut directives: Vec<String> = Vec::new();
    let (prefix, launcher) = match scheduler {
        Scheduler::Slurm => {
            directives.push(format!("--job-name={name}"));
            directives.push(format!("--nodes={}", r.nodes.map_or(1, NonZeroUsize::get)));
            directives.push(format!("--ntasks={}", shape.tasks));
            directives.push(format!("--cpus-per-task={}", shape.threads));
            if let Some(time) = r.time {
                directives.push(format!("--time={}", time.slurm()));
            }
            if let Some(queue) = &r.queue {
                directives.push(format!("--partition={queue}"));
            }
            if let Some(account) = &r.account {
                directives.push(format!("--account={account}"));
            }
            directives.push(format!(
                "--output={}",
                directive_path(&command.jobs, &format!("{name}.%j.out"))?
            ));
            // Debian's Open MPI 4.1 starts under srun through PMIx (PMI-2 aborts in MPI_Init).
            ("#SBATCH", "srun --mpi=pmix -n {ranks}")
        }
        Scheduler::Lsf => {
            directives.push(format!("-J {name}"));
            // LSF counts slots: every task's threads.
            let slots = shape.tasks * shape.threads;
            directives.push(format!("-n {slots}"));
            match r.nodes {
                Some(nodes) => {
                    let per_node = slots.div_ceil(nodes.get());
                    directives.push(format!("-R \"span[ptile={per_node}]\""));
                }
                // A job of threads on one node: its slots may not spread over hosts.
                None => directives.push("-R \"span[hosts=1]\"".to_string()),
            }
            if let Some(time) = r.time {
                directives.push(format!("-W {}", time.lsf()));
            }
            if let Some(queue) = &r.queue {
                directives.push(format!("-q {queue}"));
            }
            if let Some(account) = &r.account {
                directives.push(format!("-P {account}"));
            }
            let output = directive_path(&command.jobs, &format!("{name}.%J.out"))?;
            directives.push(format!("-o {output}"));
            ("#BSUB", "mpirun -n {ranks}")
        }
    };
    let mut text = String::from("#!/bin/bash\n");
    for directive in &directives {
        // Slurm stops reading directives at the first command: all of them come first.
        writeln!(text, "{prefix} {directive}").expect("a String");
    }
    text.push_str("set -euo pipefail\n");
    let launcher = command
        .launcher
        .as_ref()
        .map_or(launcher.to_string(), |l| l.text());
    text.push_str(&body(keys, shape, &launcher, command)?);
    Ok(text)
}

/// The command of a job: run its keys of the study inside the allocation, every argument a
/// quoted shell word. Jobs of one study may run at once, so none writes the study's tables:
/// `nlstudy collect` does, once they are done.
fn body(
    keys: &[String],
    shape: Shape,
    launcher: &str,
    command: &JobCommand,
) -> Result<String, String> {
    let mut words = vec![
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
        (shape.tasks * shape.threads).to_string(),
        "--only".into(),
        shell_word(&keys.join(","))?,
    ]);
    Ok(words.join(" ") + "\n")
}

/// `text` as one shell word: in single quotes, each `'` closed, escaped and reopened. Control
/// characters are refused: a job script is no place for them.
fn shell_word(text: &str) -> Result<String, String> {
    if let Some(c) = text.chars().find(|c| c.is_control()) {
        return Err(format!(
            "{text:?} holds the control character {c:?}, which a job script does not carry"
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
    match text.chars().find(|c| c.is_control() || "\"\\%".contains(*c)) {
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
    use crate::model::resources::{SchedulerName, WallTime};
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
            time: Some(WallTime::from_str("1-00:30:00").unwrap()),
            queue: Some(SchedulerName::from_str("debug").unwrap()),
            account: Some(SchedulerName::from_str("proj-1").unwrap()),
            cases_per_job: NonZeroUsize::new(3),
        };
        let shape = Shape {
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
                    let Ok(text) =
                        script(scheduler, "nlstudy-s-0", &keys, shape, &resources, &command)
                    else {
                        let has_control = value.chars().any(char::is_control);
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
                    let run = Command::new("bash")
                        .arg(&path)
                        .current_dir(&case)
                        .output()
                        .unwrap();
                    assert!(
                        run.status.success(),
                        "{text}\n{}",
                        String::from_utf8_lossy(&run.stderr)
                    );
                    let got = std::fs::read_to_string(&args).unwrap();
                    let expected = [
                        "run",
                        command.study.to_str().unwrap(),
                        "--results",
                        command.results.to_str().unwrap(),
                        "--solver",
                        command.nlsolve.to_str().unwrap(),
                        "--launcher",
                        match scheduler {
                            Scheduler::Slurm => "srun --mpi=pmix -n {ranks}",
                            Scheduler::Lsf => "mpirun -n {ranks}",
                        },
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
        let launcher: crate::run::pool::Launcher = given.parse().unwrap();
        let command = JobCommand {
            nlstudy: root.join("bin/nlstudy"),
            study: root.join("s.json"),
            results: root.join("results"),
            jobs: root.join("results/s/jobs"),
            nlsolve: root.join("bin/nlsolve"),
            retries: 0,
            launcher: Some(launcher),
        };
        let shape = Shape {
            tasks: 1,
            threads: 2,
        };
        let keys = ["00ff".to_string()];
        for scheduler in SCHEDULERS {
            let text = script(
                scheduler,
                "j",
                &keys,
                shape,
                &Resources::default(),
                &command,
            )
            .unwrap();
            if scheduler == Scheduler::Lsf {
                assert!(
                    text.contains("#BSUB -n 2\n#BSUB -R \"span[hosts=1]\"\n"),
                    "{text}"
                );
            }
            let path = root.join("job.sh");
            std::fs::write(&path, &text).unwrap();
            let args = root.join("args");
            stub(&command.nlstudy, &args);
            let run = Command::new("bash")
                .arg(&path)
                .current_dir(&root)
                .output()
                .unwrap();
            assert!(run.status.success(), "{text}");
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

    /// A shebang, then only directives (one option each), then `set -euo pipefail` and one
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
        let expected = match scheduler {
            Scheduler::Slurm => 8,
            Scheduler::Lsf => 7,
        };
        assert_eq!(directives, expected, "{text}");
        assert_eq!(
            &lines[1 + directives..][..1],
            ["set -euo pipefail"],
            "{text}"
        );
        assert_eq!(lines.len(), directives + 3, "{text}");
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
