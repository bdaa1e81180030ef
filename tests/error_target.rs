//! The cheapest configuration for an error target (`target` studies), as a user runs it: the
//! answer against a dense grid over the same fields, along one field and in space and time; the
//! stable step met and narrowed below without a failed run; an error floor said after the runs
//! that show it; repeats of a candidate ranked as one, and candidates whose cost intervals
//! overlap printed as a tie; a noisy timing of an answer run again; bad input refused at `plan`,
//! naming the field.

#[path = "support/parquet.rs"]
mod parquet;

use nonlocal_study::{binary, python_stub, records, text, Scratch};
use parquet::{floats, read_parquet};
use polars::prelude::DataFrame;
use serde_json::{json, Value};
use std::collections::BTreeMap;

/// A column of a table as text (null as "").
fn strings(frame: &DataFrame, name: &str) -> Vec<String> {
    let column = frame.column(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    let column = column.str().unwrap_or_else(|e| panic!("{name}: {e}"));
    (0..column.len())
        .map(|i| column.get(i).unwrap_or_default().to_string())
        .collect()
}

/// The study's target table.
fn target_table(scratch: &Scratch, name: &str) -> DataFrame {
    read_parquet(
        &scratch
            .dir
            .join(format!("results/{name}/{name}-target.parquet")),
    )
}

/// A record's integrator (forward Euler when the case leaves it to the default).
fn integrator(record: &Value) -> String {
    record["case"]["integrator"]
        .as_str()
        .unwrap_or("forward_euler")
        .to_string()
}

/// The error-target search ranks the candidates by the measured cost of the coarsest n that
/// meets the target; a dense grid over n finds no configuration that meets it more cheaply (the
/// cost here is `steps_done`, deterministic, so the check is exact to the search's tolerance).
#[test]
fn the_cheapest_configuration_for_an_error_target_is_not_beaten_by_a_dense_grid() {
    let base = json!({"dim": 1, "problem": "eigenmode", "t_end": 0.05, "cfl": 0.4});
    let methods = json!({"method": ["fd_explicit", "adi"]});
    let target = json!({
        "name": "aimed", "base": base, "sweep": [{"product": methods}],
        "target": {"field": "n", "start": 16, "below": 1e-6, "cost": "steps_done", "rtol": 0.01},
        "figures": [{"name": "work", "kind": "work_precision", "series": ["method"]}]
    });
    let scratch = Scratch::new("aimed", &target);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = target_table(&scratch, "aimed");
    let (rank, cost, error) = (
        floats(&table, "rank"),
        floats(&table, "cost"),
        floats(&table, "error"),
    );
    assert!(error.iter().all(|&e| e <= 1e-6), "{error:?}");
    let best = (0..2).find(|&k| rank[k] == 1.0).expect("a first");
    let svg = std::fs::read_to_string(scratch.dir.join("results/aimed/figures/work.svg")).unwrap();
    assert!(
        svg.contains("target: error_l2_norm ≤ 1e-6"),
        "the target is drawn"
    );
    assert!(
        svg.contains("meets the error target"),
        "the answers are marked"
    );
    let dense_study = json!({
        "name": "dense", "base": base,
        "sweep": [{"product": methods}, {"product": {"n": (100..=340).collect::<Vec<_>>()}}]
    });
    let dense = Scratch::new("dense", &dense_study);
    assert!(dense.nlstudy("run", &["--no-collect"]).status.success());
    let cheapest = records(&dense.runs("dense"))
        .iter()
        .filter(|r| r["error_l2_norm"].as_f64().is_some_and(|e| e <= 1e-6))
        .map(|r| r["steps_done"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert!(
        cheapest.is_finite(),
        "no point of the dense grid meets the target"
    );
    // Within the search's 1 % in n, and steps ∝ n².
    assert!(
        cheapest >= cost[best] / 1.0201,
        "the dense grid meets the target with {cheapest} steps, the search answered {}",
        cost[best]
    );
    let again = scratch.nlstudy("run", &[]);
    assert!(text(&again).contains("0 ran"), "{}", text(&again));
}

/// The 1D nonlocal problem of the searches in space and time: the horizon a fixed number of
/// cells (m = 4) with the asymptotically compatible quadrature, so that the spatial error falls
/// smoothly as h (the continuum source: it is real), and the explicit steps are bound by
/// dt_stable ∝ h².
fn in_space_and_time(name: &str, target: Value) -> Value {
    json!({
        "name": name,
        "base": {"dim": 1, "m": 4, "quadrature": "ac", "t_end": 0.05},
        "sweep": [{"product": {"integrator": ["forward_euler", "rk4", "crank_nicolson"]}}],
        "target": target
    })
}

/// The target the searches in space and time aim at, and their first grid and step.
const BELOW: f64 = 3e-4;

fn n_and_dt() -> Value {
    json!({"field": "n", "start": 32, "time": {"field": "dt", "start": 0.002},
           "below": BELOW, "cost": "bond_evaluations"})
}

/// A 1D case the search in space and time has not been tuned on, and the dense grid that
/// checks it: for each integrator, n from, to (exclusive) and by, and the whole numbers of steps
/// to t_end from, to and by (dt = t_end/steps, as the solver takes it).
struct Dense {
    name: &'static str,
    base: Value,
    below: f64,
    grids: [(&'static str, [usize; 3], [usize; 3]); 4],
}

/// Three cases (two kernels, three horizons, three ends), each with two explicit and two
/// implicit integrators, their grids around each integrator's cheapest configuration, 1–2 %
/// apart in n and in steps.
fn dense_cases() -> [Dense; 3] {
    [
        Dense {
            name: "constant",
            base: json!({"dim": 1, "m": 4, "quadrature": "ac", "t_end": 0.05}),
            below: 3e-4,
            grids: [
                ("forward_euler", [380, 475, 5], [1700, 2425, 25]),
                ("rk4", [380, 475, 5], [1150, 1600, 15]),
                ("crank_nicolson", [300, 560, 6], [1, 12, 1]),
                ("backward_euler", [220, 320, 4], [28, 52, 1]),
            ],
        },
        Dense {
            name: "linear",
            base: json!({"dim": 1, "m": 5, "kernel": "linear", "quadrature": "ac", "t_end": 0.02}),
            below: 3e-4,
            grids: [
                ("heun", [100, 265, 5], [60, 205, 5]),
                ("rk4", [100, 265, 5], [40, 164, 4]),
                ("crank_nicolson", [80, 305, 5], [1, 13, 1]),
                ("backward_euler", [80, 305, 5], [6, 42, 2]),
            ],
        },
        Dense {
            name: "end",
            base: json!({"dim": 1, "m": 4, "kernel": "linear", "quadrature": "ac", "t_end": 0.04}),
            below: 2e-4,
            grids: [
                ("heun", [250, 420, 6], [1300, 2300, 40]),
                ("rk4", [250, 420, 6], [900, 1700, 30]),
                ("crank_nicolson", [150, 600, 10], [1, 11, 1]),
                ("backward_euler", [150, 400, 6], [20, 80, 3]),
            ],
        },
    ]
}

/// Each candidate's answer by the operator's work (applications × bonds, the same on any
/// machine) costs at most 1.1× the cheapest run of a dense grid over n and dt that meets the
/// target, meets it itself, and the candidates rank as the grid ranks them; the search spends
/// at most a fifth of the grid's runs, and none on repeats of a count. A search that answers with a costlier run that met the
/// target, or that stops at the first run that met it, fails here.
#[test]
fn a_search_in_space_and_time_costs_within_a_tenth_of_a_dense_grids_cheapest() {
    for case in dense_cases() {
        let integrators: Vec<&str> = case.grids.iter().map(|g| g.0).collect();
        let name = format!("search_{}", case.name);
        let search = Scratch::new(
            &name,
            &json!({
                "name": name, "base": case.base,
                "sweep": [{"product": {"integrator": integrators}}],
                "target": {"field": "n", "start": 32, "time": {"field": "dt", "start": 0.002},
                           "below": case.below, "cost": "bond_evaluations"},
                "repeat": 3
            }),
        );
        let run = search.nlstudy("run", &[]);
        assert!(run.status.success(), "{}", text(&run));
        let table = target_table(&search, &name);
        let candidates = strings(&table, "integrator");
        let (n, dt, error, cost, rank) = (
            floats(&table, "resolution"),
            floats(&table, "time_resolution"),
            floats(&table, "error"),
            floats(&table, "cost"),
            floats(&table, "rank"),
        );
        let searched = records(&search.runs(&name));
        // A count is the same every time: the study's repeats are not run for it.
        assert!(
            searched.iter().all(|r| r["repeat"] == 0),
            "{}: repeated",
            case.name
        );
        let searched = searched.len();

        let t_end = case.base["t_end"].as_f64().unwrap();
        let branches: serde_json::Map<String, Value> = (case.grids.iter())
            .map(|(integrator, [n0, n1, dn], [k0, k1, dk])| {
                let ns: Vec<usize> = (*n0..*n1).step_by(*dn).collect();
                let dts: Vec<f64> = (*k0..*k1).step_by(*dk).map(|k| t_end / k as f64).collect();
                let axes = json!({"integrator": [integrator], "n": ns, "dt": dts});
                (integrator.to_string(), json!([{"product": axes}]))
            })
            .collect();
        let grid_name = format!("grid_{}", case.name);
        let grid = Scratch::new(
            &grid_name,
            &json!({"name": grid_name, "base": case.base, "sweep": [{"branches": branches}]}),
        );
        // Steps above an explicit integrator's dt_stable are refused: stored as failed, not run.
        let ran = grid.nlstudy("run", &["--no-collect", "--allow-refused", "-q"]);
        assert!(ran.status.code().is_some_and(|c| c <= 1), "{}", text(&ran));
        let grid_records: Vec<Value> = records(&grid.runs(&grid_name))
            .into_iter()
            .filter(|r| r["status"] == "ok")
            .collect();
        assert!(
            5 * searched <= grid_records.len(),
            "{}: the search ran {searched} runs, the grid {}",
            case.name,
            grid_records.len()
        );
        let work =
            |r: &Value| r["operator_applications"].as_f64().unwrap() * r["bonds"].as_f64().unwrap();
        let mut cheapest: BTreeMap<String, (f64, Value)> = BTreeMap::new();
        for r in (grid_records.iter())
            .filter(|r| r["error_l2_norm"].as_f64().is_some_and(|e| e <= case.below))
        {
            let best = (cheapest.entry(integrator(r))).or_insert((f64::INFINITY, json!(null)));
            if work(r) < best.0 {
                *best = (work(r), r["case"].clone());
            }
        }
        assert_eq!(
            cheapest.len(),
            4,
            "{}: every candidate meets the target on the grid",
            case.name
        );
        for (k, candidate) in candidates.iter().enumerate() {
            assert!(
                error[k] <= case.below,
                "{candidate}: the answer meets the target"
            );
            let (grid_best, at) = &cheapest[candidate];
            eprintln!(
                "{} {candidate}: {:.3} of the grid's cheapest ({at}) with n = {}, dt = {}",
                case.name,
                cost[k] / grid_best,
                n[k],
                dt[k]
            );
            assert!(
                cost[k] <= 1.1 * grid_best,
                "{} {candidate}: the grid meets the target at {at} with {grid_best}, the search answered n = {}, dt = {} with {}",
                case.name,
                n[k],
                dt[k],
                cost[k]
            );
        }
        let mut grid_order = candidates.clone();
        grid_order.sort_by(|a, b| cheapest[a].0.total_cmp(&cheapest[b].0));
        let mut by_rank: Vec<(f64, String)> =
            rank.iter().copied().zip(candidates.clone()).collect();
        by_rank.sort_by(|a, b| a.0.total_cmp(&b.0));
        let search_order: Vec<String> = by_rank.into_iter().map(|(_, c)| c).collect();
        assert_eq!(search_order, grid_order, "{}: {cheapest:?}", case.name);
    }
}

/// A search along dt only, at a fixed n, cannot go below the spatial error: each candidate
/// ends "unreachable: error floor … from the spatial error at n = 32" after the runs that
/// show the floor (at most 4), and the study exits 0; the same candidates searched in space
/// and time reach the target.
#[test]
fn a_floor_ends_a_step_search_and_a_search_in_space_and_time_goes_below_it() {
    let along_dt =
        json!({"field": "dt", "start": 0.001, "below": BELOW, "cost": "bond_evaluations"});
    let mut study = in_space_and_time("floor", along_dt);
    study["base"]["n"] = json!(32);
    let scratch = Scratch::new("floor", &study);
    let run = scratch.nlstudy("run", &[]);
    let said = text(&run);
    assert!(run.status.success(), "{said}");
    let table = target_table(&scratch, "floor");
    for (k, reached) in strings(&table, "reached").iter().enumerate() {
        assert!(
            reached.starts_with("unreachable: error floor")
                && reached.ends_with("from the spatial error at n = 32"),
            "{reached}"
        );
        assert!(floats(&table, "probes")[k] <= 4.0, "{said}");
        assert!(floats(&table, "resolution")[k].is_nan());
    }
    assert!(
        said.contains("no answer: unreachable: error floor"),
        "{said}"
    );

    let both = Scratch::new("both", &in_space_and_time("both", n_and_dt()));
    let run = both.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let table = target_table(&both, "both");
    assert!(floats(&table, "error").iter().all(|&e| e <= BELOW));
    assert!(strings(&table, "reached").iter().all(|r| r == "found"));
}

/// A step search that starts above the explicit integrators' dt_stable: the solver's check
/// refuses those steps, which narrow the search below them without a run (no failed record),
/// the answer lies within the tolerance below dt_stable, the study exits 0 and `plan` counts no
/// refusal. With `allow_unstable` the steps run and diverge, and narrow it all the same.
#[test]
fn a_step_search_meeting_the_stable_step_narrows_below_it_without_a_failed_run() {
    let study = json!({
        "name": "stable",
        "base": {"dim": 1, "n": 64, "m": 4, "t_end": 0.05, "source": "discrete"},
        "sweep": [{"product": {"integrator": ["heun", "rk4"], "allow_unstable": [false, true]}}],
        "target": {"field": "dt", "start": 0.004, "below": 1e-5, "cost": "steps_done"}
    });
    let scratch = Scratch::new("stable", &study);
    let run = scratch.nlstudy("run", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let stored = records(&scratch.runs("stable"));
    assert!(stored.iter().all(|r| r["status"] != "failed"), "{stored:?}");
    assert!(
        stored.iter().any(|r| r["status"] == "diverged"),
        "allow_unstable's steps above dt_stable ran and diverged"
    );
    let dt_stable = |integrator: &str| {
        stored
            .iter()
            .find(|r| r["case"]["integrator"] == integrator)
            .and_then(|r| r["dt_stable"].as_f64())
            .unwrap()
    };
    let table = target_table(&scratch, "stable");
    let (integrators, allowed) = (
        strings(&table, "integrator"),
        floats(&table, "allow_unstable"),
    );
    let (dt, error) = (floats(&table, "resolution"), floats(&table, "error"));
    for k in 0..4 {
        let stable = dt_stable(&integrators[k]);
        assert!(error[k] <= 1e-5);
        if allowed[k] == 0.0 {
            assert!(
                dt[k] <= stable && dt[k] >= stable / 1.1,
                "{}: {} against dt_stable {stable}",
                integrators[k],
                dt[k]
            );
        } else {
            // Coarser than the halvings from the start reach (0.001), up to the step that
            // stays bounded over the run.
            assert!(dt[k] > 0.00075, "{}: {}", integrators[k], dt[k]);
        }
    }
    let plan = scratch.nlstudy("plan", &[]);
    assert!(plan.status.success(), "{}", text(&plan));
    assert!(!text(&plan).contains("refused"), "{}", text(&plan));
}

/// The tie study (`repeat: 3`, three candidates, the third timed ten times slower) run on the
/// timing stub (`tests/scripts/timing-nlsolve`), its k-th runs of each case listed in `noisy`
/// marked noisy: what `run` said, the target table, the stored records and each case's run count.
fn run_the_tie(name: &str, noisy: &str) -> (String, DataFrame, Vec<Value>, Vec<usize>) {
    let study = json!({
        "name": name,
        "base": {"dim": 1, "n": 64, "m": 4, "t_end": 0.05, "source": "discrete"},
        "sweep": [{"zip": {"integrator": ["heun", "rk4", "rk4"], "threads": [1, 1, 2]}}],
        "repeat": 3,
        "target": {"field": "dt", "start": 0.0005, "below": 1e-5, "cost": "solve_cpu_s"}
    });
    let scratch = Scratch::new(name, &study);
    let stub = python_stub(&scratch.dir, "timing-nlsolve");
    let counts = scratch.dir.join("counts");
    std::fs::create_dir(&counts).unwrap();
    let run = scratch
        .command("run", &["--solver", stub.to_str().unwrap()])
        .env("NLSOLVE_REAL", binary("nlsolve"))
        .env("TIMING_COUNTS", &counts)
        .env("TIMING_NOISY", noisy)
        .output()
        .unwrap();
    let said = text(&run);
    assert!(run.status.success(), "{said}");
    let mut runs: Vec<usize> = std::fs::read_dir(&counts)
        .unwrap()
        .map(|f| std::fs::read(f.unwrap().path()).unwrap().len())
        .collect();
    runs.sort_unstable();
    let table = target_table(&scratch, name);
    (said, table, records(&scratch.runs(name)), runs)
}

/// Repeats of a candidate are one candidate: with `repeat: 3` one row each, its cost the median
/// of its answer's three timed runs (alone on the machine, after the searches) with their
/// interval. Under a solver whose timings are drawn from one distribution for every case
/// (`tests/scripts/timing-nlsolve`), two candidates tie and are printed as one place, "1–2
/// (tie within noise)"; the one timed ten times slower is third.
#[test]
fn repeats_are_one_candidate_and_overlapping_costs_are_a_tie() {
    let (said, table, stored, _) = run_the_tie("tie", "");
    assert_eq!(table.height(), 3, "one row per configuration");
    assert_eq!(floats(&table, "repeats"), [3.0; 3]);
    assert_eq!(floats(&table, "rank"), [1.0, 1.0, 3.0]);
    assert_eq!(floats(&table, "tied_to"), [2.0, 2.0, 3.0]);
    // The second to fourth of the timings, sorted: 0.09, 0.11, 0.12.
    assert_eq!(floats(&table, "cost")[..2], [0.11, 0.11]);
    assert_eq!(floats(&table, "cost_low")[..2], [0.09, 0.09]);
    assert_eq!(floats(&table, "cost_high")[..2], [0.12, 0.12]);
    assert!(said.contains("1–2 (tie within noise):"), "{said}");
    assert!(said.contains("3. integrator=rk4 threads=2:"), "{said}");
    // The answers' repeats are stored, each the answer's case.
    for r in 1..=3 {
        assert_eq!(
            stored.iter().filter(|x| x["repeat"] == r).count(),
            3,
            "repeat {r} of each answer"
        );
    }
}

/// An answer's timing run marked noisy runs again, alone, at most twice; the last run stands
/// (still marked noisy) and its timing is the one ranked. Here each answer's first repeat (its
/// case's run 1) is noisy, and so are its two reruns (runs 4 and 5): its cost is the median of
/// runs 5, 2 and 3 (0.08, 0.09, 0.11), where a rerun that did not replace the noisy timing would
/// give 0.11 (runs 1 to 3) and a third rerun 0.10 (runs 6, 2, 3).
#[test]
fn a_noisy_timing_of_an_answer_runs_again_at_most_twice_and_the_last_stands() {
    let (_, table, stored, runs) = run_the_tie("noisy-tie", "1,4,5");
    assert_eq!(floats(&table, "repeats"), [3.0; 3]);
    assert_eq!(floats(&table, "cost")[..2], [0.09, 0.09]);
    assert_eq!(floats(&table, "cost_low")[..2], [0.08, 0.08]);
    assert_eq!(floats(&table, "cost_high")[..2], [0.11, 0.11]);
    // Each answer's case: its probe, three repeats and two reruns of the first.
    assert_eq!(runs.iter().filter(|&&n| n == 6).count(), 3, "{runs:?}");
    let noisy: Vec<&Value> = (stored.iter())
        .filter(|x| x["provenance"]["noisy"] == true)
        .collect();
    assert_eq!(
        noisy.len(),
        3,
        "the first repeat of each answer stands noisy"
    );
    assert!(noisy.iter().all(|x| x["repeat"] == 1), "{noisy:?}");
}

/// A target study's bad input is refused at `plan`, naming the field and what to give.
#[test]
fn bad_targets_are_refused_at_plan_naming_the_field() {
    let scratch = Scratch::new("bad", &json!({}));
    for (target, field) in [
        (
            json!({"field": "n", "start": 16, "below": 0}),
            "target.below",
        ),
        (
            json!({"field": "n", "start": 16, "below": -1e-3}),
            "target.below",
        ),
        (
            json!({"field": "n", "start": 16, "below": 1e-3, "time": {"field": "m", "start": 2}}),
            "target.time.field",
        ),
        (
            json!({"field": "dt", "start": 0.01, "below": 1e-3, "time": {"field": "dt", "start": 0.01}}),
            "target.field",
        ),
        (
            json!({"field": "n", "start": 16, "below": 1e-3, "cost": "solve_sec"}),
            "target.cost",
        ),
    ] {
        scratch.write_study(&json!({
            "name": "bad", "base": {"dim": 1, "m": 4},
            "sweep": [{"product": {"integrator": ["rk4"]}}], "target": target
        }));
        let plan = scratch.nlstudy("plan", &[]);
        assert_eq!(plan.status.code(), Some(2), "{}", text(&plan));
        assert!(
            text(&plan).contains(&format!("`{field}`")),
            "{}",
            text(&plan)
        );
    }
}
