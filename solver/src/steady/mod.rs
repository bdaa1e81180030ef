//! Steady nonlocal diffusion (seed 001): −L u = f on Ω = [0,1]², u = g on the interaction layer Γ,
//! solved by unpreconditioned CG on the single-domain system (`steady_cg`) or by FETI on p × p
//! subdomains (`feti`).
//!
//! **Discretization** (seed 001, section 4). L × L particles x_i = ((i₁ + ½)h, (i₂ + ½)h), h = 1/L,
//! each with volume ω = h²; Γ is the layer of m particles around Ω. Particle i interacts with the
//! (2m + 1)² − 1 particles of the square |x_j − x_i|∞ ≤ δ = m h, with the kernel
//! γ(x, y) = c J(|x − y|/δ) (J = 1/r gives seed 001's C/|x − y| with C = c δ). The energy of
//! eq. 19 has the gradient A u − f with
//!     (A u)_i = 2 Σ_j γ_ij ω_i ω_j (u_i − u_j),  f_i = ω_i f(x_i) + 2 Σ_{j ∈ Γ} γ_ij ω_i ω_j g(x_j),
//! where u_j = 0 for j ∈ Γ in the first sum. (The seed prints f with a minus and without the 2;
//! differentiating its energy gives the signs above.) We store A/ω and f/ω: the same solution,
//! the same CG iterates and relative residuals, and A/ω = −L_h, the stencil operator of
//! `Stencil::square` with the weights w_o = 2 γ(o h) h² and u = 0 on Γ. So the CG baseline applies
//! A matrix-free with the register-blocked stencil kernels (serial and distributed); FETI
//! assembles its subdomain matrices as faer sparse matrices (`assembly`).
//!
//! **The constant c.** For u = |x|², u(x + z) − u(x) = 2x·z + |z|², so
//!     L u = 2 ∫_{[−δ,δ]²} (u(x + z) − u(x)) c J(|z|/δ) dz = 2c δ⁴ Q_J,  Q_J = ∫_{[−1,1]²} J(|s|) |s|² ds,
//! and L → kΔ (Δu = 4) requires c = 2k / (δ⁴ Q_J). For J = 1/r, Q = ∫_{[−1,1]²} |s| ds =
//! (4/3)(√2 + asinh 1), so C = c δ = 3k / (2 (√2 + asinh 1) δ³) ∝ δ⁻³, the seed's scaling. For the
//! separable J = 1 and J = e^{−r²}, Q_J = 8 M₀ M₂ (M_i = ∫₀¹ J rⁱ dr).
//!
//! **Quadratic exactness.** On the lattice, L_h |x|² = 2c h⁴ Σ_o J(|o|/m) |o|² (odd terms cancel),
//! a Riemann sum of 2c δ⁴ Q_J that is not equal to it: with `quadrature: midpoint` (the seed's
//! ω_j = h²) the scheme is *not* exact for the manufactured u = x₁² + x₂², and since the sum's
//! relative error depends on m only, the error does not shrink as h → 0 at fixed m. With
//! `quadrature: ac`, c is instead fitted to the lattice, c = 2k / (h⁴ Σ_o J(|o|/m) |o|²), which
//! makes L_h exact on quadratics (as seed 002's AC quadrature is), so the discrete solution is
//! u itself and the error measures the solver alone.

pub mod assembly;
pub mod cg;
pub mod cholesky;
pub mod decomposition;
pub mod distributed;
pub mod exchange;
pub mod feti;

use crate::case::{positive, refuse_given, Case, CaseError, Method};
use crate::diagnostics::{fixed_order_sum, max_error, squared_l2_error};
use crate::grid::{Grid, Horizon};
use crate::influence::Kernel;
use crate::operator::{self, Backend};
use crate::partition::Partition;
use crate::problem::{Collar, Problem};
use crate::quadrature::Quadrature;
use crate::record::{Distribution, Provenance, Record, Resolved, Status, SteadySolve};
use crate::run::Outcome;
use crate::stencil::Stencil;
use rayon::prelude::*;
use std::time::Instant;

/// Default iteration limit of a steady solve: far beyond the L/m that CG needs.
pub const MAX_ITERATIONS: usize = 100_000;

/// The steady problem of a case: the square stencil of A = −L_h and the data.
pub struct SteadyProblem {
    pub stencil: Stencil,
    /// k of the local limit kΔ.
    pub diffusivity: f64,
    pub rtol: f64,
}

/// The manufactured solution u = x₁² + x₂², also the volume constraint g on Γ.
pub fn exact(x: [f64; 2]) -> f64 {
    x[0] * x[0] + x[1] * x[1]
}

