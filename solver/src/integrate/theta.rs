//! The θ-scheme for u' = L u + b(t): backward Euler (θ = 1, order 1, L-stable) and
//! Crank–Nicolson (θ = ½, order 2, A-stable),
//!     (I − θ dt L) uⁿ⁺¹ = (I + (1 − θ) dt L) uⁿ + dt (θ b(tⁿ⁺¹) + (1 − θ) b(tⁿ)).
//! −L_h is symmetric positive definite, so each step solves an SPD system by preconditioned CG,
//! matrix-free through the operator backend, warm-started from uⁿ. The preconditioner is the
//! sine-transform inverse of I − θ dt τ(L_h) (`operator::SinePreconditioner`), which makes the
//! iteration count nearly independent of n. A varying horizon's non-symmetric forms
//! (x-centred, partial stress) are solved by BiCGStab instead (`Krylov`), never by CG.
//!
//! **Tolerance.** The manufactured solution oscillates at angular frequency 2π, so its time error
//! after N = T/dt steps is about (2π dt)^p (p the order). A solve stopped at ‖r‖ ≤ rtol ‖b‖ leaves
//! an error of about rtol ‖u‖ per step, N rtol ‖u‖ in all; the default
//!     rtol = 10⁻² (2π dt)^p / N,   clamped to [10⁻¹³, 10⁻⁶],
//! keeps it a hundred times below the time error. A case's `rtol` overrides it.

use super::checkpoint::Carried;
use super::stepper::{Rhs, Stepper};
use crate::case::{Integrator, Krylov};
use crate::linalg::bicgstab::BiCgStab;
use crate::linalg::cg::{self, combine, Cg, CgParams, Norm, Start};
use crate::operator::LinearOperator;
use crate::output::record::ImplicitSolves;
use std::f64::consts::TAU;

/// Iterations per step before a solve stops unconverged, unless the case sets `max_iterations`.
pub const DEFAULT_MAX_ITERATIONS: usize = 1000;

/// The default relative tolerance of the solves (module doc).
pub fn default_rtol(integrator: Integrator, dt: f64, steps: usize) -> f64 {
    let time_error = (TAU * dt).powi(integrator.order() as i32);
    (1e-2 * time_error / steps as f64).clamp(1e-13, 1e-6)
}

pub struct Theta<'a, Op: LinearOperator, P: LinearOperator> {
    rhs: Rhs<'a, Op>,
    theta: f64,
    /// The dt the preconditioner was made for.
    dt: f64,
    preconditioner: &'a P,
    preconditioner_workspace: P::Workspace,
    solver: Solver,
    /// L uⁿ, then L p inside the solve; the right-hand side.
    lu: Vec<f64>,
    b: Vec<f64>,
    rtol: f64,
    max_iterations: usize,
    solves: usize,
    iterations: usize,
    most_iterations: usize,
    unconverged: usize,
}

impl<'a, Op: LinearOperator, P: LinearOperator> Theta<'a, Op, P> {
    /// `integrator` is `BackwardEuler` or `CrankNicolson`; `preconditioner` approximates
    /// (I − θ dt L)⁻¹ for this `dt`.
    pub fn new(
        integrator: Integrator,
        rhs: Rhs<'a, Op>,
        preconditioner: &'a P,
        len: usize,
        dt: f64,
        solves: Solves,
    ) -> Self {
        let Solves {
            rtol,
            max_iterations,
            krylov,
        } = solves;
        Theta {
            rhs,
            theta: theta(integrator),
            dt,
            preconditioner,
            preconditioner_workspace: preconditioner.workspace(),
            solver: match krylov {
                Krylov::Cg => Solver::Cg(Cg::new(len)),
                Krylov::Bicgstab => Solver::BiCgStab(BiCgStab::new(len)),
            },
            lu: vec![0.0; len],
            b: vec![0.0; len],
            rtol,
            max_iterations,
            solves: 0,
            iterations: 0,
            most_iterations: 0,
            unconverged: 0,
        }
    }
}

/// How each θ-step solves: the relative tolerance, the iteration cap and the Krylov method.
#[derive(Clone, Copy, Debug)]
pub struct Solves {
    pub rtol: f64,
    pub max_iterations: usize,
    pub krylov: Krylov,
}

/// The buffers of the `Krylov` method the solves use.
enum Solver {
    Cg(Cg),
    BiCgStab(BiCgStab),
}

/// θ of an implicit integrator.
pub fn theta(integrator: Integrator) -> f64 {
    match integrator {
        Integrator::BackwardEuler => 1.0,
        Integrator::CrankNicolson => 0.5,
        other => panic!("{other:?} is not a θ-scheme"),
    }
}

