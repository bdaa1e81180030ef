//! What a chart is made of, as `figure` builds it: panels of series, axes, glyphs and guides.

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
        if !explained && self.drawn_glyphs().contains(&glyph) {
            self.glyphs.push((glyph, meaning.into()));
        }
    }

    /// The glyphs some series of the chart draws.
    pub(super) fn drawn_glyphs(&self) -> Vec<Glyph> {
        let mut glyphs: Vec<Glyph> = Vec::new();
        let marks = self
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
    pub(super) fn draws(&self) -> bool {
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
    /// A square around the marker: an answer (the cheapest resolution meeting an error target).
    Square,
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
