//! The comparison of two result sets as a figure: a panel per metric that got a verdict, B/A at
//! each point (numbered, the numbers named under the legend), coloured and shaped by verdict,
//! with the bootstrap interval as a dashed bar and the threshold's band. Its "worse" marks are
//! the regressions the exit status counts, one for one.

use crate::analysis::compare::{Change, Comparison, Verdict};
use crate::output::draw::{Axis, Chart, Guide, Panel, Series};

/// The verdicts in a fixed order, so that one verdict has one colour and marker in every panel.
const VERDICTS: [Verdict; 6] = [
    Verdict::Worse,
    Verdict::Better,
    Verdict::Same,
    Verdict::NoInterval,
    Verdict::TooShort,
    Verdict::Abstained,
];

pub fn chart(comparison: &Comparison, title: &str, threshold: f64) -> Chart {
    let mut points: Vec<&str> = Vec::new();
    let mut metrics: Vec<&str> = Vec::new();
    for change in comparison
        .changes
        .iter()
        .filter(|c| c.ratio.is_finite() && c.ratio > 0.0)
    {
        if !points.contains(&change.point.as_str()) {
            points.push(&change.point);
        }
        if !metrics.contains(&change.metric) {
            metrics.push(change.metric);
        }
    }
    let at = |change: &Change| {
        let k = points.iter().position(|p| *p == change.point).unwrap_or(0);
        (k + 1) as f64
    };
    let last = points.len().max(1) as f64;
    let panels = metrics
        .iter()
        .map(|&metric| {
            let changes: Vec<&Change> = comparison
                .changes
                .iter()
                .filter(|c| c.metric == metric && c.ratio.is_finite() && c.ratio > 0.0)
                .collect();
            let series = VERDICTS
                .iter()
                .map(|verdict| Series {
                    points: changes
                        .iter()
                        .filter(|c| c.verdict == *verdict)
                        .map(|c| (at(c), c.ratio))
                        .collect(),
                    line: false,
                    ..Series::line(verdict.text(), Vec::new())
                })
                .collect();
            let mut guides: Vec<Guide> = changes
                .iter()
                .filter_map(|c| {
                    let (low, high) = c.interval?;
                    Some(Guide::Dashed {
                        label: None,
                        of: VERDICTS.iter().position(|v| *v == c.verdict),
                        points: vec![(at(c), low), (at(c), high)],
                    })
                })
                .collect();
            let band = format!("threshold ±{}", crate::console::number(threshold));
            for (bound, label) in [
                (1.0 + threshold, Some(band)),
                (1.0 / (1.0 + threshold), None),
            ] {
                guides.push(Guide::Dashed {
                    label,
                    of: None,
                    points: vec![(0.5, bound), (last + 0.5, bound)],
                });
            }
            Panel {
                title: metric.to_string(),
                x: Axis {
                    include: vec![0.5, last + 0.5],
                    ..Axis::linear("point (named below)").counting()
                },
                y: Axis {
                    log: true,
                    include: vec![1.0],
                    ..Axis::linear("B / A")
                },
                series,
                guides,
                heat: None,
            }
        })
        .collect();
    let mut chart = Chart::new(
        title,
        "B/A of the medians over the repeats, with 95 % bootstrap intervals; a change is called beyond the threshold and the noise floor of run-to-run drift (the table lists each floor)",
        panels,
    );
    chart.key = points
        .iter()
        .enumerate()
        .map(|(k, p)| format!("{}: {p}", k + 1))
        .collect();
    chart
}

#[cfg(test)]
mod tests {
    use super::*;

    fn change(point: &str, metric: &'static str, ratio: f64, verdict: Verdict) -> Change {
        Change {
            point: point.into(),
            metric,
            a: 1.0,
            b: ratio,
            ratio,
            interval: Some((0.9 * ratio, 1.1 * ratio)),
            relative: Some(ratio),
            floor: Some(1.5),
            verdict,
        }
    }

    /// Every verdict the exit status counts is a mark of the figure, every metric with a verdict
    /// has its panel, the points are named, and the legend lists only what is drawn.
    #[test]
    fn the_figure_shows_every_verdict_the_exit_status_counts() {
        let comparison = Comparison {
            changes: vec![
                change("n=16", "solve_s", 2.0, Verdict::Worse),
                change("n=32", "solve_s", 1.0, Verdict::Same),
                change("n=32 threads=2", "speedup", 0.4, Verdict::Worse),
                change("n=16", "error_l2_norm", 1.0, Verdict::Same),
            ],
            only_a: vec![],
            only_b: vec![],
        };
        let chart = chart(&comparison, "t", 0.1);
        assert!(crate::output::draw::lint(&chart).is_empty());
        let titles: Vec<&str> = chart.panels.iter().map(|p| p.title.as_str()).collect();
        assert_eq!(titles, ["solve_s", "speedup", "error_l2_norm"]);
        let worse: usize = chart
            .panels
            .iter()
            .flat_map(|p| &p.series)
            .filter(|s| s.label == Verdict::Worse.text())
            .map(|s| s.points.len())
            .sum();
        assert_eq!(worse, comparison.regressions());
        assert_eq!(chart.key, ["1: n=16", "2: n=32", "3: n=32 threads=2"]);
        let svg = crate::output::draw::render(&chart).unwrap();
        for drawn in ["worse", "same", "threshold ±0.1", "3: n=32 threads=2"] {
            assert!(svg.contains(drawn), "{drawn}");
        }
        for absent in ["no interval", "too short", "every run noisy"] {
            assert!(
                !svg.contains(absent),
                "{absent} is in the legend but not drawn"
            );
        }
    }
}
