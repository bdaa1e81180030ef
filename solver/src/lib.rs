//! Nonlocal and local diffusion solvers: the partitioned nonlocal heat equation of Jha & Diehl
//! (\[JD]), the local grid and particle methods of \[HPCSE], the asymptotically compatible
//! quadratures of \[RKAC] and the steady problem with CG and FETI of \[XGDF].
//!
//! The modules are layers; each imports only those above it in this list (a test checks it):
//!
//! - `case`: the input, plain data read by everyone, and the rules every case obeys;
//! - `threads`, `linalg`: the pool and fixed-order reductions; CG, BiCGStab, sparse Cholesky
//!   (faer) and the ends of an operator's spectrum (faer's Krylov–Schur, Lanczos over ranks);
//! - `discretization`: grid, horizon, influence function, quadrature weights, stencil, stability;
//! - `problem`: manufactured solutions, initial values and sources;
//! - `operator`: L_h behind one trait, with interchangeable backends;
//! - `output`: diagnostics, field snapshots, VTK, the record and a run's outcome;
//! - `parallel`: partitions, subdomain windows, halo exchange and collectives over MPI;
//! - `integrate`: time stepping and the time step;
//! - `methods`: one module per method, and the one dispatch from a case to its method.
//!
//! A run goes case → `methods::validate` → the method's plan (stencil, operator, dt) →
//! `integrate` → `output` (errors, diagnostics, record); see docs/architecture.md.

pub mod case;
pub mod discretization;
pub mod integrate;
pub mod linalg;
pub mod methods;
pub mod operator;
pub mod output;
pub mod parallel;
pub mod problem;
pub mod threads;

pub use case::ValidCase;
pub use case::{Case, CaseError};
#[cfg(feature = "mpi")]
pub use methods::run_on_ranks;
pub use methods::{partition_report, run, validate};
pub use output::outcome::Outcome;
pub use output::record::Record;
