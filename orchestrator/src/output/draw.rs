//! Charts as SVG, through plotters: what a figure shows (panels of series, bands, guide lines
//! and notes) is decided in `figure`; this module only draws it.
//!
//! Sizes are for a page read at 100 %: a figure is at most `PAGE` px wide (the report's column),
//! several panels wrap two to a row so that each keeps at least 480 px, and every text is at
//! least 14 px. Series are told apart by colour and by marker shape, which survives grey print.
//!
//! Log axes are drawn in log₁₀ coordinates with ticks at decades (at 1, 2 and 5 when the data
//! span few decades, and at the data's own values when even those give fewer than three ticks),
//! so that linear and log axes share one chart type. The labels of one axis share one notation.

use crate::console::numbers_alike;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;

/// One SVG: a title, a subtitle (what all its series share), and panels under them.
pub struct Chart {
    pub title: String,
    pub subtitle: String,
    pub panels: Vec<Panel>,
    /// What each glyph the series draw means, for the legend (`× diverged`).
    pub glyphs: Vec<(Glyph, String)>,
    /// Lines under the legend saying what an axis's numbers stand for (`1: n=16 threads=1`).
    pub key: Vec<String>,
}

impl Chart {
    /// A chart of `panels` with no glyphs and no key.
    pub fn new(title: impl Into<String>, subtitle: impl Into<String>, panels: Vec<Panel>) -> Chart {
        Chart {
            title: title.into(),
            subtitle: subtitle.into(),
            panels,
            glyphs: Vec::new(),
            key: Vec::new(),
        }
    }

    /// Says what `glyph` means, once, when some series draws it (a legend entry of nothing
    /// drawn would be a defect: `lint`).
    pub fn explain(&mut self, glyph: Glyph, meaning: impl Into<String>) {
        let explained = self.glyphs.iter().any(|(g, _)| *g == glyph);
        if !explained && drawn_glyphs(self).contains(&glyph) {
            self.glyphs.push((glyph, meaning.into()));
        }
    }
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
    /// A scale that zooms in around a value c, to a resolution δ: v is drawn at
    /// sign(v − c)·log₁₀(1 + |v − c|/δ), so 0.9, 0.99, 0.999, 1, 1.001, 1.01 stand apart (a
    /// stability limit at dt = dt_stable, where everything interesting lies within 1 %).
    pub around: Option<(f64, f64)>,
}

/// A line of measured points, with an optional band (x, low, high) around it.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub band: Vec<(f64, f64, f64)>,
    /// Whether a line joins the points; without it they are markers only (verdicts per point).
    pub line: bool,
    /// Points drawn with a glyph of their own in the series' colour, which the chart explains
    /// (`Chart::glyphs`): a diverged run, a point timed on a busy machine.
    pub marks: Vec<((f64, f64), Glyph)>,
    /// Text written beside the series' last point, e.g. its fitted slope; the notes of a panel
    /// are moved apart so that they do not overlap, and left out when they cannot be.
    pub note: Option<String>,
}

impl Series {
    /// A line through `points`.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.into(),
            points,
            band: Vec::new(),
            line: true,
            marks: Vec::new(),
            note: None,
        }
    }

    /// Whether it draws anything: only then does it have a legend entry.
    fn draws(&self) -> bool {
        !self.points.is_empty() || !self.band.is_empty() || !self.marks.is_empty()
    }
}

/// A glyph over a point, in the colour of its series.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Glyph {
    /// ×: a run that diverged, or workers beyond the machine's cores.
    Cross,
    /// A ring around the marker: a point timed on a busy machine (`noisy`).
    Ring,
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
    /// A reference slope: the right triangle whose hypotenuse runs from `triangle[0]` to
    /// `triangle[1]`, with its right angle at `triangle[2]` under it; `slope` is written beside
    /// its vertical leg and 1 under its horizontal one.
    Slope {
        triangle: [(f64, f64); 3],
        slope: String,
    },
}

