//! Runs one case: plan the operator, resolve the time step, integrate, measure.

use crate::case::{Case, CaseError, Method};
use crate::diagnostics::{self, Histogram, MassSeries};
use crate::euler::{forward_euler, Stepping, Trajectory};
use crate::field::{FieldSnapshot, Frame, Lattice};
use crate::grid::{Grid, Horizon};
use crate::local;
use crate::operator::{self, Backend, NonlocalOperator};
use crate::problem::{
    self, manufactured_solution, Collar, Problem, Source, SourceMode, WAVENUMBER,
};
use crate::pse;
use crate::record::{Distribution, Provenance, Record, Resolved, Status, SteadySolve};
use crate::source::PointwiseSource;
use crate::stability::forward_euler_dt_stable;
use crate::stencil::Stencil;
use rayon::prelude::*;
use std::time::Instant;

/// Factor above the problem's natural scale at which a solution counts as diverged.
const DIVERGENCE_FACTOR: f64 = 1e6;
/// Longest run accepted, in steps: beyond any study this tool serves, and a guard against a
/// t_end/dt typo that would run for days.
const MAX_STEPS: usize = 100_000_000;

/// A finished run: its record, the final field on the nodes of D (empty when a distributed run
/// did not gather it), where its values sit, and the frames the case asked for.
pub struct Outcome {
    pub record: Record,
    pub field: Vec<f64>,
    pub lattice: Lattice,
    pub frames: Vec<Frame>,
}

/// Runs `case` on a rayon pool of `case.threads` threads.
pub fn run(case: &Case) -> Result<Outcome, CaseError> {
    case.validate()?;
    if case.ranks > 1 {
        return Err(CaseError::new(
            "ranks",
            format!(
                "{r} ranks need MPI: start the run with `mpirun -n {r} nlsolve run …`",
                r = case.ranks
            ),
        ));
    }
    if case.method.is_steady() {
        return crate::steady::run(case);
    }
    in_pool(case.threads, || match case.method {
        Method::Nonlocal => run_in_pool(case),
        Method::FdExplicit => local::run(case, false),
        Method::Adi => local::run(case, true),
        Method::Pse => pse::run(case),
        Method::SteadyCg | Method::Feti => unreachable!("steady methods run above"),
    })
}

/// Runs `work` on a rayon pool of `threads` threads.
fn in_pool<T: Send>(
    threads: usize,
    work: impl FnOnce() -> Result<T, CaseError> + Send,
) -> Result<T, CaseError> {
    thread_pool(threads)?.install(work)
}

/// The rayon pool a case runs on.
pub(crate) fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, CaseError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CaseError::new("threads", format!("cannot start {threads} threads: {e}")))
}

/// What a case resolves to before its time loop: the weights of L_h and the time step.
pub(crate) struct Plan {
    pub stencil: Stencil,
    /// The backend that runs: `auto` resolved by the cost model; the distributed solver's stencil.
    pub backend: Backend,
    pub collar: Collar,
    pub dt_stable: f64,
    pub dt: f64,
    pub steps: usize,
}

impl Plan {
    pub fn new(case: &Case) -> Result<Plan, CaseError> {
        let stencil = stencil_of(case);
        check_operator_does_not_vanish(case, &stencil)?;
        let dt_stable = forward_euler_dt_stable(&stencil);
        let (dt, steps) = time_step(case, dt_stable, false)?;
        check_neighbour_list_size(case, &stencil)?;
        let backend = if case.ranks > 1 {
            Backend::Stencil
        } else {
            case.backend.resolve(&stencil)
        };
        Ok(Plan {
            stencil,
            backend,
            collar: case.collar,
            dt_stable,
            dt,
            steps,
        })
    }
}

/// The weights of the case's L_h.
pub(crate) fn stencil_of(case: &Case) -> Stencil {
    let grid = Grid::new(case.dim, case.n);
    let horizon = match case.m {
        Some(m) => Horizon::from_m(&grid, m),
        None => Horizon::from_eps(&grid, case.eps.expect("validated: m or eps")),
    };
    Stencil::new(
        grid,
        horizon,
        case.kernel,
        case.quadrature,
        case.diffusivity,
    )
}

/// The max |u| beyond which a run counts as diverged, from max |u₀| and the source's scale
/// (max |φ| and max |ψ|).
pub(crate) fn divergence_bound(case: &Case, u0_max: f64, source_max: Option<(f64, f64)>) -> f64 {
    let source_scale = source_max.map_or(0.0, |(phi, psi)| WAVENUMBER * phi + psi);
    DIVERGENCE_FACTOR * (1.0f64).max(u0_max).max(case.t_end() * source_scale)
}

