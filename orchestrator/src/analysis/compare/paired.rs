//! The verdicts of interleaved reruns (`run::interleave`): each point's runs by the two builds
//! are paired round by round (A and B ran one after the other), and a timing is judged by the
//! ratios B/A of its pairs: their median, with a bootstrap interval over the pairs. A drift of
//! the machine slower than a pair (a neighbour's job, the clock) moves both runs of a pair and
//! cancels in its ratio, so no noise floor from another run's history is needed: the pairs'
//! spread is their noise. The run's common factor is judged too (the median over points of their
//! log ratios, an interval over points). Errors are compared as `compare` compares them; the
//! instruction counts of cachegrind, which repeat to well under 0.1 %, by `INSTRUCTIONS`.

use super::bootstrap::{bootstrap, resampled, seed_of};
use super::metrics::{metric, Kind, RESOLUTION_S};
use super::{change, Change, Comparison, Setting, Verdict, WHOLE_RUN};
use crate::statistics::median;
use fastrand::Rng;
use schema::record::{columns, Stored};

/// A point's runs by build A and build B, each round's pair at one index (`None` where a round
/// lacks a side's result), and its instruction counts by each (when counted).
pub struct Rounds {
    pub point: String,
    pub pairs: Vec<(Option<Stored>, Option<Stored>)>,
    pub counted: Option<(Stored, Stored)>,
}

/// The timings judged by their pairs: the wall time of the solve and its CPU time.
const PAIRED: [&str; 2] = [columns::SOLVE_S, columns::SOLVE_CPU_S];

/// The change of an instruction count that counts: 0.5 %. Counts of one build repeat within
/// 0.1 % (docs/performance.md); a 2 % change of work is called.
pub const INSTRUCTIONS: f64 = 0.005;

/// The verdicts on `points`' pairs, a timing's change counting from `threshold` (0.1: the
/// interval of B/A above 1.1 or below 1/1.1).
///
/// Long because each kind of verdict (the paired timings, the bit-for-bit errors, the instruction
/// counts) is a loop over the same points and their pairs, filling one comparison.
pub fn judge(points: &[Rounds], threshold: f64) -> Comparison {
    let mut comparison = Comparison {
        changes: Vec::new(),
        only_a: Vec::new(),
        only_b: Vec::new(),
    };
    for name in PAIRED {
        let metric = metric(name);
        let mut logs = Vec::new();
        for point in points {
            let pairs: Vec<(f64, f64)> = point
                .pairs
                .iter()
                .filter_map(|(a, b)| {
                    let read = |s: &Option<Stored>| (metric.read)(s.as_ref()?.record()?);
                    Some((read(a)?, read(b)?))
                })
                .filter(|(a, b)| a.is_finite() && b.is_finite() && *a > 0.0 && *b > 0.0)
                .collect();
            if pairs.is_empty() {
                continue;
            }
            let ratios: Vec<f64> = pairs.iter().map(|(a, b)| b / a).collect();
            let (a, b): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
            let mut judged = Change {
                point: point.point.clone(),
                metric: metric.name,
                a: median(&a),
                b: median(&b),
                ratio: median(&ratios),
                interval: None,
                relative: None,
                floor: None,
                verdict: Verdict::NoInterval,
            };
            let wall: Vec<f64> = (point.pairs.iter())
                .filter_map(|(a, b)| {
                    Some(
                        a.as_ref()?
                            .record()?
                            .solve_s
                            .min(b.as_ref()?.record()?.solve_s),
                    )
                })
                .collect();
            if median(&wall) < RESOLUTION_S {
                judged.verdict = Verdict::TooShort;
            } else if ratios.len() >= 2 {
                let mut random = Rng::with_seed(seed_of(&point.point, metric.name));
                let interval = bootstrap(&mut random, |r| resampled(r, &ratios));
                judged.interval = Some(interval);
                judged.verdict = setting(threshold).verdict(judged.ratio, interval, metric.better);
                logs.push(judged.ratio.ln());
            }
            comparison.changes.push(judged);
        }
        if logs.len() >= 2 {
            let mut random = Rng::with_seed(seed_of(WHOLE_RUN, metric.name));
            let interval = bootstrap(&mut random, |r| resampled(r, &logs).exp());
            let common = median(&logs).exp();
            comparison.changes.push(Change {
                point: WHOLE_RUN.to_string(),
                metric: metric.name,
                a: 1.0,
                b: common,
                ratio: common,
                interval: Some(interval),
                relative: None,
                floor: None,
                verdict: setting(threshold).verdict(common, interval, metric.better),
            });
        }
    }
    for name in [columns::ERROR_L2_NORM, columns::ERROR_MAX] {
        let metric = metric(name);
        for point in points {
            let first = point.pairs.iter().find_map(|(a, b)| {
                let read = |s: &Option<Stored>| (metric.read)(s.as_ref()?.record()?);
                Some((read(a)?, read(b)?))
            });
            if let Some((a, b)) = first {
                let setting = setting(threshold);
                let judged = change(
                    &point.point,
                    metric.name,
                    metric.better,
                    Kind::Deterministic,
                    &[a],
                    &[b],
                    &setting,
                );
                comparison.changes.push(judged);
            }
        }
    }
    for point in points {
        if let Some(counted) = instructions(point) {
            comparison.changes.push(counted);
        }
    }
    comparison
}

