//! A real cluster in the test suite: `scripts/slurm-local` starts Debian's munge, slurmctld,
//! slurmdbd on a MariaDB server (accounting, so `sacct` and `status` know how jobs ended) and two
//! slurmd, each in its own network namespace, on this machine. `nlstudy submit` packs a study into
//! jobs that `sbatch` queues, the jobs run `nlstudy run --only …` (an MPI case through `srun
//! --mpi=pmix`) into the record store, and `nlstudy collect` builds the tables. Then, on the same
//! cluster: a job past its time limit (TIMEOUT, its unfinished point packed again; its minute
//! passes while the stages up to the warning signal run beside it), a job array of 20 points
//! with a throttle, adaptive rounds a `submit` each and driven by `submit --follow`
//! (a boundary search killed and restarted, a refinement, an error target, a whole study in one
//! job), a job requeued mid-run, a job sent its warning signal, a cancelled job, and an MPI case
//! with one rank on each node. Last, the cluster restarts with each node its share of the cores
//! (`--share-cores`) and a whole study of 20 points runs on one node, then on both.
//!
//! One test, one Slurm: the daemons listen on fixed ports. A system test (`make test` runs it):
//! where the packages cannot be installed or a daemon cannot start, it fails saying why. The
//! two-node stage is left out only when `NLSTUDY_SLURM_TEST=single-node` asks it, and the test
//! prints the stages it ran and the seconds of each (`--nocapture` shows them).

use nonlocal_study::{numbers_of, planned_keys, records, stored_keys, text, Scratch};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn script(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scripts")
        .join(name)
}

/// The local Slurm, stopped when dropped, also when the test fails.
struct LocalSlurm {
    dir: PathBuf,
}

impl LocalSlurm {
    fn conf(&self) -> PathBuf {
        self.dir.join("slurm.conf")
    }

    /// A Slurm command (`squeue`, …) against this cluster.
    fn command(&self, program: &str) -> Command {
        let mut command = Command::new(program);
        command.env("SLURM_CONF", self.conf());
        command
    }

    /// The ids of `study`'s jobs in the queue (`submit` names them `nlstudy-<study>-…`): in
    /// `state` (squeue's `-t`, such as RUNNING), or else in any state but ended; None when squeue
    /// fails.
    fn jobs_of(&self, study: &str, state: Option<&str>) -> Option<Vec<String>> {
        let mut squeue = self.command("squeue");
        squeue.args(["-h", "-o", "%i %j"]);
        if let Some(state) = state {
            squeue.args(["-t", state]);
        }
        let out = squeue.output().unwrap();
        let prefix = format!("nlstudy-{study}-");
        out.status.success().then(|| {
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .filter_map(|l| l.split_once(' '))
                .filter(|(_, name)| name.starts_with(&prefix))
                .map(|(id, _)| id.to_string())
                .collect()
        })
    }

    /// Waits until no job of `study` is queued or running (other studies' jobs may run on).
    fn wait_for_jobs(&self, study: &str, limit: Duration) {
        wait_until(limit, &format!("{study}'s jobs ended"), || {
            self.jobs_of(study, None)
                .is_some_and(|jobs| jobs.is_empty())
        });
    }
}

