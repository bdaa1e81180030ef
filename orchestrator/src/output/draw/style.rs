//! Sizes, fonts, colours and marks: a figure's look, the same in every figure.

use plotters::prelude::*;

/// The widest figure: the report's column (70em of 16 px, less its padding).
pub(super) const PAGE: u32 = 1040;

/// A figure of one panel.
pub(super) const SINGLE: (u32, u32) = (720, 480);

/// Each panel of a figure of several: two to a row across the page, each at least 480 px wide.
pub(super) const CELL: (u32, u32) = (PAGE / 2, 440);

/// Text sizes in SVG pixels at 100 %.
pub(super) const TICK_PX: f64 = 14.0;

pub(super) const LEGEND_PX: f64 = 14.0;

pub(super) const NOTE_PX: f64 = 14.0;

pub(super) const AXIS_PX: f64 = 15.0;

pub(super) const SUBTITLE_PX: f64 = 15.0;

pub(super) const CAPTION_PX: f64 = 16.0;

pub(super) const TITLE_PX: f64 = 20.0;

/// The font of `px` SVG pixels: plotters writes a font of size s as `font-size = s / 1.24`.
pub(super) fn font(px: f64) -> FontDesc<'static> {
    ("sans-serif", px * 1.24).into_font()
}

/// About how wide a text is drawn (an average sans-serif letter is 0.55 em).
pub(super) fn text_width(text: &str, px: f64) -> u32 {
    (text.chars().count() as f64 * 0.55 * px).ceil() as u32
}

/// Fixed colours, in series order, so the same table gives the same picture: twelve that
/// stay apart on screen (Tableau 10, navy and teal), repeating only with another marker.
pub(super) fn colour(index: usize) -> RGBColor {
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
pub(super) fn marker(index: usize) -> Vec<(i32, i32)> {
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

/// Linear interpolation between colour stops at equal spacing over [0, 1].
pub(super) fn interpolate(stops: &[(u8, u8, u8)], t: f64) -> RGBColor {
    let at = t.clamp(0.0, 1.0) * (stops.len() - 1) as f64;
    let k = (at.floor() as usize).min(stops.len() - 2);
    let f = at - k as f64;
    let mix = |a: u8, b: u8| (a as f64 + f * (b as f64 - a as f64)).round() as u8;
    let (a, b) = (stops[k], stops[k + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

pub(super) const COLOUR_BAR: u32 = 120;

pub(super) const LEGEND_ROW: u32 = 24;

/// The line and marker before an entry's text.
pub(super) const LEGEND_KEY: u32 = 48;

pub(super) type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

pub(super) type DrawResult = Result<(), DrawingAreaErrorKind<std::io::Error>>;

/// Series `k`'s marker, hollow: where two series meet at one point both stay visible.
pub(super) fn marker_element(k: usize, colour: RGBColor) -> PathElement<(i32, i32)> {
    let mut outline = marker(k);
    outline.push(outline[0]);
    PathElement::new(outline, colour.stroke_width(2))
}

/// `Glyph::Cross` over a point.
pub(super) fn cross(colour: RGBColor) -> Cross<(i32, i32), i32> {
    Cross::new((0, 0), 6, colour.stroke_width(2))
}

/// `Glyph::Square` around a point's marker.
pub(super) fn square(colour: RGBColor) -> Rectangle<(i32, i32)> {
    Rectangle::new([(-10, -10), (10, 10)], colour.stroke_width(2))
}

/// `Glyph::Ring` around a point's marker.
pub(super) fn ring(colour: RGBColor) -> Circle<(i32, i32), i32> {
    Circle::new((0, 0), 9, colour.stroke_width(1))
}
