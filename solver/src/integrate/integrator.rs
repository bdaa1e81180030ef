//! The stepper a case's `integrator` names, for any operator: forward Euler, Heun and RK4, or
//! the θ-schemes with a preconditioned CG (BiCGStab for a non-symmetric L_h).

use super::euler::ForwardEuler;
use super::runge_kutta::{self, RungeKutta};
use super::stepper::{Rhs, Stepper};
use super::theta::{default_rtol, theta, Solves, Theta, DEFAULT_MAX_ITERATIONS};
use super::timed::Stepping;
use crate::case::{Case, Integrator};
use crate::operator::LinearOperator;
use crate::parallel::exchange::Ranks;
use crate::problem::Source;

/// The integrator's stability function R(z): one step multiplies an eigenvector of L_h with
/// eigenvalue λ by R(dt·λ). From the steppers' own definitions: 1 + z, the Runge–Kutta tableau,
/// (1 + (1 − θ) z) / (1 − θ z). On the negative real axis each |R| is convex or monotone, so
/// over an interval of eigenvalues its largest value is at an end.
pub fn stability_function(integrator: Integrator, z: f64) -> f64 {
    match integrator {
        Integrator::ForwardEuler => 1.0 + z,
        Integrator::Heun | Integrator::Rk4 => runge_kutta::stability_function(integrator, z),
        Integrator::BackwardEuler | Integrator::CrankNicolson => {
            let theta = theta(integrator);
            (1.0 + (1.0 - theta) * z) / (1.0 - theta * z)
        }
    }
}

/// The applications of L_h a step of `integrator` makes: one per stage of an explicit step; an
/// implicit step's, one, besides its solve's iterations.
pub fn applications_per_step(integrator: Integrator) -> usize {
    match integrator {
        Integrator::Heun | Integrator::Rk4 => runge_kutta::stages(integrator),
        Integrator::ForwardEuler | Integrator::BackwardEuler | Integrator::CrankNicolson => 1,
    }
}

/// The stepper of the case's integrator for `operator` on `len` nodes; the θ-schemes solve with
/// CG (BiCGStab when L_h is not symmetric) preconditioned by `preconditioner` (the explicit ones
/// ignore it).
pub fn stepper<'a, Op: LinearOperator, P: LinearOperator>(
    case: &Case,
    operator: &'a Op,
    source: Option<&'a Source>,
    ranks: Ranks<'a>,
    len: usize,
    stepping: &Stepping,
    preconditioner: &'a P,
) -> Box<dyn Stepper + 'a> {
    match case.integrator {
        Integrator::ForwardEuler => Box::new(ForwardEuler::new(operator, source, ranks, len)),
        Integrator::Heun | Integrator::Rk4 => Box::new(RungeKutta::new(
            case.integrator,
            operator,
            source,
            ranks,
            len,
        )),
        Integrator::BackwardEuler | Integrator::CrankNicolson => {
            let (dt, steps) = (stepping.dt, stepping.steps);
            Box::new(Theta::new(
                case.integrator,
                Rhs::new(operator, source, ranks),
                preconditioner,
                len,
                dt,
                Solves {
                    rtol: case
                        .rtol
                        .unwrap_or_else(|| default_rtol(case.integrator, dt, steps)),
                    max_iterations: case.max_iterations.unwrap_or(DEFAULT_MAX_ITERATIONS),
                    krylov: case.krylov(),
                },
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stability functions the tableau and θ give are the textbook ones: Taylor's sums to
    /// the order for the explicit methods, 1/(1 − z) and (1 + z/2)/(1 − z/2); RK4's meets 1 on
    /// the negative axis at 2.7852935634, which `discretization::stability` states.
    #[test]
    fn the_stability_functions_are_the_textbooks() {
        let taylor = |z: f64, terms: i32| {
            (0..=terms)
                .map(|j| z.powi(j) / (1..=j).product::<i32>() as f64)
                .sum::<f64>()
        };
        for z in [-3.0, -2.785_293_563_405_282, -1.0, -0.1, 0.5] {
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs().max(1.0);
            assert!(close(
                stability_function(Integrator::ForwardEuler, z),
                taylor(z, 1)
            ));
            assert!(close(stability_function(Integrator::Heun, z), taylor(z, 2)));
            assert!(close(stability_function(Integrator::Rk4, z), taylor(z, 4)));
            assert!(close(
                stability_function(Integrator::BackwardEuler, z),
                1.0 / (1.0 - z)
            ));
            let cn = (1.0 + z / 2.0) / (1.0 - z / 2.0);
            assert!(close(stability_function(Integrator::CrankNicolson, z), cn));
        }
        assert!((stability_function(Integrator::Rk4, -2.785_293_563_405_282) - 1.0).abs() < 1e-12);
        let all = [
            Integrator::ForwardEuler,
            Integrator::Heun,
            Integrator::Rk4,
            Integrator::BackwardEuler,
            Integrator::CrankNicolson,
        ];
        assert_eq!(all.map(applications_per_step), [1, 2, 4, 1, 1]);
    }
}
