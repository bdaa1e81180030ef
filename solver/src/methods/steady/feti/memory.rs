//! What a `feti` run holds at its peak, from the case alone: `nlsolve check` and `run` refuse
//! a case that would not fit before allocating.

use crate::case::{Case, FetiPreconditioner};

/// Non-zeros of the Cholesky factor of a subdomain matrix on `s` nodes with the square stencil
/// of reach m, under faer's AMD ordering: 3.8 m^1.5 s^1.25, at most the dense triangle. Fitted
/// at m = 4 to `factor_nonzeros_max` (43–47 M at s = 85 264, docs/steady.md) and to the weak
/// study's peak (7.8 GB per rank at s = 4 624); s^1.25 lies between nested dissection's
/// s log s and AMD's worse fill on grids, and m^1.5 comes from viewing the stencil as a coarse
/// grid of m × m blocks (not measured at other m).
pub(super) fn factor_nonzeros(s: f64, m: f64) -> f64 {
    (3.8 * m.powf(1.5) * s.powf(1.25)).min(s * (s + 1.0) / 2.0)
}

/// Bytes a `feti` run holds at its peak over all ranks, from the case alone (nothing
/// allocated), besides the fields of n² values counted by the caller. Per subdomain of s
/// unknowns (s_I of them interior): A_n in CSC (16 bytes per non-zero: its pairs of nodes
/// within the stencil), the Cholesky factor of A_n and, for `dirichlet` (scaled or not), of A_II
/// (8 bytes per non-zero of L, `factor_nonzeros`), or A_II itself for `dirichlet_cg`; its work
/// vectors (48 bytes per node); its interface lists and dual vectors (72 bytes per interface
/// node). Per rank: the coarse GᵀG, factored on every rank (24 bytes per entry while it is built
/// and factored), and an assembly in flight per thread (48 bytes per entry: the triplets and
/// faer's sorting of them into a matrix).
pub(crate) fn memory_bytes(case: &Case) -> f64 {
    let (Some(p), Some(m)) = (case.subdomains, case.m) else {
        return 0.0;
    };
    // The widths take a few values: count the blocks of each (Λ width, interior width).
    let mut kinds = std::collections::BTreeMap::<(usize, usize), f64>::new();
    for width in crate::methods::steady::decomposition::widths(case.n, p, m) {
        *kinds.entry(width).or_default() += 1.0;
    }
    // Pairs (i, j) of a block's nodes within m of each other, i = j included.
    let pairs = |w: usize| {
        let k = m.min(w.saturating_sub(1)) as f64;
        let w = w as f64;
        w + 2.0 * (k * w - k * (k + 1.0) / 2.0)
    };
    let reach = m as f64;
    let (mut bytes, mut largest_matrix) = (0.0, 0.0f64);
    for (&(wx, ix), &count_x) in &kinds {
        for (&(wy, iy), &count_y) in &kinds {
            let (s, interior) = ((wx * wy) as f64, (ix * iy) as f64);
            let matrix = pairs(wx) * pairs(wy);
            largest_matrix = largest_matrix.max(matrix);
            let preconditioner = match case.preconditioner() {
                FetiPreconditioner::None => 0.0,
                FetiPreconditioner::DirichletCg => 16.0 * pairs(ix) * pairs(iy),
                FetiPreconditioner::Dirichlet | FetiPreconditioner::DirichletScaled => {
                    8.0 * factor_nonzeros(interior, reach)
                }
            };
            let subdomain = 16.0 * matrix
                + 8.0 * factor_nonzeros(s, reach)
                + preconditioner
                + 48.0 * s
                + 72.0 * (s - interior);
            bytes += count_x * count_y * subdomain;
        }
    }
    let floating = (p as f64 - 2.0).max(0.0).powi(2);
    let per_rank = 24.0 * floating * floating + case.threads as f64 * 48.0 * largest_matrix;
    bytes + case.ranks as f64 * per_rank
}
