//! Conjugate gradients, once for every solver: the steady problem's unpreconditioned CG from
//! zero (\[XGDF], section 4.1's baseline), the θ-steps' preconditioned CG from the previous
//! step, and FETI's projected CG on the interface (\[XGDF]'s Algorithm 1). A solve is a
//! `CgSystem` (A, optionally M ≈ A⁻¹, and the inner product, threaded on one process or summed
//! over ranks) and its `CgParams` (where x starts, the tolerance and its norm, the iteration cap).
//!
//! The vector updates and the inner product split the vectors at fixed boundaries, so the
//! iterates do not depend on the thread count.

use crate::threads::on;
use rayon::prelude::*;
use rayon::ThreadPool;

/// Length below which a vector operation runs on one thread; the split points of `dot`.
pub(crate) const CHUNK: usize = 8192;

/// What CG iterates with: A (symmetric positive definite on the space the iterates move in),
/// optionally a preconditioner M ≈ A⁻¹, and the inner product (a sum over ranks when the
/// vectors are distributed), over vectors of `len` entries.
pub trait CgSystem {
    /// The length of every vector of the system: a solve with any other length is refused.
    fn len(&self) -> usize;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// ap = A p.
    fn apply(&mut self, p: &[f64], ap: &mut [f64]);

    /// (a, b).
    fn dot(&mut self, a: &[f64], b: &[f64]) -> f64;

    /// Whether `precondition` applies a preconditioner; without one, z is r itself.
    fn preconditioned(&self) -> bool {
        false
    }

    /// z = M r (called only when `preconditioned`).
    fn precondition(&mut self, _r: &[f64], _z: &mut [f64]) {}
}

/// Where the iterates start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Start<'a> {
    /// x = 0 (x is cleared), so r = b.
    Zero,
    /// x as given; r = b − A x.
    Guess,
    /// x as given, with its residual computed by the caller (FETI projects it).
    Residual(&'a [f64]),
}

/// The norm of the stopping test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Norm {
    /// ‖r‖ / ‖b‖.
    Residual,
    /// √(rᵀz / r₀ᵀz₀), the preconditioned residual against the first one (FETI's, \[XGDF]:
    /// "until rᵀy is small enough").
    Preconditioned,
}

/// How one solve runs.
#[derive(Clone, Copy, Debug)]
pub struct CgParams<'a> {
    pub start: Start<'a>,
    /// Stop once the `norm` of the residual is at most `rtol`.
    pub rtol: f64,
    pub norm: Norm,
    /// Stop after this many iterations, converged or not.
    pub max_iterations: usize,
    /// Where the vector updates run (the current pool when None), so that MPI calls in `apply`
    /// and `dot` can stay on the calling thread.
    pub pool: Option<&'a ThreadPool>,
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convergence {
    pub iterations: usize,
    /// The residual in the solve's norm when it stopped.
    pub relative_residual: f64,
    /// `relative_residual <= rtol`: false when the iterations ran out or the residual stopped
    /// being a number.
    pub converged: bool,
}

/// The buffers of CG for vectors of one length, made once and reused by every solve (an
/// implicit integrator solves once per step).
pub struct Cg {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

impl Cg {
    pub fn new(len: usize) -> Self {
        Cg {
            r: vec![0.0; len],
            z: vec![0.0; len],
            p: vec![0.0; len],
            ap: vec![0.0; len],
        }
    }

    /// Solves A x = b from `params.start` until the residual's norm is at most `params.rtol`
    /// or `params.max_iterations` have run. Vectors whose length is not the system's are a
    /// caller's error, refused with a message rather than read short.
    pub fn solve(
        &mut self,
        system: &mut impl CgSystem,
        b: &[f64],
        x: &mut [f64],
        params: &CgParams,
    ) -> Convergence {
        let len = system.len();
        check_lengths("CG", len, b, x, self.r.len());
        let preconditioned = system.preconditioned();
        let Cg { r, z, p, ap } = self;
        let pool = params.pool;
        match params.start {
            Start::Zero => on(pool, || {
                x.fill(0.0);
                r.copy_from_slice(b);
            }),
            Start::Guess => {
                system.apply(x, ap);
                on(pool, || {
                    r.copy_from_slice(b);
                    axpy(-1.0, ap, r);
                });
            }
            Start::Residual(r0) => {
                assert_eq!(r0.len(), len, "the initial residual's length");
                on(pool, || r.copy_from_slice(r0));
            }
        }
        // The first residual in the solve's norm, ‖r₀‖² (what rᵀz is without a
        // preconditioner) and the norm's scale.
        let (mut relative_residual, r0r0, scale) = match params.norm {
            Norm::Residual => {
                let b_norm = system.dot(b, b).sqrt();
                let r_norm = match params.start {
                    Start::Zero => b_norm,
                    _ => system.dot(r, r).sqrt(),
                };
                let relative = if b_norm > 0.0 { r_norm / b_norm } else { 0.0 };
                (relative, r_norm * r_norm, b_norm)
            }
            Norm::Preconditioned => (f64::NAN, f64::NAN, f64::NAN),
        };
        let mut rz = if preconditioned {
            system.precondition(r, z);
            on(pool, || p.copy_from_slice(z));
            system.dot(r, z)
        } else {
            on(pool, || p.copy_from_slice(r));
            r0r0
        };
        let rz0 = rz;
        if params.norm == Norm::Preconditioned {
            relative_residual = if rz0 > 0.0 { 1.0 } else { 0.0 };
        }
        let ended = |iterations: usize, relative_residual: f64| Convergence {
            iterations,
            relative_residual,
            converged: relative_residual <= params.rtol,
        };
        if relative_residual <= params.rtol {
            return ended(0, relative_residual);
        }
        for k in 1..=params.max_iterations {
            system.apply(p, ap);
            let alpha = rz / system.dot(p, ap);
            on(pool, || {
                axpy(alpha, p, x);
                axpy(-alpha, ap, r);
            });
            let rz_next = match params.norm {
                Norm::Residual => {
                    let rr = system.dot(r, r);
                    relative_residual = if scale > 0.0 { rr.sqrt() / scale } else { 0.0 };
                    let last = k == params.max_iterations || !relative_residual.is_finite();
                    if relative_residual <= params.rtol || last {
                        return ended(k, relative_residual);
                    }
                    if preconditioned {
                        system.precondition(r, z);
                        system.dot(r, z)
                    } else {
                        rr
                    }
                }
                Norm::Preconditioned => {
                    let rz_next = if preconditioned {
                        system.precondition(r, z);
                        system.dot(r, z)
                    } else {
                        system.dot(r, r)
                    };
                    relative_residual = (rz_next.max(0.0) / rz0).sqrt();
                    let last = k == params.max_iterations || !relative_residual.is_finite();
                    if relative_residual <= params.rtol || last {
                        return ended(k, relative_residual);
                    }
                    rz_next
                }
            };
            let beta = rz_next / rz;
            let direction: &[f64] = if preconditioned { z } else { r };
            on(pool, || xpby(direction, beta, p));
            rz = rz_next;
        }
        ended(0, relative_residual)
    }
}

/// A preconditioner M ≈ A⁻¹ for `Closures`: a closure writing z = M r, or `NoPreconditioner`.
pub trait Preconditioner {
    /// Whether there is one (without, CG's z is r itself).
    const PRESENT: bool = true;

