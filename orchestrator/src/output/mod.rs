//! What a person reads: SVG drawing, the figure kinds drawn from the summary table, the HTML
//! report, and the status of a study's records and jobs.

pub mod answers;
pub mod compare_figure;
pub mod draw;
pub mod figure;
pub mod history;
pub mod plot;
pub mod report;
pub mod status;
