//! `nlstudy` as a process: make-style runs, failures stored and re-run on request, a changed
//! solver version explained, and an interrupted run resumed with nothing lost or duplicated.

use nonlocal_study::{binary, planned_keys, records, stored_keys, text, Scratch};
#[path = "support/parquet.rs"]
mod parquet;

use parquet::{floats, read_parquet};
use polars::prelude::DataType;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn small_study(sizes: &[u64]) -> Value {
    json!({
        "name": "small",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": sizes, "threads": [1, 2]}}]
    })
}

/// What the solver can check without running is checked by `plan`: a time step above the
/// integrator's dt_stable (from the stencil's symbol) or `cfl` above 1 without
/// `allow_unstable`, each refused naming its field, its numbers to four significant digits.
#[test]
fn plan_refuses_a_time_step_the_run_would_refuse() {
    for (base, field, said) in [
        (
            json!({"dim": 1, "n": 64, "m": 2, "t_end": 0.1, "dt": 0.01, "integrator": "rk4"}),
            "`dt`",
            "gives dt = 0.01 above dt_stable = 0.0002901",
        ),
        (
            json!({"dim": 1, "n": 16, "m": 2, "t_end": 0.1, "cfl": 5}),
            "`cfl`",
            "above dt_stable",
        ),
        (
            json!({"method": "fd_explicit", "problem": "eigenmode", "dim": 2, "n": 16, "t_end": 0.1, "cfl": 1.5}),
            "`cfl`",
            "above dt_stable",
        ),
    ] {
        let scratch = Scratch::new("plan-dt", &json!({"name": "dt", "base": base}));
        let out = scratch.nlstudy("plan", &[]);
        let said_all = text(&out);
        assert_eq!(out.status.code(), Some(2), "{said_all}");
        assert!(
            said_all.contains(field) && said_all.contains(said),
            "{said_all}"
        );
        let numbers = said_all
            .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
            .filter(|w| w.contains('.') && w.parse::<f64>().is_ok());
        for number in numbers {
            let digits = number.split('e').next().unwrap().replace(['.', '-'], "");
            assert!(
                digits.trim_start_matches('0').len() <= 4,
                "{number} in {said_all}"
            );
        }
    }
}

#[test]
fn a_second_run_runs_nothing_and_a_new_axis_value_runs_only_its_points() {
    let scratch = Scratch::new("cache", &small_study(&[16, 32]));
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    assert!(text(&first).contains("4 ran (4 ok"), "{}", text(&first));
    let stored = records(&scratch.runs("small"));
    assert_eq!(stored.len(), 4);
    assert!(stored
        .iter()
        .all(|r| r["status"] == "ok" && r["key"].is_string()));

    let second = scratch.nlstudy("run", &[]);
    assert!(text(&second).contains("0 ran"), "{}", text(&second));
    assert!(
        text(&second).contains("4 already stored"),
        "{}",
        text(&second)
    );

    scratch.write_study(&small_study(&[16, 32, 64]));
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert_eq!(plan.matches("run   (missing)").count(), 2, "{plan}");
    assert!(plan.contains("2 to run, 4 stored"), "{plan}");
    let third = scratch.nlstudy("run", &[]);
    assert!(text(&third).contains("2 ran (2 ok"), "{}", text(&third));
    assert_eq!(records(&scratch.runs("small")).len(), 6);
}

#[test]
fn a_refused_case_stops_the_run_unless_allowed_then_is_stored_as_failed() {
    // n = 2 cannot hold m = 2 (ε = 1 > 0.5): the solver refuses it.
    let scratch = Scratch::new("failed", &small_study(&[2, 16]));
    for command in ["plan", "run"] {
        let stopped = scratch.nlstudy(command, &[]);
        assert_eq!(stopped.status.code(), Some(2), "{}", text(&stopped));
        // The refusal said once for both points it refuses, with the way on.
        assert_eq!(
            text(&stopped).matches("case field `m`").count(),
            1,
            "{}",
            text(&stopped)
        );
        assert!(
            text(&stopped).contains("2 points (first: n=2 threads=1)"),
            "{}",
            text(&stopped)
        );
        assert!(
            text(&stopped).contains("--allow-refused"),
            "{}",
            text(&stopped)
        );
    }
    assert!(records(&scratch.runs("small")).is_empty(), "nothing ran");
    let run = scratch.nlstudy("run", &["--allow-refused"]);
    assert_eq!(run.status.code(), Some(1), "{}", text(&run));
    let stored = records(&scratch.runs("small"));
    assert_eq!(stored.len(), 4);
    let failed: Vec<&Value> = stored.iter().filter(|r| r["status"] == "failed").collect();
    assert_eq!(failed.len(), 2);
    assert!(failed[0]["message"].as_str().unwrap().contains("`m`"));
    let status = text(&scratch.nlstudy("status", &[]));
    assert!(status.contains("2 failed, 2 ok"), "{status}");

    let again = text(&scratch.nlstudy("plan", &["--allow-refused"]));
    assert!(
        again.contains("0 to run"),
        "failed runs are not retried unasked: {again}"
    );
    // A refused point is not said to run: it never starts, and is stored failed again.
    let retry = text(&scratch.nlstudy("plan", &["--rerun-failed", "--allow-refused"]));
    assert_eq!(
        retry.matches("refused (stored as failed, not run)").count(),
        2,
        "{retry}"
    );
    assert!(retry.contains("0 to run, 2 refused, 2 stored"), "{retry}");
    assert!(!retry.contains("run   ("), "{retry}");
}

