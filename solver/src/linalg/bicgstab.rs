//! BiCGStab (van der Vorst 1992, right-preconditioned) for the systems CG cannot solve:
//! I − θ dt L_h with a non-symmetric L_h (the x-centred and partial-stress forms of a varying
//! horizon). It iterates on the same `CgSystem` as CG: A, the preconditioner M ≈ A⁻¹, and the
//! inner product, summed over ranks when the vectors are distributed.
//!
//! Our own rather than faer's `matrix_free::bicgstab`: faer's operators must be `Sync` and it
//! takes its own inner products, while ours carry the rank exchange (not `Sync`) and sum in a
//! fixed order, so that the iterates do not depend on the thread or rank count.

use crate::linalg::cg::{axpy, check_lengths, CgSystem, Convergence, CHUNK};
use crate::threads::on;
use rayon::prelude::*;
use rayon::ThreadPool;

/// The buffers of BiCGStab for vectors of one length, made once and reused by every solve.
pub struct BiCgStab {
    r: Vec<f64>,
    shadow: Vec<f64>,
    p: Vec<f64>,
    v: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    t: Vec<f64>,
}

impl BiCgStab {
    pub fn new(len: usize) -> Self {
        let zeros = || vec![0.0; len];
        BiCgStab {
            r: zeros(),
            shadow: zeros(),
            p: zeros(),
            v: zeros(),
            y: zeros(),
            z: zeros(),
            t: zeros(),
        }
    }

    /// Solves A x = b from the guess in `x` until ‖r‖ ≤ rtol ‖b‖ or `max_iterations` have run
    /// (or the iteration breaks down: a zero or non-finite ρ, (r̂, v), (t, s) or (t, t), reported
    /// unconverged with x as the last completed half step left it). ‖r‖ is the recursively
    /// updated residual, as in CG. `pool` is where the vector updates run, as for CG.
    pub fn solve(
        &mut self,
        system: &mut impl CgSystem,
        b: &[f64],
        x: &mut [f64],
        rtol: f64,
        max_iterations: usize,
        pool: Option<&ThreadPool>,
    ) -> Convergence {
        check_lengths("BiCGStab", system.len(), b, x, self.r.len());
        let BiCgStab {
            r,
            shadow,
            p,
            v,
            y,
            z,
            t,
        } = self;
        system.apply(x, v);
        on(pool, || {
            r.copy_from_slice(b);
            axpy(-1.0, v, r);
            shadow.copy_from_slice(r);
            p.fill(0.0);
            v.fill(0.0);
        });
        let b_norm = system.dot(b, b).sqrt();
        let relative = |system: &mut _, r: &[f64]| match b_norm > 0.0 {
            true => CgSystem::dot(system, r, r).sqrt() / b_norm,
            false => 0.0,
        };
        let mut relative_residual = relative(system, r);
        let ended = |iterations, relative_residual: f64| Convergence {
            iterations,
            relative_residual,
            converged: relative_residual <= rtol,
        };
        if relative_residual <= rtol {
            return ended(0, relative_residual);
        }
        // A breakdown (a zero or non-finite denominator) stops the solve before x is touched,
        // unconverged, after the iterations that completed.
        let broke_down = |done: usize, relative_residual: f64| Convergence {
            converged: false,
            ..ended(done, relative_residual)
        };
        let usable = |d: f64| d != 0.0 && d.is_finite();
        let (mut rho, mut alpha, mut omega) = (1.0, 1.0, 1.0);
        for k in 1..=max_iterations {
            let rho_next = system.dot(shadow, r);
            if !usable(rho_next) {
                return broke_down(k - 1, relative_residual);
            }
            let beta = (rho_next / rho) * (alpha / omega);
            on(pool, || update_direction(p, r, beta, omega, v));
            precondition(system, p, y);
            system.apply(y, v);
            let shadow_v = system.dot(shadow, v);
            if !usable(shadow_v) {
                return broke_down(k - 1, relative_residual);
            }
            alpha = rho_next / shadow_v;
            // s = r − α v, kept in r.
            on(pool, || {
                axpy(alpha, y, x);
                axpy(-alpha, v, r);
            });
            relative_residual = relative(system, r);
            if relative_residual <= rtol || !relative_residual.is_finite() {
                return ended(k, relative_residual);
            }
            precondition(system, r, z);
            system.apply(z, t);
            let (ts, tt) = (system.dot(t, r), system.dot(t, t));
            if !usable(ts) || !usable(tt) {
                // x and r are those after the half step, a consistent pair.
                return broke_down(k, relative_residual);
            }
            omega = ts / tt;
            on(pool, || {
                axpy(omega, z, x);
                axpy(-omega, t, r);
            });
            relative_residual = relative(system, r);
            if relative_residual <= rtol || !relative_residual.is_finite() || k == max_iterations {
                return ended(k, relative_residual);
            }
            rho = rho_next;
        }
        ended(max_iterations, relative_residual)
    }
}

