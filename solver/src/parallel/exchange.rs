//! The communication every distributed solver needs: a swap of blocks with some other ranks (the
//! halo exchange of seed 000's Algorithm 3, FETI's R^D exchange of seed 001's Algorithm 1), with
//! computation overlapped while the messages fly, and sums and maxima over all ranks (FETI's R^C
//! gather and the reductions). `Serial` is one process owning everything; `Mpi` is a communicator
//! of ranks (MPI_Isend/MPI_Irecv and MPI_Allreduce, as in the seeds).

use crate::case::{Case, CaseError, Partition};
use crate::discretization::stencil::Stencil;
use crate::output::diagnostics;
use crate::output::record::Distribution;
use crate::parallel::partition::{self, Ownership};
use crate::parallel::share::RankShare;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use rayon::ThreadPool;
use std::cell::Cell;
use std::time::Instant;

pub trait Exchange {
    fn rank(&self) -> usize;
    fn ranks(&self) -> usize;
    /// values ← Σ over ranks of values, elementwise (the same result on every rank).
    fn all_sum(&self, values: &mut [f64]);
    /// Σ over ranks of `local`.
    fn sum(&self, local: f64) -> f64;
    /// max over ranks of `local`.
    fn max(&self, local: f64) -> f64;
    /// Sends send[i] to peers[i] and receives receive[i] from peers[i] (sizes agreed beforehand),
    /// running `overlap` while the messages are in flight.
    fn swap_overlapped(
        &self,
        peers: &[usize],
        send: &[Vec<f64>],
        receive: &mut [Vec<f64>],
        overlap: &mut dyn FnMut(),
    );
    /// Seconds spent communicating so far (overlapped computation excluded).
    fn seconds(&self) -> f64;

    fn swap(&self, peers: &[usize], send: &[Vec<f64>], receive: &mut [Vec<f64>]) {
        self.swap_overlapped(peers, send, receive, &mut || {});
    }
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
    fn sum(&self, local: f64) -> f64 {
        local
    }
    fn max(&self, local: f64) -> f64 {
        local
    }
    fn swap_overlapped(
        &self,
        peers: &[usize],
        _send: &[Vec<f64>],
        _receive: &mut [Vec<f64>],
        overlap: &mut dyn FnMut(),
    ) {
        assert!(peers.is_empty(), "one process owns everything");
        overlap();
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

    fn reduce(&self, local: f64, operation: SystemOperation) -> f64 {
        let mut global = 0.0;
        self.world.all_reduce_into(&local, &mut global, operation);
        global
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
    fn sum(&self, local: f64) -> f64 {
        self.timed(|| self.reduce(local, SystemOperation::sum()))
    }
    fn max(&self, local: f64) -> f64 {
        self.timed(|| self.reduce(local, SystemOperation::max()))
    }
    fn swap_overlapped(
        &self,
        peers: &[usize],
        send: &[Vec<f64>],
        receive: &mut [Vec<f64>],
        overlap: &mut dyn FnMut(),
    ) {
        let mut overlap_s = 0.0;
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
                let overlap_started = Instant::now();
                overlap();
                overlap_s = overlap_started.elapsed().as_secs_f64();
                for request in requests {
                    request.wait();
                }
            })
        });
        self.seconds.set(self.seconds.get() - overlap_s);
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
    mpi: &Mpi,
    case: &Case,
    ownership: &Ownership,
    share: &RankShare,
    comm_s: f64,
) -> Distribution {
    let ghosts = mpi.sum(share.ghosts() as f64) as usize;
    Distribution {
        ranks: ownership.ranks,
        partition: case.partition,
        px: ownership.blocks.map(|(px, _)| px),
        py: ownership.blocks.map(|(_, py)| py),
        halo_nodes: ghosts,
        halo_bytes: ghosts * std::mem::size_of::<f64>(),
        imbalance: ownership.imbalance(),
        comm_s: mpi.max(comm_s),
    }
}

/// The ranks a run's vectors are spread over, and the pool each rank computes on.
#[derive(Clone, Copy)]
pub struct Ranks<'a> {
    pub exchange: &'a dyn Exchange,
    /// None: the caller already runs on its pool. MPI runs call MPI from the main thread and
    /// compute on this pool.
    pool: Option<&'a ThreadPool>,
}

impl<'a> Ranks<'a> {
    /// One process, computing on the current pool.
    pub fn single() -> Ranks<'static> {
        Ranks {
            exchange: &Serial,
            pool: None,
        }
    }

    /// The ranks of `mpi`, each computing on `pool`.
    pub fn mpi(mpi: &'a Mpi<'a>, pool: &'a ThreadPool) -> Self {
        Ranks {
            exchange: mpi,
            pool: Some(pool),
        }
    }

    /// The pool to run vector updates on: None when the caller already runs on it.
    pub fn pool(&self) -> Option<&'a ThreadPool> {
        self.pool
    }

    /// Runs `work` on the ranks' pool.
    pub fn on<T: Send>(&self, work: impl FnOnce() -> T + Send) -> T {
        crate::threads::on(self.pool, work)
    }

    pub fn sum(&self, local: f64) -> f64 {
        self.exchange.sum(local)
    }

    pub fn max(&self, local: f64) -> f64 {
        self.exchange.max(local)
    }

    /// max |vᵢ| over every rank's values (+∞ if any is NaN).
    pub fn max_abs(&self, v: &[f64]) -> f64 {
        self.max(self.on(|| diagnostics::max_abs(v)))
    }
}
