//! One subdomain's share: its matrix and load, A_n's (pseudo-)inverse by Cholesky, the
//! Dirichlet preconditioner's interior solves, and the products K_n and Q_n with their clock.

use crate::case::FetiPreconditioner;
use crate::linalg::cg::{dot_serial, Cg, CgParams, Closures, NoPreconditioner, Norm, Start};
use crate::linalg::cholesky::{symmetric_product, Cholesky};
use crate::methods::steady::assembly::assemble;
use crate::methods::steady::decomposition::{Decomposition, Subdomain};
use crate::methods::steady::problem::SteadyProblem;
use faer::sparse::SparseColMat;
use std::time::Instant;

/// Iterations of CG for the interior solves of `dirichlet_cg` (\[XGDF], section 4.1).
pub(super) const INTERIOR_CG_ITERATIONS: usize = 5;

/// How the Dirichlet preconditioner solves with A_II.
pub(super) enum InteriorSolve {
    /// No preconditioner, or no interior node: S_n = A_BB.
    None,
    Cholesky(Cholesky),
    /// `dirichlet_cg`: a few CG iterations on A_II, from zero, with their buffers.
    Cg(SparseColMat<usize, f64>, Cg),
}

/// One subdomain's matrices, factors and work vectors.
pub(super) struct Local<'d> {
    pub(super) geometry: &'d Subdomain,
    pub(super) a: SparseColMat<usize, f64>,
    pub(super) load: Vec<f64>,
    /// A_n's factor, or the regularised A_n + ρ e_k e_kᵀ's when floating.
    pub(super) factor: Cholesky,
    /// The Dirichlet preconditioner's interior I (nodes in no interface) and its solves.
    pub(super) interior: Vec<usize>,
    pub(super) interior_solve: InteriorSolve,
    /// Work vectors on Λ_n and on I.
    pub(super) u: Vec<f64>,
    pub(super) w: Vec<f64>,
    pub(super) correction: Vec<f64>,
    pub(super) interior_load: Vec<f64>,
    pub(super) interior_solution: Vec<f64>,
    /// `dirichlet_scaled`: 1/(subdomains whose Λ holds the node), per node of Λ_n.
    pub(super) multiplicity_scale: Option<Vec<f64>>,
    /// Seconds and counts of this subdomain's K_n and Q_n products.
    pub(super) clock: ProductClock,
}

/// Time spent in one subdomain's products, on whichever thread ran them.
#[derive(Clone, Copy, Default)]
pub(super) struct ProductClock {
    pub(super) k_s: f64,
    pub(super) k_products: usize,
    pub(super) q_s: f64,
    pub(super) q_products: usize,
}

impl<'d> Local<'d> {
    pub(super) fn new(
        problem: &SteadyProblem,
        decomposition: &'d Decomposition,
        geometry: &'d Subdomain,
        preconditioner: FetiPreconditioner,
    ) -> Result<Self, String> {
        let (a, load) = assemble(problem, decomposition, geometry);
        let factor = if geometry.floating {
            let mut regularised = a.clone();
            pin_diagonal(&mut regularised, geometry.unknowns() / 2);
            Cholesky::new(regularised.as_ref())
        } else {
            Cholesky::new(a.as_ref())
        }?;
        let mut on_interface = vec![false; geometry.unknowns()];
        for interface in &geometry.interfaces {
            for &i in &interface.nodes {
                on_interface[i] = true;
            }
        }
        let interior: Vec<usize> = (0..geometry.unknowns())
            .filter(|&i| !on_interface[i])
            .collect();
        let interior_solve = match preconditioner {
            _ if interior.is_empty() => InteriorSolve::None,
            FetiPreconditioner::None => InteriorSolve::None,
            FetiPreconditioner::DirichletCg => {
                InteriorSolve::Cg(submatrix(&a, &interior), Cg::new(interior.len()))
            }
            FetiPreconditioner::Dirichlet | FetiPreconditioner::DirichletScaled => {
                InteriorSolve::Cholesky(Cholesky::new(submatrix(&a, &interior).as_ref())?)
            }
        };
        let multiplicity_scale =
            (preconditioner == FetiPreconditioner::DirichletScaled).then(|| {
                let [xs, ys] = &geometry.lambda;
                ys.clone()
                    .flat_map(|y| xs.clone().map(move |x| (x, y)))
                    .map(|(x, y)| 1.0 / decomposition.zeta_a([x, y], [x, y]) as f64)
                    .collect()
            });
        let (s, ni) = (geometry.unknowns(), interior.len());
        Ok(Local {
            geometry,
            a,
            load,
            factor,
            interior,
            interior_solve,
            u: vec![0.0; s],
            w: vec![0.0; s],
            correction: vec![0.0; s],
            interior_load: vec![0.0; ni],
            interior_solution: vec![0.0; ni],
            multiplicity_scale,
            clock: ProductClock::default(),
        })
    }

    /// x ← A_n^† x.
    pub(super) fn pseudo_solve(factor: &mut Cholesky, floating: bool, x: &mut [f64]) {
        if floating {
            remove_mean(x);
        }
        factor.solve_in_place(x);
        if floating {
            remove_mean(x);
        }
    }

    /// u ← M_nᵀ λ_n (zero off the interfaces).
    pub(super) fn scatter(geometry: &Subdomain, lambda: &[f64], u: &mut [f64]) {
        u.fill(0.0);
        for interface in &geometry.interfaces {
            let values = &lambda[interface.offset..interface.offset + interface.nodes.len()];
            for (&i, &l) in interface.nodes.iter().zip(values) {
                u[i] += interface.sign * l;
            }
        }
    }

