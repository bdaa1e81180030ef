//! Nonlocal FETI (\[XGDF], section 3): the subdomain problems joined by Lagrange multipliers,
//! solved by the distributed preconditioned projected CG of Algorithm 1.
//!
//! Each rank owns a contiguous run of subdomains (`Decomposition::owner`) and keeps, per
//! subdomain, its local copy of every multiplier it touches (λ_n = R^D_n λ), as the seed does: a
//! product with K or Q is a local product per subdomain followed by one exchange that adds the
//! partner's contribution on each interface. The coarse problem GᵀG is factored on every rank.
//!
//! - A_n^† on a floating subdomain (nullspace: the constants 1) is the Moore–Penrose
//!   pseudo-inverse P A_g P, P = I − 11ᵀ/s_n, with A_g = (A_n + ρ e_k e_kᵀ)⁻¹: for b ⊥ 1 the
//!   regularised system's solution has x_k = 1ᵀb/ρ = 0, so it solves A_n x = b, and P picks the
//!   solution orthogonal to the nullspace.
//! - Algorithm 1 as printed updates r⁺ = r − (α/β) p; the projected CG it states needs
//!   r⁺ = r − (α/β) x (x = P₀ K p), which is what runs here. Its r₀ = e − K λ₀ is projected,
//!   r₀ = P₀(e − K λ₀), the residual of eq. 31: unprojected, the preconditioner Q applied to its
//!   range(G) part would add a component that never decays (the printed version converges only
//!   for Q = I). e = M A^† f is also summed over the interfaces like K λ (the printed line 4
//!   leaves that implicit).
//! - The iteration stops when √(rᵀy / r₀ᵀy₀) ≤ rtol (the seed's "until rᵀy is small enough");
//!   the record also gives the single-domain residual ‖f − A u‖/‖f‖ of the solution.
//! - Inner products sum per-subdomain partial sums in subdomain order, and G's sums are exact
//!   (one contribution per entry), so the iterates are the same bits on any number of ranks
//!   and threads.

use super::assembly::assemble;
use super::decomposition::{Decomposition, Subdomain};
use super::problem::{outcome, SteadyProblem, Stop, Summary, Timings};
use crate::case::Backend;
use crate::case::ValidCase;
use crate::case::{Case, CaseError, FetiPreconditioner};
use crate::discretization::grid::Window;
use crate::linalg::cg::{
    dot_serial, Cg, CgParams, CgSystem, Closures, NoPreconditioner, Norm, Start,
};
use crate::linalg::cholesky::{symmetric_product, Cholesky};
use crate::operator::LinearOperator;
use crate::output::outcome::Outcome;
use crate::output::record::{Distribution, FetiPhases, SteadySolve};
use crate::parallel::exchange::Exchange;
use crate::parallel::exchange::Ranks;
use crate::parallel::operator::DistributedOperator;
use crate::parallel::partition::Ownership;
use crate::parallel::share::RankShare;
use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMat;
use faer::MatMut;
use rayon::prelude::*;
use rayon::ThreadPool;
use std::collections::BTreeMap;
use std::ops::Range;
use std::time::Instant;

/// Iterations of CG for the interior solves of `dirichlet_cg` (\[XGDF], section 4.1).
const INTERIOR_CG_ITERATIONS: usize = 5;

/// Non-zeros of the Cholesky factor of a subdomain matrix on `s` nodes with the square stencil
/// of reach m, under faer's AMD ordering: 3.8 m^1.5 s^1.25, at most the dense triangle. Fitted
/// at m = 4 to `factor_nonzeros_max` (43–47 M at s = 85 264, docs/steady.md) and to the weak
/// study's peak (7.8 GB per rank at s = 4 624); s^1.25 lies between nested dissection's
/// s log s and AMD's worse fill on grids, and m^1.5 comes from viewing the stencil as a coarse
/// grid of m × m blocks (not measured at other m).
fn factor_nonzeros(s: f64, m: f64) -> f64 {
    (3.8 * m.powf(1.5) * s.powf(1.25)).min(s * (s + 1.0) / 2.0)
}

