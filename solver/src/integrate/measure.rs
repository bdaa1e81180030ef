//! What a time-dependent run measured, reduced over its ranks, and the outcome of a run in one
//! process.

use super::timed::{Stepping, Trajectory};
use crate::case::Case;
use crate::discretization::grid::Lattice;
use crate::output::diagnostics::{self, median};
use crate::output::field;
use crate::output::outcome::{record, Measured, Outcome};
use crate::output::record::{Distribution, Resolved};
use crate::parallel::exchange::Ranks;

/// The nodal exact solution at the final time, when the problem has one.
pub type Exact<'a> = Option<&'a (dyn Fn(usize) -> f64 + Sync)>;

/// The measurements of a trajectory on `ranks` (each holding its own nodes of the field): times
/// are maxima over ranks, errors and mass sums. The histogram and the field snapshot need the
/// whole field, so only single-process runs have them (validation refuses them for ranks > 1).
// Each argument is one stage's product of the same run; a struct of them would only rename them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn measure(
    ranks: Ranks,
    case: &Case,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: &Trajectory,
    lattice: &Lattice,
    exact: Exact,
    distribution: Distribution,
) -> Measured {
    let Trajectory {
        u,
        timing,
        error_total,
        c_tot,
        ..
    } = trajectory;
    // A diverged field has no meaningful error.
    let exact = exact.filter(|_| timing.diverged_at.is_none());
    let errors = exact.map(|exact| {
        let (squared, max) = ranks.on(|| {
            (
                diagnostics::squared_l2_error(exact, u, stepping.volume),
                diagnostics::max_error(exact, u),
            )
        });
        (ranks.sum(squared), ranks.max(max))
    });
    let single = ranks.exchange.ranks() == 1;
    Measured {
        setup_s: ranks.max(setup_s),
        solve_s: ranks.max(timing.solve_seconds),
        step_s: ranks.max(median(timing.step_seconds.clone())),
        steps_done: timing.steps_done,
        resumed_from_step: timing.resumed_from_step,
        segments_s: timing.segments_s.clone(),
        diverged_at: timing.diverged_at,
        divergence_bound: stepping.divergence_bound,
        peak_max_abs: ranks.max(timing.peak_max_abs),
        errors,
        error_total: *error_total,
        mass: ranks.sum(ranks.on(|| diagnostics::total_mass(u, stepping.volume))),
        max_abs: ranks.max_abs(u),
        c_tot: c_tot.clone(),
        histogram: case
            .histogram_bins
            .filter(|_| single)
            .and_then(|bins| ranks.on(|| diagnostics::histogram(u, bins))),
        field: case
            .field_snapshot
            .filter(|_| single)
            .map(|side| ranks.on(|| field::snapshot(lattice, u, exact, side))),
        distribution,
        implicit: trajectory.implicit,
        operator_applications: trajectory.operator_applications,
        amplification: trajectory.amplification,
        positivity: trajectory.positivity,
    }
}

/// The outcome of a run in one process: its trajectory measured and recorded, with the errors
/// against `exact`.
pub(crate) fn serial_outcome(
    case: &Case,
    resolved: Resolved,
    setup_s: f64,
    stepping: &Stepping,
    trajectory: Trajectory,
    lattice: Lattice,
    exact: Exact,
) -> Outcome {
    let distribution = Distribution::serial(case);
    let measured = measure(
        Ranks::single(),
        case,
        setup_s,
        stepping,
        &trajectory,
        &lattice,
        exact,
        distribution,
    );
    Outcome {
        record: record(case, resolved, measured),
        field: trajectory.u,
        lattice,
        frames: trajectory.frames,
    }
}