/// The widest figure: the report's column (70em of 16 px, less its padding).
const PAGE: u32 = 1040;
/// A figure of one panel.
const SINGLE: (u32, u32) = (720, 480);
/// Each panel of a figure of several: two to a row across the page, each at least 480 px wide.
const CELL: (u32, u32) = (PAGE / 2, 440);

/// Text sizes in SVG pixels at 100 %.
const TICK_PX: f64 = 14.0;
const LEGEND_PX: f64 = 14.0;
const NOTE_PX: f64 = 14.0;
const AXIS_PX: f64 = 15.0;
const SUBTITLE_PX: f64 = 15.0;
const CAPTION_PX: f64 = 16.0;
const TITLE_PX: f64 = 20.0;

/// The font of `px` SVG pixels: plotters writes a font of size s as `font-size = s / 1.24`.
fn font(px: f64) -> FontDesc<'static> {
    ("sans-serif", px * 1.24).into_font()
}

/// About how wide a text is drawn (an average sans-serif letter is 0.55 em).
fn text_width(text: &str, px: f64) -> u32 {
    (text.chars().count() as f64 * 0.55 * px).ceil() as u32
}

/// Fixed colours, in series order, so the same table gives the same picture: twelve that
/// stay apart on screen (Tableau 10, navy and teal), repeating only with another marker.
fn colour(index: usize) -> RGBColor {
    const PALETTE: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
        RGBColor(188, 189, 34),
        RGBColor(127, 127, 127),
        RGBColor(25, 25, 112),
        RGBColor(0, 128, 128),
    ];
    PALETTE[index % PALETTE.len()]
}

/// The marker of series `index`, as a polygon around the point in pixels: circle, square,
/// triangle, diamond, inverted triangle. Five shapes against twelve colours: no two of the
/// first sixty series look alike.
fn marker(index: usize) -> Vec<(i32, i32)> {
    match index % 5 {
        0 => (0..12)
            .map(|k| {
                let angle = f64::from(k) * std::f64::consts::PI / 6.0;
                (
                    (4.5 * angle.cos()).round() as i32,
                    (4.5 * angle.sin()).round() as i32,
                )
            })
            .collect(),
        1 => vec![(-4, -4), (4, -4), (4, 4), (-4, 4)],
        2 => vec![(0, -5), (5, 4), (-5, 4)],
        3 => vec![(0, -6), (5, 0), (0, 6), (-5, 0)],
        _ => vec![(0, 5), (5, -4), (-5, -4)],
    }
}

impl Axis {
    pub fn linear(label: impl Into<String>) -> Axis {
        Axis {
            label: label.into(),
            log: false,
            include: Vec::new(),
            whole: false,
            around: None,
        }
    }

    /// Linear, or zoomed in around `centre` (`Axis::around`) when most values crowd within 5 %
    /// of it: the resolution is their smallest distance from it.
    pub fn zooming(label: impl Into<String>, centre: f64, values: &[f64]) -> Axis {
        let distances: Vec<f64> = values
            .iter()
            .map(|v| (v - centre).abs())
            .filter(|d| d.is_finite() && *d > 0.0)
            .collect();
        let near = values
            .iter()
            .filter(|v| (*v - centre).abs() <= 0.05 * centre.abs())
            .count();
        let crowded = near * 2 > values.len() && distances.len() >= 2;
        let resolution = distances
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .max(1e-9);
        Axis {
            around: crowded.then_some((centre, resolution)),
            ..Axis::linear(label)
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
            log: lo > 0.0 && hi / lo >= 10.0,
            ..Axis::linear(label)
        }
    }

    /// Log when no value is negative and some are positive, however narrow their span: orders
    /// are read as slopes. A zero (an error exact to the last bit) has no place on it.
    pub fn log_if_positive(
        label: impl Into<String>,
        values: impl IntoIterator<Item = f64>,
    ) -> Axis {
        let (lo, hi) = span(values.into_iter().filter(|v| v.is_finite()));
        Axis {
            log: lo >= 0.0 && hi > 0.0,
            ..Axis::linear(label)
        }
    }

    fn to(&self, v: f64) -> f64 {
        match (self.log, self.around) {
            (_, Some((c, delta))) => (v - c).signum() * (1.0 + (v - c).abs() / delta).log10(),
            (true, None) => v.log10(),
            (false, None) => v,
        }
    }

