//! What a person reads: SVG drawing, the figure kinds drawn from the summary table, the HTML
//! report, and the status of a study's records and jobs.
//!
//! `draw` renders any chart and `figure` decides what each kind shows (one module per kind);
//! `plot` draws a study's figures, each only when its inputs changed. Besides: `answers` (the
//! lines `run` prints of an adaptive study), `compare_figure` (`compare.svg`), `history`
//! (`history.svg`) and `timeline` (`timeline.svg`, and the table `status --timeline` prints).

pub mod answers;
pub mod compare_figure;
pub mod draw;
pub mod figure;
pub mod history;
pub mod plot;
pub mod report;
pub mod status;
pub mod timeline;