impl SteadyProblem {
    pub fn new(case: &Case) -> Self {
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
            ..Resolved::of_stencil(&self.stencil)
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
        operator.apply(u, &mut lu);
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

/// The steady methods' rules; every other field of a time-dependent case is refused by name.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    let method = serde_json::to_value(case.method).unwrap_or_default();
    if case.dim != 2 {
        return Err(CaseError::new(
            "dim",
            format!("method {method} solves seed 001's problem on [0,1]^2; set `dim` to 2"),
        ));
    }
    let Some(m) = case.m else {
        return Err(CaseError::new(
            if case.eps.is_some() { "eps" } else { "m" },
            "the square neighbourhood spans m particles (δ = m·h): give `m`, not `eps`",
        ));
    };
    if m < 1 || 2 * m > case.n {
        return Err(CaseError::new(
            "m",
            format!("must lie in 1 ..= n/2 = {} (got {m})", case.n / 2),
        ));
    }
    if case.kernel == Kernel::Linear {
        return Err(CaseError::new(
            "kernel",
            "J = 1 − r is negative in the corners of the square neighbourhood; use inverse_distance (seed 001), constant or gaussian",
        ));
    }
    if case.quadrature == Quadrature::PartialVolume {
        return Err(CaseError::new(
            "quadrature",
            "the square neighbourhood covers whole cells, so there are no partial volumes; use midpoint (seed 001) or ac (exact on quadratics)",
        ));
    }
    if case.problem != Problem::Manufactured {
        return Err(CaseError::new(
            "problem",
            format!("method {method} solves the manufactured u = x₁² + x₂²; leave `problem` out"),
        ));
    }
    refuse_given(
        &[
            ("t_end", case.t_end.is_some()),
            ("dt", case.dt.is_some()),
            ("cfl", case.cfl.is_some()),
            ("allow_unstable", case.allow_unstable),
            ("error_total", case.error_total),
            ("source", case.source.is_some()),
            ("collar", case.collar != Collar::Zero),
            ("length", case.length.is_some()),
            ("diagnostics_every", case.diagnostics_every.is_some()),
            ("histogram_bins", case.histogram_bins.is_some()),
            ("field_snapshot", case.field_snapshot.is_some()),
            ("vtk_every", case.vtk_every.is_some()),
        ],
        |field| format!("method {method} is steady (−L u = f, g = u on Γ); leave `{field}` out"),
    )?;
    positive("diffusivity", case.diffusivity)?;
    if case.max_iterations == Some(0) {
        return Err(CaseError::new(
            "max_iterations",
            "must be at least 1 (got 0); leave it out for the default 100000",
        ));
    }
    if let Some(rtol) = case.rtol {
        if !(rtol > 0.0 && rtol < 1.0) {
            return Err(CaseError::new(
                "rtol",
                format!("must lie in (0, 1) (got {rtol}); seed 001 uses 1e-5"),
            ));
        }
    }
    if case.threads < 1 {
        return Err(CaseError::new("threads", "must be at least 1 (got 0)"));
    }
    if case.backend == Backend::NeighbourList {
        return Err(CaseError::new(
            "backend",
            "the neighbour list follows seed 000's Euclidean ball; the square neighbourhood runs on `stencil`, `fft` or `auto`",
        ));
    }
    match case.method {
        Method::SteadyCg => {
            refuse_given(
                &[
                    ("subdomains", case.subdomains.is_some()),
                    ("preconditioner", case.preconditioner.is_some()),
                ],
                |_| "belongs to `feti`; steady_cg is unpreconditioned CG, leave it out".into(),
            )?;
            case.validate_distribution()
        }
        _ => validate_feti(case, m),
    }
}

fn validate_feti(case: &Case, m: usize) -> Result<(), CaseError> {
    let Some(p) = case.subdomains else {
        return Err(CaseError::new(
            "subdomains",
            "feti needs the subdomains per side, p (p × p in all); e.g. 4",
        ));
    };
    // Each Ω_n keeps the nodes farther than δ/2 from the other blocks (eq. 8).
    let narrowest = case.n / p.max(1);
    if p < 1 || narrowest <= 2 * (m / 2) {
        return Err(CaseError::new(
            "subdomains",
            format!(
                "p = {p} gives blocks of {narrowest} nodes per side, which leave no Ω_n after the δ/2 strips (eq. 8) for m = {m}; use p ≤ n/(2⌊m/2⌋ + 1) = {}",
                case.n / (2 * (m / 2) + 1)
            ),
        ));
    }
    if case.ranks < 1 || case.ranks > p * p {
        return Err(CaseError::new(
            "ranks",
            format!(
                "{} ranks for {} subdomains: every rank owns at least one; use 1 ≤ ranks ≤ p² = {}",
                case.ranks,
                p * p,
                p * p
            ),
        ));
    }
    refuse_given(
        &[
            ("px", case.px.is_some()),
            ("py", case.py.is_some()),
            ("partition", case.partition != Partition::Block),
            ("backend", case.backend != Backend::Auto),
        ],
        |_| {
            "feti splits the grid into its p × p subdomains (`subdomains`) and assembles sparse matrices; leave it out".into()
        },
    )
}

/// Runs a steady case in one process, on a rayon pool of `case.threads` threads.
pub fn run(case: &Case) -> Result<Outcome, CaseError> {
    let started = Instant::now();
    let pool = crate::run::thread_pool(case.threads)?;
    let problem = SteadyProblem::new(case);
    if case.method == Method::Feti {
        let outcome = feti::run_on(case, &problem, &exchange::Serial, &pool, started)?;
        return Ok(outcome.expect("the only rank gets the outcome"));
    }
    pool.install(|| {
        let backend = case.backend.resolve(&problem.stencil);
        let operator = operator::plan(backend, &problem.stencil);
        let b = problem.loads();
        let mut u = vec![0.0; b.len()];
        let mut lu = vec![0.0; b.len()];
        let setup_s = started.elapsed().as_secs_f64();
        let solve_started = Instant::now();
        let convergence = cg::conjugate_gradient(
            None,
            |p, ap| {
                operator.apply(p, &mut lu);
                negate_into(&lu, ap);
            },
            cg::dot,
            &b,
            &mut u,
            problem.rtol,
            case.max_iterations(),
        );
        let solve_s = solve_started.elapsed().as_secs_f64();
        Ok(outcome(
            case,
            &problem,
            Some(backend),
            Timings { setup_s, solve_s },
            Stop::of_cg(&convergence, problem.rtol),
            SteadySolve::cg(convergence.iterations),
            Distribution::serial(case),
            u,
        ))
    })
}

/// ap = −lu, in parallel.
pub(crate) fn negate_into(lu: &[f64], ap: &mut [f64]) {
    ap.par_iter_mut().zip(lu).for_each(|(a, &l)| *a = -l);
}

pub(crate) struct Timings {
    pub setup_s: f64,
    pub solve_s: f64,
}

/// How the iteration ended: within `rtol`, or stopped at the case's `max_iterations` (or on a
/// non-finite residual), with the residual it measures.
pub(crate) struct Stop {
    pub reached_tolerance: bool,
    pub residual: f64,
}

impl Stop {
    pub(crate) fn of_cg(convergence: &cg::Convergence, rtol: f64) -> Self {
        Stop {
            reached_tolerance: convergence.relative_residual <= rtol,
            residual: convergence.relative_residual,
        }
    }
}

/// The record of a finished steady solve, its residual and error measured on the whole field.
pub(crate) fn outcome(
    case: &Case,
    problem: &SteadyProblem,
    backend: Option<Backend>,
    timings: Timings,
    stop: Stop,
    mut solve: SteadySolve,
    distribution: Distribution,
    u: Vec<f64>,
) -> Outcome {
    let grid = problem.grid();
    let Fit {
        relative_residual,
        error_max,
        error_l2,
    } = problem.measure(&u);
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
                "stopped after {iterations} iterations with residual {:.3e}, above rtol = {:e}",
                stop.residual, problem.rtol
            ),
        )
    } else {
        (Status::Ok, String::new())
    };
    let record = Record {
        case: case.clone(),
        status,
        message,
        resolved: problem.resolved(backend),
        steps_done: 0,
        setup_s: timings.setup_s,
        solve_s: timings.solve_s,
        step_s: timings.solve_s / iterations.max(1) as f64,
        error_l2: Some(error_l2),
        error_l2_norm: Some(error_l2.sqrt()),
        error_max: Some(error_max),
        error_total: None,
        mass: Some(crate::diagnostics::total_mass(&u, grid.volume())),
        max_abs: Some(crate::diagnostics::max_abs(&u)),
        diverged_step: None,
        diverged_time: None,
        c_tot: None,
        histogram: None,
        field: None,
        steady: solve,
        provenance: Provenance::here(case.threads, distribution.ranks),
        distribution,
        peak_memory_bytes: crate::record::peak_memory_bytes(),
    };
    Outcome {
        record,
        field: u,
        lattice: grid.lattice(),
        frames: Vec::new(),
    }
}
