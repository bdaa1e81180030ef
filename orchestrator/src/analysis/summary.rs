//! The summary table: one row per point, its repeats' timings reduced to median, min, max and
//! interquartile range, and the derived columns of scaling and convergence studies.
//!
//! - Timings are the record's `*_s` fields, over the repeats that ran (ok or diverged).
//! - `workers` = threads × ranks. Along a scaling series (points differing only in workers),
//!   the point with the fewest workers p₀ is the baseline (`baseline_workers`): speedup
//!   S = T(p₀)/T(p) of the median `solve_s`, efficiency S·p₀/p, and the Karp–Flatt serial
//!   fraction (1/S − 1/q)/(1 − 1/q) with q = p/p₀ (absent at the baseline, where it is 0/0).
//!   A series of one point, or whose baseline is not ok, has none of these.
//! - `bond_updates_per_s` = bonds × steps done / median `solve_s`.
//! - Along a refinement series, ordered by h, the observed order between each point and the
//!   next coarser one is ln(e_coarse/e)/ln(h_coarse/h), from the actual h of both.
//!
//! Derived values come only from points whose every repeat is `ok`.

use crate::statistics::quantile;
use crate::store::table::Row;
use crate::store::{shared, Shared};
use rayon::prelude::*;
use schema::record::columns;
use schema::record::{Status, TIMINGS};
use serde_json::{json, Value};
use std::collections::{HashMap, HashSet};
use std::sync::OnceLock;

/// The results the summary's overview shows where the study has them: what most questions
/// read first.
pub const HEADLINE_RESULTS: &[&str] = &[
    columns::STATUS,
    "solve_s_median",
    "solve_s_iqr",
    columns::ERROR_L2_NORM,
    "order_l2",
    "speedup",
    "efficiency",
];

/// The status of a summary row whose repeats ended differently.
const MIXED: &str = "mixed";

/// The errors whose observed orders are derived, and the order columns' names (`coupled_1d`'s
/// two models each have their own).
const ORDERS: [(&str, &str); 4] = [
    (columns::ERROR_L2_NORM, "order_l2"),
    (columns::ERROR_MAX, "order_max"),
    ("coupling.error_nonlocal", "order_nonlocal"),
    ("coupling.error_local", "order_local"),
];

/// Bonds × steps done / median `solve_s`: the throughput of a nonlocal operator.
pub const BOND_UPDATES_PER_S: &str = "bond_updates_per_s";

/// The columns the summary adds to a run's: labels, counts, the timings' statistics, and what
/// scaling and refinement series derive.
const DERIVED: &[&str] = &[
    "point",
    "branch",
    "refinement_series",
    "scaling_series",
    "repeats",
    "build",
    "workers",
    "parallelism",
    "noisy_repeats",
    BOND_UPDATES_PER_S,
    "baseline_workers",
    "speedup",
    "efficiency",
    "karp_flatt",
];

/// The statistics each timing `T_s` becomes (`T_s_median`, …).
const STATISTICS: [&str; 4] = ["median", "min", "max", "iqr"];

/// The columns of `timing`'s statistics (`solve_s_median`, …), named once for every row.
fn statistics_of(timing: &str) -> &'static [Shared; 4] {
    static NAMES: OnceLock<Vec<(&str, [Shared; 4])>> = OnceLock::new();
    let names = NAMES.get_or_init(|| {
        (TIMINGS.iter())
            .map(|t| (*t, STATISTICS.map(|s| Shared::from(format!("{t}_{s}")))))
            .collect()
    });
    let found = names.iter().find(|(t, _)| *t == timing);
    &found.expect("a timing of TIMINGS").1
}

/// Whether `name` is a column of a summary table: a record's (`schema::record::columns`), or
/// one the summary derives.
pub fn is_column(name: &str) -> bool {
    let statistic = STATISTICS.iter().any(|s| {
        name.strip_suffix(s)
            .and_then(|t| t.strip_suffix('_'))
            .is_some_and(is_timing)
    });
    schema::record::is_column(name)
        || DERIVED.contains(&name)
        || ORDERS.iter().any(|(_, order)| *order == name)
        || statistic
}

