//! What a run produces: diagnostics of a field, field snapshots and frames, VTK files, the
//! record (the contract with the orchestrator) and the outcome that carries it.

pub mod diagnostics;
pub mod field;
pub mod outcome;
pub mod record;
pub mod usage;
pub mod vtk;
