//! The distributed solver through `mpirun`, as a user runs it: its final field and its record's
//! numbers must equal the serial run's (the field to 1e-12, in fact bit for bit), for every rank
//! count, both partitions, 1D and 2D, two kernels and horizons from one cell to eight; ε wider
//! than a subdomain and uneven splits work; a rank count that cannot partition the grid is
//! refused by every rank with exit code 2, without hanging. System tests (`make test` runs
//! them): they launch Open MPI's `mpirun`, and take over a minute together.

use nonlocal_study::{
    binary, mpirun, mpirun_with, nlsolve, numbers_of, read_field, record, RESULT_FIELDS,
};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::atomic::{AtomicUsize, Ordering};

const TOLERANCE: f64 = 1e-12;

/// A fresh path for a field file (removed once read).
fn field_path() -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    std::env::temp_dir().join(format!(
        "nlsolve-distributed-{}-field-{}.bin",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// One run: its record and final field.
struct Run {
    record: Value,
    field: Vec<f64>,
}

fn finished(output: &Output, path: &Path, what: &str) -> Run {
    assert!(
        output.status.success(),
        "{what} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let run = Run {
        record: record(output),
        field: read_field(path),
    };
    std::fs::remove_file(path).unwrap();
    run
}

fn serial(case: &[&str]) -> Run {
    let path = field_path();
    let mut args = vec!["run", "--write-field", path.to_str().unwrap()];
    args.extend(case);
    finished(&nlsolve(&args, None), &path, "serial run")
}

fn distributed(ranks: usize, partition: &str, threads: usize, case: &[&str]) -> Run {
    let path = field_path();
    let (ranks_text, threads_text) = (ranks.to_string(), threads.to_string());
    let exe = binary("nlsolve");
    let mut program = vec![
        exe.to_str().unwrap(),
        "run",
        "--write-field",
        path.to_str().unwrap(),
    ];
    program.extend(case);
    program.extend(["--ranks", &ranks_text, "--partition", partition]);
    program.extend(["--threads", &threads_text]);
    let what = format!("{ranks} ranks, {partition}: {case:?}");
    finished(&mpirun(ranks, &program), &path, &what)
}

fn close(a: &Value, b: &Value) -> bool {
    match (a.as_f64(), b.as_f64()) {
        (Some(a), Some(b)) => (a - b).abs() <= TOLERANCE * a.abs().max(1.0),
        _ => a == b,
    }
}

/// The distributed run reproduces the serial field and numbers, and reports its distribution.
fn assert_agrees(serial: &Run, run: &Run, ranks: usize, partition: &str, what: &str) {
    assert_eq!(serial.field.len(), run.field.len(), "{what}: field length");
    let difference = serial
        .field
        .iter()
        .zip(&run.field)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        difference <= TOLERANCE,
        "{what}: field differs by {difference:e}"
    );
    for field in RESULT_FIELDS.iter().chain(&["status", "steps_done"]) {
        let (a, b) = (&serial.record[*field], &run.record[*field]);
        assert!(close(a, b), "{what}: {field} serial {a} vs distributed {b}");
    }
    let record = &run.record;
    assert_eq!(record["ranks"], ranks, "{what}");
    assert_eq!(record["partition"], partition, "{what}");
    assert_eq!(record["provenance"]["ranks"], ranks, "{what}");
    if partition == "block" {
        let blocks = record["px"].as_u64().unwrap() * record["py"].as_u64().unwrap();
        assert_eq!(blocks, ranks as u64, "{what}: px × py");
    }
    let halo = record["halo_nodes"].as_u64().unwrap();
    assert_eq!(ranks > 1, halo > 0, "{what}: halo_nodes {halo}");
    assert_eq!(record["halo_bytes"].as_u64().unwrap(), 8 * halo, "{what}");
    assert!(record["imbalance"].as_f64().unwrap() >= 1.0, "{what}");
    // Ranks exchange halos and the exchange is timed; it is part of the solve, never longer.
    let comm = record["comm_s"].as_f64().unwrap();
    assert!(ranks == 1 || comm > 0.0, "{what}: comm_s {comm}");
    assert!(
        comm <= record["solve_s"].as_f64().unwrap(),
        "{what}: comm_s {comm}"
    );
}

/// Every rank count of the issue, both partitions, two kernels and m ∈ {1, 3, 8} (the linear
/// kernel vanishes at m = 1, so it starts at 3), with each source mode and the total error.
fn rank_sweep(dim: usize, n: usize) {
    let (dim_text, n_text) = (dim.to_string(), n.to_string());
    for (kernel, m, source) in [
        ("constant", "1", "continuum"),
        ("constant", "3", "discrete"),
        ("constant", "8", "local"),
        ("linear", "3", "continuum"),
        ("linear", "8", "discrete"),
    ] {
        let case = [
            "--dim",
            &dim_text,
            "--n",
            &n_text,
            "--m",
            m,
            "--kernel",
            kernel,
            "--source",
            source,
            "--t-end",
            "0.004",
            "--cfl",
            "0.5",
            "--error-total",
        ];
        let reference = serial(&case);
        for ranks in [1, 2, 3, 4, 6] {
            for partition in ["block", "graph"] {
                if ranks == 1 && partition == "graph" {
                    continue; // one rank owns everything either way
                }
                let threads = if ranks == 2 { 2 } else { 1 };
                let what = format!("{ranks} ranks × {threads} threads, {partition}: {case:?}");
                let run = distributed(ranks, partition, threads, &case);
                assert_agrees(&reference, &run, ranks, partition, &what);
            }
        }
    }
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn one_dimensional_runs_equal_the_serial_run_on_every_rank_count() {
    rank_sweep(1, 60);
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn two_dimensional_runs_equal_the_serial_run_on_every_rank_count() {
    rank_sweep(2, 24);
}

/// n = 40 on 6 ranks gives subdomains of 6 or 7 nodes, narrower than the reach m = 8: a rank
/// needs ghosts from ranks two away. That works: each rank receives the 8 nodes on each side
/// (fewer where D ends), whoever owns them.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_horizon_wider_than_a_subdomain_reaches_past_the_neighbouring_ranks() {
    let case = [
        "--dim",
        "1",
        "--n",
        "40",
        "--m",
        "8",
        "--problem",
        "bump",
        "--t-end",
        "0.001",
        "--cfl",
        "0.9",
    ];
    let reference = serial(&case);
    let run = distributed(6, "block", 1, &case);
    assert_agrees(&reference, &run, 6, "block", "ε wider than a subdomain");
    let ghosts: usize = (0..6)
        .map(|r| {
            let (x0, x1) = (r * 40 / 6, (r + 1) * 40 / 6);
            x0.min(8) + (40 - x1).min(8)
        })
        .sum();
    assert_eq!(run.record["halo_nodes"], ghosts);
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn an_uneven_split_of_101_nodes_on_4_ranks_equals_the_serial_run() {
    for dim in ["1", "2"] {
        let case = [
            "--dim", dim, "--n", "101", "--m", "3", "--kernel", "linear", "--t-end", "0.0005",
            "--cfl", "0.5",
        ];
        let reference = serial(&case);
        for partition in ["block", "graph"] {
            let run = distributed(4, partition, 1, &case);
            assert_agrees(
                &reference,
                &run,
                4,
                partition,
                &format!("{dim}D n = 101, {partition}"),
            );
        }
    }
}

/// The explicit Runge–Kutta integrators run over ranks with the serial bits: each stage is one
/// application of the distributed operator and passes over the rank's own nodes. The step's
/// amplification measured with them agrees too.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn runge_kutta_integrators_over_ranks_equal_the_serial_run() {
    for integrator in ["heun", "rk4"] {
        let case = [
            "--dim",
            "2",
            "--n",
            "40",
            "--m",
            "3",
            "--kernel",
            "linear",
            "--t-end",
            "0.001",
            "--cfl",
            "0.9",
            "--integrator",
            integrator,
            "--amplification-steps",
            "400",
        ];
        let reference = serial(&case);
        for partition in ["block", "graph"] {
            let run = distributed(2, partition, 1, &case);
            let what = format!("{integrator}, {partition}");
            assert_agrees(&reference, &run, 2, partition, &what);
            // The step's amplification from L_h's spectrum: Lanczos's inner products summed
            // over ranks, to round-off. Its interval's ends are error bounds from residuals
            // near the tolerance, whose last digits follow that round-off: each interval holds
            // the exact radius, so the two must overlap.
            let a = &reference.record["amplification"];
            let b = &run.record["amplification"];
            assert!(
                a.is_f64() && close(a, b),
                "{what}: amplification serial {a}, distributed {b}"
            );
            let interval = |r: &Run| {
                let end = |f: &str| r.record[f].as_f64().expect("an interval end");
                (end("amplification_low"), end("amplification_high"))
            };
            let ((a_low, a_high), (b_low, b_high)) = (interval(&reference), interval(&run));
            assert!(
                a_low <= b_high && b_low <= a_high,
                "{what}: serial [{a_low}, {a_high}], distributed [{b_low}, {b_high}]"
            );
        }
    }
}

/// The FFT backend over ranks: each rank convolves its window (owned nodes and the ghosts it
/// receives) by a local FFT, whose lengths differ from the serial run's, so the fields agree to
/// rounding (the issue asks 1e-11 relative; `assert_agrees` holds them to 1e-12). 1D and 2D, both
/// partitions, a horizon wider than a subdomain, forward Euler and Crank–Nicolson.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn the_fft_backend_over_ranks_equals_the_serial_fft_run() {
    for (dim, n, m, integrator, cfl, t_end) in [
        (1, "101", "3", "forward_euler", "0.9", "0.002"),
        (2, "48", "6", "forward_euler", "0.9", "0.01"),
        (2, "40", "15", "rk4", "0.9", "0.1"),
        (2, "40", "3", "crank_nicolson", "20", "0.05"),
    ] {
        let dim_text = dim.to_string();
        let mut case = vec![
            "--dim",
            &dim_text,
            "--n",
            n,
            "--m",
            m,
            "--kernel",
            "linear",
            "--backend",
            "fft",
            "--t-end",
            t_end,
            "--cfl",
            cfl,
            "--integrator",
            integrator,
        ];
        if integrator == "crank_nicolson" {
            case.extend(["--rtol", "1e-13"]);
        }
        let reference = serial(&case);
        assert_eq!(reference.record["backend"], "fft");
        assert!(reference.record["steps"].as_u64().unwrap() >= 3, "{case:?}");
        let partitions: &[(usize, &str)] = if dim == 1 {
            &[(3, "block"), (4, "graph")]
        } else {
            &[(2, "block"), (4, "block"), (3, "graph")]
        };
        for &(ranks, partition) in partitions {
            let run = distributed(ranks, partition, 1, &case);
            let what = format!("{dim}D m = {m} {integrator}, {ranks} ranks, {partition}");
            assert_eq!(run.record["backend"], "fft", "{what}");
            assert_agrees(&reference, &run, ranks, partition, &what);
        }
    }
}

/// The implicit integrators run over ranks: CG applies the distributed operator, and the
/// sine-transform preconditioner runs on slabs of rows (2D; `parallel/slab_sine.rs`), reached
/// from the block partition's own slabs, from 2 × 2 blocks or from METIS's parts by an
/// all-to-all, or on the gathered row (1D). The inner products are summed over ranks in another
/// order, so the fields agree to the solves' tolerance (here 1e-13), not bit for bit.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn implicit_integrators_over_ranks_equal_the_serial_run() {
    for (dim, n, integrator) in [
        ("2", "40", "backward_euler"),
        ("2", "40", "crank_nicolson"),
        ("1", "101", "crank_nicolson"),
    ] {
        let case = [
            "--dim",
            dim,
            "--n",
            n,
            "--m",
            "3",
            "--kernel",
            "linear",
            "--t-end",
            "0.05",
            "--cfl",
            "20",
            "--rtol",
            "1e-13",
            "--integrator",
            integrator,
        ];
        let reference = serial(&case);
        let iterations = |r: &Run| r.record["solve_iterations_max"].as_u64().unwrap();
        assert!(iterations(&reference) >= 2, "{integrator}: a real solve");
        let runs: &[(usize, &str, &[&str])] = match dim {
            "2" => &[
                (2, "block", &[]),
                (3, "block", &[]),
                (4, "block", &[]),
                (4, "block", &["--px", "2", "--py", "2"]),
                (3, "graph", &[]),
                (4, "graph", &[]),
            ],
            _ => &[(3, "block", &[]), (2, "graph", &[])],
        };
        for &(ranks, partition, shape) in runs {
            let case: Vec<&str> = case.iter().chain(shape).copied().collect();
            let run = distributed(ranks, partition, 1, &case);
            let what = format!("{dim}D {integrator}, {ranks} ranks, {partition} {shape:?}");
            assert_agrees(&reference, &run, ranks, partition, &what);
            assert_eq!(run.record["solves_unconverged"], 0, "{what}");
            assert!(
                iterations(&run).abs_diff(iterations(&reference)) <= 1,
                "{what}"
            );
            let traffic = &run.record["traffic"];
            let count = |field: &str| traffic[field].as_u64().unwrap();
            // Every halo exchange sends what the ghosts receive.
            assert_eq!(
                count("halo_bytes"),
                count("halo_exchanges") * run.record["halo_bytes"].as_u64().unwrap(),
                "{what}"
            );
            if dim == "2" && partition == "block" && shape.is_empty() {
                // The block partition gives the implicit integrators the transform's slabs, so
                // every all-to-all is a transpose: rank q sends its h_q rows of each other
                // rank's h_p columns, n² − Σ h_q² values in all.
                assert_eq!(
                    (run.record["px"].as_u64(), run.record["py"].as_u64()),
                    (Some(1), Some(ranks as u64)),
                    "{what}"
                );
                let n: u64 = n.parse().unwrap();
                let p = ranks as u64;
                let rows = (0..p).map(|q| (q + 1) * n / p - q * n / p);
                let moved = n * n - rows.map(|h| h * h).sum::<u64>();
                assert_eq!(
                    count("all_to_all_bytes"),
                    count("all_to_alls") * 8 * moved,
                    "{what}"
                );
                assert!(count("all_to_alls") >= 2 * iterations(&run), "{what}");
            }
        }
    }
}

