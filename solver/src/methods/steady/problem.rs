//! The steady problem of a case: the square stencil of A = −L_h, the loads, the exact solution,
//! and the record of a finished solve (shared by CG and FETI, in one process or over ranks).

use crate::case::ValidCase;
use crate::case::{Backend, Case, Kernel, Quadrature};
use crate::discretization::grid::{Grid, Horizon};
use crate::discretization::influence::Influence;
use crate::discretization::stencil::Stencil;
use crate::linalg::cg::{self, CgParams, Norm, Start};
use crate::operator::{self, LinearOperator};
use crate::output::diagnostics::{
    fixed_order_sum, max_abs, max_error, squared_l2_error, total_mass,
};
use crate::output::outcome::Outcome;
use crate::output::record::{self, Distribution, Record, Resolved, Status, SteadySolve};
use crate::parallel::exchange::Exchange;
use rayon::prelude::*;
use rayon::ThreadPool;

/// The steady problem of a case: the square stencil of A = −L_h and the data.
pub struct SteadyProblem {
    pub stencil: Stencil,
    /// k of the local limit kΔ.
    pub diffusivity: f64,
    pub rtol: f64,
    /// The iteration cap of its CG (and of FETI's).
    pub max_iterations: usize,
}

/// The manufactured solution u = x₁² + x₂², also the volume constraint g on Γ.
pub fn exact(x: [f64; 2]) -> f64 {
    x[0] * x[0] + x[1] * x[1]
}

impl SteadyProblem {
    pub fn new(case: &ValidCase) -> Self {
        let grid = Grid::new(2, case.n);
        let m = case.m.expect("validated: steady methods give m");
        let horizon = Horizon::from_m(&grid, m);
        let kernel = case.kernel;
        let k = case.diffusivity;
        let mi = m as f64;
        let j = |dx: i64, dy: i64| kernel.influence(((dx * dx + dy * dy) as f64).sqrt() / mi);
        let c = match case.quadrature {
            Quadrature::Ac => {
                let (mut lattice_moment, m) = (0.0, m as i64);
                for dy in -m..=m {
                    for dx in -m..=m {
                        if (dx, dy) != (0, 0) {
                            lattice_moment += j(dx, dy) * (dx * dx + dy * dy) as f64;
                        }
                    }
                }
                2.0 * k / (grid.h.powi(4) * lattice_moment)
            }
            _ => 2.0 * k / (horizon.eps.powi(4) * square_second_moment(kernel)),
        };
        let h2 = grid.volume();
        let stencil = Stencil::square(grid, horizon, kernel, case.quadrature, c, |dx, dy| {
            2.0 * c * j(dx, dy) * h2
        });
        SteadyProblem {
            stencil,
            diffusivity: k,
            rtol: case.rtol(),
            max_iterations: case.max_iterations(),
        }
    }

    /// How its CG runs (\[XGDF], section 4.1): from zero until ‖r‖/‖b‖ ≤ rtol, at most the
    /// case's iterations; the vector updates on `pool`.
    pub fn cg_params<'a>(&self, pool: Option<&'a ThreadPool>) -> CgParams<'a> {
        CgParams {
            start: Start::Zero,
            rtol: self.rtol,
            norm: Norm::Residual,
            max_iterations: self.max_iterations,
            pool,
        }
    }

    pub fn grid(&self) -> Grid {
        self.stencil.grid
    }

    /// f = −kΔu = −4k.
    pub fn source(&self) -> f64 {
        -4.0 * self.diffusivity
    }

    /// The load f/ω of node i: f + Σ_{j ∈ Γ} w_ij g(x_j).
    pub fn load(&self, i: usize) -> f64 {
        self.source() + self.stencil.collar_sum(i, |_, x| exact(x))
    }

    /// The load of every node of Ω.
    pub fn loads(&self) -> Vec<f64> {
        (0..self.grid().nodes())
            .into_par_iter()
            .map(|i| self.load(i))
            .collect()
    }

    /// The manufactured solution at every node of Ω.
    pub fn exact_values(&self) -> Vec<f64> {
        let grid = self.grid();
        (0..grid.nodes())
            .into_par_iter()
            .map(|i| exact(grid.position(i)))
            .collect()
    }

    /// What the case resolved to.
    pub fn resolved(&self, backend: Option<Backend>) -> Resolved {
        Resolved {
            patch_error: Some(self.patch_error()),
            backend,
            ..record::resolved_of(&self.stencil)
        }
    }

    /// L_h|x|²/(4k) − 1 in the interior: 0 up to round-off for `ac`.
    pub fn patch_error(&self) -> f64 {
        self.stencil.second_moment() / (4.0 * self.diffusivity) - 1.0
    }

    /// How well u on the nodes of Ω solves the single-domain system and matches the exact u.
    pub fn measure(&self, u: &[f64]) -> Fit {
        let operator = operator::plan(Backend::Stencil, &self.stencil);
        let mut lu = vec![0.0; u.len()];
        operator.apply_once(u, &mut lu);
        let (b, exact) = (self.loads(), self.exact_values());
        let residual2 = fixed_order_sum(u.len(), |i| (b[i] + lu[i]).powi(2));
        let load2 = fixed_order_sum(u.len(), |i| b[i] * b[i]);
        Fit {
            relative_residual: (residual2 / load2).sqrt(),
            error_max: max_error(|i| exact[i], u),
            error_l2: squared_l2_error(|i| exact[i], u, self.grid().volume()),
        }
    }
}

/// A solution's numbers for its record: its fit, its mass and its largest value.
pub(crate) struct Summary {
    pub fit: Fit,
    pub mass: f64,
    pub max_abs: f64,
}

