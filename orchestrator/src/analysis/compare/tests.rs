use super::*;
use schema::record::example::record;
use schema::record::Stored;

fn run(solve_s: f64, error: f64) -> Stored {
    record(
        json!({"status": "ok", "solve_s": solve_s, "error_l2_norm": error, "bonds": 100, "steps_done": 10}),
    )
}

fn refs(values: &[Stored]) -> Vec<&Stored> {
    values.iter().collect()
}

fn paired<'a>(point: &str, a: &'a [Stored], b: &'a [Stored]) -> Paired<'a> {
    Paired {
        point: point.into(),
        a: refs(a),
        b: refs(b),
    }
}

fn one(point: &str, a: &[Stored], b: &[Stored]) -> Comparison {
    let paired = [Paired {
        point: point.into(),
        a: refs(a),
        b: refs(b),
    }];
    compare(&paired, 0.1, &NoiseModel::uncalibrated())
}

fn verdict(comparison: &Comparison, metric: &str) -> Verdict {
    let change = comparison.changes.iter().find(|c| c.metric == metric);
    change.unwrap().verdict
}

#[test]
fn a_true_slowdown_is_called_and_noise_and_drift_are_not() {
    // A: times around 1 s with 3 % noise; B twice as slow; C the same as A.
    let noise = [1.0, 1.03, 0.98, 1.01, 0.97];
    let a: Vec<Stored> = noise.iter().map(|t| run(*t, 1e-3)).collect();
    let b: Vec<Stored> = noise.iter().rev().map(|t| run(2.0 * t, 1e-3)).collect();
    let c: Vec<Stored> = noise.iter().rev().map(|t| run(*t * 1.01, 1e-3)).collect();
    let slower = one("n=8", &a, &b);
    let solve = &slower.changes[0];
    assert_eq!((solve.metric, solve.verdict), ("solve_s", Verdict::Worse));
    let (low, high) = solve.interval.unwrap();
    assert!(
        low > 1.1 && high < 2.2 && (solve.ratio - 2.0).abs() < 1e-12,
        "{low} {high}"
    );
    assert_eq!(
        verdict(&slower, "bond_updates_per_s"),
        Verdict::Worse,
        "half the rate"
    );
    assert_eq!(verdict(&slower, "error_l2_norm"), Verdict::Same);
    assert_eq!(slower.regressions(), 2);
    let same = one("n=8", &a, &c);
    assert!(
        same.changes.iter().all(|c| c.verdict == Verdict::Same),
        "A/A"
    );
    // A whole run 30 % slower, its repeats tight: the interval clears 1.1, but two runs of
    // one build drift that much here (one point, at 1 s: the floor is ×1.75), so no verdict.
    let drifted: Vec<Stored> = noise.iter().map(|t| run(1.3 * t, 1e-3)).collect();
    let drift = one("n=8", &a, &drifted);
    let solve = &drift.changes[0];
    assert!(solve.interval.unwrap().0 > 1.1, "{:?}", solve.interval);
    assert_eq!(solve.verdict, Verdict::Same);
    assert!(solve.floor.unwrap() > 1.3);
}

#[test]
fn short_timings_and_noisy_runs_get_no_verdict() {
    let fast: Vec<Stored> = [1e-4, 1.1e-4, 0.9e-4]
        .iter()
        .map(|t| run(*t, 1e-3))
        .collect();
    let slow: Vec<Stored> = [5e-4, 5.1e-4, 4.9e-4]
        .iter()
        .map(|t| run(*t, 1e-3))
        .collect();
    assert_eq!(
        verdict(&one("p", &fast, &slow), "solve_s"),
        Verdict::TooShort
    );
    // Noisy runs with twice the memory: their wall times are not judged, their memory is (a
    // busy machine lengthens a solve, it does not grow its peak memory).
    let with_memory = |t: &f64, bytes: u64| {
        let mut r = run(*t, 1e-3);
        r.record_mut().unwrap().peak_memory_bytes = Some(bytes);
        r
    };
    let quiet: Vec<Stored> = [1.0, 1.01, 0.99]
        .iter()
        .map(|t| with_memory(t, 100_000_000))
        .collect();
    let noisy: Vec<Stored> = [5.0, 5.1, 4.9]
        .iter()
        .map(|t| {
            let mut r = with_memory(t, 200_000_000);
            r.record_mut().unwrap().provenance.noisy = true;
            r
        })
        .collect();
    let abstained = one("p", &quiet, &noisy);
    assert_eq!(verdict(&abstained, "solve_s"), Verdict::Abstained);
    assert_eq!(
        verdict(&abstained, "bond_updates_per_s"),
        Verdict::Abstained
    );
    assert_eq!(verdict(&abstained, "peak_memory_bytes"), Verdict::Worse);
    assert_eq!(abstained.regressions(), 1);
}

