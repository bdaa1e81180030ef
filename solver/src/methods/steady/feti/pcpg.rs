//! The interface problem and its solve: the rank's share of the FETI system with the coarse
//! problem GᵀG, and the preconditioned projected CG of \[XGDF]'s Algorithm 1.

use super::dual::DualLayout;
use super::local::{Local, ProductClock};
use crate::case::FetiPreconditioner;
use crate::linalg::cg::{dot_serial, Cg, CgParams, CgSystem, Norm, Start};
use crate::methods::steady::decomposition::Decomposition;
use crate::methods::steady::resume::SolveCheckpoints;
use crate::output::record::FetiPhases;
use crate::parallel::exchange::Exchange;
use faer::linalg::solvers::Solve;
use faer::MatMut;
use rayon::prelude::*;
use rayon::ThreadPool;
use std::ops::Range;
use std::time::Instant;

/// The rank's share of the FETI system and the coarse problem.
pub(super) struct Feti<'d> {
    pub(super) decomposition: &'d Decomposition,
    pub(super) owned: Vec<usize>,
    pub(super) locals: Vec<Local<'d>>,
    pub(super) layout: DualLayout,
    /// (GᵀG)'s Cholesky factor (None when no subdomain floats).
    pub(super) coarse: Option<faer::linalg::solvers::Llt<f64>>,
    pub(super) preconditioner: FetiPreconditioner,
    pub(super) pool: &'d ThreadPool,
    /// This rank's wall seconds per phase since the clocks were last reset.
    pub(super) phases: PhaseSeconds,
}

#[derive(Default)]
pub(super) struct PhaseSeconds {
    pub(super) subdomain_solves: f64,
    pub(super) preconditioner: f64,
    pub(super) interface_sum: f64,
    pub(super) coarse: f64,
}

impl<'d> Feti<'d> {
    /// a · b over the multipliers, each once (on its lower-numbered subdomain), summed per
    /// subdomain and then in subdomain order.
    pub(super) fn dot(&self, exchange: &dyn Exchange, a: &[f64], b: &[f64]) -> f64 {
        let mut partial = vec![0.0; self.decomposition.subdomains.len()];
        for (k, &n) in self.owned.iter().enumerate() {
            let start = self.layout.offsets[k];
            partial[n] = self.decomposition.subdomains[n]
                .interfaces
                .iter()
                .filter(|i| n < i.other)
                .map(|i| {
                    let s = start + i.offset;
                    dot_serial(&a[s..s + i.nodes.len()], &b[s..s + i.nodes.len()])
                })
                .sum();
        }
        exchange.all_sum(&mut partial);
        partial.iter().sum()
    }

    /// out ← K x.
    pub(super) fn apply_k(&mut self, exchange: &dyn Exchange, x: &[f64], out: &mut [f64]) {
        let products_s =
            self.interface_assembled(exchange, out, |local, own, out| local.apply_k(&x[own], out));
        self.phases.subdomain_solves += products_s;
    }

    /// out ← Q r.
    pub(super) fn apply_preconditioner(
        &mut self,
        exchange: &dyn Exchange,
        r: &[f64],
        out: &mut [f64],
    ) {
        if self.preconditioner == FetiPreconditioner::None {
            out.copy_from_slice(r);
            return;
        }
        let products_s = self.interface_assembled(exchange, out, |local, own, out| {
            local.apply_dirichlet(&r[own], out)
        });
        self.phases.preconditioner += products_s;
    }