#[test]
fn run_collects_every_run_into_parquet_and_a_summary_per_point() {
    let mut study = small_study(&[16, 32]);
    study["repeat"] = json!(2);
    let scratch = Scratch::new("collect", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    the_same_when_sliced(&scratch);
    let table = |name: &str| scratch.dir.join("results/small").join(name);

    // One row per run and repeat, flat columns of the case, results, timings and provenance.
    let runs = read_parquet(&table("small.parquet"));
    assert_eq!(runs.height(), 8);
    for column in [
        "point",
        "refinement_series",
        "scaling_series",
        "key",
        "case_id",
        "repeat",
        "status",
        "case.n",
        "case.threads",
        "threads",
        "ranks",
        "run_id",
        "case.m",
        "h",
        "eps",
        "bonds",
        "steps_done",
        "solve_s",
        "step_s",
        "error_l2_norm",
        "error_max",
        "provenance.host",
        "solver_version",
    ] {
        assert!(
            runs.column(column).is_ok(),
            "{column} missing: {:?}",
            runs.get_column_names()
        );
    }
    assert_eq!(runs.column("case.n").unwrap().dtype(), &DataType::Int64);
    assert_eq!(runs.column("solve_s").unwrap().dtype(), &DataType::Float64);
    assert_eq!(runs.column("status").unwrap().dtype(), &DataType::String);
    // The case as resolved: defaults the study left out are filled in, never null.
    for (column, default) in [
        ("case.quadrature", "midpoint"),
        ("case.integrator", "forward_euler"),
        ("case.source", "continuum"),
    ] {
        let cells = runs
            .column(column)
            .unwrap_or_else(|e| panic!("{column}: {e}"));
        let cells = cells.str().unwrap();
        assert!(
            (0..cells.len()).all(|i| cells.get(i) == Some(default)),
            "{column}: {cells:?}"
        );
    }

    // One row per point; its timings are the median of its repeats' (two: their mean).
    let summary = read_parquet(&table("small-summary.parquet"));
    assert_eq!(summary.height(), 4);
    let (n, threads) = (floats(&summary, "case.n"), floats(&summary, "case.threads"));
    let solve_s = floats(&runs, "solve_s");
    let (run_n, run_threads) = (floats(&runs, "case.n"), floats(&runs, "case.threads"));
    let median = |point: usize| {
        let times: Vec<f64> = (0..runs.height())
            .filter(|&r| run_n[r] == n[point] && run_threads[r] == threads[point])
            .map(|r| solve_s[r])
            .collect();
        assert_eq!(times.len(), 2);
        (times[0] + times[1]) / 2.0
    };
    let medians = floats(&summary, "solve_s_median");
    let (speedup, efficiency) = (floats(&summary, "speedup"), floats(&summary, "efficiency"));
    for point in 0..4 {
        assert!((medians[point] - median(point)).abs() <= 1e-15 * median(point));
        // The baseline of each grid is its 1-thread point.
        let base = (0..4)
            .find(|&b| n[b] == n[point] && threads[b] == 1.0)
            .unwrap();
        let expected = median(base) / median(point);
        assert!((speedup[point] - expected).abs() < 1e-12 * expected);
        assert!((efficiency[point] - expected / threads[point]).abs() < 1e-12);
    }
    // The observed order between the grids, from the errors and the h of both.
    let (h, error) = (floats(&summary, "h"), floats(&summary, "error_l2_norm"));
    let order = floats(&summary, "order_l2");
    let (coarse, fine) = (
        (0..4).find(|&p| n[p] == 16.0).unwrap(),
        (0..4).find(|&p| n[p] == 32.0).unwrap(),
    );
    let expected = (error[coarse] / error[fine]).ln() / (h[coarse] / h[fine]).ln();
    assert!((order[fine] - expected).abs() < 1e-12, "{order:?}");
    assert!(order[coarse].is_nan(), "the coarsest grid has no order");

    // Points dropped from the study leave the tables; their records stay stored.
    let mut fewer = small_study(&[16]);
    fewer["repeat"] = json!(2);
    scratch.write_study(&fewer);
    let collect = scratch.nlstudy("collect", &[]);
    assert!(collect.status.success(), "{}", text(&collect));
    assert!(
        text(&collect).contains("4 stored records are left out"),
        "{}",
        text(&collect)
    );
    assert_eq!(read_parquet(&table("small-summary.parquet")).height(), 2);
    assert_eq!(records(&scratch.runs("small")).len(), 8);
}

#[test]
fn plan_explains_a_changed_solver_version() {
    let scratch = Scratch::new("version", &small_study(&[16]));
    assert!(scratch.nlstudy("run", &[]).status.success());
    // A solver that reports another version and otherwise is nlsolve.
    let wrapper = shell_wrapper(
        &scratch,
        "nlsolve-next",
        "if [ \"$1\" = --version ]; then echo 'nlsolve 9.9.9'; exit 0; fi",
    );
    let plan = text(&scratch.nlstudy("plan", &["--solver", wrapper.to_str().unwrap()]));
    assert_eq!(
        plan.matches("run   (solver version changed (was nlsolve 0.1.0))")
            .count(),
        2,
        "{plan}"
    );
}

/// A plan asks `nlsolve check` only of cases this solver build has not checked before: the
/// verdicts are kept beside the store (`.verdicts`), and a plan made of them says what a plan
/// that asked says, to the byte: refusals, cases this machine has too few cores for, repeats.
#[test]
fn a_plan_of_kept_verdicts_says_what_the_solver_said() {
    let scratch = Scratch::new("verdicts", &small_study(&[16]));
    assert!(scratch.nlstudy("run", &[]).status.success());
    let mut study = small_study(&[16, 24]);
    study["sweep"][0]["product"]["threads"] = json!([1, 2, 1000]);
    study["sweep"][0]["product"]["m"] = json!([2, 200]);
    study["repeat"] = json!(2);
    scratch.write_study(&study);
    // A solver that writes down what it is asked to do, and otherwise is nlsolve.
    let asked = scratch.dir.join("asked");
    let log = format!("echo \"$1\" >>{}", asked.display());
    let wrapper = shell_wrapper(&scratch, "nlsolve-logged", &log);
    let plan = || {
        let _ = std::fs::remove_file(&asked);
        let out = scratch.nlstudy("plan", &["--solver", wrapper.to_str().unwrap()]);
        let asked = std::fs::read_to_string(&asked).unwrap();
        (
            out.status.code(),
            text(&out),
            asked.lines().any(|verb| verb == "check"),
        )
    };
    let (status, said, checked) = plan();
    assert!(checked);
    assert_eq!(status, Some(2), "m = 200 is refused: {said}");
    assert!(
        said.contains("do not fit this machine") && said.contains("`m`"),
        "{said}"
    );
    let kept = scratch.dir.join("results/small/.verdicts");
    assert!(kept.is_file());
    let (status_again, said_again, checked_again) = plan();
    assert_eq!((status_again, &said_again), (status, &said));
    assert!(!checked_again, "every verdict was kept");
    // A file of verdicts that is not whole is asked again where it is not.
    let text_kept = std::fs::read(&kept).unwrap();
    std::fs::write(&kept, &text_kept[..text_kept.len() * 2 / 3]).unwrap();
    let (status_cut, said_cut, checked_cut) = plan();
    assert_eq!((status_cut, &said_cut, checked_cut), (status, &said, true));
    assert_eq!(plan(), (status, said, false));
}

/// A refinement at fixed ε whose step comes from `cfl` keeps its time error as h shrinks, which
/// the observed orders come to measure: `plan` says so once, naming the first such series, and
/// says nothing where the step shrinks with h (derived, or ε = m·h).
#[test]
fn plan_notes_a_refinement_at_fixed_eps_whose_step_does_not_shrink() {
    let study = |base: Value, derive: Value| {
        json!({
            "name": "refined",
            "base": base,
            "derive": derive,
            "sweep": [{"product": {"n": [16, 32, 64], "kernel": ["constant", "linear"]}}]
        })
    };
    let fixed = json!({"dim": 1, "eps": 0.125, "t_end": 0.01, "cfl": 0.5});
    let derived = json!({"dim": 1, "eps": 0.125, "t_end": 0.01});
    let moving = json!({"dim": 1, "m": 2, "t_end": 0.01, "cfl": 0.5});
    let said = |base: Value, derive: Value| {
        let scratch = Scratch::new("refined", &study(base, derive));
        let out = scratch.nlstudy("plan", &[]);
        assert!(out.status.success(), "{}", text(&out));
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let noted = said(fixed, json!({}));
    assert_eq!(noted.matches("nlstudy: note: ").count(), 1, "{noted}");
    assert!(
        noted.contains("2 refinement series hold `eps` fixed")
            && noted.contains("(first: kernel=constant)"),
        "{noted}"
    );
    assert!(!said(derived, json!({"dt": "h^2/4"})).contains("note"));
    assert!(!said(moving, json!({})).contains("note"));
}

#[test]
fn an_interrupted_run_resumes_with_every_record_once() {
    // Ctrl-C, a scheduler's warning (or scancel, or a preemption), a closed session: each
    // sent to nlstudy alone, which ends its solvers itself.
    for (signal, status) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        interrupted_by(signal, status);
    }
}

/// `--quiet`, on any command, leaves out the notes of what was made and keeps the results, the
/// warnings and why a command failed: the one reporter (`console`) decides, for every command.
#[test]
fn quiet_keeps_results_warnings_and_failures_and_drops_the_notes() {
    let study = json!({
        "name": "hush",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": [16, 32]}}]
    });
    let scratch = Scratch::new("quiet", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(
        said.contains("study hush: 2 ran") && said.contains("tables: "),
        "{said}"
    );
    let (loud, quiet) = (
        scratch.nlstudy("collect", &[]),
        scratch.nlstudy("collect", &["--quiet"]),
    );
    assert!(quiet.status.success(), "{}", text(&quiet));
    assert!(String::from_utf8_lossy(&loud.stderr).contains("tables: "));
    assert_eq!(
        String::from_utf8_lossy(&quiet.stderr),
        "",
        "notes under --quiet"
    );
    assert!(!quiet.stdout.is_empty(), "the overview is the result");
    assert_eq!(quiet.stdout, loud.stdout);
    // Before the command's name too, and the failure is said.
    let failed = Command::new(binary("nlstudy"))
        .args(["-q", "plot"])
        .arg(scratch.study())
        .arg("--results")
        .arg(scratch.dir.join("results"))
        .output()
        .unwrap();
    assert_eq!(failed.status.code(), Some(2), "{}", text(&failed));
    let why = String::from_utf8_lossy(&failed.stderr);
    assert!(
        why.starts_with("nlstudy: study hush lists no figures"),
        "{why}"
    );
    // A warning is said under --quiet: a point the solver refuses (n = 2 cannot hold m = 2),
    // after the plan's listing, which is the result.
    let refused = Scratch::new("quiet-refused", &small_study(&[2, 16]));
    let planned = refused.nlstudy("plan", &["-q", "--allow-refused"]);
    assert!(planned.status.success(), "{}", text(&planned));
    assert!(String::from_utf8_lossy(&planned.stdout).contains("refused (stored as failed"));
    let warned = String::from_utf8_lossy(&planned.stderr);
    assert!(
        warned.starts_with("nlstudy: warning: the solver refuses 2 points"),
        "{warned}"
    );
}

fn interrupted_by(signal: &str, status: i32) {
    let study = json!({
        "name": "long",
        "base": {"dim": 2, "m": 2, "t_end": 0.002, "cfl": 0.5},
        "sweep": [{"product": {"n": [48, 64, 80, 96, 112, 128]}}]
    });
    let scratch = Scratch::new(&format!("interrupt-{signal}"), &study);
    let child = Command::new(binary("nlstudy"))
        .arg("run")
        .arg(scratch.study())
        .arg("--results")
        .arg(scratch.dir.join("results"))
        .arg("--quiet")
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Interrupt as soon as the first record is stored.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while records(&scratch.runs("long")).is_empty() && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    let interrupted = child.wait_with_output().unwrap();
    let stored_before = records(&scratch.runs("long")).len();
    assert!(stored_before >= 1);
    if stored_before < 6 {
        let said = String::from_utf8_lossy(&interrupted.stderr);
        assert_eq!(
            interrupted.status.code(),
            Some(status),
            "SIG{signal}: {said}"
        );
        assert!(said.contains(&format!("stopped by SIG{signal}")), "{said}");
    }
    let stray: Vec<String> = std::fs::read_dir(scratch.runs("long"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| !name.starts_with('.') && name != "segments")
        .collect();
    assert!(
        stray.is_empty(),
        "SIG{signal} left half-written files: {stray:?}"
    );
    let resumed = scratch.nlstudy("run", &[]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    let stored = records(&scratch.runs("long"));
    assert_eq!(stored.len(), 6, "every point once");
    assert_eq!(
        stored_keys(&stored),
        planned_keys(&scratch),
        "the study's points"
    );
    assert!(stored.iter().all(|r| r["status"] == "ok"));
}

/// The scripts of a two-point study: directives from the study's resources and the flags, and a
/// command that runs exactly the two keys in the same record store.
#[test]
fn slurm_and_lsf_scripts_hold_the_directives_and_the_keys() {
    let study = json!({
        "name": "two",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"zip": {"n": [16, 32], "threads": [1, 2], "ranks": [2, 1]}}],
        "resources": {"time": "01:30:00", "queue": "normal", "account": "nonlocal"}
    });
    let scratch = Scratch::new("submit", &study);
    let plan = text(&scratch.nlstudy("plan", &[]));
    let keys: Vec<&str> = plan
        .lines()
        .filter(|l| l.contains("run   (missing)"))
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    assert_eq!(keys.len(), 2, "{plan}");
    std::fs::create_dir_all(scratch.dir.join("results")).unwrap();
    let absolute = |p: PathBuf| std::fs::canonicalize(p).unwrap().display().to_string();
    let results = || absolute(scratch.dir.join("results"));
    // Each word as the scripts quote it (shlex: a path of plain characters stays bare). A job
    // names its points costliest first: n = 32 before n = 16.
    let word = |w: String| shlex::try_quote(&w).unwrap().into_owned();
    let costliest_first = [keys[1], keys[0]];
    let command = |launcher: &str, export: &str| {
        format!(
            "set -eo pipefail\nset -u\n{export}exec {} run {} --results {} --solver {} --launcher '{launcher}' --no-collect -j 4 --only '{}'\n",
            word(binary("nlstudy").display().to_string()),
            word(absolute(scratch.study())),
            word(results()),
            word(absolute(binary("nlsolve"))),
            costliest_first.join(",")
        )
    };
    let jobs = format!("{}/two/jobs", results());

    let slurm = scratch.nlstudy("submit", &["--scheduler", "slurm", "--dry-run"]);
    assert!(slurm.status.success(), "{}", text(&slurm));
    let script = std::fs::read_to_string(format!("{jobs}/nlstudy-two-0.sbatch")).unwrap();
    let expected = format!(
        "#!/bin/bash\n#SBATCH --job-name=nlstudy-two-0\n#SBATCH --nodes=1\n#SBATCH --ntasks=2\n\
         #SBATCH --cpus-per-task=2\n#SBATCH --time=01:30:00\n#SBATCH --partition=normal\n\
         #SBATCH --account=nonlocal\n#SBATCH --exclusive\n\
         #SBATCH --output=\"{jobs}/nlstudy-two-0.%j.out\"\n#SBATCH --open-mode=append\n\
         #SBATCH --signal=B:TERM@60\n#SBATCH --requeue\n{}",
        command(
            "srun --mpi=pmix -n {ranks} -c {threads}",
            "export SRUN_CPUS_PER_TASK=\"${SLURM_CPUS_PER_TASK:-1}\"\n"
        )
    );
    assert_eq!(script, expected);
    // The structure both schedulers' scripts share (Slurm's also runs under a real sbatch in
    // tests/slurm.rs; LSF's can only be read here).
    check_job_structure(&script, "#SBATCH", &costliest_first);

    let lsf = scratch.nlstudy(
        "submit",
        &[
            "--scheduler",
            "lsf",
            "--dry-run",
            "--queue",
            "short",
            "--nodes",
            "2",
        ],
    );
    assert!(lsf.status.success(), "{}", text(&lsf));
    let script = std::fs::read_to_string(format!("{jobs}/nlstudy-two-0.bsub")).unwrap();
    let expected = format!(
        "#!/bin/bash\n#BSUB -J nlstudy-two-0\n#BSUB -n 2\n#BSUB -R \"affinity[core(2)]\"\n#BSUB -R \"span[ptile=1]\"\n#BSUB -W 1:30\n\
         #BSUB -q short\n#BSUB -P nonlocal\n#BSUB -x\n#BSUB -o \"{jobs}/nlstudy-two-0.%J.out\"\n\
         #BSUB -wa TERM\n#BSUB -wt 1\n#BSUB -r\n{}",
        command(
            "mpirun -n {ranks} --map-by slot:PE={threads} --bind-to core",
            ""
        )
    );
    assert_eq!(script, expected);
    check_job_structure(&script, "#BSUB", &costliest_first);
    // The Slurm script of the first submit is archived, not left beside the LSF one.
    assert!(!Path::new(&format!("{jobs}/nlstudy-two-0.sbatch")).exists());
    let archived = std::fs::read_dir(format!("{jobs}/archive"))
        .unwrap()
        .count();
    assert_eq!(archived, 1);

    // Retries pass on to each job's nlstudy run.
    let retrying = scratch.nlstudy(
        "submit",
        &["--scheduler", "slurm", "--dry-run", "--retries", "2"],
    );
    assert!(retrying.status.success(), "{}", text(&retrying));
    let script = std::fs::read_to_string(format!("{jobs}/nlstudy-two-0.sbatch")).unwrap();
    assert!(script.contains("--no-collect --retries 2 -j 4"), "{script}");

    // One case per job: two scripts, one key each, the costlier point (n = 32) first.
    let packed = scratch.nlstudy(
        "submit",
        &["--scheduler", "slurm", "--dry-run", "--cases-per-job", "1"],
    );
    assert!(
        text(&packed).contains("nlstudy-two-1 (1 cases, "),
        "{}",
        text(&packed)
    );
    let second = std::fs::read_to_string(format!("{jobs}/nlstudy-two-1.sbatch")).unwrap();
    assert!(
        second.ends_with(&format!("--only {}\n", shlex::try_quote(keys[0]).unwrap())),
        "{second}"
    );
}

/// A case that asks for fields gets its VTK frames under results/<study>/fields/<key>/, and a
/// field figure draws its snapshot from the summary table.
#[test]
fn fields_are_written_per_run_and_drawn_from_the_table() {
    let study = json!({
        "name": "fields",
        "base": {"dim": 2, "n": 24, "m": 2, "t_end": 0.004, "cfl": 0.5,
                 "field_snapshot": 8, "vtk_every": 0.002},
        "sweep": [{"product": {"threads": [1, 2]}}],
        "figures": [{"name": "final_field", "kind": "field", "where": ["threads == 1"]}]
    });
    let scratch = Scratch::new("fields", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let results = scratch.dir.join("results/fields");
    for record in records(&scratch.runs("fields")) {
        let key = record["key"].as_str().expect("a key");
        let collection = std::fs::read_to_string(results.join("fields").join(key).join("u.pvd"))
            .expect("the run's collection");
        assert_eq!(
            collection.matches("<DataSet").count(),
            3,
            "t = 0, 0.002, 0.004"
        );
        assert_eq!(record["field"]["values"].as_array().map(Vec::len), Some(64));
    }
    let svg = std::fs::read_to_string(results.join("figures/final_field.svg")).expect("the figure");
    assert!(svg.contains("error u − u_exact"));
}

/// A run with more workers than the machine has cores is stored as `oversubscribed`.
#[test]
fn runs_beyond_the_core_count_are_marked_oversubscribed() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let study = json!({
        "name": "crowded",
        "base": {"dim": 1, "n": 16, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"threads": [1, cores + 1]}}]
    });
    let scratch = Scratch::new("crowded", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let mut marks: Vec<(u64, bool)> = records(&scratch.runs("crowded"))
        .iter()
        .map(|r| {
            let threads = r["case"]["threads"].as_u64().unwrap();
            (threads, r["oversubscribed"].as_bool().expect("marked"))
        })
        .collect();
    marks.sort();
    assert_eq!(marks, [(1, false), (cores as u64 + 1, true)]);
}

/// Every study the project ships plans: its file parses and the solver accepts all its points.
#[test]
fn every_shipped_study_plans_without_a_refused_point() {
    let studies = Path::new(env!("CARGO_MANIFEST_DIR")).join("studies");
    let scratch = tempfile::tempdir().unwrap();
    let results = scratch.path().to_path_buf();
    let mut planned = 0;
    for entry in std::fs::read_dir(&studies).unwrap() {
        let path = entry.unwrap().path();
        let study_file = ["json", "jsonc", "toml"];
        if !path
            .extension()
            .is_some_and(|x| study_file.iter().any(|s| x == *s))
        {
            continue;
        }
        let out = Command::new(binary("nlstudy"))
            .arg("plan")
            .arg(&path)
            .arg("--results")
            .arg(&results)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}: {}", path.display(), text(&out));
        assert!(
            !text(&out).contains("refuse"),
            "{}: {}",
            path.display(),
            text(&out)
        );
        planned += 1;
    }
    assert!(planned >= 10, "{planned} studies");
}