/// Bytes a `feti` run holds at its peak over all ranks, from the case alone (nothing
/// allocated), besides the fields of n² values counted by the caller. Per subdomain of s
/// unknowns (s_I of them interior): A_n in CSC (16 bytes per non-zero: its pairs of nodes
/// within the stencil), the Cholesky factor of A_n and, for `dirichlet` (scaled or not), of A_II
/// (8 bytes per non-zero of L, `factor_nonzeros`), or A_II itself for `dirichlet_cg`; its work
/// vectors (48 bytes per node); its interface lists and dual vectors (72 bytes per interface
/// node). Per rank: the coarse GᵀG, factored on every rank (24 bytes per entry while it is built
/// and factored), and an assembly in flight per thread (48 bytes per entry: the triplets and
/// faer's sorting of them into a matrix).
pub(crate) fn memory_bytes(case: &Case) -> f64 {
    let (Some(p), Some(m)) = (case.subdomains, case.m) else {
        return 0.0;
    };
    // The widths take a few values: count the blocks of each (Λ width, interior width).
    let mut kinds = std::collections::BTreeMap::<(usize, usize), f64>::new();
    for width in super::decomposition::widths(case.n, p, m) {
        *kinds.entry(width).or_default() += 1.0;
    }
    // Pairs (i, j) of a block's nodes within m of each other, i = j included.
    let pairs = |w: usize| {
        let k = m.min(w.saturating_sub(1)) as f64;
        let w = w as f64;
        w + 2.0 * (k * w - k * (k + 1.0) / 2.0)
    };
    let reach = m as f64;
    let (mut bytes, mut largest_matrix) = (0.0, 0.0f64);
    for (&(wx, ix), &count_x) in &kinds {
        for (&(wy, iy), &count_y) in &kinds {
            let (s, interior) = ((wx * wy) as f64, (ix * iy) as f64);
            let matrix = pairs(wx) * pairs(wy);
            largest_matrix = largest_matrix.max(matrix);
            let preconditioner = match case.preconditioner() {
                FetiPreconditioner::None => 0.0,
                FetiPreconditioner::DirichletCg => 16.0 * pairs(ix) * pairs(iy),
                FetiPreconditioner::Dirichlet | FetiPreconditioner::DirichletScaled => {
                    8.0 * factor_nonzeros(interior, reach)
                }
            };
            let subdomain = 16.0 * matrix
                + 8.0 * factor_nonzeros(s, reach)
                + preconditioner
                + 48.0 * s
                + 72.0 * (s - interior);
            bytes += count_x * count_y * subdomain;
        }
    }
    let floating = (p as f64 - 2.0).max(0.0).powi(2);
    let per_rank = 24.0 * floating * floating + case.threads as f64 * 48.0 * largest_matrix;
    bytes + case.ranks as f64 * per_rank
}

/// How the Dirichlet preconditioner solves with A_II.
enum InteriorSolve {
    /// No preconditioner, or no interior node: S_n = A_BB.
    None,
    Cholesky(Cholesky),
    /// `dirichlet_cg`: a few CG iterations on A_II, from zero, with their buffers.
    Cg(SparseColMat<usize, f64>, Cg),
}

/// One subdomain's matrices, factors and work vectors.
struct Local<'d> {
    geometry: &'d Subdomain,
    a: SparseColMat<usize, f64>,
    load: Vec<f64>,
    /// A_n's factor, or the regularised A_n + ρ e_k e_kᵀ's when floating.
    factor: Cholesky,
    /// The Dirichlet preconditioner's interior I (nodes in no interface) and its solves.
    interior: Vec<usize>,
    interior_solve: InteriorSolve,
    /// Work vectors on Λ_n and on I.
    u: Vec<f64>,
    w: Vec<f64>,
    correction: Vec<f64>,
    interior_load: Vec<f64>,
    interior_solution: Vec<f64>,
    /// `dirichlet_scaled`: 1/(subdomains whose Λ holds the node), per node of Λ_n.
    multiplicity_scale: Option<Vec<f64>>,
    /// Seconds and counts of this subdomain's K_n and Q_n products.
    clock: ProductClock,
}

/// Time spent in one subdomain's products, on whichever thread ran them.
#[derive(Clone, Copy, Default)]
struct ProductClock {
    k_s: f64,
    k_products: usize,
    q_s: f64,
    q_products: usize,
}

