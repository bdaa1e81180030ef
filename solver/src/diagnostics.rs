//! Errors against an exact solution and the conserved-quantity diagnostics, reduced in a fixed
//! order so that the numbers do not depend on the thread count.

use rayon::prelude::*;

/// Reduction block: partial sums over fixed blocks, added in block order.
const BLOCK: usize = 4096;

/// Σᵢ f(aᵢ, bᵢ) with the same rounding whatever the number of threads.
fn fixed_order_sum(a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64 + Sync) -> f64 {
    let partials: Vec<f64> = a
        .par_chunks(BLOCK)
        .zip(b.par_chunks(BLOCK))
        .map(|(x, y)| x.iter().zip(y).map(|(&p, &q)| f(p, q)).sum())
        .collect();
    partials.iter().sum()
}

/// e^k = h^d Σᵢ |exactᵢ − uᵢ|² (seed 000, eq. A.3): the square of the discrete L² error.
pub fn squared_l2_error(exact: &[f64], u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(exact, u, |e, v| (e - v) * (e - v))
}

/// maxᵢ |exactᵢ − uᵢ|.
pub fn max_error(exact: &[f64], u: &[f64]) -> f64 {
    exact
        .par_iter()
        .zip(u)
        .map(|(e, v)| (e - v).abs())
        .reduce(|| 0.0, f64::max)
}

/// h^d Σᵢ uᵢ.
pub fn total_mass(u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(u, u, |v, _| v)
}

/// maxᵢ |uᵢ|, with a NaN counted as +∞ so that a blown-up field is never reported as small.
pub fn max_abs(u: &[f64]) -> f64 {
    u.par_iter()
        .map(|v| if v.is_nan() { f64::INFINITY } else { v.abs() })
        .reduce(|| 0.0, f64::max)
}
