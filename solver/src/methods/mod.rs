//! The methods a case can name, and the one place where a case reaches its method.
//!
//! Each method is a module with the same two entry points: `validate(case)`, the rules of its
//! own fields, and `run(case)`, which plans, integrates and measures on the current rayon pool
//! (the distributed ones also `run(world, case, …)` over MPI ranks). This module dispatches
//! with a `match` on `Method` rather than through a trait object: the set of methods is closed
//! (a case file names one of them), the compiler then checks that every method has a rule and a
//! runner, and each arm is one call, so adding a method is one module and one arm in each of
//! `check`, `run` and `run_on_ranks`.
//!
//! A case reaches a runner only as a `ValidCase`, which outside this crate only `validate` (or
//! `ValidCase::from_json`) builds: the runners' `expect`s on fields that validation guarantees
//! cannot fire through the library's API.

pub mod coupled;
pub mod local;
pub mod nonlocal;
pub mod patch_test;
pub mod pse;
pub mod resources;
pub mod seamless;
pub mod steady;

use crate::case::Rules;
use crate::case::{refuse_given, Case, CaseError, CouplingKind, Method, ValidCase};
use crate::discretization::stencil::Stencil;
use crate::output::outcome::Outcome;
use crate::parallel::share::HaloReport;
use crate::threads;
#[cfg(feature = "mpi")]
use mpi::{topology::SimpleCommunicator, traits::*};

impl ValidCase {
    /// Checks `case` against the rules every case obeys and then those of its method.
    pub fn new(case: Case) -> Result<ValidCase, CaseError> {
        validate(case)
    }

    /// Parses and validates a case, naming the offending field on any error.
    pub fn from_json(value: serde_json::Value) -> Result<ValidCase, CaseError> {
        validate(Case::parse(value)?)
    }
}

/// Checks what can be checked before any setup; dt against dt_stable is checked when the
/// stencil is known.
pub fn validate(case: Case) -> Result<ValidCase, CaseError> {
    check(&case)?;
    #[cfg(not(feature = "mpi"))]
    refuse_ranks_without_mpi(&case)?;
    Ok(ValidCase::validated(case))
}

/// The rules every case obeys, then those of its method.
fn check(case: &Case) -> Result<(), CaseError> {
    case.validate_grid()?;
    let time_dependent = |own_rules: fn(&Case) -> Result<(), CaseError>| {
        case.refuse_steady_fields()?;
        own_rules(case)?;
        case.validate_time_dependent()
    };
    if case.method != Method::PatchTest {
        let varying = case.method == Method::Nonlocal;
        refuse_given(
            &[
                (
                    "horizon_profile",
                    case.horizon_profile.is_some() && !varying,
                ),
                ("formulation", case.formulation.is_some() && !varying),
                (
                    "patch",
                    case.patch.is_some() && case.method != Method::Coupled1d,
                ),
            ],
            |_| "belongs to a variable horizon (`patch_test`, or `nonlocal`); leave it out".into(),
        )?;
    }
    for (field, given) in [
        ("local_domain", case.local_domain.is_some()),
        ("coupling", case.coupling.is_some()),
    ] {
        if case.method != Method::Coupled1d && given {
            return Err(CaseError::new(
                field,
                "belongs to the local–nonlocal coupling `coupled_1d`; leave it out",
            ));
        }
    }
    match case.method {
        Method::Nonlocal => time_dependent(nonlocal::validate),
        Method::FdExplicit | Method::Adi => time_dependent(local::validate),
        Method::Pse => time_dependent(pse::validate),
        Method::SteadyCg | Method::Feti => steady::validate(case),
        Method::PatchTest => patch_test::validate(case),
        Method::Coupled1d => coupled::validate(case),
    }
}

