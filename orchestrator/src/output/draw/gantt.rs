//! A Gantt chart as SVG: one row per lane, spans coloured by category, time along x.
//!
//! A study's run can hold 10⁵ spans on a figure 900 px wide, most narrower than a pixel: each
//! row is drawn pixel by pixel, each pixel in the category that took most of its time, and
//! equal neighbours merged into one rectangle. So the file stays small and what is drawn is
//! what took the time at the figure's resolution.

use super::style::{font, text_width, AXIS_PX, PAGE, TICK_PX, TITLE_PX};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// A span of `category` on `row`, in seconds from the chart's start.
pub struct Bar {
    pub row: usize,
    pub from: f64,
    pub to: f64,
    pub category: usize,
}

pub struct Gantt {
    pub title: String,
    pub rows: Vec<String>,
    /// Names and colours; a category of no bar is left out of the legend.
    pub categories: Vec<(String, RGBColor)>,
    pub bars: Vec<Bar>,
    /// The chart's length in seconds.
    pub length: f64,
}

const ROW_PX: u32 = 22;
const LEGEND_ROW_PX: u32 = 24;

/// The chart as SVG text.
pub fn render(gantt: &Gantt) -> Result<String, String> {
    let label_px = gantt
        .rows
        .iter()
        .map(|r| text_width(r, TICK_PX))
        .max()
        .unwrap_or(0)
        + 16;
    let used: Vec<usize> = (0..gantt.categories.len())
        .filter(|&c| gantt.bars.iter().any(|b| b.category == c))
        .collect();
    let entry_px = used
        .iter()
        .map(|&c| text_width(&gantt.categories[c].0, TICK_PX) + 40)
        .max()
        .unwrap_or(1);
    let per_line = (PAGE / entry_px).max(1) as usize;
    let legend_px = used.len().div_ceil(per_line) as u32 * LEGEND_ROW_PX;
    let (top, bottom) = (48, 56 + legend_px);
    let height = top + ROW_PX * gantt.rows.len() as u32 + bottom;
    let plot = (label_px, PAGE - 24);
    let pixels = (plot.1 - plot.0) as usize;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (PAGE, height)).into_drawing_area();
        let failed = |e: DrawingAreaErrorKind<_>| format!("cannot draw the timeline: {e}");
        root.fill(&WHITE).map_err(failed)?;
        root.draw_text(
            &gantt.title,
            &font(TITLE_PX).into_text_style(&root),
            (16, 12),
        )
        .map_err(failed)?;
        let seconds_per_pixel = gantt.length.max(1e-9) / pixels as f64;
        for (row, label) in gantt.rows.iter().enumerate() {
            let y = (top + ROW_PX * row as u32) as i32;
            let style = font(TICK_PX)
                .into_text_style(&root)
                .pos(Pos::new(HPos::Right, VPos::Center));
            root.draw_text(label, &style, (plot.0 as i32 - 8, y + ROW_PX as i32 / 2))
                .map_err(failed)?;
            // Runs of equal pixels: (first, past the last, category).
            let mut runs: Vec<(usize, usize, usize)> = Vec::new();
            for (pixel, category) in dominant(gantt, row, pixels, seconds_per_pixel) {
                match runs.last_mut() {
                    Some(run) if run.2 == category => run.1 = pixel + 1,
                    _ => runs.push((pixel, pixel + 1, category)),
                }
            }
            for (from, to, category) in runs.into_iter().filter(|r| r.2 != usize::MAX) {
                let x = |p: usize| plot.0 as i32 + p as i32;
                let colour = gantt.categories[category].1;
                root.draw(&Rectangle::new(
                    [(x(from), y + 2), (x(to), y + ROW_PX as i32 - 2)],
                    colour.filled(),
                ))
                .map_err(failed)?;
            }
        }
        let axis_y = (top + ROW_PX * gantt.rows.len() as u32) as i32 + 4;
        draw_time_axis(&root, gantt.length, plot, axis_y, seconds_per_pixel).map_err(failed)?;
        for (k, &c) in used.iter().enumerate() {
            let (name, colour) = &gantt.categories[c];
            let x = 16 + (k % per_line) as i32 * entry_px as i32;
            let y = axis_y + 52 + (k / per_line) as i32 * LEGEND_ROW_PX as i32;
            root.draw(&Rectangle::new([(x, y), (x + 24, y + 14)], colour.filled()))
                .map_err(failed)?;
            root.draw_text(name, &font(TICK_PX).into_text_style(&root), (x + 30, y))
                .map_err(failed)?;
        }
        root.present().map_err(failed)?;
    }
    Ok(svg)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// The time axis under the rows at `axis_y`: a line, ticks at round seconds, its label.