/// Two branches that hold the same case run it once, and each keeps its row in the tables.
#[test]
fn a_case_shared_by_two_branches_runs_once_and_keeps_a_row_per_branch() {
    let study = json!({
        "name": "shared",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"branches": {
            "coarse": [{"product": {"n": [16, 32]}}],
            "fine": [{"product": {"n": [32, 64]}}]
        }}]
    });
    let scratch = Scratch::new("shared", &study);
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(
        plan.contains("3 to run, 0 stored, 1 the same case as an earlier point"),
        "{plan}"
    );
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    assert!(text(&run).contains("3 ran (3 ok"), "{}", text(&run));
    assert_eq!(records(&scratch.runs("shared")).len(), 3);
    let summary = read_parquet(&scratch.dir.join("results/shared/shared-summary.parquet"));
    assert_eq!(
        summary.height(),
        4,
        "a row per point, the shared case in both branches"
    );
}

/// A job script's structure: the shebang, then only scheduler directives (each an option with a
/// value), then strict shell mode and one `nlstudy run` of exactly the job's keys, with
/// absolute paths that exist, no tables written, the MPI launcher taking `{ranks}`, and a core
/// budget equal to the slots the directives ask for (Slurm: tasks × CPUs per task; LSF: -n).
fn check_job_structure(script: &str, directive: &str, keys: &[&str]) {
    let mut lines = script.lines();
    assert_eq!(lines.next(), Some("#!/bin/bash"), "{script}");
    let lines: Vec<&str> = lines.collect();
    let directives = lines.iter().take_while(|l| l.starts_with('#')).count();
    assert!(directives >= 4, "{script}");
    for line in &lines[..directives] {
        let rest = line
            .strip_prefix(directive)
            .unwrap_or_else(|| panic!("{line}: not {directive}"));
        assert!(
            rest.starts_with(' ') && rest.trim().starts_with('-'),
            "{line}"
        );
        let option = rest.trim();
        let switch = ["--exclusive", "--requeue", "-x", "-r"].contains(&option);
        assert!(
            switch || option.contains(' ') || option.contains('='),
            "{line}: an option without a value"
        );
    }
    // Slurm's steps take the job's cores per task from SRUN_CPUS_PER_TASK (Slurm ≥ 22.05).
    let body: Vec<&str> = lines[directives..]
        .iter()
        .copied()
        .filter(|l| !l.starts_with("export SRUN_CPUS_PER_TASK="))
        .collect();
    assert_eq!(
        lines.len() - directives - body.len(),
        usize::from(directive == "#SBATCH"),
        "{script}"
    );
    assert_eq!(body.len(), 3, "{script}");
    assert_eq!(body[..2], ["set -eo pipefail", "set -u"]);
    let words: Vec<&str> = body[2].split_whitespace().collect();
    assert_eq!(
        words[0], "exec",
        "the batch shell becomes nlstudy: {script}"
    );
    let value_of = |flag: &str| {
        let at = words
            .iter()
            .position(|w| *w == flag)
            .unwrap_or_else(|| panic!("no {flag}"));
        words[at + 1]
    };
    for path in [
        words[1],
        words[3],
        value_of("--results"),
        value_of("--solver"),
    ] {
        let path = path.trim_matches('\'');
        assert!(
            Path::new(path).is_absolute() && Path::new(path).exists(),
            "{path}"
        );
    }
    assert_eq!(words[2], "run");
    assert!(words.contains(&"--no-collect"));
    assert!(
        body[2].contains("--launcher '")
            && body[2].contains("{ranks}")
            && body[2].contains("{threads}"),
        "each rank asks for its threads' cores: {}",
        body[2]
    );
    assert_eq!(value_of("--only"), format!("'{}'", keys.join(",")));
    let asked = |option: &str| -> usize {
        let line = lines[..directives]
            .iter()
            .find_map(|l| l.strip_prefix(&format!("{directive} {option}")))
            .unwrap_or_else(|| panic!("no {option} in {script}"));
        line.trim_start_matches('=').trim().parse().unwrap()
    };
    let slots = match directive {
        "#SBATCH" => asked("--ntasks") * asked("--cpus-per-task"),
        // LSF: `-n` tasks, each with the cores of its `affinity[core(k)]` (one when absent).
        _ => {
            let cores = lines[..directives]
                .iter()
                .find_map(|l| l.split("affinity[core(").nth(1))
                .map_or(1, |rest| rest.split(')').next().unwrap().parse().unwrap());
            asked("-n") * cores
        }
    };
    assert_eq!(value_of("-j"), slots.to_string(), "{script}");
}

/// Two branches that sweep different fields: every row of the terminal summary and of the
/// report's table must differ from the others, the branch and each branch's own field shown.
#[test]
fn no_two_points_render_as_identical_rows() {
    let study = json!({
        "name": "apart",
        "base": {"dim": 1, "n": 16, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"branches": {
            "threads": [{"product": {"threads": [1, 2]}}],
            "steps": [{"product": {"cfl": [0.25, 0.5]}}]
        }}]
    });
    let scratch = Scratch::new("apart", &study);
    let run = scratch.nlstudy("run", &["--no-collect"]);
    assert!(run.status.success(), "{}", text(&run));
    let collect = scratch.nlstudy("collect", &[]);
    assert!(collect.status.success(), "{}", text(&collect));
    let rows: Vec<String> = String::from_utf8_lossy(&collect.stdout)
        .lines()
        .filter(|l| l.starts_with('|') && !l.contains("---"))
        .map(str::to_string)
        .collect();
    assert_eq!(rows.len(), 5, "a header and four points: {rows:?}");
    for field in ["branch", "threads", "cfl"] {
        assert!(rows[0].contains(field), "no column {field}: {}", rows[0]);
    }
    assert_distinct(&rows);

    let report = scratch.nlstudy("report", &[]);
    assert!(report.status.success(), "{}", text(&report));
    let page = std::fs::read_to_string(scratch.dir.join("results/apart/report.html")).unwrap();
    let summary = &page[page.find("<h2>Summary</h2>").expect("a summary")..];
    let summary = &summary[..summary.find("</table>").unwrap()];
    let rows: Vec<String> = summary.split("<tr>").skip(1).map(str::to_string).collect();
    assert_eq!(rows.len(), 5, "{summary}");
    assert_distinct(&rows);
}

fn assert_distinct(rows: &[String]) {
    for (k, row) in rows.iter().enumerate() {
        assert!(
            !rows[..k].contains(row),
            "two points look alike: {row}\n{rows:#?}"
        );
    }
}

/// A figure naming a column no table will have is a bad study file at `plan`, before anything
/// runs, not a failure after every case has run.
#[test]
fn a_misspelt_figure_column_stops_plan_and_run_before_anything_runs() {
    let mut study = small_study(&[16]);
    study["figures"] = json!([{"name": "c", "kind": "convergence", "y": "eror_l2_norm"}]);
    let scratch = Scratch::new("figure-typo", &study);
    for command in ["plan", "run"] {
        let out = scratch.nlstudy(command, &[]);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out));
        assert!(
            text(&out).contains("figures[0] (c).y")
                && text(&out).contains("did you mean `error_l2_norm`?"),
            "{}",
            text(&out)
        );
    }
    assert!(records(&scratch.runs("small")).is_empty(), "nothing ran");
}

/// Two study files with one `name` do not write over each other's results: the second is
/// refused until it adopts the directory. `clean` removes figures no spec draws and lists, then
/// with --yes deletes, the records no point has.
#[test]
fn a_results_directory_belongs_to_one_study_file_and_clean_clears_what_it_no_longer_makes() {
    let mut study = small_study(&[16, 32]);
    study["figures"] = json!([
        {"name": "convergence", "kind": "convergence"},
        {"name": "scaling", "kind": "strong_scaling"}
    ]);
    let scratch = Scratch::new("owner", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));

    let other = scratch.dir.join("other.json");
    std::fs::write(&other, small_study(&[16]).to_string()).unwrap();
    let results = scratch.dir.join("results");
    let nlstudy = |verb: &str, extra: &[&str]| {
        Command::new(binary("nlstudy"))
            .arg(verb)
            .arg(&other)
            .arg("--results")
            .arg(&results)
            .args(extra)
            .output()
            .unwrap()
    };
    for verb in ["plan", "run", "collect"] {
        let refused = nlstudy(verb, &[]);
        assert_eq!(refused.status.code(), Some(2), "{verb}: {}", text(&refused));
        assert!(
            text(&refused).contains("another study file of the same name")
                && text(&refused).contains("--adopt"),
            "{}",
            text(&refused)
        );
    }
    // Adopted, the other file reuses the stored runs of its points: nothing runs.
    let adopted = nlstudy("run", &["--adopt"]);
    assert!(text(&adopted).contains("0 ran"), "{}", text(&adopted));
    assert_eq!(scratch.nlstudy("plan", &[]).status.code(), Some(2));

    // Back to the first file, with one figure and one grid fewer.
    let mut smaller = small_study(&[16]);
    smaller["figures"] = json!([{"name": "scaling", "kind": "strong_scaling"}]);
    scratch.write_study(&smaller);
    let listed = scratch.nlstudy("clean", &["--adopt"]);
    assert!(listed.status.success(), "{}", text(&listed));
    let figures = results.join("small/figures");
    assert!(!figures.join("convergence.svg").exists() && figures.join("scaling.svg").exists());
    assert!(
        text(&listed).contains("removed figures/convergence.svg")
            && text(&listed).contains("2 stored records are no point"),
        "{}",
        text(&listed)
    );
    assert_eq!(
        records(&scratch.runs("small")).len(),
        4,
        "listed, not deleted"
    );
    let deleted = scratch.nlstudy("clean", &["--yes"]);
    assert!(
        text(&deleted).contains("deleted 2 records"),
        "{}",
        text(&deleted)
    );
    assert_eq!(records(&scratch.runs("small")).len(), 2);
}

