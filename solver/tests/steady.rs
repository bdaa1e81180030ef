//! The steady problem of \[XGDF]: the assembled system against the stencil, its quadratic
//! exactness, CG and FETI against the single-domain direct solve, and how iteration counts scale.

mod common;

use common::{case, observed_orders, random_field, scientific};
use serde_json::json;
use solver::case::Backend;
use solver::linalg::cholesky::{symmetric_product, Cholesky};
use solver::methods::steady::assembly::single_domain;
use solver::methods::steady::problem::SteadyProblem;
use solver::operator::{self, LinearOperator};

/// A steady case on the L × L lattice.
fn steady(
    method: &str,
    n: usize,
    m: usize,
    quadrature: &str,
    extra: serde_json::Value,
) -> solver::case::Case {
    let mut fields = json!({
        "method": method, "dim": 2, "n": n, "m": m,
        "kernel": "inverse_distance", "quadrature": quadrature,
    });
    fields
        .as_object_mut()
        .unwrap()
        .extend(extra.as_object().unwrap().clone());
    case(fields)
}

/// The single-domain system solved by sparse Cholesky.
fn direct_solution(problem: &SteadyProblem) -> Vec<f64> {
    let (a, mut u) = single_domain(problem);
    Cholesky::new(a.as_ref()).unwrap().solve_in_place(&mut u);
    u
}

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0, |m, v| m.max(v.abs()))
}

#[test]
fn the_assembled_matrix_is_minus_the_stencil_operator_and_the_load_matches() {
    for (n, m, quadrature) in [(24, 3, "midpoint"), (20, 4, "ac")] {
        let problem = SteadyProblem::new(&common::valid(steady(
            "steady_cg",
            n,
            m,
            quadrature,
            json!({}),
        )));
        let (a, load) = single_domain(&problem);
        let u = random_field(n * n, 7);
        let mut au = vec![0.0; n * n];
        symmetric_product(a.as_ref(), &u, &mut au);
        let mut lu = vec![0.0; n * n];
        operator::plan(Backend::Stencil, &problem.stencil).apply_once(&u, &mut lu);
        let scale = max_abs(&au);
        for i in 0..n * n {
            assert!(
                (au[i] + lu[i]).abs() <= 1e-13 * scale,
                "node {i}: A u = {}, −L_h u = {}",
                au[i],
                -lu[i]
            );
        }
        let loads = problem.loads();
        assert!(max_difference(&load, &loads) <= 1e-12 * max_abs(&loads));
        // A is symmetric: the matrix of eq. 19 is a Hessian.
        let v = random_field(n * n, 8);
        let mut av = vec![0.0; n * n];
        symmetric_product(a.as_ref(), &v, &mut av);
        let (vau, uav): (f64, f64) = (
            v.iter().zip(&au).map(|(x, y)| x * y).sum(),
            u.iter().zip(&av).map(|(x, y)| x * y).sum(),
        );
        assert!((vau - uav).abs() <= 1e-12 * vau.abs().max(1.0));
    }
}

/// Quadratic exactness: `ac` fits c to the lattice, and the direct solve reproduces u = |x|² to
/// round-off. The seed's midpoint rule with the continuum c is not exact: at fixed m its error
/// stays put as h → 0 (the lattice sum's relative error depends on m only), and at fixed δ it
/// falls like h (order ≈ 1, as the lattice sum converges).
#[test]
fn ac_reproduces_the_quadratic_and_midpoint_converges_only_at_fixed_horizon() {
    for (n, m) in [(16, 2), (32, 4), (48, 5)] {
        let problem =
            SteadyProblem::new(&common::valid(steady("steady_cg", n, m, "ac", json!({}))));
        let error = max_difference(&direct_solution(&problem), &problem.exact_values());
        assert!(error < 1e-11, "ac, n {n} m {m}: max error {error:e}");
        assert!(problem.patch_error().abs() < 1e-13);
    }
    let midpoint_error = |n: usize, m: usize| {
        let problem = SteadyProblem::new(&common::valid(steady(
            "steady_cg",
            n,
            m,
            "midpoint",
            json!({}),
        )));
        max_difference(&direct_solution(&problem), &problem.exact_values())
    };
    let fixed_m: Vec<f64> = [32, 64, 128]
        .iter()
        .map(|&n| midpoint_error(n, 4))
        .collect();
    let fixed_delta: Vec<f64> = [32, 64, 128]
        .iter()
        .map(|&n| midpoint_error(n, n / 16))
        .collect();
    println!(
        "midpoint max errors, m = 4, L = 32, 64, 128: {}",
        scientific(&fixed_m)
    );
    println!(
        "midpoint max errors, δ = 1/16, L = 32, 64, 128: {} (orders {:?})",
        scientific(&fixed_delta),
        observed_orders(&fixed_delta)
    );
    for w in fixed_m.windows(2) {
        assert!(w[1] > 0.85 * w[0] && w[0] > 0.05, "fixed m: {fixed_m:?}");
    }
    for order in observed_orders(&fixed_delta) {
        assert!(order > 0.7, "fixed δ: {fixed_delta:?}");
    }
}

