use super::*;

/// The 1D Laplacian tridiag(−1, 2, −1) on n nodes.
fn laplacian(n: usize) -> impl Fn(&[f64], &mut [f64]) + Copy {
    move |p, ap| {
        for i in 0..n {
            let left = if i > 0 { p[i - 1] } else { 0.0 };
            let right = if i + 1 < n { p[i + 1] } else { 0.0 };
            ap[i] = 2.0 * p[i] - left - right;
        }
    }
}

/// A Jacobi-like preconditioner that is not the identity: z = r / (2 + i/n).
fn scaled(n: usize) -> impl Fn(&[f64], &mut [f64]) + Copy {
    move |r, z| {
        for (i, (z, r)) in z.iter_mut().zip(r).enumerate() {
            *z = r / (2.0 + i as f64 / n as f64);
        }
    }
}

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

fn params(start: Start, rtol: f64, norm: Norm, max_iterations: usize) -> CgParams {
    CgParams {
        start,
        rtol,
        norm,
        max_iterations,
        pool: None,
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The literal loops the solvers ran before they shared one CG: unpreconditioned from zero,
/// preconditioned from a guess, and FETI's projected CG (its projection left out: it is
/// part of A and M). The shared CG must give their bits.
mod literal {
    use super::super::{axpy, xpby};

    pub fn plain(
        a: impl Fn(&[f64], &mut [f64]),
        dot: impl Fn(&[f64], &[f64]) -> f64,
        b: &[f64],
        x: &mut [f64],
        rtol: f64,
        max: usize,
    ) -> (usize, f64) {
        let mut r = b.to_vec();
        let mut p = b.to_vec();
        let mut ap = vec![0.0; b.len()];
        let b_norm = dot(b, b).sqrt();
        let mut rr = b_norm * b_norm;
        if b_norm == 0.0 {
            return (0, 0.0);
        }
        for k in 1..=max {
            a(&p, &mut ap);
            let alpha = rr / dot(&p, &ap);
            axpy(alpha, &p, x);
            axpy(-alpha, &ap, &mut r);
            let rr_next = dot(&r, &r);
            let rel = rr_next.sqrt() / b_norm;
            if rel <= rtol || k == max || !rel.is_finite() {
                return (k, rel);
            }
            xpby(&r, rr_next / rr, &mut p);
            rr = rr_next;
        }
        (0, 1.0)
    }

    pub fn preconditioned(
        a: impl Fn(&[f64], &mut [f64]),
        m: impl Fn(&[f64], &mut [f64]),
        dot: impl Fn(&[f64], &[f64]) -> f64,
        b: &[f64],
        x: &mut [f64],
        rtol: f64,
        max: usize,
    ) -> (usize, f64) {
        let n = b.len();
        let (mut r, mut z, mut p, mut ap) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        a(x, &mut ap);
        r.copy_from_slice(b);
        axpy(-1.0, &ap, &mut r);
        let b_norm = dot(b, b).sqrt();
        let residual = |rr: f64| {
            if b_norm > 0.0 {
                rr.sqrt() / b_norm
            } else {
                0.0
            }
        };
        let mut rel = residual(dot(&r, &r));
        if rel <= rtol {
            return (0, rel);
        }
        m(&r, &mut z);
        p.copy_from_slice(&z);
        let mut rz = dot(&r, &z);
        for k in 1..=max {
            a(&p, &mut ap);
            let alpha = rz / dot(&p, &ap);
            axpy(alpha, &p, x);
            axpy(-alpha, &ap, &mut r);
            rel = residual(dot(&r, &r));
            if rel <= rtol || k == max || !rel.is_finite() {
                return (k, rel);
            }
            m(&r, &mut z);
            let rz_next = dot(&r, &z);
            xpby(&z, rz_next / rz, &mut p);
            rz = rz_next;
        }
        (max, rel)
    }

    pub fn projected(
        a: impl Fn(&[f64], &mut [f64]),
        m: impl Fn(&[f64], &mut [f64]),
        dot: impl Fn(&[f64], &[f64]) -> f64,
        r0: &[f64],
        lambda: &mut [f64],
        rtol: f64,
        max: usize,
    ) -> (usize, f64) {
        let len = r0.len();
        let mut r = r0.to_vec();
        let mut x = vec![0.0; len];
        let mut y = vec![0.0; len];
        m(&r, &mut y);
        let mut p = y.clone();
        let mut alpha = dot(&r, &y);
        let alpha0 = alpha;
        let mut dual = if alpha0 > 0.0 { 1.0 } else { 0.0 };
        let mut iterations = 0;
        while dual > rtol && iterations < max {
            iterations += 1;
            a(&p, &mut x);
            let step = alpha / dot(&p, &x);
            for i in 0..len {
                lambda[i] += step * p[i];
                r[i] -= step * x[i];
            }
            m(&r, &mut y);
            let alpha_next = dot(&r, &y);
            dual = (alpha_next.max(0.0) / alpha0).sqrt();
            if !dual.is_finite() {
                break;
            }
            let ratio = alpha_next / alpha;
            for i in 0..len {
                p[i] = y[i] + ratio * p[i];
            }
            alpha = alpha_next;
        }
        (iterations, dual)
    }
}

/// The 1D Laplacian's system for a smooth x: (b = A x, a guess, the guess's residual b − A guess).
fn system_with_a_guess(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let a = laplacian(n);
    let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    let mut b = vec![0.0; n];
    a(&exact, &mut b);
    let guess: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64).cos()).collect();
    let mut ax = vec![0.0; n];
    a(&guess, &mut ax);
    let r0 = b.iter().zip(&ax).map(|(b, ax)| b - ax).collect();
    (b, guess, r0)
}

