//! How work is shared among threads: the pool a case runs on, and the fixed block size whose
//! boundaries make every reduction independent of the thread count, bit for bit.

use crate::case::CaseError;

/// The rayon pool a case runs on.
pub fn pool(threads: usize) -> Result<rayon::ThreadPool, CaseError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CaseError::new("threads", format!("cannot start {threads} threads: {e}")))
}
