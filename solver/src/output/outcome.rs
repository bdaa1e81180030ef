//! A finished run: what its time loop measured, turned into its record, with its final field.

use crate::case::readable;
use crate::case::Case;
use crate::discretization::grid::Lattice;
use crate::output::diagnostics::{Amplification, Histogram, MassSeries};
use crate::output::field::{FieldSnapshot, Frame};
use crate::output::record::{
    self, first_non_finite, Distribution, ImplicitSolves, Record, Resolved, Status,
};
use schema::record::GROWING;

/// A finished run: its record, the final field on the nodes of D (empty when a distributed run
/// did not gather it), where its values sit, and the frames the case asked for.
pub struct Outcome {
    pub record: Record,
    pub field: Vec<f64>,
    pub lattice: Lattice,
    pub frames: Vec<Frame>,
}

/// What a time loop measured, already reduced over ranks.
pub(crate) struct Measured {
    pub setup_s: f64,
    pub solve_s: f64,
    pub step_s: f64,
    pub steps_done: usize,
    /// The step the run resumed from (0: from the start) and each segment's solve time.
    pub resumed_from_step: usize,
    pub segments_s: Vec<f64>,
    pub diverged_at: Option<usize>,
    pub divergence_bound: f64,
    /// The largest max |u| of any step.
    pub peak_max_abs: f64,
    /// (eᵏ, max error) at the final time, for a manufactured problem that did not diverge.
    pub errors: Option<(f64, f64)>,
    pub error_total: Option<f64>,
    pub mass: f64,
    pub max_abs: f64,
    pub c_tot: Option<MassSeries>,
    pub histogram: Option<Histogram>,
    pub field: Option<FieldSnapshot>,
    pub distribution: Distribution,
    pub implicit: ImplicitSolves,
    pub operator_applications: Option<usize>,
    pub amplification: Option<Amplification>,
    pub positivity: Option<f64>,
}

/// The record of a finished run.
pub(crate) fn record(case: &Case, resolved: Resolved, measured: Measured) -> Record {
    let t_final = measured.steps_done as f64 * resolved.dt;
    let (status, message) = match (measured.diverged_at, non_finite(&measured)) {
        (None, None) => (Status::Ok, String::new()),
        // Below the bound at every step, yet a measure is not a number: nothing usable was
        // measured, so the run is not `ok` (its record would hold a null or a NaN-blind 0).
        (None, Some((name, value))) => (
            Status::Diverged,
            format!(
                "`{name}` is {value} at t = {} although max |u| stayed below {}: the run produced no finite result; dt/dt_stable = {}",
                readable(t_final),
                readable(measured.divergence_bound),
                readable(resolved.dt / resolved.dt_stable)
            ),
        ),
        (Some(step), _) => (
            Status::Diverged,
            format!(
                "max |u| exceeded {} at step {step} (t = {}); dt/dt_stable = {}",
                readable(measured.divergence_bound),
                readable(t_final),
                readable(resolved.dt / resolved.dt_stable)
            ),
        ),
    };
    let errors = measured.errors;
    let growth = growth(measured.peak_max_abs, measured.divergence_bound);
    let message = match (status, growth) {
        (Status::Ok, Some(g)) if g >= GROWING => format!(
            "max |u| grew to 1e{} times the problem's scale without passing the divergence bound (1e{}): likely unstable",
            readable(g.floor()),
            readable(DIVERGENCE_FACTOR.log10())
        ),
        _ => message,
    };
    Record {
        status,
        message,
        growth,
        amplification: measured.amplification.map(|a| a.value),
        amplification_low: measured.amplification.and_then(|a| a.bounds).map(|b| b.0),
        amplification_high: measured.amplification.and_then(|a| a.bounds).map(|b| b.1),
        amplification_applications: (measured.amplification)
            .and_then(|a| a.applications)
            .map(|a| a as u64),
        positivity: measured.positivity,
        steps_done: measured.steps_done,
        resumed_from_step: (measured.resumed_from_step > 0).then_some(measured.resumed_from_step),
        solve_s_segments: (measured.resumed_from_step > 0).then_some(measured.segments_s),
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
        implicit: measured.implicit,
        operator_applications: measured.operator_applications.map(|a| a as u64),
        ..record::fresh(case, resolved, measured.distribution)
    }
}

/// Factor above the problem's natural scale at which a solution counts as diverged
/// (`time_step::divergence_bound`); the record's `growth` is measured against the same scale.
pub(crate) const DIVERGENCE_FACTOR: f64 = 1e6;

/// log₁₀ of the largest max |u| of any step over the problem's scale (the divergence bound over
/// 10⁶): ≤ 0 for a run that never outgrew its start or its source, the decades it grew else;
/// `None` when nothing finite was seen.
fn growth(peak_max_abs: f64, divergence_bound: f64) -> Option<f64> {
    let scale = divergence_bound / DIVERGENCE_FACTOR;
    finite((peak_max_abs / scale).log10())
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// The first of a run's measures that is not a finite number, by its name in the record. Checked
/// here, not only by `Record::diverge_if_not_finite`: the record holds these as `finite(x)`, a
/// null for a value that is not a number, which that later check cannot tell from "not measured".
fn non_finite(measured: &Measured) -> Option<(&'static str, f64)> {
    let (squared, max) = measured.errors.unzip();
    first_non_finite([
        ("error_l2", squared),
        ("error_max", max),
        ("error_total", measured.error_total),
        ("mass", Some(measured.mass)),
        ("max_abs", Some(measured.max_abs)),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case() -> Case {
        Case::parse(serde_json::json!({"dim": 2, "n": 4, "m": 1, "t_end": 0.1, "cfl": 0.5}))
            .unwrap()
    }

    /// The record of one step that stayed below the bound, with these measures.
    fn recorded(errors: Option<(f64, f64)>, mass: f64) -> Record {
        let case = case();
        let measured = Measured {
            setup_s: 0.0,
            solve_s: 0.0,
            step_s: 0.0,
            steps_done: 1,
            resumed_from_step: 0,
            segments_s: Vec::new(),
            diverged_at: None,
            divergence_bound: 1e6,
            peak_max_abs: 1.0,
            errors,
            error_total: None,
            mass,
            max_abs: 1.0,
            c_tot: None,
            histogram: None,
            field: None,
            distribution: Distribution::serial(&case),
            implicit: ImplicitSolves::default(),
            operator_applications: None,
            amplification: None,
            positivity: None,
        };
        let resolved = Resolved {
            dt: 0.1,
            dt_stable: 0.2,
            ..Resolved::default()
        };
        record(&case, resolved, measured)
    }

    #[test]
    fn a_run_whose_measures_are_not_finite_is_not_ok() {
        assert_eq!(recorded(Some((1e-6, 1e-3)), 0.5).status, Status::Ok);
        for (errors, mass, name) in [
            (Some((f64::NAN, 0.0)), 0.5, "error_l2"),
            (Some((1e-6, f64::INFINITY)), 0.5, "error_max"),
            (None, f64::NAN, "mass"),
        ] {
            let record = recorded(errors, mass);
            assert_eq!(record.status, Status::Diverged, "{name}");
            assert!(record.message.contains(name), "{}", record.message);
        }
    }
}
