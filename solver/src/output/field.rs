//! Fields as output: the frames a run keeps for ParaView, and the coarse
//! copy of the final field (and its error) a record carries for heat maps.

use crate::discretization::grid::Lattice;
pub use schema::record::FieldSnapshot;

/// The field at one output time.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub time: f64,
    pub values: Vec<f64>,
}

/// The snapshot of `u` on `lattice` with at most `side` blocks per side, and of its error
/// against `exact` when given.
pub fn snapshot(
    lattice: &Lattice,
    u: &[f64],
    exact: Option<&(dyn Fn(usize) -> f64 + Sync)>,
    side: usize,
) -> FieldSnapshot {
    let n = lattice.n;
    let stride = n.div_ceil(side.max(1));
    let blocks = n.div_ceil(stride);
    let ny = if lattice.dim == 2 { blocks } else { 1 };
    let means = |value: &dyn Fn(usize) -> f64| {
        let mut sums = vec![0.0; blocks * ny];
        let mut counts = vec![0usize; blocks * ny];
        for i in 0..lattice.nodes() {
            let (ix, iy) = (i % n, i / n);
            let block = (iy / stride) * blocks + ix / stride;
            sums[block] += value(i);
            counts[block] += 1;
        }
        sums.iter()
            .zip(&counts)
            .map(|(s, &c)| s / c as f64)
            .collect()
    };
    let half = 0.5 * lattice.spacing;
    FieldSnapshot {
        nx: blocks,
        ny,
        lower: lattice.origin - half,
        upper: lattice.origin + (n - 1) as f64 * lattice.spacing + half,
        values: means(&|i| u[i]),
        error: exact.map(|exact| means(&|i| u[i] - exact(i))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapshot_averages_blocks_and_keeps_partial_ones() {
        // 5 × 5 nodes in at most 3 blocks per side: blocks of 2, the last row and column partial.
        let lattice = Lattice {
            dim: 2,
            n: 5,
            origin: 0.1,
            spacing: 0.2,
        };
        let u: Vec<f64> = (0..25).map(|i| i as f64).collect();
        let zero = |_: usize| 0.0;
        let snapshot = snapshot(&lattice, &u, Some(&zero), 3);
        assert_eq!((snapshot.nx, snapshot.ny), (3, 3));
        assert!((snapshot.lower - 0.0).abs() < 1e-15 && (snapshot.upper - 1.0).abs() < 1e-15);
        // Block (0, 0) holds nodes 0, 1, 5, 6; block (2, 2) holds node 24 alone.
        assert_eq!(snapshot.values[0], 3.0);
        assert_eq!(snapshot.values[2], (4.0 + 9.0) / 2.0);
        assert_eq!(snapshot.values[8], 24.0);
        assert_eq!(snapshot.error.as_deref(), Some(&snapshot.values[..]));
    }

    #[test]
    fn snapshot_of_a_small_field_is_the_field() {
        let lattice = Lattice {
            dim: 1,
            n: 4,
            origin: 0.125,
            spacing: 0.25,
        };
        let u = [1.0, -2.0, 3.0, 0.5];
        let snapshot = snapshot(&lattice, &u, None, 64);
        assert_eq!((snapshot.nx, snapshot.ny), (4, 1));
        assert_eq!(snapshot.values, u);
        assert_eq!(snapshot.error, None);
    }
}
