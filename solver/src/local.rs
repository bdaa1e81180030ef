//! The local diffusion equation ∂c/∂t = D∇²c of seed 004 on the grid: explicit finite differences
//! and Peaceman–Rachford ADI, on D = (−L/2, L/2)^d with c = 0 on the boundary.
//!
//! The grid has n interior nodes per side, x_i = −L/2 + (i + 1) h with h = L/(n + 1), so the
//! boundary nodes i = −1 and i = n, where c = 0, are not stored.
//!
//! **Von Neumann bound of the explicit scheme.** Forward Euler with the (2d+1)-point Laplacian
//! multiplies the Fourier mode e^{i k·x} by g = 1 − (4 D dt / h²) Σ_a sin²(k_a h/2). The worst
//! mode has every sin² = 1, so g = 1 − 4 d D dt / h², and |g| ≤ 1 requires dt ≤ h² / (2 d D).
//! With zero Dirichlet data the modes are the sines of the grid, whose largest sin² is
//! cos²(π/(2(n+1))) < 1, so the bound is (just) sufficient on the bounded grid too.

use crate::case::{Case, CaseError};
use crate::diagnostics::{self, MassSeries};
use crate::euler::{forward_euler, timed_steps, Stepping, Trajectory};
use crate::operator::NonlocalOperator;
use crate::problem::Problem;
use crate::record::{Distribution, Resolved};
use crate::run::{median, Measured, Outcome};
use rayon::prelude::*;
use std::f64::consts::PI;
use std::time::Instant;

/// Default side L of the seed's domain.
pub const DEFAULT_LENGTH: f64 = 2.0;

/// The interior nodes of (−L/2, L/2)^d, n per side.
#[derive(Clone, Copy, Debug)]
pub struct LocalGrid {
    pub dim: usize,
    pub n: usize,
    pub length: f64,
    pub h: f64,
}

impl LocalGrid {
    pub fn new(dim: usize, n: usize, length: f64) -> Self {
        LocalGrid {
            dim,
            n,
            length,
            h: length / (n + 1) as f64,
        }
    }

    pub fn nodes(&self) -> usize {
        self.n.pow(self.dim as u32)
    }

    pub fn volume(&self) -> f64 {
        self.h.powi(self.dim as i32)
    }

    fn coordinate(&self, i: usize) -> f64 {
        -self.length / 2.0 + (i + 1) as f64 * self.h
    }

    /// The coordinates of node `index` (index = iy·n + ix; one coordinate in 1D).
    fn position(&self, index: usize) -> [f64; 2] {
        let (ix, iy) = (index % self.n, index / self.n);
        [self.coordinate(ix), self.coordinate(iy)]
    }

    /// h² / (2 d D): the explicit scheme's stable step (module comment).
    pub fn explicit_dt_stable(&self, diffusivity: f64) -> f64 {
        self.h * self.h / (2.0 * self.dim as f64 * diffusivity)
    }

    /// The initial field of `problem` on the nodes.
    pub fn sample(&self, problem: Problem) -> Vec<f64> {
        (0..self.nodes())
            .into_par_iter()
            .map(|i| initial_value(problem, &self.position(i)[..self.dim], self.length))
            .collect()
    }
}

/// c(x, 0) of a local problem at x ∈ (−L/2, L/2)^d.
pub(crate) fn initial_value(problem: Problem, x: &[f64], length: f64) -> f64 {
    match problem {
        Problem::Eigenmode => x.iter().map(|&s| (PI * s / length).cos()).product(),
        // c = 1 where every |x_a| < L/4 (seed 004), 0 elsewhere.
        _ => f64::from(u8::from(x.iter().all(|s| s.abs() < length / 4.0))),
    }
}

/// The exact eigenmode solution's decay factor at time t: exp(−d π² D t / L²).
pub fn eigenmode_decay(dim: usize, length: f64, diffusivity: f64, t: f64) -> f64 {
    (-(dim as f64) * PI * PI * diffusivity * t / (length * length)).exp()
}

/// D ∇²_h with c = 0 beyond the boundary: the 3-point (1D) or 5-point (2D) central difference.
pub struct Laplacian {
    grid: LocalGrid,
    diffusivity: f64,
}

impl NonlocalOperator for Laplacian {
    fn apply(&self, u: &[f64], out: &mut [f64]) {
        let n = self.grid.n;
        let scale = self.diffusivity / (self.grid.h * self.grid.h);
        let dim = self.grid.dim;
        out.par_chunks_mut(n).enumerate().for_each(|(y, out_row)| {
            for (x, value) in out_row.iter_mut().enumerate() {
                let across = if dim == 2 { along_y(u, x, y, n) } else { 0.0 };
                *value = scale * (along_x(u, x, y, n) + across);
            }
        });
    }
}

