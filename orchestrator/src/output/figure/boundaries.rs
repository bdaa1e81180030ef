//! Boundaries: what each boundary search measured against what the solver's theory predicts,
//! drawn from the study's boundary table (`analysis::boundaries`), not its summary.

use super::series::{describe, group, shared_by_all, subtitle, Group};
use crate::analysis::answer_table;
use crate::analysis::boundaries::{below_theory, NOTES};
use crate::output::draw::{span, Axis, Glyph, Guide, Panel, Series};
use crate::store::table::Row;

/// The swept fields of the boundary table.
pub(super) fn swept(rows: &[&Row]) -> Vec<String> {
    answer_table::swept(rows.iter().copied(), NOTES)
}

/// The measured boundaries along `x`, each series' prediction dashed in its colour, and where
/// the predictions vary, a second panel of measured / predicted; an axis that reads a
/// prediction zooms in around it to the search's tolerance. A boundary below the theory by more
/// than the tolerance is crossed. Returns the panels and the subtitle (what the series share,
/// and which searches found no boundary).
///
/// Long because its two panels (boundaries, and measured over predicted) share the series, their
/// predictions and the zoomed axis.
pub(super) fn boundaries(
    rows: &[&Row],
    series_columns: &[String],
    x: &str,
    rtol: f64,
) -> (Vec<Panel>, String) {
    let (found, none): (Vec<&Row>, Vec<&Row>) = rows
        .iter()
        .copied()
        .partition(|r| r.number("boundary").is_some());
    let mut groups = group(&found, series_columns);
    let words = [
        subtitle(&shared_by_all(&mut groups)),
        not_found(&none, series_columns),
    ];
    let words: Vec<String> = words.into_iter().filter(|w| !w.is_empty()).collect();
    let field = rows
        .iter()
        .find_map(|r| r.text("field"))
        .unwrap_or("boundary");
    let x_label = describe(&case_column(x), &[]);
    let y_label = describe(&case_column(field), &[]);
    let points = |g: &Group, y: &dyn Fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> {
        let mut points: Vec<(f64, f64)> = g
            .rows
            .iter()
            .filter_map(|r| Some((r.number(x)?, y(r)?)))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points
    };
    let line = |g: &Group, y: &dyn Fn(&Row) -> Option<f64>| {
        let mut line = Series::line(g.label(), points(g, y));
        line.marks = g
            .rows
            .iter()
            .filter(|r| below_theory(r, rtol))
            .filter_map(|r| Some(((r.number(x)?, y(r)?), Glyph::Cross)))
            .collect();
        line
    };
    let measured = |r: &Row| r.number("boundary");
    let predicted = |r: &Row| r.number("predicted");
    let ratio = |r: &Row| Some(r.number("gap")? + 1.0);
    let (lo, hi) = span(found.iter().filter_map(|r| r.number(x)));
    let x_axis = || Axis::fitting(x_label.clone(), [lo, hi]);
    // Zoomed in around `centre` to the tolerance: the gaps are fractions of a percent.
    let zoomed = |label: String, centre: f64| Axis {
        include: vec![centre],
        around: Some((centre, rtol * centre)),
        ..Axis::linear(label)
    };
    let theory = |at: f64| Guide::Dashed {
        label: Some("the theory".into()),
        of: None,
        points: vec![(lo, at), (hi, at)],
    };
    let (p_lo, p_hi) = span(found.iter().filter_map(|r| predicted(r)));
    let along = groups.iter().map(|g| line(g, &measured)).collect();
    let title = format!("measured {field}");
    if p_lo.is_finite() && p_lo == p_hi {
        // One prediction for all (cfl's 1): one panel, zoomed in around it.
        let panel = Panel {
            title,
            x: x_axis(),
            y: zoomed(y_label, p_lo),
            series: along,
            heat: None,
            guides: vec![theory(p_lo)],
        };
        return (vec![panel], words.join("; "));
    }
    let dashed = groups
        .iter()
        .enumerate()
        .map(|(k, g)| Guide::Dashed {
            label: None,
            of: Some(k),
            points: points(g, &predicted),
        })
        .filter(|guide| matches!(guide, Guide::Dashed { points, .. } if !points.is_empty()))
        .collect();
    let ys = found
        .iter()
        .flat_map(|r| [measured(r), predicted(r)])
        .flatten();
    let mut panels = vec![Panel {
        title: format!("{title}, the theory's dashed"),
        x: x_axis(),
        y: Axis::fitting(y_label.clone(), ys),
        series: along,
        heat: None,
        guides: dashed,
    }];
    if p_lo.is_finite() {
        panels.push(Panel {
            title: "measured / predicted".into(),
            x: x_axis(),
            y: zoomed(format!("{y_label}: measured / predicted"), 1.0),
            series: groups.iter().map(|g| line(g, &ratio)).collect(),
            heat: None,
            guides: vec![theory(1.0)],
        });
    }
    (panels, words.join("; "))
}