    /// out ← M_n u.
    pub(super) fn gather(geometry: &Subdomain, u: &[f64], out: &mut [f64]) {
        for interface in &geometry.interfaces {
            let values = &mut out[interface.offset..interface.offset + interface.nodes.len()];
            for (&i, o) in interface.nodes.iter().zip(values) {
                *o = interface.sign * u[i];
            }
        }
    }

    /// out ← K_n λ_n = M_n A_n^† M_nᵀ λ_n.
    pub(super) fn apply_k(&mut self, lambda: &[f64], out: &mut [f64]) {
        let started = Instant::now();
        Self::scatter(self.geometry, lambda, &mut self.u);
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        Self::gather(self.geometry, &self.u, out);
        self.clock.k_s += started.elapsed().as_secs_f64();
        self.clock.k_products += 1;
    }

    /// out ← M_n A_n^† f_n.
    pub(super) fn dual_load(&mut self, out: &mut [f64]) {
        self.u.copy_from_slice(&self.load);
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        Self::gather(self.geometry, &self.u, out);
    }

    /// out ← Q_n r_n = M_n S_n M_nᵀ r_n (eq. 33), S_n = A_BB − A_BI A_II⁻¹ A_IB applied as
    /// A_n v − A_n (A_II⁻¹ (A_n v)_I) on B, for v = M_nᵀ r_n (zero on I); with multiplicity
    /// scaling, M_n D_n S_n D_n M_nᵀ r_n.
    pub(super) fn apply_dirichlet(&mut self, residual: &[f64], out: &mut [f64]) {
        let started = Instant::now();
        Self::scatter(self.geometry, residual, &mut self.u);
        if let Some(scale) = &self.multiplicity_scale {
            self.u.iter_mut().zip(scale).for_each(|(u, d)| *u *= d);
        }
        symmetric_product(self.a.as_ref(), &self.u, &mut self.w);
        let y = &mut self.interior_solution;
        let solved = match &mut self.interior_solve {
            InteriorSolve::None => false,
            InteriorSolve::Cholesky(factor) => {
                for (yi, &i) in y.iter_mut().zip(&self.interior) {
                    *yi = self.w[i];
                }
                factor.solve_in_place(y);
                true
            }
            InteriorSolve::Cg(a_ii, cg) => {
                for (b, &i) in self.interior_load.iter_mut().zip(&self.interior) {
                    *b = self.w[i];
                }
                let system = &mut Closures {
                    len: y.len(),
                    precondition: NoPreconditioner,
                    apply: |p: &[f64], ap: &mut [f64]| symmetric_product(a_ii.as_ref(), p, ap),
                    dot: dot_serial,
                };
                // A fixed number of iterations: rtol 0 is never reached.
                let params = CgParams {
                    start: Start::Zero,
                    rtol: 0.0,
                    norm: Norm::Residual,
                    max_iterations: INTERIOR_CG_ITERATIONS,
                    pool: None,
                };
                cg.solve(system, &self.interior_load, y, &params);
                true
            }
        };
        if solved {
            self.u.fill(0.0);
            for (&yi, &i) in y.iter().zip(&self.interior) {
                self.u[i] = yi;
            }
            symmetric_product(self.a.as_ref(), &self.u, &mut self.correction);
            for (w, c) in self.w.iter_mut().zip(&self.correction) {
                *w -= c;
            }
        }
        if let Some(scale) = &self.multiplicity_scale {
            self.w.iter_mut().zip(scale).for_each(|(w, d)| *w *= d);
        }
        Self::gather(self.geometry, &self.w, out);
        self.clock.q_s += started.elapsed().as_secs_f64();
        self.clock.q_products += 1;
    }

    /// u_n = A_n^†(f_n − M_nᵀ λ_n) + α_n 1.
    pub(super) fn solution(&mut self, lambda: &[f64], alpha: f64) -> Vec<f64> {
        Self::scatter(self.geometry, lambda, &mut self.u);
        for (u, f) in self.u.iter_mut().zip(&self.load) {
            *u = f - *u;
        }
        Self::pseudo_solve(&mut self.factor, self.geometry.floating, &mut self.u);
        self.u.iter().map(|u| u + alpha).collect()
    }
}

/// A_kk += A_kk: makes a floating A_n definite without changing its pattern.
pub(super) fn pin_diagonal(a: &mut SparseColMat<usize, f64>, k: usize) {
    let range = a.col_ptr()[k]..a.col_ptr()[k + 1];
    let at = range
        .clone()
        .find(|&e| a.row_idx()[e] == k)
        .expect("A has its diagonal");
    a.val_mut()[at] *= 2.0;
}

pub(super) fn remove_mean(x: &mut [f64]) {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    x.iter_mut().for_each(|v| *v -= mean);
}

/// A restricted to the rows and columns `keep` (sorted).
pub(super) fn submatrix(a: &SparseColMat<usize, f64>, keep: &[usize]) -> SparseColMat<usize, f64> {
    let mut place = vec![usize::MAX; a.nrows()];
    for (new, &old) in keep.iter().enumerate() {
        place[old] = new;
    }
    let mut entries = Vec::new();
    for (new_col, &col) in keep.iter().enumerate() {
        let range = a.col_ptr()[col]..a.col_ptr()[col + 1];
        for e in range {
            let row = place[a.row_idx()[e]];
            if row != usize::MAX {
                entries.push(faer::sparse::Triplet::new(row, new_col, a.val()[e]));
            }
        }
    }
    SparseColMat::try_new_from_triplets(keep.len(), keep.len(), &entries)
        .expect("entries lie inside the submatrix")
}
