//! The subdomain stiffness matrices A_n and loads f_n of \[XGDF], eq. 23 (divided by ω, as in
//! `steady`), assembled as faer sparse matrices. The single-domain A and f of eqs. 19–20 are the
//! case p = 1, where ζ = 1 and Λ is all of Ω.

use super::decomposition::{Decomposition, Subdomain};
use super::problem::{exact, SteadyProblem};
use faer::sparse::SparseColMat;

/// A_n and f_n: for node i of Λ_n and each bond o with j = i + o in E_n, weight w_o / ζ_A(i, j):
/// on A's diagonal and, for j ∈ Λ_n, off it with a minus sign; for j ∈ Γ_n times g(x_j) into f;
/// plus f(x_i)/ζ_F(i).
pub fn assemble(
    problem: &SteadyProblem,
    decomposition: &Decomposition,
    subdomain: &Subdomain,
) -> (SparseColMat<usize, f64>, Vec<f64>) {
    let stencil = &problem.stencil;
    let grid = stencil.grid;
    let axis = &decomposition.axis;
    let n = grid.n as i64;
    let [xs, ys] = &subdomain.lambda;
    let [ex, ey] = [
        &axis.extended[subdomain.block[0]],
        &axis.extended[subdomain.block[1]],
    ];
    let unknowns = subdomain.unknowns();
    let mut entries = Vec::with_capacity(unknowns * stencil.offsets);
    let mut load = vec![0.0; unknowns];
    for y in ys.clone() {
        for x in xs.clone() {
            let i = subdomain.local(x, y);
            let zeta_f = decomposition.zeta_a([x, y], [x, y]) as f64;
            let mut diagonal = 0.0;
            let mut dirichlet = 0.0;
            for row in &stencil.rows {
                let jy = y + row.dy;
                if !ey.contains(&jy) {
                    continue;
                }
                for (dx, w) in row.bonds() {
                    let jx = x + dx;
                    if !ex.contains(&jx) {
                        continue;
                    }
                    let w = w / decomposition.zeta_a([x, y], [jx, jy]) as f64;
                    diagonal += w;
                    if (0..n).contains(&jx) && (0..n).contains(&jy) {
                        entries.push(faer::sparse::Triplet::new(subdomain.local(jx, jy), i, -w));
                    } else {
                        dirichlet += w * exact([grid.coord(jx), grid.coord(jy)]);
                    }
                }
            }
            entries.push(faer::sparse::Triplet::new(i, i, diagonal));
            load[i] = problem.source() / zeta_f + dirichlet;
        }
    }
    let a = SparseColMat::try_new_from_triplets(unknowns, unknowns, &entries)
        .expect("every entry lies inside Λ_n");
    (a, load)
}

/// The single-domain A and f (eqs. 19–20): the decomposition with p = 1.
pub fn single_domain(problem: &SteadyProblem) -> (SparseColMat<usize, f64>, Vec<f64>) {
    let grid = problem.grid();
    let decomposition = Decomposition::new(grid.n, 1, problem.stencil.horizon.m);
    assemble(problem, &decomposition, &decomposition.subdomains[0])
}
