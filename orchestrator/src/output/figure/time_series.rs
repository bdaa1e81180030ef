//! Time series: a per-run series of the record (such as c_tot(t)) against time, or any
//! per-run series against another (such as a patch test's L_h u against x).

use super::series::*;
use crate::output::draw::{Axis, Panel, Series};

pub(super) fn time_series(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .flat_map(|g| g.rows.iter().map(move |r| (g, r)))
        .map(|(g, r)| {
            let points = numbers(r.get(x))
                .into_iter()
                .zip(numbers(r.get(y)))
                .collect();
            series(g.label(), points)
        })
        .collect();
    // The whole range from 0, as [HPCSE] draws c_tot(t).
    let mut y_axis = Axis::linear(describe(y, groups));
    y_axis.include = vec![0.0];
    Panel {
        title: "time series".into(),
        x: Axis::linear(describe(x, groups)),
        y: y_axis,
        series: lines,
        guides: Vec::new(),
        heat: None,
    }
}
