//! Charts as SVG, through plotters: what a figure shows (panels of series, bands, guide lines
//! and notes) is decided in `figure`; this module only draws it.
//!
//! Log axes are drawn in log₁₀ coordinates with ticks at decades (and at 2 and 5 when the
//! data span few decades), so that linear and log axes share one chart type.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;
use std::ops::Range;

/// One SVG: panels side by side under a title.
pub struct Chart {
    pub title: String,
    pub panels: Vec<Panel>,
}

pub struct Panel {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
    pub guides: Vec<Guide>,
    /// Drawn instead of the series and guides, with its colour bar.
    pub heat: Option<HeatMap>,
}

/// Values on nx × ny equal cells tiling [lower, upper]², row by row from the bottom.
pub struct HeatMap {
    pub nx: usize,
    pub ny: usize,
    pub lower: f64,
    pub upper: f64,
    pub values: Vec<f64>,
    /// Colours symmetric about 0 (blue below, white at 0, red above), for signed values such as
    /// errors; else a sequential map from the smallest value to the largest.
    pub diverging: bool,
}

pub struct Axis {
    pub label: String,
    pub log: bool,
    /// Values the axis must show even without data there (e.g. 0 and 1 of an efficiency).
    pub include: Vec<f64>,
    /// Counts (workers): ticks on whole numbers only.
    pub whole: bool,
}

/// A line of measured points, with an optional band (x, low, high) around it.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub band: Vec<(f64, f64, f64)>,
    /// Points drawn as crosses, e.g. diverged runs.
    pub crosses: Vec<(f64, f64)>,
    /// Text written beside the series' last point, e.g. its fitted slope.
    pub note: Option<String>,
}

/// What the data is read against.
pub enum Guide {
    /// A dashed line through points, in the colour of series `of` (black if none).
    Dashed {
        label: Option<String>,
        of: Option<usize>,
        points: Vec<(f64, f64)>,
    },
    /// A vertical line across the panel.
    Vertical { label: String, x: f64 },
}

const PANEL: (u32, u32) = (640, 480);

/// Fixed colours, in series order, so the same table gives the same picture.
fn colour(index: usize) -> RGBColor {
    const PALETTE: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    PALETTE[index % PALETTE.len()]
}

impl Axis {
    pub fn linear(label: impl Into<String>) -> Axis {
        Axis {
            label: label.into(),
            log: false,
            include: Vec::new(),
            whole: false,
        }
    }

    /// The same axis, ticked on whole numbers.
    pub fn counting(self) -> Axis {
        Axis {
            whole: true,
            ..self
        }
    }

    /// Log when the values are positive and span a decade or more.
    pub fn fitting(label: impl Into<String>, values: impl IntoIterator<Item = f64>) -> Axis {
        let (lo, hi) = span(values.into_iter().filter(|v| v.is_finite()));
        Axis {
            label: label.into(),
            log: lo > 0.0 && hi / lo >= 10.0,
            include: Vec::new(),
            whole: false,
        }
    }

    fn to(&self, v: f64) -> f64 {
        if self.log {
            v.log10()
        } else {
            v
        }
    }

    /// The axis's range in drawing coordinates, from the values it shows, padded.
    fn range(&self, values: impl Iterator<Item = f64>) -> (f64, f64) {
        let shown = values
            .chain(self.include.iter().copied())
            .filter(|v| v.is_finite() && (!self.log || *v > 0.0))
            .map(|v| self.to(v));
        let (lo, hi) = span(shown);
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
        (lo - pad, hi + pad)
    }

    /// Tick positions in drawing coordinates.
    fn ticks(&self, (lo, hi): (f64, f64)) -> Vec<f64> {
        if !self.log {
            let mut ticks = linear_ticks(lo, hi);
            if self.whole {
                ticks.retain(|t| t.fract() == 0.0);
            }
            return ticks;
        }
        let decades = (lo.floor() as i32)..=(hi.ceil() as i32);
        let mut ticks: Vec<f64> = if hi - lo <= 2.5 {
            decades
                .flat_map(|k| [1.0f64, 2.0, 5.0].map(|m| f64::from(k) + m.log10()))
                .collect()
        } else {
            let step = ((hi - lo) / 6.0).ceil() as i32;
            decades.filter(|k| k % step == 0).map(f64::from).collect()
        };
        ticks.retain(|t| (lo..=hi).contains(t));
        ticks
    }

    fn tick_label(&self, t: f64) -> String {
        if self.log {
            short_number(10f64.powf(t))
        } else {
            short_number(t)
        }
    }
}

