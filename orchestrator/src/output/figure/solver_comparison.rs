//! Solver comparison: iterations and solve time of the steady solvers against subdomains.

use super::series::*;
use crate::output::draw::{Axis, Panel, Series};
use crate::store::table::Row;

/// Iterations (`y`) and median solve time against the subdomains, a series per solver; a row
/// without subdomains (CG) is drawn at every subdomain count of the rows with its n.
pub(super) fn solver_comparison(
    rows: &[&Row],
    series_columns: &[String],
    x: &str,
    y: &str,
) -> Vec<Panel> {
    let subdomains_of_n: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| Some((r.number("case.n")?, r.number(x)?)))
        .collect();
    let mut placed: Vec<Row> = Vec::new();
    for &row in rows {
        if row.number(x).is_some() {
            placed.push(row.clone());
            continue;
        }
        let n = row.number("case.n");
        let mut at: Vec<f64> = subdomains_of_n
            .iter()
            .filter(|(m, _)| Some(*m) == n)
            .map(|&(_, s)| s)
            .collect();
        at.sort_by(f64::total_cmp);
        at.dedup();
        for s in at {
            let mut copy = row.clone();
            copy.set(x, serde_json::json!(s));
            placed.push(copy);
        }
    }
    let placed: Vec<&Row> = placed.iter().collect();
    let mut groups = group(&placed, series_columns);
    shared_by_all(&mut groups);
    [(y, "iterations"), ("solve_s_median", "solve time")]
        .into_iter()
        .map(|(column, title)| {
            let lines: Vec<Series> = groups
                .iter()
                .map(|g| series(g.label(), g.points(x, column)))
                .collect();
            Panel {
                title: title.into(),
                x: Axis::fitting(describe(x, &groups), all(lines.iter(), |p| p.0)),
                y: Axis::fitting(describe(column, &groups), all(lines.iter(), |p| p.1)),
                series: lines,
                heat: None,
                guides: Vec::new(),
            }
        })
        .collect()
}