impl Drop for LocalSlurm {
    /// Stops the daemons; their directory (logs, spool and accounting database, about 180 MB)
    /// goes too unless the test failed, when its logs say why.
    fn drop(&mut self) {
        let stopped = Command::new(script("slurm-local"))
            .arg("stop")
            .arg(&self.dir)
            .status()
            .is_ok_and(|status| status.success());
        if stopped && !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// `nlstudy <verb> …` against the local Slurm.
fn nlstudy(scratch: &Scratch, slurm: &LocalSlurm, verb: &str, extra: &[&str]) -> Output {
    scratch
        .command(verb, extra)
        .env("SLURM_CONF", slurm.conf())
        .output()
        .unwrap()
}

/// `nlstudy submit --follow …` against the local Slurm, asking its queue at most every `poll`
/// seconds; not started yet.
fn follow(scratch: &Scratch, slurm: &LocalSlurm, poll: &str, extra: &[&str]) -> Command {
    let args = [
        "--scheduler",
        "slurm",
        "--time",
        "00:05:00",
        "--follow",
        "--poll",
        poll,
    ];
    let mut command = scratch.command("submit", &[&args[..], extra].concat());
    command.env("SLURM_CONF", slurm.conf());
    command
}

/// `nlstudy submit --scheduler slurm …` against the local Slurm.
fn submit(scratch: &Scratch, slurm: &LocalSlurm, extra: &[&str]) -> Output {
    let mut args = vec!["--scheduler", "slurm"];
    args.extend(extra);
    nlstudy(scratch, slurm, "submit", &args)
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn studies_submitted_to_a_local_slurm_run_store_and_collect() {
    let setup = Command::new(script("setup.sh"))
        .arg("--slurm")
        .output()
        .unwrap();
    // A missing component fails the test: a skip would pass CI without testing anything.
    assert!(
        setup.status.success(),
        "Debian's Slurm packages could not be installed: {}",
        text(&setup).trim()
    );
    // Each stage's seconds, printed with its name: where the test's minutes go.
    let mut stages = Vec::new();
    let mut lap = Instant::now();
    let mut ran = |stages: &mut Vec<String>, stage: &str| {
        stages.push(format!("{stage} ({} s)", lap.elapsed().as_secs()));
        lap = Instant::now();
    };
    let dir = std::env::temp_dir().join(format!("nlstudy-slurm-test-{}", std::process::id()));
    let slurm = LocalSlurm { dir: dir.clone() };
    let start = |extra: &[&str]| {
        Command::new(script("slurm-local"))
            .arg("start")
            .arg(&dir)
            .args(["--accounting"])
            .args(extra)
            .output()
            .unwrap()
    };
    // One node only when the run opts out of the second one (a host without network
    // namespaces): otherwise a second node that cannot start fails the test.
    let single_node = std::env::var("NLSTUDY_SLURM_TEST").is_ok_and(|v| v == "single-node");
    let two_nodes = !single_node;
    let started = match single_node {
        true => start(&[]),
        false => start(&["--nodes", "2"]),
    };
    assert!(
        started.status.success(),
        "slurm-local start: {}",
        text(&started)
    );
    ran(&mut stages, "set-up and start");

    // Four points in two jobs, packed by predicted cost: the 2D case on 2 ranks (launched by
    // srun) outweighs the three 1D grids together, so it has a job of its own.
    let study = json!({
        "name": "cluster",
        "base": {"m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"zip": {"dim": [1, 1, 1, 2], "n": [16, 32, 64, 64], "ranks": [1, 1, 1, 2]}}]
    });
    let scratch = Scratch::new("slurm", &study);
    let out = submit(
        &scratch,
        &slurm,
        &["--cases-per-job", "2", "--time", "00:05:00"],
    );
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(
        text(&out).matches("submitted as job ").count(),
        2,
        "{}",
        text(&out)
    );
    slurm.wait_for_jobs("cluster", Duration::from_secs(300));
    let stored = records(&scratch.runs("cluster"));
    assert_eq!(stored.len(), 4, "job output: {}", logs(&scratch, "cluster"));
    assert!(stored.iter().all(|r| r["status"] == "ok"), "{stored:?}");
    assert_eq!(
        stored_keys(&stored),
        planned_keys(&scratch),
        "the study's points"
    );
    assert!(
        stored.iter().any(|r| r["ranks"] == 2),
        "the MPI case ran on 2 ranks"
    );
    wait_until(Duration::from_secs(30), "accounting of both jobs", || {
        let said = text(&nlstudy(&scratch, &slurm, "status", &[]));
        said.contains(": completed, 1 of 1 points stored")
            && said.contains(": completed, 3 of 3 points stored")
    });
    // The jobs ran on both nodes: a table of several hosts, asked for.
    let collected = scratch.nlstudy("collect", &["--allow-mixed"]);
    assert!(collected.status.success(), "{}", text(&collected));
    assert!(scratch.dir.join("results/cluster/cluster.parquet").exists());
    let again = submit(&scratch, &slurm, &["--dry-run"]);
    assert!(
        text(&again).contains("nothing to submit"),
        "{}",
        text(&again)
    );

    ran(&mut stages, "jobs and srun");

    // The time-limit job waits out its minute while the stages after it run beside it: each of
    // them waits for its own study's jobs only.
    let limit = past_its_time_limit_started(&slurm, two_nodes);
    ran(&mut stages, "time limit started");
    array_with_a_throttle(&scratch, &slurm);
    ran(&mut stages, "array with a throttle");
    refined_a_round_per_submit(&scratch, &slurm);
    searched_a_round_per_submit(&scratch, &slurm);
    ran(&mut stages, "adaptive rounds");
    followed_to_the_answer(&slurm);
    ran(&mut stages, "followed to the answer (search)");
    refined_and_targeted_by_the_driver(&slurm);
    ran(&mut stages, "refinement, target, whole");
    killed_between_sbatch_and_its_entry(&slurm);
    cancelled_twice_then_given_up(&slurm);
    ran(&mut stages, "past cancelled jobs");
    requeued_mid_run(&scratch, &slurm);
    ran(&mut stages, "requeue");
    warned_before_the_limit_and_cancelled(&scratch, &slurm);
    ran(&mut stages, "warning signal and cancel");
    past_its_time_limit_ended(&limit, &slurm);
    ran(&mut stages, "time limit and accounting ended");
    if two_nodes {
        one_rank_on_each_node(&scratch, &slurm);
        two_cores_for_each_of_two_ranks(&scratch, &slurm);
        ran(&mut stages, "two nodes");
        // The same two nodes, each with its share of the machine's cores.
        let stopped = Command::new(script("slurm-local"))
            .arg("stop")
            .arg(&dir)
            .output()
            .unwrap();
        assert!(stopped.status.success(), "{}", text(&stopped));
        let shared = start(&["--nodes", "2", "--share-cores"]);
        assert!(
            shared.status.success(),
            "slurm-local start: {}",
            text(&shared)
        );
        every_node_of_an_allocation(&slurm);
        ran(&mut stages, "every node of an allocation");
    } else {
        stages.push("two nodes: not run (NLSTUDY_SLURM_TEST=single-node)".to_string());
    }
    // Each stage asserts what it shows, so reaching here means all ran; this says which.
    eprintln!("slurm stages run: {}", stages.join(", "));
}

/// A job past its one-minute limit: its quick points are stored, the slow one (about 10 000
/// steps at n = 1024) is killed and left missing, and only it is packed again. Started: the
/// quick points are stored while the slow one runs, the job is running, and a second submit
/// packs nothing.
fn past_its_time_limit_started(slurm: &LocalSlurm, two_nodes: bool) -> Scratch {
    let scratch = Scratch::new("limit", &quick_and_slow("limit"));
    // On the last node, off the first one where the stages beside it run (one host for the
    // runs of each of their tables, as when the job ran alone).
    let mut limit = vec!["--time", "00:01:00"];
    if two_nodes {
        limit.extend(["--queue", "last"]);
    }
    let out = submit(&scratch, slurm, &limit);
    assert!(out.status.success(), "{}", text(&out));
    wait_until(Duration::from_secs(60), "the quick points", || {
        records(&scratch.runs("limit")).len() >= 2
    });
    let running = text(&nlstudy(&scratch, slurm, "status", &[]));
    assert!(
        running.contains("nlstudy-limit-0: running, 2 of 3 points stored"),
        "{running}"
    );
    let twice = submit(&scratch, slurm, &limit);
    assert!(twice.status.success(), "{}", text(&twice));
    assert!(
        text(&twice).contains("1 points are in jobs still queued or running")
            && text(&twice).contains("nothing to submit"),
        "{}",
        text(&twice)
    );
    scratch
}

/// The time-limit job ended: accounting says timeout, the two quick points are stored whole,
/// and only the slow point is packed again.
fn past_its_time_limit_ended(scratch: &Scratch, slurm: &LocalSlurm) {
    slurm.wait_for_jobs("limit", Duration::from_secs(300));
    status_says(
        scratch,
        slurm,
        "nlstudy-limit-0: timeout (ended at its time limit",
    );
    let ended = text(&nlstudy(scratch, slurm, "status", &[]));
    assert!(
        ended.contains("nlstudy-limit-0: timeout (ended at its time limit")
            && ended.contains("2 of 3 points stored")
            && ended.contains("1 of 3 points to run"),
        "accounting tells a timeout: {ended}"
    );
    let runs = scratch.runs("limit");
    let stored = records(&runs);
    assert_eq!(
        stored.len(),
        2,
        "the two quick points: {stored:?}\n{}",
        logs(scratch, "limit")
    );
    let stray = stray_files(&runs);
    assert!(stray.is_empty(), "half-written files: {stray:?}");
    let again = submit(scratch, slurm, &["--dry-run"]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        text(&again).contains("nlstudy-limit-0 (1 cases, "),
        "{}",
        text(&again)
    );
}

/// Waits for `status` to say `expected`: accounting learns of a job's end a moment after the
/// queue forgets it.
fn status_says(scratch: &Scratch, slurm: &LocalSlurm, expected: &str) {
    let mut said = String::new();
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(30) {
        said = text(&nlstudy(scratch, slurm, "status", &[]));
        if said.contains(expected) {
            return;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    panic!("status never said {expected:?}: {said}");
}

/// Two quick points and a slow one (about 10 000 steps at n = 1024, well over a minute here).
fn quick_and_slow(name: &str) -> Value {
    json!({
        "name": name,
        "base": {"m": 2, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"zip": {
            "dim": [1, 1, 2],
            "n": [16, 32, 1024],
            "m": [2, 2, 8],
            "t_end": [0.001, 0.001, 1e-4],
            "cfl": [0.5, 0.5, null],
            "dt": [null, null, 1e-8]
        }}]
    })
}

/// The id `submit` printed for its only job.
fn job_id(out: &Output) -> String {
    let said = text(out);
    let ids: Vec<&str> = said
        .lines()
        .filter_map(|l| l.trim().strip_prefix("submitted as job "))
        .collect();
    assert_eq!(ids.len(), 1, "one job: {said}");
    ids[0].to_string()
}

/// Waits until `done` holds, failing with `what` after `limit`.
fn wait_until(limit: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let started = Instant::now();
    while !done() {
        assert!(started.elapsed() < limit, "{what} within {limit:?}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The job logs of `study`, joined.
fn logs(scratch: &Scratch, study: &str) -> String {
    let jobs = scratch.dir.join("results").join(study).join("jobs");
    std::fs::read_dir(&jobs)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "out"))
        .map(|e| std::fs::read_to_string(e.path()).unwrap_or_default())
        .collect::<Vec<_>>()
        .join("\n")
}

/// What a store holds beside its segments, catalog and locks (nothing may be left
/// half-written): files in `runs/` but its folders, and in `runs/segments/`.
fn stray_files(runs: &Path) -> Vec<String> {
    let listed = |dir: &Path| -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect()
    };
    let segments = listed(&runs.join("segments"))
        .into_iter()
        .filter(|name| !(name.ends_with(".seg") || name == "catalog" || name == ".compact.lock"));
    listed(runs)
        .into_iter()
        .filter(|name| name != ".work" && name != "segments")
        .chain(segments)
        .collect()
}

/// 20 points as one array of 20 elements, two at a time: one `sbatch` call, every record stored
/// once, and `status` counts the elements by their accounted state.
fn array_with_a_throttle(scratch: &Scratch, slurm: &LocalSlurm) {
    let n: Vec<u64> = (16..36).collect();
    let study = json!({
        "name": "array",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"product": {"n": n}}],
        "share_machine": true
    });
    scratch.write_study(&study);
    let out = submit(scratch, slurm, &["--array", "--throttle", "2"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("array of 20 elements"),
        "{}",
        text(&out)
    );
    let id = job_id(&out);
    let script = std::fs::read_to_string(
        scratch
            .dir
            .join("results/array/jobs/nlstudy-array-0.sbatch"),
    )
    .unwrap();
    assert!(script.contains("#SBATCH --array=0-19%2\n"), "{script}");
    slurm.wait_for_jobs("array", Duration::from_secs(300));
    let stored = records(&scratch.runs("array"));
    assert_eq!(stored.len(), 20, "{}", logs(scratch, "array"));
    assert_eq!(stored_keys(&stored), planned_keys(scratch));
    assert!(
        stored
            .iter()
            .all(|r| r["status"] == "ok" && r["attempt"] == 1),
        "{stored:?}"
    );
    status_says(
        scratch,
        slurm,
        &format!("job {id} nlstudy-array-0 (array of 20): 20 completed, 20 of 20 points stored"),
    );
}

/// A refinement on a cluster, a round per `submit` (`a_round_per_submit`): three levels.
fn refined_a_round_per_submit(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = json!({
        "name": "rounds",
        "base": {"method": "fd_explicit", "dim": 1, "problem": "eigenmode", "t_end": 0.01,
                 "cfl": 0.4},
        "refine": {"field": "n", "start": 16, "max_levels": 3, "agree": 1e-9}
    });
    a_round_per_submit(
        scratch,
        slurm,
        &study,
        &[1, 2, 3],
        "max_levels run at n = 64, 3 levels",
    );
}

/// A boundary search on a cluster, a round per `submit` (`a_round_per_submit`): k-section with
/// 15 probes a round narrows forward Euler's limit to 5 % in three rounds (the bracket's ends,
/// then two of 15).
fn searched_a_round_per_submit(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = json!({
        "name": "searched",
        "base": {"dim": 1, "n": 64, "m": 2, "problem": "bump", "t_end": 1e-6,
                 "allow_unstable": true, "amplification_steps": 100},
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 0.05, "per_round": 15}
    });
    a_round_per_submit(scratch, slurm, &study, &[2, 17, 32], "(predicted 1, ");
}

/// An adaptive study on a cluster, a round per `submit`: each submit sends the next round of
/// probes only (each job runs its share with `run --only`), after which the store holds
/// `stored[k]` records; then submit has nothing left, and `run` gives the answer (`answer` is
/// in what it prints) without running anything.
fn a_round_per_submit(
    scratch: &Scratch,
    slurm: &LocalSlurm,
    study: &Value,
    stored: &[usize],
    answer: &str,
) {
    let name = study["name"].as_str().expect("a named study");
    scratch.write_study(study);
    for (round, &stored) in stored.iter().enumerate() {
        let out = submit(scratch, slurm, &["--time", "00:05:00"]);
        assert!(
            out.status.success() && text(&out).contains("submitted as job "),
            "round {}: {}",
            round + 1,
            text(&out)
        );
        slurm.wait_for_jobs(name, Duration::from_secs(120));
        let records = records(&scratch.runs(name));
        assert_eq!(records.len(), stored, "{}", logs(scratch, name));
    }
    let done = submit(scratch, slurm, &["--dry-run"]);
    assert!(text(&done).contains("nothing to submit"), "{}", text(&done));
    let run = scratch.nlstudy("run", &[]);
    assert!(
        text(&run).contains("0 ran") && text(&run).contains(answer),
        "{}",
        text(&run)
    );
}

/// `submit --follow` takes a boundary study of four searches to its answer with one command:
/// the rounds and boundaries of a local `run`. Killed (SIGKILL) once its first round is in the
/// ledger and started again, it waits for that round and submits no point twice.
fn followed_to_the_answer(slurm: &LocalSlurm) {
    let study = json!({
        "name": "followed",
        "base": {"dim": 1, "n": 64, "problem": "bump", "t_end": 1e-6,
                 "allow_unstable": true, "amplification_steps": 100},
        "sweep": [{"product": {"integrator": ["forward_euler", "heun"], "m": [1, 2]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 0.01, "per_round": 7}
    });
    let local = Scratch::new("followed-local", &study);
    let run = local.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    // Each search's line: its point, boundary, prediction and probes.
    let answers = |said: &str| -> Vec<String> {
        let lines = said
            .lines()
            .filter(|l| l.contains("(predicted ") && l.ends_with(" probes"));
        lines.map(|l| l.trim().to_string()).collect()
    };
    assert_eq!(answers(&text(&run)).len(), 4, "{}", text(&run));

    let cluster = Scratch::new("followed", &study);
    let mut first = follow(&cluster, slurm, "2", &[])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ledger = cluster.dir.join("results/followed/jobs/ledger");
    let entries = || -> Vec<Value> {
        let files = std::fs::read_dir(&ledger).into_iter().flatten().flatten();
        files
            .filter_map(|f| serde_json::from_slice(&std::fs::read(f.path()).ok()?).ok())
            .collect()
    };
    wait_until(Duration::from_secs(60), "the first round's job", || {
        !entries().is_empty()
    });
    first.kill().unwrap();
    first.wait().unwrap();
    let again = follow(&cluster, slurm, "2", &[]).output().unwrap();
    let said = text(&again);
    assert!(
        again.status.success(),
        "{said}\n{}",
        logs(&cluster, "followed")
    );
    assert!(
        said.contains("jobs: ") && said.contains(" of at most 4: "),
        "{said}"
    );
    let mut submitted: Vec<String> = entries()
        .iter()
        .flat_map(|e| e["keys"].as_array().unwrap().clone())
        .map(|k| k.as_str().unwrap().to_string())
        .collect();
    let jobs = submitted.len();
    submitted.sort();
    submitted.dedup();
    assert_eq!(submitted.len(), jobs, "a point was submitted twice: {said}");
    assert_eq!(answers(&said), answers(&text(&run)), "{said}");
    assert!(said.contains("report: "), "{said}");
    assert!(said.contains(" s of waiting; it took "), "{said}");

    // The whole study in one job: one sbatch, the same answer.
    let whole = Scratch::new("followed-whole", &study);
    let out = follow(&whole, slurm, "2", &["--whole"]).output().unwrap();
    let said = text(&out);
    assert!(out.status.success(), "{said}\n{}", logs(&whole, "followed"));
    assert_eq!(said.matches("submitted as job ").count(), 1, "{said}");
    assert_eq!(answers(&said), answers(&text(&run)), "{said}");
}

/// The answer lines `run` and the driver print: the indented lines just above `table: `, but
/// the note on noisy timings.
fn answer_lines(said: &str) -> Vec<String> {
    let lines: Vec<&str> = said.lines().collect();
    let Some(table) = lines.iter().position(|l| l.starts_with("table: ")) else {
        return Vec::new();
    };
    let above = lines[..table].iter().rev();
    let answers = above.take_while(|l| l.starts_with("  ") && !l.contains(" noisy"));
    let mut answers: Vec<String> = answers.map(|l| l.trim().to_string()).collect();
    answers.reverse();
    answers
}

/// A refinement and an error target through the driver: each reaches, with one command, the
/// answer a local `run` gives. The target's cost is a count (`bond_evaluations`): a timed cost
/// steers the search by the runs' own timings, so on a loaded machine the cluster's and the
/// local search may rightly end at different runs (a CI run on record: n = 416 against 431).
fn refined_and_targeted_by_the_driver(slurm: &LocalSlurm) {
    let refine = json!({
        "name": "refined",
        "base": {"method": "fd_explicit", "dim": 1, "problem": "eigenmode", "t_end": 0.01,
                 "cfl": 0.4},
        "refine": {"field": "n", "start": 16, "max_levels": 3, "agree": 1e-9}
    });
    let target = json!({
        "name": "targeted",
        "base": {"dim": 1, "m": 4, "quadrature": "ac", "t_end": 0.05, "integrator": "rk4"},
        "target": {"field": "n", "start": 32, "time": {"field": "dt", "start": 0.002},
                   "below": 3e-4, "cost": "bond_evaluations"}
    });
    for study in [refine, target] {
        let name = study["name"].as_str().unwrap();
        let local = Scratch::new(&format!("{name}-local"), &study);
        let run = local.nlstudy("run", &[]);
        let expected = answer_lines(&text(&run));
        assert!(!expected.is_empty(), "{}", text(&run));
        let cluster = Scratch::new(name, &study);
        let out = follow(&cluster, slurm, "1", &[]).output().unwrap();
        let said = text(&out);
        assert!(out.status.success(), "{said}\n{}", logs(&cluster, name));
        assert!(said.contains("\nround 2"), "{said}");
        let answers = answer_lines(&said);
        assert_eq!(answers, expected, "{name}: {said}");
    }
}

/// A submit killed after `sbatch` took its job and before the ledger had the job's id leaves
/// the entry it wrote first, under the job's mark: the driver finds the job by that mark, waits
/// for it, and submits nothing again.
fn killed_between_sbatch_and_its_entry(slurm: &LocalSlurm) {
    let study = json!({
        "name": "window",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"product": {"n": [16, 32]}}]
    });
    let scratch = Scratch::new("window", &study);
    let dry = nlstudy(
        &scratch,
        slurm,
        "submit",
        &["--scheduler", "slurm", "--dry-run"],
    );
    assert!(dry.status.success(), "{}", text(&dry));
    let jobs = scratch.dir.join("results/window/jobs");
    let token = "nlstudy-1-2";
    let entry = json!({
        "scheduler": "slurm", "id": format!("submitting-{token}"), "name": "nlstudy-window-0",
        "keys": planned_keys(&scratch), "submitted": 1_764_000_000u64
    });
    std::fs::create_dir_all(jobs.join("ledger")).unwrap();
    std::fs::write(
        jobs.join(format!("ledger/submitting-{token}.json")),
        entry.to_string(),
    )
    .unwrap();
    let sbatch = slurm
        .command("sbatch")
        .args(["--parsable", &format!("--comment={token}")])
        .arg(jobs.join("nlstudy-window-0.sbatch"))
        .output()
        .unwrap();
    assert!(sbatch.status.success(), "{}", text(&sbatch));
    let id = String::from_utf8_lossy(&sbatch.stdout).trim().to_string();
    let out = follow(&scratch, slurm, "1", &[]).output().unwrap();
    let said = text(&out);
    assert!(out.status.success(), "{said}\n{}", logs(&scratch, "window"));
    assert!(
        !said.contains("submitted as job"),
        "submitted twice: {said}"
    );
    assert!(jobs.join(format!("ledger/{id}.json")).exists(), "{said}");
    assert!(!jobs
        .join(format!("ledger/submitting-{token}.json"))
        .exists());
    assert_eq!(records(&scratch.runs("window")).len(), 2, "{said}");
}

/// Followed, a point whose job is cancelled while it runs is submitted once more; cancelled
/// again, it is stored failed with what accounting says of both jobs, and the driver exits 1.
fn cancelled_twice_then_given_up(slurm: &LocalSlurm) {
    let study = json!({
        "name": "given-up",
        "base": {"dim": 2, "m": 8, "t_end": 1e-4, "dt": 1e-8, "source": "discrete"},
        "sweep": [{"product": {"n": [1024]}}]
    });
    let scratch = Scratch::new("given-up", &study);
    let driver = follow(&scratch, slurm, "1", &[])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut cancelled: Vec<String> = Vec::new();
    for _ in 0..2 {
        let mut running = String::new();
        wait_until(Duration::from_secs(60), "a job running", || {
            let jobs = slurm
                .jobs_of("given-up", Some("RUNNING"))
                .unwrap_or_default();
            running = jobs.into_iter().next().unwrap_or_default();
            !running.is_empty() && !cancelled.contains(&running)
        });
        let cancel = slurm.command("scancel").arg(&running).output().unwrap();
        assert!(cancel.status.success(), "{}", text(&cancel));
        cancelled.push(running);
    }
    let out = driver.wait_with_output().unwrap();
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    let why = format!(
        "submitted 2 times, and its jobs ended without its record: job {} CANCELLED",
        cancelled[0]
    );
    assert!(said.contains(&why), "{why}: {said}");
    let stored = records(&scratch.runs("given-up"));
    assert_eq!(stored.len(), 1, "{said}");
    assert_eq!(stored[0]["status"], "failed");
    assert!(stored[0]
        .to_string()
        .contains(&format!("job {} CANCELLED", cancelled[1])));
}

/// A job requeued while it runs (as a preemption would) runs again and takes up only what is
/// missing: every point stored once, none lost. The study checkpoints: the point the requeue
/// stopped (its solver wrote its checkpoint on the SIGTERM) resumes from its checkpoint rather
/// than from step 0, with the numbers of a run never stopped.
fn requeued_mid_run(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = json!({
        "name": "requeue",
        "checkpoint_every_s": 0.2,
        "base": {"dim": 2, "m": 4, "t_end": 0.02, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"product": {"n": [448, 464, 480, 496, 512, 528]}}]
    });
    scratch.write_study(&study);
    let out = submit(scratch, slurm, &["--time", "00:10:00"]);
    assert!(out.status.success(), "{}", text(&out));
    let id = job_id(&out);
    let runs = scratch.runs("requeue");
    let checkpoints = || -> Vec<String> {
        std::fs::read_dir(runs.join(".work"))
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                Some(name.strip_suffix(".checkpoint")?.to_string())
            })
            .collect()
    };
    // A point in its time loop: its first periodic checkpoint is written.
    let mut stopped = Vec::new();
    wait_until(
        Duration::from_secs(120),
        "a first record and a checkpoint",
        || {
            stopped = checkpoints();
            !records(&runs).is_empty() && !stopped.is_empty()
        },
    );
    let requeue = slurm
        .command("scontrol")
        .args(["requeue", &id])
        .output()
        .unwrap();
    assert!(
        requeue.status.success(),
        "scontrol requeue: {}",
        text(&requeue)
    );
    // Slurm holds a requeued job about two minutes before it is eligible again (a requeue
    // loop's brake); the test makes it eligible in two seconds. Not at once: slurmd refuses a
    // job credential issued within the second its job was killed in ("Job 30 already killed,
    // do not launch batch job"), and the job would end there, never to run again.
    wait_until(Duration::from_secs(60), "the job pending again", || {
        let q = slurm
            .command("squeue")
            .args(["-h", "-j", &id, "-o", "%T"])
            .output()
            .unwrap();
        text(&q).contains("PENDING")
    });
    let now = slurm
        .command("scontrol")
        .args(["update", &format!("jobid={id}"), "StartTime=now+2"])
        .output()
        .unwrap();
    assert!(
        now.status.success(),
        "scontrol update StartTime: {}",
        text(&now)
    );
    slurm.wait_for_jobs("requeue", Duration::from_secs(600));
    let stored = records(&runs);
    let log = logs(scratch, "requeue");
    assert_eq!(stored.len(), 6, "{log}");
    assert_eq!(stored_keys(&stored), planned_keys(scratch), "{log}");
    assert!(stray_files(&runs).is_empty(), "{:?}", stray_files(&runs));
    assert!(
        log.contains("stopped by SIGTERM"),
        "the first run was stopped: {log}"
    );
    assert!(
        log.contains("already stored"),
        "the second run took up what was missing: {log}"
    );
    // The point stopped in its time loop resumed there, with the numbers of a run never stopped.
    let resumed: Vec<&Value> = stored
        .iter()
        .filter(|r| {
            r.get("resumed_from_step")
                .is_some_and(|s| s.as_u64() > Some(0))
        })
        .collect();
    assert!(
        resumed
            .iter()
            .any(|r| stopped.iter().any(|key| r["key"] == key.as_str())),
        "no stopped point resumed from its checkpoint ({stopped:?}): {log}"
    );
    assert!(
        checkpoints().is_empty(),
        "checkpoints outlived their records"
    );
    for record in resumed {
        let alone = Command::new(nonlocal_study::binary("nlsolve"))
            .args(["run", "--case", "-"])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .spawn()
            .and_then(|mut child| {
                use std::io::Write;
                let case = record["case"].to_string();
                child.stdin.take().unwrap().write_all(case.as_bytes())?;
                child.wait_with_output()
            })
            .unwrap();
        let alone: Value = serde_json::from_slice(&alone.stdout).unwrap();
        // The stored record adds its identity; nlsolve's prints the case resolved.
        let numbers = |record: &Value| {
            let mut record = numbers_of(record);
            let fields = record.as_object_mut().unwrap();
            for added in [
                "key",
                "case_id",
                "repeat",
                "solver_version",
                "attempt",
                "oversubscribed",
                "case",
                "provenance",
            ] {
                fields.remove(added);
            }
            record
        };
        assert_eq!(numbers(record), numbers(&alone), "{}", record["key"]);
    }
}