/// Every column name a summary may have (the case's written `case.*`): for suggestions.
pub fn column_names() -> Vec<String> {
    let statistics = TIMINGS
        .iter()
        .flat_map(|t| STATISTICS.iter().map(move |s| format!("{t}_{s}")));
    std::iter::once("case.*".to_string())
        .chain(schema::record::columns().iter().cloned())
        .chain(DERIVED.iter().map(|c| c.to_string()))
        .chain(ORDERS.iter().map(|(_, order)| order.to_string()))
        .chain(statistics)
        .collect()
}

/// One summary row per point (its repeats: rows sharing the `point` label, or the `case_id`
/// where rows have no label), in the order points first appear. Points of different branches
/// that are one case share its records but keep a row each. The runs' rows are taken apart
/// into their points' (no cell is copied).
pub fn summarize(runs: Vec<Row>) -> Vec<Row> {
    let mut summary = reduce_points(runs);
    derive(&mut summary);
    summary
}

/// `summarize` without what the series derive: each point's repeats reduced to its row.
pub fn reduce_points(runs: Vec<Row>) -> Vec<Row> {
    let points = groups(&runs, |r| r.text("point").or(r.text(columns::CASE_ID)));
    let mut runs: Vec<Option<Row>> = runs.into_iter().map(Some).collect();
    let points: Vec<Vec<Row>> = points
        .into_iter()
        .map(|members| {
            let repeats = members.into_iter().map(|i| runs[i].take());
            repeats.map(|r| r.expect("a run is one point's")).collect()
        })
        .collect();
    drop(runs);
    points.into_par_iter().map(reduce).collect()
}

/// What the scaling and refinement series derive, set on each point's reduced row; a point's
/// derived columns read only the `DERIVED_FROM` columns of the points of its series, in their
/// order.
pub fn derive(summary: &mut [Row]) {
    let mut labels = Labels::default();
    let mut points: Vec<SeriesPoint> = (summary.iter())
        .map(|row| SeriesPoint::from_row(row, &mut labels))
        .collect();
    derive_series(&mut points);
    for (row, point) in summary.iter_mut().zip(points) {
        for (name, value) in point.derived {
            row.set(name, value);
        }
    }
}

/// What the scaling and refinement series derive, of the points' `SeriesPoint`s: each point's
/// `derived` cells, which `derive` sets on its row in their order.
pub fn derive_series(points: &mut [SeriesPoint]) {
    derive_scaling(points);
    derive_orders(points);
}

/// The columns of a reduced row that `derive` reads, with whether each is text, a count or
/// another number.
pub const DERIVED_FROM: &[(&str, Cell)] = &[
    ("scaling_series", Cell::Text),
    ("refinement_series", Cell::Text),
    (columns::STATUS, Cell::Text),
    ("workers", Cell::Count),
    ("solve_s_median", Cell::Number),
    (columns::H, Cell::Number),
    (ORDERS[0].0, Cell::Number),
    (ORDERS[1].0, Cell::Number),
    (ORDERS[2].0, Cell::Number),
    (ORDERS[3].0, Cell::Number),
];

/// What `derive` reads of a point's reduced row (its `DERIVED_FROM` cells, typed: about 200
/// bytes, where the cells were a kilobyte), and the cells it derives for it.
#[derive(Clone, Debug)]
pub struct SeriesPoint {
    scaling: Option<Shared>,
    refinement: Option<Shared>,
    ok: bool,
    workers: Option<u64>,
    solve_s_median: Option<f64>,
    h: Option<f64>,
    /// The errors of `ORDERS`, in order.
    errors: [Option<f64>; 4],
    /// The cells derived for the point, in the order they are set (no two of one name, and
    /// none a reduced row has: `no_record_column_is_one_the_series_derive`).
    pub derived: Vec<(&'static str, Value)>,
}

impl SeriesPoint {
    /// What `derive` reads of `row`, its series' labels kept in `labels`.
    pub fn from_row(row: &Row, labels: &mut Labels) -> SeriesPoint {
        let mut label = |name| row.text(name).map(|text| labels.shared(text));
        SeriesPoint {
            scaling: label("scaling_series"),
            refinement: label("refinement_series"),
            ok: is_ok(row),
            workers: row.count("workers"),
            solve_s_median: row.number("solve_s_median"),
            h: row.number(columns::H),
            errors: ORDERS.map(|(error, _)| row.number(error)),
            derived: Vec::new(),
        }
    }

