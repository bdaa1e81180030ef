//! The stepper a case's `integrator` names, for any operator: forward Euler, Heun and RK4, or
//! the θ-schemes with a preconditioned CG (BiCGStab for a non-symmetric L_h).

use super::euler::ForwardEuler;
use super::runge_kutta::RungeKutta;
use super::stepper::{Rhs, Stepper};
use super::theta::{default_rtol, Solves, Theta, DEFAULT_MAX_ITERATIONS};
use super::timed::Stepping;
use crate::case::{Case, Integrator};
use crate::operator::LinearOperator;
use crate::parallel::exchange::Ranks;
use crate::problem::Source;

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
