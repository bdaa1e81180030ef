//! Linear algebra the methods share: conjugate gradients and BiCGStab (for the non-symmetric
//! systems) with fixed-order inner products, sparse Cholesky factorisations by faer, and the ends
//! of a sparse operator's spectrum by faer's Krylov–Schur.

pub mod bicgstab;
pub mod cg;
pub mod cholesky;
pub mod lanczos;
pub mod spectrum;
pub mod tridiagonal;