/// A build without the `mpi` feature has no MPI (nor METIS): a case over several ranks is
/// refused, saying how to build with them.
#[cfg(not(feature = "mpi"))]
fn refuse_ranks_without_mpi(case: &Case) -> Result<(), CaseError> {
    if case.ranks <= 1 {
        return Ok(());
    }
    Err(CaseError::new(
        "ranks",
        format!(
            "{} ranks need MPI, and this nlsolve was built without it (`--no-default-features`); install Open MPI (`scripts/setup.sh` does) and build with the default features, `cargo build --release`",
            case.ranks
        ),
    ))
}

/// Runs `case` in this process, on a rayon pool of `case.threads` threads.
pub fn run(case: &Case) -> Result<Outcome, CaseError> {
    let case = validate(case.clone())?;
    resources::fit_machine(&case)?;
    if case.ranks > 1 {
        return Err(CaseError::new(
            "ranks",
            format!(
                "{r} ranks need MPI: start the run with `mpirun -n {r} nlsolve run …`",
                r = case.ranks
            ),
        ));
    }
    let outcome = match case.method {
        Method::Nonlocal => in_pool(&case, nonlocal::run),
        Method::FdExplicit => in_pool(&case, |case| local::run(case, false)),
        Method::Adi => in_pool(&case, |case| local::run(case, true)),
        Method::Pse => in_pool(&case, pse::run),
        // The steady methods start their pool inside their setup timing.
        Method::SteadyCg | Method::Feti => steady::run(&case),
        Method::PatchTest => in_pool(&case, patch_test::run),
        Method::Coupled1d => match case.coupling() {
            CouplingKind::Optimization => in_pool(&case, coupled::run),
            CouplingKind::Seamless => in_pool(&case, seamless::run),
        },
    };
    let used = used_by_this_process();
    outcome.map(|outcome| finished(&case, with_usage(outcome, &[used])))
}

/// What `nlsolve check` verifies beyond `validate` without running: for the time-stepping
/// methods whose stable step is known before setup (a constant-horizon `nonlocal`, `fd_explicit`,
/// `adi`, `pse`), the time step against dt_stable and the count of steps, the refusals `run`
/// would make after its setup. `memo` keeps the stencils' stable steps between cases (see
/// `nonlocal::preflight`).
pub fn preflight(
    case: &ValidCase,
    memo: &mut std::collections::HashMap<String, Result<f64, CaseError>>,
) -> Result<(), CaseError> {
    match case.method {
        Method::Nonlocal if case.horizon_profile.is_none() => nonlocal::preflight(case, memo),
        Method::FdExplicit => local::preflight(case, false),
        Method::Adi => local::preflight(case, true),
        Method::Pse => pse::preflight(case, memo),
        _ => Ok(()),
    }
}

/// Every outcome leaves through here: an `ok` record may hold no result that is not finite, and
/// each carries the memory estimate beside its measured peak.
/// This process's set-up CPU, solve CPU and solve wait (`output::usage`), `NAN` where unknown.
fn used_by_this_process() -> [f64; 3] {
    let (setup, solve) = crate::output::usage::taken();
    [
        setup.map_or(f64::NAN, |u| u.cpu_s),
        solve.map_or(f64::NAN, |u| u.cpu_s),
        solve.and_then(|u| u.wait_s).unwrap_or(f64::NAN),
    ]
}