/// Every quadrature's weights, and the exact collar's source term, travel to the ranks.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn quadratures_and_the_exact_collar_equal_the_serial_run() {
    for (dim, quadrature, source, collar) in [
        ("1", "partial_volume", "continuum", "exact"),
        ("2", "ac", "local", "exact"),
        ("2", "partial_volume", "discrete", "zero"),
    ] {
        let case = [
            "--dim",
            dim,
            "--n",
            "30",
            "--eps",
            "0.11",
            "--kernel",
            "gaussian",
            "--quadrature",
            quadrature,
            "--source",
            source,
            "--collar",
            collar,
            "--t-end",
            "0.003",
            "--cfl",
            "0.5",
            "--error-total",
        ];
        let reference = serial(&case);
        for partition in ["block", "graph"] {
            let run = distributed(3, partition, 1, &case);
            assert_agrees(
                &reference,
                &run,
                3,
                partition,
                &format!("{case:?} {partition}"),
            );
        }
    }
}

/// The halo a run exchanges is what `nlsolve partition` reports without running.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn the_partition_report_matches_the_run() {
    let case = [
        "--dim", "2", "--n", "101", "--m", "3", "--t-end", "0.0002", "--cfl", "0.5",
    ];
    for partition in ["block", "graph"] {
        let run = distributed(4, partition, 1, &case);
        let mut args = vec!["partition", "--ranks", "4", "--partition", partition];
        args.extend(&case);
        let report = record(&nlsolve(&args, None));
        for field in ["halo_nodes", "halo_bytes", "imbalance", "px", "py"] {
            assert_eq!(report[field], run.record[field], "{partition}: {field}");
        }
    }
    let report = record(&nlsolve(
        &[
            "partition",
            "--dim",
            "2",
            "--n",
            "101",
            "--m",
            "3",
            "--ranks",
            "4",
        ],
        None,
    ));
    assert_eq!(
        (report["px"].as_u64(), report["py"].as_u64()),
        (Some(2), Some(2))
    );
}

