//! Running a study: the `nlsolve` process, the plan of which points run (make-style), the local
//! worker pool and its progress output, and clusters (job scripts, schedulers, the jobs ledger).

pub mod allocation;
pub mod cluster;
pub mod instructions;
pub mod interleave;
pub mod nlsolve;
pub mod plan;
pub mod pool;
pub mod progress;
pub mod search;
pub mod signals;
pub mod worker;