/// A solver of another fingerprint (a wrapper that reports one, and writes it into the records
/// it passes on) makes every stored point stale: `plan` says so, `--keep-stale` reuses them,
/// `run` runs them again and keeps the superseded records in the study's history.
#[test]
fn another_solver_makes_stored_points_stale_and_their_old_records_go_to_history() {
    let scratch = Scratch::new("stale", &small_study(&[16]));
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let real = binary("nlsolve");
    let other = "f".repeat(64);
    let wrapper = scratch.dir.join("other-nlsolve");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\nif [ \"$1\" = fingerprint ]; then echo {other}; exit 0; fi\nout=$('{}' \"$@\")\nstatus=$?\nprintf '%s\\n' \"$out\" | sed 's/\"fingerprint\":\"[0-9a-f]*\"/\"fingerprint\":\"{other}\"/'\nexit $status\n",
            real.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let with_other = |verb: &str, extra: &[&str]| {
        // The wrapper prints what the solver printed once it has ended: one process per case.
        let mut args = vec!["--solver", wrapper.to_str().unwrap()];
        if verb == "run" {
            args.push("--isolate");
        }
        args.extend_from_slice(extra);
        scratch.nlstudy(verb, &args)
    };

    let plan = text(&with_other("plan", &[]));
    assert_eq!(plan.matches("stale: solver changed (").count(), 2, "{plan}");
    assert!(
        plan.contains("→ ffffffff)") && plan.contains("2 to run"),
        "{plan}"
    );
    let kept = text(&with_other("plan", &["--keep-stale"]));
    assert!(
        kept.contains("0 to run") && kept.contains("stale but kept"),
        "{kept}"
    );

    let rerun = with_other("run", &[]);
    assert!(text(&rerun).contains("2 ran (2 ok"), "{}", text(&rerun));
    let history: Vec<_> = std::fs::read_dir(scratch.dir.join("results/small/history"))
        .expect("a history")
        .flatten()
        .collect();
    assert_eq!(history.len(), 2, "the superseded records are kept");
    for record in records(&scratch.runs("small")) {
        assert_eq!(record["provenance"]["fingerprint"], json!(other));
    }
    assert!(text(&with_other("plan", &[])).contains("0 to run"));
    // The superseded build is found by its fingerprint (its runs are single: no interval).
    let real_build = text(&Command::new(&real).arg("fingerprint").output().unwrap());
    let by_build = format!("fingerprint:{}", &real_build.trim()[..8]);
    let compared = text(&with_other("compare", &["--against", &by_build]));
    assert!(compared.contains("no interval can be formed"), "{compared}");
    let unknown = text(&with_other("compare", &["--against", "fingerprint:0123"]));
    assert!(
        unknown.contains("no stored or superseded record"),
        "{unknown}"
    );
    // Two builds, neither of them necessarily current: B by --of.
    let two = ["--of", "fingerprint:ffff", "--against", &by_build];
    let compared = text(&scratch.nlstudy("compare", &two));
    assert!(compared.contains("no interval can be formed"), "{compared}");
    let unknown = text(&scratch.nlstudy(
        "compare",
        &["--of", "fingerprint:0123", "--against", "history"],
    ));
    assert!(unknown.contains("--of fingerprint"), "{unknown}");
    // Back to the real solver: its points are stale again.
    let back = text(&scratch.nlstudy("plan", &[]));
    assert_eq!(
        back.matches("stale: solver changed (ffffffff").count(),
        2,
        "{back}"
    );

    // Kept, beside new points of the real solver: one table would mix two builds.
    scratch.write_study(&small_study(&[16, 32]));
    let mixed = scratch.nlstudy("run", &["--keep-stale"]);
    assert_eq!(mixed.status.code(), Some(1), "{}", text(&mixed));
    assert!(
        text(&mixed).contains("the runs mix solver fingerprints: ffffffff (2 runs)")
            && text(&mixed).contains("--allow-mixed"),
        "{}",
        text(&mixed)
    );
    let allowed = scratch.nlstudy("collect", &["--allow-mixed"]);
    assert!(allowed.status.success(), "{}", text(&allowed));
}

/// `compare` against a results directory. A solver wrapper reports timings of a judgeable
/// scale (0.2 s × $FACTOR, within 1 %): a baseline a quarter as long makes every timing worse,
/// with an interval above 1 and beyond the noise floor; a set against itself changes nothing; a
/// point of one side is listed. Refused: unlike machines, a side of two builds, single runs, a
/// directory that does not exist and another study's results, and a refused compare leaves the
/// results directory's owner as it was. The same study file copied elsewhere is the same study.
#[test]
fn compare_calls_a_true_slowdown_and_refuses_what_does_not_compare() {
    let mut study = small_study(&[16]);
    study["repeat"] = json!(3);
    let scratch = Scratch::new("compare", &study);
    let wrapper = timing_wrapper(&scratch);
    let run_into = |study: &Path, dir: &str, env: &[(&str, &str)]| {
        let out = Command::new(binary("nlstudy"))
            .args(["run", "--no-collect", "--results"])
            .arg(scratch.dir.join(dir))
            .arg("--solver")
            .arg(&wrapper)
            .arg(study)
            .envs(env.iter().copied())
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", text(&out));
    };
    let side = |dir: &str, env: &[(&str, &str)]| run_into(&scratch.study(), dir, env);
    let compare = |against: &str, extra: &[&str]| {
        let against = scratch.dir.join(against);
        let mut args = vec!["--against", against.to_str().unwrap(), "--solver"];
        args.push(wrapper.to_str().unwrap());
        args.extend_from_slice(extra);
        scratch.nlstudy("compare", &args)
    };
    side("results", &[]);
    side("faster", &[("FACTOR", "0.25")]);
    let slower = compare("faster", &[]);
    assert_eq!(slower.status.code(), Some(1), "{}", text(&slower));
    let slower = text(&slower);
    let worse: Vec<&str> = slower
        .lines()
        .filter(|l| l.contains("| solve_s |"))
        .collect();
    assert_eq!(worse.len(), 2, "{slower}");
    for line in worse {
        assert!(line.ends_with("| worse |"), "{line}");
        let low: f64 = line
            .split('[')
            .nth(1)
            .unwrap()
            .split(',')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(low > 1.1, "{line}");
    }
    let compared = scratch.dir.join("results/small");
    assert!(compared.join("compare.parquet").exists() && compared.join("compare.svg").exists());
    // The figure marks what the exit status counts.
    let svg = std::fs::read_to_string(compared.join("compare.svg")).unwrap();
    assert!(svg.contains("worse"), "the figure shows the regressions");
    // The same runs on both sides: nothing changed.
    let itself = compare("results", &[]);
    assert!(itself.status.success(), "{}", text(&itself));
    assert!(!text(&itself).contains("| worse |") && !text(&itself).contains("| better |"));
    let svg = std::fs::read_to_string(compared.join("compare.svg")).unwrap();
    assert!(!svg.contains("worse"), "no regression, no worse mark");

    // Unlike machines are refused unless allowed.
    side("elsewhere", &[("CPU", "another CPU")]);
    let unlike = compare("elsewhere", &[]);
    assert_eq!(unlike.status.code(), Some(2), "{}", text(&unlike));
    assert!(
        text(&unlike).contains("unlike machines"),
        "{}",
        text(&unlike)
    );
    assert!(compare("elsewhere", &["--allow-unlike"]).status.code() != Some(2));

    // A side whose runs come from two builds is refused, as `collect` refuses it.
    // Edited as a file of the store's older layout, which supersedes the segment's record.
    let mixed = scratch.dir.join("faster/small/runs");
    let mut record = records(&mixed).swap_remove(0);
    record["provenance"]["fingerprint"] = json!("ab".repeat(32));
    let key = record["key"].as_str().unwrap().to_string();
    std::fs::write(mixed.join(format!("{key}.json")), record.to_string()).unwrap();
    let two_builds = compare("faster", &[]);
    assert_eq!(two_builds.status.code(), Some(2), "{}", text(&two_builds));
    assert!(
        text(&two_builds).contains("side A"),
        "{}",
        text(&two_builds)
    );
    assert_eq!(compare("faster", &["--allow-mixed"]).status.code(), Some(1));

    // A point stored on one side only is listed.
    let mut grown = small_study(&[16, 32]);
    grown["repeat"] = json!(3);
    scratch.write_study(&grown);
    side("results", &[]);
    let one_sided = compare("elsewhere", &["--allow-unlike"]);
    assert_eq!(
        text(&one_sided).matches("only in B: n=32").count(),
        2,
        "{}",
        text(&one_sided)
    );

    // The same study in another checkout (a copy of the file, the same text) compares.
    let copy = scratch.dir.join("checkout/study.json");
    std::fs::create_dir_all(copy.parent().unwrap()).unwrap();
    std::fs::copy(scratch.study(), &copy).unwrap();
    run_into(&copy, "theirs", &[]);
    let same = compare("theirs", &[]);
    assert!(same.status.success(), "{}", text(&same));
    // Another study's results, a directory that is not there, and single runs are refused; a
    // refused compare takes no results directory.
    let other = scratch.dir.join("other.json");
    let mut different = grown.clone();
    different["description"] = json!("another study of the same name");
    std::fs::write(&other, different.to_string()).unwrap();
    run_into(&other, "foreign", &[]);
    let foreign = compare("foreign", &[]);
    assert_eq!(foreign.status.code(), Some(2), "{}", text(&foreign));
    assert!(
        text(&foreign).contains("compare result sets of one study"),
        "{}",
        text(&foreign)
    );
    let owner = std::fs::read_to_string(compared.join("study-file.json")).unwrap();
    let nowhere = Command::new(binary("nlstudy"))
        .args(["compare", "--adopt", "--against"])
        .arg(scratch.dir.join("nowhere"))
        .arg("--results")
        .arg(scratch.dir.join("results"))
        .arg(&other)
        .output()
        .unwrap();
    assert_eq!(nowhere.status.code(), Some(2), "{}", text(&nowhere));
    assert!(
        text(&nowhere).contains("no such directory"),
        "{}",
        text(&nowhere)
    );
    assert_eq!(
        std::fs::read_to_string(compared.join("study-file.json")).unwrap(),
        owner,
        "a refused compare adopts nothing"
    );
    scratch.write_study(&small_study(&[16]));
    let single = compare("faster", &[]);
    assert!(
        text(&single).contains("no interval can be formed"),
        "{}",
        text(&single)
    );
}

/// A/A comparisons do not depend on timing here: a solver wrapper reports timings drawn from one
/// distribution (0.2 s × n/16, a factor per `nlstudy run` of σ 3 % set by the test, 1 % per run
/// from the key and a seed), as a quiet machine would. Twenty reruns with `--force`, each
/// compared with the one it replaced (`--against history`), call no change and exit 0; then one
/// point 1.5× slower is called worse, and only it.
#[test]
fn a_to_a_comparisons_call_nothing_twenty_times_and_a_slower_point_is_called() {
    let study = json!({
        "name": "aa",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5},
        "sweep": [{"product": {"n": [16, 18, 20, 22, 24, 26, 28, 30, 32, 34], "threads": [1, 2]}}],
        "repeat": 3,
        "share_machine": true
    });
    let scratch = Scratch::new("a-to-a", &study);
    // A shell script, not Python: 1300 runs. Each case's real record is made once and kept;
    // its timings, timestamp and load are then drawn anew for every run.
    let wrapper = scratch.dir.join("drawn-nlsolve");
    let kept = scratch.dir.join("records");
    std::fs::create_dir_all(&kept).unwrap();
    std::fs::write(
        &wrapper,
        format!(
            r#"#!/bin/sh
[ "$1" = run ] || exec '{real}' "$@"
case_file=$3
key=$(basename "$case_file" .case.json)
kept='{kept}'/$key.json
[ -s "$kept" ] || '{real}' "$@" > "$kept" 2>/dev/null || exit $?
awk -v factor="$RUN_FACTOR" -v seed="$RUN_SEED" -v key="$key" -v slow="$SLOW_N" -v now="$(date -u +%Y-%m-%dT%H:%M:%SZ)" '{{
    h = 0; s = key seed
    for (i = 1; i <= length(s); i++) h = (h * 31 + index("0123456789abcdef", substr(s, i, 1))) % 1000
    match($0, /"n":[0-9]+/); n = substr($0, RSTART + 4, RLENGTH - 4)
    t = 0.2 * n / 16 * factor * (1 + 0.01 * (h / 500 - 1)) * (n == slow ? 1.5 : 1)
    match($0, /"steps_done":[0-9]+/); steps = substr($0, RSTART + 13, RLENGTH - 13)
    gsub(/"solve_s":[^,}}]+/, "\"solve_s\":" t)
    gsub(/"step_s":[^,}}]+/, "\"step_s\":" t / (steps > 0 ? steps : 1))
    gsub(/"setup_s":[^,}}]+/, "\"setup_s\":" t / 4)
    gsub(/"noisy":true/, "\"noisy\":false")
    gsub(/"timestamp":"[^"]*"/, "\"timestamp\":\"" now "\"")
    print
}}' "$kept"
"#,
            real = binary("nlsolve").display(),
            kept = kept.display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    // The run factors: exp(0.03 z), z standard normal (Box–Muller over a fixed sequence).
    let mut rng = fastrand::Rng::with_seed(0x5eed);
    // In (0, 1]: the logarithm below is finite.
    let mut uniform = || 1.0 - rng.f64();
    let mut factor = || {
        let z = (-2.0 * uniform().ln()).sqrt() * (2.0 * std::f64::consts::PI * uniform()).cos();
        (0.03 * z).exp().to_string()
    };
    let run = |k: usize, factor: &str, slow: &str| {
        let out = scratch
            .command(
                "run",
                &[
                    "--no-collect",
                    "--force",
                    "--isolate",
                    "--solver",
                    wrapper.to_str().unwrap(),
                ],
            )
            .env("RUN_FACTOR", factor)
            .env("RUN_SEED", k.to_string())
            .env("SLOW_N", slow)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", text(&out));
    };
    let compare = || {
        let args = [
            "--against",
            "history",
            "--solver",
            wrapper.to_str().unwrap(),
        ];
        scratch.nlstudy("compare", &args)
    };
    run(0, &factor(), "");
    for k in 1..=20 {
        run(k, &factor(), "");
        let out = compare();
        let said = text(&out);
        assert_eq!(out.status.code(), Some(0), "A/A {k}: {said}");
        assert!(
            !said.contains("| worse |") && !said.contains("| better |"),
            "A/A {k}: {said}"
        );
        assert!(
            said.contains("| speedup |"),
            "speedups are compared too: {said}"
        );
    }
    run(21, &factor(), "24");
    let out = compare();
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    let worse: Vec<&str> = said.lines().filter(|l| l.ends_with("| worse |")).collect();
    assert!(
        worse
            .iter()
            .any(|l| l.contains("n=24") && l.contains("| solve_s |")),
        "{said}"
    );
    assert!(
        worse.iter().all(|l| l.contains("n=24")),
        "only the slower point: {said}"
    );
}