#[test]
fn cg_converges_to_the_direct_solution_on_any_thread_count() {
    let base = steady("steady_cg", 48, 4, "midpoint", json!({"rtol": 1e-10}));
    let problem = SteadyProblem::new(&common::valid(base.clone()));
    let direct = direct_solution(&problem);
    let mut fields = Vec::new();
    for (threads, backend) in [(1, "stencil"), (2, "stencil"), (2, "fft")] {
        let mut case = base.clone();
        case.threads = threads;
        case.backend = serde_json::from_value(json!(backend)).unwrap();
        let outcome = solver::run(&case).unwrap();
        let difference = max_difference(&outcome.field, &direct) / max_abs(&direct);
        assert!(
            difference < 1e-8,
            "{threads} threads, {backend}: {difference:e}"
        );
        assert!(outcome.record.steady.relative_residual.unwrap() < 1e-10);
        fields.push(outcome.field);
    }
    assert_eq!(
        fields[0], fields[1],
        "the stencil CG depends on the thread count"
    );
}

/// FETI's reconstructed field equals the single-domain direct solve, for every preconditioner and
/// p = 2 (no floating subdomain), 3 and 4 (floating subdomains), with threads. The distributed
/// runs are checked against these one-process runs bit for bit in tests/distributed.rs.
#[test]
fn feti_reconstructs_the_single_domain_solution() {
    for (n, m, quadrature) in [(48, 4, "midpoint"), (45, 3, "ac")] {
        let problem = SteadyProblem::new(&common::valid(steady(
            "steady_cg",
            n,
            m,
            quadrature,
            json!({}),
        )));
        let direct = direct_solution(&problem);
        for p in [2, 3, 4] {
            for preconditioner in ["none", "dirichlet", "dirichlet_cg", "dirichlet_scaled"] {
                let feti = steady(
                    "feti",
                    n,
                    m,
                    quadrature,
                    json!({"subdomains": p, "preconditioner": preconditioner, "rtol": 1e-9, "threads": 2}),
                );
                let outcome = solver::run(&feti).unwrap();
                let difference = max_difference(&outcome.field, &direct) / max_abs(&direct);
                let solve = &outcome.record.steady;
                println!(
                    "n {n} m {m} p {p} {preconditioner}: {} iterations, {} multipliers, {} floating, relative difference {difference:.2e}",
                    solve.iterations.unwrap(),
                    solve.multipliers.unwrap(),
                    solve.floating_subdomains.unwrap()
                );
                assert!(difference < 1e-6, "p {p} {preconditioner}: {difference:e}");
                assert_eq!(solve.floating_subdomains, Some((p - 2) * (p - 2)));
                // The phase clocks cover the iterations and name only what ran.
                let phases = solve.feti_phases.as_ref().unwrap();
                let per_iteration = phases.subdomain_solves_s
                    + phases.preconditioner_s
                    + phases.interface_sum_s
                    + phases.coarse_s
                    + phases.other_s;
                let iterations = solve.iterations.unwrap() as f64;
                assert!(per_iteration * iterations <= outcome.record.solve_s);
                assert!(phases.subdomain_k_s > 0.0);
                assert_eq!(phases.subdomain_q_s == 0.0, preconditioner == "none");
                assert_eq!(
                    phases.coarse_s == 0.0,
                    p == 2,
                    "only p = 2 has no coarse space"
                );
            }
        }
    }
}

