//! Errors against an exact solution and the conserved-quantity diagnostics, reduced in a fixed
//! order so that the numbers do not depend on the thread count.

use rayon::prelude::*;

/// Reduction block: partial sums over fixed index blocks, added in block order.
const BLOCK: usize = 4096;

/// Σᵢ term(i) for i < len, with the same rounding whatever the number of threads.
fn fixed_order_sum(len: usize, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partials: Vec<f64> = (0..len.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| (b * BLOCK..len.min((b + 1) * BLOCK)).map(&term).sum())
        .collect();
    partials.iter().sum()
}

/// e^k = h^d Σᵢ |exact(i) − uᵢ|² (seed 000, eq. A.3): the square of the discrete L² error.
pub fn squared_l2_error(exact: impl Fn(usize) -> f64 + Sync, u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(u.len(), |i| (exact(i) - u[i]).powi(2))
}

/// maxᵢ |exact(i) − uᵢ|.
pub fn max_error(exact: impl Fn(usize) -> f64 + Sync, u: &[f64]) -> f64 {
    (0..u.len())
        .into_par_iter()
        .map(|i| (exact(i) - u[i]).abs())
        .reduce(|| 0.0, f64::max)
}

/// h^d Σᵢ uᵢ.
pub fn total_mass(u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(u.len(), |i| u[i])
}

/// maxᵢ |uᵢ|, with a NaN counted as +∞ so that a blown-up field is never reported as small.
pub fn max_abs(u: &[f64]) -> f64 {
    u.par_iter().map(|&v| magnitude(v)).reduce(|| 0.0, f64::max)
}

/// |v|, or +∞ for a NaN.
#[inline]
pub fn magnitude(v: f64) -> f64 {
    if v.is_nan() {
        f64::INFINITY
    } else {
        v.abs()
    }
}
