//! `nlstudy compare`: two result sets of one study, point by point.
//!
//! A measured metric (a timing, a rate, memory) is the ratio B/A of the medians over the repeats,
//! with a bootstrap interval over those repeats. That interval sees only the noise *within* a
//! run; two runs of one build differ by more, in two ways (`NoiseModel`, measured on the 2-core
//! VM this tool is developed on, docs/provenance.md): the whole run moves (the machine's state:
//! its clock, a neighbour's job), and each point moves on its own. So each metric's common
//! factor is estimated from the comparison itself (the median over its points of log B/A) and
//! judged as the run's own row, against the drift of whole runs; each point is judged relative
//! to that factor, against the drift of single points at its timing scale. A change is called
//! only when the bootstrap interval clears the threshold *and* the ratio clears its noise floor
//! (`Z` robust standard deviations of that drift: from the study's own A/A history where it holds
//! enough pairs of runs of one build, else this VM's). A wall time under `RESOLUTION_S` is too
//! short to judge, and a point whose runs were all timed on a busy machine (`noisy`) gets none.
//!
//! Errors are deterministic: they are compared with a relative and an absolute tolerance (a
//! reference of 0 breaks a relative one alone), and observed orders by how far they moved from
//! the nearest whole order. A speedup is a ratio of medians of two points of one run (their
//! common factor cancels): its B/A gets an interval by resampling the repeats of both points on
//! both sides; an efficiency is the speedup over the same worker ratio on both sides, so its B/A
//! is the speedup's and is not repeated.

use crate::console::number;
use crate::statistics::median;
use crate::store::table::Row;
use fastrand::Rng;
use schema::record::Stored;
use serde_json::json;
use std::collections::HashMap;

mod bootstrap;
mod metrics;
mod noise;
pub mod paired;

pub use metrics::{is_order, measured, order_shift, ORDER_TOLERANCE};
pub use noise::NoiseModel;

use bootstrap::*;
use metrics::*;
use noise::*;
use schema::record::columns;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict {
    Better,
    Worse,
    Same,
    /// Too few repeats on a side to form an interval.
    NoInterval,
    /// A wall time under `RESOLUTION_S`.
    TooShort,
    /// Every run of a side was timed on a busy machine.
    Abstained,
}