/// mpirun's output and each rank's exit code, printed by a shell around nlsolve. mpirun is told
/// not to kill the other ranks when the first exits non-zero, so each rank shows its own code.
fn exit_codes_of_every_rank(ranks: usize, args: &str) -> (Output, Vec<String>) {
    let nlsolve = binary("nlsolve").display().to_string();
    let plain: Vec<&str> = std::iter::once(nlsolve.as_str())
        .chain(args.split(' '))
        .collect();
    let output = mpirun(ranks, &plain);
    let script = format!(
        "{nlsolve} {args}; code=$?; echo \"rank $OMPI_COMM_WORLD_RANK exit $code\"; exit $code"
    );
    let every_rank = mpirun_with(
        ranks,
        &["sh", "-c", &script],
        &[("OMPI_MCA_orte_abort_on_non_zero_status", "0")],
    );
    let stdout = String::from_utf8_lossy(&every_rank.stdout);
    let mut codes: Vec<String> = stdout
        .lines()
        .filter(|l| l.starts_with("rank "))
        .map(String::from)
        .collect();
    codes.sort();
    (output, codes)
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn more_ranks_than_nodes_is_refused_by_every_rank_with_exit_code_2() {
    let (output, codes) = exit_codes_of_every_rank(
        5,
        "run --dim 1 --n 4 --m 1 --t-end 0.01 --cfl 0.5 --ranks 5",
    );
    let expected: Vec<String> = (0..5).map(|r| format!("rank {r} exit 2")).collect();
    assert_eq!(codes, expected);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("case field `ranks`: 5 ranks cannot share 4 nodes"),
        "{stderr}"
    );
    assert_eq!(
        stderr.matches("case field").count(),
        1,
        "rank 0 alone explains: {stderr}"
    );
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_rank_count_that_differs_from_mpirun_or_has_no_block_shape_is_refused() {
    let (output, codes) = exit_codes_of_every_rank(
        3,
        "run --dim 1 --n 40 --m 1 --t-end 0.01 --cfl 0.5 --ranks 2",
    );
    assert_eq!(output.status.code(), Some(2));
    assert_eq!(codes.len(), 3);
    assert!(codes.iter().all(|c| c.ends_with("exit 2")), "{codes:?}");
    assert!(String::from_utf8_lossy(&output.stderr).contains("mpirun started 3"));

    // 7 ranks on a 5 × 5 grid: 7 × 1 does not fit, so no block partition exists.
    let (output, codes) = exit_codes_of_every_rank(
        7,
        "run --dim 2 --n 5 --m 1 --t-end 0.01 --cfl 0.5 --ranks 7",
    );
    assert!(
        codes.iter().all(|c| c.ends_with("exit 2")) && codes.len() == 7,
        "{codes:?}"
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("no factor pair px × py"), "{stderr}");
}

/// Instability is detected by the same reduction on every rank: the run ends `diverged` at the
/// serial run's step.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn an_unstable_run_diverges_at_the_serial_step() {
    let case = [
        "--dim",
        "2",
        "--n",
        "32",
        "--m",
        "3",
        "--t-end",
        "1",
        "--cfl",
        "1.3",
        "--allow-unstable",
    ];
    let reference = serial(&case);
    assert_eq!(reference.record["status"], "diverged");
    let run = distributed(3, "graph", 1, &case);
    for field in ["status", "diverged_step", "diverged_time", "steps_done"] {
        assert_eq!(reference.record[field], run.record[field], "{field}");
    }
}

