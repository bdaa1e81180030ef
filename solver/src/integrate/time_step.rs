//! The time step a case runs with, and the bound beyond which a run counts as diverged.

use crate::case::{readable, Case, CaseError};
use crate::problem::WAVENUMBER;

use crate::output::outcome::DIVERGENCE_FACTOR;
/// Longest run accepted, in steps: beyond any study this tool serves, and a guard against a
/// t_end/dt typo that would run for days.
const MAX_STEPS: usize = 100_000_000;

/// The max |u| beyond which a run counts as diverged, from max |u₀| and the source's scale
/// (max |φ| and max |ψ|). Never above the largest finite number: a bound that overflowed to +∞
/// would let a field of +∞ (and of NaN, which counts as +∞) pass as not diverged.
pub(crate) fn divergence_bound(case: &Case, u0_max: f64, source_max: Option<(f64, f64)>) -> f64 {
    let source_scale = source_max.map_or(0.0, |(phi, psi)| WAVENUMBER * phi + psi);
    (DIVERGENCE_FACTOR * (1.0f64).max(u0_max).max(case.t_end() * source_scale)).min(f64::MAX)
}

/// The time step the case asks for, before it is lowered to land on t_end: its `dt`, or `cfl`
/// times dt_stable; with the field that gave it.
pub(crate) fn requested(case: &Case, dt_stable: f64) -> (f64, &'static str) {
    match (case.dt, case.cfl) {
        (Some(dt), _) => (dt, "dt"),
        (None, Some(cfl)) => (cfl * dt_stable, "cfl"),
        (None, None) => unreachable!("validated: dt or cfl"),
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
    // dt_stable ∝ h²/k: one that is not a positive finite number means that L_h's weights are
    // no numbers (k overflowed them) or all vanish (+∞: every bond of the horizon has J = 0),
    // and no step would compute a number. Validation keeps k of ordinary size; this is the guard.
    if !(dt_stable > 0.0 && dt_stable.is_finite()) {
        let field = match (dt_stable == f64::INFINITY, case.horizon_profile.is_some()) {
            (false, _) => "diffusivity",
            (true, true) => "horizon_profile",
            (true, false) if case.m.is_some() => "m",
            (true, false) => "eps",
        };
        return Err(CaseError::new(
            field,
            format!(
                "gives the stable time step dt_stable = {} (∝ h²/k at k = {}), not a positive finite number: the operator's weights vanish or are no numbers; use a horizon whose bonds carry weight (ε ≥ 2h for J = 1 − r) and a diffusivity of ordinary size",
                readable(dt_stable),
                readable(case.diffusivity)
            ),
        ));
    }
    let (requested, field) = requested(case, dt_stable);
    if requested > dt_stable * (1.0 + 1e-12) && !case.allow_unstable && !unconditionally_stable {
        return Err(CaseError::new(
            field,
            format!(
                "gives dt = {} above dt_stable = {} for this case; lower `dt`, \
                 use `cfl` ≤ 1, or set `allow_unstable: true` to probe instability",
                readable(requested),
                readable(dt_stable)
            ),
        ));
    }
    let steps = ((case.t_end() / requested) * (1.0 - 1e-12)).ceil().max(1.0);
    // With dt = cfl·dt_stable the steps grow like k (dt_stable ∝ 1/k): when k is what takes
    // them past the limit (they would fit at k = 1), the diffusivity is the field to change.
    let k = case.diffusivity;
    if steps > MAX_STEPS as f64 && field == "cfl" && k > 1.0 && steps / k <= MAX_STEPS as f64 {
        return Err(CaseError::new(
            "diffusivity",
            format!(
                "k = {} makes dt_stable ∝ h²/k so small that t_end needs {} steps of cfl·dt_stable, more than {}; use a smaller diffusivity (or a shorter `t_end`)",
                readable(k),
                readable(steps),
                readable(MAX_STEPS as f64)
            ),
        ));
    }
    if steps > MAX_STEPS as f64 {
        return Err(CaseError::new(
            "t_end",
            format!(
                "t_end / dt = {} steps, more than {}; shorten `t_end` or enlarge the time step",
                readable(steps),
                readable(MAX_STEPS as f64)
            ),
        ));
    }
    Ok((case.t_end() / steps, steps as usize))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn case(fields: serde_json::Value) -> Case {
        Case::parse(fields).unwrap()
    }

    #[test]
    fn a_stable_step_that_is_no_positive_number_is_refused_naming_the_field() {
        let case = case(json!({
            "dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "diffusivity": 1e308
        }));
        for dt_stable in [f64::NAN, 0.0, -0.0, -1.0] {
            for unconditionally_stable in [false, true] {
                let refusal = time_step(&case, dt_stable, unconditionally_stable).unwrap_err();
                assert_eq!(refusal.field, "diffusivity", "{dt_stable}: {refusal}");
            }
        }
        // +∞: L_h vanished, which the horizon decides.
        let refusal = time_step(&case, f64::INFINITY, false).unwrap_err();
        assert_eq!(refusal.field, "m", "{refusal}");
    }

    #[test]
    fn too_many_steps_name_the_diffusivity_when_it_is_the_cause() {
        // dt_stable ∝ h²/k: at k = 1e300 about 1e-303, so 2e301 steps of half of it.
        let large = case(json!({
            "dim": 2, "n": 16, "m": 2, "t_end": 0.01, "cfl": 0.5, "diffusivity": 1e300
        }));
        let refusal = time_step(&large, 1e-303, false).unwrap_err();
        assert_eq!(refusal.field, "diffusivity", "{refusal}");
        // At k = 1 it is the final time.
        let long = case(json!({"dim": 1, "n": 16, "m": 2, "t_end": 1e9, "cfl": 0.5}));
        let refusal = time_step(&long, 1e-3, false).unwrap_err();
        assert_eq!(refusal.field, "t_end", "{refusal}");
    }

    #[test]
    fn the_divergence_bound_stays_finite_whatever_the_source() {
        let case = case(json!({"dim": 1, "n": 8, "m": 2, "t_end": 1e300, "cfl": 0.5}));
        assert_eq!(divergence_bound(&case, 1.0, Some((1.0, 1e300))), f64::MAX);
        let bound = divergence_bound(&case, f64::NAN, Some((f64::INFINITY, f64::NAN)));
        assert!(bound.is_finite(), "{bound}");
    }
}
