//! Stability: max |u| at the end against dt / dt_stable, diverged runs marked.

use super::series::*;
use crate::output::draw::{Axis, Glyph, Guide, Panel, Series};
use crate::store::table::Row;
use schema::record::columns;
use schema::record::{Status, GROWING};

pub(super) fn stability(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| {
            let mut line = series(g.label(), g.points(x, y));
            // A diverged run stops where |u| passed the bound; its cross sits at what it reached.
            // A run `ok` by the bound that grew a decade past its scale is unstable too.
            let grew = |r: &Row| r.number(columns::GROWTH).is_some_and(|g| g >= GROWING);
            line.marks = g
                .rows
                .iter()
                .filter(|r| r.status() == Some(Status::Diverged) || grew(r))
                .filter_map(|r| Some((r.number(x)?, r.number(y).filter(|v| v.is_finite())?)))
                .map(|p| (p, Glyph::Cross))
                .collect();
            line
        })
        .collect();
    let drawn: Vec<(f64, f64)> = lines
        .iter()
        .flat_map(|s| s.points.iter().chain(s.marks.iter().map(|(p, _)| p)))
        .copied()
        .collect();
    let (xs, ys): (Vec<f64>, Vec<f64>) = drawn.into_iter().unzip();
    let mut x_axis = Axis::zooming(describe(x, groups), 1.0, &xs);
    x_axis.include = vec![1.0];
    Panel {
        title: "stability".into(),
        x: x_axis,
        y: Axis::fitting(describe(y, groups), ys),
        series: lines,
        heat: None,
        guides: vec![Guide::Vertical {
            label: "dt = dt_stable".into(),
            x: 1.0,
        }],
    }
}