impl Plan {
    pub fn resolved(&self) -> Resolved {
        let stencil = &self.stencil;
        Resolved {
            dt: self.dt,
            dt_stable: self.dt_stable,
            steps: self.steps,
            collar: Some(self.collar),
            patch_error: Some(stencil.patch_error()),
            backend: Some(self.backend),
            ..Resolved::of_stencil(stencil)
        }
    }
}

/// What a time loop measured, already reduced over ranks.
pub(crate) struct Measured {
    pub setup_s: f64,
    pub solve_s: f64,
    pub step_s: f64,
    pub steps_done: usize,
    pub diverged_at: Option<usize>,
    pub divergence_bound: f64,
    /// (eᵏ, max error) at the final time, for a manufactured problem that did not diverge.
    pub errors: Option<(f64, f64)>,
    pub error_total: Option<f64>,
    pub mass: f64,
    pub max_abs: f64,
    pub c_tot: Option<MassSeries>,
    pub histogram: Option<Histogram>,
    pub field: Option<FieldSnapshot>,
    pub distribution: Distribution,
}

/// The record of a finished run.
pub(crate) fn record(case: &Case, resolved: Resolved, measured: Measured) -> Record {
    let t_final = measured.steps_done as f64 * resolved.dt;
    let (status, message) = match measured.diverged_at {
        None => (Status::Ok, String::new()),
        Some(step) => (
            Status::Diverged,
            format!(
                "max |u| exceeded {:e} at step {step} (t = {t_final}); dt/dt_stable = {:.4}",
                measured.divergence_bound,
                resolved.dt / resolved.dt_stable
            ),
        ),
    };
    let errors = measured.errors;
    Record {
        case: case.clone(),
        status,
        message,
        resolved,
        steps_done: measured.steps_done,
        setup_s: measured.setup_s,
        solve_s: measured.solve_s,
        step_s: measured.step_s,
        error_l2: errors.map(|(ek, _)| ek),
        error_l2_norm: errors.map(|(ek, _)| ek.sqrt()),
        error_max: errors.map(|(_, max)| max),
        error_total: measured.error_total,
        mass: finite(measured.mass),
        max_abs: finite(measured.max_abs),
        diverged_step: measured.diverged_at,
        diverged_time: measured.diverged_at.map(|_| t_final),
        c_tot: measured.c_tot,
        histogram: measured.histogram,
        field: measured.field,
        provenance: Provenance::here(case.threads, measured.distribution.ranks),
        distribution: measured.distribution,
        steady: SteadySolve::default(),
        peak_memory_bytes: crate::record::peak_memory_bytes(),
    }
}

fn run_in_pool(case: &Case) -> Result<Outcome, CaseError> {
    let setup_started = Instant::now();
    let plan = Plan::new(case)?;
    let stencil = &plan.stencil;
    let grid = stencil.grid;
    let operator = operator::plan(plan.backend, stencil);
    let (u0, source) = initial_state(case, stencil, operator.as_ref());
    let setup_s = setup_started.elapsed().as_secs_f64();

    let source_max = source
        .as_ref()
        .map(|s| (diagnostics::max_abs(&s.phi), diagnostics::max_abs(&s.psi)));
    let divergence_bound = divergence_bound(case, diagnostics::max_abs(&u0), source_max);
    let stepping = Stepping::of_case(case, plan.dt, plan.steps, divergence_bound, grid.volume());
    let trajectory = forward_euler(operator.as_ref(), u0, source.as_ref(), &stepping);

    let t_final = trajectory.timing.steps_done as f64 * plan.dt;
    let exact = source
        .as_ref()
        .map(|source| manufactured_solution(&source.phi, t_final));
    let lattice = grid.lattice();
    Ok(serial_outcome(
        case,
        plan.resolved(),
        setup_s,
        &stepping,
        trajectory,
        lattice,
        exact.as_ref().map(|e| e as &(dyn Fn(usize) -> f64 + Sync)),
    ))
}

