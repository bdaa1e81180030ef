//! Sparse Cholesky factorisations by faer (AMD ordering, simplicial or supernodal as faer
//! chooses), with the workspace of their solves kept, so a solve allocates nothing.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMat, SparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

/// L Lᵀ = A for a symmetric positive definite sparse A.
pub struct Cholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    workspace: MemBuffer,
}

impl Cholesky {
    /// Factors A (both triangles stored; the lower one is read). Err names what failed: a
    /// matrix that is not positive definite, or memory.
    pub fn new(a: SparseColMatRef<'_, usize, f64>) -> Result<Self, String> {
        let symbolic = factorize_symbolic_cholesky(
            a.symbolic(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| format!("symbolic Cholesky: {e:?}"))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let mut scratch = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        )
        .map_err(|e| format!("Cholesky workspace: {e:?}"))?;
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut scratch),
                Default::default(),
            )
            .map_err(|e| format!("numeric Cholesky: {e:?}"))?;
        let workspace = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        Ok(Cholesky {
            symbolic,
            values,
            workspace,
        })
    }

    /// x ← A⁻¹ x.
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        let n = x.len();
        let rhs = MatMut::from_column_major_slice_mut(x, n, 1);
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.workspace),
        );
    }

    /// Stored entries of the factor L (supernodes stored dense count whole).
    pub fn nonzeros(&self) -> usize {
        self.symbolic.len_val()
    }
}

/// y = A x for a matrix stored by columns whose columns are its rows (A symmetric).
pub fn symmetric_product(a: SparseColMatRef<'_, usize, f64>, x: &[f64], y: &mut [f64]) {
    let (col_ptr, row_idx, values) = (a.col_ptr(), a.row_idx(), a.val());
    for (j, yj) in y.iter_mut().enumerate() {
        let range = col_ptr[j]..col_ptr[j + 1];
        *yj = row_idx[range.clone()]
            .iter()
            .zip(&values[range])
            .map(|(&i, &v)| v * x[i])
            .sum();
    }
}

/// An n × n sparse matrix from (row, column, value) entries, duplicates summed.
pub fn sparse_matrix(n: usize, entries: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
    let triplets: Vec<faer::sparse::Triplet<usize, usize, f64>> = entries
        .iter()
        .map(|&(i, j, v)| faer::sparse::Triplet::new(i, j, v))
        .collect();
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("entries lie inside the matrix")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_small_spd_system() {
        // tridiag(−1, 4, −1), n = 6.
        let n = 6;
        let mut entries = Vec::new();
        for i in 0..n {
            entries.push((i, i, 4.0));
            if i + 1 < n {
                entries.push((i, i + 1, -1.0));
                entries.push((i + 1, i, -1.0));
            }
        }
        let a = sparse_matrix(n, &entries);
        let x: Vec<f64> = (0..n).map(|i| i as f64 - 2.5).collect();
        let mut b = vec![0.0; n];
        symmetric_product(a.as_ref(), &x, &mut b);
        let mut factor = Cholesky::new(a.as_ref()).unwrap();
        factor.solve_in_place(&mut b);
        for (got, want) in b.iter().zip(&x) {
            assert!((got - want).abs() < 1e-13, "{got} vs {want}");
        }
        assert!(factor.nonzeros() >= 2 * n - 1);
    }

    #[test]
    fn refuses_an_indefinite_matrix() {
        let a = sparse_matrix(2, &[(0, 0, 1.0), (1, 1, -1.0)]);
        assert!(Cholesky::new(a.as_ref()).is_err());
    }
}