    /// out ← Σ_n R_nᵀ product_n: every owned subdomain's local product in parallel, as
    /// `product(local, its range in the dual vectors, its part of out)`, then the interface sum.
    /// Returns the products' wall seconds; the sum's go to the phase clock.
    pub(super) fn interface_assembled(
        &mut self,
        exchange: &dyn Exchange,
        out: &mut [f64],
        product: impl Fn(&mut Local<'d>, Range<usize>, &mut [f64]) + Sync,
    ) -> f64 {
        let started = Instant::now();
        let parts = self.layout.split(out);
        let offsets = &self.layout.offsets;
        let locals = &mut self.locals;
        self.pool.install(|| {
            locals
                .par_iter_mut()
                .zip(parts)
                .enumerate()
                .for_each(|(k, (local, out))| product(local, offsets[k]..offsets[k + 1], out))
        });
        let products_s = started.elapsed().as_secs_f64();
        let summing = Instant::now();
        self.layout.interface_sum(exchange, out);
        self.phases.interface_sum += summing.elapsed().as_secs_f64();
        products_s
    }

    /// Gᵀ x, summed over ranks: per floating subdomain a, Σ over a's multipliers of sign · x.
    pub(super) fn g_transpose(&self, exchange: &dyn Exchange, x: &[f64]) -> Vec<f64> {
        let mut gx = vec![0.0; self.decomposition.floating.len()];
        for (k, &n) in self.owned.iter().enumerate() {
            let subdomain = &self.decomposition.subdomains[n];
            if let Some(a) = subdomain.coarse {
                let start = self.layout.offsets[k];
                gx[a] = subdomain
                    .interfaces
                    .iter()
                    .map(|i| {
                        let s = start + i.offset;
                        i.sign * x[s..s + i.nodes.len()].iter().sum::<f64>()
                    })
                    .sum();
            }
        }
        exchange.all_sum(&mut gx);
        gx
    }

    /// (GᵀG)⁻¹ v.
    pub(super) fn coarse_solve(&self, v: &mut [f64]) {
        if let Some(coarse) = &self.coarse {
            let n = v.len();
            coarse.solve_in_place(MatMut::from_column_major_slice_mut(v, n, 1));
        }
    }

    /// x ← x + G̃ β: on n's multipliers, sign · (β_n − β_other) over the floating ones.
    pub(super) fn add_g(&self, beta: &[f64], x: &mut [f64]) {
        for (k, &n) in self.owned.iter().enumerate() {
            let subdomain = &self.decomposition.subdomains[n];
            let start = self.layout.offsets[k];
            for interface in &subdomain.interfaces {
                let own = subdomain.coarse.map_or(0.0, |a| beta[a]);
                let other = self.decomposition.subdomains[interface.other]
                    .coarse
                    .map_or(0.0, |b| beta[b]);
                let value = interface.sign * (own - other);
                if value != 0.0 {
                    let s = start + interface.offset;
                    x[s..s + interface.nodes.len()]
                        .iter_mut()
                        .for_each(|v| *v += value);
                }
            }
        }
    }

    /// x ← P₀ x = x − G (GᵀG)⁻¹ Gᵀ x.
    pub(super) fn project(&mut self, exchange: &dyn Exchange, x: &mut [f64]) {
        if self.coarse.is_none() {
            return;
        }
        let started = Instant::now();
        let mut beta = self.g_transpose(exchange, x);
        self.coarse_solve(&mut beta);
        beta.iter_mut().for_each(|b| *b = -*b);
        self.add_g(&beta, x);
        self.phases.coarse += started.elapsed().as_secs_f64();
    }

    /// Starts the phase clocks and the subdomains' product clocks from zero.
    pub(super) fn reset_clocks(&mut self) {
        self.phases = PhaseSeconds::default();
        self.locals
            .iter_mut()
            .for_each(|l| l.clock = ProductClock::default());
    }

    /// Seconds per iteration of each phase over `iterations` taking `loop_s` (max over ranks),
    /// and the mean product times of one subdomain (over every rank's subdomains).
    pub(super) fn phases(
        &self,
        exchange: &dyn Exchange,
        iterations: usize,
        loop_s: f64,
    ) -> FetiPhases {
        let per_iteration = |s: f64| exchange.max(s) / iterations.max(1) as f64;
        let clocks = self.locals.iter().map(|l| l.clock);
        let mut sums = clocks.fold([0.0; 4], |[k, nk, q, nq], c| {
            [
                k + c.k_s,
                nk + c.k_products as f64,
                q + c.q_s,
                nq + c.q_products as f64,
            ]
        });
        exchange.all_sum(&mut sums);
        let mean = |s: f64, count: f64| if count > 0.0 { s / count } else { 0.0 };
        let phases = &self.phases;
        let other = loop_s
            - phases.subdomain_solves
            - phases.preconditioner
            - phases.interface_sum
            - phases.coarse;
        FetiPhases {
            subdomain_solves_s: per_iteration(phases.subdomain_solves),
            preconditioner_s: per_iteration(phases.preconditioner),
            interface_sum_s: per_iteration(phases.interface_sum),
            coarse_s: per_iteration(phases.coarse),
            other_s: per_iteration(other.max(0.0)),
            subdomain_k_s: mean(sums[0], sums[1]),
            subdomain_q_s: mean(sums[2], sums[3]),
        }
    }
}

/// What the projected CG returns.
pub(super) struct DualSolve {
    pub(super) lambda: Vec<f64>,
    pub(super) iterations: usize,
    pub(super) dual_residual: f64,
    pub(super) phases: FetiPhases,
}

/// The interface problem P₀ K λ = P₀ e as CG sees it: A = P₀ K, M = P₀ Q (\[XGDF]'s
/// Algorithm 1), the inner product over the multipliers. The phases are timed from the first
/// iteration's product on, not over the start-up.
pub(super) struct DualSystem<'f, 'd> {
    pub(super) feti: &'f mut Feti<'d>,
    pub(super) exchange: &'f dyn Exchange,
    pub(super) iterations_started: Option<Instant>,
}

impl CgSystem for DualSystem<'_, '_> {
    fn len(&self) -> usize {
        self.feti.layout.len()
    }