/// The warning before the time limit (`--signal=B:TERM@…`; sent here by hand, as Slurm would,
/// to the batch shell alone) stops the job cleanly: whole records, the unfinished point missing,
/// and `status` says so; a cancelled job is shown as cancelled.
fn warned_before_the_limit_and_cancelled(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = quick_and_slow("warned");
    scratch.write_study(&study);
    let out = submit(scratch, slurm, &["--time", "00:10:00"]);
    assert!(out.status.success(), "{}", text(&out));
    let id = job_id(&out);
    let script = std::fs::read_to_string(
        scratch
            .dir
            .join("results/warned/jobs/nlstudy-warned-0.sbatch"),
    )
    .unwrap();
    assert!(script.contains("#SBATCH --signal=B:TERM@60\n"), "{script}");
    let runs = scratch.runs("warned");
    wait_until(Duration::from_secs(120), "the quick points", || {
        records(&runs).len() >= 2
    });
    std::thread::sleep(Duration::from_millis(500)); // the slow point's solver is running
    let warn = slurm
        .command("scancel")
        .args(["--signal=TERM", "--batch", &id])
        .output()
        .unwrap();
    assert!(warn.status.success(), "{}", text(&warn));
    slurm.wait_for_jobs("warned", Duration::from_secs(120));
    assert_eq!(records(&runs).len(), 2, "{}", logs(scratch, "warned"));
    assert!(stray_files(&runs).is_empty(), "{:?}", stray_files(&runs));
    assert!(logs(scratch, "warned").contains("stopped by SIGTERM"));
    status_says(
        scratch,
        slurm,
        &format!(
            "job {id} nlstudy-warned-0: stopped_by_sigterm (stopped by SIGTERM before its limit"
        ),
    );

    // The slow point again, cancelled while it runs.
    let out = submit(scratch, slurm, &["--time", "00:10:00"]);
    let id = job_id(&out);
    wait_until(Duration::from_secs(60), "the job running", || {
        let q = slurm
            .command("squeue")
            .args(["-h", "-j", &id, "-o", "%T"])
            .output()
            .unwrap();
        text(&q).contains("RUNNING")
    });
    let cancel = slurm.command("scancel").arg(&id).output().unwrap();
    assert!(cancel.status.success(), "{}", text(&cancel));
    slurm.wait_for_jobs("warned", Duration::from_secs(120));
    status_says(
        scratch,
        slurm,
        &format!("job {id} nlstudy-warned-0: cancelled (cancelled: `submit` again"),
    );
}

