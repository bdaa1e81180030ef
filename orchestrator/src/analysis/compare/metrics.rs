//! The metrics a comparison judges, which way each improves, how each varies between runs of
//! one case, and how they are read from records.

use schema::record::Status;
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

/// The metrics of a record compared, with their direction.
pub(super) const METRICS: &[(&str, Better, Kind)] = &[
    ("solve_s", Better::Lower, Kind::Measured),
    ("step_s", Better::Lower, Kind::Measured),
    ("setup_s", Better::Lower, Kind::Measured),
    ("bond_updates_per_s", Better::Higher, Kind::Measured),
    ("peak_memory_bytes", Better::Lower, Kind::Measured),
    ("error_l2_norm", Better::Lower, Kind::Deterministic),
    ("error_max", Better::Lower, Kind::Deterministic),
];

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

/// The scale a measured metric's drift is read at: a rate's is its run's solve time.
pub(super) fn scale_of(metric: &str, record: &Value) -> Option<f64> {
    match metric {
        "bond_updates_per_s" => record.get("solve_s")?.as_f64(),
        _ => record.get(metric)?.as_f64(),
    }
}

pub(super) fn is_noisy(record: &Value) -> bool {
    record.pointer("/provenance/noisy") == Some(&Value::Bool(true))
}

/// The records that measured something (`ok`, `diverged`).
pub fn measured<'a>(records: &[&'a Value]) -> Vec<&'a Value> {
    records
        .iter()
        .copied()
        .filter(|r| matches!(Status::of_record(r), Some(Status::Ok | Status::Diverged)))
        .collect()
}

/// The metric's finite values over the records (positive ones for a measured metric, whose
/// ratios are taken); `bond_updates_per_s` from bonds × steps done / solve time, as the
/// summary derives it.
pub(super) fn values(records: &[&Value], metric: &str, kind: Kind) -> Vec<f64> {
    records
        .iter()
        .filter_map(|r| match metric {
            "bond_updates_per_s" => {
                let count = |f: &str| r.get(f)?.as_f64();
                Some(count("bonds")? * count("steps_done")? / count("solve_s")?)
            }
            _ => r.get(metric)?.as_f64(),
        })
        .filter(|x| x.is_finite() && (kind == Kind::Deterministic || *x > 0.0))
        .collect()
}