/// FETI over ranks (several subdomains per rank, p = 3 and 4 with floating subdomains) computes
/// the one-process iterates: the same field bit for bit and the same iteration count. The
/// one-process field equals the single-domain direct solve (solver/tests/steady.rs).
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn feti_on_several_ranks_gives_the_one_process_field_bit_for_bit_and_its_numbers() {
    for (p, ranks, preconditioner) in [
        ("3", 2, "dirichlet"),
        ("4", 3, "dirichlet_cg"),
        ("4", 2, "none"),
        ("5", 3, "dirichlet_scaled"),
    ] {
        let case = [
            "--method",
            "feti",
            "--dim",
            "2",
            "--n",
            "64",
            "--m",
            "4",
            "--kernel",
            "inverse_distance",
            "--subdomains",
            p,
            "--preconditioner",
            preconditioner,
        ];
        let one = serial(&case);
        let many = distributed(ranks, "block", 1, &case);
        assert_eq!(
            one.field, many.field,
            "p {p} on {ranks} ranks, {preconditioner}"
        );
        assert_eq!(one.record["iterations"], many.record["iterations"]);
        // Measured rank by rank on the subdomains each holds, without the whole field.
        for field in [
            "error_max",
            "error_l2",
            "mass",
            "max_abs",
            "relative_residual",
        ] {
            let (a, b) = (&one.record[field], &many.record[field]);
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(
                (a - b).abs() <= 1e-9 * a.abs(),
                "p {p} on {ranks} ranks: {field} {a} vs {b}"
            );
        }
        assert_eq!(many.record["ranks"], ranks);
        assert_eq!(
            many.record["subdomains"].as_u64(),
            Some(p.parse::<u64>().unwrap().pow(2))
        );
    }
}

