//! Unpreconditioned conjugate gradients from a zero initial guess (seed 001, section 4.1's
//! baseline), over any matrix–vector product and inner product: threaded on one process, or
//! with a halo exchange and a reduction over ranks.
//!
//! The vector updates and the inner product split the vectors at fixed boundaries, so the
//! iterates do not depend on the thread count.

use crate::threads::on;
use rayon::prelude::*;
use rayon::ThreadPool;

/// Length below which a vector operation runs on one thread; the split points of `dot`.
const CHUNK: usize = 8192;

/// How an iteration ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convergence {
    pub iterations: usize,
    /// ‖r_k‖/‖b‖ of the recursively updated residual.
    pub relative_residual: f64,
}

/// Solves A x = b for symmetric positive definite A from x = 0, until ‖r‖ ≤ rtol ‖b‖ or
/// `max_iterations`. `apply(p, ap)` writes ap = A p; `dot` is the inner product (a sum over
/// ranks when the vectors are distributed). x must be zero on entry. The vector updates run on
/// `pool` (the current one when None), so that MPI calls in `apply` and `dot` can stay on the
/// calling thread.
pub fn conjugate_gradient(
    pool: Option<&ThreadPool>,
    mut apply: impl FnMut(&[f64], &mut [f64]),
    dot: impl Fn(&[f64], &[f64]) -> f64,
    b: &[f64],
    x: &mut [f64],
    rtol: f64,
    max_iterations: usize,
) -> Convergence {
    let mut r = b.to_vec();
    let mut p = b.to_vec();
    let mut ap = vec![0.0; b.len()];
    let b_norm = dot(b, b).sqrt();
    let mut rr = b_norm * b_norm;
    if b_norm == 0.0 {
        return Convergence {
            iterations: 0,
            relative_residual: 0.0,
        };
    }
    for k in 1..=max_iterations {
        apply(&p, &mut ap);
        let alpha = rr / dot(&p, &ap);
        on(pool, || {
            axpy(alpha, &p, x);
            axpy(-alpha, &ap, &mut r);
        });
        let rr_next = dot(&r, &r);
        let relative_residual = rr_next.sqrt() / b_norm;
        if relative_residual <= rtol || k == max_iterations || !relative_residual.is_finite() {
            return Convergence {
                iterations: k,
                relative_residual,
            };
        }
        let beta = rr_next / rr;
        on(pool, || xpby(&r, beta, &mut p));
        rr = rr_next;
    }
    Convergence {
        iterations: 0,
        relative_residual: 1.0,
    }
}

/// The buffers of preconditioned CG for vectors of one length, made once and reused by every
/// solve (an implicit integrator solves once per step).
pub struct Pcg {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

impl Pcg {
    pub fn new(len: usize) -> Self {
        Pcg {
            r: vec![0.0; len],
            z: vec![0.0; len],
            p: vec![0.0; len],
            ap: vec![0.0; len],
        }
    }

    /// Solves A x = b for symmetric positive definite A and M ≈ A⁻¹ (`precondition(r, z)` writes
    /// z = M r), from the initial guess in x, until ‖r‖ ≤ rtol ‖b‖ or `max_iterations`. `apply`
    /// and `dot` are as for `conjugate_gradient`; the vector updates run on `pool`.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        pool: Option<&ThreadPool>,
        mut apply: impl FnMut(&[f64], &mut [f64]),
        mut precondition: impl FnMut(&[f64], &mut [f64]),
        dot: impl Fn(&[f64], &[f64]) -> f64,
        b: &[f64],
        x: &mut [f64],
        rtol: f64,
        max_iterations: usize,
    ) -> Convergence {
        let Pcg { r, z, p, ap } = self;
        apply(x, ap);
        on(pool, || {
            r.copy_from_slice(b);
            axpy(-1.0, ap, r);
        });
        let b_norm = dot(b, b).sqrt();
        let residual = |rr: f64| {
            if b_norm > 0.0 {
                rr.sqrt() / b_norm
            } else {
                0.0
            }
        };
        let mut relative_residual = residual(dot(r, r));
        if relative_residual <= rtol {
            return Convergence {
                iterations: 0,
                relative_residual,
            };
        }
        precondition(r, z);
        on(pool, || p.copy_from_slice(z));
        let mut rz = dot(r, z);
        for k in 1..=max_iterations {
            apply(p, ap);
            let alpha = rz / dot(p, ap);
            on(pool, || {
                axpy(alpha, p, x);
                axpy(-alpha, ap, r);
            });
            relative_residual = residual(dot(r, r));
            if relative_residual <= rtol || k == max_iterations || !relative_residual.is_finite() {
                return Convergence {
                    iterations: k,
                    relative_residual,
                };
            }
            precondition(r, z);
            let rz_next = dot(r, z);
            let beta = rz_next / rz;
            on(pool, || xpby(z, beta, p));
            rz = rz_next;
        }
        Convergence {
            iterations: max_iterations,
            relative_residual,
        }
    }
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

    fn max_difference(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    }

    /// The 1D Laplacian tridiag(−1, 2, −1): CG converges in at most n iterations.
    #[test]
    fn solves_a_tridiagonal_system_in_at_most_n_iterations() {
        let n = 50;
        let apply = laplacian(n);
        let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n];
        apply(&exact, &mut b);
        let mut x = vec![0.0; n];
        let convergence = conjugate_gradient(None, apply, dot, &b, &mut x, 1e-12, 1000);
        assert!(convergence.iterations <= n, "{convergence:?}");
        let error = max_difference(&x, &exact);
        assert!(error < 1e-9, "error {error}");
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
        let mut pcg = Pcg::new(n);
        let mut x = vec![0.0; n];
        let first = pcg.solve(None, apply, inverse, dot, &b, &mut x, 1e-12, 100);
        assert_eq!(first.iterations, 1, "{first:?}");
        let again = pcg.solve(None, apply, inverse, dot, &b, &mut x, 1e-12, 100);
        assert_eq!(again.iterations, 0, "{again:?}");
        let error = max_difference(&x, &exact);
        assert!(error < 1e-12, "error {error}");
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