/// Runs a grid case (`fd_explicit`, or `adi` when `implicit`).
pub fn run(case: &Case, implicit: bool) -> Result<Outcome, CaseError> {
    let setup_started = Instant::now();
    let grid = LocalGrid::new(case.dim, case.n, case.length());
    let dt_stable = grid.explicit_dt_stable(case.diffusivity);
    let (dt, steps) = crate::run::time_step(case, dt_stable, implicit)?;
    let u0 = grid.sample(case.problem);
    let divergence_bound = crate::run::divergence_bound(case, diagnostics::max_abs(&u0), None);
    let setup_s = setup_started.elapsed().as_secs_f64();
    let stepping = Stepping {
        dt,
        steps,
        divergence_bound,
        track_total_error: false,
        volume: grid.volume(),
        diagnostics_every: case.diagnostics_every,
    };
    let trajectory = if implicit {
        Adi::new(grid, case.diffusivity, dt).integrate(u0, &stepping)
    } else {
        let laplacian = Laplacian {
            grid,
            diffusivity: case.diffusivity,
        };
        forward_euler(&laplacian, u0, None, &stepping)
    };
    let resolved = Resolved {
        h: grid.h,
        eps: None,
        m: None,
        c: None,
        dt,
        dt_stable,
        steps,
        nodes: grid.nodes(),
        bonds: 2 * grid.dim * grid.nodes(),
        pair_visits: None,
    };
    let position = |i: usize| grid.position(i);
    Ok(outcome(
        case, resolved, setup_s, &stepping, trajectory, position,
    ))
}

/// The outcome of a local run whose node or particle i sits at `position(i)`: errors against
/// the exact eigenmode (when that is the problem), diagnostics and the record.
pub(crate) fn outcome(
    case: &Case,
    resolved: Resolved,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: Trajectory,
    position: impl Fn(usize) -> [f64; 2] + Sync,
) -> Outcome {
    let Trajectory {
        u, timing, c_tot, ..
    } = trajectory;
    let t_final = timing.steps_done as f64 * stepping.dt;
    let errors = (case.problem == Problem::Eigenmode && timing.diverged_at.is_none()).then(|| {
        let decay = eigenmode_decay(case.dim, case.length(), case.diffusivity, t_final);
        let exact = |i: usize| {
            decay * initial_value(Problem::Eigenmode, &position(i)[..case.dim], case.length())
        };
        (
            diagnostics::squared_l2_error(exact, &u, stepping.volume),
            diagnostics::max_error(exact, &u),
        )
    });
    let measured = Measured {
        setup_s,
        solve_s: timing.solve_seconds,
        step_s: median(timing.step_seconds),
        steps_done: timing.steps_done,
        diverged_at: timing.diverged_at,
        divergence_bound: stepping.divergence_bound,
        errors,
        error_total: None,
        mass: diagnostics::total_mass(&u, stepping.volume),
        max_abs: diagnostics::max_abs(&u),
        c_tot,
        histogram: crate::run::histogram(case, &u),
        distribution: Distribution::serial(case),
    };
    Outcome {
        record: crate::run::record(case, resolved, measured),
        field: u,
    }
}

/// Peaceman–Rachford ADI: per step of dt, a half step implicit in x and explicit in y, then one
/// implicit in y and explicit in x, each of dt/2:
///     (1 − ½dt D δx²) c* = (1 + ½dt D δy²) cⁿ,   (1 − ½dt D δy²) cⁿ⁺¹ = (1 + ½dt D δx²) c*.
/// Seed 004 writes each half step with Δt; its Δt is our dt/2. In 1D there is no y: the two
/// halves compose to Crank–Nicolson. Both are second order in dt and unconditionally stable.
pub struct Adi {
    grid: LocalGrid,
    /// r = ½ dt D / h².
    r: f64,
    thomas: Thomas,
}

impl Adi {
    pub fn new(grid: LocalGrid, diffusivity: f64, dt: f64) -> Self {
        let r = 0.5 * dt * diffusivity / (grid.h * grid.h);
        Adi {
            grid,
            r,
            thomas: Thomas::new(grid.n, -r, 1.0 + 2.0 * r),
        }
    }

