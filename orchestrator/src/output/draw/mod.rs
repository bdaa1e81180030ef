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

mod chart;
pub mod gantt;
mod heat_map;
mod layout;
mod legend;
mod panel;
mod scale;
mod style;

pub use chart::*;
pub use legend::lint;
pub use scale::span;

use layout::{grid, wrap};
use legend::{draw_legend, legend, LegendLayout};
use panel::draw_panel;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use style::*;

/// The chart as SVG text: the title and subtitle, the panels (wrapped two to a row), and one
/// legend, in the grid's spare cell when it has one the legend fits in, else under the panels.
///
/// Long because plotters lays out a drawing area once: the title, the panels' grid and the legend's
/// cell are split from it in turn.
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

#[cfg(test)]
mod tests {
    use super::layout::{notes_fit, spread};
    use super::scale::linear_ticks;
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
