//! A heat map panel with its colour bar.

use super::chart::*;
use super::scale::*;
use super::style::DrawResult;
use super::style::*;
use plotters::prelude::*;

impl HeatMap {
    /// The values the colours span: [min, max], or [−a, a] with a = max |v| when diverging.
    pub(super) fn scale(&self) -> (f64, f64) {
        let (lo, hi) = span(self.values.iter().copied().filter(|v| v.is_finite()));
        let (lo, hi) = match self.diverging {
            true => {
                let a = lo.abs().max(hi.abs());
                (-a, a)
            }
            false => (lo, hi),
        };
        match hi > lo {
            true => (lo, hi),
            false => (lo - 0.5, lo + 0.5), // a constant field, or none finite
        }
    }

    pub(super) fn colour(&self, v: f64, (lo, hi): (f64, f64)) -> RGBColor {
        // Viridis (sequential, readable in grey) and a blue–white–red map, at five stops each.
        const SEQUENTIAL: [(u8, u8, u8); 5] = [
            (68, 1, 84),
            (59, 82, 139),
            (33, 145, 140),
            (94, 201, 98),
            (253, 231, 37),
        ];
        const DIVERGING: [(u8, u8, u8); 5] = [
            (59, 76, 192),
            (141, 176, 254),
            (247, 247, 247),
            (244, 154, 123),
            (180, 4, 38),
        ];
        if !v.is_finite() {
            return RGBColor(128, 128, 128);
        }
        let stops = if self.diverging {
            &DIVERGING
        } else {
            &SEQUENTIAL
        };
        interpolate(stops, (v - lo) / (hi - lo))
    }
}

/// The cells coloured by value, and beside them a colour bar with its scale.
pub(super) fn draw_heat_map(
    panel: &Panel,
    heat: &HeatMap,
    area: &Area,
    caption: bool,
) -> DrawResult {
    let (width, _) = area.dim_in_pixel();
    let (cells, bar) = area.split_horizontally(width.saturating_sub(COLOUR_BAR));
    let (lo, hi) = (heat.lower, heat.upper);
    let mut builder = ChartBuilder::on(&cells);
    if caption {
        builder.caption(&panel.title, font(CAPTION_PX));
    }
    let side = Ticked::linear(lo, hi);
    let mut chart = builder
        .margin(14)
        .x_label_area_size(56)
        .y_label_area_size(70)
        .build_cartesian_2d(side.clone(), side.clone())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(side.describe(&panel.x.label))
        .y_desc(side.describe(&panel.y.label))
        .x_label_formatter(&|t| side.label(*t))
        .y_label_formatter(&|t| side.label(*t))
        .label_style(font(TICK_PX))
        .axis_desc_style(font(AXIS_PX))
        .draw()?;
    let scale = heat.scale();
    let (dx, dy) = ((hi - lo) / heat.nx as f64, (hi - lo) / heat.ny as f64);
    chart.draw_series(heat.values.iter().enumerate().map(|(i, &v)| {
        let (ix, iy) = ((i % heat.nx) as f64, (i / heat.nx) as f64);
        let corners = [
            (lo + ix * dx, lo + iy * dy),
            (lo + (ix + 1.0) * dx, lo + (iy + 1.0) * dy),
        ];
        Rectangle::new(corners, heat.colour(v, scale).filled())
    }))?;

    let mut builder = ChartBuilder::on(&bar);
    builder
        .margin_top(if caption { 48 } else { 14 })
        .margin_bottom(70)
        .margin_right(8)
        .set_label_area_size(LabelAreaPosition::Right, 80);
    let levels = Ticked::linear(scale.0, scale.1);
    let mut key = builder.build_cartesian_2d(0.0..1.0, levels.clone())?;
    let level_label = |t: &f64| levels.label(*t);
    let mut mesh = key.configure_mesh();
    mesh.disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&level_label)
        .label_style(font(TICK_PX))
        .axis_desc_style(font(AXIS_PX));
    if levels.power != 0 {
        mesh.y_desc(levels.describe("").trim_start());
    }
    mesh.draw()?;
    const LEVELS: usize = 64;
    let step = (scale.1 - scale.0) / LEVELS as f64;
    key.draw_series((0..LEVELS).map(|k| {
        let v = scale.0 + k as f64 * step;
        let colour = heat.colour(v + 0.5 * step, scale);
        Rectangle::new([(0.0, v), (1.0, v + step)], colour.filled())
    }))?;
    Ok(())
}
