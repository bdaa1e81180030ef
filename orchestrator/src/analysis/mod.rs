//! From records to numbers: the run table and the per-point summary (speedups, convergence
//! orders, timing statistics), and Markdown pivots over it.

pub mod answer_table;
pub mod boundaries;
pub mod collect;
pub mod compare;
pub mod convergence;
pub mod figure_columns;
pub mod incremental;
pub mod pivot;
pub mod scaling_model;
pub mod summary;
pub mod target;
