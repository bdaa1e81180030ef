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

/// A scratch directory and its guard, which removes it however the test ends.
fn sandbox() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().to_path_buf();
    (dir, path)
}

/// The command of a job in `root`'s usual places: `bin/`, `s.json`, `results/`; no retries,
/// the scheduler's launcher, points of its own.
fn job_command(root: &Path) -> JobCommand {
    JobCommand {
        nlstudy: root.join("bin/nlstudy"),
        study: root.join("s.json"),
        results: root.join("results"),
        jobs: root.join("results/s/jobs"),
        nlsolve: root.join("bin/nlsolve"),
        retries: 0,
        launcher: None,
        whole: false,
        allow_mixed: false,
    }
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
            let accepted = crate::kinds::parse(&study);
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
    let (_sandbox, root) = sandbox();
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
                whole: false,
                allow_mixed: false,
            };
            for scheduler in SCHEDULERS {
                let job = Spec {
                    name: "nlstudy-s-0",
                    bundles: std::slice::from_ref(&keys),
                    array: false,
                    shape,
                    time: Some(WallTime::from_str("1-00:30:00").unwrap()),
                    probes: None,
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
}

/// `submit --launcher` reaches the job's `nlstudy run` as one argument that splits back
/// into the launcher's words, whatever they hold; an LSF job on one node keeps its slots on
/// one host.
#[test]
fn a_sites_launcher_reaches_the_job_whole_and_lsf_keeps_a_job_on_one_host() {
    let (_sandbox, root) = sandbox();
    let given = "env \"A=$(touch MARK) b\" srun --mpi=pmi2 -n {ranks}";
    let launcher: Launcher = given.parse().unwrap();
    let command = JobCommand {
        launcher: Some(launcher),
        ..job_command(&root)
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
        probes: None,
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
}

/// A whole study on several nodes leaves the cores to the allocation (no `-j`: `run` places a
/// step per case on every node) and tabulates its nodes' runs together; on one node it keeps
/// to its cores and refuses a mix unless asked.
#[test]
fn a_whole_study_on_several_nodes_uses_them_all_and_tabulates_their_runs() {
    let (_sandbox, root) = sandbox();
    let command = |allow_mixed| JobCommand {
        whole: true,
        allow_mixed,
        ..job_command(&root)
    };
    let settings = Settings {
        scheduler: Scheduler::Slurm,
        resources: &Resources::default(),
        site: &Site::default(),
        exclusive: true,
        throttle: None,
    };
    let on = |nodes, allow_mixed| {
        let job = Spec {
            name: "j",
            bundles: &[vec!["00ff".to_string()]],
            array: false,
            shape: Shape {
                nodes,
                tasks: nodes,
                threads: 1,
            },
            time: None,
            probes: None,
        };
        let text = script(&job, &settings, &command(allow_mixed)).unwrap();
        let run = text.lines().last().unwrap().to_string();
        run
    };
    let two = on(2, false);
    assert!(
        !two.contains(" -j ") && two.ends_with(" --allow-mixed"),
        "{two}"
    );
    let one = on(1, false);
    assert!(
        one.ends_with(" -j 1") && !one.contains("--allow-mixed"),
        "{one}"
    );
    assert!(on(1, true).ends_with(" -j 1 --allow-mixed"));
}

/// Every field of a site profile lands in both schedulers' scripts in its place: checked
/// values as directives, modules as quoted words, the prologue as its own lines before the
/// command; and the script still runs only the stub with the job's arguments.
#[test]
fn every_site_profile_field_lands_in_both_schedulers_scripts() {
    let (_sandbox, root) = sandbox();
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
        launcher: site.launcher.clone(),
        ..job_command(&root)
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
        probes: None,
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
            after("module load openmpi/4.1.6") < after("module load gcc@12")
                && after("module load gcc@12") < after("export SITE_MARK=1 # a comment")
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
}

/// An array's element runs its own bundle: Slurm's index from 0, LSF's from 1; each is handed
/// the array's probes file, its path one word whatever it holds.
#[test]
fn each_array_element_runs_its_own_bundle() {
    let (_sandbox, root) = sandbox();
    let command = job_command(&root);
    let probes = root.join("it's a job's.probes.json");
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
        probes: Some(&probes),
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
                got.ends_with(&format!(
                    "--only\n{}\n--probes\n{}\n",
                    bundle.join(","),
                    probes.display()
                )),
                "{got}"
            );
        }
    }
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
    let (_sandbox, root) = sandbox();
    let jobs = root.join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    std::fs::write(jobs.join("nlstudy-s-0.sbatch"), "old").unwrap();
    std::fs::write(jobs.join("nlstudy-s-0.probes.json"), "[]").unwrap();
    std::fs::write(jobs.join("nlstudy-s-0.42.out"), "log").unwrap();
    std::fs::write(jobs.join("notes.json"), "{}").unwrap();
    archive_earlier_scripts(&jobs).unwrap();
    assert!(!jobs.join("nlstudy-s-0.sbatch").exists());
    assert!(
        !jobs.join("nlstudy-s-0.probes.json").exists(),
        "its probes go with it"
    );
    assert!(jobs.join("nlstudy-s-0.42.out").exists(), "job output stays");
    assert!(
        jobs.join("notes.json").exists(),
        "what is not the tool's stays"
    );
    let archived: Vec<_> = std::fs::read_dir(jobs.join("archive"))
        .unwrap()
        .flatten()
        .collect();
    assert_eq!(archived.len(), 2);
}
