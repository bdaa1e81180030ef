//! The scaling model (`analysis::scaling_model`) fitted to the study's own runs: strong scaling
//! of a 16384² grid from 1 to 4096 ranks, weak scaling at 1024² nodes per rank, each on
//! InfiniBand HDR and on 10 GbE, and the model against what the runs here measured and sent.

use super::series::*;
use crate::analysis::scaling_model::{
    fit, half_efficiency, predict, Network, Rates, SolverPath, HDR, TEN_GBE,
};
use crate::output::draw::{Axis, Guide, Panel, Series};
use crate::store::table::Row;
use schema::record::columns;
use serde_json::Value;

/// The strong-scaling grid and the weak-scaling grid per rank.
const STRONG_N: usize = 16384;
const WEAK_N: usize = 1024;

/// Ranks 1, 4, 16, … 4096: powers of four, so weak scaling keeps a square grid.
fn ranks() -> Vec<usize> {
    (0..=6).map(|k| 1 << (2 * k)).collect()
}

/// Long because its two panels share the fitted rates, the rank counts and their axes, declared
/// side by side as the figure shows them.
pub(super) fn scaling_model(rows: &[&Row]) -> Result<(Vec<Panel>, String), String> {
    let fitted = fit(rows);
    if fitted.is_empty() {
        return Err("no path has both a one-rank, one-thread run and a run over ranks with its traffic recorded; run each path on 1 and on 2 ranks".into());
    }
    let ranks = ranks();
    let counts: Vec<f64> = ranks.iter().map(|&p| p as f64).collect();
    let (mut time, mut strong, mut weak) = (Vec::new(), Vec::new(), Vec::new());
    let mut stops = Vec::new();
    for rates in &fitted {
        for network in [HDR, TEN_GBE] {
            let label = format!("{}, {}", rates.path.label(), network.name);
            let at = |n: usize, p: usize| predict(rates, n, p, &network).total_s();
            let one = at(STRONG_N, 1);
            time.push(series(
                label.clone(),
                counts
                    .iter()
                    .zip(&ranks)
                    .map(|(&c, &p)| (c, at(STRONG_N, p)))
                    .collect(),
            ));
            strong.push(series(
                label.clone(),
                counts
                    .iter()
                    .zip(&ranks)
                    .map(|(&c, &p)| (c, one / (c * at(STRONG_N, p))))
                    .collect(),
            ));
            let base = at(WEAK_N, 1);
            weak.push(series(
                label,
                counts
                    .iter()
                    .zip(&ranks)
                    .map(|(&c, &p)| (c, base / at(WEAK_N * (p as f64).sqrt() as usize, p)))
                    .collect(),
            ));
            let all: Vec<usize> = (0..=12).map(|k| 1 << k).collect();
            stops.push(
                half_efficiency(rates, STRONG_N, &all, &network)
                    .map_or("> 4096".to_string(), |p| p.to_string()),
            );
        }
    }
    let efficiency = |label: &str| {
        let mut axis = Axis::linear(label);
        axis.include = vec![0.0, 1.0];
        axis
    };
    let ranks_axis = || Axis::fitting("ranks P (one core each)", counts.iter().copied()).counting();
    let ideal = |points: Vec<(f64, f64)>| Guide::Dashed {
        label: Some("ideal".into()),
        of: None,
        points,
    };
    let (first, last) = (counts[0], counts[counts.len() - 1]);
    let (checks, at_two, counts) = validation(rows, &fitted);
    let panels = vec![
        Panel {
            title: format!("strong scaling, n = {STRONG_N}: predicted time per step"),
            x: ranks_axis(),
            y: Axis::fitting(
                "seconds per step (steady CG: per iteration)",
                all(time.iter(), |p| p.1),
            ),
            series: time,
            guides: Vec::new(),
            heat: None,
        },
        Panel {
            title: "strong scaling: predicted efficiency".into(),
            x: ranks_axis(),
            y: efficiency("T(1) / (P T(P))"),
            series: strong,
            guides: vec![ideal(vec![(first, 1.0), (last, 1.0)])],
            heat: None,
        },
        Panel {
            title: format!("weak scaling, {WEAK_N}² nodes per rank: predicted efficiency"),
            x: ranks_axis(),
            y: efficiency("T(1) / T(P), n = 1024 √P"),
            series: weak,
            guides: vec![ideal(vec![(first, 1.0), (last, 1.0)])],
            heat: None,
        },
        Panel {
            title: "the model against the runs here".into(),
            x: Axis::fitting(
                "ranks of the run",
                checks.iter().flat_map(|s| s.points.iter().map(|p| p.0)),
            )
            .counting(),
            y: Axis::fitting("model / measured", all(checks.iter(), |p| p.1)),
            series: checks,
            guides: vec![Guide::Dashed {
                label: Some("exact".into()),
                of: None,
                points: vec![(1.0, 1.0), (8.0, 1.0)],
            }],
            heat: None,
        },
    ];
    let paths = fitted.iter().map(|r| r.path.label());
    let stops: Vec<String> = paths
        .zip(stops.chunks(2))
        .map(|(path, at)| format!("{path} {} / {}", at[0], at[1]))
        .collect();
    let at_two: Vec<String> = at_two
        .iter()
        .map(|(path, ratio)| format!("{} {ratio:.2}", path.label()))
        .collect();
    let subtitle = format!(
        "50% strong efficiency at P = (HDR / 10 GbE): {}. Model / measured step time at 2 ranks: {}; ghosts and all-to-all bytes within {:.1}% of the runs' at 2–8 ranks",
        stops.join(", "),
        at_two.join(", "),
        100.0 * counts,
    );
    Ok((panels, subtitle))
}