/// A history of two runs of one build, 12 points with 3 % jitter between them.
fn quiet_history() -> Vec<Stored> {
    let build = "ab".repeat(32);
    let mut random = fastrand::Rng::with_seed(7);
    let mut history = Vec::new();
    for key in 0..12 {
        for (k, stamp) in ["2026-01-01T00:00:00Z", "2026-01-01T01:00:00Z"]
            .iter()
            .enumerate()
        {
            let jitter = 1.0 + 0.02 * (random.usize(..100) as f64 / 50.0 - 1.0);
            history.push(record(json!({"key": format!("k{key}"), "status": "ok",
                "solve_s": 2.0 * jitter * (1.0 + 0.01 * k as f64), "run_id": format!("run{k}"),
                "provenance": {"fingerprint": build, "timestamp": stamp}})));
        }
    }
    history
}

/// A/A pairs of one build in the history make the point floor this machine's: a quiet
/// machine's history lowers it so that a 1.5× slowdown is called.
#[test]
fn the_floor_is_calibrated_from_pairs_of_runs_of_one_build() {
    let history = quiet_history();
    let quiet = NoiseModel::calibrate(&refs(&history));
    let default = NoiseModel::uncalibrated();
    assert!(
        quiet.point_floor("solve_s", 2.0) < 1.2,
        "{}",
        quiet.point_floor("solve_s", 2.0)
    );
    assert!(default.point_floor("solve_s", 2.0) > 1.5);
    assert_eq!(
        quiet.point_floor("solve_s", 2e-3),
        default.point_floor("solve_s", 2e-3),
        "no pairs there"
    );
    assert_eq!(
        quiet.run_floor("solve_s"),
        default.run_floor("solve_s"),
        "one pair of runs is not enough"
    );
    assert!(
        quiet.describe().contains("12 point pairs"),
        "{}",
        quiet.describe()
    );
    let a: Vec<Stored> = [2.0, 2.02, 1.98].iter().map(|t| run(*t, 1e-3)).collect();
    let b: Vec<Stored> = [3.0, 3.03, 2.97].iter().map(|t| run(*t, 1e-3)).collect();
    let paired = [paired("p", &a, &b)];
    assert_eq!(
        verdict(&compare(&paired, 0.1, &quiet), "solve_s"),
        Verdict::Worse
    );
    assert_eq!(
        verdict(&compare(&paired, 0.1, &default), "solve_s"),
        Verdict::Same
    );
    // Reruns of one key at a time (`run --force --only KEY`) have no common factor: each
    // point is its own median, 0 from it, and would make the floor 1. They calibrate nothing.
    let build = "ab".repeat(32);
    let one_key: Vec<Stored> = (0..12)
        .map(|k| {
            record(
                json!({"key": "k0", "status": "ok", "solve_s": 2.0 + 0.01 * k as f64,
                   "run_id": format!("run{k}"),
                   "provenance": {"fingerprint": build,
                                  "timestamp": format!("2026-01-01T00:{k:02}:00Z")}}),
            )
        })
        .collect();
    let alone = NoiseModel::calibrate(&refs(&one_key));
    assert!(alone.describe().contains("default"), "{}", alone.describe());
    // Pairs of two builds, or of one process, are no A/A pairs.
    let other_build =
        |r: &mut Stored| r.record_mut().unwrap().provenance.fingerprint = "cd".repeat(32);
    let one_process = |r: &mut Stored| r.run_id = Some("run0".into());
    for (field, change) in [
        ("fingerprint", &other_build as &dyn Fn(&mut Stored)),
        ("run_id", &one_process),
    ] {
        let changed: Vec<Stored> = history
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let mut r = r.clone();
                if k % 2 == 1 {
                    change(&mut r);
                }
                r
            })
            .collect();
        assert!(
            NoiseModel::calibrate(&refs(&changed))
                .describe()
                .contains("default"),
            "{field}"
        );
    }
}

/// Twelve points whose whole run is 20 % slower and one of them 1.5× beyond: the run's row
/// says 1.2, within the drift of whole runs; the one point is worse beside the others.
/// Each point's runs of both sides, as `compare` takes them.
fn all_paired(sides: &[(String, Vec<Stored>, Vec<Stored>)]) -> Vec<Paired<'_>> {
    sides.iter().map(|(p, a, b)| paired(p, a, b)).collect()
}

