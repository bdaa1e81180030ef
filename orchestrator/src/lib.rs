//! The study orchestrator behind `nlstudy`: study files → points → cases → runs → records →
//! Parquet tables → SVG figures. Its folders are its layers, lowest first; each imports only
//! the layers before it (tests/architecture.rs checks this):
//!
//! - `allocator`: how the allocator gives freed memory back;
//! - `console`: printing that never panics on a closed or full stream;
//! - `statistics`: order statistics (quantiles, the median) of measured values, and the log–log
//!   slope observed orders are fitted by;
//! - `model`: the study file, its sweeps and expressions, its figure specs, its adaptive
//!   question — pure data;
//! - `store`: the record store (keys, locks, atomic writes) and records as table rows;
//! - `run`: the `nlsolve` process, the plan (make-style), the worker pool, progress, and
//!   `run::cluster` for job scripts, schedulers and the jobs ledger;
//! - `analysis`: records → run and summary tables (speedups, orders), pivots, the adaptive
//!   questions' tables, `compare`;
//! - `output`: SVG drawing and figures, the HTML report, the status of a study;
//! - `kinds`: the kinds of adaptive question behind one trait, and their registry;
//! - `cli`: the command line, every command and flag in one table (`cli::args`);
//! - `commands`: each command given its flags, one module each, and the exit status it ends with
//!   (`schema::exit`, the table both binaries share).
//!
//! The record's status and timings and the case's fields come from the `schema` crate, which
//! `nlsolve` writes from.

/// `eprintln!` that never panics (see `console`), for the progress of a run (`run/progress.rs`).
macro_rules! errln {
    ($($arg:tt)*) => { $crate::console::err(format_args!("{}\n", format_args!($($arg)*))) };
}

pub mod allocator;
pub(crate) mod analysis;
pub mod cli;
pub mod commands;
pub(crate) mod console;
pub(crate) mod kinds;
pub(crate) mod model;
pub(crate) mod output;
pub(crate) mod run;
pub(crate) mod statistics;
pub(crate) mod store;
