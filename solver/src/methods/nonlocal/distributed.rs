//! The fully distributed solver (\[JD], section 3 and Algorithm 3) over MPI.
//!
//! Every rank plans its `RankShare` once from the ownership map (a block partition each rank
//! computes alike, or a METIS partition made on rank 0 and broadcast), then runs the case's
//! integrator on its own nodes with the `DistributedOperator`, which exchanges the halo while it
//! computes the interior nodes. The time loop is the serial one (`nonlocal::solve`). With the
//! stencil backend the per-node arithmetic is the serial stencil's, in the same order, so the
//! explicit integrators' fields equal the serial ones bit for bit; with the FFT backend each rank
//! convolves its window by a local FFT and the fields agree to rounding. Errors and mass are sums
//! over ranks and agree to rounding.
//!
//! MPI is called from the main thread only (`Threading::Funneled`); the computing runs on the
//! case's rayon pool.

use super::{solve, Plan};
use crate::case::CaseError;
use crate::case::ValidCase;
use crate::integrate::measure::measure;
use crate::output::outcome::{self, Outcome};
use crate::output::record::Record;
use crate::parallel::exchange::peak_memory_over_ranks;
use crate::parallel::exchange::Ranks;
use crate::parallel::operator::DistributedOperator;
use crate::parallel::share::RankShare;
use crate::parallel::world::{distribution, gather, ownership, Mpi};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::time::Instant;

/// Runs a nonlocal case on the ranks of `world` (its size already checked against
/// `case.ranks`). Rank 0 gets the outcome (with the whole field when `gather_field`), the other
/// ranks `None`.
pub fn run(
    world: &SimpleCommunicator,
    case: &ValidCase,
    gather_field: bool,
) -> Result<Option<Outcome>, CaseError> {
    let pool = crate::threads::pool(case.threads)?;
    let setup_started = Instant::now();
    let plan = pool.install(|| Plan::new(case))?;
    let ownership = ownership(world, case, &plan.stencil)?;
    let rank = world.rank() as usize;
    let share = RankShare::new(&ownership, &plan.stencil, rank);
    let partition = ownership.summary();
    drop(ownership); // the whole grid's owners: not held through the run
    let mpi = Mpi::new(world);
    let ranks = Ranks::mpi(&mpi, &pool);
    let operator = DistributedOperator::new(&plan.stencil, &share, ranks, plan.backend);
    let grid = plan.stencil.grid;
    let nodes = share.node_indices(grid.n);
    let (solved, trajectory) = solve(case, &plan, &operator, ranks, Some(nodes), setup_started);

    let distribution = distribution(&mpi, case, &partition, &share, trajectory.step_comm_s);
    let exact = solved.exact(trajectory.timing.steps_done);
    let measured = measure(
        ranks,
        case,
        solved.setup_s,
        &solved.stepping,
        &trajectory,
        &grid.lattice(),
        exact.as_ref().map(|e| e as &(dyn Fn(usize) -> f64 + Sync)),
        distribution,
    );
    let peak_memory_bytes = peak_memory_over_ranks(&mpi);
    let field = gather_field
        .then(|| {
            gather(
                world,
                &share.node_indices(grid.n),
                &trajectory.u,
                grid.nodes(),
            )
        })
        .flatten();
    Ok((rank == 0).then(|| Outcome {
        record: Record {
            peak_memory_bytes,
            ..outcome::record(case, plan.resolved(), measured)
        },
        field: field.unwrap_or_default(),
        lattice: grid.lattice(),
        frames: Vec::new(), // refused for ranks > 1 by the case's validation
    }))
}
