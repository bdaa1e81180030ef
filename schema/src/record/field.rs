//! What a record carries of a run's fields, when its case asks: the c_tot(t) series, the final
//! field's histogram and a coarse copy of the final field (and its error) for heat maps.

use serde::{Deserialize, Serialize};

/// c_tot(t) = h^d Σᵢ cᵢ(t) sampled during a run (\[HPCSE]'s diagnostics.dat): at t = 0 and at the
/// steps its output interval makes due.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MassSeries {
    pub time: Vec<f64>,
    pub c_tot: Vec<f64>,
}

impl MassSeries {
    /// The series as CSV with a header: `t,c_tot`, one row per sample.
    pub fn to_csv(&self) -> String {
        let mut csv = String::from("t,c_tot\n");
        for (t, c) in self.time.iter().zip(&self.c_tot) {
            csv.push_str(&format!("{t},{c}\n"));
        }
        csv
    }
}

/// Counts of values in `counts.len()` equal bins over [lo, hi] (the last bin closed).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    pub lo: f64,
    pub hi: f64,
    pub counts: Vec<u64>,
}

/// A coarse copy of a final field: block means over s×s nodes (s nodes in 1D), s = ⌈n/side⌉,
/// so a heat map shows every node's contribution, not a subsample that could miss a spike.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FieldSnapshot {
    /// Blocks along x and along y (1 in 1D).
    pub nx: usize,
    pub ny: usize,
    /// The extent [lower, upper] of the nodes' cells along each axis.
    pub lower: f64,
    pub upper: f64,
    /// Block means of u, row by row (iy·nx + ix).
    pub values: Vec<f64>,
    /// Block means of u − exact, when the problem has an exact solution.
    pub error: Option<Vec<f64>>,
}