/// Whether `change`, a point's CPU time, is undecided at `threshold`: its interval holds one
/// of the edges 1 + threshold and 1/(1 + threshold), so more pairs could still call it changed
/// or the same. (Its wall time is not asked: on a busy machine more rounds rarely settle it.)
pub fn undecided(change: &Change, threshold: f64) -> bool {
    let Some((low, high)) = change.interval else {
        return false;
    };
    let holds = |edge: f64| low <= edge && edge <= high;
    change.metric == columns::SOLVE_CPU_S
        && change.point != WHOLE_RUN
        && (holds(1.0 + threshold) || holds(1.0 / (1.0 + threshold)))
}

/// A timing's setting: its threshold, no floor (the pairs' spread is their noise), judged as it
/// is (no common factor taken out).
fn setting(threshold: f64) -> Setting {
    Setting {
        threshold,
        floor: 1.0,
        common: 1.0,
        seed: 0,
    }
}

/// The change of a point's instruction count, B/A, when both builds counted it.
fn instructions(point: &Rounds) -> Option<Change> {
    let (a, b) = point.counted.as_ref()?;
    let count = |s: &Stored| Some(s.record()?.instructions? as f64);
    let (a, b) = (count(a)?, count(b)?);
    let ratio = b / a;
    let verdict = match ratio {
        r if r > 1.0 + INSTRUCTIONS => Verdict::Worse,
        r if r < 1.0 / (1.0 + INSTRUCTIONS) => Verdict::Better,
        _ => Verdict::Same,
    };
    Some(Change {
        point: point.point.clone(),
        metric: columns::INSTRUCTIONS,
        a,
        b,
        ratio,
        interval: None,
        relative: None,
        floor: Some(1.0 + INSTRUCTIONS),
        verdict,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record;
    use serde_json::json;

    fn run(solve_s: f64, cpu: f64) -> Stored {
        record(json!({"solve_s": solve_s, "solve_cpu_s": cpu, "error_l2_norm": 1e-3}))
    }

    /// Pairs whose ratio holds at 1.25 through a drift of the machine that moves every pair by
    /// up to 2× are called worse, and pairs of one build are the same, however they drift.
    #[test]
    fn a_slowdown_is_called_through_a_drift_that_moves_both_sides() {
        let drift = [1.0, 1.9, 0.7, 1.4, 1.1, 2.0, 0.8];
        let slower: Vec<(Stored, Stored)> = (drift.iter())
            .map(|d| (run(0.1 * d, 0.1), run(0.125 * d, 0.125)))
            .collect();
        let same: Vec<(Stored, Stored)> = (drift.iter().enumerate())
            .map(|(k, d)| {
                (
                    run(0.1 * d, 0.1),
                    run(0.1 * d * (1.0 + 0.01 * k as f64), 0.1),
                )
            })
            .collect();
        let rounds = |pairs: &[(Stored, Stored)], name: &str| Rounds {
            point: name.to_string(),
            pairs: (pairs.iter())
                .map(|(a, b)| (Some(a.clone()), Some(b.clone())))
                .collect(),
            counted: None,
        };
        for (point, expected) in [
            (rounds(&slower, "slower"), Verdict::Worse),
            (rounds(&same, "same"), Verdict::Same),
        ] {
            let points = [point];
            let judged = judge(&points, 0.1);
            for name in PAIRED {
                let change = judged
                    .changes
                    .iter()
                    .find(|c| c.metric == name && c.point != WHOLE_RUN)
                    .unwrap();
                assert_eq!(change.verdict, expected, "{name}: {}", change.ratio);
            }
        }
    }

    /// A CPU time is undecided while its interval holds an edge of the threshold band, decided
    /// once it lies inside the band or beyond an edge; wall time and the common factor never
    /// ask for more rounds.
    #[test]
    fn a_cpu_time_is_undecided_while_its_interval_holds_an_edge() {
        let change = |metric, point: &str, interval| Change {
            point: point.into(),
            metric,
            a: 1.0,
            b: 1.0,
            ratio: 1.0,
            interval,
            relative: None,
            floor: None,
            verdict: Verdict::Same,
        };
        let cpu = |interval| change(columns::SOLVE_CPU_S, "p", Some(interval));
        assert!(undecided(&cpu((1.03, 1.26)), 0.1));
        assert!(undecided(&cpu((0.85, 1.02)), 0.1));
        assert!(!undecided(&cpu((1.15, 1.32)), 0.1));
        assert!(!undecided(&cpu((0.95, 1.05)), 0.1));
        assert!(!undecided(&cpu((0.7, 0.85)), 0.1));
        assert!(!undecided(
            &change(columns::SOLVE_S, "p", Some((1.03, 1.26))),
            0.1
        ));
        assert!(!undecided(
            &change(columns::SOLVE_CPU_S, WHOLE_RUN, Some((1.03, 1.26))),
            0.1
        ));
        assert!(!undecided(&change(columns::SOLVE_CPU_S, "p", None), 0.1));
    }

    #[test]
    fn an_instruction_count_is_judged_to_half_a_percent() {
        let counted = |n: u64| record(json!({"instructions": n, "instructions_by": "cachegrind"}));
        let (a, same, worse) = (counted(1_000_000), counted(1_004_000), counted(1_020_000));
        for (b, expected) in [(&same, Verdict::Same), (&worse, Verdict::Worse)] {
            let point = Rounds {
                point: "p".into(),
                pairs: Vec::new(),
                counted: Some((a.clone(), b.clone())),
            };
            assert_eq!(instructions(&point).unwrap().verdict, expected);
        }
    }
}