/// Weak scaling at m = 4 and L/p = 24 (p = 2, 3, 4, 8): CG's iterations grow like L/m (eq. 36)
/// while the Dirichlet-preconditioned FETI count levels off. Measured: p = 2 takes about half
/// the iterations of the rest (10 against 14–18): it has no floating subdomain, so no coarse
/// space and no cross points shared by four subdomains. From p = 3, the first p with floating
/// subdomains, on, the count varies by less than 50%; that is what is asserted, next to p = 2's,
/// for `dirichlet` (eq. 33) and `dirichlet_scaled` (5, 7, 9, 10).
#[test]
fn dirichlet_feti_iterations_level_off_while_cg_grows() {
    let mut feti_counts = Vec::new();
    let mut scaled_counts: Vec<usize> = Vec::new();
    let mut cg_counts = Vec::new();
    let ps = [2, 3, 4, 8];
    for p in ps {
        let n = 24 * p;
        let run = |case| {
            solver::run(&case)
                .unwrap()
                .record
                .steady
                .iterations
                .unwrap()
        };
        feti_counts.push(run(steady(
            "feti",
            n,
            4,
            "midpoint",
            json!({"subdomains": p, "threads": 2}),
        )));
        scaled_counts.push(run(steady(
            "feti",
            n,
            4,
            "midpoint",
            json!({"subdomains": p, "threads": 2, "preconditioner": "dirichlet_scaled"}),
        )));
        cg_counts.push(run(steady(
            "steady_cg",
            n,
            4,
            "midpoint",
            json!({"threads": 2}),
        )));
    }
    println!(
        "L/p = 24, m = 4, p = {ps:?}: FETI iterations, dirichlet {feti_counts:?}, \
         dirichlet_scaled {scaled_counts:?}; CG iterations {cg_counts:?}"
    );
    for counts in [&feti_counts, &scaled_counts] {
        let floating = &counts[1..];
        let (low, high) = (
            *floating.iter().min().unwrap() as f64,
            *floating.iter().max().unwrap() as f64,
        );
        assert!(
            high < 1.5 * low,
            "FETI iterations from p = 3 on vary by 50% or more: {counts:?}"
        );
        assert!(counts[0] as f64 >= 0.4 * low, "p = 2: {counts:?}");
    }
    assert!(
        cg_counts.windows(2).all(|w| w[1] > w[0]),
        "CG: {cg_counts:?}"
    );
    let (first, last) = (cg_counts[0] as f64, *cg_counts.last().unwrap() as f64);
    assert!(
        last > 3.0 * first,
        "CG should grow about like L (×4 here): {cg_counts:?}"
    );
}

/// A solve that hits `max_iterations` before `rtol` says so: status `diverged`, the residual in
/// the message, rather than `ok`; for CG and for FETI.
#[test]
fn a_solve_stopped_by_the_iteration_limit_is_not_ok() {
    for (method, limit, base) in [
        ("steady_cg", 5, json!({})),
        ("feti", 2, json!({"subdomains": 3})),
    ] {
        let mut limited = base.clone();
        limited["max_iterations"] = json!(limit);
        let stopped = solver::run(&steady(method, 48, 4, "ac", limited)).unwrap();
        let record = &stopped.record;
        assert_eq!(
            record.status,
            solver::output::record::Status::Diverged,
            "{method}"
        );
        assert_eq!(record.steady.iterations, Some(limit), "{method}");
        assert!(
            record.message.contains("above rtol"),
            "{method}: {}",
            record.message
        );
        let converged = solver::run(&steady(method, 48, 4, "ac", base)).unwrap();
        assert_eq!(
            converged.record.status,
            solver::output::record::Status::Ok,
            "{method}"
        );
    }
}
