//! The legend (only what is drawn, every glyph explained) and `lint`, which refuses a chart
//! that would say less than it shows.

use super::chart::*;
use super::style::DrawResult;
use super::style::*;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// An entry of the legend and what its key draws.
pub(super) struct Entry<'a> {
    pub(super) label: &'a str,
    pub(super) colour: RGBColor,
    pub(super) key: Key,
}

#[derive(Clone, Copy, PartialEq)]
pub(super) enum Key {
    /// A series: its marker (the series' index), on a line when it has one.
    Series { marker: usize, line: bool },
    /// A dashed guide.
    Dashed,
    /// A glyph, in black (each series draws it in its own colour).
    Glyph(Glyph),
}

/// The legend: every labelled series that draws something and every labelled guide of the
/// panels, once each, in order, then each glyph drawn with what it means. Nothing drawn has
/// no entry, and nothing without an entry is drawn (`lint` checks the glyphs).
pub(super) fn legend(chart: &Chart) -> Vec<Entry<'_>> {
    let mut entries: Vec<Entry> = Vec::new();
    for panel in &chart.panels {
        let series = panel
            .series
            .iter()
            .enumerate()
            .filter(|(_, s)| s.draws() && !s.label.is_empty())
            .map(|(k, s)| Entry {
                label: &s.label,
                colour: colour(k),
                key: Key::Series {
                    marker: k,
                    line: s.line,
                },
            });
        let guides = panel.guides.iter().filter_map(|g| match g {
            Guide::Dashed { label, of, .. } => Some(Entry {
                label: label.as_deref()?,
                colour: of.map_or(BLACK, colour),
                key: Key::Dashed,
            }),
            Guide::Vertical { label, .. } => Some(Entry {
                label,
                colour: BLACK,
                key: Key::Dashed,
            }),
            Guide::Slope { .. } => None,
        });
        for entry in series.chain(guides) {
            if !entries.iter().any(|e| e.label == entry.label) {
                entries.push(entry);
            }
        }
    }
    for (glyph, meaning) in &chart.glyphs {
        if chart.drawn_glyphs().contains(glyph) {
            entries.push(Entry {
                label: meaning,
                colour: BLACK,
                key: Key::Glyph(*glyph),
            });
        }
    }
    entries
}

/// What a reader of the chart could not make sense of: an empty title or axis label, a
/// subtitle part with nothing on one side of its `=`, a glyph drawn that the legend does not
/// explain or explained but not drawn, a series drawn without a label. `render` refuses such
/// a chart; the figures' tests run it over every kind.
pub fn lint(chart: &Chart) -> Vec<String> {
    let mut defects = Vec::new();
    if chart.title.trim().is_empty() {
        defects.push("no title".to_string());
    }
    for part in chart.subtitle.split("; ").filter(|p| !p.is_empty()) {
        for pair in part.split(", ") {
            if let Some((field, value)) = pair.split_once(" = ") {
                if field.trim().is_empty() || value.trim().is_empty() {
                    defects.push(format!("subtitle part `{pair}` names no field or no value"));
                }
            } else if pair.trim() == "=" {
                defects.push("a lone `=` in the subtitle".to_string());
            }
        }
    }
    for panel in chart.panels.iter().filter(|p| p.heat.is_none()) {
        for (axis, name) in [(&panel.x, "x"), (&panel.y, "y")] {
            if axis.label.trim().is_empty() {
                defects.push(format!(
                    "panel `{}`: its {name} axis has no label",
                    panel.title
                ));
            }
        }
        if panel.series.iter().any(|s| s.draws() && s.label.is_empty()) {
            defects.push(format!(
                "panel `{}`: a series drawn without a label",
                panel.title
            ));
        }
        let drawn = |pick: fn(&(f64, f64)) -> f64| {
            let series = panel.series.iter();
            let points = series.flat_map(|s| s.points.iter().chain(s.marks.iter().map(|m| &m.0)));
            points.map(pick).collect::<Vec<f64>>()
        };
        for (axis, name, values) in [
            (&panel.x, "x", drawn(|p| p.0)),
            (&panel.y, "y", drawn(|p| p.1)),
        ] {
            if axis.log && !values.is_empty() && !values.iter().any(|v| *v > 0.0 && v.is_finite()) {
                defects.push(format!(
                    "panel `{}`: its {name} axis is logarithmic and no value is positive",
                    panel.title
                ));
            }
        }
    }
    let drawn = chart.drawn_glyphs();
    for glyph in &drawn {
        if !chart.glyphs.iter().any(|(g, _)| g == glyph) {
            defects.push(format!("{glyph:?} drawn but not explained in the legend"));
        }
    }
    for (glyph, meaning) in &chart.glyphs {
        if !drawn.contains(glyph) {
            defects.push(format!(
                "the legend explains {glyph:?} ({meaning}), which nothing draws"
            ));
        }
    }
    defects
}

/// How the legend's entries are laid out: columns of cells of one size.
pub(super) struct LegendLayout {
    pub(super) columns: u32,
    /// Each entry's cell: its width, and its height (a row per line of the longest label).
    pub(super) entry: (u32, u32),
}

pub(super) fn draw_legend(
    entries: &[Entry],
    labels: &[Vec<String>],
    area: &Area,
    layout: &LegendLayout,
) -> DrawResult {
    for (k, (entry, lines)) in entries.iter().zip(labels).enumerate() {
        let (row, column) = (k as u32 / layout.columns, k as u32 % layout.columns);
        let x = (20 + column * layout.entry.0) as i32;
        let y = (8 + row * layout.entry.1) as i32 + LEGEND_ROW as i32 / 2;
        let style = entry.colour.stroke_width(2);
        match entry.key {
            Key::Dashed => {
                for dash in [0, 12, 24] {
                    area.draw(&PathElement::new(
                        vec![(x + dash, y), (x + dash + 7, y)],
                        style,
                    ))?;
                }
            }
            Key::Series { marker: k, line } => {
                if line {
                    area.draw(&PathElement::new(vec![(x, y), (x + 32, y)], style))?;
                }
                area.draw(&(EmptyElement::at((x + 16, y)) + marker_element(k, entry.colour)))?;
            }
            Key::Glyph(Glyph::Cross) => {
                area.draw(&(EmptyElement::at((x + 16, y)) + cross(BLACK)))?;
            }
            Key::Glyph(Glyph::Ring) => {
                area.draw(&(EmptyElement::at((x + 16, y)) + ring(BLACK)))?;
            }
            Key::Glyph(Glyph::Square) => {
                area.draw(&(EmptyElement::at((x + 16, y)) + square(BLACK)))?;
            }
        }
        let left = Pos::new(HPos::Left, VPos::Center);
        for (j, line) in lines.iter().enumerate() {
            let text = Text::new(
                line.clone(),
                (x + LEGEND_KEY as i32, y + (j as u32 * LEGEND_ROW) as i32),
                TextStyle::from(font(LEGEND_PX)).pos(left),
            );
            area.draw(&text)?;
        }
    }
    Ok(())
}
