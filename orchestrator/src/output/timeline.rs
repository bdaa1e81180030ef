//! A run's timeline for a person: `status --timeline`'s table of where each lane's wall time
//! went, and the figure, `results/<study>/timeline.svg`, one row per lane grouped by node,
//! coloured by phase.

use crate::analysis::timeline::{Phase, Timeline};
use crate::console::counted;
use crate::output::draw::gantt::{self, Bar, Gantt};
use crate::store::{write_atomically, Fault, Store};
use plotters::style::RGBColor;
use std::path::PathBuf;

/// Each phase's colour: the solver's work in blues and greens, the tool's in warm colours,
/// waiting in greys.
fn colour(phase: Phase) -> RGBColor {
    match phase {
        Phase::Starting => RGBColor(255, 127, 14),
        Phase::Setup => RGBColor(148, 103, 189),
        Phase::Solve => RGBColor(31, 119, 180),
        Phase::Measuring => RGBColor(44, 160, 44),
        Phase::Passing => RGBColor(140, 86, 75),
        Phase::Unrecorded => RGBColor(214, 39, 40),
        Phase::Idle => RGBColor(215, 215, 215),
        Phase::Planning => RGBColor(150, 150, 150),
    }
}

/// `this machine #0`: a lane's row label.
fn lane_label((node, lane): &(String, usize)) -> String {
    format!("{node} #{lane}")
}

/// What the run was: its cases, lanes, nodes and length.
fn headline(timeline: &Timeline) -> String {
    let nodes: std::collections::BTreeSet<&str> =
        timeline.lanes.iter().map(|l| l.0.as_str()).collect();
    format!(
        "run {}: {} on {} of {} in {:.2} s",
        timeline.run,
        counted(timeline.cases, "case"),
        counted(timeline.lanes.len(), "lane"),
        counted(nodes.len(), "node"),
        timeline.end - timeline.begin
    )
}

/// The table `status --timeline` prints of a run: seconds of each phase on each lane, and the
/// share of the lane's wall time they account for.
pub fn table(timeline: &Timeline) -> Vec<String> {
    let mut lines = vec![headline(timeline)];
    let labels: Vec<String> = timeline.lanes.iter().map(lane_label).collect();
    let width = labels.iter().map(|l| l.chars().count()).max().unwrap_or(4);
    let mut header = format!("  {:width$}  {:>8}", "lane", "wall s");
    for phase in Phase::ALL {
        header.push_str(&format!(
            "  {:>w$}",
            phase.name(),
            w = phase.name().len().max(6)
        ));
    }
    header.push_str("  accounted");
    lines.push(header);
    let mut busy = 0.0;
    for (lane, label) in labels.iter().enumerate() {
        let totals = timeline.totals(lane);
        let mut line = format!("  {label:width$}  {:>8.2}", timeline.walls[lane]);
        for (phase, seconds) in Phase::ALL.iter().zip(totals) {
            line.push_str(&format!("  {seconds:>w$.2}", w = phase.name().len().max(6)));
            busy += if phase.busy() { seconds } else { 0.0 };
        }
        let accounted = totals.iter().sum::<f64>() / timeline.walls[lane];
        line.push_str(&format!("  {:>8.1} %", 100.0 * accounted));
        lines.push(line);
    }
    let wall: f64 = timeline.walls.iter().sum();
    lines.push(format!(
        "  busy {:.1} % of the lanes' wall time (the rest idle or between rounds)",
        100.0 * busy / wall.max(f64::MIN_POSITIVE)
    ));
    lines
}

/// The figure of a run's timeline.
pub fn chart(timeline: &Timeline) -> Gantt {
    Gantt {
        title: format!("Timeline of {}", headline(timeline)),
        rows: timeline.lanes.iter().map(lane_label).collect(),
        categories: Phase::ALL
            .iter()
            .map(|&p| (p.name().to_string(), colour(p)))
            .collect(),
        bars: timeline
            .spans
            .iter()
            .map(|span| Bar {
                row: span.lane,
                from: span.from - timeline.begin,
                to: span.to - timeline.begin,
                category: Phase::ALL
                    .iter()
                    .position(|p| *p == span.phase)
                    .expect("listed"),
            })
            .collect(),
        length: timeline.end - timeline.begin,
    }
}

/// Draws the study's latest run's timeline into `results/<study>/timeline.svg`; `None` when
/// no run left one.
pub fn write_latest(store: &Store) -> Result<Option<(PathBuf, String)>, Fault> {
    let (_, runs) = crate::store::timeline::latest(store, 1);
    match runs.iter().find_map(Timeline::of) {
        Some(timeline) => write(store, &timeline).map(Some),
        None => Ok(None),
    }
}

/// Draws `timeline` into `results/<study>/timeline.svg`; returns its path and text.
pub fn write(store: &Store, timeline: &Timeline) -> Result<(PathBuf, String), Fault> {
    let svg = gantt::render(&chart(timeline)).map_err(Fault::Io)?;
    let path = store.table("timeline.svg");
    write_atomically(&path, svg.as_bytes())?;
    Ok((path, svg))
}