impl SteadyProblem {
    /// The numbers of u on every node of Ω.
    pub(crate) fn summarize(&self, u: &[f64]) -> Summary {
        Summary {
            fit: self.measure(u),
            mass: total_mass(u, self.grid().volume()),
            max_abs: max_abs(u),
        }
    }
}

impl Summary {
    /// The numbers of a solution spread over ranks: each rank holds u, its loads b and L_h u at
    /// its `nodes`, measures them there, and the sums and maxima are reduced, so that no rank
    /// needs the whole field.
    pub(crate) fn over_ranks(
        grid: &Grid,
        nodes: &[usize],
        (u, b, lu): (&[f64], &[f64], &[f64]),
        exchange: &dyn Exchange,
        pool: &ThreadPool,
    ) -> Summary {
        let (local, error_max, max_abs) = pool.install(|| {
            let exact = |k: usize| exact(grid.position(nodes[k]));
            let local = [
                (0..u.len())
                    .into_par_iter()
                    .map(|k| (b[k] + lu[k]).powi(2))
                    .sum::<f64>(),
                b.par_iter().map(|v| v * v).sum::<f64>(),
                squared_l2_error(exact, u, grid.volume()),
                total_mass(u, grid.volume()),
            ];
            (local, max_error(exact, u), max_abs(u))
        });
        let [residual2, load2, error_l2, mass] = local.map(|v| exchange.sum(v));
        Summary {
            fit: Fit {
                relative_residual: (residual2 / load2).sqrt(),
                error_max: exchange.max(error_max),
                error_l2,
            },
            mass,
            max_abs: exchange.max(max_abs),
        }
    }
}

/// A solution measured against the system and the manufactured u.
pub struct Fit {
    /// ‖b − A u‖ / ‖b‖.
    pub relative_residual: f64,
    /// max |u − exact|.
    pub error_max: f64,
    /// h² Σ (u − exact)², the squared discrete L² error.
    pub error_l2: f64,
}

/// Q_J = ∫_{[−1,1]²} J(|s|) |s|² ds for the kernels positive on the whole square.
fn square_second_moment(kernel: Kernel) -> f64 {
    match kernel {
        Kernel::InverseDistance => 4.0 / 3.0 * (2f64.sqrt() + 1f64.asinh()),
        // J(|s|)|s|² = J(s₁)J(s₂)(s₁² + s₂²) for J = 1 and e^{−r²}.
        Kernel::Constant | Kernel::Gaussian => 8.0 * kernel.moment(0) * kernel.moment(2),
        Kernel::Linear => unreachable!("validated: J = 1 − r is negative in the square's corners"),
    }
}

/// ap = −lu, in parallel.
pub(crate) fn negate_into(lu: &[f64], ap: &mut [f64]) {
    ap.par_iter_mut().zip(lu).for_each(|(a, &l)| *a = -l);
}

use super::resume::Resumed;

pub(crate) struct Timings {
    pub setup_s: f64,
    /// The solve's seconds over all its segments, and the iteration it resumed from.
    pub solve: Resumed,
}

/// How the iteration ended: within `rtol`, or stopped at the case's `max_iterations` (or on a
/// non-finite residual), with the residual it measures.
pub(crate) struct Termination {
    pub reached_tolerance: bool,
    pub residual: f64,
}

impl Termination {
    pub(crate) fn of_cg(convergence: &cg::Convergence) -> Self {
        Termination {
            reached_tolerance: convergence.converged,
            residual: convergence.relative_residual,
        }
    }
}

/// The record of a finished steady solve, with its numbers (`summary`) and the field when held
/// (empty when distributed and not asked for).
// Each argument is one stage's product of the same solve; a struct of them would only rename them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn outcome(
    case: &Case,
    problem: &SteadyProblem,
    backend: Option<Backend>,
    timings: Timings,
    stop: Termination,
    mut solve: SteadySolve,
    distribution: Distribution,
    summary: Summary,
    field: Vec<f64>,
) -> Outcome {
    let grid = problem.grid();
    let Summary {
        fit:
            Fit {
                relative_residual,
                error_max,
                error_l2,
            },
        mass,
        max_abs,
    } = summary;
    solve.relative_residual = Some(relative_residual);
    let iterations = solve.iterations.unwrap_or(0);
    let (status, message) = if !relative_residual.is_finite() {
        (
            Status::Diverged,
            "the iteration produced a non-finite solution".to_string(),
        )
    } else if !stop.reached_tolerance {
        (
            Status::Diverged,
            format!(
                "stopped after {iterations} iterations with residual {}, above rtol = {}",
                crate::case::readable(stop.residual),
                crate::case::readable(problem.rtol)
            ),
        )
    } else {
        (Status::Ok, String::new())
    };
    let record = Record {
        status,
        message,
        setup_s: timings.setup_s,
        solve_s: timings.solve.solve_s,
        step_s: timings.solve.solve_s / iterations.max(1) as f64,
        resumed_from_step: (timings.solve.from_iteration > 0)
            .then_some(timings.solve.from_iteration),
        solve_s_segments: timings.solve.segments_s,
        error_l2: Some(error_l2),
        error_l2_norm: Some(error_l2.sqrt()),
        error_max: Some(error_max),
        mass: Some(mass),
        max_abs: Some(max_abs),
        steady: solve,
        ..record::fresh(case, problem.resolved(backend), distribution)
    };
    Outcome {
        record,
        field,
        lattice: grid.lattice(),
        frames: Vec::new(),
    }
}
