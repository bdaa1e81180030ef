//! Convergence: error against h (or m) on log–log axes, each line labelled with its fitted order.

use super::series::*;
use crate::output::draw::{Axis, Panel, Series};

/// The least-squares slope of log y against log x.
pub fn fitted_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = logs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

pub(super) fn convergence(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| {
            let points = g.points(x, y);
            let slope = fitted_slope(&points);
            let mut line = series(
                match slope {
                    Some(s) => format!("{} slope {s:.2}", g.legend()),
                    None => g.legend(),
                },
                points,
            );
            line.note = slope.map(|s| format!("  {s:.2}"));
            line
        })
        .collect();
    Panel {
        title: "convergence".into(),
        x: Axis::fitting(describe(x), all(lines.iter(), |p| p.0)),
        y: Axis::fitting(describe(y), all(lines.iter(), |p| p.1)),
        series: lines,
        guides: Vec::new(),
        heat: None,
    }
}
