//! The nonlocal heat equation of \[JD]: plan the operator, resolve the time step, step with
//! the case's integrator (eq. 2.1's forward Euler by default) on one process (`run`) or over MPI
//! ranks (`distributed`), measure.

#[cfg(feature = "mpi")]
pub mod distributed;
pub mod variable_horizon;

use crate::case::ValidCase;
use crate::case::{
    readable, Backend, Case, CaseError, Collar, Integrator, Problem, SourceMode, MAX_EPS,
};
use crate::discretization::stability::{
    dt_stable, forward_euler_dt_stable, forward_euler_dt_stable_floor,
};
use crate::discretization::stencil::Stencil;
use crate::integrate::amplification::{
    amplification, middle_node, positivity, spectral, spectral_budget, spectrum_key,
    POSITIVITY_RTOL,
};
use crate::integrate::integrator::stepper;
use crate::integrate::measure::serial_outcome;
use crate::integrate::stepper::{integrate, Stepper};
use crate::integrate::theta::theta;
use crate::integrate::time_step::{divergence_bound, requested, time_step};
use crate::integrate::timed::{Stepping, Trajectory};
use crate::operator::{self, Identity, LinearOperator, SinePreconditioner};
use crate::output::outcome::Outcome;
use crate::output::record::{self, Resolved};
use crate::parallel::exchange::Ranks;
use crate::parallel::gathered::Gathered;
use crate::parallel::slab_sine::SlabSine;
use crate::problem::source::PointwiseSource;
use crate::problem::{self, manufactured_solution, Source};
use rayon::prelude::*;
use std::time::Instant;

/// The nonlocal method's own rules: \[JD]'s problems on D = [0,1]^d and a horizon in (0, 1/2].
pub fn validate(case: &Case) -> Result<(), CaseError> {
    if case.problem.is_local() {
        return Err(CaseError::new(
                "problem",
                "the nonlocal method solves `manufactured` or `bump`; `eigenmode` and `square` are for `fd_explicit`, `adi` and `pse`",
            ));
    }
    if case.length.is_some() {
        return Err(CaseError::new(
            "length",
            "the nonlocal method runs on D = [0,1]^d; leave `length` out",
        ));
    }
    if case.horizon_profile.is_some() {
        return variable_horizon::validate(case);
    }
    if case.formulation.is_some() {
        return Err(CaseError::new(
            "formulation",
            "chooses how a varying horizon enters L_h; give a `horizon_profile` with it, or leave it out",
        ));
    }
    if case.collar == Collar::Exact && case.problem != Problem::Manufactured {
        return Err(CaseError::new(
                "collar",
                "`exact` continues the manufactured solution into the collar; use it with problem `manufactured`",
            ));
    }
    let eps = match (case.m, case.eps) {
        (Some(_), Some(_)) => {
            return Err(CaseError::new(
                "eps",
                "give the horizon once, as `m` (cells) or `eps` (length), not both",
            ))
        }
        (None, None) => {
            return Err(CaseError::new(
                "m",
                "the horizon is missing; give `m` (ε = m·h) or `eps`",
            ))
        }
        (Some(0), None) => {
            return Err(CaseError::new(
                "m",
                "must be at least 1 (got 0); the horizon ε = m·h spans m cells",
            ))
        }
        (Some(m), None) => {
            let eps = m as f64 / case.n as f64;
            if eps > MAX_EPS {
                return Err(CaseError::new(
                    "m",
                    format!(
                        "m = {m} with n = {} gives ε = m/n = {} above {MAX_EPS}; use m ≤ n/2",
                        case.n,
                        readable(eps)
                    ),
                ));
            }
            eps
        }
        (None, Some(eps)) => eps,
    };
    if !(eps > 0.0 && eps <= MAX_EPS) {
        return Err(CaseError::new(
            "eps",
            format!(
                "must lie in (0, {MAX_EPS}] (got {}); the collar of width ε surrounds D = [0,1]^d",
                readable(eps)
            ),
        ));
    }
    Ok(())
}

