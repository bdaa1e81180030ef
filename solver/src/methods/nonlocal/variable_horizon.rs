//! The nonlocal heat equation with a horizon that varies along x (\[LSSM]), in 1D or 2D on one
//! process: the rows of `VariableHorizonOperator` with u = 0 on the collar (eq. 2.2), stepped by
//! any of the method's integrators. The implicit ones solve by CG for the symmetric standard
//! form and by BiCGStab for the others, preconditioned by the sine transform of the
//! constant-horizon operator at the smallest ε (it diagonalises only a constant horizon, so it
//! is a preconditioner here, not a solver).
//!
//! The standard formulation is symmetric and negative definite, so every integrator is stable
//! within its usual bound. The partial stress is not symmetric, and where the horizon varies its
//! eigenvalues reach Re λ > 0 (docs/variable_horizon.md): u grows whatever dt, so such a case
//! runs only with `allow_unstable`, as a probe. The x-centred form is not symmetric either, but
//! keeps Re λ ≤ 0.

use crate::case::{
    horizon_length, Backend, Case, CaseError, Collar, Formulation, HorizonProfile, Krylov, Problem,
    Quadrature, SourceMode, ValidCase,
};
use crate::discretization::grid::{Grid, Horizon};
use crate::discretization::stability::{self, dt_stable, positive_step};
use crate::discretization::stencil::Stencil;
use crate::discretization::variable_horizon::VariableHorizonOperator;
use crate::integrate::amplification::{amplification, positivity, POSITIVITY_RTOL};
use crate::integrate::integrator::stepper;
use crate::integrate::measure::serial_outcome;
use crate::integrate::stepper::{integrate, Stepper};
use crate::integrate::theta::theta;
use crate::integrate::time_step::{divergence_bound, requested, time_step};
use crate::integrate::timed::Stepping;
use crate::methods::patch_test::{spectrum, validate_horizon};
use crate::operator::{Identity, LinearOperator, RowOperator, SinePreconditioner};
use crate::output::outcome::Outcome;
use crate::output::record::Resolved;
use crate::parallel::exchange::Ranks;
use crate::problem::{self, manufactured_solution, Source};
use std::time::Instant;

/// The rules of a nonlocal case with a `horizon_profile`.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    if case.ranks > 1 {
        return Err(CaseError::new(
            "ranks",
            "a varying horizon runs on one process: each node's rows reach its own horizon and its neighbours', so its operator is not partitioned over ranks; use ranks = 1 and `threads`",
        ));
    }
    if !matches!(case.backend, Backend::Auto | Backend::NeighbourList) {
        return Err(CaseError::new(
            "backend",
            "a varying horizon gives every node its own weights, which only its neighbour lists hold; leave `backend` out",
        ));
    }
    if case.collar == Collar::Exact {
        return Err(CaseError::new(
            "collar",
            "a varying horizon runs with the zero collar of eq. 2.2; leave `collar` out",
        ));
    }
    if matches!(case.problem, Problem::Manufactured) && case.source() == SourceMode::Continuum {
        return Err(CaseError::new(
            "source",
            "`continuum` integrates the operator of a constant horizon; use `discrete` (the time error alone) or `local` (the distance to kΔ)",
        ));
    }
    if case.krylov == Some(Krylov::Cg) && !case.formulation().is_symmetric() {
        // Its name as the case writes it.
        let name = serde_json::json!(case.formulation());
        return Err(CaseError::new(
            "krylov",
            format!(
                "CG needs a symmetric operator, and formulation {name} is not symmetric; use `bicgstab`, or leave `krylov` out to have it chosen"
            ),
        ));
    }
    if case.formulation == Some(Formulation::PartialStress)
        && case.horizon_profile != Some(HorizonProfile::Constant)
        && !case.allow_unstable
    {
        return Err(CaseError::new(
            "formulation",
            "the partial stress has eigenvalues with Re λ > 0 where the horizon varies, so u grows whatever dt (docs/variable_horizon.md); use `standard`, or set `allow_unstable: true` to watch it grow",
        ));
    }
    validate_horizon(case)
}