/// A whole study of 20 single-rank points in one allocation of two nodes of one core each
/// (`slurm-local --share-cores`): the pool inside runs a job step per point on both nodes, so
/// the records name both hosts; the same study on one node is timed beside it, and the ratio of
/// the two jobs' times is reported (not asserted: it is a timing).
fn every_node_of_an_allocation(slurm: &LocalSlurm) {
    let study = json!({
        "name": "spread",
        "base": {"dim": 1, "m": 4, "t_end": 0.3, "cfl": 0.5, "source": "discrete"},
        "sweep": [{"product": {"n": (1000..1020).collect::<Vec<_>>()}}]
    });
    let mut seconds = Vec::new();
    let mut simulated = Vec::new();
    for nodes in ["1", "2"] {
        let scratch = Scratch::new(&format!("spread-{nodes}"), &study);
        let started = Instant::now();
        let out = follow(&scratch, slurm, "0.5", &["--whole", "--nodes", nodes])
            .output()
            .unwrap();
        seconds.push(started.elapsed().as_secs_f64());
        let said = text(&out);
        assert!(out.status.success(), "{said}\n{}", logs(&scratch, "spread"));
        let stored = records(&scratch.runs("spread"));
        assert_eq!(stored.len(), 20, "{said}\n{}", logs(&scratch, "spread"));
        let hosts: std::collections::BTreeSet<&str> = stored
            .iter()
            .map(|r| r["provenance"]["host"].as_str().unwrap())
            .collect();
        let expected = match nodes {
            "1" => vec!["nlnode1"],
            _ => vec!["nlnode1", "nlnode2"],
        };
        assert_eq!(hosts.into_iter().collect::<Vec<_>>(), expected, "{said}");
        simulated.push(simulate(&scratch, slurm));
        if nodes == "2" {
            let log = logs(&scratch, "spread");
            assert!(
                log.contains("2 nodes of the allocation, a worker step on each node's cores"),
                "{log}"
            );
            // Workers answer over connections of their own, not the steps' standard streams
            // (whose forwarding held each answer of over 1 kB for 40 ms).
            assert!(
                log.contains("give their answers over connections to 10.213.57.")
                    && log.contains("a worker on nlnode2 connected"),
                "{log}"
            );
        }
    }
    eprintln!(
        "every node of an allocation: 20 points, 1 node {:.1} s, 2 nodes {:.1} s: ratio {:.2}",
        seconds[0],
        seconds[1],
        seconds[1] / seconds[0]
    );
    // The simulator replays each run on its own allocation within 20 % of what the run's
    // timeline measured: its lanes, longest first, and one driver's time per case account for
    // the run's length. Each run predicted on the other's allocation is said, not asserted:
    // this lane runs beside the others, and a load that changes between the two runs moves
    // their times apart (quiet, each was within 7 %: docs/scaling.md).
    for (run, (measured, replayed, other)) in ["1 node", "2 nodes"].iter().zip(&simulated) {
        eprintln!("simulated: {run}: {measured:.2} s measured, {replayed:.2} s replayed, {other:.2} s predicted on the other shape");
        assert!(
            (replayed / measured - 1.0).abs() <= 0.2,
            "{run}: replayed {replayed:.2} s, measured {measured:.2} s"
        );
    }
}