#[test]
fn a_point_is_judged_beside_its_run_and_the_run_on_its_own() {
    let quiet = NoiseModel::calibrate(&refs(&quiet_history()));
    let times = |t: f64| -> Vec<Stored> {
        [t, t * 1.01, t * 0.99]
            .iter()
            .map(|t| run(*t, 1e-3))
            .collect()
    };
    let sides: Vec<(String, Vec<Stored>, Vec<Stored>)> = (0..12)
        .map(|k| {
            let base = 2.0 + 0.1 * k as f64;
            let slower = if k == 5 { 1.5 } else { 1.0 };
            (format!("n={k}"), times(base), times(1.2 * slower * base))
        })
        .collect();
    let comparison = compare(&all_paired(&sides), 0.1, &quiet);
    let solve: Vec<&Change> = comparison
        .changes
        .iter()
        .filter(|c| c.metric == "solve_s")
        .collect();
    let whole = solve.iter().find(|c| c.point == WHOLE_RUN).unwrap();
    assert!(
        (whole.ratio - 1.2).abs() < 1e-9 && whole.verdict == Verdict::Same,
        "{}",
        whole.ratio
    );
    for change in solve.iter().filter(|c| c.point != WHOLE_RUN) {
        let expected = if change.point == "n=5" {
            Verdict::Worse
        } else {
            Verdict::Same
        };
        assert_eq!(change.verdict, expected, "{}", change.point);
    }
    assert!(
        (solve
            .iter()
            .find(|c| c.point == "n=5")
            .unwrap()
            .relative
            .unwrap()
            - 1.5)
            .abs()
            < 1e-9
    );
    // A whole run twice as slow is beyond the drift of whole runs.
    let doubled: Vec<(String, Vec<Stored>, Vec<Stored>)> = (0..6)
        .map(|k| (format!("n={k}"), times(2.0), times(4.0)))
        .collect();
    let comparison = compare(&all_paired(&doubled), 0.1, &quiet);
    assert_eq!(
        comparison
            .changes
            .iter()
            .find(|c| c.point == WHOLE_RUN && c.metric == "solve_s")
            .unwrap()
            .verdict,
        Verdict::Worse
    );
}

#[test]
fn speedups_get_intervals_from_the_repeats_of_both_points() {
    let times = |ts: &[f64]| -> Vec<Stored> { ts.iter().map(|t| run(*t, 1e-3)).collect() };
    let (base_a, base_b) = (times(&[2.0, 2.02, 1.98]), times(&[2.0, 2.03, 1.97]));
    let (two_a, two_b) = (times(&[1.0, 1.01, 0.99]), times(&[1.6, 1.62, 1.58]));
    let points = [
        paired("threads=1", &base_a, &base_b),
        paired("threads=2", &two_a, &two_b),
    ];
    let baselines = [("threads=2".to_string(), "threads=1".to_string())];
    let quiet = NoiseModel::uncalibrated();
    let changes = compare_speedups(&points, &baselines, 0.1, &quiet);
    assert_eq!(changes.len(), 1);
    let speedup = &changes[0];
    assert!((speedup.a - 2.0).abs() < 1e-12 && (speedup.b - 1.25).abs() < 1e-12);
    let (low, high) = speedup.interval.unwrap();
    assert!(low < 0.625 && 0.625 < high, "{low} {high}");
    // A speedup 2 → 1.25 is a factor 1.6, within this VM's drift of two points near 1 s
    // (×2.0: they drift by σ 0.10 at 1 s and 0.13 at 0.1 s).
    assert_eq!(speedup.verdict, Verdict::Same);
    let (two_b, base_b) = (times(&[4.0, 4.04, 3.96]), times(&[2.0, 2.02, 1.98]));
    let points = [
        paired("threads=1", &base_a, &base_b),
        paired("threads=2", &two_a, &two_b),
    ];
    let changes = compare_speedups(&points, &baselines, 0.1, &quiet);
    assert_eq!(changes[0].verdict, Verdict::Worse, "speedup 2 → 0.5");
    let single = [
        paired("threads=2", &two_a[..1], &two_b[..1]),
        paired("threads=1", &base_a[..1], &base_b[..1]),
    ];
    let changes = compare_speedups(&single, &baselines, 0.1, &quiet);
    assert_eq!(changes[0].verdict, Verdict::NoInterval);
}

#[test]
fn orders_are_compared_by_their_distance_to_the_theory() {
    let row = |order: f64| {
        let mut row = Row::default();
        row.set("point", json!("n=64"));
        row.set("order_l2", json!(order));
        row
    };
    let verdict = |a: f64, b: f64| compare_orders(&[row(a)], &[row(b)])[0].verdict;
    assert_eq!(verdict(2.0, 1.85), Verdict::Worse);
    assert_eq!(verdict(2.0, 2.05), Verdict::Same);
    assert_eq!(verdict(1.7, 1.98), Verdict::Better, "closer to 2");
    assert!(
        compare_orders(&[row(2.0)], &[]).is_empty(),
        "a point on one side"
    );
}

#[test]
fn errors_use_tolerances_one_repeat_gives_no_interval_and_one_sided_points_are_listed() {
    let a = [run(1.0, 0.0)];
    let b = [run(1.0, 1e-15)];
    let worse = [run(1.0, 1e-6)];
    let zero = one("p", &a, &b);
    assert_eq!(
        verdict(&zero, "error_l2_norm"),
        Verdict::Same,
        "a reference of 0 with the absolute tolerance"
    );
    assert_eq!(verdict(&zero, "solve_s"), Verdict::NoInterval);
    assert_eq!(one("p", &a, &worse).regressions(), 1);
    let one_sided = compare(
        &[paired("p", &a, &[]), paired("q", &[], &b)],
        0.1,
        &NoiseModel::uncalibrated(),
    );
    assert_eq!(
        (one_sided.only_a, one_sided.only_b),
        (vec!["p".to_string()], vec!["q".to_string()])
    );
}