/// A solver `name` in the scratch directory that runs the shell lines `first`, then is nlsolve.
fn shell_wrapper(scratch: &Scratch, name: &str, first: &str) -> PathBuf {
    let wrapper = scratch.dir.join(name);
    let nlsolve = binary("nlsolve");
    let script = format!("#!/bin/sh\n{first}\nexec {} \"$@\"\n", nlsolve.display());
    std::fs::write(&wrapper, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    wrapper
}

/// A solver wrapper whose records report timings of a scale `compare` judges: solve 0.2 s ×
/// $FACTOR (within 1 %, per process), step, set-up and the whole wall time in proportion, never `noisy`, and the CPU
/// $CPU when given.
fn timing_wrapper(scratch: &Scratch) -> PathBuf {
    let wrapper = scratch.dir.join("timed-nlsolve");
    std::fs::write(
        &wrapper,
        format!(
            "#!/usr/bin/env python3\nimport json, os, subprocess, sys\ntimed_runs = []\ndef timed(text):\n    record = json.loads(text)\n    if 'error' in record:\n        return text\n    timed_runs.append(1)\n    scale = 0.2 * float(os.environ.get('FACTOR', '1')) * (1 + 0.01 * (((os.getpid() + len(timed_runs)) % 7) - 3) / 3)\n    record['solve_s'] = scale\n    record['step_s'] = scale / max(1, record['steps_done'])\n    record['setup_s'] = scale / 4\n    record['wall_s'] = scale * 1.25\n    record['provenance']['noisy'] = False\n    record['provenance']['cpu'] = os.environ.get('CPU', record['provenance']['cpu'])\n    return json.dumps(record) + '\\n'\nreal = subprocess.Popen(['{}'] + sys.argv[1:], stdout=subprocess.PIPE, text=True)\nfor line in real.stdout:\n    sys.stdout.write(timed(line) if sys.argv[1:2] in (['run'], ['serve']) and line.strip() else line)\n    sys.stdout.flush()\nsys.exit(real.wait())\n",
            binary("nlsolve").display()
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    wrapper
}

/// A scheduler stand-in on PATH (`sbatch`, `squeue`, `sacct`) that logs each call and answers
/// as Slurm does: `submit --array` hands a study of 10⁴ points of one shape to the scheduler in
/// one array of 1000 elements, with at most five calls in all.
#[test]
fn ten_thousand_points_are_submitted_as_one_array_in_a_few_scheduler_calls() {
    let t_end: Vec<f64> = (1..=100).map(|k| 1e-4 * k as f64).collect();
    let study = json!({
        "name": "many",
        "base": {"dim": 1, "m": 2, "cfl": 0.5},
        "sweep": [{"product": {"n": (16..116).collect::<Vec<u64>>(), "t_end": t_end}}]
    });
    let scratch = Scratch::new("many", &study);
    let bin = scratch.dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let calls = scratch.dir.join("calls.log");
    for (program, answer) in [("sbatch", "42"), ("squeue", ""), ("sacct", "")] {
        let path = bin.join(program);
        let script = format!(
            "#!/bin/bash\necho \"{program} $*\" >> '{}'\necho '{answer}'\n",
            calls.display()
        );
        std::fs::write(&path, script).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap());
    let submit = |extra: &[&str]| {
        let mut args = vec!["--scheduler", "slurm", "--array", "--throttle", "4"];
        args.extend(extra);
        scratch
            .command("submit", &args)
            .env("PATH", &path)
            .output()
            .unwrap()
    };
    let out = submit(&[]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("nlstudy-many-0 (array of 1000 elements, 10000 cases, "),
        "{}",
        text(&out)
    );
    let logged = std::fs::read_to_string(&calls).unwrap();
    assert!(logged.lines().count() <= 5, "{logged}");
    assert_eq!(logged.matches("sbatch --parsable").count(), 1, "{logged}");
    let script =
        std::fs::read_to_string(scratch.dir.join("results/many/jobs/nlstudy-many-0.sbatch"))
            .unwrap();
    assert!(script.contains("#SBATCH --array=0-999%4\n"), "{script}");
    let ledger: Value = serde_json::from_str(
        &std::fs::read_to_string(scratch.dir.join("results/many/jobs/ledger/42.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(ledger["elements"].as_array().unwrap().len(), 1000);
    assert_eq!(ledger["keys"].as_array().unwrap().len(), 10_000);
}

/// A job's time limit from stored timings: two grids run here, the next ones scaled from them,
/// and `submit` says where the limit came from; `--time` wins. (The runs' timings are the
/// wrapper's 0.2 s: the real ones, tens of microseconds, scale by any power a delay of a few
/// milliseconds on a busy machine makes of them.)
#[test]
fn time_limits_come_from_stored_timings_unless_given() {
    let study = small_study(&[16, 32]);
    let scratch = Scratch::new("limits", &study);
    let first = scratch.nlstudy("submit", &["--scheduler", "slurm", "--dry-run"]);
    assert!(
        text(&first).contains("time: the scheduler's default (n=32 threads=1 has no stored timing"),
        "{}",
        text(&first)
    );
    let wrapper = timing_wrapper(&scratch);
    let ran = scratch.nlstudy(
        "run",
        &["--no-collect", "--solver", wrapper.to_str().unwrap()],
    );
    assert!(ran.status.success(), "{}", text(&ran));
    scratch.write_study(&small_study(&[16, 32, 64, 128]));
    let out = scratch.nlstudy("submit", &["--scheduler", "slurm", "--dry-run"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("time 00:05:00: from 4 points scaled from smaller grids × 2, + 10 s for the job and 1 s a case (10 s over ranks), at least 5 min"),
        "{}",
        text(&out)
    );
    let out = scratch.nlstudy(
        "submit",
        &["--scheduler", "slurm", "--dry-run", "--time", "02:00:00"],
    );
    assert!(
        text(&out).contains("time 02:00:00: as given"),
        "{}",
        text(&out)
    );
    let out = scratch.nlstudy(
        "submit",
        &["--scheduler", "slurm", "--dry-run", "--time", "1:30"],
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(text(&out).contains("ambiguous"), "{}", text(&out));
}

/// `submit` of an adaptive study says what comes next by the way it goes to the cluster: its
/// round and the rounds at most, or the whole study in one job, on every node of it.
#[test]
fn submitting_an_adaptive_study_says_its_rounds_and_how_they_run() {
    let study = json!({
        "name": "ways",
        "base": {"dim": 1, "n": 64, "m": 2, "problem": "bump", "t_end": 1e-6,
                 "allow_unstable": true, "amplification_steps": 100},
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 0.01, "per_round": 7}
    });
    let scratch = Scratch::new("ways", &study);
    let dry = |extra: &[&str]| dry_submit(&scratch, extra);
    let rounds = dry(&[]);
    assert!(
        rounds.contains("this round: 1 jobs, 2 points, of at most 4 rounds; submit again"),
        "{rounds}"
    );
    let whole = dry(&["--whole", "--nodes", "2"]);
    assert!(
        whole.contains("its rounds, 4 at most, run inside the allocation by a worker step on each of its 2 nodes"),
        "{whole}"
    );
}

/// What a round, and a whole adaptive study in one job, may take, from stored timings: nothing
/// before a point is timed; once the first round is stored (the wrapper's runs, 25 s each), the
/// next round's probes, new points, cost what their searches' stored probes did (25 s each),
/// and a whole job's limit is the plan's worst case of rounds × that round × 2 +
/// 10 s. A study whose first round does not bound its later ones (7 probes a round after
/// the bracket's 2) gets no forecast from it.
#[test]
fn a_forecast_and_a_whole_jobs_limit_come_from_the_stored_rounds_timings() {
    let study = |per_round: usize| {
        json!({
            "name": "forecast",
            "base": {"dim": 1, "n": 64, "m": 2, "problem": "bump", "t_end": 1e-6,
                     "allow_unstable": true, "amplification_steps": 100},
            "sweep": [{"product": {"integrator": ["forward_euler", "heun"]}}],
            "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                         "rtol": 0.01, "per_round": per_round}
        })
    };
    let scratch = Scratch::new("forecast", &study(1));
    let dry = |extra: &[&str]| dry_submit(&scratch, extra);
    let whole = dry(&["--whole"]);
    assert!(
        whole.contains("the scheduler's default (no point of the study is timed yet"),
        "{whole}"
    );
    assert!(!dry(&[]).contains("s a round"));
    // The first round only (its four bracket ends), as a job's `run --only` runs it.
    let plan = text(&scratch.nlstudy("plan", &[]));
    let keys: Vec<&str> = plan
        .lines()
        .filter(|l| l.split_whitespace().nth(1) == Some("run"))
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(keys.len(), 4, "{plan}");
    let wrapper = timing_wrapper(&scratch);
    let only = keys.join(",");
    let args = [
        "--no-collect",
        "--only",
        &only,
        "--solver",
        wrapper.to_str().unwrap(),
    ];
    let ran = scratch.command("run", &args).env("FACTOR", "100").output();
    let ran = ran.unwrap();
    assert!(ran.status.success(), "{}", text(&ran));

    let rounds = dry(&[]);
    let most: f64 = between(&rounds, "of at most ", " rounds").parse().unwrap();
    assert_eq!(most, 10.0, "2 + 9 halvings of 1.5 to 0.005: {rounds}");
    // Two probes (a search's one each) of 25 s on the job's one lane.
    let round_s: f64 = between(&rounds, "predicted ", " s a round")
        .parse()
        .unwrap();
    assert!((49.0..=51.0).contains(&round_s), "{rounds}");
    // The job's own limit: its two probes at their searches' stored probes' times, × 2 + 10 s.
    assert!(
        rounds.contains("time 00:05:00: from 2 points timed by their searches' stored probes × 2"),
        "{rounds}"
    );
    assert!(
        rounds.contains("from the points' stored timings, so about")
            && rounds.contains("for 10 rounds at most, queue waits not included"),
        "{rounds}"
    );
    // 10 × 50 s × 2 + 10 s, rounded up to the minute: 17 min.
    let whole = dry(&["--whole"]);
    assert!(
        whole.contains("time 00:17:00: from the plan's worst case, 10 rounds × "),
        "{whole}"
    );

    scratch.write_study(&study(7));
    let later_longer = dry(&["--whole"]);
    assert!(
        later_longer.contains("its later rounds may be longer than its first"),
        "{later_longer}"
    );
    assert!(!dry(&[]).contains("s a round"));
}

/// A round's job is handed its probes (`--probes`, a file its submit wrote beside its script)
/// and plans them without replaying the study's searches: the same keys and points to run as
/// the replay plans, round after round, to the study's end. A file that no longer gives the
/// job's probes (garbled, a key missing, a probe moved to another point of the sweep) is said
/// and the searches are replayed: the same keys run.
#[test]
fn a_job_handed_its_probes_plans_them_as_the_replay_of_its_searches_does() {
    let study = json!({
        "name": "handed",
        "base": {"dim": 1, "n": 32, "m": 2, "problem": "bump", "t_end": 1e-6,
                 "allow_unstable": true, "amplification_steps": 50},
        "sweep": [{"product": {"integrator": ["forward_euler", "heun"]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 0.05, "per_round": 1}
    });
    let scratch = Scratch::new("handed", &study);
    let jobs = scratch.dir.join("results/handed/jobs");
    let replayed = "its searches are replayed to find them";
    // The points `plan` says run, as `key label` lines.
    let to_run = |extra: &[&str]| -> Vec<String> {
        let plan = scratch.nlstudy("plan", extra);
        assert!(plan.status.success(), "{}", text(&plan));
        let said = String::from_utf8_lossy(&plan.stdout).to_string();
        let mut lines: Vec<String> = (said.lines())
            .filter(|l| l.split_whitespace().nth(1) == Some("run"))
            .map(String::from)
            .collect();
        lines.sort();
        lines
    };
    let mut rounds = 0;
    loop {
        let submitted = dry_submit(&scratch, &["--cases-per-job", "1"]);
        if submitted.contains("nothing to submit") {
            break;
        }
        rounds += 1;
        let mut scripts: Vec<PathBuf> = std::fs::read_dir(&jobs)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "sbatch"))
            .collect();
        scripts.sort();
        // The bracket's two ends first, then a probe a search each round.
        let probes = if rounds == 1 { 4 } else { 2 };
        assert_eq!(scripts.len(), probes, "{submitted}");
        for script in &scripts {
            let script = std::fs::read_to_string(script).unwrap();
            let words: Vec<&str> = script.lines().last().unwrap().split(' ').collect();
            let value_of = |option: &str| {
                let at = words.iter().position(|w| *w == option);
                let value = words[at.unwrap_or_else(|| panic!("no {option}: {script}")) + 1];
                value.trim_matches('\'').to_string()
            };
            let (only, probes) = (value_of("--only"), value_of("--probes"));
            let handed = ["--only", &only, "--probes", &probes];
            let planned = to_run(&handed);
            assert_eq!(planned.len(), 1, "{planned:?}");
            assert_eq!(planned, to_run(&["--only", &only]), "round {rounds}");
            // The file damaged each way, after which the same probe is planned by the replay.
            let file = std::fs::read_to_string(&probes).unwrap();
            let mut moved: Value = serde_json::from_str(&file).unwrap();
            moved[0]["origin"] = json!(1 - moved[0]["origin"].as_u64().unwrap());
            for damaged in ["[{\"key\": ".to_string(), "[]".into(), moved.to_string()] {
                std::fs::write(&probes, &damaged).unwrap();
                let plan = scratch.nlstudy("plan", &handed);
                assert!(text(&plan).contains(replayed), "{damaged}: {}", text(&plan));
                assert_eq!(to_run(&handed), planned, "{damaged}");
            }
            std::fs::write(&probes, &file).unwrap();
            let ran = scratch.nlstudy("run", &[&handed[..], &["--no-collect"]].concat());
            assert!(ran.status.success(), "{}", text(&ran));
            assert!(!text(&ran).contains(replayed), "{}", text(&ran));
        }
    }
    assert!(
        rounds >= 4,
        "bisection to 5 % of the bracket takes rounds: {rounds}"
    );
    // The jobs ran every probe: the study is answered as a run would answer it.
    let answered = scratch.nlstudy("run", &[]);
    assert!(text(&answered).contains(": 0 ran ("), "{}", text(&answered));
}

/// What `submit --scheduler slurm --dry-run EXTRA…` says of the study of `scratch`; it succeeds.
fn dry_submit(scratch: &Scratch, extra: &[&str]) -> String {
    let out = scratch.nlstudy(
        "submit",
        &[&["--scheduler", "slurm", "--dry-run"], extra].concat(),
    );
    assert!(out.status.success(), "{}", text(&out));
    text(&out)
}

/// The text of `said` between the first `before` and the next `after`.
fn between<'a>(said: &'a str, before: &str, after: &str) -> &'a str {
    let start = said
        .find(before)
        .unwrap_or_else(|| panic!("no {before:?} in {said}"))
        + before.len();
    let end = said[start..]
        .find(after)
        .unwrap_or_else(|| panic!("no {after:?} in {said}"));
    &said[start..start + end]
}

/// A boundary search finds each explicit integrator's stability limit where the operator's
/// symbol puts it (cfl = 1), finds none for Crank–Nicolson, spends every probe once (the table's
/// probes are the stored records), and a second run runs nothing and gives the same table.
#[test]
fn a_boundary_search_finds_the_symbols_stability_limit_and_resumes_from_the_store() {
    let study = json!({
        "name": "boundary",
        "base": {"dim": 1, "n": 128, "problem": "bump", "t_end": 1e-6, "allow_unstable": true,
                 "amplification_steps": 400},
        "sweep": [{"product": {"m": [1, 4], "integrator": ["forward_euler", "rk4", "crank_nicolson"]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 2e-3, "per_round": 2},
        "figures": [{"name": "limits", "kind": "boundaries", "series": ["integrator"]}]
    });
    let scratch = Scratch::new("boundary", &study);
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(plan.contains("boundary along `cfl`: 6 searches"), "{plan}");
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    // Each round counts its own cases, so each line says its round.
    let said = text(&run);
    assert!(
        said.contains("[round 1: 1/") && said.contains("[round 2: 1/"),
        "{said}"
    );
    let path = scratch
        .dir
        .join("results/boundary/boundary-boundaries.parquet");
    let table = read_parquet(&path);
    assert_eq!(table.height(), 6);
    let integrators = table.column("integrator").unwrap().str().unwrap().clone();
    let integrators: Vec<&str> = (0..integrators.len())
        .map(|i| integrators.get(i).unwrap())
        .collect();
    let (boundary, predicted) = (floats(&table, "boundary"), floats(&table, "predicted"));
    for (k, integrator) in integrators.iter().enumerate() {
        if *integrator == "crank_nicolson" {
            assert!(boundary[k].is_nan() && predicted[k].is_nan(), "{k}");
        } else {
            assert_eq!(predicted[k], 1.0);
            // The grid's top eigenvalue lies a little under the symbol's maximum: the measured
            // limit is at or just above the prediction.
            assert!(
                boundary[k] > 1.0 - 2e-3 && boundary[k] < 1.005,
                "{integrator}: {}",
                boundary[k]
            );
        }
    }
    let probes: f64 = floats(&table, "probes").iter().sum();
    assert_eq!(probes as usize, records(&scratch.runs("boundary")).len());
    // The figure is drawn from the boundary table: the limits along m, the theory at cfl 1.
    let figure = scratch.dir.join("results/boundary/figures/limits.svg");
    let svg = std::fs::read_to_string(&figure).expect("the boundaries figure");
    for words in [
        "no boundary found by 2 searches (integrator = crank_nicolson)",
        "horizon m = ε/h",
        "the theory",
    ] {
        assert!(svg.contains(words), "{words} not in {}", figure.display());
    }
    let again = scratch.nlstudy("run", &[]);
    assert!(text(&again).contains("0 ran"), "{}", text(&again));
    let again = floats(&read_parquet(&path), "boundary");
    assert!(again
        .iter()
        .zip(&boundary)
        .all(|(a, b)| a == b || (a.is_nan() && b.is_nan())));
}

/// Along a field of whole numbers (`m`) every probe's case holds a whole number and the search
/// ends at neighbours: the smallest m whose quadrature's patch error is below 1 %.
#[test]
fn a_boundary_search_along_a_whole_field_ends_at_neighbours() {
    let study = json!({
        "name": "whole",
        "base": {"dim": 1, "n": 256, "problem": "bump", "t_end": 1e-6, "cfl": 0.5,
                 "quadrature": "partial_volume"},
        "boundary": {"field": "m", "bracket": [1, 64], "flips": "patch_error < 0.01", "rtol": 1e-3}
    });
    let scratch = Scratch::new("whole", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = read_parquet(&scratch.dir.join("results/whole/whole-boundaries.parquet"));
    let (lo, hi) = (
        floats(&table, "boundary_lo")[0],
        floats(&table, "boundary_hi")[0],
    );
    assert_eq!(hi - lo, 1.0, "neighbours: {lo} {hi}");
    assert!(
        text(&run).contains(&format!("m = {hi} holds, {lo} does not")),
        "{}",
        text(&run)
    );
    for record in records(&scratch.runs("whole")) {
        assert!(record["case"]["m"].is_u64(), "{}", record["case"]);
    }
}

#[test]
fn a_boundary_search_that_cannot_be_made_is_refused_naming_the_field() {
    let study = |boundary: Value, sweep: Value| {
        json!({"name": "refused",
               "base": {"dim": 1, "n": 16, "m": 2, "t_end": 1e-6, "allow_unstable": true},
               "sweep": sweep, "boundary": boundary})
    };
    let good = json!({"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                      "rtol": 1e-3});
    let with = |field: &str, value: Value| {
        let mut boundary = good.clone();
        boundary[field] = value;
        boundary
    };
    for (boundary, sweep, field) in [
        (
            with("bracket", json!([1.0, 1.0])),
            json!([]),
            "boundary.bracket",
        ),
        (with("rtol", json!(0)), json!([]), "boundary.rtol"),
        (
            with("field", json!("integrator")),
            json!([]),
            "boundary.field",
        ),
        (
            with("max_probes", json!(0)),
            json!([]),
            "boundary.max_probes",
        ),
        (
            with("flips", json!("amplification >")),
            json!([]),
            "boundary.flips",
        ),
        (
            good.clone(),
            json!([{"product": {"cfl": [0.5]}}]),
            "boundary.field",
        ),
    ] {
        let scratch = Scratch::new("refused", &study(boundary, sweep));
        let plan = scratch.nlstudy("plan", &[]);
        assert_eq!(plan.status.code(), Some(2), "{}", text(&plan));
        assert!(text(&plan).contains(field), "{field}: {}", text(&plan));
    }
    let mut unbounded = study(good.clone(), json!([]));
    unbounded["budget"] = json!({"runs": 0});
    let mut unasked = study(good.clone(), json!([]));
    unasked.as_object_mut().unwrap().remove("boundary");
    unasked["budget"] = json!({"runs": 10});
    for (refused, field) in [(unbounded, "budget.runs"), (unasked, "`budget`")] {
        let scratch = Scratch::new("refused", &refused);
        let plan = scratch.nlstudy("plan", &[]);
        assert_eq!(plan.status.code(), Some(2), "{}", text(&plan));
        assert!(text(&plan).contains(field), "{field}: {}", text(&plan));
    }
    let mut both = study(good, json!([]));
    both["refine"] = json!({"field": "n", "start": 8});
    let scratch = Scratch::new("refused", &both);
    let plan = scratch.nlstudy("plan", &[]);
    assert_eq!(plan.status.code(), Some(2), "{}", text(&plan));
    assert!(text(&plan).contains("`refine`"), "{}", text(&plan));
}

/// A refinement doubles n until the last three observed orders agree with the expected one
/// (FD and ADI on the heat eigenmode: order 2 in h at a fixed dt/dt_stable), never beyond: the
/// levels run are the records stored, and a second run runs nothing.
#[test]
fn a_refinement_stops_once_its_order_is_established() {
    let study = json!({
        "name": "refined",
        "base": {"dim": 1, "problem": "eigenmode", "t_end": 0.05, "cfl": 0.4},
        "sweep": [{"product": {"method": ["fd_explicit", "adi"]}}],
        "refine": {"field": "n", "start": 16, "order": 2}
    });
    let scratch = Scratch::new("refined", &study);
    let plan = text(&scratch.nlstudy("plan", &[]));
    assert!(plan.contains("refine along `n`: 2 refinements"), "{plan}");
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let path = scratch
        .dir
        .join("results/refined/refined-convergence.parquet");
    let table = read_parquet(&path);
    assert_eq!(table.height(), 2);
    for order in floats(&table, "order_finest") {
        assert!((order - 2.0).abs() <= 0.05, "{order}");
    }
    let stopped = table.column("stopped").unwrap().str().unwrap().clone();
    assert!((0..2).all(|i| stopped.get(i) == Some("order established")));
    let levels: f64 = floats(&table, "levels").iter().sum();
    assert!(levels <= 16.0);
    assert_eq!(levels as usize, records(&scratch.runs("refined")).len());
    let again = scratch.nlstudy("run", &[]);
    assert!(text(&again).contains("0 ran"), "{}", text(&again));
}

/// A study that sweeps nothing names its one point `the base case` in what it prints (each
/// case's line, the answer), never an empty label (`ok `, `: order 2`).
#[test]
fn a_study_that_sweeps_nothing_names_its_point_the_base_case() {
    let base = json!({"dim": 1, "n": 16, "method": "fd_explicit", "problem": "eigenmode",
                      "t_end": 0.05, "cfl": 0.4});
    let fixed = Scratch::new("single", &json!({"name": "single", "base": base}));
    let run = fixed.nlstudy("run", &[]);
    let said = text(&run);
    assert!(
        run.status.success() && said.contains("[1/1] ok the base case"),
        "{said}"
    );
    // A refinement's probes are labelled by the field it refines; its answer by the point.
    let refined = json!({"name": "single", "base": base,
                         "refine": {"field": "n", "start": 16, "order": 2}});
    let refined = Scratch::new("single", &refined);
    let run = refined.nlstudy("run", &[]);
    let said = text(&run);
    assert!(run.status.success(), "{said}");
    assert!(said.contains("  the base case: order "), "{said}");
    assert!(!said.contains("\n  : order"), "{said}");
}

/// A boundary search killed with SIGKILL mid-round (no chance to clean up) and run again ends
/// where an uninterrupted one does, and no probe runs twice: the records stored before the
/// kill and the runs after it add up to the probes the table counts.
#[test]
fn a_search_killed_mid_round_resumes_without_running_a_probe_twice() {
    let study = |name: &str| {
        json!({
            "name": name,
            "base": {"dim": 1, "n": 128, "problem": "bump", "t_end": 1e-6,
                     "allow_unstable": true, "amplification_steps": 400},
            "sweep": [{"product": {"m": [1, 4], "integrator": ["forward_euler", "rk4"]}}],
            "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                         "rtol": 2e-3}
        })
    };
    let whole = Scratch::new("whole", &study("resumed"));
    assert!(whole.nlstudy("run", &["--quiet"]).status.success());
    let table = |scratch: &Scratch| {
        read_parquet(
            &scratch
                .dir
                .join("results/resumed/resumed-boundaries.parquet"),
        )
    };
    let answer = floats(&table(&whole), "boundary");

    let killed = Scratch::new("killed", &study("resumed"));
    let mut child = killed.spawn("run", &["--quiet", "-j", "1"]);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while records(&killed.runs("resumed")).len() < 7 && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let stored = records(&killed.runs("resumed")).len();
    assert!(stored >= 7, "{stored}");
    let resumed = killed.nlstudy("run", &[]);
    assert!(resumed.status.success(), "{}", text(&resumed));
    let said = text(&resumed);
    let ran: usize = said
        .split("study resumed: ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    let probes: f64 = floats(&table(&killed), "probes").iter().sum();
    assert_eq!(stored + ran, probes as usize, "{said}");
    assert_eq!(floats(&table(&killed), "boundary"), answer);
}

/// Six boundary searches (two ends each, then three probes a round) under a study budget of
/// `runs`.
fn budgeted(name: &str, runs: usize) -> Value {
    json!({
        "name": name,
        "base": {"dim": 1, "n": 64, "problem": "bump", "t_end": 1e-6, "allow_unstable": true,
                 "amplification_steps": 100},
        "sweep": [{"product": {"m": [1, 2, 4], "integrator": ["forward_euler", "crank_nicolson"]}}],
        "boundary": {"field": "cfl", "bracket": [0.5, 2.0], "flips": "amplification > 1",
                     "rtol": 1e-3},
        "budget": {"runs": runs}
    })
}

/// The study's budget is honoured: a round is cut to the runs left and none starts once they are
/// spent; the searches it stopped say so, the run reports what was spent, and a second run
/// spends nothing more.
#[test]
fn an_adaptive_study_stops_at_its_budget_and_says_so() {
    let scratch = Scratch::new("budgeted", &budgeted("budgeted", 15));
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    assert!(
        text(&run).contains("budget: 15 of 15 runs"),
        "{}",
        text(&run)
    );
    assert_eq!(records(&scratch.runs("budgeted")).len(), 15);
    let table = read_parquet(
        &scratch
            .dir
            .join("results/budgeted/budgeted-boundaries.parquet"),
    );
    let ended = table.column("ended").unwrap().str().unwrap().clone();
    let ended: Vec<&str> = (0..ended.len()).map(|i| ended.get(i).unwrap()).collect();
    assert_eq!(
        ended
            .iter()
            .filter(|e| **e == "the study's budget spent before the tolerance")
            .count(),
        3,
        "{ended:?}"
    );
    let again = scratch.nlstudy("run", &[]);
    assert!(text(&again).contains("0 ran"), "{}", text(&again));
    assert_eq!(records(&scratch.runs("budgeted")).len(), 15);
}

/// A budget spent before a search's bracket ends were both probed (11 runs for six searches of
/// two ends each) leaves that search without an estimate: the middle of a bracket never probed
/// is no boundary, so the table holds none for it and its answer line says why.
#[test]
fn a_budget_spent_before_a_brackets_ends_gives_that_search_no_boundary() {
    let scratch = Scratch::new("unprobed", &budgeted("unprobed", 11));
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let said = text(&run);
    let why = "the study's budget spent before the bracket's ends were probed";
    let line = said
        .lines()
        .find(|l| l.contains(why))
        .unwrap_or_else(|| panic!("{said}"));
    assert!(!line.contains("cfl ="), "{line}");
    let table = read_parquet(
        &scratch
            .dir
            .join("results/unprobed/unprobed-boundaries.parquet"),
    );
    let ended = table.column("ended").unwrap().str().unwrap().clone();
    let boundary = floats(&table, "boundary");
    let unprobed: Vec<usize> = (0..ended.len())
        .filter(|&i| ended.get(i) == Some(why))
        .collect();
    assert_eq!(unprobed.len(), 1, "{table}");
    assert!(boundary[unprobed[0]].is_nan(), "{table}");
    assert!(
        floats(&table, "boundary_lo")[unprobed[0]].is_nan(),
        "{table}"
    );
}

/// `collect` is make-style: with no record, point or study text changed since the tables were
/// made, they stand as they are (not rewritten) and it says so; a new point's record, a rerun
/// or a table gone makes them again.
#[test]
fn a_collect_with_nothing_new_leaves_the_tables_and_a_new_record_remakes_them() {
    let scratch = Scratch::new("remade", &small_study(&[16, 32]));
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let table = scratch.dir.join("results/small/small.parquet");
    let summary = scratch.dir.join("results/small/small-summary.parquet");
    let made = std::fs::metadata(&table).unwrap().modified().unwrap();
    let bytes = std::fs::read(&table).unwrap();
    let again = scratch.nlstudy("collect", &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(text(&again).contains("up to date"), "{}", text(&again));
    assert!(
        text(&again).contains("| n |"),
        "the overview is printed: {}",
        text(&again)
    );
    assert_eq!(std::fs::metadata(&table).unwrap().modified().unwrap(), made);
    assert_eq!(std::fs::read(&table).unwrap(), bytes);

    scratch.write_study(&small_study(&[16, 32, 48]));
    let grown = scratch.nlstudy("run", &[]);
    assert!(grown.status.success(), "{}", text(&grown));
    assert!(!text(&grown).contains("up to date"), "{}", text(&grown));
    assert!(text(&grown).contains("(6 runs)"), "{}", text(&grown));

    let key = records(&scratch.runs("small"))[0]["key"]
        .as_str()
        .unwrap()
        .to_string();
    let forced = scratch.nlstudy("run", &["--force", "--only", &key]);
    assert!(forced.status.success(), "{}", text(&forced));
    assert!(
        !text(&forced).contains("up to date"),
        "a rerun remakes them: {}",
        text(&forced)
    );

    std::fs::remove_file(&summary).unwrap();
    let remade = scratch.nlstudy("collect", &[]);
    assert!(!text(&remade).contains("up to date"), "{}", text(&remade));
    assert!(summary.exists());
}

/// The tables and overview a collect from scratch makes of the records stored now: the tables
/// and what they were made of are put aside, collected again, and put back.
fn from_scratch(scratch: &Scratch) -> (Vec<u8>, Vec<u8>, String) {
    let dir = scratch.dir.join("results/small");
    let made = dir.join(".collected.json");
    let kept = std::fs::read(&made).unwrap();
    std::fs::remove_file(&made).unwrap();
    let again = scratch.nlstudy("collect", &[]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(!text(&again).contains("read anew"), "{}", text(&again));
    let read = |name: &str| std::fs::read(dir.join(name)).unwrap();
    let whole = (
        read("small.parquet"),
        read("small-summary.parquet"),
        overview(&dir),
    );
    the_same_when_sliced(scratch);
    std::fs::write(&made, kept).unwrap();
    whole
}

/// Collected from scratch a slice of the plan at a time, as a large study is (a run or three at
/// a time, a point's repeats kept together), the tables of study `small` are those a collect in
/// one slice made.
fn the_same_when_sliced(scratch: &Scratch) {
    let dir = scratch.dir.join("results/small");
    let read = |name: &str| std::fs::read(dir.join(name)).unwrap();
    let whole = (read("small.parquet"), read("small-summary.parquet"));
    for slice in ["1", "3"] {
        let _ = std::fs::remove_file(dir.join(".collected.json"));
        let sliced = (scratch.command("collect", &[]))
            .env("NLSTUDY_COLLECT_SLICE", slice)
            .output()
            .unwrap();
        assert!(sliced.status.success(), "{}", text(&sliced));
        assert!(read("small.parquet") == whole.0, "runs, slices of {slice}");
        assert!(
            read("small-summary.parquet") == whole.1,
            "summary, slices of {slice}"
        );
    }
}

/// A study whose later points have columns the first lack (two methods, resolved to cases of
/// different fields) is collected alike in any slices: the run table, written as its slices
/// come while they keep the first's columns, is read back and stacked with the rest once one
/// does not.
#[test]
fn a_study_whose_later_slices_bring_columns_is_tabulated_alike_in_any_slices() {
    let study = json!({
        "name": "small",
        "base": {"dim": 1, "t_end": 0.001, "cfl": 0.5},
        "sweep": [
            {"zip": {"method": ["nonlocal", "fd_explicit"], "problem": ["manufactured", "eigenmode"], "m": [2, null]}},
            {"product": {"n": [16, 48]}}
        ]
    });
    let scratch = Scratch::new("two-methods", &study);
    let ran = scratch.nlstudy("run", &[]);
    assert!(ran.status.success(), "{}", text(&ran));
    let frame = read_parquet(&scratch.dir.join("results/small/small.parquet"));
    let first_lacks =
        (frame.columns().iter()).any(|c| c.get(0).unwrap().is_null() && c.null_count() < c.len());
    assert!(first_lacks, "the first run has every column: {frame}");
    the_same_when_sliced(&scratch);
}

/// The overview the last collect printed, as it keeps it.
fn overview(study: &Path) -> String {
    let made: Value =
        serde_json::from_slice(&std::fs::read(study.join(".collected.json")).unwrap()).unwrap();
    made["collected"]["overview"].as_str().unwrap().to_string()
}

/// A collect after some records changed reads only those (and the runs of the series their
/// points lie on) and splices them into the tables it made before, which come out byte for
/// byte as a collect from scratch makes them: grown by new points, with a point rerun, and
/// shrunk by a point taken out of the study. (`small_study` has refinement and scaling series,
/// so orders and speedups are derived across the changed points.)
#[test]
fn a_collect_after_some_records_changed_splices_them_in_as_from_scratch() {
    let scratch = Scratch::new("spliced", &small_study(&[16, 32, 48, 64]));
    let first = scratch.nlstudy("run", &[]);
    assert!(first.status.success(), "{}", text(&first));
    let dir = scratch.dir.join("results/small");
    let check = |collected: &Output, read: usize| {
        assert!(
            text(collected).contains(&format!(": {read} runs read anew, the rest kept")),
            "{}",
            text(collected)
        );
        let spliced = (
            std::fs::read(dir.join("small.parquet")).unwrap(),
            std::fs::read(dir.join("small-summary.parquet")).unwrap(),
            overview(&dir),
        );
        let whole = from_scratch(&scratch);
        assert_eq!(spliced.2, whole.2, "the overview");
        assert!(spliced.0 == whole.0, "the run table: {}", text(collected));
        assert!(
            spliced.1 == whole.1,
            "the summary table: {}",
            text(collected)
        );
    };

    scratch.write_study(&small_study(&[16, 32, 48, 64, 80]));
    let grown = scratch.nlstudy("run", &[]);
    check(&grown, 2);

    let key = records(&scratch.runs("small"))[0]["key"]
        .as_str()
        .unwrap()
        .to_string();
    let rerun = scratch.nlstudy("run", &["--force", "--only", &key]);
    check(&rerun, 1);

    scratch.write_study(&small_study(&[16, 48, 64, 80]));
    let shrunk = scratch.nlstudy("collect", &[]);
    check(&shrunk, 0);
    let made = dir.join(".collected.json");
    let said_when_shrunk = std::fs::read(&made).unwrap();

    // The same points in another order: the rows move.
    scratch.write_study(&small_study(&[80, 64, 48, 16]));
    check(&scratch.nlstudy("collect", &[]), 0);
    // A collect killed after it wrote these tables but before it said what they are made of
    // leaves what the one before said, of the same rows in another order: that neither stands
    // for these tables nor is spliced into them.
    std::fs::write(&made, said_when_shrunk).unwrap();
    scratch.write_study(&small_study(&[16, 48, 64, 80]));
    let recollected = scratch.nlstudy("collect", &[]);
    assert!(recollected.status.success(), "{}", text(&recollected));
    assert!(
        !text(&recollected).contains("up to date"),
        "{}",
        text(&recollected)
    );
    assert!(
        !text(&recollected).contains("read anew"),
        "{}",
        text(&recollected)
    );
    let tables = std::fs::read(dir.join("small.parquet")).unwrap();
    assert!(tables == from_scratch(&scratch).0);

    // Runs that fail (more threads than this machine runs) have cells of other types and
    // columns of their own, and join every scaling series.
    let mut failing = small_study(&[16, 48, 64, 80]);
    failing["sweep"][0]["product"]["threads"] = json!([1, 2, 1000]);
    scratch.write_study(&failing);
    let failed = scratch.nlstudy("run", &[]);
    assert!(text(&failed).contains("4 failed"), "{}", text(&failed));
    check(&failed, 4);
}

/// A study with a record of every kind: a nonlocal run with its c_tot series, histogram,
/// snapshot and amplification; a point over two ranks (its `hosts` and `cpus`, lists of text); a
/// diverged run, a refused point (failed), an implicit integrator, the grid and particle
/// methods, the steady solvers over ranks, a varying horizon's patch test, the coupled problem,
/// and repeats.
fn every_kind_of_record() -> Value {
    json!({"name": "kinds", "base": {"threads": 1}, "sweep": [{"branches": {"nonlocal": [{"product": {"dim": [1], "n": [64], "m": [2], "t_end": [0.01], "cfl": [0.5], "source": ["discrete"], "diagnostics_every": [0.005], "histogram_bins": [4], "field_snapshot": [8], "amplification_steps": [20], "error_total": [true]}}], "ranks": [{"product": {"dim": [2], "n": [32], "m": [2], "t_end": [0.002], "cfl": [0.5], "ranks": [2]}}], "diverged": [{"product": {"dim": [1], "n": [32], "m": [2], "t_end": [0.05], "cfl": [3.0], "allow_unstable": [true]}}], "refused": [{"product": {"dim": [1], "n": [3], "m": [2], "t_end": [0.01], "cfl": [0.5]}}], "implicit": [{"product": {"dim": [2], "n": [32], "m": [2], "t_end": [0.01], "cfl": [2.0], "integrator": ["crank_nicolson"]}}], "local": [{"zip": {"method": ["fd_explicit", "adi", "pse"], "cfl": [0.5, 2.0, 0.4], "m": [null, null, 2]}}, {"product": {"dim": [2], "n": [32], "t_end": [0.01], "problem": ["square"]}}], "steady": [{"product": {"method": ["steady_cg", "feti"], "dim": [2], "n": [32], "m": [2], "ranks": [2], "subdomains": [2]}}], "patch": [{"product": {"method": ["patch_test"], "dim": [1], "kernel": ["linear"], "n": [100], "horizon_profile": [{"kind": "linear", "left": 0.1, "right": 0.05}], "formulation": ["standard"], "patch": ["quadratic"]}}], "coupled": [{"product": {"method": ["coupled_1d"], "dim": [1], "eps": [0.065], "kernel": ["inverse_distance"], "coupling": ["optimization"], "patch": ["quadratic"], "n": [32]}}], "repeated": {"sweep": [{"product": {"dim": [1], "n": [32], "m": [2], "t_end": [0.01], "cfl": [0.5], "integrator": ["rk4"]}}], "repeat": 2}}}]})
}

/// Every kind of record reads back from the run table: `show --from-table` gives each record
/// `show` gives from the store, field for field (the case with the solver's defaults filled in).
/// A results folder copied elsewhere collects again (`.collected.json` names its tables by file
/// name, so the copy's stand for themselves, not the original's), and one copied without its
/// runs makes its report from the tables alone.
#[test]
fn every_kind_of_record_reads_back_from_the_run_table_and_a_copied_folder_collects() {
    let scratch = Scratch::new("kinds", &every_kind_of_record());
    // (`--retries 1`: Open MPI 4.1's fault at the teardown of a job, more frequent on a busy
    // machine, is a failure outside the case: docs/guide/contributing.md.)
    let run = scratch.nlstudy("run", &["--allow-refused", "--retries", "1"]);
    assert_eq!(
        run.status.code(),
        Some(1),
        "a refused point fails: {}",
        text(&run)
    );
    let show = |results: &Path, extra: &[&str]| -> Vec<Value> {
        let out = Command::new(binary("nlstudy"))
            .arg("show")
            .arg(scratch.study())
            .arg("--results")
            .arg(results)
            .args(extra)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", text(&out));
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(|line| serde_json::from_str(line).unwrap())
            .collect()
    };
    let results = scratch.dir.join("results");
    let stored = show(&results, &[]);
    let tabled = show(&results, &["--from-table"]);
    assert_eq!(stored.len(), 14);
    assert_eq!(tabled.len(), stored.len());
    let statuses: std::collections::BTreeSet<&str> = stored
        .iter()
        .map(|r| r["status"].as_str().unwrap())
        .collect();
    assert_eq!(statuses, ["diverged", "failed", "ok"].into());
    let two_hosts = |r: &&Value| r["hosts"].as_array().is_some_and(|h| h.len() == 2);
    assert!(
        stored.iter().any(|r| two_hosts(&r)),
        "no record of two ranks"
    );
    for (store, table) in stored.iter().zip(&tabled) {
        let (mut store, mut table) = (store.clone(), table.clone());
        let (case, resolved) = (store["case"].take(), table["case"].take());
        assert_eq!(store, table, "a record read back from the table differs");
        for (field, value) in case.as_object().unwrap() {
            assert_eq!(
                &resolved[field], value,
                "the table's case differs in `{field}`"
            );
        }
    }

    // The folder copied: its collect reads its own tables, and rebuilds a corrupt one.
    let copy = scratch.dir.join("copy");
    let copied = Command::new("cp")
        .arg("-a")
        .arg(&results)
        .arg(&copy)
        .status()
        .unwrap();
    assert!(copied.success());
    std::fs::write(copy.join("kinds/kinds.parquet"), b"not a table").unwrap();
    let collect = Command::new(binary("nlstudy"))
        .arg("collect")
        .arg(scratch.study())
        .arg("--results")
        .arg(&copy)
        .output()
        .unwrap();
    assert!(collect.status.success(), "{}", text(&collect));
    assert!(!text(&collect).contains("up to date"), "{}", text(&collect));
    assert_eq!(show(&copy, &["--from-table"]), tabled);

    // Copied without its runs: the report from the tables alone.
    std::fs::remove_dir_all(copy.join("kinds/runs")).unwrap();
    let report = Command::new(binary("nlstudy"))
        .arg("report")
        .arg(scratch.study())
        .arg("--results")
        .arg(&copy)
        .args(["--solver", "/nonexistent/nlsolve"])
        .output()
        .unwrap();
    assert!(report.status.success(), "{}", text(&report));
    let page = std::fs::read_to_string(copy.join("kinds/report.html")).unwrap();
    assert!(page.contains("Built from the run table kinds.parquet alone"));
    assert!(page.contains("14 stored runs"), "{page}");
}
