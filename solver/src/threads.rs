//! How work is shared among threads: the pool a case runs on, and the fixed block size whose
//! boundaries make every reduction independent of the thread count, bit for bit.

use crate::case::CaseError;

/// Nodes per unit of parallel work over a flat array (updates, 1D stencil segments, a rank's
/// window): fixed, so every value, and every reduction over blocks, is computed the same way
/// whatever the thread count. 4096 f64 are 32 KiB, an L1 cache's worth.
pub const BLOCK: usize = 4096;

/// The rayon pool a case runs on.
pub fn pool(threads: usize) -> Result<rayon::ThreadPool, CaseError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CaseError::new("threads", format!("cannot start {threads} threads: {e}")))
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
