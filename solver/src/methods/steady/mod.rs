//! Steady nonlocal diffusion (\[XGDF]): −L u = f on Ω = [0,1]², u = g on the interaction layer Γ,
//! solved by unpreconditioned CG on the single-domain system (`steady_cg`) or by FETI on p × p
//! subdomains (`feti`).
//!
//! **Discretization** (\[XGDF], section 4). L × L particles x_i = ((i₁ + ½)h, (i₂ + ½)h), h = 1/L,
//! each with volume ω = h²; Γ is the layer of m particles around Ω. Particle i interacts with the
//! (2m + 1)² − 1 particles of the square |x_j − x_i|∞ ≤ δ = m h, with the kernel
//! γ(x, y) = c J(|x − y|/δ) (J = 1/r gives \[XGDF]'s C/|x − y| with C = c δ). The energy of
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
//! makes L_h exact on quadratics (as \[RKAC]'s AC quadrature is), so the discrete solution is
//! u itself and the error measures the solver alone.

pub mod assembly;
pub mod decomposition;
#[cfg(feature = "mpi")]
pub mod distributed;
pub mod feti;
pub mod problem;
mod resume;

use crate::case::Rules;
use crate::case::ValidCase;
use crate::case::{
    refuse_given, validate_diffusivity, Backend, Case, CaseError, Collar, Kernel, Method,
    Partition, Problem, Quadrature,
};
use crate::linalg::cg::{self, Cg};
use crate::operator::{self, LinearOperator};
use crate::output::outcome::Outcome;
use crate::output::record::{Distribution, SteadySolve};
use crate::parallel::exchange;
use problem::{negate_into, outcome, SteadyProblem, Termination, Timings};
use resume::SolveCheckpoints;
use std::time::Instant;

/// The steady methods' rules; every other field of a time-dependent case is refused by name.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    let method = serde_json::to_value(case.method).unwrap_or_default();
    if case.dim != 2 {
        return Err(CaseError::new(
            "dim",
            format!("method {method} solves [XGDF]'s problem on [0,1]^2; set `dim` to 2"),
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
            "J = 1 − r is negative in the corners of the square neighbourhood; use inverse_distance ([XGDF]), constant or gaussian",
        ));
    }
    if case.quadrature == Quadrature::PartialVolume {
        return Err(CaseError::new(
            "quadrature",
            "the square neighbourhood covers whole cells, so there are no partial volumes; use midpoint ([XGDF]) or ac (exact on quadratics)",
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
            ("integrator", !case.integrator.is_forward_euler()),
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
    validate_diffusivity(case.diffusivity)?;
    case.validate_iteration()?;
    if case.threads < 1 {
        return Err(CaseError::new("threads", "must be at least 1 (got 0)"));
    }
    if case.backend == Backend::NeighbourList {
        return Err(CaseError::new(
            "backend",
            "the neighbour list follows [JD]'s Euclidean ball; the square neighbourhood runs on `stencil`, `fft` or `auto`",
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
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    let started = Instant::now();
    let pool = crate::threads::pool(case.threads)?;
    let problem = SteadyProblem::new(case);
    if case.method == Method::Feti {
        let outcome = feti::run_on(case, &problem, &exchange::Serial, &pool, started, true)?;
        return Ok(outcome.expect("the only rank gets the outcome"));
    }
    pool.install(|| {
        let backend = operator::resolve(case.backend, &problem.stencil);
        let operator = operator::plan(backend, &problem.stencil);
        let mut workspace = operator.workspace();
        let b = problem.loads();
        let mut u = vec![0.0; b.len()];
        let mut lu = vec![0.0; b.len()];
        let setup_s = started.elapsed().as_secs_f64();
        let solving = crate::output::usage::Solving::starts();
        let system = &mut cg::Closures {
            len: b.len(),
            precondition: cg::NoPreconditioner,
            apply: |p: &[f64], ap: &mut [f64]| {
                operator.apply(p, &mut lu, &mut workspace);
                negate_into(&lu, ap);
            },
            dot: cg::dot,
        };
        let params = problem.cg_params(None);
        let mut checkpoints =
            SolveCheckpoints::take(&exchange::Serial, params.rtol, params.max_iterations);
        let convergence =
            Cg::new(b.len()).solve_checkpointed(system, &b, &mut u, &params, &mut checkpoints);
        let solve = checkpoints.resumed(solving.ends());
        drop(checkpoints);
        Ok(outcome(
            case,
            &problem,
            Some(backend),
            Timings { setup_s, solve },
            Termination::of_cg(&convergence),
            SteadySolve::cg(convergence.iterations),
            Distribution::serial(case),
            problem.summarize(&u),
            u,
        ))
    })
}
