//! The comparison of two result sets as a figure: for each measured metric a panel of B/A per
//! point with its bootstrap interval, coloured by verdict, beside the threshold's band.

use crate::analysis::compare::{Comparison, Verdict};
use crate::output::draw::{Axis, Chart, Guide, Panel, Series};

/// The verdicts in legend order (each a series: its points as crosses, no line between them).
const VERDICTS: [(Verdict, &str); 4] = [
    (Verdict::Worse, "worse"),
    (Verdict::Better, "better"),
    (Verdict::Same, "same"),
    (Verdict::NoInterval, "no interval"),
];

pub fn chart(comparison: &Comparison, title: &str, threshold: f64) -> Chart {
    let mut metrics: Vec<&str> = Vec::new();
    for change in comparison.changes.iter().filter(|c| c.interval.is_some()) {
        if !metrics.contains(&change.metric) {
            metrics.push(change.metric);
        }
    }
    let panels = metrics
        .iter()
        .map(|&metric| {
            let changes: Vec<_> = comparison
                .changes
                .iter()
                .filter(|c| c.metric == metric && c.ratio.is_finite())
                .collect();
            let at = |k: usize| (k + 1) as f64;
            let series = VERDICTS
                .iter()
                .map(|(verdict, label)| Series {
                    label: label.to_string(),
                    points: Vec::new(),
                    band: Vec::new(),
                    crosses: changes
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| c.verdict == *verdict)
                        .map(|(k, c)| (at(k), c.ratio))
                        .collect(),
                    note: None,
                })
                .collect();
            let last = at(changes.len().saturating_sub(1)).max(1.0);
            let mut guides: Vec<Guide> = changes
                .iter()
                .enumerate()
                .filter_map(|(k, c)| {
                    let (low, high) = c.interval?;
                    let of = VERDICTS.iter().position(|(v, _)| *v == c.verdict);
                    Some(Guide::Dashed {
                        label: None,
                        of,
                        points: vec![(at(k), low), (at(k), high)],
                    })
                })
                .collect();
            for (bound, label) in [
                (
                    1.0 + threshold,
                    Some(format!("threshold ±{}", crate::console::number(threshold))),
                ),
                (1.0 / (1.0 + threshold), None),
            ] {
                guides.push(Guide::Dashed {
                    label,
                    of: None,
                    points: vec![(1.0, bound), (last, bound)],
                });
            }
            Panel {
                title: metric.to_string(),
                x: Axis {
                    label: "point (in the order of the study)".into(),
                    log: false,
                    include: vec![],
                    whole: true,
                },
                y: Axis {
                    label: "B / A of the medians, 95 % interval".into(),
                    log: true,
                    include: vec![1.0],
                    whole: false,
                },
                series,
                guides,
                heat: None,
            }
        })
        .collect();
    Chart {
        title: title.to_string(),
        subtitle: String::new(),
        panels,
    }
}
