//! Linear algebra the methods share: conjugate gradients with fixed-order inner products, and
//! sparse Cholesky factorisations by faer.

pub mod cg;
pub mod cholesky;