/// Forward Euler's stable step of the stencil, once the stencil is known to have weight (see
/// `check_operator_does_not_vanish`).
fn operator_dt_stable(case: &Case, stencil: &Stencil) -> Result<f64, CaseError> {
    check_operator_does_not_vanish(case, stencil)?;
    Ok(forward_euler_dt_stable(stencil))
}

/// The integrator's dt_stable (forward Euler's for the implicit ones, which are stable at any
/// dt: `cfl` for them is relative to it), and the time step and steps the case takes.
fn step_of(case: &Case, euler_dt_stable: f64) -> Result<(f64, f64, usize), CaseError> {
    let explicit_dt_stable = dt_stable(case.integrator, euler_dt_stable);
    let dt_stable = explicit_dt_stable.unwrap_or(euler_dt_stable);
    let (dt, steps) = time_step(case, dt_stable, explicit_dt_stable.is_none())?;
    Ok((dt_stable, dt, steps))
}

/// The time step of a constant-horizon case, checked as `run` checks it (a horizon without
/// weight, dt above dt_stable, too many steps) without building more than the stencil: what
/// `nlsolve check` refuses before anything runs. Forward Euler's stable step depends only on
/// the stencil's fields, so it is kept in `memo` by them: a plan of 10⁵ points builds few.
pub fn preflight(
    case: &Case,
    memo: &mut std::collections::HashMap<String, Result<f64, CaseError>>,
) -> Result<(), CaseError> {
    let key = format!(
        "{} {} {:?} {:?} {:?} {:?} {}",
        case.dim, case.n, case.m, case.eps, case.kernel, case.quadrature, case.diffusivity
    );
    // With `cfl`, whether dt ≤ dt_stable does not depend on dt_stable, and the steps are fewest
    // at the exact dt_stable: when a floor under it passes, so does the exact one, and the
    // symbol's maximum (O(m^2d), most of a plan's time at 10⁵ points) is left uncomputed.
    if case.dt.is_none() {
        let floor = memo
            .entry(format!("floor {key}"))
            .or_insert_with(|| {
                Ok(forward_euler_dt_stable_floor(&Stencil::of_case(case)).unwrap_or(0.0))
            })
            .clone()?;
        if floor > 0.0 && step_of(case, floor).is_ok() {
            return Ok(());
        }
    }
    let euler = memo
        .entry(key)
        .or_insert_with(|| operator_dt_stable(case, &Stencil::of_case(case)))
        .clone()?;
    step_of(case, euler).map(drop)
}

/// What a case resolves to before its time loop: the weights of L_h and the time step.
pub(crate) struct Plan {
    pub stencil: Stencil,
    /// The backend that runs: `auto` resolved by the cost model.
    pub backend: Backend,
    pub collar: Collar,
    pub integrator: Integrator,
    pub dt_stable: f64,
    pub dt: f64,
    pub steps: usize,
}

impl Plan {
    pub fn new(case: &Case) -> Result<Plan, CaseError> {
        let stencil = Stencil::of_case(case);
        let euler_dt_stable = operator_dt_stable(case, &stencil)?;
        let (dt_stable, dt, steps) = step_of(case, euler_dt_stable)?;
        check_neighbour_list_size(case, &stencil)?;
        let backend = operator::resolve(case.backend, &stencil);
        Ok(Plan {
            stencil,
            backend,
            collar: case.collar,
            integrator: case.integrator,
            dt_stable,
            dt,
            steps,
        })
    }
}

impl Plan {
    pub fn resolved(&self) -> Resolved {
        let stencil = &self.stencil;
        Resolved {
            dt: self.dt,
            dt_stable: self.dt_stable,
            dt_positive: crate::discretization::stability::dt_positive(self.integrator, stencil),
            steps: self.steps,
            collar: Some(self.collar),
            patch_error: Some(stencil.patch_error()),
            backend: Some(self.backend),
            integrator: Some(self.integrator),
            ..record::resolved_of(stencil)
        }
    }
}

