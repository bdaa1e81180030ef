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

mod dual;
mod local;
mod memory;
mod pcpg;

pub(crate) use memory::memory_bytes;

use dual::DualLayout;
use local::Local;
use pcpg::{projected_cg, Feti, PhaseSeconds};

use crate::case::Backend;
use crate::case::CaseError;
use crate::case::ValidCase;
use crate::discretization::grid::Window;
use crate::methods::steady::decomposition::Decomposition;
use crate::methods::steady::problem::{outcome, SteadyProblem, Summary, Termination, Timings};
use crate::methods::steady::resume::SolveCheckpoints;
use crate::operator::LinearOperator;
use crate::output::outcome::Outcome;
use crate::output::record::{Distribution, SteadySolve};
use crate::parallel::exchange::Exchange;
use crate::parallel::exchange::Ranks;
use crate::parallel::operator::DistributedOperator;
use crate::parallel::partition::Ownership;
use crate::parallel::share::RankShare;
use rayon::prelude::*;
use rayon::ThreadPool;
use std::time::Instant;

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
    let mut feti = set_up(case, problem, &decomposition, exchange, pool)?;
    let nf = decomposition.floating.len();
    let (e, g) = loads(&mut feti, exchange);
    let setup_s = exchange.max(started.elapsed().as_secs_f64());
    let comm_before = exchange.seconds();

    let solving = crate::output::usage::Solving::starts();
    let mut checkpoints = SolveCheckpoints::take(exchange, problem.rtol, case.max_iterations());
    let dual = projected_cg(
        &mut feti,
        exchange,
        &e,
        &g,
        problem.rtol,
        case.max_iterations(),
        &mut checkpoints,
    );
    let pieces = primal(&mut feti, exchange, &dual.lambda, &e);
    let solve_s = checkpoints.resumed(exchange.max(solving.ends()));
    let comm_s = exchange.max(exchange.seconds() - comm_before + checkpoints.earlier_comm_s());
    drop(checkpoints);

    let (summary, field, peak_memory_bytes) = solution(
        problem,
        &decomposition,
        exchange,
        pool,
        &pieces,
        gather_field,
    );
    let (received, factor_nonzeros) = exchanged_and_factored(&feti, exchange);
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
    distribution.halo_nodes = received as usize;
    distribution.halo_bytes = received as usize * std::mem::size_of::<f64>();
    let mut outcome = outcome(
        case,
        problem,
        None,
        Timings {
            setup_s,
            solve: solve_s,
        },
        Termination {
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

/// The right-hand sides of the dual problem: e = M A^† f and g = Zᵀ f.
fn loads(feti: &mut Feti, exchange: &dyn Exchange) -> (Vec<f64>, Vec<f64>) {
    let mut e = vec![0.0; feti.layout.len()];
    feti.interface_assembled(exchange, &mut e, |local, _, out| local.dual_load(out));
    let mut g = vec![0.0; feti.decomposition.floating.len()];
    for local in &feti.locals {
        if let Some(a) = local.geometry.coarse {
            g[a] = local.load.iter().sum();
        }
    }
    exchange.all_sum(&mut g);
    (e, g)
}

/// The multiplier values each exchange brings in, over all ranks, and the most nonzeros of a
/// subdomain's factor.
fn exchanged_and_factored(feti: &Feti, exchange: &dyn Exchange) -> (f64, f64) {
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
    (received[0], factor_nonzeros)
}

/// This rank's part of the FETI system: its subdomains factorised, the coarse problem GᵀG's
/// factor and the layout of the multipliers.
fn set_up<'d>(
    case: &ValidCase,
    problem: &'d SteadyProblem,
    decomposition: &'d Decomposition,
    exchange: &dyn Exchange,
    pool: &'d ThreadPool,
) -> Result<Feti<'d>, CaseError> {
    let p = case.subdomains.expect("validated: feti gives p");
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
                        decomposition,
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
    let coarse = decomposition.coarse_factor().transpose().map_err(|e| {
        CaseError::new(
            "subdomains",
            format!("the coarse problem GᵀG is singular ({e:?}); report this case"),
        )
    })?;
    let layout = DualLayout::new(decomposition, &owned, rank, ranks);
    Ok(Feti {
        decomposition,
        owned,
        locals,
        layout,
        coarse,
        preconditioner,
        pool,
        phases: PhaseSeconds::default(),
    })
}

/// The primal solution from the multipliers λ: α from Gα = Kλ − e, then
/// u_n = A_n^†(f_n − M_nᵀλ_n) + Z_n α_n on each of this rank's subdomains, by its index.
fn primal(
    feti: &mut Feti,
    exchange: &dyn Exchange,
    lambda: &[f64],
    e: &[f64],
) -> Vec<(usize, Vec<f64>)> {
    let pool = feti.pool;
    let mut w = vec![0.0; feti.layout.len()];
    feti.apply_k(exchange, lambda, &mut w);
    w.iter_mut().zip(e).for_each(|(w, e)| *w -= e);
    let mut alpha = feti.g_transpose(exchange, &w);
    feti.coarse_solve(&mut alpha);
    let offsets = &feti.layout.offsets;
    let locals = &mut feti.locals;
    pool.install(|| {
        locals
            .par_iter_mut()
            .enumerate()
            .map(|(k, local)| {
                let a = local.geometry.coarse.map_or(0.0, |c| alpha[c]);
                (
                    local.geometry.index,
                    local.solution(&lambda[offsets[k]..offsets[k + 1]], a),
                )
            })
            .collect()
    })
}

/// The solution's numbers for the record, its field (one process; over ranks only when
/// `gather_field`) and the peak memory, from this rank's `pieces`.
fn solution(
    problem: &SteadyProblem,
    decomposition: &Decomposition,
    exchange: &dyn Exchange,
    pool: &ThreadPool,
    pieces: &[(usize, Vec<f64>)],
    gather_field: bool,
) -> (Summary, Vec<f64>, Option<u64>) {
    let (grid, p, ranks) = (problem.grid(), decomposition.p, exchange.ranks());
    // Node x's value comes from the subdomain whose block Ω̃_n holds it (None: another rank's).
    let mut piece_of: Vec<Option<&[f64]>> = vec![None; p * p];
    for (n, u) in pieces {
        piece_of[*n] = Some(u);
    }
    let value_at = |i: usize| -> Option<f64> {
        let (x, y) = (i % grid.n, i / grid.n);
        let index = decomposition.block_of(y) * p + decomposition.block_of(x);
        Some(piece_of[index]?[decomposition.subdomains[index].local(x as i64, y as i64)])
    };
    // One process holds the field; over ranks it is measured where it lies, and assembled (on
    // every rank) only when asked for.
    if ranks == 1 {
        let field: Vec<f64> = (0..grid.nodes())
            .map(|i| value_at(i).expect("one process holds every subdomain"))
            .collect();
        let summary = problem.summarize(&field);
        (summary, field, crate::output::record::peak_memory_bytes())
    } else {
        let summary = measured_over_ranks(problem, decomposition, exchange, pool, &value_at);
        let peak = crate::parallel::exchange::peak_memory_over_ranks(exchange);
        let field = gather_field.then(|| {
            let mut field: Vec<f64> = (0..grid.nodes())
                .map(|i| value_at(i).unwrap_or(0.0))
                .collect();
            exchange.all_sum(&mut field);
            field
        });
        (summary, field.unwrap_or_default(), peak)
    }
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
    use super::memory::factor_nonzeros;
    use super::*;
    use crate::case::FetiPreconditioner;
    use crate::linalg::cholesky::symmetric_product;

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
