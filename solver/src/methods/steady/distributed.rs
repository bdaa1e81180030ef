//! The steady methods on the ranks of an MPI communicator.
//!
//! `steady_cg` distributes the rows of A = −L_h by the case's partition (block by default) and
//! applies A with the time-dependent solver's machinery: each rank's `Subdomain` window, the
//! same halo exchange (interior rows computed while the ghosts travel) and the same stencil
//! kernel; inner products are reduced over ranks. `feti` runs the same code as on one process,
//! with `exchange::Mpi`. MPI is called from the main thread only; computing runs on the pool.

use super::feti;
use super::problem::{outcome, SteadyProblem, Stop, Timings};
use crate::case::ValidCase;
use crate::case::{Backend, CaseError, Method};
use crate::linalg::cg::{self, conjugate_gradient};
use crate::operator::stencil::apply_on_runs;
use crate::output::outcome::Outcome;
use crate::output::record::SteadySolve;
use crate::parallel::exchange::Mpi;
use crate::parallel::exchange::{all_max, all_sum, distribution, ownership};
use crate::parallel::halo::HaloExchange;
use crate::parallel::subdomain::Subdomain;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::prelude::*;
use std::cell::Cell;
use std::time::Instant;

/// Runs a steady case on `world` (its size already checked against `case.ranks`).
pub fn run(world: &SimpleCommunicator, case: &ValidCase) -> Result<Option<Outcome>, CaseError> {
    let started = Instant::now();
    let pool = crate::threads::pool(case.threads)?;
    let problem = pool.install(|| SteadyProblem::new(case));
    if case.method == Method::Feti {
        return feti::run_on(case, &problem, &Mpi::new(world), &pool, started);
    }
    let stencil = &problem.stencil;
    let grid = stencil.grid;
    let ownership = ownership(world, case, stencil)?;
    let rank = world.rank() as usize;
    let subdomain = Subdomain::new(&ownership, stencil, rank);
    let window = &subdomain.window;
    let nodes = subdomain.node_indices(grid.n);
    let places: Vec<usize> = subdomain
        .runs()
        .flat_map(|run| {
            let start = window.index(run.x0, run.y);
            start..start + run.len()
        })
        .collect();
    let b: Vec<f64> = pool.install(|| nodes.par_iter().map(|&i| problem.load(i)).collect());
    let interior_nodes: usize = subdomain.interior.iter().map(|r| r.len()).sum();
    let mut halo = HaloExchange::new(&subdomain.neighbours);
    let mut p_window = vec![0.0; window.len()];
    let comm_s = Cell::new(0.0);
    let setup_s = started.elapsed().as_secs_f64();

    let solve_started = Instant::now();
    let mut u = vec![0.0; b.len()];
    let convergence = conjugate_gradient(
        Some(&pool),
        |p, ap| {
            for (&place, &value) in places.iter().zip(p) {
                p_window[place] = value;
            }
            let (ap_interior, ap_boundary) = ap.split_at_mut(interior_nodes);
            let exchange_s = halo.exchange(world, &mut p_window, |p| {
                pool.install(|| apply_on_runs(stencil, window, &subdomain.interior, p, ap_interior))
            });
            comm_s.set(comm_s.get() + exchange_s);
            pool.install(|| {
                apply_on_runs(stencil, window, &subdomain.boundary, &p_window, ap_boundary)
            });
            ap.iter_mut().for_each(|v| *v = -*v);
        },
        |x, y| {
            let local = pool.install(|| cg::dot(x, y));
            let reduce_started = Instant::now();
            let global = all_sum(world, local);
            comm_s.set(comm_s.get() + reduce_started.elapsed().as_secs_f64());
            global
        },
        &b,
        &mut u,
        problem.rtol,
        case.max_iterations(),
    );
    let solve_s = solve_started.elapsed().as_secs_f64();

    // The whole field on every rank (each node from its owner), for the residual and the error.
    let mut field = vec![0.0; grid.nodes()];
    for (&i, &value) in nodes.iter().zip(&u) {
        field[i] = value;
    }
    let local = field.clone();
    world.all_reduce_into(&local[..], &mut field[..], SystemOperation::sum());
    let distribution = distribution(world, case, &ownership, &subdomain, comm_s.get());
    let timings = Timings {
        setup_s: all_max(world, setup_s),
        solve_s: all_max(world, solve_s),
    };
    if rank != 0 {
        return Ok(None);
    }
    Ok(Some(pool.install(|| {
        outcome(
            case,
            &problem,
            Some(Backend::Stencil),
            timings,
            Stop::of_cg(&convergence, problem.rtol),
            SteadySolve::cg(convergence.iterations),
            distribution,
            field,
        )
    })))
}