/// Plans, integrates and measures a nonlocal case with a `horizon_profile`.
///
/// Long because the untimed measurements after the run (amplification, positivity) reuse the
/// stepper the closure `with_stepper` builds over this function's operator and preconditioner.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    let setup_started = Instant::now();
    let profile = case.horizon_profile();
    let variable = VariableHorizonOperator::new(
        case.dim,
        case.n,
        profile,
        horizon_length(case),
        case.kernel,
        case.diffusivity,
        case.formulation(),
    );
    let operator = RowOperator::new(variable.rows_with_zero_collar());
    let (diagonal, off_diagonal_nonnegative) = match case.amplification_steps {
        Some(_) => diagonal_and_sign(&variable),
        None => (Vec::new(), true),
    };
    let eps_max = variable.eps.iter().copied().fold(0.0, f64::max);
    let eps_min = variable.eps.iter().copied().fold(f64::INFINITY, f64::min);
    // Gershgorin's bound: the exact step of the symmetric standard form is about twice this.
    let euler_dt_stable = 2.0 / operator.lambda_bound();
    let explicit_dt_stable = dt_stable(case.integrator, euler_dt_stable);
    let dt_stable = explicit_dt_stable.unwrap_or(euler_dt_stable);
    let (dt, steps) = time_step(case, dt_stable, explicit_dt_stable.is_none())?;

    let grid = Grid::new(case.dim, case.n);
    let nodes = grid.nodes();
    let (u0, source) = initial_and_source(case, &grid, &operator);
    let ranks = Ranks::single();
    let mass0 = crate::output::diagnostics::total_mass(&u0, grid.volume());
    let source_max = source
        .as_ref()
        .map(|s| (ranks.max_abs(&s.phi), ranks.max_abs(&s.psi)));
    let bound = divergence_bound(case, ranks.max_abs(&u0), source_max);
    let stepping = Stepping::of_case(case, dt, steps, bound, grid.volume());
    // The implicit solves' preconditioner: the sine transform of the constant-horizon operator
    // at the smallest ε, the one whose stiff modes a small horizon adds; built for each step.
    let with_stepper =
        |case: &Case, stepping: &Stepping, source, with: &mut dyn FnMut(&mut dyn Stepper)| {
            let preconditioner = case.integrator.is_implicit().then(|| {
                let horizon = Horizon::from_eps(&grid, eps_min);
                let stencil = Stencil::new(
                    grid,
                    horizon,
                    case.kernel,
                    Quadrature::Midpoint,
                    case.diffusivity,
                );
                SinePreconditioner::new(&stencil, theta(case.integrator) * stepping.dt)
            });
            let mut stepper = match &preconditioner {
                Some(sine) => stepper(case, &operator, source, ranks, nodes, stepping, sine),
                None => stepper(case, &operator, source, ranks, nodes, stepping, &Identity),
            };
            with(stepper.as_mut());
        };
    let setup_s = setup_started.elapsed().as_secs_f64();
    let (mut u0, mut trajectory) = (Some(u0), None);
    with_stepper(case, &stepping, source.as_ref(), &mut |stepper| {
        let u0 = u0.take().expect("integrated once");
        trajectory = Some(integrate(stepper, ranks, u0, source.as_ref(), &stepping));
    });
    let mut trajectory = trajectory.expect("integrated");
    // Untimed, after the run, at the step asked for (as for a constant horizon), and the stable
    // step the computed spectrum gives, where no symbol does.
    let (mut dt_stable_spectrum, mut dt_positive) = (None, None);
    if let Some(steps) = case.amplification_steps {
        let (asked, _) = requested(case, dt_stable);
        let asked = Stepping::of_case(case, asked, steps, bound, grid.volume());
        with_stepper(case, &asked, None, &mut |stepper| {
            trajectory.amplification = amplification(stepper, ranks, None, nodes, asked.dt, steps);
        });
        let tight = Case {
            rtol: Some(POSITIVITY_RTOL),
            ..Case::clone(case)
        };
        // The spike sits where |L_ii| is largest (the smallest horizon): the column whose
        // positivity a step loses first.
        let (spike, largest) = largest_on_the_diagonal(&diagonal);
        dt_positive = positive_step(case.integrator, largest, off_diagonal_nonnegative);
        with_stepper(&tight, &asked, None, &mut |stepper| {
            trajectory.positivity = positivity(stepper, ranks, None, nodes, asked.dt, spike);
        });
        let euler = spectrum(&variable, case.diffusivity).and_then(|s| s.dt_forward_euler);
        dt_stable_spectrum = euler.and_then(|euler| stability::dt_stable(case.integrator, euler));
    }
    let resolved = Resolved {
        h: grid.h,
        eps: Some(eps_max),
        dt,
        dt_stable,
        dt_stable_spectrum,
        dt_positive,
        steps,
        nodes,
        bonds: variable.bonds,
        collar: Some(Collar::Zero),
        backend: Some(Backend::NeighbourList),
        integrator: Some(case.integrator),
        ..Resolved::default()
    };
    let t_end = trajectory.timing.steps_done as f64 * dt;
    let exact = source
        .as_ref()
        .map(|s| manufactured_solution(&s.phi, t_end));
    let mut outcome = serial_outcome(
        case,
        resolved,
        setup_s,
        &stepping,
        trajectory,
        grid.lattice(),
        exact.as_ref().map(|e| e as &(dyn Fn(usize) -> f64 + Sync)),
    );
    // Only a positive field has a mass to drift from: the manufactured profile's sums to
    // about 0, and a drift relative to it would be noise.
    let record = &mut outcome.record;
    record.mass_drift = record
        .mass
        .filter(|_| case.problem == Problem::Bump && mass0 > 0.0)
        .map(|mass| (mass - mass0) / mass0)
        .filter(|drift| drift.is_finite());
    Ok(outcome)
}