fn draw_time_axis(
    root: &Area,
    length: f64,
    plot: (u32, u32),
    axis_y: i32,
    seconds_per_pixel: f64,
) -> Result<(), DrawingAreaErrorKind<std::io::Error>> {
    root.draw(&PathElement::new(
        [(plot.0 as i32, axis_y), (plot.1 as i32, axis_y)],
        BLACK,
    ))?;
    let step = tick_step(length);
    let mut t = 0.0;
    while t <= length + 1e-9 {
        let x = plot.0 as i32 + (t / seconds_per_pixel).round() as i32;
        root.draw(&PathElement::new([(x, axis_y), (x, axis_y + 5)], BLACK))?;
        let style = font(TICK_PX)
            .into_text_style(root)
            .pos(Pos::new(HPos::Center, VPos::Top));
        root.draw_text(&format!("{t}"), &style, (x, axis_y + 7))?;
        t += step;
    }
    let style = font(AXIS_PX)
        .into_text_style(root)
        .pos(Pos::new(HPos::Center, VPos::Top));
    let middle = ((plot.0 + plot.1) / 2) as i32;
    root.draw_text(
        "seconds since the run's first case",
        &style,
        (middle, axis_y + 26),
    )
}

/// Each pixel of `row` with the category that took most of its time (`usize::MAX`: none).
fn dominant(
    gantt: &Gantt,
    row: usize,
    pixels: usize,
    seconds_per_pixel: f64,
) -> impl Iterator<Item = (usize, usize)> {
    let categories = gantt.categories.len();
    let mut time = vec![0.0; pixels * categories];
    for bar in gantt.bars.iter().filter(|b| b.row == row && b.to > b.from) {
        let (a, b) = (bar.from / seconds_per_pixel, bar.to / seconds_per_pixel);
        let first = (a.floor().max(0.0) as usize).min(pixels - 1);
        let last = (b.ceil() as usize).clamp(first + 1, pixels);
        for pixel in first..last {
            let overlap = b.min(pixel as f64 + 1.0) - a.max(pixel as f64);
            time[pixel * categories + bar.category] += overlap.max(0.0);
        }
    }
    (0..pixels).map(move |pixel| {
        let slice = &time[pixel * categories..(pixel + 1) * categories];
        let best = (0..categories).max_by(|&i, &j| slice[i].total_cmp(&slice[j]));
        let category = best.filter(|&c| slice[c] > 0.0).unwrap_or(usize::MAX);
        (pixel, category)
    })
}

/// A round step between time ticks giving about 5 to 10 ticks.
fn tick_step(length: f64) -> f64 {
    let rough = (length / 6.0).max(1e-9);
    let decade = 10f64.powf(rough.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&s| length / s <= 10.0)
        .unwrap_or(10.0 * decade)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_pixel_takes_the_category_of_most_of_its_time() {
        let bar = |from, to, category| Bar {
            row: 0,
            from,
            to,
            category,
        };
        let gantt = Gantt {
            title: "t".into(),
            rows: vec!["a".into()],
            categories: vec![("x".into(), RED), ("y".into(), BLUE)],
            bars: vec![bar(0.0, 1.3, 0), bar(1.3, 2.0, 1), bar(3.5, 4.0, 1)],
            length: 4.0,
        };
        let pixels: Vec<usize> = dominant(&gantt, 0, 4, 1.0).map(|p| p.1).collect();
        assert_eq!(pixels, vec![0, 1, usize::MAX, 1]);
        assert_eq!(tick_step(54.0), 10.0);
        assert_eq!(tick_step(3.0), 0.5);
        let svg = render(&gantt).unwrap();
        assert!(
            svg.contains("<svg") && svg.matches("<rect").count() >= 4,
            "{svg}"
        );
    }
}