/// `plan --simulate 1x1,2x1` of a study's latest run: its measured length, the model's replay
/// of it on its own lanes, and its prediction on the other shape (one node or two, one core
/// each).
fn simulate(scratch: &Scratch, slurm: &LocalSlurm) -> (f64, f64, f64) {
    let out = nlstudy(scratch, slurm, "plan", &["--simulate", "1x1,2x1"]);
    let said = text(&out);
    assert!(out.status.success(), "{said}");
    let seconds = |line: &str, after: &str| -> f64 {
        let rest = &line[line.find(after).unwrap() + after.len()..];
        let number = rest.trim_start().split([' ', ')']).next().unwrap();
        number.parse().unwrap_or_else(|_| panic!("{line}"))
    };
    let lines: Vec<&str> = said.lines().collect();
    let find = |start: &str| {
        *lines
            .iter()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("{said}"))
    };
    let from = find("from run");
    let one_lane = from.contains("on 1 lane,");
    let measured = seconds(from, if one_lane { "lane," } else { "lanes," });
    let replayed = seconds(from, "replays it:");
    let other = seconds(find(if one_lane { "on 2x1 " } else { "on 1x1 " }), "):");
    (measured, replayed, other)
}

/// A 2-rank case on two nodes: one rank on each, and the record names both hosts.
fn one_rank_on_each_node(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = json!({
        "name": "twonode",
        "base": {"dim": 2, "n": 64, "m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete", "ranks": 2}
    });
    scratch.write_study(&study);
    let out = submit(scratch, slurm, &["--nodes", "2"]);
    assert!(out.status.success(), "{}", text(&out));
    slurm.wait_for_jobs("twonode", Duration::from_secs(180));
    let stored = records(&scratch.runs("twonode"));
    assert_eq!(stored.len(), 1, "{}", logs(scratch, "twonode"));
    assert_eq!(stored[0]["status"], "ok", "{:?}", stored[0]);
    let hosts: std::collections::BTreeSet<&str> = stored[0]["hosts"]
        .as_array()
        .expect("a distributed record names its hosts")
        .iter()
        .map(|h| h.as_str().unwrap())
        .collect();
    assert_eq!(
        hosts.len(),
        2,
        "one rank on each node: {:?}",
        stored[0]["hosts"]
    );
}