#[test]
fn every_start_and_norm_gives_the_bits_of_the_loop_it_replaced() {
    let n = 64;
    let (a, m) = (laplacian(n), scaled(n));
    let (b, guess, r0) = system_with_a_guess(n);
    let mut cg = Cg::new(n);
    for (rtol, max) in [(1e-10, 1000), (0.0, 5), (1e-3, 1000), (1e-10, 0)] {
        // Unpreconditioned from zero: the steady solvers and FETI's interior solves.
        let mut x = vec![1.0; n];
        let got = cg.solve(
            &mut Closures {
                len: n,
                apply: a,
                precondition: NoPreconditioner,
                dot,
            },
            &b,
            &mut x,
            &params(Start::Zero, rtol, Norm::Residual, max),
        );
        let mut reference = vec![0.0; n];
        let (k, rel) = literal::plain(a, dot, &b, &mut reference, rtol, max);
        assert_eq!(
            (got.iterations, got.relative_residual.to_bits()),
            (k, rel.to_bits()),
            "plain {rtol} {max}"
        );
        assert_eq!(bits(&x), bits(&reference), "plain {rtol} {max}");
        // Preconditioned from a guess: the θ-steps.
        let mut x = guess.clone();
        let system = &mut Closures {
            len: n,
            apply: a,
            precondition: m,
            dot,
        };
        let got = cg.solve(
            system,
            &b,
            &mut x,
            &params(Start::Guess, rtol, Norm::Residual, max),
        );
        let mut reference = guess.clone();
        let (k, rel) = literal::preconditioned(a, m, dot, &b, &mut reference, rtol, max);
        assert_eq!(
            (got.iterations, got.relative_residual.to_bits()),
            (k, rel.to_bits()),
            "pcg {rtol} {max}"
        );
        assert_eq!(bits(&x), bits(&reference), "pcg {rtol} {max}");
        // FETI's: the caller's residual, the preconditioned norm.
        let mut x = guess.clone();
        let got = cg.solve(
            system,
            &b,
            &mut x,
            &params(Start::Residual(&r0), rtol, Norm::Preconditioned, max),
        );
        let mut reference = guess.clone();
        let (k, rel) = literal::projected(a, m, dot, &r0, &mut reference, rtol, max);
        assert_eq!(
            (got.iterations, got.relative_residual.to_bits()),
            (k, rel.to_bits()),
            "feti {rtol} {max}"
        );
        assert_eq!(bits(&x), bits(&reference), "feti {rtol} {max}");
    }
}

/// The 1D Laplacian: CG converges in at most n iterations, and says so.
#[test]
fn solves_a_tridiagonal_system_in_at_most_n_iterations() {
    let n = 50;
    let apply = laplacian(n);
    let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    let mut b = vec![0.0; n];
    apply(&exact, &mut b);
    let mut x = vec![0.0; n];
    let system = &mut Closures {
        len: n,
        apply,
        precondition: NoPreconditioner,
        dot,
    };
    let convergence = Cg::new(n).solve(
        system,
        &b,
        &mut x,
        &params(Start::Zero, 1e-12, Norm::Residual, 1000),
    );
    assert!(
        convergence.converged && convergence.iterations <= n,
        "{convergence:?}"
    );
    let error = max_difference(&x, &exact);
    assert!(error < 1e-9, "error {error}");
    let capped = Cg::new(n).solve(
        system,
        &b,
        &mut x,
        &params(Start::Zero, 1e-12, Norm::Residual, 3),
    );
    assert_eq!(
        (capped.iterations, capped.converged),
        (3, false),
        "{capped:?}"
    );
}

/// PCG with M = A⁻¹ (the 1D Laplacian's inverse in closed form) converges in one
/// iteration, and a warm start at the solution needs none.
#[test]
fn pcg_with_the_exact_inverse_takes_one_iteration_and_a_solved_start_none() {
    let n = 40;
    let apply = laplacian(n);
    // A⁻¹ of tridiag(−1, 2, −1) is min(i+1, j+1)·(n − max(i, j))/(n + 1).
    let inverse = |r: &[f64], z: &mut [f64]| {
        for (i, zi) in z.iter_mut().enumerate() {
            *zi = (0..n)
                .map(|j| (i.min(j) + 1) as f64 * (n - i.max(j)) as f64 / (n + 1) as f64 * r[j])
                .sum();
        }
    };
    let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    let mut b = vec![0.0; n];
    apply(&exact, &mut b);
    let mut cg = Cg::new(n);
    let mut x = vec![0.0; n];
    let system = &mut Closures {
        len: n,
        apply,
        precondition: inverse,
        dot,
    };
    let guess = params(Start::Guess, 1e-12, Norm::Residual, 100);
    let first = cg.solve(system, &b, &mut x, &guess);
    assert_eq!(first.iterations, 1, "{first:?}");
    let again = cg.solve(system, &b, &mut x, &guess);
    assert_eq!(again.iterations, 0, "{again:?}");
    let error = max_difference(&x, &exact);
    assert!(error < 1e-12, "error {error}");
}