/// The record with what each rank's process used (`used_by_this_process` of each, in rank
/// order): the CPU times and the wait summed over ranks, each rank's solve CPU beside them over
/// ranks, and the run noisy if its solve waited for cores beyond its share, or was on no core
/// for half of it (stopped, swapped out; any thread count). Only a run of one thread per rank is
/// judged by its wait: the threads of a pool wait too each time a step wakes
/// them (tens of microseconds a step on a virtual machine's idle cores), which is the run's own
/// cost, not a neighbour's.
fn with_usage(mut outcome: Outcome, ranks: &[[f64; 3]]) -> Outcome {
    let sum = |k: usize| {
        let total: f64 = ranks.iter().map(|r| r[k]).sum();
        total.is_finite().then_some(total)
    };
    let record = &mut outcome.record;
    (record.setup_cpu_s, record.solve_cpu_s, record.solve_wait_s) = (sum(0), sum(1), sum(2));
    if ranks.len() > 1 && ranks.iter().all(|r| r[1].is_finite()) {
        record.distribution.solve_cpu_s_ranks = ranks.iter().map(|r| r[1]).collect();
    }
    let one_thread = record.provenance.threads == 1;
    if let (Some(cpu), Some(wait), true) = (record.solve_cpu_s, record.solve_wait_s, one_thread) {
        record.provenance = record.provenance.clone().with_wait(cpu, wait);
    }
    if let Some(cpu) = record.solve_cpu_s {
        record.provenance =
            (record.provenance.clone()).with_time_off_cpu(record.solve_s, cpu, record.solve_wait_s);
    }
    outcome
}

fn finished(case: &ValidCase, mut outcome: Outcome) -> Outcome {
    outcome.record.diverge_if_not_finite();
    outcome.record.memory_estimate_bytes = Some(resources::estimated_bytes_per_rank(case));
    outcome
}

/// Runs a method on a rayon pool of `case.threads` threads.
fn in_pool(
    case: &ValidCase,
    run: impl FnOnce(&ValidCase) -> Result<Outcome, CaseError> + Send,
) -> Result<Outcome, CaseError> {
    threads::pool(case.threads)?.install(|| run(case))
}

/// What a distributed run of `case` would exchange, found without running it (and without
/// MPI: a build without it reports the block partition too).
pub fn partition_report(case: &Case) -> Result<HaloReport, CaseError> {
    check(case)?;
    let case = ValidCase::validated(case.clone());
    resources::fit_machine(&case)?;
    if case.method.is_local() {
        return Err(CaseError::new(
            "method",
            "the partition report is for the nonlocal method, the one that runs on many ranks",
        ));
    }
    HaloReport::measure(&case, &Stencil::of_case(&case))
}

#[cfg(feature = "mpi")]
/// Runs `case` on the ranks of `world`. Rank 0 gets the outcome (with the whole field when
/// `gather_field`), the other ranks `None`. Every rank returns the same error for bad input.
pub fn run_on_ranks(
    world: &SimpleCommunicator,
    case: &Case,
    gather_field: bool,
) -> Result<Option<Outcome>, CaseError> {
    let case = validate(case.clone())?;
    resources::fit_machine(&case)?;
    if case.method.is_local() || matches!(case.method, Method::PatchTest | Method::Coupled1d) {
        return Err(CaseError::new(
            "method",
            "fd_explicit, adi, pse, patch_test and coupled_1d run on one process; start them without mpirun",
        ));
    }
    let ranks = world.size() as usize;
    if ranks != case.ranks {
        return Err(CaseError::new(
            "ranks",
            format!(
                "the case asks for {} ranks but mpirun started {ranks}; start `mpirun -n {}` or set `ranks` to {ranks}",
                case.ranks, case.ranks
            ),
        ));
    }
    let outcome = match case.method {
        Method::Nonlocal => nonlocal::distributed::run(world, &case, gather_field),
        Method::SteadyCg | Method::Feti => steady::distributed::run(world, &case, gather_field),
        Method::FdExplicit | Method::Adi | Method::Pse | Method::PatchTest | Method::Coupled1d => {
            unreachable!("refused above")
        }
    };
    // Every rank's usage, gathered on every rank (each rank took part in the run's collectives,
    // so each takes part in this one).
    let mine = used_by_this_process();
    let mut all = vec![0.0; 3 * ranks];
    world.all_gather_into(&mine[..], &mut all[..]);
    let used: Vec<[f64; 3]> = all.chunks(3).map(|r| [r[0], r[1], r[2]]).collect();
    outcome.map(|outcome| outcome.map(|outcome| finished(&case, with_usage(outcome, &used))))
}