    /// Steps forward from u, in the shared timed loop.
    fn integrate(&self, mut u: Vec<f64>, stepping: &Stepping) -> Trajectory {
        // Buffers for c* (by rows) and for cⁿ⁺¹ by columns, allocated once.
        let mut half = vec![0.0; u.len()];
        let mut by_columns = vec![0.0; u.len()];
        let mass = |u: &[f64]| diagnostics::total_mass(u, stepping.volume);
        let mut c_tot = MassSeries::start(
            stepping.diagnostics_every,
            stepping.dt,
            stepping.steps,
            mass(&u),
        );
        let timing = timed_steps(
            &mut u,
            stepping.steps,
            stepping.divergence_bound,
            |u, _| {
                self.step(u, &mut half, &mut by_columns);
                diagnostics::max_abs(u)
            },
            |u, k| MassSeries::observe_if(&mut c_tot, k, || mass(u)),
        );
        Trajectory {
            u,
            timing,
            error_total: None,
            c_tot,
        }
    }

    fn step(&self, u: &mut [f64], half: &mut [f64], by_columns: &mut [f64]) {
        let n = self.grid.n;
        let r = self.r;
        if self.grid.dim == 1 {
            // c* solves the implicit half; cⁿ⁺¹ = (1 + r δx²) c*.
            half.copy_from_slice(u);
            self.thomas.solve(half);
            for x in 0..n {
                u[x] = half[x] + r * second_difference(half, x, n);
            }
            return;
        }
        // Half 1, row by row: rhs = (1 + r δy²) cⁿ, then the x-implicit solve in place.
        half.par_chunks_mut(n).enumerate().for_each(|(y, line)| {
            for (x, value) in line.iter_mut().enumerate() {
                *value = u[y * n + x] + r * along_y(u, x, y, n);
            }
            self.thomas.solve(line);
        });
        // Half 2, column by column: rhs = (1 + r δx²) c*, then the y-implicit solve in place.
        by_columns
            .par_chunks_mut(n)
            .enumerate()
            .for_each(|(x, column)| {
                for (y, value) in column.iter_mut().enumerate() {
                    *value = half[y * n + x] + r * along_x(half, x, y, n);
                }
                self.thomas.solve(column);
            });
        // Back to rows.
        u.par_chunks_mut(n).enumerate().for_each(|(y, row)| {
            for (x, value) in row.iter_mut().enumerate() {
                *value = by_columns[x * n + y];
            }
        });
    }
}

/// c_{x−1} − 2c_x + c_{x+1} along a row of `u` (1D: the whole field), zero beyond the ends.
fn second_difference(u: &[f64], x: usize, n: usize) -> f64 {
    let left = if x > 0 { u[x - 1] } else { 0.0 };
    let right = if x + 1 < n { u[x + 1] } else { 0.0 };
    left - 2.0 * u[x] + right
}

/// δx² at (x, y) of a row-major n × n field, zero beyond the boundary.
fn along_x(u: &[f64], x: usize, y: usize, n: usize) -> f64 {
    second_difference(&u[y * n..(y + 1) * n], x, n)
}

/// δy² at (x, y) of a row-major n × n field, zero beyond the boundary.
fn along_y(u: &[f64], x: usize, y: usize, n: usize) -> f64 {
    let below = if y > 0 { u[(y - 1) * n + x] } else { 0.0 };
    let above = if y + 1 < n { u[(y + 1) * n + x] } else { 0.0 };
    below - 2.0 * u[y * n + x] + above
}

/// The Thomas algorithm for the constant tridiagonal matrix (a, b, a) of order n with the
/// elimination factors precomputed once, so that a solve is two sweeps over the line and
/// allocates nothing.
pub struct Thomas {
    a: f64,
    /// c'_i of the forward sweep and 1/(b − a c'_{i−1}).
    upper: Vec<f64>,
    inverse_pivot: Vec<f64>,
}

impl Thomas {
    pub fn new(n: usize, a: f64, b: f64) -> Self {
        let mut upper = Vec::with_capacity(n);
        let mut inverse_pivot = Vec::with_capacity(n);
        let mut previous = 0.0;
        for _ in 0..n {
            let pivot = 1.0 / (b - a * previous);
            inverse_pivot.push(pivot);
            previous = a * pivot;
            upper.push(previous);
        }
        Thomas {
            a,
            upper,
            inverse_pivot,
        }
    }

    /// Overwrites `d` with the solution x of the system.
    pub fn solve(&self, d: &mut [f64]) {
        let n = d.len();
        let mut previous = 0.0;
        for i in 0..n {
            previous = (d[i] - self.a * previous) * self.inverse_pivot[i];
            d[i] = previous;
        }
        for i in (0..n.saturating_sub(1)).rev() {
            d[i] -= self.upper[i] * d[i + 1];
        }
    }
}