/// CG over ranks applies the same A through the halo exchange; its inner products are summed in
/// another order, so the iterates agree to rounding, not bit for bit.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn steady_cg_over_ranks_converges_to_the_one_process_solution() {
    let case = [
        "--method",
        "steady_cg",
        "--dim",
        "2",
        "--n",
        "60",
        "--m",
        "3",
        "--kernel",
        "inverse_distance",
        "--rtol",
        "1e-10",
    ];
    let one = serial(&case);
    for (ranks, partition) in [(2, "block"), (3, "graph")] {
        let many = distributed(ranks, partition, 1, &case);
        let scale = one.field.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let difference = one
            .field
            .iter()
            .zip(&many.field)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(
            difference < 1e-8 * scale,
            "{ranks} ranks {partition}: {difference:e}"
        );
        let iterations = |r: &Run| r.record["iterations"].as_i64().unwrap();
        assert!((iterations(&one) - iterations(&many)).abs() <= 1);
        // Measured rank by rank and summed, without the whole field on any rank.
        let residual = many.record["relative_residual"].as_f64().unwrap();
        assert!(
            residual <= 2e-10,
            "{ranks} ranks {partition}: residual {residual}"
        );
        for field in ["error_max", "error_l2", "mass", "max_abs"] {
            let (a, b) = (&one.record[field], &many.record[field]);
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(
                (a - b).abs() <= 1e-6 * a.abs(),
                "{ranks} ranks {partition}: {field} {a} vs {b}"
            );
        }
    }
}

