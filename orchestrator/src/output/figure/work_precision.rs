//! Work–precision: run time against error, with the Pareto front of all methods.

use super::series::*;
use crate::analysis::answer_table;
use crate::analysis::target::NOTES;
use crate::model::target::TargetSpec;
use crate::output::draw::{Axis, Glyph, Guide, Panel, Series};
use crate::store::table::Row;
use serde_json::Value;

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

/// Marks an error-target study's answers on its work–precision panel: for each candidate the
/// resolution that met the target (a square around its point, its series' note naming it: `n =
/// 128, dt = 0.0012 (rank 1–2, a tie)`), a candidate with no answer named so in the legend, and
/// the target itself where the x axis is the error the target bounds.
pub(super) fn mark_target(
    panel: &mut Panel,
    groups: &[Group],
    (x, y): (&str, &str),
    spec: &TargetSpec,
    answers: &[Row],
) {
    let swept = answer_table::swept(answers, NOTES);
    let same = |a: Option<&Value>, b: Option<&Value>| match (a, b) {
        (Some(a), Some(b)) => a == b || a.as_f64().zip(b.as_f64()).is_some_and(|(a, b)| a == b),
        _ => false,
    };
    let summary_value = |row: &Row, name: &str| {
        row.get(&format!("case.{name}"))
            .or_else(|| row.get(name))
            .cloned()
    };
    // The candidate a summary row is a point of, and whether it is that candidate's answer.
    let candidate = |row: &Row| {
        answers.iter().find(|answer| {
            swept
                .iter()
                .all(|name| same(summary_value(row, name).as_ref(), answer.get(name)))
        })
    };
    let is_answer = |row: &Row, answer: &Row| {
        answer.number("rank").is_some()
            && same(
                summary_value(row, &spec.field).as_ref(),
                answer.get("resolution"),
            )
            && spec.time.as_ref().is_none_or(|time| {
                same(
                    summary_value(row, &time.field).as_ref(),
                    answer.get("time_resolution"),
                )
            })
    };
    for (line, group) in panel.series.iter_mut().zip(groups) {
        let mut named = None;
        for row in &group.rows {
            let Some(answer) = candidate(row) else {
                continue;
            };
            if is_answer(row, answer) {
                if let (Some(px), Some(py)) = (row.number(x), row.number(y)) {
                    line.marks.push(((px, py), Glyph::Square));
                }
                named = Some(answer_note(spec, answer));
            } else if answer.number("rank").is_none() {
                named = named.or_else(|| {
                    answer
                        .text("reached")
                        .map(|why| format!("no answer: {why}"))
                });
            }
        }
        match named {
            Some(note) if note.starts_with("no answer") => {
                line.label = format!("{} ({note})", line.label)
            }
            Some(note) => line.note = Some(note),
            None => {}
        }
    }
    if x.strip_prefix("case.").unwrap_or(x) == spec.error {
        panel.x.include.push(spec.below);
        panel.guides.push(Guide::Vertical {
            label: format!(
                "target: {} ≤ {}",
                spec.error,
                crate::console::number(spec.below)
            ),
            x: spec.below,
        });
    }
}

/// An answer's note: its resolutions and its rank, a tie said.
fn answer_note(spec: &TargetSpec, answer: &Row) -> String {
    let number = crate::console::number;
    let mut note = format!(
        "{} = {}",
        spec.field,
        answer.number("resolution").map_or("?".into(), number)
    );
    if let Some(time) = &spec.time {
        let value = answer.number("time_resolution").map_or("?".into(), number);
        note.push_str(&format!(", {} = {value}", time.field));
    }
    let (rank, last) = (answer.count("rank"), answer.count("tied_to"));
    match (rank, last) {
        (Some(rank), Some(last)) if last > rank => {
            note.push_str(&format!(" (rank {rank}–{last}, a tie within noise)"))
        }
        (Some(rank), _) => note.push_str(&format!(" (rank {rank})")),
        _ => {}
    }
    note
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_pareto_front_keeps_the_points_no_other_beats_in_both_error_and_time() {
        let front = super::pareto_front(&[(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0)]);
        assert_eq!(front, [(1.0, 5.0), (2.0, 3.0), (4.0, 1.0)]);
    }
}

#[cfg(test)]
mod target_tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_answers_of_an_error_target_are_squared_and_the_target_drawn() {
        let summary: Vec<Row> = [
            ("fd", 16, 1e-4, 0.001),
            ("fd", 56, 9e-6, 0.002),
            ("fd", 64, 7e-6, 0.003),
            ("adi", 125, 9.9e-6, 0.03),
        ]
        .into_iter()
        .map(|(method, n, error, time)| {
            let mut row = Row::default();
            row.set("case.method", json!(method));
            row.set("case.n", json!(n));
            row.set("status", json!("ok"));
            row.set("error_l2_norm", json!(error));
            row.set("solve_s_median", json!(time));
            row
        })
        .collect();
        let answers: Vec<Row> = [("fd", 56, 1), ("adi", 125, 2)]
            .into_iter()
            .map(|(method, n, rank)| {
                let mut row = Row::default();
                row.set("method", json!(method));
                row.set("field", json!("n"));
                row.set("target", json!(1e-5));
                row.set("resolution", json!(n));
                row.set("rank", json!(rank));
                row
            })
            .collect();
        let spec: TargetSpec =
            serde_json::from_value(json!({"field": "n", "start": 16, "below": 1e-5})).unwrap();
        let kept: Vec<&Row> = summary.iter().collect();
        let groups = group(&kept, &["case.method".to_string()]);
        let (x, y) = ("error_l2_norm", "solve_s_median");
        let mut panel = work_precision(&groups, x, y);
        mark_target(&mut panel, &groups, (x, y), &spec, &answers);
        let marks: Vec<_> = panel.series.iter().map(|s| s.marks.clone()).collect();
        assert_eq!(
            marks,
            [
                vec![((9e-6, 0.002), Glyph::Square)],
                vec![((9.9e-6, 0.03), Glyph::Square)]
            ]
        );
        assert!(panel.x.include.contains(&1e-5));
        assert!(panel
            .guides
            .iter()
            .any(|g| matches!(g, Guide::Vertical { x, .. } if *x == 1e-5)));
    }
}
