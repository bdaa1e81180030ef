//! Nonlocal diffusion solvers: the partitioned nonlocal heat equation of Jha & Diehl (seed 000),
//! planned once and stepped many times, with interchangeable operator backends.
//!
//! A run goes case → grid and horizon → stencil weights and stable step → operator plan →
//! forward Euler → errors and diagnostics → record (see `run`).

pub mod case;
pub mod continuum;
pub mod diagnostics;
pub mod distributed;
pub mod euler;
pub mod field;
pub mod grid;
pub mod influence;
pub mod local;
pub mod operator;
pub mod partition;
pub mod problem;
pub mod pse;
pub mod quadrature;
pub mod record;
pub mod run;
mod source;
pub mod stability;
pub mod steady;
pub mod stencil;
pub mod subdomain;
pub mod vtk;
