//! `nlstudy compare`: two result sets of one study, point by point. For each metric with a
//! direction, the ratio B/A of the medians over the repeats with a bootstrap confidence
//! interval; a change is called only when the interval clears 1 by more than the threshold.
//! Errors are deterministic: they are compared with a relative and an absolute tolerance (a
//! reference of 0 breaks a relative one alone), not with intervals.

use crate::console::number;
use crate::statistics::median;
use crate::store::table::Row;
use schema::record::Status;
use serde_json::{json, Value};
use std::collections::HashMap;

/// Which way a metric improves.
#[derive(Clone, Copy, PartialEq)]
enum Better {
    Lower,
    Higher,
    /// Closer to the theoretical order (a convergence order).
    Closer,
}

/// How a metric varies between runs of one case.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Timings and what they give: noisy, compared by intervals over the repeats.
    Measured,
    /// Errors: the same bits on every run of one build, compared with tolerances.
    Deterministic,
}

/// The metrics compared, with their direction.
const METRICS: &[(&str, Better, Kind)] = &[
    ("solve_s", Better::Lower, Kind::Measured),
    ("step_s", Better::Lower, Kind::Measured),
    ("setup_s", Better::Lower, Kind::Measured),
    ("bond_updates_per_s", Better::Higher, Kind::Measured),
    ("peak_memory_bytes", Better::Lower, Kind::Measured),
    ("error_l2_norm", Better::Lower, Kind::Deterministic),
    ("error_max", Better::Lower, Kind::Deterministic),
];

/// What the summary derives, compared point by point: speedup and efficiency (higher is better,
/// beyond the threshold; from medians, so without an interval), and observed orders, better
/// when closer to the theoretical order (taken as the whole number nearest the baseline's: the
/// orders of these methods are whole) by more than `ORDER_TOLERANCE`, worse when farther.
const DERIVED: &[(&str, Better)] = &[
    ("speedup", Better::Higher),
    ("efficiency", Better::Higher),
    ("order_l2", Better::Closer),
    ("order_max", Better::Closer),
];

/// How far an observed order may move before it counts as a change.
const ORDER_TOLERANCE: f64 = 0.1;

/// Errors differ when |b − a| > ABSOLUTE + RELATIVE·|a|: round-off of a changed summation order
/// stays below, a changed discretization does not.
const RELATIVE: f64 = 1e-9;
const ABSOLUTE: f64 = 1e-14;

/// Bootstrap resamples per interval, and the interval's coverage.
const RESAMPLES: usize = 2000;
const COVERAGE: f64 = 0.95;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict {
    Better,
    Worse,
    Same,
    /// Too few repeats on a side to form an interval.
    NoInterval,
}

impl Verdict {
    fn text(self) -> &'static str {
        match self {
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::Same => "same",
            Verdict::NoInterval => "no interval (fewer than 2 repeats)",
        }
    }
}

/// One metric of one point on both sides.
pub struct Change {
    pub point: String,
    pub metric: &'static str,
    pub a: f64,
    pub b: f64,
    /// B/A of the medians (of the values, for a deterministic metric).
    pub ratio: f64,
    /// The bootstrap interval of the ratio (measured metrics with repeats on both sides).
    pub interval: Option<(f64, f64)>,
    pub verdict: Verdict,
}

/// A point's runs on each side: its label and each side's records (one per repeat).
pub struct Paired<'a> {
    pub point: String,
    pub a: Vec<&'a Value>,
    pub b: Vec<&'a Value>,
}

pub struct Comparison {
    pub changes: Vec<Change>,
    /// Points stored on one side only.
    pub only_a: Vec<String>,
    pub only_b: Vec<String>,
}

impl Comparison {
    pub fn regressions(&self) -> usize {
        self.changes
            .iter()
            .filter(|c| c.verdict == Verdict::Worse)
            .count()
    }
}