    fn from(&self, t: f64) -> f64 {
        match (self.log, self.around) {
            (_, Some((c, delta))) => c + t.signum() * delta * (10f64.powf(t.abs()) - 1.0),
            (true, None) => 10f64.powf(t),
            (false, None) => t,
        }
    }

    /// The values it shows in drawing coordinates: finite, and positive on a log axis.
    fn shown(&self, values: impl Iterator<Item = f64>) -> Vec<f64> {
        values
            .chain(self.include.iter().copied())
            .filter(|v| v.is_finite() && (!self.log || *v > 0.0))
            .map(|v| self.to(v))
            .collect()
    }

    /// The axis's range in drawing coordinates, from the values it shows, padded.
    fn range(shown: &[f64]) -> (f64, f64) {
        let (lo, hi) = span(shown.iter().copied());
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
        (lo - pad, hi + pad)
    }

    /// Tick positions in drawing coordinates over the range, given the values measured.
    fn ticks(&self, (lo, hi): (f64, f64), shown: &[f64]) -> Vec<f64> {
        if self.around.is_some() {
            // The values measured, at most ten of them: on a zoomed scale round numbers are
            // sparse exactly where the data is dense.
            let mut own = shown.to_vec();
            own.sort_by(f64::total_cmp);
            own.dedup_by(|a, b| (*a - *b).abs() < 0.05);
            let every = own.len().div_ceil(10).max(1);
            return own
                .into_iter()
                .step_by(every)
                .filter(|t| (lo..=hi).contains(t))
                .collect();
        }
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
            let step = ((hi - lo) / 8.0).ceil() as i32;
            decades.filter(|k| k % step == 0).map(f64::from).collect()
        };
        ticks.retain(|t| (lo..=hi).contains(t));
        if ticks.len() < 3 {
            // Less than a factor 2.5 (h from 1/32 to 1/64): the values themselves, at most eight.
            let mut own = shown.to_vec();
            own.sort_by(f64::total_cmp);
            own.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            let every = own.len().div_ceil(8).max(1);
            let own: Vec<f64> = own.into_iter().step_by(every).collect();
            if own.len() > ticks.len() {
                return own;
            }
        }
        ticks
    }

    /// The ticks with their labels, in one notation. Ticks from 1 to 10⁵ and more, which
    /// `console::number` writes in full, are written in thousands, millions, …, the power
    /// going into the axis's label.
    fn ticked(&self, range: (f64, f64), shown: &[f64]) -> Ticked {
        let ticks = self.ticks(range, shown);
        let values: Vec<f64> = ticks.iter().map(|&t| self.from(t)).collect();
        let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let counts = values.iter().all(|v| *v == 0.0 || v.abs() >= 1.0);
        let in_full = largest >= 1e5 && counts;
        let power = match in_full {
            true => 3 * (largest.log10() / 3.0).floor() as i32,
            false => 0,
        };
        let scaled: Vec<f64> = values.iter().map(|v| v / 10f64.powi(power)).collect();
        Ticked {
            lo: range.0,
            hi: range.1,
            labels: numbers_alike(&scaled),
            ticks,
            power,
        }
    }
}

/// A linear coordinate with the ticks we choose (plotters' own f64 axis picks its ticks itself)
/// and their labels.
#[derive(Clone)]
struct Ticked {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
    labels: Vec<String>,
    /// The labels are the values over 10^power.
    power: i32,
}

impl Ticked {
    /// Ticks on a linear scale over [lo, hi] (a heat map's sides, a colour bar).
    fn linear(lo: f64, hi: f64) -> Ticked {
        Axis::linear("").ticked((lo, hi), &[])
    }

    /// The axis's description, with the power its labels leave out.
    fn describe(&self, label: &str) -> String {
        match self.power {
            0 => label.to_string(),
            power => format!("{label} (×1e{power})"),
        }
    }

