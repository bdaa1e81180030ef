//! What a run produces: diagnostics of a field, field snapshots and frames, VTK files, the
//! record's constructors for this process (the record's data, the contract with the
//! orchestrator, is `schema::record`), the threads' CPU time (`usage`) and the outcome that
//! carries the record.

pub mod diagnostics;
pub mod field;
pub mod outcome;
pub mod record;
pub mod usage;
pub mod vtk;
