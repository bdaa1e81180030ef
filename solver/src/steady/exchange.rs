//! The communication FETI's projected CG needs (seed 001, Algorithm 1): a swap of interface blocks
//! with the ranks that own neighbouring subdomains (the R^D exchange) and sums over all ranks (the
//! R^C gather and the reductions). `Serial` is one process owning every subdomain; `Mpi` is a
//! communicator of ranks (MPI_Isend/MPI_Irecv and MPI_Allreduce, as in the seed).

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