    fn label(&self, t: f64) -> String {
        let at = self.ticks.iter().position(|&k| k == t);
        at.map(|k| self.labels[k].clone()).unwrap_or_default()
    }
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

/// Lines of at most `width` characters, broken at spaces; a longer word (a path) is broken
/// into pieces of `width`.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let width = width.max(8);
    let mut lines: Vec<String> = Vec::new();
    // `n = 64` is one word: a line never ends in `=` nor starts with one.
    let mut glued: Vec<String> = Vec::new();
    let mut pieces = text.split_whitespace().peekable();
    while let Some(word) = pieces.next() {
        match (word, glued.last_mut(), pieces.peek()) {
            ("=", Some(field), Some(value)) => {
                *field = format!("{field} = {value}");
                pieces.next();
            }
            _ => glued.push(word.to_string()),
        }
    }
    let words = glued.iter().flat_map(|word| {
        let chars: Vec<char> = word.chars().collect();
        chars
            .chunks(width)
            .map(|piece| piece.iter().collect::<String>())
            .collect::<Vec<_>>()
    });
    for word in words {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 1 + word.chars().count() <= width => {
                line.push(' ');
                line.push_str(&word);
            }
            _ => lines.push(word),
        }
    }
    lines
}

/// Positions for labels wanted at `wanted` (pixels, in any order): each as near its own as a
/// gap of at least `gap` between neighbours allows, kept within [lo, hi] while they fit.
fn spread(wanted: &[f64], gap: f64, (lo, hi): (f64, f64)) -> Vec<f64> {
    let mut order: Vec<usize> = (0..wanted.len()).collect();
    order.sort_by(|&a, &b| wanted[a].total_cmp(&wanted[b]));
    let mut placed = wanted.to_vec();
    let mut previous = f64::NEG_INFINITY;
    for &i in &order {
        placed[i] = wanted[i].max(lo).max(previous + gap);
        previous = placed[i];
    }
    let mut next = f64::INFINITY;
    for &i in order.iter().rev() {
        placed[i] = placed[i].min(hi).min(next - gap);
        next = placed[i];
    }
    placed
}

/// Whether `count` notes `gap` apart fit within [lo, hi].
fn notes_fit(count: usize, gap: f64, (lo, hi): (f64, f64)) -> bool {
    gap * count as f64 <= hi - lo + gap
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

const COLOUR_BAR: u32 = 120;

/// The cells coloured by value, and beside them a colour bar with its scale.
fn draw_heat_map(panel: &Panel, heat: &HeatMap, area: &Area, caption: bool) -> DrawResult {
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

/// An entry of the legend and what its key draws.
struct Entry<'a> {
    label: &'a str,
    colour: RGBColor,
    key: Key,
}

#[derive(Clone, Copy, PartialEq)]
enum Key {
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
fn legend(chart: &Chart) -> Vec<Entry<'_>> {
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
        if drawn_glyphs(chart).contains(glyph) {
            entries.push(Entry {
                label: meaning,
                colour: BLACK,
                key: Key::Glyph(*glyph),
            });
        }
    }
    entries
}