    /// The derived cell `name` set to `value`: in place if the point has it, else last.
    fn set(&mut self, name: &'static str, value: Value) {
        match self.derived.iter_mut().find(|(n, _)| *n == name) {
            Some((_, cell)) => *cell = value,
            None => self.derived.push((name, value)),
        }
    }
}

/// Series labels, each kept once: the points of a series share its label.
#[derive(Default)]
pub struct Labels(HashSet<Shared>);

impl Labels {
    fn shared(&mut self, text: &str) -> Shared {
        match self.0.get(text) {
            Some(kept) => kept.clone(),
            None => {
                let kept: Shared = text.into();
                self.0.insert(kept.clone());
                kept
            }
        }
    }
}

/// What a cell `derive` reads holds.
#[derive(Clone, Copy, PartialEq)]
pub enum Cell {
    Text,
    Count,
    Number,
}

/// Indices of the rows with each key, keys in first-seen order; rows without a key are left out.
/// (By a hash of the keys: a search through the groups made so far made `collect` of 10⁵ points
/// quadratic, half of its time in comparing labels.)
fn groups<'a, T>(rows: &'a [T], key: impl Fn(&'a T) -> Option<&'a str>) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut at: HashMap<&str, usize> = HashMap::new();
    for (i, row) in rows.iter().enumerate() {
        let Some(k) = key(row) else { continue };
        match at.get(k) {
            Some(&g) => groups[g].push(i),
            None => {
                at.insert(k, groups.len());
                groups.push(vec![i]);
            }
        }
    }
    groups
}

fn is_timing(name: &str) -> bool {
    TIMINGS.contains(&name)
}

fn is_ok(row: &Row) -> bool {
    row.status() == Some(Status::Ok)
}

/// The repeats of one point as one row: the values of its first ok repeat (else its first),
/// the status they share (`mixed` if they differ), and their timings' statistics.
fn reduce(mut repeats: Vec<Row>) -> Row {
    let statuses: Vec<&str> = repeats
        .iter()
        .map(|r| r.text(columns::STATUS).unwrap_or(""))
        .collect();
    let uniform = statuses.iter().all(|s| *s == statuses[0]);
    let status = json!(if uniform { statuses[0] } else { MIXED });
    let first = repeats.iter().position(is_ok).unwrap_or(0);
    let ran: Vec<&Row> = repeats
        .iter()
        .zip(&statuses)
        .filter(|(_, s)| Status::parse(s) != Some(Status::Failed))
        .map(|(r, _)| r)
        .collect();
    // What the repeats measured, in the summary's column order.
    let mut measured: Vec<(Shared, Value)> = Vec::new();
    // The solver build that ran the point: what a figure splits its series by when a table
    // mixes builds (`collect --allow-mixed`).
    let builds: Vec<&str> = ran
        .iter()
        .map(|r| r.text(columns::FINGERPRINT).unwrap_or(""))
        .collect();
    if let Some(first_build) = builds.first() {
        let build = match builds.iter().all(|b| b == first_build) {
            true => crate::run::plan::short(first_build),
            false => MIXED,
        };
        measured.push((shared("build"), json!(build)));
    }
    for (name, _) in repeats[first].cells().filter(|(name, _)| is_timing(name)) {
        let mut times: Vec<f64> = ran.iter().filter_map(|r| r.number(name)).collect();
        times.sort_by(f64::total_cmp);
        let statistic = |f: fn(&[f64]) -> f64| match times.is_empty() {
            true => Value::Null,
            false => json!(f(&times)),
        };
        let values = [
            statistic(|t| quantile(t, 0.5)),
            statistic(|t| t[0]),
            statistic(|t| t[t.len() - 1]),
            statistic(|t| quantile(t, 0.75) - quantile(t, 0.25)),
        ];
        measured.extend(statistics_of(name).iter().cloned().zip(values));
    }
    // Repeats timed while other tasks wanted the cores they left free.
    let noisy = repeats
        .iter()
        .filter(|r| r.get(columns::NOISY) == Some(&Value::Bool(true)))
        .count();
    let count = repeats.len();
    // The first's cells as they are (their names differ, so none is looked for), in the room
    // its row had.
    let mut row: Row = std::mem::take(&mut repeats[first])
        .into_iter()
        .filter(|(name, _)| {
            let per_run = matches!(&**name, columns::KEY | columns::REPEAT | columns::RUN_ID)
                || name.starts_with("provenance.");
            !per_run && !is_timing(name)
        })
        .collect();
    row.set("status", status);
    // The columns the summary adds are no run's (`a_summary_adds_no_column_a_run_has`): each
    // is pushed, none looked for among the run's hundred.
    row.push_new(shared("repeats"), json!(count));
    for (name, value) in measured {
        row.push_new(name, value);
    }
    let (threads, ranks) = (
        row.count("case.threads").unwrap_or(1),
        row.count("case.ranks").unwrap_or(1),
    );
    row.push_new(shared("workers"), json!(threads * ranks));
    // What multiplies the workers: a scaling figure draws each kind as a line of its own.
    let parallelism = match (threads > 1, ranks > 1) {
        (false, false) => "serial",
        (true, false) => columns::THREADS,
        (false, true) => columns::RANKS,
        (true, true) => "threads × ranks",
    };
    row.push_new(shared("parallelism"), json!(parallelism));
    row.push_new(shared("noisy_repeats"), json!(noisy));
    let work = (
        row.number(columns::BONDS),
        row.number(columns::STEPS_DONE),
        row.number("solve_s_median"),
    );
    let updates = match work {
        (Some(bonds), Some(steps), Some(t)) if t > 0.0 && is_ok(&row) => json!(bonds * steps / t),
        _ => Value::Null,
    };
    row.push_new(shared(BOND_UPDATES_PER_S), updates);
    row
}

