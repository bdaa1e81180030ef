//! The metrics a comparison judges, which way each improves, how each varies between runs of
//! one case, and how they are read from records.

use crate::analysis::summary::BOND_UPDATES_PER_S;
use schema::record::columns;
use schema::record::{Record, Status, Stored};
use serde_json::Value;

/// Which way a metric improves.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Better {
    Lower,
    Higher,
}

/// How a metric varies between runs of one case.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Kind {
    /// Timings and what they give: noisy, compared by intervals and the noise floor.
    Measured,
    /// Errors: the same bits on every run of one build, compared with tolerances.
    Deterministic,
}

/// A metric of a record compared: its column's name, how it is read, which way it improves and
/// how it varies.
pub(super) struct Metric {
    pub name: &'static str,
    pub read: fn(&Record<Value>) -> Option<f64>,
    pub better: Better,
    pub kind: Kind,
    /// The wall time a value is measured over, for a wall time or a rate over one: its drift is
    /// read at that scale, and below `RESOLUTION_S` it is too short to judge.
    pub span: Option<fn(&Record<Value>) -> f64>,
    /// A wall time, or a rate over one: other tasks on the machine lengthen it, so runs timed
    /// on a busy machine (`noisy`) cannot judge it. A CPU time (the work itself) and the peak
    /// memory are measured whatever the load.
    pub wall: bool,
}

/// The metrics of a record compared; `bond_updates_per_s` from bonds × steps done / solve time,
/// as the summary derives it.
pub(super) const METRICS: &[Metric] = &[
    Metric {
        name: columns::SOLVE_S,
        read: |r| Some(r.solve_s),
        better: Better::Lower,
        kind: Kind::Measured,
        span: Some(|r| r.solve_s),
        wall: true,
    },
    Metric {
        name: columns::SOLVE_CPU_S,
        read: |r| r.solve_cpu_s,
        better: Better::Lower,
        kind: Kind::Measured,
        span: Some(|r| r.solve_cpu_s.unwrap_or(r.solve_s)),
        wall: false,
    },
    Metric {
        name: columns::STEP_S,
        read: |r| Some(r.step_s),
        better: Better::Lower,
        kind: Kind::Measured,
        span: None,
        wall: true,
    },
    Metric {
        name: columns::SETUP_S,
        read: |r| Some(r.setup_s),
        better: Better::Lower,
        kind: Kind::Measured,
        span: Some(|r| r.setup_s),
        wall: true,
    },
    Metric {
        name: BOND_UPDATES_PER_S,
        read: |r| Some(r.resolved.bonds as f64 * r.steps_done as f64 / r.solve_s),
        better: Better::Higher,
        kind: Kind::Measured,
        span: Some(|r| r.solve_s),
        wall: true,
    },
    Metric {
        name: columns::PEAK_MEMORY_BYTES,
        read: |r| r.peak_memory_bytes.map(|b| b as f64),
        better: Better::Lower,
        kind: Kind::Measured,
        span: None,
        wall: false,
    },
    Metric {
        name: columns::ERROR_L2_NORM,
        read: |r| r.error_l2_norm,
        better: Better::Lower,
        kind: Kind::Deterministic,
        span: None,
        wall: false,
    },
    Metric {
        name: columns::ERROR_MAX,
        read: |r| r.error_max,
        better: Better::Lower,
        kind: Kind::Deterministic,
        span: None,
        wall: false,
    },
];

/// The metric called `name`.
pub(super) fn metric(name: &str) -> &'static Metric {
    METRICS
        .iter()
        .find(|m| m.name == name)
        .expect("a metric of METRICS")
}

/// The observed orders the summary derives, better when closer to the theoretical order (the
/// whole number nearest the baseline's: the orders of these methods are whole) by more than
/// `ORDER_TOLERANCE`, worse when farther. Deterministic, as the errors they come from.
pub(super) const ORDERS: &[&str] = &["order_l2", "order_max"];

/// How far an observed order may move before it counts as a change.
pub const ORDER_TOLERANCE: f64 = 0.1;

/// Whether `metric` is an observed order (judged by `order_shift`, not by a ratio).
pub fn is_order(metric: &str) -> bool {
    ORDERS.contains(&metric)
}

/// How much farther B's observed order lies from the theoretical one (the whole number nearest
/// A's) than A's: positive when B is worse. What an order's verdict judges.
pub fn order_shift(a: f64, b: f64) -> f64 {
    let theory = a.round();
    (b - theory).abs() - (a - theory).abs()
}

/// Errors differ when |b − a| > ABSOLUTE + RELATIVE·|a|: round-off of a changed summation order
/// stays below, a changed discretization does not.
pub(super) const RELATIVE: f64 = 1e-9;

pub(super) const ABSOLUTE: f64 = 1e-14;

/// Wall times (`solve_s`, `setup_s`) shorter than this are start-up effects (page faults, the
/// clock ramping up) more than the solver's work: too short to judge.
pub(super) const RESOLUTION_S: f64 = 1e-3;

/// The scale a measured metric's drift is read at: its span if it has one, else its value.
pub(super) fn scale_of(metric: &Metric, record: &Stored) -> Option<f64> {
    let record = record.record()?;
    match metric.span {
        Some(span) => Some(span(record)),
        None => (metric.read)(record),
    }
}

/// The records that measured something (`ok`, `diverged`).
pub fn measured<'a>(records: &[&'a Stored]) -> Vec<&'a Stored> {
    records
        .iter()
        .copied()
        .filter(|r| matches!(r.status(), Status::Ok | Status::Diverged))
        .collect()
}

/// The metric's finite values over the records (positive ones for a measured metric, whose
/// ratios are taken).
pub(super) fn values(records: &[&Stored], metric: &Metric) -> Vec<f64> {
    records
        .iter()
        .filter_map(|r| (metric.read)(r.record()?))
        .filter(|x| x.is_finite() && (metric.kind == Kind::Deterministic || *x > 0.0))
        .collect()
}
