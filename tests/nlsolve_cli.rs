//! `nlsolve` as a process: a record on stdout, identical numbers for any thread count, and bad
//! input refused with exit code 2 and a sentence naming the field.

use nonlocal_study::{nlsolve, record, RESULT_FIELDS};
use schema::case::Case;
use serde_json::{json, Value};

const BASE: &[&str] = &[
    "run", "--dim", "2", "--n", "48", "--m", "3", "--kernel", "linear", "--t-end", "0.02", "--cfl",
    "0.5",
];

fn result_numbers(record: &Value) -> Vec<(String, Value)> {
    RESULT_FIELDS
        .iter()
        .map(|k| (k.to_string(), record[k].clone()))
        .collect()
}

#[test]
fn flags_give_one_record_with_the_fields_of_the_contract() {
    let out = nlsolve(BASE, None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec = record(&out);
    assert_eq!(rec["status"], "ok");
    let bookkeeping = [
        "case",
        "message",
        "setup_s",
        "solve_s",
        "step_s",
        "provenance",
    ];
    for field in RESULT_FIELDS.iter().chain(&bookkeeping) {
        assert!(rec.get(field).is_some(), "record lacks `{field}`");
    }
    assert_eq!(rec["nodes"], 48 * 48);
    assert_eq!(rec["bonds"], 48 * 48 * 28);
    let (ek, norm) = (
        rec["error_l2"].as_f64().unwrap(),
        rec["error_l2_norm"].as_f64().unwrap(),
    );
    assert!(
        (norm * norm - ek).abs() <= 1e-15 * ek,
        "error_l2 is e^k, the square of error_l2_norm"
    );
    // φ = sin(2πx₁) sin(2πx₂) is odd about x₁ = ½ on the cell-centred grid, and so is the whole
    // solution: the mass stays zero to round-off, and |û| ≤ |cos(2πT)| + error.
    assert!(
        rec["mass"].as_f64().unwrap().abs() < 1e-14,
        "mass {}",
        rec["mass"]
    );
    let amplitude = (2.0 * std::f64::consts::PI * 0.02f64).cos();
    let max_abs = rec["max_abs"].as_f64().unwrap();
    assert!(
        (max_abs - amplitude).abs() <= rec["error_max"].as_f64().unwrap() + 1e-3,
        "max |û| = {max_abs}"
    );
    for field in ["solver_version", "host", "cpu", "threads", "timestamp"] {
        assert!(
            rec["provenance"].get(field).is_some(),
            "provenance lacks `{field}`"
        );
    }
    let summary = String::from_utf8_lossy(&out.stderr);
    assert!(
        summary.contains("steps") && summary.contains("status ok"),
        "{summary}"
    );
}

#[test]
fn case_file_and_flags_agree_and_flags_override() {
    let case = r#"{"dim": 2, "n": 48, "m": 3, "kernel": "linear", "t_end": 0.02, "cfl": 0.5, "threads": 1}"#;
    let from_file = record(&nlsolve(&["run", "--case", "-"], Some(case)));
    let from_flags = record(&nlsolve(BASE, None));
    assert_eq!(result_numbers(&from_file), result_numbers(&from_flags));
    let overridden = record(&nlsolve(&["run", "--case", "-", "--n", "24"], Some(case)));
    assert_eq!(overridden["nodes"], 24 * 24);
}

#[test]
fn one_two_and_three_threads_give_bitwise_identical_numbers() {
    for backend in ["stencil", "neighbour_list"] {
        let records: Vec<Value> = ["1", "2", "3"]
            .iter()
            .map(|threads| {
                let mut args = BASE.to_vec();
                args.extend(["--threads", threads, "--backend", backend, "--error-total"]);
                record(&nlsolve(&args, None))
            })
            .collect();
        // serde_json prints the shortest string that round-trips, so equal text is equal bits.
        for r in &records[1..] {
            assert_eq!(result_numbers(r), result_numbers(&records[0]), "{backend}");
        }
        assert!(records[0]["error_total"].as_f64().unwrap() > 0.0);
    }
}

/// Runs a bad case and checks exit code 2, no record, and a message naming the field.
fn assert_refused(args: &[&str], stdin: Option<&str>, field: &str) {
    let out = nlsolve(args, stdin);
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {message}");
    assert!(out.stdout.is_empty(), "no record for bad input");
    assert!(
        message.contains(field),
        "message must name `{field}`: {message}"
    );
    assert!(!message.contains("panicked"), "{message}");
    assert_eq!(message.trim().lines().count(), 1, "one sentence: {message}");
}

#[test]
fn bad_input_exits_2_naming_the_field() {
    let by_file = [
        (
            r#"{"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "colour": 3}"#,
            "colour",
        ),
        (
            r#"{"dim": 2, "n": 0, "m": 2, "t_end": 0.01, "cfl": 0.5}"#,
            "`n`",
        ),
        (
            r#"{"dim": 2, "n": -4, "m": 2, "t_end": 0.01, "cfl": 0.5}"#,
            "`n`",
        ),
        (
            r#"{"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "kernel": "cubic"}"#,
            "kernel",
        ),
        (r#"{"n": 16, "m": 2, "t_end": 0.1, "cfl": 0.5}"#, "dim"),
        ("{not json", "not valid JSON"),
        (
            r#"{"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "dim": 1}"#,
            "the key `dim` is given twice",
        ),
        (
            r#"{"method": "pse", "problem": "eigenmode", "dim": 1, "n": 8, "m": 2, "t_end": 0.01, "cfl": 0.5, "length": -2}"#,
            "`length`",
        ),
        (
            r#"{"dim": 2, "n": 8, "eps": 1e-300, "t_end": 0.01, "cfl": 0.5}"#,
            "ε = 1e-300 is below h",
        ),
        (
            r#"{"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "threads": 5000}"#,
            "`threads`: must lie in 1 ..= 1024",
        ),
        // Over 4 threads per core on any machine of fewer than 250 cores: refused by `run`.
        (
            r#"{"dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "threads": 1000}"#,
            "at most 4 per core",
        ),
        // 3.6·10⁹ nodes: more than 100 GiB of fields, refused before any is allocated.
        (
            r#"{"dim": 2, "n": 60000, "m": 2, "t_end": 0.01, "cfl": 0.5}"#,
            "`n`: the run needs at least",
        ),
    ];
    for (case, field) in by_file {
        assert_refused(&["run", "--case", "-"], Some(case), field);
    }
    let by_flags = [
        ("--dim 2 --n 16 --m 0 --t-end 0.1 --cfl 0.5", "`m`"),
        ("--dim 1 --n 16 --eps 0.6 --t-end 0.1 --cfl 0.5", "`eps`"),
        ("--dim 1 --n 16 --m 9 --t-end 0.1 --cfl 0.5", "`m`"),
        ("--dim 1 --n 16 --m 2 --t-end -0.1 --cfl 0.5", "`t_end`"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --dt 1", "`dt`"),
        ("--dim 3 --n 16 --m 2 --t-end 0.1 --cfl 0.5", "`dim`"),
        ("--dim 1 --n 16 --t-end 0.1 --cfl 0.5", "`m`"),
        ("--dim 1 --n 16 --eps 0.01 --t-end 0.1 --cfl 0.5", "`eps`"),
        ("--dim 1 --n 16 --m 2 --t-end 1e9 --cfl 0.5", "`t_end`"),
        ("--dim 1 --n 16 --m 2 --cfl 0.5", "`t_end`"),
        ("--method feti --dim 2 --n 32 --m 4", "`subdomains`"),
        ("--method feti --dim 2 --n 32 --m 4 --subdomains 8", "`subdomains`"),
        ("--method feti --dim 2 --n 32 --m 4 --subdomains 2 --ranks 5", "`ranks`"),
        ("--method steady_cg --dim 2 --n 32 --m 4 --t-end 1", "`t_end`"),
        ("--method steady_cg --dim 2 --n 32 --m 4 --subdomains 2", "`subdomains`"),
        ("--method steady_cg --dim 1 --n 32 --m 4", "`dim`"),
        ("--method steady_cg --dim 2 --n 32 --m 4 --kernel linear", "`kernel`"),
        ("--method steady_cg --dim 2 --n 32 --m 4 --rtol 2", "`rtol`"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --rtol 1e-6", "`rtol`"),
        ("--method steady_cg --dim 2 --n 32 --m 4 --max-iterations 0", "`max_iterations`"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --max-iterations 9", "`max_iterations`"),
        ("--n abc", "--n"),
        ("--colour 3", "--colour"),
        ("--case /nonexistent/case.json", "--case"),
        (
            "--dim 1 --n 4 --m 1 --t-end 0.1 --cfl 0.5 --ranks 5",
            "`ranks`",
        ),
        (
            "--dim 1 --n 16 --m 1 --t-end 0.1 --cfl 0.5 --ranks 2",
            "`ranks`",
        ),
        (
            "--dim 2 --n 16 --m 1 --t-end 0.1 --cfl 0.5 --partition graph --px 2",
            "`px`",
        ),
        (
            "--dim 2 --n 16 --m 1 --t-end 0.1 --cfl 0.5 --partition metis",
            "partition",
        ),
        (
            "--dim 2 --n 16 --m 1 --t-end 0.1 --cfl 0.5 --ranks 2 --backend neighbour_list",
            "`backend`",
        ),
        (
            "--method pse --problem square --dim 2 --n 16 --t-end 0.1 --cfl 0.5",
            "`eps`",
        ),
        (
            "--method adi --problem square --dim 1 --n 16 --t-end 0.1 --cfl 0.5 --write-diagnostics /tmp/never.csv",
            "`diagnostics_every`",
        ),
        (
            "--method adi --problem square --dim 1 --n 16 --t-end 0.1 --cfl 0.5 --histogram-bins 0",
            "`histogram_bins`",
        ),
        (
            "--dim 2 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --field-snapshot 1000",
            "`field_snapshot`",
        ),
        (
            "--dim 2 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --vtk-every 0",
            "`vtk_every`",
        ),
        (
            "--dim 2 --n 4096 --m 2 --t-end 1 --cfl 0.5 --vtk-every 0.001",
            "`vtk_every`",
        ),
        (
            "--dim 2 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --ranks 2 --field-snapshot 8",
            "`field_snapshot`",
        ),
        (
            r#"--dim 1 --n 200 --t-end 0.1 --cfl 10 --integrator crank_nicolson --source local --formulation x_centred --krylov cg --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#,
            "`krylov`",
        ),
        ("--method patch_test --dim 1 --n 64 --eps 0.1 --t-end 1", "`t_end`"),
        ("--method patch_test --dim 1 --n 64", "`eps`"),
        ("--method patch_test --dim 1 --n 40 --eps 0.025 --kernel linear", "`eps`"),
        (
            r#"--method patch_test --dim 1 --n 64 --horizon-profile {"kind":"transition","left":0.1,"right":0.05,"start":0.7,"end":0.3}"#,
            "`horizon_profile`",
        ),
        (
            r#"--method patch_test --dim 1 --n 64 --horizon-profile {"kind":"linear","left":0.6,"right":0.1}"#,
            "`horizon_profile`",
        ),
        (
            r#"--method patch_test --dim 1 --n 64 --eps 0.1 --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#,
            "`eps`",
        ),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --formulation partial_stress", "`formulation`"),
        (r#"--dim 2 --n 32 --t-end 0.1 --cfl 0.5 --source local --ranks 2 --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`ranks`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source local --ranks 2 --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`ranks`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source local --backend fft --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`backend`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source local --collar exact --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`collar`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source continuum --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`source`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source local --m 2 --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`m`"),
        (r#"--dim 1 --n 64 --t-end 0.1 --cfl 0.5 --source local --formulation partial_stress --horizon-profile {"kind":"linear","left":0.1,"right":0.05}"#, "`formulation`"),
        ("--method patch_test --dim 1 --n 64 --eps 0.1 --patch quartic", "`patch`"),
        ("--method coupled_1d --dim 2 --n 16 --eps 0.065", "`dim`"),
        ("--method coupled_1d --dim 1 --n 16", "`eps`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0", "`eps`"),
        ("--method coupled_1d --dim 1 --n 32 --eps 1e-9", "`eps`"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --diffusivity nan", "--diffusivity"),
        ("--dim 1 --n 16 --m 2 --t-end NaN --cfl 0.5", "not a finite number"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --rtol=-inf", "--rtol"),
        ("--method coupled_1d --dim 1 --n 1 --eps 0.065", "`n`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --local-domain 1.2,2", "`local_domain`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --local-domain -0.1,1.75", "`local_domain`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --local-domain 0.75,1.03", "`local_domain`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --local-domain 0.75,1e12", "`local_domain`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --t-end 1", "`t_end`"),
        ("--method coupled_1d --dim 1 --n 16 --eps 0.065 --ranks 2", "`ranks`"),
        ("--dim 1 --n 16 --m 2 --t-end 0.1 --cfl 0.5 --local-domain 0.75,1.75", "`local_domain`"),
    ];
    for (flags, field) in by_flags {
        let mut args = vec!["run"];
        args.extend(flags.split_whitespace());
        assert_refused(&args, None, field);
    }
}

#[test]
fn help_and_the_guide_document_every_case_field() {
    let out = nlsolve(&["--help"], None);
    let help = String::from_utf8_lossy(&out.stdout);
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/guide/solver.md"))
            .unwrap();
    let fields = Case::field_names();
    assert!(fields.len() > 30, "{fields:?}");
    for field in fields {
        let flag = format!("--{}", field.replace('_', "-"));
        let named = help.match_indices(&flag).any(|(at, _)| {
            !help[at + flag.len()..].starts_with(|c: char| c.is_alphanumeric() || c == '-')
        });
        assert!(named, "nlsolve --help lacks {flag}");
        assert!(
            readme.contains(&format!("| `{field}` |"))
                || readme.contains(&format!("`{field}`, `"))
                || readme.contains(&format!(", `{field}` |")),
            "docs/guide/solver.md's table of case fields lacks `{field}`"
        );
    }
    for flag in ["--case", "--write-field", "--write-diagnostics"] {
        assert!(help.contains(flag), "help lacks {flag}");
    }
    // Every method the solver accepts (serde lists them when refusing an unknown one) is named
    // in the help of `--method`.
    let refusal = nlsolve(
        &["check"],
        Some("{\"method\": \"no_such_method\", \"dim\": 1, \"n\": 8}\n"),
    );
    let refusal = String::from_utf8_lossy(&refusal.stdout).to_string();
    let accepted = refusal
        .split("expected one of ")
        .nth(1)
        .and_then(|list| list.split(';').next())
        .unwrap_or_else(|| panic!("no list of methods in {refusal}"));
    let methods: Vec<&str> = accepted.split('`').skip(1).step_by(2).collect();
    assert!(methods.len() >= 6, "{refusal}");
    for method in methods {
        assert!(help.contains(method), "help of --method lacks {method}");
    }
}

#[test]
fn an_oracle_too_large_for_memory_is_refused_before_allocating() {
    // 2D n = 20000, m = 8: 4·10⁸ nodes × 196 bonds × 4 bytes ≈ 290 GiB of neighbour lists.
    let args = [
        "run",
        "--dim",
        "2",
        "--n",
        "20000",
        "--m",
        "8",
        "--t-end",
        "0.1",
        "--cfl",
        "0.5",
        "--backend",
        "neighbour_list",
    ];
    assert_refused(&args, None, "backend");
}

#[test]
fn the_partition_report_refuses_a_block_shape_that_does_not_multiply_to_the_ranks() {
    let partition = |px: &str| -> Vec<String> {
        format!("partition --dim 2 --n 16 --m 2 --ranks 4 --px {px}")
            .split_whitespace()
            .map(String::from)
            .collect()
    };
    let args = partition("3");
    assert_refused(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        None,
        "`px`",
    );
    let args = partition("4");
    let out = nlsolve(&args.iter().map(String::as_str).collect::<Vec<_>>(), None);
    let report = record(&out);
    assert_eq!(
        (report["px"].as_u64(), report["py"].as_u64()),
        (Some(4), Some(1))
    );
}

/// `--write-diagnostics` writes the record's c_tot(t) series as CSV under a `t,c_tot` header.
#[test]
fn the_diagnostics_file_is_the_records_series_as_csv() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    let path = dir.join("diagnostics.csv");
    let out = nlsolve(
        &[
            "run",
            "--method",
            "fd_explicit",
            "--problem",
            "square",
            "--dim",
            "2",
            "--n",
            "40",
            "--t-end",
            "0.1",
            "--cfl",
            "0.9",
            "--diagnostics-every",
            "0.02",
            "--write-diagnostics",
            path.to_str().expect("utf-8 path"),
        ],
        None,
    );
    let record = record(&out);
    let csv = std::fs::read_to_string(&path).expect("the diagnostics file is written");
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("t,c_tot"));
    let rows: Vec<(f64, f64)> = lines
        .map(|line| {
            let (t, c) = line.split_once(',').expect("two columns");
            (t.parse().expect("t"), c.parse().expect("c_tot"))
        })
        .collect();
    let series = &record["c_tot"];
    let column = |name: &str| -> Vec<f64> {
        series[name]
            .as_array()
            .expect("array")
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    assert_eq!(rows.len(), 6, "t = 0, 0.02, …, 0.1");
    assert_eq!(rows.iter().map(|r| r.0).collect::<Vec<_>>(), column("time"));
    assert_eq!(
        rows.iter().map(|r| r.1).collect::<Vec<_>>(),
        column("c_tot")
    );
}

/// The h the solver reports is the h `nlstudy` gives study expressions (`schema`'s
/// `Method::grid_spacing`), for every method; and every column a record gives the tables is one
/// the schema lists (`nlstudy plan` checks figures against that list before anything runs).
#[test]
fn every_method_reports_the_grid_spacing_and_the_columns_of_the_schema() {
    let cases = [
        r#"{"method": "nonlocal", "dim": 1, "n": 24, "m": 2, "t_end": 0.001, "cfl": 0.5}"#,
        r#"{"method": "nonlocal", "dim": 2, "n": 16, "m": 2, "t_end": 0.001, "cfl": 0.5, "integrator": "crank_nicolson", "diagnostics_every": 0.0005, "histogram_bins": 4, "field_snapshot": 4, "error_total": true}"#,
        r#"{"method": "patch_test", "dim": 1, "n": 24, "patch": "quadratic", "horizon_profile": {"kind": "linear", "left": 0.05, "right": 0.1}}"#,
        r#"{"method": "fd_explicit", "problem": "eigenmode", "dim": 1, "n": 24, "length": 3, "t_end": 0.001, "cfl": 0.5}"#,
        r#"{"method": "adi", "problem": "square", "dim": 2, "n": 24, "t_end": 0.001, "dt": 0.0005}"#,
        r#"{"method": "pse", "problem": "eigenmode", "dim": 1, "n": 24, "m": 4, "length": 3, "t_end": 0.001, "cfl": 0.5}"#,
        r#"{"method": "steady_cg", "dim": 2, "n": 16, "m": 2}"#,
        r#"{"method": "feti", "dim": 2, "n": 16, "m": 2, "subdomains": 2}"#,
        r#"{"method": "patch_test", "dim": 1, "n": 24, "eps": 0.1}"#,
        r#"{"method": "coupled_1d", "dim": 1, "n": 24, "eps": 0.065}"#,
    ];
    for case in cases {
        let out = nlsolve(&["run", "--case", "-"], Some(case));
        assert!(
            out.status.success(),
            "{case}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let rec = record(&out);
        let parsed = Case::parse(rec["case"].clone()).unwrap();
        assert_eq!(rec["h"].as_f64(), Some(parsed.h()), "{case}");
        for column in schema::record::columns::flattened_names(&rec) {
            assert!(
                schema::record::is_column(&column),
                "{case}: the record's column `{column}` is not a column of schema::record"
            );
        }
    }
}

/// `nlsolve machine` and the `needs` of `nlsolve check` are all `check`'s sentence on
/// whether a case fits this machine depends on: a case within `most_threads` and
/// `available_bytes` has none, one beyond either has one (a plan that keeps verdicts decides on
/// these numbers whether a kept verdict still stands).
#[test]
fn check_says_a_case_does_not_fit_exactly_where_its_needs_exceed_the_machine() {
    let machine: Value = serde_json::from_slice(&nlsolve(&["machine"], None).stdout).unwrap();
    let cores = machine["cores"].as_u64().unwrap();
    let most = machine["most_threads"].as_u64().unwrap();
    let available = machine["available_bytes"].as_u64().unwrap();
    assert!(cores >= 1 && most >= cores && available > 0, "{machine}");
    let case = |dim: u64, n: u64, threads: u64| {
        json!({"dim": dim, "n": n, "m": 2, "t_end": 1e-9, "cfl": 0.5, "threads": threads})
            .to_string()
    };
    let cases = [
        case(1, 16, most),
        case(1, 16, most + 1),
        case(2, 4096, 1),
        // 10¹⁰ nodes of a few fields: more than any machine this runs on has.
        case(2, 100_000, 1),
    ]
    .join("\n");
    let out = nlsolve(&["check"], Some(&cases));
    let verdicts: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    assert_eq!(verdicts.len(), 4);
    for verdict in &verdicts {
        let threads = verdict["resolved"]["threads"].as_u64().unwrap();
        let needs = verdict["needs"]["bytes"].as_u64().unwrap();
        let fits = threads <= most && needs <= available;
        assert_eq!(
            verdict.get("machine").is_none(),
            fits,
            "{verdict} on {machine}"
        );
    }
    let said = |k: usize| {
        verdicts[k]["machine"]
            .as_str()
            .unwrap_or_default()
            .to_string()
    };
    assert!(
        said(1).contains("`threads`") && said(3).contains("`n`"),
        "{verdicts:?}"
    );
    assert!(verdicts[3]["needs"]["bytes"].as_u64().unwrap() > available);
}