/// A linear coordinate with the ticks we choose (plotters' own f64 axis picks its ticks itself).
struct Ticked {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl Ranged for Ticked {
    type ValueType = f64;
    type FormatOption = DefaultFormatting;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let fraction = (value - self.lo) / (self.hi - self.lo);
        limit.0 + (f64::from(limit.1 - limit.0) * fraction + 1e-3).floor() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, _hint: Hint) -> Vec<f64> {
        self.ticks.clone()
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

/// (min, max) of the values; (∞, −∞) when there are none.
pub fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

/// About six ticks at 1, 2 or 5 times a power of ten.
fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Short and exact enough for a tick: 0.001, 2.5, 1e-6, 3e5.
fn short_number(v: f64) -> String {
    let magnitude = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&magnitude) {
        let text = format!("{v:.1e}");
        text.replace(".0e", "e")
    } else {
        let text = format!("{v:.4}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Linear interpolation between colour stops at equal spacing over [0, 1].
fn interpolate(stops: &[(u8, u8, u8)], t: f64) -> RGBColor {
    let at = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let k = (at.floor() as usize).min(stops.len() - 2);
    let f = at - k as f64;
    let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    let (a, b) = (stops[k], stops[k + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

impl HeatMap {
    /// The values the colours span: [min, max], or [−a, a] with a = max |v| when diverging.
    fn scale(&self) -> (f64, f64) {
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

    fn colour(&self, v: f64, (lo, hi): (f64, f64)) -> RGBColor {
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

const COLOUR_BAR: u32 = 110;

/// The cells coloured by value, and beside them a colour bar with its scale.
fn draw_heat_map(panel: &Panel, heat: &HeatMap, area: &Area, caption: bool) -> DrawResult {
    let (width, _) = area.dim_in_pixel();
    let (cells, bar) = area.split_horizontally(width.saturating_sub(COLOUR_BAR));
    let (lo, hi) = (heat.lower, heat.upper);
    let axis = || Ticked {
        lo,
        hi,
        ticks: linear_ticks(lo, hi),
    };
    let mut builder = ChartBuilder::on(&cells);
    if caption {
        builder.caption(&panel.title, ("sans-serif", 17));
    }
    let mut chart = builder
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(axis(), axis())?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(&panel.x.label)
        .y_desc(&panel.y.label)
        .x_label_formatter(&|t| short_number(*t))
        .y_label_formatter(&|t| short_number(*t))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
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
        .margin_top(if caption { 44 } else { 14 })
        .margin_bottom(64)
        .margin_right(8)
        .set_label_area_size(LabelAreaPosition::Right, 70);
    let mut key = builder.build_cartesian_2d(
        0.0..1.0,
        Ticked {
            lo: scale.0,
            hi: scale.1,
            ticks: linear_ticks(scale.0, scale.1),
        },
    )?;
    key.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&|t| short_number(*t))
        .label_style(("sans-serif", 13))
        .draw()?;
    const LEVELS: usize = 64;
    let step = (scale.1 - scale.0) / LEVELS as f64;
    key.draw_series((0..LEVELS).map(|k| {
        let v = scale.0 + k as f64 * step;
        let colour = heat.colour(v + 0.5 * step, scale);
        Rectangle::new([(0.0, v), (1.0, v + step)], colour.filled())
    }))?;
    Ok(())
}

/// An entry of the legend under the panels.
struct Entry<'a> {
    label: &'a str,
    colour: RGBColor,
    dashed: bool,
}

/// The legend: every labelled series and guide of the panels, once each, in order.
fn legend(chart: &Chart) -> Vec<Entry<'_>> {
    let mut entries: Vec<Entry> = Vec::new();
    for panel in &chart.panels {
        let series = panel.series.iter().enumerate().map(|(k, s)| Entry {
            label: &s.label,
            colour: colour(k),
            dashed: false,
        });
        let guides = panel.guides.iter().filter_map(|g| match g {
            Guide::Dashed { label, of, .. } => Some(Entry {
                label: label.as_deref()?,
                colour: of.map_or(BLACK, colour),
                dashed: true,
            }),
            Guide::Vertical { label, .. } => Some(Entry {
                label,
                colour: BLACK,
                dashed: true,
            }),
        });
        for entry in series.chain(guides) {
            if !entries.iter().any(|e| e.label == entry.label) {
                entries.push(entry);
            }
        }
    }
    entries
}

const LEGEND_ROW: u32 = 22;
const LEGEND_COLUMN: u32 = 480;

/// The chart as SVG text: the title, the panels side by side, and one legend under them.
pub fn render(chart: &Chart) -> Result<String, String> {
    let mut svg = String::new();
    // Wide enough for the title too (about 10 px a character at its size).
    let title_width = 10 * chart.title.chars().count() as u32 + 40;
    let width = (PANEL.0 * chart.panels.len().max(1) as u32).max(title_width);
    let entries = legend(chart);
    let columns = (width / LEGEND_COLUMN).max(1);
    let rows = (entries.len() as u32).div_ceil(columns);
    let height = PANEL.1 + rows * LEGEND_ROW + 10;
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        let failed = |e: &dyn std::fmt::Display| format!("cannot draw `{}`: {e}", chart.title);
        root.fill(&WHITE).map_err(|e| failed(&e))?;
        let root = root
            .titled(&chart.title, ("sans-serif", 20))
            .map_err(|e| failed(&e))?;
        let (plots, key) = root.split_vertically(PANEL.1 - 30);
        let areas = plots.split_evenly((1, chart.panels.len().max(1)));
        let captions = chart.panels.len() > 1;
        for (panel, area) in chart.panels.iter().zip(&areas) {
            draw_panel(panel, area, captions).map_err(|e| failed(&e))?;
        }
        draw_legend(&entries, &key, columns).map_err(|e| failed(&e))?;
        root.present().map_err(|e| failed(&e))?;
    }
    Ok(svg)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;
type DrawResult = Result<(), DrawingAreaErrorKind<std::io::Error>>;

fn draw_legend(entries: &[Entry], area: &Area, columns: u32) -> DrawResult {
    for (k, entry) in entries.iter().enumerate() {
        let (row, column) = (k as u32 / columns, k as u32 % columns);
        let x = (20 + column * LEGEND_COLUMN) as i32;
        let y = (8 + row * LEGEND_ROW) as i32 + LEGEND_ROW as i32 / 2;
        let style = entry.colour.stroke_width(2);
        if entry.dashed {
            for dash in [0, 12, 24] {
                area.draw(&PathElement::new(
                    vec![(x + dash, y), (x + dash + 7, y)],
                    style,
                ))?;
            }
        } else {
            area.draw(&PathElement::new(vec![(x, y), (x + 30, y)], style))?;
            area.draw(&Circle::new((x + 15, y), 3, entry.colour.filled()))?;
        }
        let font = ("sans-serif", 14).into_font();
        area.draw(&Text::new(entry.label.to_string(), (x + 40, y - 7), font))?;
    }
    Ok(())
}

fn draw_panel(panel: &Panel, area: &Area, caption: bool) -> DrawResult {
    if let Some(heat) = &panel.heat {
        return draw_heat_map(panel, heat, area, caption);
    }
    let xs = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter().chain(&s.crosses).map(|p| p.0))
        .chain(panel.guides.iter().flat_map(|g| match g {
            Guide::Dashed { points, .. } => points.iter().map(|p| p.0).collect::<Vec<_>>(),
            Guide::Vertical { x, .. } => vec![*x],
        }));
    let ys = panel
        .series
        .iter()
        .flat_map(|s| {
            let band = s.band.iter().flat_map(|b| [b.1, b.2]);
            s.points
                .iter()
                .chain(&s.crosses)
                .map(|p| p.1)
                .chain(band)
                .collect::<Vec<_>>()
        })
        .chain(panel.guides.iter().flat_map(|g| match g {
            Guide::Dashed { points, .. } => points.iter().map(|p| p.1).collect::<Vec<_>>(),
            Guide::Vertical { .. } => Vec::new(),
        }));
    let (x, y) = (&panel.x, &panel.y);
    let (x_range, y_range) = (x.range(xs), y.range(ys));
    let mut builder = ChartBuilder::on(area);
    if caption {
        builder.caption(&panel.title, ("sans-serif", 17));
    }
    let mut chart = builder
        .margin(14)
        .x_label_area_size(50)
        .y_label_area_size(78)
        .build_cartesian_2d(
            Ticked {
                lo: x_range.0,
                hi: x_range.1,
                ticks: x.ticks(x_range),
            },
            Ticked {
                lo: y_range.0,
                hi: y_range.1,
                ticks: y.ticks(y_range),
            },
        )?;
    chart
        .configure_mesh()
        .x_desc(&x.label)
        .y_desc(&y.label)
        .x_label_formatter(&|t| x.tick_label(*t))
        .y_label_formatter(&|t| y.tick_label(*t))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    let at = |(px, py): (f64, f64)| (x.to(px), y.to(py));
    let visible = |p: &(f64, f64)| {
        let (px, py) = at(*p);
        px.is_finite() && py.is_finite()
    };
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
        chart.draw_series(LineSeries::new(points.clone(), style.stroke_width(2)))?;
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 3, style.filled())))?;
        let crosses = series.crosses.iter().filter(|p| visible(p));
        chart.draw_series(crosses.map(|p| Cross::new(at(*p), 6, style.stroke_width(2))))?;
        if let (Some(note), Some(last)) = (&series.note, points.last()) {
            chart.draw_series(std::iter::once(Text::new(
                note.clone(),
                *last,
                ("sans-serif", 14).into_font().color(&style),
            )))?;
        }
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
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_fall_on_round_numbers() {
        assert_eq!(
            linear_ticks(0.0, 1.05),
            [0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let counts = Axis::linear("").counting();
        let workers: Vec<f64> = counts.ticks((0.9, 2.1));
        assert_eq!(workers, [1.0, 2.0]);
        let log = Axis {
            log: true,
            ..Axis::linear("")
        };
        let decades: Vec<String> = log
            .ticks((-6.2, -1.9))
            .iter()
            .map(|t| log.tick_label(*t))
            .collect();
        assert_eq!(decades, ["1e-6", "1e-5", "1e-4", "0.001", "0.01"]);
        let narrow: Vec<String> = log
            .ticks((-0.1, 0.75))
            .iter()
            .map(|t| log.tick_label(*t))
            .collect();
        assert_eq!(narrow, ["1", "2", "5"]);
        let decade: Vec<String> = log
            .ticks((-0.66, 0.75))
            .iter()
            .map(|t| log.tick_label(*t))
            .collect();
        assert_eq!(decade, ["0.5", "1", "2", "5"]);
    }
}
