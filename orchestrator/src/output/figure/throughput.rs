//! Throughput: bond updates per second of the operator backends against m, one panel per n, with the crossover where the FFT overtakes the stencil.

use super::series::*;
use crate::output::draw::{Axis, Guide, Panel, Series};
use crate::store::table::Row;
use schema::record::columns;

/// One panel per grid size n: a series per backend, and the crossover where the FFT overtakes
/// the stencil.
pub(super) fn throughput(rows: &[&Row], series_columns: &[String], x: &str, y: &str) -> Vec<Panel> {
    let mut sizes: Vec<f64> = rows.iter().filter_map(|r| r.number("case.n")).collect();
    sizes.sort_by(f64::total_cmp);
    sizes.dedup();
    sizes
        .iter()
        .map(|&n| {
            let of_size: Vec<&Row> = rows
                .iter()
                .copied()
                .filter(|r| r.number("case.n") == Some(n))
                .collect();
            let mut groups = group(&of_size, series_columns);
            shared_by_all(&mut groups);
            let lines: Vec<Series> = groups
                .iter()
                .map(|g| series(g.label(), g.points(x, y)))
                .collect();
            let backend_points = |name: &str| {
                groups
                    .iter()
                    .find(|g| {
                        g.rows
                            .iter()
                            .all(|r| r.text(columns::BACKEND) == Some(name))
                    })
                    .map(|g| g.points(x, y))
            };
            let guides = match (backend_points("stencil"), backend_points("fft")) {
                (Some(stencil), Some(fft)) => crossover(&stencil, &fft)
                    .map(|m| Guide::Vertical {
                        label: format!("n = {n}: FFT faster from m ≈ {m:.1}"),
                        x: m,
                    })
                    .into_iter()
                    .collect(),
                _ => Vec::new(),
            };
            Panel {
                title: format!("n = {n}"),
                x: Axis::fitting(describe(x, &groups), all(lines.iter(), |p| p.0)),
                y: Axis::fitting(describe(y, &groups), all(lines.iter(), |p| p.1)),
                series: lines,
                guides,
                heat: None,
            }
        })
        .collect()
}

/// The m where `fast_for_large` (throughput against m) first overtakes `fast_for_small`,
/// interpolated linearly in log m on the log of their ratio between the m's both measured.
fn crossover(fast_for_small: &[(f64, f64)], fast_for_large: &[(f64, f64)]) -> Option<f64> {
    let advantage: Vec<(f64, f64)> = fast_for_small
        .iter()
        .filter_map(|&(m, small)| {
            let &(_, large) = fast_for_large.iter().find(|p| p.0 == m)?;
            Some((m.ln(), (large / small).ln()))
        })
        .collect();
    advantage.windows(2).find_map(|pair| {
        let [(m0, a0), (m1, a1)] = [pair[0], pair[1]];
        (a0 < 0.0 && a1 >= 0.0).then(|| (m0 + (m1 - m0) * a0 / (a0 - a1)).exp())
    })
}

#[cfg(test)]
mod tests {
    use super::crossover;

    #[test]
    fn crossover_interpolates_in_log_m_where_the_ratio_changes_sign() {
        // The FFT's throughput grows like m² while the stencil's stays flat: they meet at m = 4.
        let stencil = [(1.0, 16.0), (2.0, 16.0), (8.0, 16.0)];
        let fft = [(1.0, 1.0), (2.0, 4.0), (8.0, 64.0)];
        let m = crossover(&stencil, &fft).expect("they cross");
        assert!((m - 4.0).abs() < 1e-12, "{m}");
        // Never overtaken: no crossover.
        assert_eq!(
            crossover(
                &fft[..2],
                &stencil[..2]
                    .iter()
                    .map(|&(m, _)| (m, 0.5))
                    .collect::<Vec<_>>()
            ),
            None
        );
    }
}