/// Runs a case of the nonlocal method on the current rayon pool.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    if case.horizon_profile.is_some() {
        return variable_horizon::run(case);
    }
    let setup_started = Instant::now();
    let plan = Plan::new(case)?;
    let operator = operator::plan(plan.backend, &plan.stencil);
    let (solved, trajectory) = solve(case, &plan, &operator, Ranks::single(), None, setup_started);
    let exact = solved.exact(trajectory.timing.steps_done);
    Ok(serial_outcome(
        case,
        plan.resolved(),
        solved.setup_s,
        &solved.stepping,
        trajectory,
        plan.stencil.grid.lattice(),
        exact.as_ref().map(|e| e as &(dyn Fn(usize) -> f64 + Sync)),
    ))
}

/// What a case's integration was set up with on some ranks, each holding its own nodes.
pub(crate) struct Solved {
    pub setup_s: f64,
    pub stepping: Stepping,
    pub source: Option<Source>,
}

impl Solved {
    /// The manufactured solution after `steps_done` steps, on this rank's nodes.
    pub fn exact(&self, steps_done: usize) -> Option<impl Fn(usize) -> f64 + Sync + '_> {
        let source = self.source.as_ref()?;
        Some(manufactured_solution(
            &source.phi,
            steps_done as f64 * self.stepping.dt,
        ))
    }
}

/// Samples the case's initial state and source on `nodes` (all of D when None), in their order,
/// and integrates it with `operator` on `ranks`. Setup time counts from `setup_started`. The
/// node list is let go once sampled unless the 1D preconditioner gathers with it: a rank holds
/// nothing the size of its share that it does not use.
pub(crate) fn solve<Op: LinearOperator>(
    case: &Case,
    plan: &Plan,
    operator: &Op,
    ranks: Ranks,
    nodes: Option<Vec<usize>>,
    setup_started: Instant,
) -> (Solved, Trajectory) {
    let (u0, source) = initial_state(case, &plan.stencil, operator, ranks, nodes.as_deref());
    // Kept only for the measurement of the step's amplification, which seeds by global node.
    let rough_nodes = case.amplification_steps.and(nodes.clone());
    let setup_s = setup_started.elapsed().as_secs_f64();
    let source_max = source
        .as_ref()
        .map(|s| (ranks.max_abs(&s.phi), ranks.max_abs(&s.psi)));
    let divergence_bound = divergence_bound(case, ranks.max_abs(&u0), source_max);
    let volume = plan.stencil.grid.volume();
    let stepping = Stepping::of_case(case, plan.dt, plan.steps, divergence_bound, volume);
    let len = u0.len();
    let on = (case, plan, operator, ranks, len);
    let mut trajectory = with_stepper(on, nodes, &stepping, source.as_ref(), |stepper| {
        integrate(stepper, ranks, u0, source.as_ref(), &stepping)
    });
    // Untimed, after the run: the homogeneous step (no source) on a rough field, at the step
    // the case asks for (before it is lowered to land on t_end, which a stability search
    // would otherwise feel as a shifted boundary).
    if let Some(steps) = case.amplification_steps {
        let (asked, _) = requested(case, plan.dt_stable);
        let asked = Stepping::of_case(case, asked, plan.steps, divergence_bound, volume);
        // L_h of a constant horizon is symmetric: its spectrum gives the step's spectral radius
        // to round-off in some dozens of applications, where a rough field's growth over a
        // few hundred steps approaches it from below (an unstable step near the boundary would
        // be called stable). The rough field stays for an operator found not symmetric.
        let nodes = rough_nodes.as_deref();
        // Over ranks each run measures afresh: every rank then takes the same path.
        let single = ranks.exchange.ranks() == 1;
        let budget = spectral_budget(case.integrator, steps);
        let key = single.then(|| spectrum_key::<Op>(&plan.stencil));
        let step = (case.integrator, asked.dt);
        trajectory.amplification =
            spectral(operator, ranks, nodes, len, step, budget, key.as_deref()).or_else(|| {
                with_stepper(on, rough_nodes.clone(), &asked, None, |stepper| {
                    amplification(stepper, ranks, nodes, len, asked.dt, steps)
                })
            });
        let tight = Case {
            rtol: Some(POSITIVITY_RTOL),
            ..case.clone()
        };
        let spike = middle_node(plan.stencil.grid.dim, plan.stencil.grid.n);
        let on = (&tight, plan, operator, ranks, len);
        trajectory.positivity = with_stepper(on, rough_nodes.clone(), &asked, None, |stepper| {
            positivity(stepper, ranks, rough_nodes.as_deref(), len, asked.dt, spike)
        });
    }
    (
        Solved {
            setup_s,
            stepping,
            source,
        },
        trajectory,
    )
}