/// Which searches found no boundary, and how they ended: `no boundary found by 16 searches
/// (integrator = backward_euler, crank_nicolson): does not hold at the upper end …`.
fn not_found(none: &[&Row], series_columns: &[String]) -> String {
    if none.is_empty() {
        return String::new();
    }
    let mut which = Vec::new();
    for column in series_columns {
        let mut values: Vec<String> = Vec::new();
        for value in none.iter().filter_map(|r| r.get(column)) {
            let text = value
                .as_str()
                .map_or_else(|| value.to_string(), str::to_string);
            if !value.is_null() && !values.contains(&text) {
                values.push(text);
            }
        }
        if !values.is_empty() {
            which.push(format!("{column} = {}", values.join(", ")));
        }
    }
    let searches = if none.len() == 1 {
        "search"
    } else {
        "searches"
    };
    let mut words = format!("no boundary found by {} {searches}", none.len());
    if !which.is_empty() {
        words += &format!(" ({})", which.join("; "));
    }
    let ends: Vec<&str> = none.iter().filter_map(|r| r.text("ended")).collect();
    if let Some(first) = ends
        .first()
        .filter(|first| ends.iter().all(|e| e == *first))
    {
        words += &format!(": {first}");
    }
    words
}

/// The summary's name of a case field, which `describe` knows.
fn case_column(field: &str) -> String {
    format!("case.{field}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{json, Value};

    /// A row of the boundary table: the swept fields, then the answer.
    fn row(swept: &[(&str, Value)], field: &str, boundary: Option<f64>, predicted: f64) -> Row {
        let mut row = Row::default();
        for (name, value) in swept {
            row.set(name, value.clone());
        }
        row.set("field", json!(field));
        row.set("boundary", json!(boundary));
        row.set("predicted", json!(predicted));
        row.set("gap", json!(boundary.map(|b| b / predicted - 1.0)));
        let ended = match boundary {
            Some(_) => "found",
            None => "does not hold at the upper end: no boundary up to it",
        };
        row.set("ended", json!(ended));
        row
    }

    #[test]
    fn one_prediction_for_all_gives_one_panel_zoomed_in_around_it() {
        let rows = [
            row(
                &[("integrator", json!("rk4")), ("m", json!(1))],
                "cfl",
                Some(1.002),
                1.0,
            ),
            // 1 % below the theory, past the tolerance: a finding.
            row(
                &[("integrator", json!("rk4")), ("m", json!(2))],
                "cfl",
                Some(0.99),
                1.0,
            ),
            row(
                &[("integrator", json!("backward_euler")), ("m", json!(1))],
                "cfl",
                None,
                1.0,
            ),
        ];
        let rows: Vec<&Row> = rows.iter().collect();
        assert_eq!(swept(&rows), ["integrator", "m"]);
        let (panels, words) = boundaries(&rows, &["integrator".into()], "m", 1e-3);
        assert_eq!(panels.len(), 1);
        let panel = &panels[0];
        assert_eq!(panel.y.around, Some((1.0, 1e-3)));
        assert_eq!(panel.y.label, "dt / dt_stable");
        assert_eq!(
            panel.series.len(),
            1,
            "the search that found none draws nothing"
        );
        assert_eq!(panel.series[0].points, [(1.0, 1.002), (2.0, 0.99)]);
        assert_eq!(panel.series[0].marks, [((2.0, 0.99), Glyph::Cross)]);
        assert_eq!(
            words,
            "integrator = rk4; no boundary found by 1 search (integrator = backward_euler): does not hold at the upper end: no boundary up to it"
        );
    }

    #[test]
    fn predictions_that_vary_are_dashed_per_series_and_divided_out_in_a_second_panel() {
        let dt = |m: i64, boundary: f64, predicted: f64| {
            row(
                &[("m", json!(m)), ("dim", json!(1))],
                "dt",
                Some(boundary),
                predicted,
            )
        };
        let rows = [
            dt(1, 2.002e-4, 2e-4),
            dt(2, 1.001e-4, 1e-4),
            dt(4, 5.0e-5, 5e-5),
        ];
        let rows: Vec<&Row> = rows.iter().collect();
        let (panels, _) = boundaries(&rows, &[], "m", 1e-3);
        assert_eq!(panels.len(), 2);
        let [Guide::Dashed { of, points, .. }] = &panels[0].guides[..] else {
            panic!("one dashed prediction")
        };
        assert_eq!(*of, Some(0));
        assert_eq!(points, &[(1.0, 2e-4), (2.0, 1e-4), (4.0, 5e-5)]);
        let ratios: Vec<f64> = panels[1].series[0].points.iter().map(|p| p.1).collect();
        let expected = [1.001, 1.001, 1.0];
        assert!(
            ratios
                .iter()
                .zip(expected)
                .all(|(r, e)| (r - e).abs() < 1e-12),
            "{ratios:?}"
        );
        assert_eq!(panels[1].y.around, Some((1.0, 1e-3)));
    }
}