impl<'d> Local<'d> {
    fn new(
        problem: &SteadyProblem,
        decomposition: &'d Decomposition,
        geometry: &'d Subdomain,
        preconditioner: FetiPreconditioner,
    ) -> Result<Self, String> {
        let (a, load) = assemble(problem, decomposition, geometry);
        let factor = if geometry.floating {
            let mut regularised = a.clone();
            pin_diagonal(&mut regularised, geometry.unknowns() / 2);
            Cholesky::new(regularised.as_ref())
        } else {
            Cholesky::new(a.as_ref())
        }?;
        let mut on_interface = vec![false; geometry.unknowns()];
        for interface in &geometry.interfaces {
            for &i in &interface.nodes {
                on_interface[i] = true;
            }
        }
        let interior: Vec<usize> = (0..geometry.unknowns())
            .filter(|&i| !on_interface[i])
            .collect();
        let interior_solve = match preconditioner {
            _ if interior.is_empty() => InteriorSolve::None,
            FetiPreconditioner::None => InteriorSolve::None,
            FetiPreconditioner::DirichletCg => {
                InteriorSolve::Cg(submatrix(&a, &interior), Cg::new(interior.len()))
            }
            FetiPreconditioner::Dirichlet | FetiPreconditioner::DirichletScaled => {
                InteriorSolve::Cholesky(Cholesky::new(submatrix(&a, &interior).as_ref())?)
            }
        };
        let multiplicity_scale =
            (preconditioner == FetiPreconditioner::DirichletScaled).then(|| {
                let [xs, ys] = &geometry.lambda;
                ys.clone()
                    .flat_map(|y| xs.clone().map(move |x| (x, y)))
                    .map(|(x, y)| 1.0 / decomposition.zeta_a([x, y], [x, y]) as f64)
                    .collect()
            });
        let (s, ni) = (geometry.unknowns(), interior.len());
        Ok(Local {
            geometry,
            a,
            load,
            factor,
            interior,
            interior_solve,
            u: vec![0.0; s],
            w: vec![0.0; s],
            correction: vec![0.0; s],
            interior_load: vec![0.0; ni],
            interior_solution: vec![0.0; ni],
            multiplicity_scale,
            clock: ProductClock::default(),
        })
    }

    /// x ← A_n^† x.
    fn pseudo_solve(factor: &mut Cholesky, floating: bool, x: &mut [f64]) {
        if floating {
            remove_mean(x);
        }
        factor.solve_in_place(x);
        if floating {
            remove_mean(x);
        }
    }

    /// u ← M_nᵀ λ_n (zero off the interfaces).
    fn scatter(geometry: &Subdomain, lambda: &[f64], u: &mut [f64]) {
        u.fill(0.0);
        for interface in &geometry.interfaces {
            let values = &lambda[interface.offset..interface.offset + interface.nodes.len()];
            for (&i, &l) in interface.nodes.iter().zip(values) {
                u[i] += interface.sign * l;
            }
        }
    }

    /// out ← M_n u.
    fn gather(geometry: &Subdomain, u: &[f64], out: &mut [f64]) {
        for interface in &geometry.interfaces {
            let values = &mut out[interface.offset..interface.offset + interface.nodes.len()];
            for (&i, o) in interface.nodes.iter().zip(values) {
                *o = interface.sign * u[i];
            }
        }
    }

    /// out ← K_n λ_n = M_n A_n^† M_nᵀ λ_n.
    fn apply_k(&mut self, lambda: &[f64], out: &mut [f64]) {
        let started = Instant::now();
        Self::scatter(self.geometry, lambda, &mut self.u);
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        Self::gather(self.geometry, &self.u, out);
        self.clock.k_s += started.elapsed().as_secs_f64();
        self.clock.k_products += 1;
    }

    /// out ← M_n A_n^† f_n.
    fn dual_load(&mut self, out: &mut [f64]) {
        self.u.copy_from_slice(&self.load);
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        Self::gather(self.geometry, &self.u, out);
    }

    /// out ← Q_n r_n = M_n S_n M_nᵀ r_n (eq. 33), S_n = A_BB − A_BI A_II⁻¹ A_IB applied as
    /// A_n v − A_n (A_II⁻¹ (A_n v)_I) on B, for v = M_nᵀ r_n (zero on I); with multiplicity
    /// scaling, M_n D_n S_n D_n M_nᵀ r_n.
    fn apply_dirichlet(&mut self, residual: &[f64], out: &mut [f64]) {
        let started = Instant::now();
        Self::scatter(self.geometry, residual, &mut self.u);
        if let Some(scale) = &self.multiplicity_scale {
            self.u.iter_mut().zip(scale).for_each(|(u, d)| *u *= d);
        }
        symmetric_product(self.a.as_ref(), &self.u, &mut self.w);
        let y = &mut self.interior_solution;
        let solved = match &mut self.interior_solve {
            InteriorSolve::None => false,
            InteriorSolve::Cholesky(factor) => {
                for (yi, &i) in y.iter_mut().zip(&self.interior) {
                    *yi = self.w[i];
                }
                factor.solve_in_place(y);
                true
            }
            InteriorSolve::Cg(a_ii, cg) => {
                for (b, &i) in self.interior_load.iter_mut().zip(&self.interior) {
                    *b = self.w[i];
                }
                let system = &mut Closures {
                    len: y.len(),
                    precondition: NoPreconditioner,
                    apply: |p: &[f64], ap: &mut [f64]| symmetric_product(a_ii.as_ref(), p, ap),
                    dot: dot_serial,
                };
                // A fixed number of iterations: rtol 0 is never reached.
                let params = CgParams {
                    start: Start::Zero,
                    rtol: 0.0,
                    norm: Norm::Residual,
                    max_iterations: INTERIOR_CG_ITERATIONS,
                    pool: None,
                };
                cg.solve(system, &self.interior_load, y, &params);
                true
            }
        };
        if solved {
            self.u.fill(0.0);
            for (&yi, &i) in y.iter().zip(&self.interior) {
                self.u[i] = yi;
            }
            symmetric_product(self.a.as_ref(), &self.u, &mut self.correction);
            for (w, c) in self.w.iter_mut().zip(&self.correction) {
                *w -= c;
            }
        }
        if let Some(scale) = &self.multiplicity_scale {
            self.w.iter_mut().zip(scale).for_each(|(w, d)| *w *= d);
        }
        Self::gather(self.geometry, &self.w, out);
        self.clock.q_s += started.elapsed().as_secs_f64();
        self.clock.q_products += 1;
    }

