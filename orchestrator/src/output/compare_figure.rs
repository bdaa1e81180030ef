//! The comparison of two result sets as a figure: a panel per metric that got a verdict, B/A at
//! each point (numbered, the numbers named under the legend), coloured and shaped by verdict,
//! with the bootstrap interval as a dashed bar and the threshold's band. An observed order is
//! drawn as what its verdict judges, how much farther B lies from the whole order than A, in a
//! band of the order tolerance. A change no axis can hold (B/A zero, negative or not finite)
//! is listed under the legend with its verdict. Its "worse" marks and listed "worse" changes
//! are the regressions the exit status counts, one for one.

use crate::analysis::compare::{
    is_order, order_shift, Change, Comparison, Verdict, ORDER_TOLERANCE,
};
use crate::console::number;
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

/// Where a change sits on its metric's panel: an order's shift, or a ratio the log axis holds.
fn height(change: &Change) -> Option<f64> {
    let y = match is_order(change.metric) {
        true => order_shift(change.a, change.b),
        false => change.ratio,
    };
    (y.is_finite() && (is_order(change.metric) || y > 0.0)).then_some(y)
}

/// Long because its panel, its verdicts' glyphs and the notes on what is not drawn are declared
/// side by side as the figure shows them.
pub fn chart(comparison: &Comparison, title: &str, threshold: f64) -> Chart {
    let (drawn, undrawn): (Vec<&Change>, Vec<&Change>) =
        comparison.changes.iter().partition(|c| height(c).is_some());
    let mut points: Vec<&str> = Vec::new();
    let mut metrics: Vec<&str> = Vec::new();
    for change in &drawn {
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
            let changes: Vec<&Change> = drawn
                .iter()
                .copied()
                .filter(|c| c.metric == metric)
                .collect();
            let series = VERDICTS
                .iter()
                .map(|verdict| Series {
                    points: changes
                        .iter()
                        .filter(|c| c.verdict == *verdict)
                        .filter_map(|c| Some((at(c), height(c)?)))
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
            let (band, bounds, y) = match is_order(metric) {
                true => (
                    format!("tolerance ±{}", number(ORDER_TOLERANCE)),
                    [ORDER_TOLERANCE, -ORDER_TOLERANCE],
                    Axis {
                        include: vec![0.0],
                        ..Axis::linear("B's distance from the whole order − A's")
                    },
                ),
                false => (
                    format!("threshold ±{}", number(threshold)),
                    [1.0 + threshold, 1.0 / (1.0 + threshold)],
                    Axis {
                        log: true,
                        include: vec![1.0],
                        ..Axis::linear("B / A")
                    },
                ),
            };
            for (bound, label) in bounds.into_iter().zip([Some(band), None]) {
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
                y,
                series,
                guides,
                heat: None,
            }
        })
        .collect();
    let mut chart = Chart::new(
        title,
        "B/A of the medians over the repeats, with 95 % bootstrap intervals; a change is called beyond the threshold and the noise floor of run-to-run drift (the table lists each floor); an observed order is drawn as how much farther from the whole order B lies than A",
        panels,
    );
    chart.key = points
        .iter()
        .enumerate()
        .map(|(k, p)| format!("{}: {p}", k + 1))
        .chain(undrawn.iter().map(|c| {
            format!(
                "{}, {}: {} → {}, {} (not drawn: B/A is no positive number)",
                c.point,
                c.metric,
                number(c.a),
                number(c.b),
                c.verdict.text()
            )
        }))
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
                // An exact A (error 0) that B lost: a regression with no ratio to draw.
                Change {
                    a: 0.0,
                    b: 1e-3,
                    ratio: f64::INFINITY,
                    ..change("n=64", "error_max", 1.0, Verdict::Worse)
                },
                // An order that fell from 2.0 to 1.5: 0.5 farther from 2, whatever its ratio.
                Change {
                    a: 2.0,
                    b: 1.5,
                    ratio: 0.75,
                    interval: None,
                    ..change("n=32", "order_l2", 0.75, Verdict::Worse)
                },
                // Orders about 0 of either sign (a saturated error): the ratio −1.5 has no
                // place on a log axis, the shift 0.03 − 0.02 has.
                Change {
                    a: -0.02,
                    b: 0.03,
                    ratio: -1.5,
                    interval: None,
                    ..change("n=16", "order_max", -1.5, Verdict::Same)
                },
            ],
            only_a: vec![],
            only_b: vec![],
        };
        let chart = chart(&comparison, "t", 0.1);
        assert!(crate::output::draw::lint(&chart).is_empty());
        let titles: Vec<&str> = chart.panels.iter().map(|p| p.title.as_str()).collect();
        assert_eq!(
            titles,
            [
                "solve_s",
                "speedup",
                "error_l2_norm",
                "order_l2",
                "order_max"
            ]
        );
        let worse: Vec<f64> = chart
            .panels
            .iter()
            .flat_map(|p| &p.series)
            .filter(|s| s.label == Verdict::Worse.text())
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .collect();
        let listed = chart.key.iter().filter(|k| k.contains("worse")).count();
        assert_eq!(worse.len() + listed, comparison.regressions());
        assert_eq!(worse, [2.0, 0.4, 0.5], "the order is drawn as its shift");
        let order_max = &chart.panels[4].series;
        let (x, shift) = order_max[2].points[0];
        assert!(x == 1.0 && (shift - 0.01).abs() < 1e-15, "{shift}");
        assert_eq!(
            chart.key,
            [
                "1: n=16",
                "2: n=32",
                "3: n=32 threads=2",
                "n=64, error_max: 0 → 0.001, worse (not drawn: B/A is no positive number)"
            ]
        );
        let svg = crate::output::draw::render(&chart).unwrap();
        for drawn in [
            "worse",
            "same",
            "threshold ±0.1",
            "tolerance ±0.1",
            "3: n=32 threads=2",
        ] {
            assert!(svg.contains(drawn), "{drawn}");
        }
        for absent in ["no interval", "too short", "every run timed"] {
            assert!(
                !svg.contains(absent),
                "{absent} is in the legend but not drawn"
            );
        }
    }
}