/// A rank holds its share of the grid, not the whole of it: the record's peak memory (the
/// largest rank's), less a trivial case's on as many ranks (the binary and the MPI library),
/// falls with the rank count, for forward Euler and Crank–Nicolson (2D, n = 1024, m = 4).
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn peak_memory_per_rank_falls_with_the_rank_count() {
    let peak = |ranks: usize, case: &[&str]| -> f64 {
        let output = if ranks == 1 {
            nlsolve(case, None)
        } else {
            let exe = binary("nlsolve");
            let ranks_text = ranks.to_string();
            let mut program = vec![exe.to_str().unwrap()];
            program.extend(case);
            program.extend(["--ranks", &ranks_text]);
            mpirun(ranks, &program)
        };
        assert!(output.status.success(), "{ranks} ranks: {case:?}");
        record(&output)["peak_memory_bytes"].as_f64().unwrap()
    };
    let trivial = [
        "run", "--dim", "2", "--n", "16", "--m", "2", "--t-end", "1e-3", "--cfl", "0.5",
    ];
    let fixed: Vec<f64> = [1, 2, 4].iter().map(|&p| peak(p, &trivial)).collect();
    for (integrator, t_end, cfl) in [
        ("forward_euler", "5e-7", "0.9"),
        ("crank_nicolson", "1e-4", "100"),
    ] {
        let case = [
            "run",
            "--dim",
            "2",
            "--n",
            "1024",
            "--m",
            "4",
            "--source",
            "discrete",
            "--threads",
            "1",
            "--integrator",
            integrator,
            "--t-end",
            t_end,
            "--cfl",
            cfl,
        ];
        let net: Vec<f64> = [1, 2, 4]
            .iter()
            .zip(&fixed)
            .map(|(&p, fixed)| peak(p, &case) - fixed)
            .collect();
        let (half, quarter) = (net[1] / net[0], net[2] / net[0]);
        assert!(
            half <= 0.65 && quarter <= 0.4,
            "{integrator}: per-rank peak at 2 and 4 ranks is {half:.2} and {quarter:.2} of one rank's ({net:?} bytes above the trivial case's {fixed:?})"
        );
    }
}