impl<Op: LinearOperator, P: LinearOperator> Stepper for Theta<'_, Op, P> {
    fn step(&mut self, u: &mut [f64], t: f64, dt: f64) -> f64 {
        assert_eq!(dt, self.dt, "the preconditioner was made for this dt");
        let Theta {
            rhs,
            theta,
            preconditioner,
            preconditioner_workspace,
            lu,
            b,
            rtol,
            max_iterations,
            solver,
            ..
        } = self;
        let (theta, ranks) = (*theta, rhs.ranks);
        rhs.apply(u, lu);
        ranks.on(|| combine(b, u, (1.0 - theta) * dt, lu));
        rhs.add_source(&[(t + dt, theta * dt), (t, (1.0 - theta) * dt)], b);
        let shift = theta * dt;
        let system = &mut cg::Closures {
            len: u.len(),
            apply: |p: &[f64], ap: &mut [f64]| {
                rhs.apply(p, lu);
                ranks.on(|| combine(ap, p, -shift, lu));
            },
            precondition: |r: &[f64], z: &mut [f64]| {
                preconditioner.apply(r, z, preconditioner_workspace)
            },
            dot: |x: &[f64], y: &[f64]| ranks.sum(ranks.on(|| cg::dot(x, y))),
        };
        // From the previous step's field, until ‖r‖/‖b‖ ≤ rtol.
        let params = CgParams {
            start: Start::Guess,
            rtol: *rtol,
            norm: Norm::Residual,
            max_iterations: *max_iterations,
            pool: ranks.pool(),
        };
        let convergence = match solver {
            Solver::Cg(cg) => cg.solve(system, b, u, &params),
            Solver::BiCgStab(bicgstab) => {
                bicgstab.solve(system, b, u, *rtol, *max_iterations, ranks.pool())
            }
        };
        self.solves += 1;
        self.iterations += convergence.iterations;
        self.most_iterations = self.most_iterations.max(convergence.iterations);
        if !convergence.converged {
            self.unconverged += 1;
        }
        self.rhs.ranks.max_abs(u)
    }

    fn carry(&self, carried: &mut Carried) {
        carried.put_count("theta.solves", self.solves);
        carried.put_count("theta.iterations", self.iterations);
        carried.put_count("theta.most_iterations", self.most_iterations);
        carried.put_count("theta.unconverged", self.unconverged);
    }

    fn take_back(&mut self, carried: &Carried) {
        let count = |name| carried.count(name).unwrap_or(0);
        self.solves = count("theta.solves");
        self.iterations = count("theta.iterations");
        self.most_iterations = count("theta.most_iterations");
        self.unconverged = count("theta.unconverged");
    }

    fn solves(&self) -> ImplicitSolves {
        ImplicitSolves {
            solve_iterations_mean: Some(self.iterations as f64 / self.solves.max(1) as f64),
            solve_iterations_max: Some(self.most_iterations),
            solves_unconverged: Some(self.unconverged),
            solve_rtol: Some(self.rtol),
        }
    }

    fn applications(&self) -> Option<usize> {
        Some(self.rhs.applications)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};
    use crate::discretization::stability::forward_euler_dt_stable;
    use crate::discretization::stencil::Stencil;
    use crate::operator::{Identity, RowOperator, SinePreconditioner, StencilOperator};
    use crate::parallel::exchange::Ranks;

    /// Preconditioned and plain CG solve the same θ-step to the tolerance, and the sine
    /// transform saves most of the iterations (2D, ε = 4h, dt = 100 dt_stable).
    #[test]
    fn the_preconditioner_changes_the_iterations_not_the_step() {
        let grid = Grid::new(2, 48);
        let stencil = Stencil::new(
            grid,
            Horizon::from_m(&grid, 4),
            Kernel::Linear,
            Quadrature::Midpoint,
            1.0,
        );
        let operator = StencilOperator::new(&stencil);
        let dt = 100.0 * forward_euler_dt_stable(&stencil);
        let u0: Vec<f64> = (0..grid.nodes())
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let rtol = 1e-12;
        for integrator in [Integrator::BackwardEuler, Integrator::CrankNicolson] {
            let sine = SinePreconditioner::new(&stencil, theta(integrator) * dt);
            let (mut with, mut without) = (u0.clone(), u0.clone());
            let iterations = |solves: ImplicitSolves| solves.solve_iterations_max.unwrap();
            let with_iterations = iterations(theta_step(
                &sine, &operator, &mut with, integrator, dt, rtol,
            ));
            let without_iterations = iterations(theta_step(
                &Identity,
                &operator,
                &mut without,
                integrator,
                dt,
                rtol,
            ));
            let scale = u0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let difference = with
                .iter()
                .zip(&without)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                difference < 1e-9 * scale,
                "{integrator:?}: the two solves differ by {difference:e}"
            );
            assert!(
                3 * with_iterations < without_iterations,
                "{integrator:?}: {with_iterations} iterations preconditioned, {without_iterations} without"
            );
        }
    }

    /// BiCGStab's θ-step with the non-symmetric x-centred form of a varying horizon (1D
    /// transition and 2D ramp, dt = 100× Gershgorin's explicit step), preconditioned by the sine
    /// transform at the smallest ε and not, is the dense LU solve of the same step to the
    /// tolerance.
    #[test]
    fn bicgstab_takes_the_dense_solves_step_with_a_non_symmetric_operator() {
        use crate::case::{Formulation, HorizonProfile};
        use crate::discretization::variable_horizon::VariableHorizonOperator;
        use faer::linalg::solvers::Solve;
        let transition = HorizonProfile::Transition {
            left: 0.1,
            right: 0.025,
            start: 0.4,
            end: 0.6,
        };
        let ramp = HorizonProfile::Linear {
            left: 0.1,
            right: 0.05,
        };
        for (dim, n, profile, eps_min) in [(1, 200, transition, 0.025), (2, 32, ramp, 0.05)] {
            let variable = VariableHorizonOperator::new(
                dim,
                n,
                profile,
                0.1,
                Kernel::Linear,
                1.0,
                Formulation::XCentred,
            );
            let rows: Vec<Vec<(usize, f64)>> = variable.rows_with_zero_collar().collect();
            let operator = RowOperator::new(rows.clone());
            let len = rows.len();
            let dt = 100.0 * 2.0 / operator.lambda_bound();
            let u0: Vec<f64> = (0..len)
                .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
                .collect();
            let grid = Grid::new(dim, n);
            let stencil = Stencil::new(
                grid,
                Horizon::from_eps(&grid, eps_min),
                Kernel::Linear,
                Quadrature::Midpoint,
                1.0,
            );
            for integrator in [Integrator::BackwardEuler, Integrator::CrankNicolson] {
                let theta = theta(integrator);
                let mut a = faer::Mat::<f64>::identity(len, len);
                let mut b = faer::Mat::<f64>::from_fn(len, 1, |i, _| u0[i]);
                for (i, row) in rows.iter().enumerate() {
                    for &(j, v) in row {
                        a[(i, j)] -= theta * dt * v;
                        b[(i, 0)] += (1.0 - theta) * dt * v * u0[j];
                    }
                }
                let exact = a.partial_piv_lu().solve(&b);
                let sine = SinePreconditioner::new(&stencil, theta * dt);
                let rtol = 1e-12;
                for preconditioned in [true, false] {
                    let mut u = u0.clone();
                    let rhs = Rhs::new(&operator, None, Ranks::single());
                    let solves = match preconditioned {
                        true => step_with(&sine, rhs, &mut u, integrator, dt, rtol),
                        false => step_with(&Identity, rhs, &mut u, integrator, dt, rtol),
                    };
                    assert_eq!(solves.solves_unconverged, Some(0));
                    let scale = (0..len).fold(0.0f64, |m, i| m.max(exact[(i, 0)].abs()));
                    let error = (0..len).fold(0.0f64, |m, i| m.max((u[i] - exact[(i, 0)]).abs()));
                    assert!(
                        error < 1e-9 * scale,
                        "{dim}D {integrator:?} preconditioned {preconditioned}: {error:e} from LU ({solves:?})"
                    );
                }
            }
        }
    }

    /// One BiCGStab θ-step from u.
    fn step_with<P: LinearOperator>(
        preconditioner: &P,
        rhs: Rhs<'_, RowOperator>,
        u: &mut [f64],
        integrator: Integrator,
        dt: f64,
        rtol: f64,
    ) -> ImplicitSolves {
        let len = u.len();
        let mut theta = Theta::new(
            integrator,
            rhs,
            preconditioner,
            len,
            dt,
            Solves {
                rtol,
                max_iterations: 10_000,
                krylov: Krylov::Bicgstab,
            },
        );
        theta.step(u, 0.0, dt);
        theta.solves()
    }

    /// One θ-step from u with `preconditioner`, and what its solve took.
    fn theta_step<P: LinearOperator>(
        preconditioner: &P,
        operator: &StencilOperator,
        u: &mut [f64],
        integrator: Integrator,
        dt: f64,
        rtol: f64,
    ) -> ImplicitSolves {
        let rhs = Rhs::new(operator, None, Ranks::single());
        let mut theta = Theta::new(
            integrator,
            rhs,
            preconditioner,
            u.len(),
            dt,
            Solves {
                rtol,
                max_iterations: 100_000,
                krylov: Krylov::Cg,
            },
        );
        theta.step(u, 0.0, dt);
        theta.solves()
    }
}
