//! Running a study: the `nlsolve` process, the plan of which points run (make-style), the local
//! worker pool and its progress output, and clusters (job scripts, schedulers, the jobs ledger).
//!
//! Also: the nodes the pool runs on (`allocation`: this machine, or every node of a job's
//! allocation), the signals that stop a run (`signals`), the rounds of an adaptive study
//! (`search`), and for `compare --against solver:PATH` interleaved reruns of two builds
//! (`interleave`) and instruction counts under cachegrind (`instructions`).

pub mod allocation;
pub mod cluster;
pub mod dial_back;
pub mod instructions;
pub mod interleave;
pub mod nlsolve;
pub mod plan;
pub mod pool;
pub mod progress;
pub mod search;
pub mod signals;
pub mod timeline;
pub mod worker;