/// The step a checkpoint file was taken at, from its header (the line after its first).
fn checkpoint_step(path: &Path) -> u64 {
    let bytes = std::fs::read(path).unwrap();
    let header = bytes.split(|&b| b == b'\n').nth(1).unwrap();
    serde_json::from_slice::<Value>(header).unwrap()["step"]
        .as_u64()
        .unwrap()
}

/// Over two ranks, `nlsolve run --checkpoint`: SIGTERM to every rank (as `scancel --signal`
/// and a scheduler's warning deliver it) stops them at one step, each rank's file written
/// (rank 0's at FILE, rank 1's at FILE.rank1) before any exits 143; resumed over two ranks, the
/// record is the record of a run never stopped, bit for bit but for timings, and the files go.
/// A set of files not of one step (one missing) is not resumed: the run starts afresh.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_run_over_two_ranks_stops_at_one_step_and_resumes_with_the_same_bits() {
    stops_over_two_ranks_and_resumes(
        "heat",
        r#"{"dim": 2, "n": 64, "m": 3, "t_end": 0.5, "cfl": 0.5, "ranks": 2, "source": "discrete"}"#,
        200,
    );
}

/// The same for the other integrators, each of which carries its own state (Heun's and RK4's
/// stages, the θ-steps' solve counts and warm start).
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn every_integrator_over_two_ranks_stops_at_one_step_and_resumes_with_the_same_bits() {
    for (integrator, cfl) in [
        ("heun", 0.5),
        ("rk4", 0.9),
        ("backward_euler", 1.0),
        ("crank_nicolson", 1.0),
    ] {
        let case = format!(
            r#"{{"dim": 2, "n": 64, "m": 3, "t_end": 0.05, "cfl": {cfl}, "ranks": 2, "source": "discrete", "integrator": "{integrator}"}}"#
        );
        stops_over_two_ranks_and_resumes(integrator, &case, 20);
    }
}

/// The same for the steady solves, whose steps are CG iterations: steady CG over the ranks'
/// rows and FETI's projected CG over their subdomains.
#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn a_steady_solve_over_two_ranks_stops_at_one_iteration_and_resumes_with_the_same_bits() {
    stops_over_two_ranks_and_resumes(
        "steady_cg",
        r#"{"method": "steady_cg", "dim": 2, "n": 512, "m": 4, "rtol": 1e-12, "ranks": 2}"#,
        25,
    );
    stops_over_two_ranks_and_resumes(
        "feti",
        r#"{"method": "feti", "dim": 2, "n": 192, "m": 3, "subdomains": 8, "rtol": 1e-12, "ranks": 2}"#,
        4,
    );
}

