//! What a pool is given: its cores and nodes, how cases run and stop.

use crate::model::launcher::Launcher;
use crate::run::allocation::Node;
use std::time::Duration;

pub struct PoolOptions {
    /// Cores the running cases may use together (threads × ranks each).
    pub cores: usize,
    /// Where cases run, each within its cores: this machine, or the nodes of the allocation
    /// this process runs in (`allocation::nodes`).
    pub nodes: Vec<Node>,
    /// One case at a time on a node, so that timings are not disturbed.
    pub exclusive: bool,
    pub timeout: Option<Duration>,
    /// Command prefix of MPI cases, e.g. `srun --mpi=pmix -n {ranks}`.
    pub launcher: Launcher,
    /// Further attempts at a case that failed for a reason outside it: past its timeout, killed
    /// by a signal, or its MPI launcher hung or failed after the record was printed. A case
    /// that diverges or is refused is a result and never runs again.
    pub retries: usize,
    /// A process per case (`--isolate`), never a worker.
    pub isolate: bool,
    /// Cases checkpoint this often (a time loop, or a steady solve's CG), besides on a stopping
    /// signal, in `runs/.work/<key>.checkpoint` (and `.rank<r>` beside it over ranks), and
    /// resume from it.
    pub checkpoint_every: Option<Duration>,
    /// Keep each checkpoint after its record is stored.
    pub keep_checkpoints: bool,
}

impl PoolOptions {
    /// Whether cases run side by side: on several nodes, or several cores of a shared one.
    pub fn side_by_side(&self) -> bool {
        match self.exclusive {
            true => self.nodes.len() > 1,
            false => self.cores > 1,
        }
    }
}

/// The cores this process may use (its affinity mask and cgroup quota respected), read once: it
/// reads the cgroup's files, and every record asks.
pub fn machine_cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}