/// A 2 × 2 case (two ranks of two threads) on two nodes of two cores: the job asks two cores per
/// task and the default launcher (`srun -c {threads}`) gives each rank two, so each rank's
/// affinity, which the record keeps, holds two CPUs, and the record is not oversubscribed.
fn two_cores_for_each_of_two_ranks(scratch: &Scratch, slurm: &LocalSlurm) {
    let study = json!({
        "name": "twobytwo",
        "base": {"dim": 2, "n": 64, "m": 2, "t_end": 0.001, "cfl": 0.5, "source": "discrete", "ranks": 2, "threads": 2}
    });
    scratch.write_study(&study);
    let out = submit(scratch, slurm, &["--nodes", "2"]);
    assert!(out.status.success(), "{}", text(&out));
    let script = std::fs::read_to_string(
        scratch
            .dir
            .join("results/twobytwo/jobs/nlstudy-twobytwo-0.sbatch"),
    )
    .unwrap_or_default();
    assert!(
        script.contains("--cpus-per-task=2") && script.contains("SRUN_CPUS_PER_TASK"),
        "{script}"
    );
    slurm.wait_for_jobs("twobytwo", Duration::from_secs(180));
    let stored = records(&scratch.runs("twobytwo"));
    assert_eq!(stored.len(), 1, "{}", logs(scratch, "twobytwo"));
    let record = &stored[0];
    assert_eq!(record["status"], "ok", "{record:?}");
    let cpus: Vec<usize> = record["cpus"]
        .as_array()
        .expect("a distributed record keeps each rank's CPUs")
        .iter()
        .map(|list| cpu_count(list.as_str().unwrap()))
        .collect();
    assert_eq!(
        cpus,
        [2, 2],
        "each rank sees two cores: {:?}",
        record["cpus"]
    );
    assert_eq!(record["oversubscribed"], false, "{record:?}");
}

/// The CPUs of a list such as `0-1,4`.
fn cpu_count(list: &str) -> usize {
    list.split(',')
        .map(|part| match part.split_once('-') {
            Some((a, b)) => b.parse::<usize>().unwrap() - a.parse::<usize>().unwrap() + 1,
            None => 1,
        })
        .sum()
}
