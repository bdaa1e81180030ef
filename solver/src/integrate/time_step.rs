//! The time step a case runs with, and the bound beyond which a run counts as diverged.

use crate::case::{Case, CaseError};
use crate::problem::WAVENUMBER;

/// Factor above the problem's natural scale at which a solution counts as diverged.
const DIVERGENCE_FACTOR: f64 = 1e6;
/// Longest run accepted, in steps: beyond any study this tool serves, and a guard against a
/// t_end/dt typo that would run for days.
const MAX_STEPS: usize = 100_000_000;

/// The max |u| beyond which a run counts as diverged, from max |u₀| and the source's scale
/// (max |φ| and max |ψ|).
pub(crate) fn divergence_bound(case: &Case, u0_max: f64, source_max: Option<(f64, f64)>) -> f64 {
    let source_scale = source_max.map_or(0.0, |(phi, psi)| WAVENUMBER * phi + psi);
    DIVERGENCE_FACTOR * (1.0f64).max(u0_max).max(case.t_end() * source_scale)
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
