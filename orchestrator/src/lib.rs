//! The study orchestrator behind `nlstudy`: study files → points → cases → runs → records →
//! Parquet tables → SVG figures. Its modules, roughly lowest first (tests/architecture.rs
//! checks that their imports have no cycle):
//!
//! - `expression`, `store`, `progress`, `draw`: the study language, the record store, progress
//!   output, and SVG drawing — no knowledge of studies (the record's status and timings and the
//!   case's fields come from the `schema` crate, which `nlsolve` writes from);
//! - `table`, `summary`: records as rows, and the per-point summary with speedups and orders;
//! - `figure`, `pivot`: the figure kinds (one module each) and Markdown pivots over the summary;
//! - `study`: a study file, expanded into points and cases, with its figures and resources;
//! - `solver`: the `nlsolve` binary, which checks the cases;
//! - `plan`: which points run and why (make-style);
//! - `pool`, `submit`: running the plan on a local worker pool, or as Slurm/LSF jobs;
//! - `collect`, `plot`, `status`: records → tables, tables → figures, records → a status report;
//! - `commands`: the command line, one function per command.

pub mod collect;
pub mod commands;
pub mod draw;
pub mod expression;
pub mod figure;
pub mod jobs;
pub mod pivot;
pub mod plan;
pub mod plot;
pub mod pool;
pub mod progress;
pub mod report;
pub mod solver;
pub mod status;
pub mod store;
pub mod study;
pub mod submit;
pub mod summary;
pub mod table;