/// What a stepper runs on: the case, its plan, L_h, the ranks and the length of a rank's share.
type On<'a, Op> = (&'a Case, &'a Plan, &'a Op, Ranks<'a>, usize);

/// Calls `with` on the case's stepper for `stepping.dt` over `source`, with the implicit
/// integrators' preconditioner of I − θ dt L_h built for that dt on this rank's `nodes` (all
/// of D when None). The node list is let go once used unless the 1D preconditioner gathers
/// with it.
fn with_stepper<Op: LinearOperator, R>(
    (case, plan, operator, ranks, len): On<Op>,
    nodes: Option<Vec<usize>>,
    stepping: &Stepping,
    source: Option<&Source>,
    with: impl FnOnce(&mut dyn Stepper) -> R,
) -> R {
    let implicit = case.integrator.is_implicit();
    // θ dt: the implicit integrators' shift (θ exists for them only).
    let shift = || theta(case.integrator) * stepping.dt;
    let grid = plan.stencil.grid;
    // Over ranks in 2D the transform runs on slabs of rows; in 1D each rank applies it to the
    // gathered row (n values: a 1D grid is small enough to hold whole).
    let slabs = nodes
        .as_deref()
        .filter(|_| implicit && grid.dim == 2)
        .map(|nodes| SlabSine::new(&plan.stencil, shift(), nodes, ranks));
    let whole =
        (implicit && slabs.is_none()).then(|| SinePreconditioner::new(&plan.stencil, shift()));
    let gathered = whole
        .as_ref()
        .zip(nodes)
        .map(|(whole, nodes)| Gathered::new(whole, nodes, grid.nodes(), ranks));
    if ranks.exchange.ranks() > 1 {
        crate::parallel::release_freed_memory();
    }
    let mut stepper = match (&slabs, &gathered, &whole) {
        (Some(slabs), ..) => stepper(case, operator, source, ranks, len, stepping, slabs),
        (_, Some(gathered), _) => stepper(case, operator, source, ranks, len, stepping, gathered),
        (_, _, Some(whole)) => stepper(case, operator, source, ranks, len, stepping, whole),
        _ => stepper(case, operator, source, ranks, len, stepping, &Identity),
    };
    with(stepper.as_mut())
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
                "ε = {} is below h = {}, so the ball holds no neighbour; use ε ≥ h",
                readable(stencil.horizon.eps),
                readable(h)
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

/// u₀ and the source fields of the case's problem on `nodes` (all of D when None).
fn initial_state(
    case: &Case,
    stencil: &Stencil,
    operator: &impl LinearOperator,
    ranks: Ranks,
    nodes: Option<&[usize]>,
) -> (Vec<f64>, Option<Source>) {
    let grid = &stencil.grid;
    let count = nodes.map_or(grid.nodes(), <[usize]>::len);
    let sample = |f: &(dyn Fn(usize) -> f64 + Sync)| -> Vec<f64> {
        ranks.on(|| {
            (0..count)
                .into_par_iter()
                .map(|k| f(nodes.map_or(k, |nodes| nodes[k])))
                .collect()
        })
    };
    let at = |f: fn(usize, [f64; 2]) -> f64| move |i: usize| f(grid.dim, grid.position(i));
    if case.problem == Problem::Bump {
        return (sample(&at(problem::bump)), None);
    }
    let phi = sample(&at(problem::profile));
    let psi = match case.source() {
        SourceMode::Discrete => {
            let mut psi = vec![0.0; phi.len()];
            operator.apply_once(&phi, &mut psi);
            psi
        }
        SourceMode::Continuum | SourceMode::Local => {
            let pointwise = PointwiseSource::new(case, stencil).expect("a pointwise mode");
            sample(&|i| pointwise.psi(i))
        }
        SourceMode::None => unreachable!("validated: the manufactured problem has a source"),
    };
    (phi.clone(), Some(Source { phi, psi }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// `preflight` refuses what `Plan::new` (run's own check) refuses, on the same field, and
    /// nothing else: on both sides of dt = dt_stable, and of the step limit for `cfl`, where it
    /// decides from the floor under dt_stable alone.
    #[test]
    fn the_preflight_refuses_exactly_what_the_run_refuses() {
        let mut memo = std::collections::HashMap::new();
        let mut checked = 0;
        for (dim, m, kernel, quadrature) in [
            (1, 1, "constant", "midpoint"),
            (1, 3, "linear", "partial_volume"),
            (1, 4, "inverse_distance", "ac"),
            (2, 2, "constant", "ac"),
            (2, 3, "gaussian", "midpoint"),
            (2, 1, "linear", "midpoint"),
        ] {
            let base = json!({"dim": dim, "n": 32, "m": m, "kernel": kernel,
                              "quadrature": quadrature, "t_end": 0.01, "cfl": 0.5});
            let exact = Plan::new(&Case::parse(base.clone()).unwrap()).map(|p| p.dt_stable);
            let Ok(dt_stable) = exact else {
                // J = 1 − r at m = 1: no weight. Both refuse it, naming m.
                let case = Case::parse(base).unwrap();
                let refused = preflight(&case, &mut memo).unwrap_err();
                assert_eq!(refused.field, exact.unwrap_err().field);
                continue;
            };
            let limit = 1e8 * dt_stable;
            for (fields, t_end) in [
                (json!({"cfl": 0.5}), 0.01),
                (json!({"cfl": 1.0}), 0.01),
                (json!({"cfl": 1.01}), 0.01),
                (json!({"cfl": 1.0}), 0.999 * limit),
                (json!({"cfl": 1.0}), 1.001 * limit),
                (json!({"cfl": 0.5}), 0.499 * limit),
                (json!({"cfl": 0.5}), 0.501 * limit),
                (json!({"dt": 0.99 * dt_stable, "cfl": null}), 0.01),
                (json!({"dt": 1.01 * dt_stable, "cfl": null}), 0.01),
                (json!({"integrator": "rk4", "cfl": 1.0}), 0.01),
                (json!({"integrator": "crank_nicolson", "cfl": 4.0}), 0.01),
            ] {
                let mut fields_of = base.clone();
                for (name, value) in fields.as_object().unwrap() {
                    match value.is_null() {
                        true => fields_of.as_object_mut().unwrap().remove(name),
                        false => fields_of
                            .as_object_mut()
                            .unwrap()
                            .insert(name.clone(), value.clone()),
                    };
                }
                fields_of["t_end"] = json!(t_end);
                let case = Case::parse(fields_of.clone()).unwrap();
                let run = Plan::new(&case).map(drop).map_err(|e| e.field);
                let check = preflight(&case, &mut memo).map_err(|e| e.field);
                assert_eq!(check, run, "{fields_of}");
                checked += usize::from(run.is_err());
            }
        }
        assert!(checked >= 20, "{checked} refusals compared");
    }
}