/// Compares each point's runs, `threshold` being the smallest change in a measured metric that
/// counts (0.1: the interval of B/A must lie above 1.1 or below 1/1.1).
pub fn compare(points: &[Paired], threshold: f64) -> Comparison {
    let mut comparison = Comparison {
        changes: Vec::new(),
        only_a: Vec::new(),
        only_b: Vec::new(),
    };
    for paired in points {
        let (a, b) = (measured(&paired.a), measured(&paired.b));
        match (a.is_empty(), b.is_empty()) {
            (true, true) => continue,
            (false, true) => comparison.only_a.push(paired.point.clone()),
            (true, false) => comparison.only_b.push(paired.point.clone()),
            (false, false) => {
                for &(metric, better, kind) in METRICS {
                    let (xa, xb) = (values(&a, metric, kind), values(&b, metric, kind));
                    if xa.is_empty() || xb.is_empty() {
                        continue;
                    }
                    let seed = seed_of(&paired.point, metric);
                    comparison.changes.push(change(
                        &paired.point,
                        metric,
                        better,
                        kind,
                        &xa,
                        &xb,
                        threshold,
                        seed,
                    ));
                }
            }
        }
    }
    comparison
}

#[allow(clippy::too_many_arguments)]
fn change(
    point: &str,
    metric: &'static str,
    better: Better,
    kind: Kind,
    a: &[f64],
    b: &[f64],
    threshold: f64,
    seed: u64,
) -> Change {
    let (ma, mb) = (median(a), median(b));
    let ratio = mb / ma;
    let (interval, verdict) = match kind {
        Kind::Deterministic => {
            let differs = (mb - ma).abs() > ABSOLUTE + RELATIVE * ma.abs();
            let verdict = match (differs, mb < ma) {
                (false, _) => Verdict::Same,
                (true, lower) if lower == (better == Better::Lower) => Verdict::Better,
                (true, _) => Verdict::Worse,
            };
            (None, verdict)
        }
        Kind::Measured if a.len() < 2 || b.len() < 2 => (None, Verdict::NoInterval),
        Kind::Measured => {
            let (low, high) = bootstrap(a, b, seed);
            let (up, down) = (low > 1.0 + threshold, high < 1.0 / (1.0 + threshold));
            let verdict = match (up, down, better) {
                (true, _, Better::Lower) | (_, true, Better::Higher) => Verdict::Worse,
                (true, _, Better::Higher) | (_, true, Better::Lower) => Verdict::Better,
                _ => Verdict::Same,
            };
            (Some((low, high)), verdict)
        }
    };
    Change {
        point: point.to_string(),
        metric,
        a: ma,
        b: mb,
        ratio,
        interval,
        verdict,
    }
}

/// What the summaries of the two sides derive for each point (`DERIVED`), by the `point` label.
pub fn compare_derived(a: &[Row], b: &[Row], threshold: f64) -> Vec<Change> {
    let mut changes = Vec::new();
    for row_a in a {
        let Some(point) = row_a.text("point") else {
            continue;
        };
        let Some(row_b) = b.iter().find(|r| r.text("point") == Some(point)) else {
            continue;
        };
        for &(metric, better) in DERIVED {
            let (Some(xa), Some(xb)) = (row_a.number(metric), row_b.number(metric)) else {
                continue;
            };
            if !(xa.is_finite() && xb.is_finite()) {
                continue;
            }
            let ratio = xb / xa;
            let verdict = match better {
                Better::Closer => {
                    let theory = xa.round();
                    let moved = (xb - theory).abs() - (xa - theory).abs();
                    match moved {
                        m if m > ORDER_TOLERANCE => Verdict::Worse,
                        m if m < -ORDER_TOLERANCE => Verdict::Better,
                        _ => Verdict::Same,
                    }
                }
                _ if ratio < 1.0 / (1.0 + threshold) => Verdict::Worse,
                _ if ratio > 1.0 + threshold => Verdict::Better,
                _ => Verdict::Same,
            };
            changes.push(Change {
                point: point.to_string(),
                metric,
                a: xa,
                b: xb,
                ratio,
                interval: None,
                verdict,
            });
        }
    }
    changes
}

/// The records that measured something (`ok`, `diverged`).
pub fn measured<'a>(records: &[&'a Value]) -> Vec<&'a Value> {
    records
        .iter()
        .copied()
        .filter(|r| matches!(Status::of(r), Some(Status::Ok | Status::Diverged)))
        .collect()
}