impl Verdict {
    pub fn text(self) -> &'static str {
        match self {
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::Same => "same",
            Verdict::NoInterval => "no interval (fewer than 2 repeats)",
            Verdict::TooShort => "too short to judge (under 1 ms of wall time)",
            Verdict::Abstained => {
                "no verdict: every run timed on a busy machine (its CPU time, solve_cpu_s, is judged)"
            }
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
    /// The ratio beside its run's common factor: what a measured point's verdict judges.
    pub relative: Option<f64>,
    /// The noise floor the ratio had to clear, as a factor (measured metrics).
    pub floor: Option<f64>,
    pub verdict: Verdict,
}

/// A point's runs on each side: its label and each side's records (one per repeat).
pub struct Paired<'a> {
    pub point: String,
    pub a: Vec<&'a Stored>,
    pub b: Vec<&'a Stored>,
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

/// The label of a metric's row for the run as a whole: its common factor.
pub const WHOLE_RUN: &str = "all points (the run's common factor)";

/// Compares each point's runs, `threshold` being the smallest change in a measured metric that
/// counts (0.1: the interval of B/A must lie above 1.1 or below 1/1.1), beyond the noise floor;
/// a measured metric also gets a row for the whole run (`WHOLE_RUN`) when enough points have it.
pub fn compare(points: &[Paired], threshold: f64, noise: &NoiseModel) -> Comparison {
    let mut comparison = Comparison {
        changes: Vec::new(),
        only_a: Vec::new(),
        only_b: Vec::new(),
    };
    let mut both = Vec::new();
    for paired in points {
        let (a, b) = (measured(&paired.a), measured(&paired.b));
        match (a.is_empty(), b.is_empty()) {
            (true, true) => {}
            (false, true) => comparison.only_a.push(paired.point.clone()),
            (true, false) => comparison.only_b.push(paired.point.clone()),
            (false, false) => both.push((paired.point.as_str(), a, b)),
        }
    }
    for metric in METRICS {
        let (better, kind) = (metric.better, metric.kind);
        let mut sides = Vec::new();
        for (point, a, b) in &both {
            let (xa, xb) = (values(a, metric), values(b, metric));
            if xa.is_empty() || xb.is_empty() {
                continue;
            }
            let scales: Vec<f64> = a.iter().filter_map(|r| scale_of(metric, r)).collect();
            let scale = if scales.is_empty() {
                median(&xa)
            } else {
                median(&scales)
            };
            let all_noisy = |side: &[&Stored]| side.iter().all(|r| r.noisy());
            let scale_b: Vec<f64> = b.iter().filter_map(|r| scale_of(metric, r)).collect();
            let shortest = scale.min(if scale_b.is_empty() {
                scale
            } else {
                median(&scale_b)
            });
            let short = metric.span.is_some() && shortest < RESOLUTION_S;
            let noisy = metric.wall && (all_noisy(a) || all_noisy(b));
            let set_aside = match (short, noisy) {
                _ if kind == Kind::Deterministic => None,
                (true, _) => Some(Verdict::TooShort),
                (_, true) => Some(Verdict::Abstained),
                _ => None,
            };
            sides.push((*point, xa, xb, scale, set_aside));
        }
        // The run's common factor, from the points that can be judged.
        let logs: Vec<f64> = sides
            .iter()
            .filter(|side| side.4.is_none())
            .map(|(_, xa, xb, ..)| (median(xb) / median(xa)).ln())
            .collect();
        let common = (kind == Kind::Measured && logs.len() >= COMMON_POINTS).then(|| median(&logs));
        for (point, xa, xb, scale, set_aside) in &sides {
            let setting = Setting {
                threshold,
                floor: match common {
                    Some(_) => noise.point_floor(metric.name, *scale),
                    None => noise.point_and_run_floor(metric.name, *scale),
                },
                common: common.unwrap_or(0.0).exp(),
                seed: seed_of(point, metric.name),
            };
            let mut change = change(point, metric.name, better, kind, xa, xb, &setting);
            if let Some(verdict) = set_aside {
                change.verdict = *verdict;
            }
            comparison.changes.push(change);
        }
        if let Some(common) = common {
            let mut random = Rng::with_seed(seed_of(WHOLE_RUN, metric.name));
            let interval = bootstrap(&mut random, |r| resampled(r, &logs).exp());
            let setting = Setting {
                threshold,
                floor: noise.run_floor(metric.name),
                common: 1.0,
                seed: 0,
            };
            comparison.changes.push(Change {
                point: WHOLE_RUN.to_string(),
                metric: metric.name,
                a: 1.0,
                b: common.exp(),
                ratio: common.exp(),
                interval: Some(interval),
                relative: None,
                floor: Some(setting.floor),
                verdict: setting.verdict(common.exp(), interval, better),
            });
        }
    }
    comparison
}

/// The median of `values` and its percentile bootstrap interval (as a comparison's), seeded by
/// `label` so that it is the same every time.
pub fn median_interval(label: &str, values: &[f64]) -> (f64, (f64, f64)) {
    let mut random = Rng::with_seed(seed_of(label, "median"));
    (
        median(values),
        bootstrap(&mut random, |r| resampled(r, values)),
    )
}

/// What a measured verdict is judged against.
struct Setting {
    threshold: f64,
    /// The noise floor, a factor ≥ 1.
    floor: f64,
    /// The run's common factor, which a point's ratio is judged beside (1 for none).
    common: f64,
    seed: u64,
}

impl Setting {
    /// The verdict on a ratio whose interval is (low, high), each taken beside the run's.
    fn verdict(&self, ratio: f64, (low, high): (f64, f64), better: Better) -> Verdict {
        let (ratio, low, high) = (ratio / self.common, low / self.common, high / self.common);
        let beyond = |r: f64| r.ln().abs() > self.floor.ln();
        let up = low > 1.0 + self.threshold && beyond(ratio);
        let down = high < 1.0 / (1.0 + self.threshold) && beyond(ratio);
        match (up, down, better) {
            (true, _, Better::Lower) | (_, true, Better::Higher) => Verdict::Worse,
            (true, _, Better::Higher) | (_, true, Better::Lower) => Verdict::Better,
            _ => Verdict::Same,
        }
    }
}

fn change(
    point: &str,
    metric: &'static str,
    better: Better,
    kind: Kind,
    a: &[f64],
    b: &[f64],
    setting: &Setting,
) -> Change {
    let (ma, mb) = (median(a), median(b));
    let ratio = mb / ma;
    let (interval, floor, verdict) = match kind {
        Kind::Deterministic => {
            let differs = (mb - ma).abs() > ABSOLUTE + RELATIVE * ma.abs();
            let verdict = match (differs, mb < ma) {
                (false, _) => Verdict::Same,
                (true, lower) if lower == (better == Better::Lower) => Verdict::Better,
                (true, _) => Verdict::Worse,
            };
            (None, None, verdict)
        }
        Kind::Measured if a.len() < 2 || b.len() < 2 => {
            (None, Some(setting.floor), Verdict::NoInterval)
        }
        Kind::Measured => {
            let mut random = Rng::with_seed(setting.seed);
            let interval = bootstrap(&mut random, |r| resampled(r, b) / resampled(r, a));
            let verdict = setting.verdict(ratio, interval, better);
            (Some(interval), Some(setting.floor), verdict)
        }
    };
    Change {
        point: point.to_string(),
        metric,
        a: ma,
        b: mb,
        ratio,
        interval,
        relative: (kind == Kind::Measured).then_some(ratio / setting.common),
        floor,
        verdict,
    }
}

/// The observed orders of each point on both sides (`ORDERS`), by the `point` label of the
/// summaries.
pub fn compare_orders(a: &[Row], b: &[Row]) -> Vec<Change> {
    let mut changes = Vec::new();
    let b_by_point: HashMap<&str, &Row> = b
        .iter()
        .rev() // the first row of a point wins, as a search from the front would find it
        .filter_map(|r| Some((r.text("point")?, r)))
        .collect();
    for row_a in a {
        let Some(point) = row_a.text("point") else {
            continue;
        };
        let Some(row_b) = b_by_point.get(point) else {
            continue;
        };
        for &metric in ORDERS {
            let (Some(xa), Some(xb)) = (row_a.number(metric), row_b.number(metric)) else {
                continue;
            };
            if !(xa.is_finite() && xb.is_finite()) {
                continue;
            }
            let verdict = match order_shift(xa, xb) {
                m if m > ORDER_TOLERANCE => Verdict::Worse,
                m if m < -ORDER_TOLERANCE => Verdict::Better,
                _ => Verdict::Same,
            };
            changes.push(Change {
                point: point.to_string(),
                metric,
                a: xa,
                b: xb,
                ratio: xb / xa,
                interval: None,
                relative: None,
                floor: None,
                verdict,
            });
        }
    }
    changes
}

/// The speedup of each point over its scaling series' baseline (`baselines`: point label →
/// the label of the point it is measured against) on both sides: B/A of t₀/t with an interval
/// from resampling the repeats of both points on both sides, judged as a timing at the scale of
/// the shorter of the two.
pub fn compare_speedups(
    points: &[Paired],
    baselines: &[(String, String)],
    threshold: f64,
    noise: &NoiseModel,
) -> Vec<Change> {
    let by_label: HashMap<&str, &Paired> = points.iter().map(|p| (p.point.as_str(), p)).collect();
    let times = |runs: &[&Stored]| values(&measured(runs), metric(columns::SOLVE_S));
    let mut changes = Vec::new();
    for (point, base) in baselines {
        let (Some(p), Some(q)) = (by_label.get(point.as_str()), by_label.get(base.as_str())) else {
            continue;
        };
        let [ta, tb, ba, bb] = [times(&p.a), times(&p.b), times(&q.a), times(&q.b)];
        if [&ta, &tb, &ba, &bb].iter().any(|t| t.is_empty()) {
            continue;
        }
        let speedup = |base: &[f64], time: &[f64]| median(base) / median(time);
        let (sa, sb) = (speedup(&ba, &ta), speedup(&bb, &tb));
        let shortest = median(&ta).min(median(&ba));
        // Both points ran in one run, whose common factor cancels in their ratio; each drifts.
        let setting = Setting {
            threshold,
            floor: noise.pair_floor(columns::SOLVE_S, median(&ta), median(&ba)),
            common: 1.0,
            seed: seed_of(point, "speedup"),
        };
        let all_noisy = [&p.a, &p.b, &q.a, &q.b]
            .iter()
            .any(|side| side.iter().all(|r| r.noisy()));
        let (interval, verdict) = if [&ta, &tb, &ba, &bb].iter().any(|t| t.len() < 2) {
            (None, Verdict::NoInterval)
        } else {
            let mut random = Rng::with_seed(setting.seed);
            let interval = bootstrap(&mut random, |r| {
                (resampled(r, &bb) / resampled(r, &tb)) / (resampled(r, &ba) / resampled(r, &ta))
            });
            let verdict = match (shortest < RESOLUTION_S, all_noisy) {
                (true, _) => Verdict::TooShort,
                (_, true) => Verdict::Abstained,
                _ => setting.verdict(sb / sa, interval, Better::Higher),
            };
            (Some(interval), verdict)
        };
        changes.push(Change {
            point: point.clone(),
            metric: "speedup",
            a: sa,
            b: sb,
            ratio: sb / sa,
            interval,
            relative: None,
            floor: Some(setting.floor),
            verdict,
        });
    }
    changes
}

/// The machines the measured records of a side ran on: their CPU models, instruction sets and
/// cores online.
pub fn machines(records: &[&Stored]) -> Vec<String> {
    let mut machines: Vec<String> = measured(records)
        .iter()
        .filter_map(|r| r.provenance())
        .map(|p| {
            let known = |text: &str| match text {
                "" => "unknown".to_string(),
                text => text.to_string(),
            };
            let cores = match p.cores_online {
                0 => "unknown".to_string(),
                n => n.to_string(),
            };
            format!(
                "{} ({}, {cores} cores)",
                known(&p.cpu),
                known(&p.instruction_set)
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
        Verdict::NoInterval | Verdict::TooShort | Verdict::Abstained => 2,
        Verdict::Same => 3,
    });
    let mut text = String::from(
        "| point | metric | A | B | B/A | 95 % interval | beside the run | noise floor | verdict |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for c in changes {
        let interval = c.interval.map_or(String::new(), |(lo, hi)| {
            format!("[{}, {}]", number(lo), number(hi))
        });
        let floor = c.floor.map_or(String::new(), |f| format!("×{}", number(f)));
        let relative = c.relative.map_or(String::new(), number);
        text.push_str(&format!(
            "| {} | {} | {} | {} | {} | {interval} | {relative} | {floor} | {} |\n",
            crate::analysis::pivot::cell(&c.point),
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
            row.set("relative", json!(c.relative));
            row.set("floor", json!(c.floor));
            row.set("verdict", json!(c.verdict.text()));
            row
        })
        .collect()
}

/// Pairs each point's repeats (their keys) with the records each side holds for them.
pub fn pair<'a>(
    points: &[(String, Vec<String>)],
    a: &'a HashMap<String, Stored>,
    b: &'a HashMap<String, Stored>,
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
mod tests;
