//! The record: one JSON object per run, the contract between the solver, which writes it
//! (`Record`), and the orchestrator, which stores it with the fields it adds (`Stored`) and
//! takes its tables' columns from it. What became of a run (`Status`) and the column names
//! (`columns`) are here too. The children import each other, never this module, so that the
//! module graph stays acyclic.

pub mod columns;
pub mod example;
mod field;
mod method;
mod provenance;
mod run;
mod status;
mod stored;

pub use columns::{column, columns, every_field, is_column, RESULTS, TABULATED, TIMINGS};
pub use field::{FieldSnapshot, Histogram, MassSeries};
pub use method::{Coupling, PatchTest, Spectrum};
pub use provenance::{Load, Provenance};
pub use run::{
    first_non_finite, Distribution, FetiPhases, ImplicitSolves, Record, Resolved, SteadySolve,
    Traffic,
};
pub use status::{Status, GROWING};
pub use stored::{Failure, Outcome, Stored};
