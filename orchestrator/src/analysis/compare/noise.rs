//! The run-to-run drift a change must clear: of a whole run and of each point beside it,
//! from the study's A/A history where it holds enough pairs, else this VM's (`NoiseModel`).

use super::metrics::*;
use crate::statistics::median;
use crate::store::fingerprint_of;
use schema::record::Stored;
use std::collections::{BTreeMap, HashMap};

/// How many robust standard deviations of the drift a change must exceed. The drift is
/// heavy-tailed (a neighbour's job on a shared host): on this VM's A/A pairs the largest was 4.6
/// σ; 5 keeps the false-positive rate of A/A comparisons at zero (docs/provenance.md).
pub(super) const Z: f64 = 5.0;

/// How much one point's log(B/A) of medians moves between two runs of one build on this VM, once
/// the run's common factor is taken out: the robust σ (1.4826 · median |d|) by decade of seconds
/// of A's median (`studies/noise.json`, 24 points × 3 repeats, run eleven times with `--force`:
/// 10 pairs of runs, 720 point pairs).
pub(super) const DEFAULT_WITHIN: &[(i32, f64)] = &[
    (-5, 0.16),
    (-4, 0.17),
    (-3, 0.16),
    (-2, 0.14),
    (-1, 0.13),
    (0, 0.10),
];

/// How much a whole run's common factor moves between two runs of one build on this VM: the
/// robust σ of the medians over points of log(B/A) (the same 10 pairs of runs, 3 timings each).
pub(super) const DEFAULT_BETWEEN: f64 = 0.05;

/// The fewest points whose median is a run's common factor; with fewer, each point carries the
/// run's drift as well as its own.
pub(super) const COMMON_POINTS: usize = 5;

/// Single-run pairs a decade needs before the study's history replaces the default drift of
/// points there, and pairs of runs (`run_id`) before it replaces the drift of whole runs.
pub(super) const CALIBRATION_SAMPLES: usize = 10;

pub(super) const CALIBRATION_RUNS: usize = 10;

/// Memory is not timed: its drift is the allocator's and the page cache's, a few per cent.
pub(super) const MEMORY_DRIFT: f64 = 0.03;

/// The run-to-run drift of measured metrics in two parts: of a whole run (its common factor)
/// and of each point beside it, as robust standard deviations of log ratios between two runs of
/// one build; from the study's history where it holds enough A/A pairs, else this VM's.
pub struct NoiseModel {
    /// Point drift by metric and decade of its value, with the single-run pairs it came from.
    within: BTreeMap<(String, i32), (f64, usize)>,
    /// Whole-run drift by metric, with the pairs of runs it came from.
    between: BTreeMap<String, (f64, usize)>,
    /// What the history held, whether or not enough to measure from: point pairs (of the metric
    /// with the most), and pairs of runs (of `COMMON_POINTS` points or more).
    found: (usize, usize),
}

impl NoiseModel {
    /// The default drift everywhere.
    #[cfg(test)]
    pub fn uncalibrated() -> NoiseModel {
        NoiseModel {
            within: BTreeMap::new(),
            between: BTreeMap::new(),
            found: (0, 0),
        }
    }