/// The glyphs some series of the chart draws.
fn drawn_glyphs(chart: &Chart) -> Vec<Glyph> {
    let mut glyphs: Vec<Glyph> = Vec::new();
    let marks = chart
        .panels
        .iter()
        .flat_map(|p| &p.series)
        .flat_map(|s| &s.marks);
    for (_, glyph) in marks {
        if !glyphs.contains(glyph) {
            glyphs.push(*glyph);
        }
    }
    glyphs
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
    let drawn = drawn_glyphs(chart);
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

const LEGEND_ROW: u32 = 24;
/// The line and marker before an entry's text.
const LEGEND_KEY: u32 = 48;

/// Where the panels go: how many to a row, and the size of each.
fn grid(panels: usize) -> (usize, (u32, u32)) {
    match panels {
        0 | 1 => (1, SINGLE),
        _ => (2, CELL),
    }
}

/// The chart as SVG text: the title and subtitle, the panels (wrapped two to a row), and one
/// legend, in the grid's spare cell when it has one the legend fits in, else under the panels.
pub fn render(chart: &Chart) -> Result<String, String> {
    if let Some(defect) = lint(chart).first() {
        return Err(format!("cannot draw `{}`: {defect}", chart.title));
    }
    let count = chart.panels.len().max(1);
    let (columns, cell) = grid(count);
    let rows = count.div_ceil(columns);
    let width = cell.0 * columns as u32;
    let title = wrap(
        &chart.title,
        ((width - 40) as f64 / (0.55 * TITLE_PX)) as usize,
    );
    let subtitle = wrap(
        &chart.subtitle,
        ((width - 40) as f64 / (0.55 * SUBTITLE_PX)) as usize,
    );
    let header = 14 + 28 * title.len() as u32 + 22 * subtitle.len() as u32;

    let entries = legend(chart);
    // A label longer than the figure is wide wraps onto lines of its own.
    let label_room = ((width - LEGEND_KEY - 44) as f64 / (0.55 * LEGEND_PX)) as usize;
    let labels: Vec<Vec<String>> = entries.iter().map(|e| wrap(e.label, label_room)).collect();
    let lines_of = |k: usize| labels[k].len().max(1) as u32;
    let entry_width = labels
        .iter()
        .map(|lines| {
            let widest = lines
                .iter()
                .map(|l| text_width(l, LEGEND_PX))
                .max()
                .unwrap_or(0);
            LEGEND_KEY + widest + 24
        })
        .max()
        .unwrap_or(0);
    let tallest = (0..entries.len()).map(lines_of).max().unwrap_or(1);
    let entry_height = LEGEND_ROW * tallest;
    let spare = !count.is_multiple_of(columns)
        && entry_width <= cell.0
        && (entries.len() as u32 + 1) * entry_height <= cell.1;
    let legend_columns = (width / entry_width.max(1)).max(1);
    let legend_height = match spare || entries.is_empty() {
        true => 0,
        false => (entries.len() as u32).div_ceil(legend_columns) * entry_height + 16,
    };
    let key_lines: Vec<String> = chart
        .key
        .iter()
        .flat_map(|line| wrap(line, ((width - 40) as f64 / (0.55 * LEGEND_PX)) as usize))
        .collect();
    let key_height = match key_lines.is_empty() {
        true => 0,
        false => key_lines.len() as u32 * LEGEND_ROW + 12,
    };
    let height = header + cell.1 * rows as u32 + legend_height + key_height;

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        let failed = |e: &dyn std::fmt::Display| format!("cannot draw `{}`: {e}", chart.title);
        root.fill(&WHITE).map_err(|e| failed(&e))?;
        let centred = Pos::new(HPos::Center, VPos::Top);
        let lines = title
            .iter()
            .map(|l| (l, TITLE_PX, 28))
            .chain(subtitle.iter().map(|l| (l, SUBTITLE_PX, 22)));
        let mut y = 10;
        for (line, px, step) in lines {
            let text = Text::new(
                line.clone(),
                (width as i32 / 2, y),
                TextStyle::from(font(px)).pos(centred),
            );
            root.draw(&text).map_err(|e| failed(&e))?;
            y += step;
        }
        let (_, body) = root.split_vertically(header);
        let (plots, key) = body.split_vertically(cell.1 * rows as u32);
        let (key, below) = key.split_vertically(legend_height.max(1));
        let areas = plots.split_evenly((rows, columns));
        let captions = chart.panels.len() > 1;
        for (panel, area) in chart.panels.iter().zip(&areas) {
            draw_panel(panel, area, captions).map_err(|e| failed(&e))?;
        }
        let (key, key_columns) = match spare {
            true => (&areas[count], 1),
            false => (&key, legend_columns),
        };
        let layout = LegendLayout {
            columns: key_columns,
            entry: (entry_width, entry_height),
        };
        draw_legend(&entries, &labels, key, &layout).map_err(|e| failed(&e))?;
        for (k, line) in key_lines.iter().enumerate() {
            let text = Text::new(
                line.clone(),
                (20, 6 + (k as u32 * LEGEND_ROW) as i32),
                TextStyle::from(font(LEGEND_PX)).pos(Pos::new(HPos::Left, VPos::Top)),
            );
            below.draw(&text).map_err(|e| failed(&e))?;
        }
        root.present().map_err(|e| failed(&e))?;
    }
    Ok(svg)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;
type DrawResult = Result<(), DrawingAreaErrorKind<std::io::Error>>;

/// How the legend's entries are laid out: columns of cells of one size.
struct LegendLayout {
    columns: u32,
    /// Each entry's cell: its width, and its height (a row per line of the longest label).
    entry: (u32, u32),
}

fn draw_legend(
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

/// Series `k`'s marker, hollow: where two series meet at one point both stay visible.
fn marker_element(k: usize, colour: RGBColor) -> PathElement<(i32, i32)> {
    let mut outline = marker(k);
    outline.push(outline[0]);
    PathElement::new(outline, colour.stroke_width(2))
}

/// `Glyph::Cross` over a point.
fn cross(colour: RGBColor) -> Cross<(i32, i32), i32> {
    Cross::new((0, 0), 6, colour.stroke_width(2))
}

/// `Glyph::Ring` around a point's marker.
fn ring(colour: RGBColor) -> Circle<(i32, i32), i32> {
    Circle::new((0, 0), 9, colour.stroke_width(1))
}

/// Every x (`pick` 0) or y (`pick` 1) a panel's series and guides draw.
fn coordinates(panel: &Panel, pick: fn(&(f64, f64)) -> f64, bands: bool) -> Vec<f64> {
    let series = panel.series.iter().flat_map(|s| {
        let band = s.band.iter().flat_map(move |b| match bands {
            true => vec![b.1, b.2],
            false => vec![b.0],
        });
        let marks = s.marks.iter().map(|(p, _)| p);
        s.points.iter().chain(marks).map(pick).chain(band)
    });
    let guides = panel.guides.iter().flat_map(|g| match g {
        Guide::Dashed { points, .. } => points.iter().map(pick).collect::<Vec<_>>(),
        Guide::Vertical { x, .. } => match bands {
            true => Vec::new(),
            false => vec![*x],
        },
        Guide::Slope { triangle, .. } => triangle.iter().map(pick).collect(),
    });
    series.chain(guides).collect()
}

fn draw_panel(panel: &Panel, area: &Area, caption: bool) -> DrawResult {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(axis: &Axis, range: (f64, f64), shown: &[f64]) -> Vec<String> {
        axis.ticked(range, shown).labels
    }

    #[test]
    fn ticks_fall_on_round_numbers_in_one_notation_per_axis() {
        assert_eq!(
            linear_ticks(0.0, 1.05),
            [0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let counts = Axis::linear("").counting();
        assert_eq!(counts.ticks((0.9, 2.1), &[]), [1.0, 2.0]);
        let log = Axis {
            log: true,
            ..Axis::linear("")
        };
        // Not `1e-4` beside `0.01`: every label of the axis in the notation one of them needs.
        assert_eq!(
            labels(&log, (-6.2, -1.9), &[]),
            ["1e-6", "1e-5", "1e-4", "1e-3", "1e-2"]
        );
        assert_eq!(labels(&log, (-0.1, 0.75), &[]), ["1", "2", "5"]);
        assert_eq!(labels(&log, (-0.66, 0.75), &[]), ["0.5", "1", "2", "5"]);
        // Not 100000000000: large values in a power of ten the axis's label states.
        let rates = log.ticked((7.9, 11.1), &[]);
        assert_eq!(rates.labels, ["0.1", "1", "10", "100"]);
        assert_eq!(rates.describe("updates per s"), "updates per s (×1e9)");
        // An axis with fractions too keeps its values.
        let blowup = log.ticked((-2.1, 6.1), &[]);
        assert_eq!((blowup.labels[0].as_str(), blowup.power), ("0.01", 0));
        // h from 1/64 to 1/16 spans less than a decade: 1, 2, 5 give two ticks, the grids three.
        let h: Vec<f64> = [64.0f64, 32.0, 16.0].iter().map(|n| -n.log10()).collect();
        let range = Axis::range(&h);
        assert_eq!(labels(&log, range, &h), ["0.01563", "0.03125", "0.0625"]);
    }

    /// Values crowding around 1 (a stability limit) are drawn on a scale that zooms in there:
    /// 0.999, 1 and 1.001 stand apart, each a tick of its own.
    #[test]
    fn an_axis_zooms_in_where_the_values_crowd() {
        let cfl = [0.5, 0.9, 0.99, 0.999, 1.0, 1.001, 1.01, 1.2];
        let axis = Axis::zooming("dt / dt_stable", 1.0, &cfl);
        let (centre, resolution) = axis.around.expect("zoomed");
        assert!(
            centre == 1.0 && (resolution - 1e-3).abs() < 1e-12,
            "{resolution}"
        );
        let shown = axis.shown(cfl.iter().copied());
        // Neighbours at least a quarter of a decade apart, where a linear axis over 0.5–1.2
        // puts 0.999, 1 and 1.001 within a pixel of each other.
        for pair in shown.windows(2).filter(|p| p[0] != p[1]) {
            assert!((pair[1] - pair[0]).abs() > 0.25, "{shown:?}");
        }
        for v in cfl {
            assert!((axis.from(axis.to(v)) - v).abs() < 1e-12, "{v}");
        }
        let labels = axis.ticked(Axis::range(&shown), &shown).labels;
        for label in ["0.999", "1", "1.001", "1.01"] {
            assert!(labels.iter().any(|l| l == label), "{label}: {labels:?}");
        }
        let spread = Axis::zooming("n", 1.0, &[16.0, 32.0, 64.0]);
        assert_eq!(spread.around, None, "values far from 1 keep a linear axis");
    }

    #[test]
    fn notes_are_moved_apart_by_the_gap_within_the_panel() {
        let placed = spread(&[103.0, 100.0, 300.0], 18.0, (0.0, 400.0));
        assert_eq!(
            placed,
            [118.0, 100.0, 300.0],
            "the lower moves, the apart one stays"
        );
        // At the bottom there is no room below: they stack upwards.
        let placed = spread(&[398.0, 399.0, 400.0], 18.0, (0.0, 400.0));
        assert_eq!(placed, [364.0, 382.0, 400.0]);
    }

    #[test]
    fn series_stay_apart_by_colour_and_marker_past_twelve() {
        let colours: Vec<RGBColor> = (0..12).map(colour).collect();
        for (k, c) in colours.iter().enumerate() {
            assert!(!colours[..k].contains(c), "colour {k} repeats");
        }
        let looks: Vec<(RGBColor, Vec<(i32, i32)>)> =
            (0..60).map(|k| (colour(k), marker(k))).collect();
        for (k, look) in looks.iter().enumerate() {
            assert!(
                !looks[..k].contains(look),
                "series {k} looks like an earlier one"
            );
        }
    }

    #[test]
    fn long_titles_wrap_at_spaces_and_long_words_in_pieces() {
        assert_eq!(
            wrap("Strong scaling over threads: nonlocal", 16),
            ["Strong scaling", "over threads:", "nonlocal"]
        );
        assert!(wrap("", 10).is_empty());
        assert_eq!(
            wrap("error at 2D n = 64 against h", 12),
            ["error at 2D", "n = 64", "against h"]
        );
        let path = format!("against /{}", "x".repeat(40));
        let lines = wrap(&path, 16);
        assert!(lines.iter().all(|l| l.chars().count() <= 16), "{lines:?}");
        assert_eq!(lines.concat().replace(' ', ""), path.replace(' ', ""));
    }

    #[test]
    fn notes_that_cannot_stand_apart_are_not_placed_outside() {
        // Twenty notes of 18 px in 100 px: `spread` leaves some outside; the panel drops them.
        let placed = spread(&[50.0; 20], 18.0, (0.0, 100.0));
        assert!(placed.iter().any(|p| *p < 0.0));
        assert!(
            !notes_fit(20, 18.0, (0.0, 100.0)),
            "so draw_panel leaves every note out"
        );
        assert!(notes_fit(6, 18.0, (0.0, 100.0)));
    }
}