/// Runs `case` over two ranks whole, then checkpointing every `every` steps until SIGTERM
/// stops it, then with one rank's file missing, then resumed, as the tests above say.
fn stops_over_two_ranks_and_resumes(name: &str, case: &str, every: u64) {
    let scratch = tempfile::Builder::new()
        .prefix(&format!("nlsolve-ranks-checkpoint-{name}-"))
        .tempdir()
        .unwrap();
    let dir = scratch.path();
    let case_file = dir.join("case.json");
    std::fs::write(&case_file, case).unwrap();
    let nlsolve = binary("nlsolve");
    let (nlsolve, case) = (nlsolve.to_str().unwrap(), case_file.to_str().unwrap());
    let file = dir.join("run.checkpoint");
    let rank1 = dir.join("run.checkpoint.rank1");
    let path = file.to_str().unwrap();
    let whole = record(&mpirun(2, &[nlsolve, "run", "--case", case]));
    let length = whole["iterations"].as_u64().or(whole["steps"].as_u64());
    assert!(length.unwrap() > 2 * every, "{name}: too short: {whole}");

    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/mpirun");
    let args = [
        "run",
        "--case",
        case,
        "--checkpoint",
        path,
        "--checkpoint-every-steps",
        &every.to_string(),
    ];
    // The signal must reach the ranks inside their time loop: caught once rank 0 has written
    // a checkpoint (rank 1 is then past step 1's exchange, in the loop too), with at least as
    // many steps still to go; a run that still ends before the signal is started again (it is
    // not the run's fault). The ranks run at the machine's normal priority: at the lowest, their
    // steps up to the checkpoint crawled beside the other tests (108 to 214 s for the four
    // integrators in CI runs, against 24 s at normal priority beside a busy process).
    let mut stopped = None;
    for _attempt in 0..5 {
        let mut child = std::process::Command::new(script)
            .args(["-n", "2", nlsolve])
            .args(args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        while !file.exists() && child.try_wait().unwrap().is_none() {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        // The ranks, not mpirun: each gets the signal, as a batch system's tasks do.
        let pattern = format!("^{nlsolve} run --case {case} --checkpoint");
        std::process::Command::new("pkill")
            .args(["-TERM", "-f", &pattern])
            .status()
            .unwrap();
        let output = child.wait_with_output().unwrap();
        if !output.status.success() {
            stopped = Some(output);
            break;
        }
    }
    let stopped = stopped.expect("five runs ended before the signal reached their time loop");
    let said = String::from_utf8_lossy(&stopped.stderr);
    assert!(stopped.stdout.is_empty(), "a stopped run prints no record");
    assert!(said.contains("stopped at"), "{name}: {said}");
    let step = checkpoint_step(&file);
    assert_eq!(
        step,
        checkpoint_step(&rank1),
        "the ranks stopped at one step"
    );

    // One rank's file missing: the run starts afresh, and says so.
    let saved = std::fs::read(&rank1).unwrap();
    std::fs::remove_file(&rank1).unwrap();
    let kept = dir.join("kept");
    std::fs::copy(&file, &kept).unwrap();
    let afresh = mpirun(2, &[nlsolve, "run", "--case", case, "--checkpoint", path]);
    let said = String::from_utf8_lossy(&afresh.stderr);
    assert!(said.contains("not of one step"), "{said}");
    let afresh = record(&afresh);
    assert_eq!(
        afresh["resumed_from_step"].as_u64().unwrap_or(0),
        0,
        "{afresh}"
    );
    assert_eq!(numbers_of(&afresh), numbers_of(&whole));

    std::fs::rename(&kept, &file).unwrap();
    std::fs::write(&rank1, saved).unwrap();
    let resumed = record(&mpirun(
        2,
        &[nlsolve, "run", "--case", case, "--checkpoint", path],
    ));
    assert_eq!(
        resumed["resumed_from_step"].as_u64(),
        Some(step),
        "{resumed}"
    );
    assert_eq!(
        numbers_of(&resumed),
        numbers_of(&whole),
        "the resumed run's record differs"
    );
    assert!(
        !file.exists() && !rank1.exists(),
        "the files stay after the record"
    );
}
