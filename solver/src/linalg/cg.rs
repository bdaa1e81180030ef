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
        self.solve_checkpointed(system, b, x, params, &mut NoCheckpoints)
    }

    /// `solve`, going on from the state `checkpoints` resumes from (if any) and handing it the
    /// state after every iteration: a solve stopped after iteration k and resumed there makes
    /// the iterates, and so the result, of one never stopped, bit for bit.
    pub fn solve_checkpointed(
        &mut self,
        system: &mut impl CgSystem,
        b: &[f64],
        x: &mut [f64],
        params: &CgParams,
        checkpoints: &mut dyn Checkpoints,
    ) -> Convergence {
        let len = system.len();
        check_lengths("CG", len, b, x, self.r.len());
        let preconditioned = system.preconditioned();
        let Cg { r, z, p, ap } = self;
        let pool = params.pool;
        let ended = |iterations: usize, relative_residual: f64| Convergence {
            iterations,
            relative_residual,
            converged: relative_residual <= params.rtol,
        };
        // The iteration to go on from, rᵀz, the stopping norm's reference (‖b‖, or r₀ᵀz₀ for
        // the preconditioned norm) and the residual in that norm.
        let (done, mut rz, reference, mut relative_residual) = match checkpoints.resume(len) {
            Some(state) => {
                on(pool, || {
                    x.copy_from_slice(&state.x);
                    r.copy_from_slice(&state.r);
                    p.copy_from_slice(&state.p);
                });
                (
                    state.iteration,
                    state.rz,
                    state.reference,
                    state.relative_residual,
                )
            }
            None => {
                let (rz, reference, relative_residual) = start(system, b, x, (r, z, p, ap), params);
                if relative_residual <= params.rtol {
                    return ended(0, relative_residual);
                }
                (0, rz, reference, relative_residual)
            }
        };
        for k in done + 1..=params.max_iterations {
            system.apply(p, ap);
            let alpha = rz / system.dot(p, ap);
            on(pool, || {
                axpy(alpha, p, x);
                axpy(-alpha, ap, r);
            });
            let rz_next = match params.norm {
                Norm::Residual => {
                    let rr = system.dot(r, r);
                    relative_residual = if reference > 0.0 {
                        rr.sqrt() / reference
                    } else {
                        0.0
                    };
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
                    relative_residual = (rz_next.max(0.0) / reference).sqrt();
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
            checkpoints.after_iteration(State {
                iteration: k,
                x: &x[..],
                r: &r[..],
                p: &p[..],
                rz,
                reference,
                relative_residual,
            });
        }
        ended(done, relative_residual)
    }
}

/// The start of a solve from `params.start`: r₀, the first direction p₀, and (r₀ᵀz₀, the
/// stopping norm's reference, the first residual in that norm).
fn start(
    system: &mut impl CgSystem,
    b: &[f64],
    x: &mut [f64],
    (r, z, p, ap): (&mut [f64], &mut [f64], &mut [f64], &mut [f64]),
    params: &CgParams,
) -> (f64, f64, f64) {
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
            assert_eq!(r0.len(), r.len(), "the initial residual's length");
            on(pool, || r.copy_from_slice(r0));
        }
    }
    // The first residual in the solve's norm, ‖r₀‖² (what rᵀz is without a preconditioner)
    // and the norm's scale.
    let (relative_residual, r0r0, scale) = match params.norm {
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
    let rz = if system.preconditioned() {
        system.precondition(r, z);
        on(pool, || p.copy_from_slice(z));
        system.dot(r, z)
    } else {
        on(pool, || p.copy_from_slice(r));
        match params.norm {
            Norm::Residual => r0r0,
            Norm::Preconditioned => system.dot(r, r),
        }
    };
    match params.norm {
        Norm::Residual => (rz, scale, relative_residual),
        Norm::Preconditioned => (rz, rz, if rz > 0.0 { 1.0 } else { 0.0 }),
    }
}

/// CG's state between two iterations, all it needs to go on: the iterate, the residual, the
/// search direction (z is made again from r), rᵀz, the stopping norm's reference and the
/// residual in that norm. Borrowed from the solve (`V = &[f64]`) or read back (`Vec<f64>`).
#[derive(Clone, Debug, PartialEq)]
pub struct State<V> {
    /// The iterations done.
    pub iteration: usize,
    pub x: V,
    pub r: V,
    pub p: V,
    pub rz: f64,
    pub reference: f64,
    pub relative_residual: f64,
}

/// Where a solve's checkpoints go: the state to resume from, and the state after each
/// iteration (to save, or to stop at).
pub trait Checkpoints {
    /// The state after some iteration to go on from, taken once before the first one; None
    /// to start from `CgParams::start`. Vectors not of `len` values are not this solve's.
    fn resume(&mut self, len: usize) -> Option<State<Vec<f64>>>;

    /// After every iteration that did not end the solve.
    fn after_iteration(&mut self, state: State<&[f64]>);
}

/// A solve without checkpoints.
pub struct NoCheckpoints;

impl Checkpoints for NoCheckpoints {
    fn resume(&mut self, _: usize) -> Option<State<Vec<f64>>> {
        None
    }

    fn after_iteration(&mut self, _: State<&[f64]>) {}
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
mod tests;