/// The outcome of a run in one process: its trajectory measured and recorded, with the errors
/// against `exact` (the exact solution at the final time, by node, when the problem has one).
pub(crate) fn serial_outcome(
    case: &Case,
    resolved: Resolved,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: Trajectory,
    lattice: Lattice,
    exact: Option<&(dyn Fn(usize) -> f64 + Sync)>,
) -> Outcome {
    let Trajectory {
        u,
        timing,
        error_total,
        c_tot,
        frames,
    } = trajectory;
    // A diverged field has no meaningful error.
    let exact = exact.filter(|_| timing.diverged_at.is_none());
    let errors = exact.map(|exact| {
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
        error_total,
        mass: diagnostics::total_mass(&u, stepping.volume),
        max_abs: diagnostics::max_abs(&u),
        c_tot,
        histogram: case
            .histogram_bins
            .and_then(|bins| diagnostics::histogram(&u, bins)),
        field: case
            .field_snapshot
            .map(|side| FieldSnapshot::of(&lattice, &u, exact, side)),
        distribution: Distribution::serial(case),
    };
    Outcome {
        record: record(case, resolved, measured),
        field: u,
        lattice,
        frames,
    }
}

/// The time step actually used and the number of steps: dt (or cfl·dt_stable) lowered so that an
/// integer number of steps lands on t_end; refused above dt_stable unless the case allows it or
/// the scheme is `unconditionally_stable`.
pub(crate) fn time_step(
    case: &Case,
    dt_stable: f64,
    unconditionally_stable: bool,
) -> Result<(f64, usize), CaseError> {
    let (requested, field) = match (case.dt, case.cfl) {
        (Some(dt), _) => (dt, "dt"),
        (None, Some(cfl)) => (cfl * dt_stable, "cfl"),
        (None, None) => unreachable!("validated: dt or cfl"),
    };
    if requested > dt_stable * (1.0 + 1e-12) && !case.allow_unstable && !unconditionally_stable {
        return Err(CaseError::new(
            field,
            format!(
                "gives dt = {requested:e} above dt_stable = {dt_stable:e} for this case; lower `dt`, \
                 use `cfl` ≤ 1, or set `allow_unstable: true` to probe instability"
            ),
        ));
    }
    let steps = ((case.t_end() / requested) * (1.0 - 1e-12)).ceil().max(1.0);
    if steps > MAX_STEPS as f64 {
        return Err(CaseError::new(
            "t_end",
            format!(
                "t_end / dt = {steps:e} steps, more than {MAX_STEPS:e}; shorten `t_end` or enlarge the time step"
            ),
        ));
    }
    Ok((case.t_end() / steps, steps as usize))
}

/// A horizon whose ball holds no node, or only bonds with J = 0 (J = 1 − r at ε = h), gives
/// L_h = 0 and an infinite dt_stable: no study wants that, so say which field to change.
fn check_operator_does_not_vanish(case: &Case, stencil: &Stencil) -> Result<(), CaseError> {
    let field = if case.m.is_some() { "m" } else { "eps" };
    let h = stencil.grid.h;
    if stencil.offsets == 0 {
        return Err(CaseError::new(
            field,
            format!(
                "ε = {} is below h = {h}, so the ball holds no neighbour; use ε ≥ h",
                stencil.horizon.eps
            ),
        ));
    }
    if stencil.total_weight == 0.0 {
        return Err(CaseError::new(
            field,
            format!(
                "every bond of this horizon has J = 0 (kernel {:?}, ε/h = {}), so L_h vanishes; use m ≥ 2 (ε ≥ 2h)",
                case.kernel, stencil.horizon.radius_cells
            ),
        ));
    }
    Ok(())
}

/// The oracle stores every bond (4 bytes each) by a u32 index on the extended grid: refuse a case
/// whose lists would not fit, rather than abort on a failed allocation.
fn check_neighbour_list_size(case: &Case, stencil: &Stencil) -> Result<(), CaseError> {
    const LIMIT_BYTES: usize = 8 << 30;
    if case.backend != Backend::NeighbourList {
        return Ok(());
    }
    let bytes = stencil.bonds().saturating_mul(4);
    let extended_nodes = (case.n + 2 * stencil.horizon.m).pow(case.dim as u32);
    if bytes > LIMIT_BYTES || extended_nodes > u32::MAX as usize {
        return Err(CaseError::new(
            "backend",
            format!(
                "`neighbour_list` would store {:.1} GiB of bonds for this case (limit {} GiB); use `stencil`",
                bytes as f64 / (1u64 << 30) as f64,
                LIMIT_BYTES >> 30
            ),
        ));
    }
    Ok(())
}

/// u₀ and the source fields of the case's problem.
fn initial_state(
    case: &Case,
    stencil: &Stencil,
    operator: &dyn NonlocalOperator,
) -> (Vec<f64>, Option<Source>) {
    let grid = &stencil.grid;
    if case.problem == Problem::Bump {
        return (problem::sample(grid, problem::bump), None);
    }
    let phi = problem::sample(grid, problem::profile);
    let psi = match case.source() {
        SourceMode::Discrete => {
            let mut psi = vec![0.0; phi.len()];
            operator.apply(&phi, &mut psi);
            psi
        }
        SourceMode::Continuum | SourceMode::Local => {
            let pointwise = PointwiseSource::new(case, stencil).expect("a pointwise mode");
            (0..grid.nodes())
                .into_par_iter()
                .map(|i| pointwise.psi(i))
                .collect()
        }
        SourceMode::None => unreachable!("validated: the manufactured problem has a source"),
    };
    (phi.clone(), Some(Source { phi, psi }))
}

pub(crate) fn median(mut samples: Vec<f64>) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let mid = samples.len() / 2;
    *samples.select_nth_unstable_by(mid, f64::total_cmp).1
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}
