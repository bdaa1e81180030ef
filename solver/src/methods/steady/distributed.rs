//! The steady methods on the ranks of an MPI communicator.
//!
//! `steady_cg` distributes the rows of A = −L_h by the case's partition (block by default) and
//! applies A with the time-dependent solver's `DistributedOperator` (interior rows computed while
//! the ghosts travel, the serial stencil kernel); inner products are reduced over ranks. `feti` runs the same code as on one process,
//! with `exchange::Mpi`. MPI is called from the main thread only; computing runs on the pool.

use super::feti;
use super::problem::negate_into;
use super::problem::{outcome, SteadyProblem, Summary, Termination, Timings};
use super::resume::SolveCheckpoints;
use crate::case::ValidCase;
use crate::case::{CaseError, Method};
use crate::linalg::cg::{self, Cg};
use crate::operator::{self, LinearOperator};
use crate::output::outcome::Outcome;
use crate::output::record::SteadySolve;
use crate::parallel::exchange::peak_memory_over_ranks;
use crate::parallel::exchange::{Exchange, Ranks};
use crate::parallel::operator::DistributedOperator;
use crate::parallel::share::RankShare;
use crate::parallel::world::{distribution, gather, ownership, Mpi};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::prelude::*;
use std::time::Instant;

/// Runs a steady case on `world` (its size already checked against `case.ranks`).
pub fn run(
    world: &SimpleCommunicator,
    case: &ValidCase,
    gather_field: bool,
) -> Result<Option<Outcome>, CaseError> {
    let started = Instant::now();
    let pool = crate::threads::pool(case.threads)?;
    let problem = pool.install(|| SteadyProblem::new(case));
    if case.method == Method::Feti {
        return feti::run_on(
            case,
            &problem,
            &Mpi::new(world),
            &pool,
            started,
            gather_field,
        );
    }
    let stencil = &problem.stencil;
    let grid = stencil.grid;
    let ownership = ownership(world, case, stencil)?;
    let rank = world.rank() as usize;
    let share = RankShare::new(&ownership, stencil, rank);
    let partition = ownership.summary();
    drop(ownership);
    let nodes = share.node_indices(grid.n);
    let b: Vec<f64> = pool.install(|| nodes.par_iter().map(|&i| problem.load(i)).collect());
    let mpi = Mpi::new(world);
    let ranks = Ranks::mpi(&mpi, &pool);
    let backend = pool.install(|| operator::resolve(case.backend, stencil));
    let operator = DistributedOperator::new(stencil, &share, ranks, backend);
    let mut workspace = operator.workspace();
    let mut lp = vec![0.0; b.len()];
    let setup_s = started.elapsed().as_secs_f64();

    let solving = crate::output::usage::Solving::starts();
    let comm_before = mpi.seconds();
    let mut u = vec![0.0; b.len()];
    let system = &mut cg::Closures {
        len: b.len(),
        precondition: cg::NoPreconditioner,
        apply: |p: &[f64], ap: &mut [f64]| {
            operator.apply(p, &mut lp, &mut workspace);
            pool.install(|| negate_into(&lp, ap));
        },
        dot: |x: &[f64], y: &[f64]| mpi.sum(pool.install(|| cg::dot(x, y))),
    };
    let params = problem.cg_params(Some(&pool));
    let mut checkpoints = SolveCheckpoints::take(&mpi, params.rtol, params.max_iterations);
    let convergence =
        Cg::new(b.len()).solve_checkpointed(system, &b, &mut u, &params, &mut checkpoints);
    let segment_s = solving.ends();
    let comm_s = mpi.seconds() - comm_before + checkpoints.earlier_comm_s();

    // Measured where the values are, each rank on its nodes, then summed over ranks: no rank
    // holds the whole field unless it was asked for.
    operator.apply(&u, &mut lp, &mut workspace);
    let summary = Summary::over_ranks(&grid, &nodes, (&u, &b, &lp), &mpi, &pool);
    let field = gather_field
        .then(|| gather(world, &nodes, &u, grid.nodes()))
        .flatten();
    let distribution = distribution(&mpi, case, &partition, &share, comm_s);
    // Reduced after `distribution` has counted the traffic, as reductions that only report.
    let timings = Timings {
        setup_s: mpi.max(setup_s),
        solve: checkpoints.resumed(mpi.max(segment_s)),
    };
    drop(checkpoints);
    let peak_memory_bytes = peak_memory_over_ranks(&mpi);
    if rank != 0 {
        return Ok(None);
    }
    Ok(Some(pool.install(|| {
        let mut outcome = outcome(
            case,
            &problem,
            Some(backend),
            timings,
            Termination::of_cg(&convergence),
            SteadySolve::cg(convergence.iterations),
            distribution,
            summary,
            field.unwrap_or_default(),
        );
        outcome.record.peak_memory_bytes = peak_memory_bytes;
        outcome
    })))
}
