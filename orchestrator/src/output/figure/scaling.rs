//! Strong and weak scaling: time, speedup and efficiency against workers (threads × ranks).

use super::series::*;
use crate::output::draw::{self, Axis, Glyph, Guide, Panel, Series};
use crate::store::table::Row;
use schema::record::Status;

/// The groups of a scaling figure split by the kind of parallelism that multiplies their
/// workers (threads, ranks, both), each kind's line starting at the group's serial point: a
/// 2-thread and a 2-rank point of one series are two lines, not one zig-zag. A group of one
/// kind stays whole.
pub(super) fn by_parallelism<'a>(groups: Vec<Group<'a>>) -> Vec<Group<'a>> {
    let mut split = Vec::new();
    for group in groups {
        let kind = |r: &&Row| r.text("parallelism").unwrap_or("serial").to_string();
        let mut kinds: Vec<String> = group
            .rows
            .iter()
            .map(kind)
            .filter(|k| k != "serial")
            .collect();
        kinds.sort();
        kinds.dedup();
        if kinds.len() < 2 {
            split.push(group);
            continue;
        }
        for parallel in kinds {
            let rows = group
                .rows
                .iter()
                .filter(|r| kind(r) == "serial" || kind(r) == parallel)
                .copied()
                .collect();
            let mut parts = group.parts.clone();
            parts.push(("parallelism".to_string(), parallel));
            split.push(Group { parts, rows });
        }
    }
    split
}

/// The glyphs over the points of `series` (one per group, in order), by their own rows: a ring
/// where the runs were noisy, a cross where they ran more workers than the machine had cores
/// (the record's `oversubscribed`: their times measure contention, not scaling).
fn mark_by_row(groups: &[Group], x: &str, series: &mut [Series]) {
    for (g, line) in groups.iter().zip(series) {
        let noisy = g.noisy_xs(x);
        let crowded = g.oversubscribed_xs(x);
        for &point in &line.points {
            if noisy.contains(&point.0) {
                line.marks.push((point, Glyph::Ring));
            }
            if crowded.contains(&point.0) {
                line.marks.push((point, Glyph::Cross));
            }
        }
    }
}

pub(super) fn strong_scaling(groups: &[Group], x: &str, y: &str) -> Vec<Panel> {
    let (mut times, mut speedups, mut efficiencies) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ideal_time, mut ideal_speedup) = (Vec::new(), Vec::new());
    let drawn: Vec<Group> = groups
        .iter()
        .filter(|g| !g.points(x, y).is_empty())
        .cloned()
        .collect();
    for (k, g) in drawn.iter().enumerate() {
        let points = g.points(x, y);
        let &(p0, t0) = points.first().expect("drawn groups have points");
        let mut time = series(g.label(), points.clone());
        if let Some((lo, hi)) = band_columns(y) {
            let rows = g.rows.iter().filter(|r| r.status() == Some(Status::Ok));
            time.band = rows
                .filter_map(|r| Some((r.number(x)?, r.number(&lo)?, r.number(&hi)?)))
                .collect();
            time.band.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let speedup: Vec<(f64, f64)> = points.iter().map(|&(p, t)| (p, t0 / t)).collect();
        let efficiency = speedup.iter().map(|&(p, s)| (p, s * p0 / p)).collect();
        let label = |first: bool| first.then(|| "ideal".to_string());
        ideal_time.push(Guide::Dashed {
            label: label(k == 0),
            of: Some(k),
            points: points.iter().map(|&(p, _)| (p, t0 * p0 / p)).collect(),
        });
        ideal_speedup.push(Guide::Dashed {
            label: label(k == 0),
            of: Some(k),
            points: points.iter().map(|&(p, _)| (p, p / p0)).collect(),
        });
        times.push(time);
        speedups.push(series(g.label(), speedup));
        efficiencies.push(series(g.label(), efficiency));
    }
    for lines in [&mut times, &mut speedups, &mut efficiencies] {
        mark_by_row(&drawn, x, lines);
    }
    let workers = all(times.iter(), |p| p.0);
    let x_axis = || Axis::fitting(describe(x, groups), workers.iter().copied()).counting();
    let mut efficiency_axis = Axis::linear("parallel efficiency T(p₀)·p₀ / (T(p)·p)");
    efficiency_axis.include = vec![0.0, 1.0];
    vec![
        Panel {
            title: match times.iter().any(|t| !t.band.is_empty()) {
                true => "time (band: min to max of the repeats)".into(),
                false => "time".into(),
            },
            x: x_axis(),
            y: Axis::fitting(describe(y, groups), all(times.iter(), |p| p.1)),
            series: times,
            guides: ideal_time,
            heat: None,
        },
        Panel {
            title: "speedup".into(),
            x: x_axis(),
            y: Axis::fitting("speedup T(p₀) / T(p)", all(speedups.iter(), |p| p.1)),
            series: speedups,
            guides: ideal_speedup,
            heat: None,
        },
        Panel {
            title: "parallel efficiency".into(),
            x: x_axis(),
            y: efficiency_axis,
            series: efficiencies,
            guides: vec![ideal_efficiency(&workers)],
            heat: None,
        },
    ]
}

/// Efficiency 1 across the workers shown.
fn ideal_efficiency(workers: &[f64]) -> Guide {
    let (lo, hi) = draw::span(workers.iter().copied());
    Guide::Dashed {
        label: Some("ideal".into()),
        of: None,
        points: match lo <= hi {
            true => vec![(lo, 1.0), (hi, 1.0)],
            false => Vec::new(),
        },
    }
}

pub(super) fn weak_scaling(groups: &[Group], x: &str, y: &str) -> Panel {
    let drawn: Vec<Group> = groups
        .iter()
        .filter(|g| !g.points(x, y).is_empty())
        .cloned()
        .collect();
    let mut lines: Vec<Series> = drawn
        .iter()
        .map(|g| {
            let points = g.points(x, y);
            let t0 = points[0].1;
            series(
                g.label(),
                points.iter().map(|&(p, t)| (p, t0 / t)).collect(),
            )
        })
        .collect();
    mark_by_row(&drawn, x, &mut lines);
    let workers = all(lines.iter(), |p| p.0);
    let mut y_axis = Axis::linear("weak-scaling efficiency T(p₀) / T(p)");
    y_axis.include = vec![0.0, 1.0];
    Panel {
        title: "weak scaling".into(),
        x: Axis::fitting(describe(x, groups), workers.iter().copied()).counting(),
        y: y_axis,
        heat: None,
        guides: vec![ideal_efficiency(&workers)],
        series: lines,
    }
}