/// out = M r, or r itself without a preconditioner.
fn precondition(system: &mut impl CgSystem, r: &[f64], out: &mut [f64]) {
    match system.preconditioned() {
        true => system.precondition(r, out),
        false => out.copy_from_slice(r),
    }
}

/// p ← r + β (p − ω v).
fn update_direction(p: &mut [f64], r: &[f64], beta: f64, omega: f64, v: &[f64]) {
    p.par_chunks_mut(CHUNK)
        .zip(r.par_chunks(CHUNK))
        .zip(v.par_chunks(CHUNK))
        .for_each(|((p, r), v)| {
            for ((p, &r), &v) in p.iter_mut().zip(r).zip(v) {
                *p = r + beta * (*p - omega * v);
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::cg::{dot, Closures};
    use faer::linalg::solvers::Solve;
    use faer::Mat;

    /// A non-symmetric, diagonally dominant matrix (an upwinded convection–diffusion stencil
    /// with far couplings), its BiCGStab solution against faer's dense LU, with the Jacobi
    /// preconditioner and with the identity, on one thread and on two: the same bits.
    #[test]
    fn bicgstab_solves_a_non_symmetric_system_as_a_dense_solve_does() {
        let n = 300;
        let entry = |i: usize, j: usize| -> f64 {
            let d = j as i64 - i as i64;
            match d {
                0 => 4.0 + (i % 7) as f64 * 0.1,
                -1 => -1.7,
                1 => -0.6,
                -9 => -0.4,
                13 => -0.3,
                _ => 0.0,
            }
        };
        let dense = Mat::from_fn(n, n, entry);
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let exact = dense
            .partial_piv_lu()
            .solve(Mat::from_fn(n, 1, |i, _| b[i]));
        let apply = |p: &[f64], ap: &mut [f64]| {
            for (i, out) in ap.iter_mut().enumerate() {
                *out = [0i64, -1, 1, -9, 13]
                    .iter()
                    .map(|&d| i as i64 + d)
                    .filter(|&j| (0..n as i64).contains(&j))
                    .map(|j| entry(i, j as usize) * p[j as usize])
                    .sum();
            }
        };
        let solve = |threads: usize, jacobi: bool| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut x = vec![0.0; n];
            let mut solver = BiCgStab::new(n);
            let mut solve_with = |precondition: &mut (dyn FnMut(&[f64], &mut [f64]) + Send)| {
                let system = &mut Closures {
                    len: n,
                    apply,
                    precondition: |r: &[f64], z: &mut [f64]| precondition(r, z),
                    dot,
                };
                pool.install(|| solver.solve(system, &b, &mut x, 1e-13, 500, None))
            };
            let convergence = match jacobi {
                true => solve_with(&mut |r, z| {
                    for (i, z) in z.iter_mut().enumerate() {
                        *z = r[i] / entry(i, i);
                    }
                }),
                false => solve_with(&mut |r, z| z.copy_from_slice(r)),
            };
            assert!(convergence.converged, "{convergence:?}");
            x
        };
        for jacobi in [false, true] {
            let x = solve(1, jacobi);
            let error = (0..n).fold(0.0f64, |m, i| m.max((x[i] - exact[(i, 0)]).abs()));
            assert!(
                error < 1e-11,
                "jacobi {jacobi}: BiCGStab is {error:e} from LU"
            );
            assert_eq!(x, solve(2, jacobi), "the thread count changed the bits");
        }
    }
}