#[test]
#[should_panic(expected = "CG on a system of 8 unknowns was given b of 7")]
fn vectors_of_another_length_are_refused_with_a_message() {
    let system = &mut Closures {
        precondition: NoPreconditioner,
        len: 8,
        apply: laplacian(8),
        dot,
    };
    let mut x = vec![0.0; 8];
    Cg::new(8).solve(
        system,
        &[1.0; 7],
        &mut x,
        &params(Start::Zero, 1e-8, Norm::Residual, 10),
    );
}

#[test]
fn dot_does_not_depend_on_the_thread_count() {
    let a: Vec<f64> = (0..100_003).map(|i| (i as f64).sin()).collect();
    let b: Vec<f64> = (0..100_003).map(|i| (i as f64 * 0.7).cos()).collect();
    let on = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| dot(&a, &b))
    };
    assert_eq!(on(1).to_bits(), on(3).to_bits());
    let plain: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    assert!((on(2) - plain).abs() < 1e-9 * plain.abs().max(1.0));
}

/// Keeps the state after iteration `at` and, given one, resumes from it.
struct KeepAt {
    at: usize,
    kept: Option<State<Vec<f64>>>,
    resume: Option<State<Vec<f64>>>,
}

impl Checkpoints for KeepAt {
    fn resume(&mut self, len: usize) -> Option<State<Vec<f64>>> {
        self.resume.take().filter(|s| s.x.len() == len)
    }

    fn after_iteration(&mut self, state: State<&[f64]>) {
        if state.iteration == self.at {
            self.kept = Some(State {
                iteration: state.iteration,
                x: state.x.to_vec(),
                r: state.r.to_vec(),
                p: state.p.to_vec(),
                rz: state.rz,
                reference: state.reference,
                relative_residual: state.relative_residual,
            });
        }
    }
}

/// A solve resumed from its state after iteration k, into an x holding anything, ends with the
/// bits and the convergence of the solve never stopped: for each start and norm, with and
/// without a preconditioner.
#[test]
fn a_solve_resumed_after_any_iteration_has_the_bits_of_one_never_stopped() {
    let n = 64;
    let (a, m) = (laplacian(n), scaled(n));
    let (b, guess, r0) = system_with_a_guess(n);
    let starts = [
        (Start::Zero, Norm::Residual),
        (Start::Guess, Norm::Residual),
        (Start::Residual(&r0), Norm::Preconditioned),
    ];
    let mut cg = Cg::new(n);
    for (start, norm) in starts {
        for preconditioned in [false, true] {
            let solve = |cg: &mut Cg, x: &mut [f64], checkpoints: &mut dyn Checkpoints| {
                let params = params(start, 1e-12, norm, 1000);
                if preconditioned {
                    let system = &mut Closures {
                        len: n,
                        apply: a,
                        precondition: m,
                        dot,
                    };
                    cg.solve_checkpointed(system, &b, x, &params, checkpoints)
                } else {
                    let system = &mut Closures {
                        len: n,
                        apply: a,
                        precondition: NoPreconditioner,
                        dot,
                    };
                    cg.solve_checkpointed(system, &b, x, &params, checkpoints)
                }
            };
            let mut whole = guess.clone();
            let never_stopped = solve(&mut cg, &mut whole, &mut NoCheckpoints);
            assert!(
                never_stopped.converged && never_stopped.iterations > 10,
                "{start:?} {norm:?} {preconditioned}: {never_stopped:?}"
            );
            for at in [
                1,
                never_stopped.iterations / 2,
                never_stopped.iterations - 1,
            ] {
                let what = format!("{start:?} {norm:?} preconditioned {preconditioned} at {at}");
                let mut keep = KeepAt {
                    at,
                    kept: None,
                    resume: None,
                };
                let mut x = guess.clone();
                solve(&mut cg, &mut x, &mut keep);
                let kept = keep
                    .kept
                    .take()
                    .unwrap_or_else(|| panic!("{what}: not kept"));
                let mut resumed = vec![f64::NAN; n];
                let mut from = KeepAt {
                    at: usize::MAX,
                    kept: None,
                    resume: Some(kept),
                };
                let convergence = solve(&mut cg, &mut resumed, &mut from);
                assert_eq!(convergence, never_stopped, "{what}");
                assert_eq!(bits(&resumed), bits(&whole), "{what}");
            }
        }
    }
}
