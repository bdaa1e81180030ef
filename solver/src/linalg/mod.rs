//! Linear algebra the methods share: conjugate gradients with fixed-order inner products, and a
//! dense Cholesky factorisation.

pub mod cg;
pub mod cholesky;
