//! The contract between the solver (`nlsolve`) and the orchestrator (`nlstudy`): the case's
//! fields and choices, the exit statuses of both binaries, the grid spacing h each method defines, a record's status and timings, and
//! the FFT lengths the solver transforms at.
//! Plain serde data, the checkpoint file's format, and the file handling both binaries share (a
//! whole-or-nothing write, a capped read of regular files only), so that the orchestrator reads
//! what the solver writes without linking the numerics.

pub mod atomic;
pub mod case;
pub mod checkpoint;
pub mod choices;
#[cfg(feature = "cli")]
pub mod cli;
pub mod error;
pub mod exit;
pub mod json;
pub mod protocol;
pub mod record;
pub mod regular;
pub mod text;
pub mod transform;
