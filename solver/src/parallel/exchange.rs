//! The communication FETI's projected CG needs (seed 001, Algorithm 1): a swap of interface blocks
//! with the ranks that own neighbouring subdomains (the R^D exchange) and sums over all ranks (the
//! R^C gather and the reductions). `Serial` is one process owning every subdomain; `Mpi` is a
//! communicator of ranks (MPI_Isend/MPI_Irecv and MPI_Allreduce, as in the seed).

use crate::case::{Case, CaseError, Partition};
use crate::discretization::stencil::Stencil;
use crate::output::record::Distribution;
use crate::parallel::partition::{self, Ownership};
use crate::parallel::subdomain::Subdomain;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::cell::Cell;
use std::time::Instant;

pub trait Exchange {
    fn rank(&self) -> usize;
    fn ranks(&self) -> usize;
    /// values ← Σ over ranks of values, elementwise (the same result on every rank).
    fn all_sum(&self, values: &mut [f64]);
    /// Sends send[i] to peers[i] and receives receive[i] from peers[i] (sizes agreed beforehand).
    fn swap(&self, peers: &[usize], send: &[Vec<f64>], receive: &mut [Vec<f64>]);
    /// Seconds spent communicating so far.
    fn seconds(&self) -> f64;
}

/// One process: nothing to send, sums over one rank.
pub struct Serial;

impl Exchange for Serial {
    fn rank(&self) -> usize {
        0
    }
    fn ranks(&self) -> usize {
        1
    }
    fn all_sum(&self, _values: &mut [f64]) {}
    fn swap(&self, peers: &[usize], _send: &[Vec<f64>], _receive: &mut [Vec<f64>]) {
        assert!(peers.is_empty(), "one process owns every subdomain");
    }
    fn seconds(&self) -> f64 {
        0.0
    }
}

/// The ranks of an MPI communicator, called from the main thread only.
pub struct Mpi<'a> {
    pub world: &'a SimpleCommunicator,
    seconds: Cell<f64>,
}

impl<'a> Mpi<'a> {
    pub fn new(world: &'a SimpleCommunicator) -> Self {
        Mpi {
            world,
            seconds: Cell::new(0.0),
        }
    }

    fn timed<T>(&self, work: impl FnOnce() -> T) -> T {
        let started = Instant::now();
        let result = work();
        self.seconds
            .set(self.seconds.get() + started.elapsed().as_secs_f64());
        result
    }
}

impl Exchange for Mpi<'_> {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }
    fn ranks(&self) -> usize {
        self.world.size() as usize
    }
    fn all_sum(&self, values: &mut [f64]) {
        self.timed(|| {
            let local = values.to_vec();
            self.world
                .all_reduce_into(&local[..], values, SystemOperation::sum());
        })
    }
    fn swap(&self, peers: &[usize], send: &[Vec<f64>], receive: &mut [Vec<f64>]) {
        self.timed(|| {
            mpi::request::scope(|scope| {
                let mut requests = Vec::with_capacity(2 * peers.len());
                for (&peer, buffer) in peers.iter().zip(receive.iter_mut()) {
                    let from = self.world.process_at_rank(peer as i32);
                    requests.push(from.immediate_receive_into(scope, &mut buffer[..]));
                }
                for (&peer, buffer) in peers.iter().zip(send) {
                    let to = self.world.process_at_rank(peer as i32);
                    requests.push(to.immediate_send(scope, &buffer[..]));
                }
                for request in requests {
                    request.wait();
                }
            })
        })
    }
    fn seconds(&self) -> f64 {
        self.seconds.get()
    }
}

/// The partition of the case, the same on every rank.
pub(crate) fn ownership(
    world: &SimpleCommunicator,
    case: &Case,
    stencil: &Stencil,
) -> Result<Ownership, CaseError> {
    let grid = stencil.grid;
    if case.partition == Partition::Block {
        return partition::of(case, stencil); // cheap and the same everywhere
    }
    // METIS on rank 0 and the map broadcast: one partition, however METIS would behave on
    // other hosts.
    let root = world.process_at_rank(0);
    let computed = (world.rank() == 0).then(|| partition::of(case, stencil));
    let mut failed = i32::from(matches!(computed, Some(Err(_))));
    root.broadcast_into(&mut failed);
    let mut owner = match computed {
        Some(Err(e)) => return Err(e),
        Some(Ok(ownership)) => ownership.owner,
        None if failed == 1 => {
            return Err(CaseError::new(
                "partition",
                "the graph partition failed on rank 0",
            ))
        }
        None => vec![0; grid.nodes()],
    };
    root.broadcast_into(&mut owner[..]);
    Ok(Ownership {
        grid,
        ranks: case.ranks,
        owner,
        blocks: None,
    })
}

/// How a run was spread over the ranks of `world`: the partition, the ghosts summed over ranks
/// and the communication seconds `comm_s` (this rank's) maximised over them.
pub(crate) fn distribution(
    world: &SimpleCommunicator,
    case: &Case,
    ownership: &Ownership,
    subdomain: &Subdomain,
    comm_s: f64,
) -> Distribution {
    let ghosts = all_sum(world, subdomain.ghosts() as f64) as usize;
    Distribution {
        ranks: ownership.ranks,
        partition: case.partition,
        px: ownership.blocks.map(|(px, _)| px),
        py: ownership.blocks.map(|(_, py)| py),
        halo_nodes: ghosts,
        halo_bytes: ghosts * std::mem::size_of::<f64>(),
        imbalance: ownership.imbalance(),
        comm_s: all_max(world, comm_s),
    }
}

pub(crate) fn all_max(world: &SimpleCommunicator, local: f64) -> f64 {
    let mut global = 0.0;
    world.all_reduce_into(&local, &mut global, SystemOperation::max());
    global
}

pub(crate) fn all_sum(world: &SimpleCommunicator, local: f64) -> f64 {
    let mut global = 0.0;
    world.all_reduce_into(&local, &mut global, SystemOperation::sum());
    global
}