/// L_h's diagonal, and whether its other entries are all ≥ 0, for the positivity theory.
fn diagonal_and_sign(variable: &VariableHorizonOperator) -> (Vec<f64>, bool) {
    let (mut diagonal, mut off_diagonal_nonnegative) = (Vec::new(), true);
    for (i, row) in variable.rows_with_zero_collar().enumerate() {
        diagonal.push(
            row.iter()
                .filter(|(j, _)| *j == i)
                .map(|(_, a)| a)
                .sum::<f64>(),
        );
        off_diagonal_nonnegative &= row.iter().all(|&(j, a)| j == i || a >= 0.0);
    }
    (diagonal, off_diagonal_nonnegative)
}

/// The node of the largest |L_ii| and its size.
fn largest_on_the_diagonal(diagonal: &[f64]) -> (usize, f64) {
    diagonal.iter().enumerate().fold(
        (0, 0.0),
        |best, (i, a)| {
            if a.abs() > best.1 {
                (i, a.abs())
            } else {
                best
            }
        },
    )
}

/// The initial field, and the manufactured problem's source (None for the bump): its profile φ
/// and ψ = L_h φ (discrete) or the local Laplacian's multiple of φ.
fn initial_and_source(
    case: &ValidCase,
    grid: &Grid,
    operator: &RowOperator,
) -> (Vec<f64>, Option<Source>) {
    let nodes = grid.nodes();
    let x = |i: usize| grid.position(i);
    match case.problem {
        Problem::Bump => (
            (0..nodes).map(|i| problem::bump(case.dim, x(i))).collect(),
            None,
        ),
        _ => {
            let phi: Vec<f64> = (0..nodes)
                .map(|i| problem::profile(case.dim, x(i)))
                .collect();
            let psi = match case.source() {
                SourceMode::Discrete => {
                    let mut psi = vec![0.0; nodes];
                    operator.apply_once(&phi, &mut psi);
                    psi
                }
                _ => {
                    let factor = problem::local_laplacian_factor(case.dim, case.diffusivity);
                    phi.iter().map(|p| factor * p).collect()
                }
            };
            (phi.clone(), Some(Source { phi, psi }))
        }
    }
}
