//! The eigenvalues of a sparse L_h that decide stepping it in time, where a dense
//! eigendecomposition (O(n³)) is out of reach, as for 2D: faer's Krylov–Schur
//! (`matrix_free::eigen::partial_eigen`, the eigenvalues of largest magnitude) on
//! - the shifted inverse (L_h − σ I)⁻¹, by a sparse LU of L_h − σ I: its largest eigenvalues
//!   μ are L_h's nearest σ, λ = σ + 1/μ. For σ > 0 on a ladder right of the slow modes these
//!   are the rightmost ones, the ones that grow or decay slowest (not a proof: an eigenvalue
//!   far from every σ could hide; the tests check the ends against the dense spectrum);
//! - L_h itself: the eigenvalues of largest |λ|, which bound the explicit steps.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::Solve;
use faer::matrix_free::eigen::{partial_eigen, partial_eigen_scratch, PartialEigenParams};
use faer::matrix_free::LinOp;
use faer::sparse::linalg::solvers::Lu;
use faer::sparse::{SparseColMat, Triplet};
use faer::{c64, Col, Mat, MatMut, MatRef, Par};

/// Eigenvalues computed at each end of the spectrum.
pub const EIGENVALUES_PER_END: usize = 16;

/// Relative tolerance of the Krylov–Schur iteration.
const TOLERANCE: f64 = 1e-10;

/// Restarts of one Krylov–Schur run before it returns what converged. A cluster of near-zero
/// eigenvalues (the constant-horizon partial stress in 2D has a whole band of them) converges
/// slowly near every shift: faer's default of 1000 restarts took minutes at 64², where 100
/// leave every test's ends converged.
const MAX_RESTARTS: usize = 100;

/// (L_h − σ I)⁻¹ by its sparse LU.
struct ShiftedInverse {
    lu: Lu<usize, f64>,
    n: usize,
}

impl std::fmt::Debug for ShiftedInverse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "(L − σ I)⁻¹ on {} unknowns", self.n)
    }
}

impl LinOp<f64> for ShiftedInverse {
    fn apply_scratch(&self, _: usize, _: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.n
    }
    fn ncols(&self) -> usize {
        self.n
    }
    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _: Par, _: &mut MemStack) {
        { out }.copy_from(self.lu.solve(rhs));
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, s: &mut MemStack) {
        self.apply(out, rhs, par, s)
    }
}

/// L_h as a sparse matrix, for the largest |λ|.
#[derive(Debug)]
struct Sparse(SparseColMat<usize, f64>);

impl LinOp<f64> for Sparse {
    fn apply_scratch(&self, _: usize, _: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.0.nrows()
    }
    fn ncols(&self) -> usize {
        self.0.ncols()
    }
    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _: Par, _: &mut MemStack) {
        { out }.copy_from(&self.0 * rhs);
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, s: &mut MemStack) {
        self.apply(out, rhs, par, s)
    }
}

/// The eigenvalues of largest magnitude of `operator` that Krylov–Schur converged.
fn largest(operator: &dyn LinOp<f64>, n: usize) -> Vec<c64> {
    let count = EIGENVALUES_PER_END.min(n);
    let params = PartialEigenParams {
        max_restarts: MAX_RESTARTS,
        ..PartialEigenParams::default()
    };
    let mut scratch = MemBuffer::new(partial_eigen_scratch(operator, count, Par::Seq, params));
    let mut vectors = Mat::<c64>::zeros(n, count);
    let mut values = vec![c64::new(0.0, 0.0); count];
    // A start with every mode in it, and no randomness: the same run gives the same numbers.
    let start = Col::<f64>::from_fn(n, |i| 1.0 + ((i * 7919) % 101) as f64 / 101.0);
    let info = partial_eigen(
        vectors.as_mut(),
        &mut values,
        operator,
        start.as_ref(),
        TOLERANCE,
        Par::Seq,
        MemStack::new(&mut scratch),
        params,
    );
    values.truncate(info.n_converged_eigen);
    values
}

/// The rows of L_h (row i: (column, a_ij)) as a sparse matrix of `n` columns, shifted by −σ I.
fn matrix(rows: &[Vec<(usize, f64)>], n: usize, sigma: f64) -> SparseColMat<usize, f64> {
    let triplets: Vec<Triplet<usize, usize, f64>> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, row)| row.iter().map(move |&(j, a)| Triplet::new(i, j, a)))
        .chain((0..n).map(|i| Triplet::new(i, i, -sigma)))
        .collect();
    SparseColMat::try_new_from_triplets(n, n, &triplets).expect("indices within the matrix")
}

/// Shifts σ/k of the shift-invert runs: a ladder along the positive real axis, since what lies
/// nearest one σ may be a cluster of slow modes that hides a farther eigenvalue with a larger
/// real part (the partial stress has both).
const SHIFTS: [f64; 3] = [1.0, 10.0, 100.0];

/// The rightmost eigenvalues (those nearest each shift of a ladder σ = k, 10k, 100k, right of
/// the slow modes of diffusivity k) and those of largest |λ| of the square operator whose rows
/// are `rows`: those that converged, the shifts' runs possibly finding one twice. An error when
/// either end converged none (or the LU failed).
pub fn ends(rows: &[Vec<(usize, f64)>], diffusivity: f64) -> Result<Vec<c64>, String> {
    let n = rows.len();
    let mut eigenvalues = Vec::new();
    for sigma in SHIFTS.map(|s| s * diffusivity) {
        let lu = matrix(rows, n, sigma)
            .sp_lu()
            .map_err(|e| format!("the sparse LU of L − σI failed: {e:?}"))?;
        eigenvalues.extend(largest(&ShiftedInverse { lu, n }, n).into_iter().map(|mu| {
            let modulus2 = mu.re * mu.re + mu.im * mu.im;
            c64::new(sigma + mu.re / modulus2, -mu.im / modulus2)
        }));
    }
    let rightmost = eigenvalues.len();
    eigenvalues.extend(largest(&Sparse(matrix(rows, n, 0.0)), n));
    // Without a converged eigenvalue at either end there is no spectrum to report.
    if rightmost == 0 || eigenvalues.len() == rightmost {
        return Err(format!(
            "Krylov–Schur converged {rightmost} eigenvalues near the shifts and {} of the largest within {MAX_RESTARTS} restarts",
            eigenvalues.len() - rightmost
        ));
    }
    Ok(eigenvalues)
}
