//! Clusters: the schedulers, the job scripts written for them, the ledger of submitted jobs, and
//! `nlstudy submit`, which ties them together.

pub mod ledger;
pub mod scheduler;
pub mod script;
pub mod submit;