    fn apply(&mut self, p: &[f64], x: &mut [f64]) {
        if self.iterations_started.is_none() {
            self.feti.reset_clocks();
            self.iterations_started = Some(Instant::now());
        }
        self.feti.apply_k(self.exchange, p, x);
        self.feti.project(self.exchange, x);
    }

    fn dot(&mut self, a: &[f64], b: &[f64]) -> f64 {
        self.feti.dot(self.exchange, a, b)
    }

    fn preconditioned(&self) -> bool {
        true
    }

    fn precondition(&mut self, r: &[f64], y: &mut [f64]) {
        self.feti.apply_preconditioner(self.exchange, r, y);
        self.feti.project(self.exchange, y);
    }
}

/// Algorithm 1: preconditioned projected CG on P₀ K λ = P₀ e, Gᵀλ = g, until
/// √(rᵀy / r₀ᵀy₀) ≤ rtol.
pub(super) fn projected_cg(
    feti: &mut Feti,
    exchange: &dyn Exchange,
    e: &[f64],
    g: &[f64],
    rtol: f64,
    max_iterations: usize,
    checkpoints: &mut SolveCheckpoints,
) -> DualSolve {
    let len = feti.layout.len();
    let mut lambda = vec![0.0; len];
    let mut beta = g.to_vec();
    feti.coarse_solve(&mut beta);
    feti.add_g(&beta, &mut lambda);
    let mut x = vec![0.0; len];
    feti.apply_k(exchange, &lambda, &mut x);
    // The residual of P₀ K λ = P₀ e (eq. 31): projected, so that y = P₀ Q r stays symmetric.
    let mut r: Vec<f64> = e.iter().zip(&x).map(|(e, x)| e - x).collect();
    feti.project(exchange, &mut r);
    let params = CgParams {
        start: Start::Residual(&r),
        rtol,
        norm: Norm::Preconditioned,
        max_iterations,
        pool: None,
    };
    let mut system = DualSystem {
        feti,
        exchange,
        iterations_started: None,
    };
    let convergence =
        Cg::new(len).solve_checkpointed(&mut system, e, &mut lambda, &params, checkpoints);
    let started = system.iterations_started;
    if started.is_none() {
        // Solved before any iteration: no phase is timed.
        feti.reset_clocks();
    }
    let loop_s = started.map_or(0.0, |started| started.elapsed().as_secs_f64());
    // Per iteration of the segment timed: a resumed solve times those after its checkpoint.
    let timed = convergence.iterations - checkpoints.resumed_from();
    let phases = feti.phases(exchange, timed, loop_s);
    DualSolve {
        lambda,
        iterations: convergence.iterations,
        dual_residual: convergence.relative_residual,
        phases,
    }
}
