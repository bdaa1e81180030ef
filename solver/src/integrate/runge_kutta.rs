//! Explicit Runge–Kutta methods whose stages each use only the previous one (Heun's RK2 and the
//! classical RK4), for u' = L u + b(t):
//!     k₁ = f(t, u),  kₛ = f(t + cₛ dt, u + aₛ dt kₛ₋₁),  u ← u + dt Σ bₛ kₛ.
//! The source is evaluated at each stage's time, so the observed order is the method's. Each
//! stage is one application of L and two passes over the vectors; every pass splits them at fixed
//! blocks, so results do not depend on the thread or rank count.

use super::stepper::{Rhs, Stepper};
use crate::case::Integrator;
use crate::linalg::cg::{axpy, combine};
use crate::operator::LinearOperator;
use crate::parallel::exchange::Ranks;
use crate::problem::Source;
use crate::threads::BLOCK;
use rayon::prelude::*;

/// One stage: (c, a, b) of the tableau.
type Stage = (f64, f64, f64);

const HEUN: [Stage; 2] = [(0.0, 0.0, 0.5), (1.0, 1.0, 0.5)];
const RK4: [Stage; 4] = [
    (0.0, 0.0, 1.0 / 6.0),
    (0.5, 0.5, 1.0 / 3.0),
    (0.5, 0.5, 1.0 / 3.0),
    (1.0, 1.0, 1.0 / 6.0),
];

/// The tableau of `integrator`, `Heun` or `Rk4`.
fn tableau(integrator: Integrator) -> &'static [Stage] {
    match integrator {
        Integrator::Heun => &HEUN,
        Integrator::Rk4 => &RK4,
        other => panic!("{other:?} is not an explicit Runge–Kutta method"),
    }
}

/// The stages of a step of `integrator` (`Heun` or `Rk4`), each one application of L.
pub fn stages(integrator: Integrator) -> usize {
    tableau(integrator).len()
}

/// R(z) of `integrator` (`Heun` or `Rk4`): `step`'s loop on u' = λu from u = 1, z = dt·λ, with
/// w = dt·k: w₁ = z, wₛ = z(1 + aₛ wₛ₋₁), R = 1 + Σ bₛ wₛ.
pub fn stability_function(integrator: Integrator, z: f64) -> f64 {
    let (mut w, mut sum) = (0.0, 0.0);
    for &(_, a, b) in tableau(integrator) {
        w = z * (1.0 + a * w);
        sum += b * w;
    }
    1.0 + sum
}

pub struct RungeKutta<'a, Op: LinearOperator> {
    rhs: Rhs<'a, Op>,
    stages: &'static [Stage],
    /// u + aₛ dt kₛ₋₁, the stage's rate kₛ, and Σ bₛ kₛ so far.
    stage: Vec<f64>,
    rate: Vec<f64>,
    sum: Vec<f64>,
}

impl<'a, Op: LinearOperator> RungeKutta<'a, Op> {
    /// `integrator` is `Heun` or `Rk4`, for vectors of `len` values.
    pub fn new(
        integrator: Integrator,
        operator: &'a Op,
        source: Option<&'a Source>,
        ranks: Ranks<'a>,
        len: usize,
    ) -> Self {
        RungeKutta {
            rhs: Rhs::new(operator, source, ranks),
            stages: tableau(integrator),
            stage: vec![0.0; len],
            rate: vec![0.0; len],
            sum: vec![0.0; len],
        }
    }
}

impl<Op: LinearOperator> Stepper for RungeKutta<'_, Op> {
    fn step(&mut self, u: &mut [f64], t: f64, dt: f64) -> f64 {
        let ranks = self.rhs.ranks;
        for (s, &(c, a, b)) in self.stages.iter().enumerate() {
            if s == 0 {
                self.rhs.rate(t, u, &mut self.rate);
            } else {
                let (stage, rate) = (&mut self.stage, &self.rate);
                ranks.on(|| combine(stage, u, a * dt, rate));
                self.rhs.rate(t + c * dt, &self.stage, &mut self.rate);
            }
            let (sum, rate) = (&mut self.sum, &self.rate);
            ranks.on(|| {
                if s == 0 {
                    scale(sum, b, rate)
                } else {
                    axpy(b, rate, sum)
                }
            });
        }
        let sum = &self.sum;
        ranks.on(|| axpy(dt, sum, u));
        self.rhs.ranks.max_abs(u)
    }

    fn applications(&self) -> Option<usize> {
        Some(self.rhs.applications)
    }
}

/// out = a y.
fn scale(out: &mut [f64], a: f64, y: &[f64]) {
    out.par_chunks_mut(BLOCK)
        .zip(y.par_chunks(BLOCK))
        .for_each(|(o, y)| o.iter_mut().zip(y).for_each(|(o, &y)| *o = a * y));
}
