//! Work–precision: run time against error, with the Pareto front of all methods.

use super::series::*;
use crate::output::draw::{Axis, Guide, Panel, Series};

/// The points no other point beats in both error and time, by increasing error.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in sorted {
        if front.last().is_none_or(|last| p.1 < last.1) {
            front.push(p);
        }
    }
    front
}

pub(super) fn work_precision(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| series(g.label(), g.points(x, y)))
        .collect();
    let everything: Vec<(f64, f64)> = lines.iter().flat_map(|s| s.points.clone()).collect();
    Panel {
        title: "work–precision".into(),
        x: Axis::fitting(describe(x, groups), all(lines.iter(), |p| p.0)),
        y: Axis::fitting(describe(y, groups), all(lines.iter(), |p| p.1)),
        series: lines,
        heat: None,
        guides: vec![Guide::Dashed {
            label: Some("Pareto front".into()),
            of: None,
            points: pareto_front(&everything),
        }],
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_pareto_front_keeps_the_points_no_other_beats_in_both_error_and_time() {
        let front = super::pareto_front(&[(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0)]);
        assert_eq!(front, [(1.0, 5.0), (2.0, 3.0), (4.0, 1.0)]);
    }
}
