//! Convergence: error against h (or m, or dt) on log–log axes. Each series is labelled with its
//! fitted order and the order between its two finest grids (where a stalling error shows
//! first), and a reference triangle of each rounded order shows what that slope looks like.

use super::series::*;
use crate::console::number;
use crate::output::draw::{span, Axis, Guide, Panel, Series};
use crate::statistics::fitted_slope;

/// Whether the grids get finer as x grows: m = ε/h and n do, h and dt do not.
fn finer_upwards(x: &str) -> bool {
    matches!(x.strip_prefix("case.").unwrap_or(x), "m" | "n")
}

/// The two points of the finest grids (the points are sorted by x).
fn finest_pair<'a>(points: &'a [(f64, f64)], x: &str) -> &'a [(f64, f64)] {
    let two = points.len().min(2);
    match finer_upwards(x) {
        true => &points[points.len() - two..],
        false => &points[..two],
    }
}

/// The piecewise linear line through points sorted by x, level beyond its ends.
fn along(points: &[(f64, f64)], x: f64) -> f64 {
    let right = points
        .partition_point(|p| p.0 < x)
        .clamp(1, points.len() - 1);
    let ((x0, y0), (x1, y1)) = (points[right - 1], points[right]);
    let t = match x1 > x0 {
        true => ((x - x0) / (x1 - x0)).clamp(0.0, 1.0),
        false => 0.0,
    };
    y0 + t * (y1 - y0)
}

/// An observed order as a figure states it: two decimals (a slope read off a log–log plot has
/// no more), and 0 for an order that rounds to 0 (`-0.0001` of a stalled error reads as 0).
fn order_text(order: f64) -> String {
    let rounded = (order * 100.0).round() / 100.0;
    number(if rounded == 0.0 { 0.0 } else { rounded })
}

pub(super) fn convergence(groups: &[Group], x: &str, y: &str) -> Panel {
    let mut lines = Vec::new();
    let mut fits = Vec::new();
    for g in groups {
        let points = g.points(x, y);
        let fit = fitted_slope(&points);
        let finest = fitted_slope(finest_pair(&points, x));
        let mut line = series(g.label(), points);
        if let (Some(fit), Some(finest)) = (fit, finest) {
            line.label = format!(
                "{}: order {} fitted, {} finest pair",
                line.label,
                order_text(fit),
                order_text(finest)
            );
            line.note = Some(order_text(fit));
        }
        fits.push(fit);
        lines.push(line);
    }
    let guides = reference_slopes(&lines, &fits, x);
    let xs = all(lines.iter(), |p| p.0);
    let ys = all(lines.iter(), |p| p.1);
    Panel {
        title: "convergence".into(),
        x: Axis::log_if_positive(describe(x, groups), xs.iter().copied()),
        y: Axis::log_if_positive(describe(y, groups), ys.iter().copied()),
        series: lines,
        guides,
        heat: None,
    }
}