    /// u_n = A_n^†(f_n − M_nᵀ λ_n) + α_n 1.
    fn solution(&mut self, lambda: &[f64], alpha: f64) -> Vec<f64> {
        Self::scatter(self.geometry, lambda, &mut self.u);
        for (u, f) in self.u.iter_mut().zip(&self.load) {
            *u = f - *u;
        }
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        self.u.iter().map(|u| u + alpha).collect()
    }
}

/// A_kk += A_kk: makes a floating A_n definite without changing its pattern.
fn pin_diagonal(a: &mut SparseColMat<usize, f64>, k: usize) {
    let range = a.col_ptr()[k]..a.col_ptr()[k + 1];
    let at = range
        .clone()
        .find(|&e| a.row_idx()[e] == k)
        .expect("A has its diagonal");
    a.val_mut()[at] *= 2.0;
}

fn remove_mean(x: &mut [f64]) {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    x.iter_mut().for_each(|v| *v -= mean);
}

/// A restricted to the rows and columns `keep` (sorted).
fn submatrix(a: &SparseColMat<usize, f64>, keep: &[usize]) -> SparseColMat<usize, f64> {
    let mut place = vec![usize::MAX; a.nrows()];
    for (new, &old) in keep.iter().enumerate() {
        place[old] = new;
    }
    let mut entries = Vec::new();
    for (new_col, &col) in keep.iter().enumerate() {
        let range = a.col_ptr()[col]..a.col_ptr()[col + 1];
        for e in range {
            let row = place[a.row_idx()[e]];
            if row != usize::MAX {
                entries.push(faer::sparse::Triplet::new(row, new_col, a.val()[e]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(keep.len(), keep.len(), &entries)
        .expect("entries lie inside the submatrix")
}

/// Where each owned subdomain's multipliers sit in the rank's dual vectors, and who adds what.
struct DualLayout {
    offsets: Vec<usize>,
    /// Interfaces between two owned subdomains: (start in one, start in the other, length).
    local_pairs: Vec<(usize, usize, usize)>,
    /// Per other rank: its number and the blocks (start, length) it shares, in the order both
    /// sides agree on (by the pair of subdomain numbers).
    peers: Vec<usize>,
    peer_blocks: Vec<Vec<(usize, usize)>>,
}

/// A block of multipliers a peer rank also holds: the subdomain pair of its interface, and its
/// start and length in this rank's vector.
type RemotePair = ((usize, usize), usize, usize);

impl DualLayout {
    fn new(decomposition: &Decomposition, owned: &[usize], rank: usize, ranks: usize) -> Self {
        let mut offsets = vec![0];
        for &n in owned {
            offsets.push(offsets.last().unwrap() + decomposition.subdomains[n].multipliers());
        }
        let start_of = |n: usize| offsets[n - owned[0]];
        let mut local_pairs = Vec::new();
        let mut remote: BTreeMap<usize, Vec<RemotePair>> = BTreeMap::new();
        for &n in owned {
            for interface in &decomposition.subdomains[n].interfaces {
                let start = start_of(n) + interface.offset;
                let len = interface.nodes.len();
                let other = interface.other;
                let owner = decomposition.owner(other, ranks);
                if owner == rank {
                    if n < other {
                        let back = decomposition.subdomains[other]
                            .interfaces
                            .iter()
                            .find(|i| i.other == n)
                            .expect("interfaces come in pairs");
                        local_pairs.push((start, start_of(other) + back.offset, len));
                    }
                } else {
                    let key = (n.min(other), n.max(other));
                    remote.entry(owner).or_default().push((key, start, len));
                }
            }
        }
        let mut peers = Vec::new();
        let mut peer_blocks = Vec::new();
        for (peer, mut blocks) in remote {
            blocks.sort_unstable_by_key(|&(key, _, _)| key);
            peers.push(peer);
            peer_blocks.push(blocks.into_iter().map(|(_, s, l)| (s, l)).collect());
        }
        DualLayout {
            offsets,
            local_pairs,
            peers,
            peer_blocks,
        }
    }

    fn len(&self) -> usize {
        *self.offsets.last().unwrap()
    }

    /// Each owned subdomain's part of a dual vector.
    fn split<'v>(&self, x: &'v mut [f64]) -> Vec<&'v mut [f64]> {
        let mut parts = Vec::with_capacity(self.offsets.len() - 1);
        let mut rest = x;
        for window in self.offsets.windows(2) {
            let (part, tail) = rest.split_at_mut(window[1] - window[0]);
            parts.push(part);
            rest = tail;
        }
        parts
    }

    /// x ← the sum of both subdomains' contributions on every interface (the R^D exchange).
    fn interface_sum(&self, exchange: &dyn Exchange, x: &mut [f64]) {
        for &(a, b, len) in &self.local_pairs {
            for i in 0..len {
                let sum = x[a + i] + x[b + i];
                x[a + i] = sum;
                x[b + i] = sum;
            }
        }
        if self.peers.is_empty() {
            return;
        }
        let send: Vec<Vec<f64>> = self
            .peer_blocks
            .iter()
            .map(|blocks| {
                blocks
                    .iter()
                    .flat_map(|&(s, l)| x[s..s + l].iter().copied())
                    .collect()
            })
            .collect();
        let mut receive: Vec<Vec<f64>> = send.iter().map(|b| vec![0.0; b.len()]).collect();
        exchange.swap(&self.peers, &send, &mut receive);
        for (blocks, received) in self.peer_blocks.iter().zip(&receive) {
            let mut at = 0;
            for &(s, l) in blocks {
                for i in 0..l {
                    x[s + i] += received[at + i];
                }
                at += l;
            }
        }
    }
}

/// The rank's share of the FETI system and the coarse problem.
struct Feti<'d> {
    decomposition: &'d Decomposition,
    owned: Vec<usize>,
    locals: Vec<Local<'d>>,
    layout: DualLayout,
    /// (GᵀG)'s Cholesky factor (None when no subdomain floats).
    coarse: Option<faer::linalg::solvers::Llt<f64>>,
    preconditioner: FetiPreconditioner,
    pool: &'d ThreadPool,
    /// This rank's wall seconds per phase since the clocks were last reset.
    phases: PhaseSeconds,
}

#[derive(Default)]
struct PhaseSeconds {
    subdomain_solves: f64,
    preconditioner: f64,
    interface_sum: f64,
    coarse: f64,
}

impl<'d> Feti<'d> {
    /// a · b over the multipliers, each once (on its lower-numbered subdomain), summed per
    /// subdomain and then in subdomain order.
    fn dot(&self, exchange: &dyn Exchange, a: &[f64], b: &[f64]) -> f64 {
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
    fn apply_k(&mut self, exchange: &dyn Exchange, x: &[f64], out: &mut [f64]) {
        let products_s =
            self.interface_assembled(exchange, out, |local, own, out| local.apply_k(&x[own], out));
        self.phases.subdomain_solves += products_s;
    }

    /// out ← Q r.
    fn apply_preconditioner(&mut self, exchange: &dyn Exchange, r: &[f64], out: &mut [f64]) {
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
    fn interface_assembled(
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
    fn g_transpose(&self, exchange: &dyn Exchange, x: &[f64]) -> Vec<f64> {
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
    fn coarse_solve(&self, v: &mut [f64]) {
        if let Some(coarse) = &self.coarse {
            let n = v.len();
            coarse.solve_in_place(MatMut::from_column_major_slice_mut(v, n, 1));
        }
    }

    /// x ← x + G̃ β: on n's multipliers, sign · (β_n − β_other) over the floating ones.
    fn add_g(&self, beta: &[f64], x: &mut [f64]) {
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
    fn project(&mut self, exchange: &dyn Exchange, x: &mut [f64]) {
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
    fn reset_clocks(&mut self) {
        self.phases = PhaseSeconds::default();
        self.locals
            .iter_mut()
            .for_each(|l| l.clock = ProductClock::default());
    }

    /// Seconds per iteration of each phase over `iterations` taking `loop_s` (max over ranks),
    /// and the mean product times of one subdomain (over every rank's subdomains).
    fn phases(&self, exchange: &dyn Exchange, iterations: usize, loop_s: f64) -> FetiPhases {
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
struct DualSolve {
    lambda: Vec<f64>,
    iterations: usize,
    dual_residual: f64,
    phases: FetiPhases,
}

/// The interface problem P₀ K λ = P₀ e as CG sees it: A = P₀ K, M = P₀ Q (\[XGDF]'s
/// Algorithm 1), the inner product over the multipliers. The phases are timed from the first
/// iteration's product on, not over the start-up.
struct DualSystem<'f, 'd> {
    feti: &'f mut Feti<'d>,
    exchange: &'f dyn Exchange,
    iterations_started: Option<Instant>,
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
fn projected_cg(
    feti: &mut Feti,
    exchange: &dyn Exchange,
    e: &[f64],
    g: &[f64],
    rtol: f64,
    max_iterations: usize,
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
    let convergence = Cg::new(len).solve(&mut system, e, &mut lambda, &params);
    let started = system.iterations_started;
    if started.is_none() {
        // Solved before any iteration: no phase is timed.
        feti.reset_clocks();
    }
    let loop_s = started.map_or(0.0, |started| started.elapsed().as_secs_f64());
    let phases = feti.phases(exchange, convergence.iterations, loop_s);
    DualSolve {
        lambda,
        iterations: convergence.iterations,
        dual_residual: convergence.relative_residual,
        phases,
    }
}

/// Runs a `feti` case on the ranks of `exchange` (one process: `exchange::Serial`). Rank 0
/// returns the outcome; the others None.
pub fn run_on(
    case: &ValidCase,
    problem: &SteadyProblem,
    exchange: &dyn Exchange,
    pool: &ThreadPool,
    started: Instant,
    gather_field: bool,
) -> Result<Option<Outcome>, CaseError> {
    let p = case.subdomains.expect("validated: feti gives p");
    let grid = problem.grid();
    let decomposition = Decomposition::new(grid.n, p, problem.stencil.horizon.m);
    let (rank, ranks) = (exchange.rank(), exchange.ranks());
    let owned: Vec<usize> = (0..p * p)
        .filter(|&n| decomposition.owner(n, ranks) == rank)
        .collect();
    let preconditioner = case.preconditioner();
    let locals: Vec<Local> = pool
        .install(|| {
            owned
                .par_iter()
                .map(|&n| {
                    Local::new(
                        problem,
                        &decomposition,
                        &decomposition.subdomains[n],
                        preconditioner,
                    )
                })
                .collect::<Result<_, _>>()
        })
        .map_err(|e| {
            CaseError::new(
                "subdomains",
                format!("a subdomain factorisation failed ({e}); report this case"),
            )
        })?;
    let nf = decomposition.floating.len();
    let coarse = decomposition.coarse_factor().transpose().map_err(|e| {
        CaseError::new(
            "subdomains",
            format!("the coarse problem GᵀG is singular ({e:?}); report this case"),
        )
    })?;
    let layout = DualLayout::new(&decomposition, &owned, rank, ranks);
    let mut feti = Feti {
        decomposition: &decomposition,
        owned,
        locals,
        layout,
        coarse,
        preconditioner,
        pool,
        phases: PhaseSeconds::default(),
    };
    // e = M A^† f and g = Zᵀ f.
    let mut e = vec![0.0; feti.layout.len()];
    feti.interface_assembled(exchange, &mut e, |local, _, out| local.dual_load(out));
    let mut g = vec![0.0; nf];
    for local in &feti.locals {
        if let Some(a) = local.geometry.coarse {
            g[a] = local.load.iter().sum();
        }
    }
    exchange.all_sum(&mut g);
    let setup_s = exchange.max(started.elapsed().as_secs_f64());
    let comm_before = exchange.seconds();

    let solve_started = Instant::now();
    let dual = projected_cg(
        &mut feti,
        exchange,
        &e,
        &g,
        problem.rtol,
        case.max_iterations(),
    );
    // α from Gα = Kλ − e, then u_n = A_n^†(f_n − M_nᵀλ_n) + Z_n α_n.
    let mut w = vec![0.0; feti.layout.len()];
    feti.apply_k(exchange, &dual.lambda, &mut w);
    w.iter_mut().zip(&e).for_each(|(w, e)| *w -= e);
    let mut alpha = feti.g_transpose(exchange, &w);
    feti.coarse_solve(&mut alpha);
    let offsets = &feti.layout.offsets;
    let locals = &mut feti.locals;
    let pieces: Vec<(usize, Vec<f64>)> = pool.install(|| {
        locals
            .par_iter_mut()
            .enumerate()
            .map(|(k, local)| {
                let a = local.geometry.coarse.map_or(0.0, |c| alpha[c]);
                (
                    local.geometry.index,
                    local.solution(&dual.lambda[offsets[k]..offsets[k + 1]], a),
                )
            })
            .collect()
    });
    let solve_s = exchange.max(solve_started.elapsed().as_secs_f64());
    let comm_s = exchange.max(exchange.seconds() - comm_before);

    // Node x's value comes from the subdomain whose block Ω̃_n holds it (None: another rank's).
    let mut piece_of: Vec<Option<&[f64]>> = vec![None; p * p];
    for (n, u) in &pieces {
        piece_of[*n] = Some(u);
    }
    let value_at = |i: usize| -> Option<f64> {
        let (x, y) = (i % grid.n, i / grid.n);
        let index = decomposition.block_of(y) * p + decomposition.block_of(x);
        Some(piece_of[index]?[decomposition.subdomains[index].local(x as i64, y as i64)])
    };
    // One process holds the field; over ranks it is measured where it lies, and assembled (on
    // every rank) only when asked for.
    let (summary, field, peak_memory_bytes) = if ranks == 1 {
        let field: Vec<f64> = (0..grid.nodes())
            .map(|i| value_at(i).expect("one process holds every subdomain"))
            .collect();
        let summary = problem.summarise(&field);
        (summary, field, crate::output::record::peak_memory_bytes())
    } else {
        let summary = measured_over_ranks(problem, &decomposition, exchange, pool, &value_at);
        let peak = crate::parallel::exchange::peak_memory_over_ranks(exchange);
        let field = gather_field.then(|| {
            let mut field: Vec<f64> = (0..grid.nodes())
                .map(|i| value_at(i).unwrap_or(0.0))
                .collect();
            exchange.all_sum(&mut field);
            field
        });
        (summary, field.unwrap_or_default(), peak)
    };
    // Multiplier values each exchange brings in, over all ranks.
    let mut received = [feti
        .layout
        .peer_blocks
        .iter()
        .flatten()
        .map(|&(_, len)| len)
        .sum::<usize>() as f64];
    exchange.all_sum(&mut received);
    let factor_nonzeros = exchange.max(
        feti.locals
            .iter()
            .map(|l| l.factor.nonzeros())
            .max()
            .unwrap_or(0) as f64,
    );
    if rank != 0 {
        return Ok(None);
    }
    let solve = SteadySolve {
        iterations: Some(dual.iterations),
        relative_residual: None,
        dual_residual: Some(dual.dual_residual),
        subdomains: Some(p * p),
        floating_subdomains: Some(nf),
        multipliers: Some(decomposition.multipliers()),
        factor_nonzeros_max: Some(factor_nonzeros as usize),
        feti_phases: Some(dual.phases),
    };
    let mut distribution = Distribution::serial(case);
    distribution.ranks = ranks;
    distribution.px = None;
    distribution.py = None;
    distribution.comm_s = comm_s;
    distribution.halo_nodes = received[0] as usize;
    distribution.halo_bytes = received[0] as usize * std::mem::size_of::<f64>();
    let mut outcome = outcome(
        case,
        problem,
        None,
        Timings { setup_s, solve_s },
        Stop {
            reached_tolerance: dual.dual_residual <= problem.rtol,
            residual: dual.dual_residual,
        },
        solve,
        distribution,
        summary,
        field,
    );
    outcome.record.peak_memory_bytes = peak_memory_bytes;
    Ok(Some(outcome))
}

/// The solution's numbers for the record, over ranks: each rank measures the nodes of its
/// subdomains' blocks (`value_at` gives them, None elsewhere) with the distributed operator, and
/// the sums and maxima are reduced; no rank holds the whole field.
fn measured_over_ranks(
    problem: &SteadyProblem,
    decomposition: &Decomposition,
    exchange: &dyn Exchange,
    pool: &ThreadPool,
    value_at: &(dyn Fn(usize) -> Option<f64> + Sync),
) -> Summary {
    let (stencil, grid) = (&problem.stencil, problem.grid());
    let (rank, ranks) = (exchange.rank(), exchange.ranks());
    let p = decomposition.p;
    // Node (x, y) belongs to the rank of its block's subdomain; a rank looks up its window only.
    let owner = |x: usize, y: usize| {
        let index = decomposition.block_of(y) * p + decomposition.block_of(x);
        decomposition.owner(index, ranks) as u32
    };
    let mine: Vec<usize> = (0..p * p)
        .filter(|&k| decomposition.owner(k, ranks) == rank)
        .collect();
    let span = |k: usize| (k * grid.n / p, (k + 1) * grid.n / p);
    let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
    for &k in &mine {
        let ((x0, x1), (y0, y1)) = (span(k % p), span(k / p));
        lo = [lo[0].min(x0), lo[1].min(y0)];
        hi = [hi[0].max(x1), hi[1].max(y1)];
    }
    let window = Window::around(&grid, lo, hi, stencil.reach());
    let owners: Vec<u32> = (window.y0..window.y0 + window.ny)
        .flat_map(|y| (window.x0..window.x0 + window.nx).map(move |x| owner(x, y)))
        .collect();
    let mut counts = vec![0; ranks];
    for k in 0..p * p {
        let width = |k: usize| (k + 1) * grid.n / p - k * grid.n / p;
        counts[decomposition.owner(k, ranks)] += width(k % p) * width(k / p);
    }
    let ownership = Ownership::of_window(grid, ranks, window, owners, counts);
    let share = RankShare::new(&ownership, stencil, rank);
    let ranks_of = Ranks::on_pool(exchange, pool);
    let operator = DistributedOperator::new(stencil, &share, ranks_of, Backend::Stencil);
    let nodes = share.node_indices(grid.n);
    let u: Vec<f64> = nodes
        .iter()
        .map(|&i| value_at(i).expect("the rank's own node"))
        .collect();
    let mut lu = vec![0.0; u.len()];
    operator.apply_once(&u, &mut lu);
    let b: Vec<f64> = pool.install(|| nodes.par_iter().map(|&i| problem.load(i)).collect());
    Summary::over_ranks(&grid, &nodes, (&u, &b, &lu), exchange, pool)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At the case (n = 512, m = 4, p = 2: 1974 MiB measured at the peak, where the
    /// fields alone are 12 MiB) the estimate is within a factor 2; and the fill model gives the
    /// factors docs/steady.md measured at L/p = 288.
    #[test]
    fn the_memory_estimate_counts_the_subdomain_factors() {
        let case = ValidCase::from_json(serde_json::json!({
            "method": "feti", "dim": 2, "n": 512, "m": 4, "kernel": "inverse_distance",
            "subdomains": 2,
        }))
        .unwrap();
        let mib = memory_bytes(&case) / (1u64 << 20) as f64;
        assert!((1974.0 / 2.0..1974.0 * 2.0).contains(&mib), "{mib} MiB");
        let nonzeros = factor_nonzeros(85_264.0, 4.0);
        assert!((40e6..50e6).contains(&nonzeros), "{nonzeros:e}");
        // Never more than the dense triangle.
        assert_eq!(factor_nonzeros(10.0, 8.0), 55.0);
    }

    /// On a floating subdomain, A_n^† is the Moore–Penrose pseudo-inverse: A A^† b = P b (P removes
    /// the mean, the projection on range A_n = 1⊥), A^† b ⊥ 1, and A^† is symmetric.
    #[test]
    fn the_floating_solve_is_the_moore_penrose_pseudo_inverse() {
        let case = ValidCase::from_json(serde_json::json!({
            "method": "feti", "dim": 2, "n": 36, "m": 4, "kernel": "inverse_distance",
            "subdomains": 3,
        }))
        .unwrap();
        let problem = SteadyProblem::new(&case);
        let decomposition = Decomposition::new(36, 3, 4);
        let geometry = &decomposition.subdomains[4];
        assert!(geometry.floating);
        let mut local = Local::new(
            &problem,
            &decomposition,
            geometry,
            FetiPreconditioner::Dirichlet,
        )
        .unwrap();
        let s = geometry.unknowns();
        let b: Vec<f64> = (0..s).map(|i| (i as f64 * 0.37).sin() + 0.3).collect();
        let c: Vec<f64> = (0..s).map(|i| (i as f64 * 0.11).cos()).collect();
        let pseudo = |local: &mut Local, v: &[f64]| {
            let mut x = v.to_vec();
            Local::pseudo_solve(&mut local.factor, true, &mut x);
            x
        };
        let x = pseudo(&mut local, &b);
        let mut ax = vec![0.0; s];
        symmetric_product(local.a.as_ref(), &x, &mut ax);
        let mean = b.iter().sum::<f64>() / s as f64;
        for (axi, bi) in ax.iter().zip(&b) {
            assert!(
                (axi - (bi - mean)).abs() < 1e-10,
                "A A† b ≠ P b: {axi} vs {}",
                bi - mean
            );
        }
        assert!(x.iter().sum::<f64>().abs() < 1e-10 * s as f64);
        let y = pseudo(&mut local, &c);
        let (cx, by): (f64, f64) = (
            c.iter().zip(&x).map(|(p, q)| p * q).sum(),
            b.iter().zip(&y).map(|(p, q)| p * q).sum(),
        );
        assert!(
            (cx - by).abs() < 1e-9 * cx.abs().max(1.0),
            "cᵀA†b {cx} vs bᵀA†c {by}"
        );
    }
}
