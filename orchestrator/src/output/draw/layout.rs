//! Where things go: panels on the page, long words wrapped, notes spread so none overlaps.

use super::chart::*;
use super::style::*;

/// Lines of at most `width` characters, broken at spaces; a longer word (a path) is broken
/// into pieces of `width`.
pub(super) fn wrap(text: &str, width: usize) -> Vec<String> {
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
pub(super) fn spread(wanted: &[f64], gap: f64, (lo, hi): (f64, f64)) -> Vec<f64> {
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
pub(super) fn notes_fit(count: usize, gap: f64, (lo, hi): (f64, f64)) -> bool {
    gap * count as f64 <= hi - lo + gap
}

/// Where the panels go: how many to a row, and the size of each.
pub(super) fn grid(panels: usize) -> (usize, (u32, u32)) {
    match panels {
        0 | 1 => (1, SINGLE),
        _ => (2, CELL),
    }
}

/// Every x (`pick` 0) or y (`pick` 1) a panel's series and guides draw.
pub(super) fn coordinates(panel: &Panel, pick: fn(&(f64, f64)) -> f64, bands: bool) -> Vec<f64> {
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