/// A triangle for each whole order (not 0) that a series' fit is close to (within 0.25), under
/// the finest pair of the first series with it; a stalling or wandering series gets none, and
/// none is drawn when the axes are not both logarithmic.
fn reference_slopes(lines: &[Series], fits: &[Option<f64>], x: &str) -> Vec<Guide> {
    let logs = |s: &Series| -> Vec<(f64, f64)> {
        s.points
            .iter()
            .filter(|(x, y)| *x > 0.0 && *y > 0.0)
            .map(|(x, y)| (x.log10(), y.log10()))
            .collect()
    };
    let none_negative = lines
        .iter()
        .all(|s| s.points.iter().all(|&(x, y)| x >= 0.0 && y >= 0.0));
    let (lo, hi) = span(lines.iter().flat_map(logs).map(|p| p.1));
    if !none_negative || !lo.is_finite() {
        return Vec::new();
    }
    // A fifth of the panel wide, below the line by a tenth of the errors' span (at least a
    // fifth of a decade), from the finest grid towards the coarser ones.
    let (left, right) = span(lines.iter().flat_map(logs).map(|p| p.0));
    let (w, below) = (0.2 * (right - left), (0.1 * (hi - lo)).max(0.2));
    let mut drawn: Vec<f64> = Vec::new();
    let mut guides = Vec::new();
    for (line, fit) in lines.iter().zip(fits) {
        let Some(fit) = fit else { continue };
        let slope = fit.round();
        if slope == 0.0 || (fit - slope).abs() > 0.25 || drawn.contains(&slope) || w <= 0.0 {
            continue;
        }
        let points = logs(line);
        let a = match finer_upwards(x) {
            true => points[points.len() - 1].0 - w,
            false => points[0].0,
        };
        let start = (along(&points, a) - below).min(along(&points, a + w) - slope * w - below);
        let end = start + slope * w;
        // The right angle under the hypotenuse's higher end.
        let corner = match slope > 0.0 {
            true => (a + w, start),
            false => (a, end),
        };
        let to_data = |(x, y): (f64, f64)| (10f64.powf(x), 10f64.powf(y));
        guides.push(Guide::Slope {
            triangle: [(a, start), (a + w, end), corner].map(to_data),
            slope: number(slope),
        });
        drawn.push(slope);
    }
    guides
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::table::Row;
    use serde_json::json;

    /// A series with e = h² on its coarse grids and a stall on its finest (e = h² + 1.5e-4).
    fn rows() -> Vec<Row> {
        [1.0 / 8.0, 1.0 / 16.0, 1.0 / 32.0, 1.0 / 64.0]
            .iter()
            .map(|&h: &f64| {
                let mut row = Row::default();
                row.set("h", json!(h));
                row.set("error_l2_norm", json!(h * h + 1.5e-4));
                row.set("status", json!("ok"));
                row.set("repeats", json!(3));
                row
            })
            .collect()
    }

    #[test]
    fn each_series_gives_its_fitted_and_its_finest_order_and_a_reference_slope() {
        let rows = rows();
        let groups = group(&rows.iter().collect::<Vec<_>>(), &[]);
        let panel = convergence(&groups, "h", "error_l2_norm");
        let points = &panel.series[0].points;
        let fit = fitted_slope(points).unwrap();
        let finest = (points[1].1 / points[0].1).ln() / 2f64.ln();
        assert!(finest < fit - 0.2, "{finest} {fit}");
        assert_eq!(
            panel.series[0].label,
            format!(
                "all points: order {} fitted, {} finest pair",
                order_text(fit),
                order_text(finest)
            )
        );
        // A stalled error's order is 0, not -0.0001.
        assert_eq!(order_text(-1e-4), "0");
        assert_eq!(order_text(1.996), "2");
        assert_eq!(order_text(0.8449), "0.84");
        // Deterministic errors: no repeat counts.
        assert!(!panel.series[0].label.contains("repeat"));
        assert!(
            panel.x.log && panel.y.log,
            "h spans less than a decade, yet log"
        );
        let [Guide::Slope { triangle, slope }] = &panel.guides[..] else {
            panic!("one reference slope");
        };
        assert_eq!(slope, &number(fit.round()));
        let [start, end, corner] = triangle.map(|(x, y)| (x.log10(), y.log10()));
        let rise = (end.1 - start.1) / (end.0 - start.0);
        assert!(
            (rise - slope.parse::<f64>().unwrap()).abs() < 1e-9,
            "{rise}"
        );
        assert_eq!(
            (corner.0, corner.1),
            (end.0, start.1),
            "a right angle under the end"
        );
        // Under the series: below its finest pair at both ends of the hypotenuse.
        let line = |x: f64| {
            let (a, b) = (points[0], points[1]);
            let t = (x - a.0.log10()) / (b.0.log10() - a.0.log10());
            a.1.log10() + t * (b.1.log10() - a.1.log10())
        };
        assert!(start.1 < line(start.0) && end.1 < line(end.0));
    }
}