/// This machine's ranks share memory: its network's bandwidth is what the two-rank
/// Crank–Nicolson run moved per second of communication, its latency what is left of the
/// two-rank Euler run's communication per message.
fn this_machine(rows: &[&Row], fitted: &[Rates]) -> Network {
    let two = |path: SolverPath| {
        rows.iter().find(|r| {
            SolverPath::of_row(r) == Some(path)
                && r.number(columns::RANKS) == Some(2.0)
                && r.number("comm_s_median").is_some()
        })
    };
    let sent_per_step = |r: &Row| -> Option<f64> {
        let bytes = r.number(columns::TRAFFIC_HALO_BYTES)?
            + r.number(columns::ALL_TO_ALL_BYTES).unwrap_or(0.0);
        Some(bytes / 2.0 / r.number(columns::STEPS_DONE)?)
    };
    let bandwidth = two(SolverPath::CrankNicolson)
        .and_then(|r| Some(sent_per_step(r)? / r.number("comm_s_median")?))
        .filter(|b| b.is_finite() && *b > 0.0)
        .unwrap_or(5e9);
    let latency = two(SolverPath::EulerStencil)
        .zip(fitted.iter().find(|r| r.path == SolverPath::EulerStencil))
        .and_then(|(r, rates)| {
            let comm = r.number("comm_s_median")? - sent_per_step(r)? / bandwidth;
            Some(comm / (rates.halos + 2.0 * rates.reductions))
        })
        .filter(|a| a.is_finite() && *a > 0.0)
        .unwrap_or(1e-6);
    Network {
        name: "this machine",
        latency_s: latency,
        bandwidth,
    }
}

