//! The communication every distributed solver needs: a swap of blocks with some other ranks (the
//! halo exchange of \[JD]'s Algorithm 3, FETI's R^D exchange of \[XGDF]'s Algorithm 1), with
//! computation overlapped while the messages fly, and sums and maxima over all ranks (FETI's R^C
//! gather and the reductions). `Serial` is one process owning everything; `world::Mpi` (with the
//! `mpi` feature) is a communicator of ranks (MPI_Isend/MPI_Irecv and MPI_Allreduce, as in \[JD]).

use crate::output::diagnostics;
use crate::output::record::Traffic;
use rayon::ThreadPool;

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
    /// Sends `send_counts[q]` values to each rank q and receives `receive_counts[p]` from each
    /// rank p, both buffers in rank order (MPI_Alltoallv): the transposes of the distributed
    /// sine transform.
    fn all_to_all(
        &self,
        send: &[f64],
        send_counts: &[usize],
        receive: &mut [f64],
        receive_counts: &[usize],
    );
    /// Seconds spent communicating so far (overlapped computation excluded).
    fn seconds(&self) -> f64;
    /// What this rank has sent so far (`Traffic`'s bytes are this rank's here).
    fn traffic(&self) -> Traffic {
        Traffic::default()
    }
    /// Counts `earlier` as sent already: the traffic of the steps a resumed run did before
    /// its checkpoint.
    fn count_earlier(&self, _earlier: Traffic) {}
    /// The maximum of `local` over ranks, for the run's bookkeeping (checkpoints agreeing on a
    /// step): counted in neither its traffic nor its communication time, so that a run that
    /// checkpoints has the record of one that does not.
    fn bookkeeping_max(&self, local: f64) -> f64 {
        local
    }

    fn swap(&self, peers: &[usize], send: &[Vec<f64>], receive: &mut [Vec<f64>]) {
        self.swap_overlapped(peers, send, receive, &mut || {});
    }
}

/// Where each rank's piece starts in a buffer of pieces of `counts` values, in rank order (the
/// displacements of MPI_Alltoallv).
pub fn offsets(counts: &[usize]) -> Vec<usize> {
    counts
        .iter()
        .scan(0, |at, &c| {
            let here = *at;
            *at += c;
            Some(here)
        })
        .collect()
}

/// The largest peak resident memory of any rank so far (None where /proc does not tell): what
/// a distributed record reports, taken before rank 0 gathers a field it was asked for.
pub fn peak_memory_over_ranks(exchange: &dyn Exchange) -> Option<u64> {
    let mine = crate::output::record::peak_memory_bytes().unwrap_or(0);
    Some(exchange.max(mine as f64) as u64).filter(|&bytes| bytes > 0)
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
    fn all_to_all(
        &self,
        send: &[f64],
        send_counts: &[usize],
        receive: &mut [f64],
        receive_counts: &[usize],
    ) {
        assert_eq!(
            (send_counts, receive_counts),
            (&[send.len()][..], &[receive.len()][..])
        );
        receive.copy_from_slice(send);
    }
    fn seconds(&self) -> f64 {
        0.0
    }
}

/// The ranks a run's vectors are spread over, and the pool each rank computes on.
#[derive(Clone, Copy)]
pub struct Ranks<'a> {
    pub exchange: &'a dyn Exchange,
    /// None: the caller already runs on its pool. MPI runs call MPI from the main thread and
    /// compute on this pool.
    pub(super) pool: Option<&'a ThreadPool>,
}

impl<'a> Ranks<'a> {
    /// One process, computing on the current pool.
    pub fn single() -> Ranks<'static> {
        Ranks {
            exchange: &Serial,
            pool: None,
        }
    }

    /// `exchange`'s ranks, each computing on `pool`.
    pub fn on_pool(exchange: &'a dyn Exchange, pool: &'a ThreadPool) -> Ranks<'a> {
        Ranks {
            exchange,
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
