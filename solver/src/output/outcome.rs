//! A finished run: what its time loop measured, turned into its record, with its final field.

use crate::case::Case;
use crate::discretization::grid::Lattice;
use crate::output::diagnostics::{Histogram, MassSeries};
use crate::output::field::{FieldSnapshot, Frame};
use crate::output::record::{Distribution, ImplicitSolves, Record, Resolved, Status};

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
    pub implicit: ImplicitSolves,
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
        status,
        message,
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
        implicit: measured.implicit,
        ..Record::new(case, resolved, measured.distribution)
    }
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}