/// Model / measured for each run of the study over ranks: the step time of those on 2 ranks (the
/// one-rank runs are what the model is fitted to; more ranks oversubscribe this machine), and
/// the ghosts and all-to-all bytes of every one; with each path's time ratio at 2 ranks and the
/// worst relative error of the counts.
fn validation(rows: &[&Row], fitted: &[Rates]) -> (Vec<Series>, Vec<(SolverPath, f64)>, f64) {
    let here = this_machine(rows, fitted);
    let (mut times, mut ghosts, mut moved) = (Vec::new(), Vec::new(), Vec::new());
    let mut at_two = Vec::new();
    for row in rows {
        let Some(rates) = SolverPath::of_row(row).and_then(|p| fitted.iter().find(|r| r.path == p))
        else {
            continue;
        };
        let (Some(n), Some(p)) = (row.number("case.n"), row.number(columns::RANKS)) else {
            continue;
        };
        if p < 2.0 {
            continue;
        }
        let prediction = predict(rates, n as usize, p as usize, &here);
        let oversubscribed = row.get(columns::OVERSUBSCRIBED) == Some(&Value::Bool(true));
        if let Some(step) = row
            .number("step_s_median")
            .filter(|_| !oversubscribed && p == 2.0)
        {
            times.push((p, prediction.total_s() / step));
            at_two.push((rates.path, prediction.total_s() / step));
        }
        if let Some(halo) = row.number(columns::HALO_NODES) {
            ghosts.push((p, prediction.ghosts / halo));
        }
        let calls = row.number(columns::ALL_TO_ALLS).filter(|c| *c > 0.0);
        if let Some((bytes, calls)) = row.number(columns::ALL_TO_ALL_BYTES).zip(calls) {
            moved.push((p, prediction.all_to_all_bytes / (bytes / calls)));
        }
    }
    let worst =
        |points: &[(f64, f64)]| points.iter().map(|p| (p.1 - 1.0).abs()).fold(0.0, f64::max);
    let counts = worst(&ghosts).max(worst(&moved));
    at_two.sort_by_key(|(path, _)| *path);
    let checks = [
        ("step time (2 ranks)", times),
        ("ghost values per exchange", ghosts),
        ("bytes per all-to-all", moved),
    ]
    .into_iter()
    .filter(|(_, points)| !points.is_empty())
    .map(|(label, points)| series(label.to_string(), points))
    .collect();
    (checks, at_two, counts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn row(cells: Value) -> Row {
        Row::of_cells(cells)
    }

    /// Two Euler runs (1 and 2 ranks) are enough for that path's curves; the validation
    /// compares the two-rank run's recorded ghosts with the formula's.
    #[test]
    fn the_figure_fits_a_path_from_its_runs_and_checks_its_ghosts() {
        let base = json!({"case.method": "nonlocal", "case.dim": 2, "case.integrator": "forward_euler",
            "backend": "stencil", "case.n": 1024, "m": 4, "case.threads": 1, "steps_done": 10});
        let mut one = base.clone();
        one.as_object_mut().unwrap().extend(
            json!({"ranks": 1, "step_s_median": 0.005})
                .as_object()
                .unwrap()
                .clone(),
        );
        let mut two = base;
        two.as_object_mut().unwrap().extend(
            json!({"ranks": 2, "step_s_median": 0.0026, "comm_s_median": 1e-4,
            "halo_nodes": 8192, "traffic.halo_exchanges": 11, "traffic.halo_bytes": 11 * 8192 * 8,
            "traffic.reductions": 12, "traffic.all_to_alls": 0})
            .as_object()
            .unwrap()
            .clone(),
        );
        let rows = [row(one), row(two)];
        let rows: Vec<&Row> = rows.iter().collect();
        let (panels, subtitle) = scaling_model(&rows).unwrap();
        assert_eq!(panels.len(), 4);
        assert_eq!(panels[0].series.len(), 2, "one path on two networks");
        let ghosts = panels[3]
            .series
            .iter()
            .find(|s| s.label.starts_with("ghost"))
            .unwrap();
        assert_eq!(
            ghosts.points,
            vec![(2.0, 1.0)],
            "2 m n ghosts for two slabs"
        );
        // The two-rank run measured what the model says here, exactly: its latency and
        // bandwidth are fitted to the runs, and the halo is the whole of its communication.
        assert!(
            subtitle.contains("at P = (HDR / 10 GbE): Euler, stencil ")
                && subtitle.contains("2 ranks: Euler, stencil 1.00")
                && subtitle.contains("within 0.0%"),
            "{subtitle}"
        );
    }
}