fn derive_scaling(points: &mut [SeriesPoint]) {
    for members in groups(points, |p| p.scaling.as_deref()) {
        let workers: Vec<u64> = members
            .iter()
            .map(|&i| points[i].workers.unwrap_or(1))
            .collect();
        let base = (0..members.len())
            .min_by_key(|&k| workers[k])
            .expect("a group has members");
        let baseline = &points[members[base]];
        let base_time = (baseline.solve_s_median).filter(|_| baseline.ok && members.len() > 1);
        let Some(t0) = base_time else { continue };
        for (k, &i) in members.iter().enumerate() {
            let point = &mut points[i];
            let time = point.solve_s_median.filter(|_| point.ok);
            let speedup = time.filter(|t| *t > 0.0).map(|t| t0 / t);
            let q = workers[k] as f64 / workers[base] as f64;
            let karp_flatt = speedup
                .filter(|_| q > 1.0)
                .map(|s| (1.0 / s - 1.0 / q) / (1.0 - 1.0 / q));
            point.set("baseline_workers", json!(workers[base]));
            point.set("speedup", json!(speedup));
            point.set("efficiency", json!(speedup.map(|s| s / q)));
            point.set("karp_flatt", json!(karp_flatt));
        }
    }
}

fn derive_orders(points: &mut [SeriesPoint]) {
    for mut members in groups(points, |p| p.refinement.as_deref().filter(|_| p.ok)) {
        let h = |i: usize| points[i].h.unwrap_or(f64::NAN);
        members.sort_by(|&a, &b| h(b).total_cmp(&h(a))); // coarse first
        let mut orders = Vec::new();
        for pair in members.windows(2) {
            let (coarse, fine) = (pair[0], pair[1]);
            let ratio = h(coarse) / h(fine);
            for (k, &(_, order)) in ORDERS.iter().enumerate() {
                let errors = (points[coarse].errors[k], points[fine].errors[k]);
                let observed = match errors {
                    (Some(e_c), Some(e)) if e_c > 0.0 && e > 0.0 && ratio > 1.0 => {
                        Some((e_c / e).ln() / ratio.ln())
                    }
                    _ => None,
                };
                orders.push((fine, order, observed));
            }
        }
        for (i, order, observed) in orders {
            points[i].set(order, json!(observed));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's row with the fields the summary reads.
    fn run(case_id: &str, threads: u64, ranks: u64, solve_s: f64) -> Row {
        let mut row = Row::default();
        row.set("scaling_series", json!("n=64"));
        row.set(
            "refinement_series",
            json!(format!("threads={threads} ranks={ranks}")),
        );
        row.set("case_id", json!(case_id));
        row.set("status", json!("ok"));
        row.set("case.threads", json!(threads));
        row.set("case.ranks", json!(ranks));
        row.set("h", json!(1.0 / 64.0));
        row.set("bonds", json!(1000));
        row.set("steps_done", json!(10));
        row.set("solve_s", json!(solve_s));
        row
    }

    fn column(rows: &[Row], name: &str) -> Vec<Option<f64>> {
        rows.iter().map(|r| r.number(name)).collect()
    }

    fn close(got: Vec<Option<f64>>, expected: &[Option<f64>]) {
        assert_eq!(got.len(), expected.len(), "{got:?} vs {expected:?}");
        for (g, e) in got.iter().zip(expected) {
            match (g, e) {
                (Some(g), Some(e)) => assert!(
                    (g - e).abs() < 1e-12 * e.abs().max(1.0),
                    "{got:?} vs {expected:?}"
                ),
                _ => assert_eq!(g, e, "{got:?} vs {expected:?}"),
            }
        }
    }

    #[test]
    fn derive_on_what_it_reads_sets_what_it_sets_on_whole_rows() {
        // Two scaling series and a refinement series, one point failed.
        let mut runs: Vec<Row> = (0..6)
            .map(|k| {
                let mut row = run(&format!("p{k}"), 1 << (k % 3), 1, 4.0 / (1 + k % 3) as f64);
                row.set("point", json!(format!("p{k}")));
                row.set("scaling_series", json!(format!("n={}", k / 3)));
                row.set("refinement_series", json!(format!("t={}", k % 3)));
                row.set("h", json!(1.0 / (16 << (k / 3)) as f64));
                row.set("error_l2_norm", json!(1.0 / (16 << (k / 3)) as f64));
                row
            })
            .collect();
        runs[4].set("status", json!("failed"));
        let whole = summarize(runs.clone());
        let reduced = reduce_points(runs);
        // Of the `DERIVED_FROM` cells alone, as a collect from scratch keeps them.
        let mut read: Vec<Row> = (reduced.iter())
            .map(|row| {
                (DERIVED_FROM.iter())
                    .filter_map(|(name, _)| Some((shared(name), row.get(name)?.clone())))
                    .collect()
            })
            .collect();
        let mut labels = Labels::default();
        let mut series: Vec<SeriesPoint> = (read.iter())
            .map(|row| SeriesPoint::from_row(row, &mut labels))
            .collect();
        derive_series(&mut series);
        derive(&mut read);
        for (row, (reduced, series)) in whole.iter().zip(reduced.into_iter().zip(series)) {
            let derived = series.derived.into_iter().map(|(n, v)| (shared(n), v));
            let cells: Vec<_> = reduced.into_iter().chain(derived).collect();
            assert_eq!(*row, cells.into_iter().collect::<Row>());
        }
        for (row, read) in whole.iter().zip(&read) {
            for (name, value) in read.cells() {
                assert_eq!(row.get(name), Some(value), "{name}");
            }
        }
        assert!(whole[3].get("order_l2").is_some() && whole[1].get("speedup").is_some());
    }

    #[test]
    fn a_summary_adds_no_column_a_run_has() {
        // A run's row of every column a record has, and the labels and `threads` beside them.
        let labels = ["point", "branch", "refinement_series", "scaling_series"];
        let mut run = Row::default();
        for name in (schema::record::columns().iter().map(String::as_str))
            .chain(labels)
            .chain([columns::THREADS])
        {
            run.set(name, json!(2.0));
        }
        run.set("point", json!("p"));
        run.set(columns::STATUS, json!("ok"));
        let reduced = reduce_points(vec![run]);
        let names: Vec<&str> = reduced[0].cells().map(|(name, _)| name).collect();
        let distinct: HashSet<&str> = names.iter().copied().collect();
        assert_eq!(distinct.len(), names.len(), "{names:?}");
        assert!(names.contains(&"solve_s_median") && names.contains(&"workers"));
    }

    #[test]
    fn no_record_column_is_one_the_series_derive() {
        let derived = ["baseline_workers", "speedup", "efficiency", "karp_flatt"];
        let orders = ORDERS.iter().map(|(_, order)| *order);
        for name in derived.into_iter().chain(orders) {
            assert!(!schema::record::is_column(name), "{name}");
            assert!(
                !DERIVED_FROM.iter().any(|(from, _)| *from == name),
                "{name}"
            );
        }
    }

    #[test]
    fn repeats_reduce_to_median_min_and_iqr() {
        let runs: Vec<Row> = [4.0, 1.0, 3.0, 2.0]
            .iter()
            .map(|&t| run("a", 1, 1, t))
            .collect();
        let summary = summarize(runs);
        assert_eq!(summary.len(), 1);
        let row = &summary[0];
        assert_eq!(row.number("repeats"), Some(4.0));
        assert_eq!(row.number("solve_s_median"), Some(2.5));
        assert_eq!(row.number("solve_s_min"), Some(1.0));
        assert_eq!(row.number("solve_s_max"), Some(4.0));
        // Quartiles of 1, 2, 3, 4 by linear interpolation: 1.75 and 3.25.
        assert_eq!(row.number("solve_s_iqr"), Some(1.5));
        assert_eq!(row.get("solve_s"), None);
        assert_eq!(row.number("bond_updates_per_s"), Some(1000.0 * 10.0 / 2.5));
    }

    #[test]
    fn speedup_efficiency_and_serial_fraction_against_the_fewest_workers() {
        // Amdahl with serial fraction 0.1 and T(1) = 10: T(p) = 10 (0.1 + 0.9/p).
        let amdahl = |p: f64| 10.0 * (0.1 + 0.9 / p);
        let runs = vec![
            run("t2", 2, 1, amdahl(2.0)),
            run("t1", 1, 1, amdahl(1.0)),
            run("r4", 2, 2, amdahl(4.0)),
        ];
        let summary = summarize(runs);
        let s2 = 1.0 / (0.1 + 0.9 / 2.0);
        let s4 = 1.0 / (0.1 + 0.9 / 4.0);
        // Counts are integers (Int64 columns in Parquet), not floats.
        let cells =
            |name: &str| -> Vec<Option<&Value>> { summary.iter().map(|r| r.get(name)).collect() };
        assert_eq!(
            cells("workers"),
            [Some(&json!(2)), Some(&json!(1)), Some(&json!(4))]
        );
        assert_eq!(cells("baseline_workers"), [Some(&json!(1)); 3]);
        assert_eq!(cells("repeats"), [Some(&json!(1)); 3]);
        close(
            column(&summary, "speedup"),
            &[Some(s2), Some(1.0), Some(s4)],
        );
        close(
            column(&summary, "efficiency"),
            &[Some(s2 / 2.0), Some(1.0), Some(s4 / 4.0)],
        );
        close(
            column(&summary, "karp_flatt"),
            &[Some(0.1), None, Some(0.1)],
        );

        // Against a baseline of 2 workers the speedups are relative: 4 workers at half the
        // time is perfect scaling.
        let runs = vec![run("t2", 2, 1, 6.0), run("r4", 2, 2, 3.0)];
        let summary = summarize(runs);
        close(column(&summary, "speedup"), &[Some(1.0), Some(2.0)]);
        close(column(&summary, "efficiency"), &[Some(1.0), Some(1.0)]);
        close(column(&summary, "karp_flatt"), &[None, Some(0.0)]);
    }

    #[test]
    fn orders_come_from_the_actual_grid_ratios() {
        // e = h² on the grids h = 1/10, 1/30, 1/40, listed out of order.
        let runs: Vec<Row> = [30.0, 10.0, 40.0]
            .iter()
            .map(|&n: &f64| {
                let mut row = run(&format!("n{n}"), 1, 1, 1.0);
                row.set("scaling_series", json!(format!("n={n}")));
                row.set("h", json!(1.0 / n));
                row.set("error_l2_norm", json!(1.0 / (n * n)));
                row.set("error_max", json!(3.0 / n));
                row
            })
            .collect();
        let summary = summarize(runs);
        close(column(&summary, "order_l2"), &[Some(2.0), None, Some(2.0)]);
        close(column(&summary, "order_max"), &[Some(1.0), None, Some(1.0)]);
    }

    #[test]
    fn failed_and_mixed_points_get_no_derived_values() {
        let mut failed = run("a", 1, 1, 1.0);
        failed.set("status", json!("failed"));
        let runs = vec![run("a", 1, 1, 2.0), failed, run("b", 2, 1, 1.0)];
        let summary = summarize(runs);
        assert_eq!(summary[0].text("status"), Some("mixed"));
        // The failed repeat's time is not a timing.
        assert_eq!(summary[0].number("solve_s_median"), Some(2.0));
        // The baseline (1 thread) is mixed: no speedups in its series.
        close(column(&summary, "speedup"), &[None, None]);
        assert_eq!(summary[0].number("bond_updates_per_s"), None);
        // A point alone in its series has no baseline to compare with.
        let alone = summarize(vec![run("c", 2, 1, 1.0)]);
        assert_eq!(alone[0].number("speedup"), None);
    }
}
