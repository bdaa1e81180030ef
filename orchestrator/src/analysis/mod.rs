//! From records to numbers: the run table and the per-point summary (speedups, convergence
//! orders, timing statistics), and Markdown pivots over it.
//!
//! Also: the tables of the adaptive questions (`answer_table`, shared by `boundaries`,
//! `convergence` and `target`), `compare` (two result sets judged against the noise of the
//! machine), the scaling model (`scaling_model`) and the figure specs checked against the
//! summary's columns before anything runs (`figure_columns`).

pub mod answer_table;
pub mod boundaries;
pub mod collect;
pub mod compare;
pub mod convergence;
pub mod figure_columns;
pub mod incremental;
pub mod pivot;
pub mod scaling_model;
pub mod simulate;
pub mod summary;
pub mod target;
pub mod timeline;