/// The metric's finite values over the records (positive ones for a measured metric, whose
/// ratios are taken); `bond_updates_per_s` from bonds × steps done / solve time, as the
/// summary derives it.
fn values(records: &[&Value], metric: &str, kind: Kind) -> Vec<f64> {
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

/// The percentile interval of median(B*)/median(A*) over resamples of each side's repeats.
fn bootstrap(a: &[f64], b: &[f64], seed: u64) -> (f64, f64) {
    let mut random = crate::statistics::SplitMix(seed);
    let mut resample = |values: &[f64]| -> f64 {
        let drawn: Vec<f64> = (0..values.len())
            .map(|_| values[random.below(values.len())])
            .collect();
        median(&drawn)
    };
    let mut ratios: Vec<f64> = (0..RESAMPLES).map(|_| resample(b) / resample(a)).collect();
    ratios.sort_by(f64::total_cmp);
    let tail = (1.0 - COVERAGE) / 2.0;
    let at = |q: f64| ratios[((q * (RESAMPLES - 1) as f64).round() as usize).min(RESAMPLES - 1)];
    (at(tail), at(1.0 - tail))
}

/// A seed from the point and metric (FNV-1a), so that intervals do not depend on the order.
fn seed_of(point: &str, metric: &str) -> u64 {
    point
        .bytes()
        .chain([0])
        .chain(metric.bytes())
        .fold(0xcbf2_9ce4_8422_2325, |h, byte| {
            (h ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
}

/// The machines the measured records of a side ran on: their CPU models, instruction sets and
/// cores online.
pub fn machines(records: &[&Value]) -> Vec<String> {
    let mut machines: Vec<String> = measured(records)
        .iter()
        .map(|r| {
            let field = |f: &str| match crate::store::provenance(r, f) {
                "" => "unknown",
                text => text,
            };
            let cores = r
                .pointer("/provenance/cores_online")
                .and_then(Value::as_u64)
                .map_or("unknown".to_string(), |n| n.to_string());
            format!(
                "{} ({}, {cores} cores)",
                field("cpu"),
                field("instruction_set")
            )
        })
        .collect();
    machines.sort();
    machines.dedup();
    machines
}

/// The comparison as a Markdown table: the changed metrics first, then the others.
pub fn markdown(comparison: &Comparison) -> String {
    let mut changes: Vec<&Change> = comparison.changes.iter().collect();
    changes.sort_by_key(|c| match c.verdict {
        Verdict::Worse => 0,
        Verdict::Better => 1,
        Verdict::NoInterval => 2,
        Verdict::Same => 3,
    });
    let mut text =
        String::from("| point | metric | A | B | B/A | 95 % interval | verdict |\n| --- | --- | --- | --- | --- | --- | --- |\n");
    for c in changes {
        let interval = c.interval.map_or(String::new(), |(lo, hi)| {
            format!("[{}, {}]", number(lo), number(hi))
        });
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {interval} | {} |\n",
            c.point,
            c.metric,
            number(c.a),
            number(c.b),
            if c.ratio.is_finite() {
                number(c.ratio)
            } else {
                String::new()
            },
            c.verdict.text()
        ));
    }
    text
}

/// The comparison as table rows (for Parquet).
pub fn rows(comparison: &Comparison) -> Vec<Row> {
    comparison
        .changes
        .iter()
        .map(|c| {
            let mut row = Row::default();
            row.set("point", json!(c.point));
            row.set("metric", json!(c.metric));
            row.set("a", json!(c.a));
            row.set("b", json!(c.b));
            row.set("ratio", json!(c.ratio));
            row.set("low", json!(c.interval.map(|i| i.0)));
            row.set("high", json!(c.interval.map(|i| i.1)));
            row.set("verdict", json!(c.verdict.text()));
            row
        })
        .collect()
}

/// Pairs each point's repeats (their keys) with the records each side holds for them.
pub fn pair<'a>(
    points: &[(String, Vec<String>)],
    a: &'a HashMap<String, Value>,
    b: &'a HashMap<String, Value>,
) -> Vec<Paired<'a>> {
    points
        .iter()
        .map(|(point, keys)| Paired {
            point: point.clone(),
            a: keys.iter().filter_map(|k| a.get(k)).collect(),
            b: keys.iter().filter_map(|k| b.get(k)).collect(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(solve_s: f64, error: f64) -> Value {
        json!({"status": "ok", "solve_s": solve_s, "error_l2_norm": error, "bonds": 100, "steps_done": 10})
    }

    fn refs(values: &[Value]) -> Vec<&Value> {
        values.iter().collect()
    }

    #[test]
    fn a_true_slowdown_is_called_and_noise_is_not() {
        // A: times around 1 s with 3 % noise; B twice as slow; C the same as A.
        let noise = [1.0, 1.03, 0.98, 1.01, 0.97];
        let a: Vec<Value> = noise.iter().map(|t| run(*t, 1e-3)).collect();
        let b: Vec<Value> = noise.iter().rev().map(|t| run(2.0 * t, 1e-3)).collect();
        let c: Vec<Value> = noise.iter().rev().map(|t| run(*t * 1.01, 1e-3)).collect();
        let slower = compare(
            &[Paired {
                point: "n=8".into(),
                a: refs(&a),
                b: refs(&b),
            }],
            0.1,
        );
        let solve = &slower.changes[0];
        assert_eq!((solve.metric, solve.verdict), ("solve_s", Verdict::Worse));
        let (low, high) = solve.interval.unwrap();
        assert!(
            low > 1.1 && high < 2.2 && (solve.ratio - 2.0).abs() < 1e-12,
            "{low} {high}"
        );
        let rate = slower
            .changes
            .iter()
            .find(|c| c.metric == "bond_updates_per_s")
            .unwrap();
        assert_eq!(rate.verdict, Verdict::Worse, "half the rate is worse too");
        let error = slower
            .changes
            .iter()
            .find(|c| c.metric == "error_l2_norm")
            .unwrap();
        assert_eq!(error.verdict, Verdict::Same);
        assert_eq!(slower.regressions(), 2);

        let same = compare(
            &[Paired {
                point: "n=8".into(),
                a: refs(&a),
                b: refs(&c),
            }],
            0.1,
        );
        assert!(
            same.changes.iter().all(|c| c.verdict == Verdict::Same),
            "A/A"
        );
    }

    #[test]
    fn derived_speedups_and_orders_are_compared_too() {
        let row = |speedup: f64, order: f64| {
            let mut row = Row::default();
            row.set("point", json!("n=64 threads=2"));
            row.set("speedup", json!(speedup));
            row.set("order_l2", json!(order));
            row
        };
        let changes = compare_derived(&[row(1.8, 2.0)], &[row(1.2, 1.85)], 0.1);
        let verdict = |m: &str| changes.iter().find(|c| c.metric == m).unwrap().verdict;
        assert_eq!(
            (verdict("speedup"), verdict("order_l2")),
            (Verdict::Worse, Verdict::Worse)
        );
        let changes = compare_derived(&[row(1.8, 2.0)], &[row(1.85, 2.05)], 0.1);
        assert!(changes.iter().all(|c| c.verdict == Verdict::Same));
        // An order of 1.7 that reaches 1.98 came closer to 2.
        let closer = compare_derived(&[row(1.8, 1.7)], &[row(1.8, 1.98)], 0.1);
        assert_eq!(
            closer
                .iter()
                .find(|c| c.metric == "order_l2")
                .unwrap()
                .verdict,
            Verdict::Better
        );
        assert!(
            compare_derived(&[row(1.8, 2.0)], &[], 0.1).is_empty(),
            "a point on one side"
        );
    }

    #[test]
    fn errors_use_tolerances_one_repeat_gives_no_interval_and_one_sided_points_are_listed() {
        let a = [run(1.0, 0.0)];
        let b = [run(1.0, 1e-15)];
        let worse = [run(1.0, 1e-6)];
        let zero = compare(
            &[Paired {
                point: "p".into(),
                a: refs(&a),
                b: refs(&b),
            }],
            0.1,
        );
        let error = zero
            .changes
            .iter()
            .find(|c| c.metric == "error_l2_norm")
            .unwrap();
        assert_eq!(
            error.verdict,
            Verdict::Same,
            "a reference of 0 with the absolute tolerance"
        );
        let solve = zero.changes.iter().find(|c| c.metric == "solve_s").unwrap();
        assert_eq!(solve.verdict, Verdict::NoInterval);
        let changed = compare(
            &[Paired {
                point: "p".into(),
                a: refs(&a),
                b: refs(&worse),
            }],
            0.1,
        );
        assert_eq!(changed.regressions(), 1);
        let one_sided = compare(
            &[
                Paired {
                    point: "p".into(),
                    a: refs(&a),
                    b: vec![],
                },
                Paired {
                    point: "q".into(),
                    a: vec![],
                    b: refs(&b),
                },
            ],
            0.1,
        );
        assert_eq!(
            (one_sided.only_a, one_sided.only_b),
            (vec!["p".to_string()], vec!["q".to_string()])
        );
    }
}
