//! One panel of series, bands, guides and notes.

use super::chart::*;
use super::heat_map::*;
use super::layout::*;
use super::style::DrawResult;
use super::style::*;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Long because plotters draws a panel through one chart context, which its parts (mesh, bands,
/// series, guides, notes) borrow in turn, in the order they overlap.
pub(super) fn draw_panel(panel: &Panel, area: &Area, caption: bool) -> DrawResult {
    if let Some(heat) = &panel.heat {
        return draw_heat_map(panel, heat, area, caption);
    }
    let (x, y) = (&panel.x, &panel.y);
    let xs = x.shown(coordinates(panel, |p| p.0, false).into_iter());
    let ys = y.shown(coordinates(panel, |p| p.1, true).into_iter());
    let (x_range, y_range) = (Axis::range(&xs), Axis::range(&ys));
    let notes: Vec<(usize, &str)> = panel
        .series
        .iter()
        .enumerate()
        .filter_map(|(k, s)| Some((k, s.note.as_deref()?)))
        .collect();
    // At most a third of the panel: a longer note is left out (its series' label says it too).
    let (panel_width, _) = area.dim_in_pixel();
    let notes: Vec<(usize, &str)> = notes
        .into_iter()
        .filter(|(_, n)| text_width(n, NOTE_PX) + 12 <= panel_width / 3)
        .collect();
    let note_room = notes.iter().map(|(_, n)| text_width(n, NOTE_PX) + 12).max();
    let mut builder = ChartBuilder::on(area);
    if caption {
        builder.caption(&panel.title, font(CAPTION_PX));
    }
    // Ticks at the data's own values come from the series, not from where guides are drawn.
    let measured = |pick: fn(&(f64, f64)) -> f64, axis: &Axis| {
        axis.shown(panel.series.iter().flat_map(|s| s.points.iter().map(pick)))
    };
    let x_ticks = x.ticked(x_range, &measured(|p| p.0, x));
    let y_ticks = y.ticked(y_range, &measured(|p| p.1, y));
    let mut chart = builder
        .margin(14)
        .margin_right(14 + note_room.unwrap_or(0))
        .x_label_area_size(56)
        .y_label_area_size(90)
        .build_cartesian_2d(x_ticks.clone(), y_ticks.clone())?;
    chart
        .configure_mesh()
        .x_desc(x_ticks.describe(&x.label))
        .y_desc(y_ticks.describe(&y.label))
        .x_label_formatter(&|t| x_ticks.label(*t))
        .y_label_formatter(&|t| y_ticks.label(*t))
        .label_style(font(TICK_PX))
        .axis_desc_style(font(AXIS_PX))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let at = |(px, py): (f64, f64)| (x.to(px), y.to(py));
    let visible = |p: &(f64, f64)| {
        let (px, py) = at(*p);
        px.is_finite() && py.is_finite()
    };
    let mut last_points = Vec::new();
    for (k, series) in panel.series.iter().enumerate() {
        let style = colour(k);
        let band: Vec<(f64, f64)> = series
            .band
            .iter()
            .map(|b| at((b.0, b.2)))
            .chain(series.band.iter().rev().map(|b| at((b.0, b.1))))
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        if band.len() > 2 {
            chart.draw_series(std::iter::once(Polygon::new(band, style.mix(0.2).filled())))?;
        }
        let points: Vec<(f64, f64)> = series
            .points
            .iter()
            .filter(|p| visible(p))
            .map(|p| at(*p))
            .collect();
        if series.line {
            chart.draw_series(LineSeries::new(points.clone(), style.stroke_width(2)))?;
        }
        chart.draw_series(
            points
                .iter()
                .map(|p| EmptyElement::at(*p) + marker_element(k, style)),
        )?;
        let marked = |glyph: Glyph| {
            series
                .marks
                .iter()
                .filter(move |(p, g)| *g == glyph && visible(p))
                .map(|(p, _)| at(*p))
        };
        chart.draw_series(marked(Glyph::Cross).map(|p| EmptyElement::at(p) + cross(style)))?;
        chart.draw_series(marked(Glyph::Ring).map(|p| EmptyElement::at(p) + ring(style)))?;
        chart.draw_series(marked(Glyph::Square).map(|p| EmptyElement::at(p) + square(style)))?;
        last_points.push(points.last().copied());
    }
    // The notes beside the last points, stacked apart where they would overlap.
    let placed: Vec<(usize, &str, (f64, f64))> = notes
        .iter()
        .filter_map(|&(k, note)| Some((k, note, last_points[k]?)))
        .collect();
    let wanted: Vec<f64> = placed
        .iter()
        .map(|(_, _, p)| f64::from(chart.backend_coord(p).1))
        .collect();
    let (_, rows) = chart.plotting_area().get_pixel_range();
    let bounds = (f64::from(rows.start) + 8.0, f64::from(rows.end) - 8.0);
    // Notes that cannot all stand apart within the plot are left out, not drawn past its edge.
    let gap = NOTE_PX + 4.0;
    let stacked = spread(&wanted, gap, bounds);
    let placed = match notes_fit(placed.len(), gap, bounds) {
        true => placed,
        false => Vec::new(),
    };
    for ((&(k, note, point), wanted), stacked) in placed.iter().zip(&wanted).zip(&stacked) {
        let offset = (10, (stacked - wanted).round() as i32);
        let style = font(NOTE_PX)
            .color(&colour(k))
            .pos(Pos::new(HPos::Left, VPos::Center));
        let text = Text::new(note.to_string(), offset, style);
        chart.draw_series(std::iter::once(EmptyElement::at(point) + text))?;
    }
    for guide in &panel.guides {
        match guide {
            Guide::Dashed { of, points, .. } => {
                let style = of.map_or(BLACK, colour);
                let points: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|p| visible(p))
                    .map(|p| at(*p))
                    .collect();
                chart.draw_series(DashedLineSeries::new(points, 6, 4, style.stroke_width(1)))?;
            }
            Guide::Vertical { x: vx, .. } => {
                let line = vec![(x.to(*vx), y_range.0), (x.to(*vx), y_range.1)];
                chart.draw_series(DashedLineSeries::new(line, 6, 4, BLACK.stroke_width(1)))?;
            }
            Guide::Slope { triangle, slope } => {
                let [start, end, corner] = triangle.map(at);
                let outline = vec![start, end, corner, start];
                chart.draw_series(std::iter::once(PathElement::new(outline, BLACK)))?;
                // The vertical leg joins the corner to the hypotenuse's end above it.
                let top = if start.0 == corner.0 { start } else { end };
                let across = if start.0 == corner.0 { end } else { start };
                let beside = match corner.0 > across.0 {
                    true => (6, Pos::new(HPos::Left, VPos::Center)),
                    false => (-6, Pos::new(HPos::Right, VPos::Center)),
                };
                let rise = EmptyElement::at((corner.0, 0.5 * (corner.1 + top.1)))
                    + Text::new(
                        slope.clone(),
                        (beside.0, 0),
                        TextStyle::from(font(NOTE_PX)).pos(beside.1),
                    );
                let run = EmptyElement::at((0.5 * (corner.0 + across.0), corner.1))
                    + Text::new(
                        "1",
                        (0, 4),
                        TextStyle::from(font(NOTE_PX)).pos(Pos::new(HPos::Center, VPos::Top)),
                    );
                chart.draw_series(std::iter::once(rise))?;
                chart.draw_series(std::iter::once(run))?;
            }
        }
    }
    Ok(())
}