    fn apply(&mut self, r: &[f64], z: &mut [f64]);
}

/// CG without a preconditioner.
pub struct NoPreconditioner;

impl Preconditioner for NoPreconditioner {
    const PRESENT: bool = false;

    fn apply(&mut self, _: &[f64], _: &mut [f64]) {}
}

impl<M: FnMut(&[f64], &mut [f64])> Preconditioner for M {
    fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        self(r, z)
    }
}

/// A `CgSystem` of closures: `apply` writes ap = A p, `precondition` is the preconditioner,
/// `dot` the inner product.
pub struct Closures<A, M, D> {
    pub len: usize,
    pub apply: A,
    pub precondition: M,
    pub dot: D,
}

impl<A, M, D> CgSystem for Closures<A, M, D>
where
    A: FnMut(&[f64], &mut [f64]),
    M: Preconditioner,
    D: Fn(&[f64], &[f64]) -> f64,
{
    fn len(&self) -> usize {
        self.len
    }

    fn apply(&mut self, p: &[f64], ap: &mut [f64]) {
        (self.apply)(p, ap)
    }

    fn dot(&mut self, a: &[f64], b: &[f64]) -> f64 {
        (self.dot)(a, b)
    }

    fn preconditioned(&self) -> bool {
        M::PRESENT
    }

    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.precondition.apply(r, z)
    }
}

/// Refuses, with a message rather than a short read, a solve whose b, x or buffers are not of
/// the system's length (a caller's error).
pub(crate) fn check_lengths(method: &str, len: usize, b: &[f64], x: &[f64], buffers: usize) {
    assert!(
        b.len() == len && x.len() == len && buffers == len,
        "{method} on a system of {len} unknowns was given b of {}, x of {} and buffers of {buffers}",
        b.len(),
        x.len(),
    );
}

/// y += a x.
pub fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.par_chunks_mut(CHUNK)
        .zip(x.par_chunks(CHUNK))
        .for_each(|(y, x)| y.iter_mut().zip(x).for_each(|(y, &x)| *y += a * x));
}

/// out = x + a y.
pub fn combine(out: &mut [f64], x: &[f64], a: f64, y: &[f64]) {
    out.par_chunks_mut(CHUNK)
        .zip(x.par_chunks(CHUNK).zip(y.par_chunks(CHUNK)))
        .for_each(|(o, (x, y))| {
            for ((o, &x), &y) in o.iter_mut().zip(x).zip(y) {
                *o = x + a * y;
            }
        });
}

/// p ← x + β p, the new search direction of (preconditioned) CG.
fn xpby(x: &[f64], beta: f64, p: &mut [f64]) {
    p.par_chunks_mut(CHUNK)
        .zip(x.par_chunks(CHUNK))
        .for_each(|(p, x)| p.iter_mut().zip(x).for_each(|(p, &x)| *p = x + beta * *p));
}

/// Σ aᵢ bᵢ, summed in a fixed tree of fixed chunks (the same rounding on any thread count).
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    if a.len() <= CHUNK {
        return dot_serial(a, b);
    }
    let mid = (a.len() / CHUNK / 2).max(1) * CHUNK;
    let (left, right) = rayon::join(|| dot(&a[..mid], &b[..mid]), || dot(&a[mid..], &b[mid..]));
    left + right
}

/// Σ aᵢ bᵢ with eight partial sums, so that the loop vectorises.
pub fn dot_serial(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = a8
        .remainder()
        .iter()
        .zip(b8.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a8.zip(b8) {
        for l in 0..8 {
            lanes[l] += x[l] * y[l];
        }
    }
    lanes.iter().sum::<f64>() + tail
}

#[cfg(test)]
mod tests {
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

    #[test]
    fn every_start_and_norm_gives_the_bits_of_the_loop_it_replaced() {
        let n = 64;
        let (a, m) = (laplacian(n), scaled(n));
        let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n];
        a(&exact, &mut b);
        let guess: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64).cos()).collect();
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
            let mut ax = vec![0.0; n];
            a(&guess, &mut ax);
            let r0: Vec<f64> = b.iter().zip(&ax).map(|(b, ax)| b - ax).collect();
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
}
