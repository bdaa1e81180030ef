//! How work is shared among threads: the pool a case runs on, and the fixed block size whose
//! boundaries make every reduction independent of the thread count, bit for bit.

use crate::case::CaseError;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// Nodes per unit of parallel work over a flat array (updates, 1D stencil segments, a rank's
/// window): fixed, so every value, and every reduction over blocks, is computed the same way
/// whatever the thread count. 4096 f64 are 32 KiB, an L1 cache's worth.
pub const BLOCK: usize = 4096;

/// The rayon pool a case of `threads` threads runs on: made once per thread count and kept, so
/// that a process answering case after case (`nlsolve serve`) starts no threads per case.
pub fn pool(threads: usize) -> Result<Arc<rayon::ThreadPool>, CaseError> {
    static POOLS: Mutex<BTreeMap<usize, Arc<rayon::ThreadPool>>> = Mutex::new(BTreeMap::new());
    let mut pools = POOLS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(pool) = pools.get(&threads) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CaseError::new("threads", format!("cannot start {threads} threads: {e}")))?;
    Ok(Arc::clone(pools.entry(threads).or_insert(Arc::new(pool))))
}

/// The cores this process may use (its affinity mask and cgroup quota), read once: it reads
/// the cgroup's files, and a worker asks for every case.
pub fn cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Runs `work` on `pool`, or where the caller is when None.
pub fn on<T: Send>(pool: Option<&rayon::ThreadPool>, work: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(pool) => pool.install(work),
        None => work(),
    }
}

/// Tasks a transform-based operator splits the rows of a 2D field between on the current pool
/// (one per thread, at most one per row); a 1D field is one row and one task.
pub fn row_tasks(dim: usize, n: usize) -> usize {
    if dim == 2 {
        rayon::current_num_threads().min(n)
    } else {
        1
    }
}
