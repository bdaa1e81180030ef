//! Linear algebra the methods share: conjugate gradients with fixed-order inner products, BiCGStab
//! (faer's) for the non-symmetric systems, and
//! sparse Cholesky factorisations by faer.

pub mod bicgstab;
pub mod cg;
pub mod cholesky;
pub mod spectrum;
