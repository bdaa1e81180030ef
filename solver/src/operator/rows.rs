//! An operator held as its rows, each a list of (column, coefficient): what a discretization
//! whose weights change from node to node assembles (a varying horizon, \[LSSM]). Each output
//! is its row's sum in the stored order, computed by one thread, so the result does not depend
//! on the thread count.

use super::linear::LinearOperator;
use crate::threads::BLOCK;
use rayon::prelude::*;

pub struct RowOperator {
    /// Row i's entries are `starts[i]..starts[i + 1]` of `columns` and `coefficients`.
    starts: Vec<usize>,
    columns: Vec<usize>,
    coefficients: Vec<f64>,
}

impl RowOperator {
    pub fn new(rows: impl IntoIterator<Item = Vec<(usize, f64)>>) -> Self {
        let mut operator = RowOperator {
            starts: vec![0],
            columns: Vec::new(),
            coefficients: Vec::new(),
        };
        for row in rows {
            for (column, a) in row {
                operator.columns.push(column);
                operator.coefficients.push(a);
            }
            operator.starts.push(operator.columns.len());
        }
        operator
    }

    /// Gershgorin's bound on the largest |eigenvalue|: max over rows of Σ_j |a_ij|.
    pub fn lambda_bound(&self) -> f64 {
        self.starts
            .windows(2)
            .map(|r| {
                self.coefficients[r[0]..r[1]]
                    .iter()
                    .map(|a| a.abs())
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    }
}

impl LinearOperator for RowOperator {
    type Workspace = ();

    fn workspace(&self) {}

    fn apply(&self, u: &[f64], out: &mut [f64], _: &mut ()) {
        out.par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(b, chunk)| {
                for (k, o) in chunk.iter_mut().enumerate() {
                    let row = b * BLOCK + k;
                    let entries = self.starts[row]..self.starts[row + 1];
                    *o = self.columns[entries.clone()]
                        .iter()
                        .zip(&self.coefficients[entries])
                        .map(|(&j, a)| a * u[j])
                        .sum();
                }
            });
    }
}
