//! Clusters: the schedulers, the job scripts written for them, the ledger of submitted jobs, and
//! `nlstudy submit`, which ties them together.

pub mod balance;
pub mod cost;
pub mod ended;
pub mod follow;
pub mod forecast;
pub mod ledger;
pub mod limits;
pub mod pack;
pub mod probes;
pub mod scheduler;
pub mod script;
pub mod submit;

/// Seconds since the Unix epoch: when a job was submitted, when earlier scripts were archived.
fn unix_seconds() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}