    /// The drift measured from `records` (a study's superseded and stored records, those being
    /// judged left out): consecutive runs of one key by one build are A/A pairs. The pairs of two
    /// `nlstudy` processes (`run_id`s) share those processes' machine state: their median is a
    /// sample of the whole-run drift, and the pairs' distances from it of the point drift.
    pub fn calibrate(records: &[&Stored]) -> NoiseModel {
        let mut by_key: HashMap<&str, Vec<&Stored>> = HashMap::new();
        for record in measured(records) {
            by_key.entry(&record.key).or_default().push(record);
        }
        // log(new/old) and the decade of old, by metric and pair of runs.
        type Pairs = Vec<(f64, i32)>;
        let mut by_runs: BTreeMap<(&'static str, String), Pairs> = BTreeMap::new();
        for runs in by_key.values_mut() {
            runs.retain(|r| crate::store::timestamp::record_time(r).is_some());
            runs.sort_by(|a, b| {
                let time = |r: &Stored| crate::store::timestamp::record_time(r).unwrap_or(0.0);
                time(a).total_cmp(&time(b))
            });
            for pair in runs.windows(2) {
                let build = fingerprint_of(pair[0]);
                let (Some(old_run), Some(new_run)) = (&pair[0].run_id, &pair[1].run_id) else {
                    continue;
                };
                if build.is_empty() || build != fingerprint_of(pair[1]) || old_run == new_run {
                    continue;
                }
                for metric in METRICS.iter().filter(|m| m.kind == Kind::Measured) {
                    let (old, new) = (values(&pair[..1], metric), values(&pair[1..], metric));
                    if let ([old], [new]) = (old.as_slice(), new.as_slice()) {
                        let scale = decade(scale_of(metric, pair[0]).unwrap_or(*old));
                        let runs = format!("{old_run} {new_run}");
                        by_runs
                            .entry((metric.name, runs))
                            .or_default()
                            .push(((new / old).ln(), scale));
                    }
                }
            }
        }
        let mut within: BTreeMap<(String, i32), Vec<f64>> = BTreeMap::new();
        let mut between: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        // Point pairs by metric, and the pairs of runs they came from.
        let mut found: (BTreeMap<&str, usize>, std::collections::BTreeSet<String>) =
            Default::default();
        // A pair of runs of fewer points has no common factor to speak of (the distances of a
        // single point from its own median are 0): it calibrates nothing.
        for ((metric, runs), pairs) in by_runs
            .into_iter()
            .filter(|(_, p)| p.len() >= COMMON_POINTS)
        {
            *found.0.entry(metric).or_default() += pairs.len();
            found.1.insert(runs.clone());
            let logs: Vec<f64> = pairs.iter().map(|p| p.0).collect();
            let common = median(&logs);
            between
                .entry(metric.to_string())
                .or_default()
                .push(common.abs());
            for (log, scale) in pairs {
                let at = (metric.to_string(), scale);
                within.entry(at).or_default().push((log - common).abs());
            }
        }
        NoiseModel {
            within: robust(within, CALIBRATION_SAMPLES),
            between: robust(between, CALIBRATION_RUNS),
            found: (found.0.into_values().max().unwrap_or(0), found.1.len()),
        }
    }

    /// The σ of a point's drift beside its run's (`metric` at the scale `scale`: seconds, or
    /// bytes for memory).
    pub(super) fn within(&self, metric: &str, scale: f64) -> f64 {
        if metric == "peak_memory_bytes" {
            return MEMORY_DRIFT;
        }
        let decade = decade(scale);
        if let Some(&(sigma, _)) = self.within.get(&(metric.to_string(), decade)) {
            return sigma;
        }
        let (_, sigma) = DEFAULT_WITHIN
            .iter()
            .min_by_key(|(d, _)| (d - decade).abs())
            .expect("a default drift");
        *sigma
    }

    /// The σ of a whole run's drift.
    pub(super) fn between(&self, metric: &str) -> f64 {
        match metric {
            "peak_memory_bytes" => MEMORY_DRIFT,
            _ => self.between.get(metric).map_or(DEFAULT_BETWEEN, |d| d.0),
        }
    }

    /// The factor a point's ratio, relative to its run's, must clear.
    pub fn point_floor(&self, metric: &str, scale: f64) -> f64 {
        (Z * self.within(metric, scale)).exp()
    }

    /// The factor a ratio of two points of one run (a speedup) must clear: both points drift.
    pub fn pair_floor(&self, metric: &str, scale: f64, other: f64) -> f64 {
        (Z * self.within(metric, scale).hypot(self.within(metric, other))).exp()
    }

    /// The factor a point's ratio must clear when its run's factor is not known (too few points):
    /// both drifts at once.
    pub(super) fn point_and_run_floor(&self, metric: &str, scale: f64) -> f64 {
        (Z * self.within(metric, scale).hypot(self.between(metric))).exp()
    }

    /// The factor a whole run's common factor must clear.
    pub fn run_floor(&self, metric: &str) -> f64 {
        (Z * self.between(metric)).exp()
    }

    /// Where the floors came from, in words a user can act on: what the study's history held,
    /// what was measured from it, and what more would measure the rest.
    pub fn describe(&self) -> String {
        let (point_pairs, run_pairs) = self.found;
        if run_pairs == 0 {
            return format!(
                "noise floors: this machine's default drift (the study's history holds no two runs of one build of {COMMON_POINTS} points or more to measure it from: `nlstudy run --force` makes them; `compare --against solver:PATH` pairs interleaved runs instead)"
            );
        }
        let scales = self.within.len();
        let points = match scales {
            0 => format!(
                "point drift: the default (its {point_pairs} point pairs fill no timing scale to the {CALIBRATION_SAMPLES} pairs each needs)"
            ),
            _ => format!(
                "point drift measured at {scales} metric scales from {point_pairs} point pairs, the default at others"
            ),
        };
        let runs = match self.between.values().map(|(_, k)| *k).max() {
            Some(measured) => format!("whole-run drift measured from {measured} pairs of runs"),
            None => format!(
                "whole-run drift: the default ({run_pairs} pairs of runs of the {CALIBRATION_RUNS} it needs: `nlstudy run --force` {} more times)",
                CALIBRATION_RUNS - run_pairs.min(CALIBRATION_RUNS)
            ),
        };
        format!("noise floors from the study's history of {run_pairs} pairs of runs of one build: {points}; {runs}")
    }
}

/// 1.4826 · median of absolute deviations from a centre: a robust σ, for the groups with at
/// least `fewest` samples.
pub(super) fn robust<K: Ord>(
    groups: BTreeMap<K, Vec<f64>>,
    fewest: usize,
) -> BTreeMap<K, (f64, usize)> {
    groups
        .into_iter()
        .filter(|(_, d)| d.len() >= fewest)
        .map(|(at, d)| (at, (1.4826 * median(&d), d.len())))
        .collect()
}

/// The decade of a positive scale (0 for one that is not: it has no decade to look up).
pub(super) fn decade(x: f64) -> i32 {
    match x > 0.0 && x.is_finite() {
        true => x.log10().floor() as i32,
        false => 0,
    }
}
