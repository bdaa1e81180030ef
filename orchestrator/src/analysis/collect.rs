//! `nlstudy collect`: the stored records of the study's current points as two Parquet tables,
//! `<study>.parquet` (one row per run and repeat) and `<study>-summary.parquet` (one row per
//! point; see `summary`). Records of points the study no longer has (removed from the sweep,
//! or run by another solver version) stay stored but are left out.

use crate::analysis::{pivot, summary};
use crate::model::study::Study;
use crate::run::plan::{short, Planned};
use crate::store::table::{self, Row};
use crate::store::Fault;
use crate::store::Store;
use rayon::prelude::*;
use schema::record::columns;
use schema::record::{Status, Stored};
use serde_json::{json, Value};
use std::collections::{HashMap, HashSet};
use std::path::PathBuf;

#[derive(serde::Serialize, serde::Deserialize)]
pub struct Collected {
    pub runs: PathBuf,
    pub summary: PathBuf,
    pub rows: usize,
    pub points: usize,
    /// Runs (points and repeats) with no stored record yet.
    pub missing: usize,
    /// Stored records that are not points of the study now.
    pub left_out: usize,
    /// The summary table's headline columns as markdown, for printing.
    pub overview: String,
    /// Whether the tables were already made of these records, and stand as they were.
    #[serde(skip)]
    pub up_to_date: bool,
}

/// What the last collect made the tables of and said, beside them: when nothing it read has
/// changed since, the tables stand (make-style) and a collect costs a plan.
#[derive(serde::Serialize, serde::Deserialize)]
struct Made {
    inputs: String,
    collected: Collected,
}

/// The file `Made` is kept in, in the study's results directory.
const MADE: &str = ".collected.json";

/// A signature of everything the tables are made of: this build of nlstudy, the study's
/// description, each planned point's key, labels and the sequence number of its stored record
/// (a rerun, a new record or one gone changes it), the records in all (those left out count),
/// and `allow_mixed`.
fn inputs_of(planned: &[Planned], store: &Store, study: &Study, allow_mixed: bool) -> String {
    use sha2::Digest;
    let mut hasher = sha2::Sha256::new();
    if let Ok(meta) = std::env::current_exe().and_then(std::fs::metadata) {
        hasher.update(format!("{} {:?}\n", meta.len(), meta.modified().ok()));
    }
    hasher.update(format!(
        "{:?} {allow_mixed} {}\n",
        study.description,
        store.count()
    ));
    let keys: Vec<&str> = planned.iter().map(|p| p.key.as_str()).collect();
    for (planned, seq) in planned.iter().zip(store.sequence_numbers(&keys)) {
        let series = planned.point.series();
        hasher.update(format!(
            "{} {seq} {:?} {:?} {:?} {:?}\n",
            planned.key,
            planned.point.label_without_repeat(),
            planned.point.branch,
            series.refinement,
            series.scaling
        ));
    }
    crate::store::hex(&hasher.finalize())
}

/// The tables as the last collect made them, if nothing they are made of changed since and
/// they are all there, whole (each matches its sum).
fn made_already(store: &Store, inputs: &str) -> Option<Collected> {
    let text =
        crate::store::fs::read_regular(&store.table(MADE), crate::store::fs::RECORD_CAP).ok()?;
    let made: Made = serde_json::from_str(&text).ok()?;
    let there = |path: &PathBuf| table::matches_its_sum(path);
    (made.inputs == inputs && there(&made.collected.runs) && there(&made.collected.summary))
        .then_some(Collected {
            up_to_date: true,
            ..made.collected
        })
}

/// The fields that lead a run's row; the case follows, then the results, then provenance.
const LEADING: &[&str] = &[
    columns::KEY,
    columns::CASE_ID,
    columns::REPEAT,
    columns::STATUS,
    columns::MESSAGE,
];

/// One run's row: the point's label and series, then the record, flattened: its columns are
/// what `Stored` serializes.
fn run_row(planned: &Planned, stored: &Stored) -> Row {
    let Value::Object(mut record) = stored.to_value() else {
        return Row::default();
    };
    // The case with its defaults filled in, as the solver resolves it now (records keep the
    // case as keyed, which leaves some defaults out).
    if let Ok(checked) = &planned.case {
        record.insert("case".into(), checked.resolved());
    }
    // (The row grows cell by cell, to twice the room it needs at most: room its summary row,
    // made in place of it, fills.)
    let mut row = Row::default();
    let series = planned.point.series();
    row.set("point", json!(planned.point.label_without_repeat()));
    if let Some(branch) = &planned.point.branch {
        row.set("branch", json!(&**branch));
    }
    row.set("refinement_series", json!(series.refinement));
    row.set("scaling_series", json!(series.scaling));
    for field in LEADING {
        row.set(field, record.remove(*field).unwrap_or(Value::Null));
    }
    let rank = |name: &str| match name {
        "case" => 0,
        "provenance" => 2,
        _ => 1,
    };
    let mut rest: Vec<(String, Value)> = record.into_iter().collect();
    rest.sort_by_key(|(name, _)| rank(name)); // stable: names stay sorted within a rank
    for (name, value) in rest {
        row.set_flattened(&name, value);
    }
    // Beside `ranks` (the record's), the threads each rank ran: what `where` and figure specs
    // call `threads`.
    if let Some(threads) = row.get("case.threads").cloned() {
        row.set(columns::THREADS, threads);
    }
    row
}

/// The columns that name a point's place in the study rather than measure it: labels, as the
/// figures' legends show them and the summary groups repeats by `point`. (A struct of the swept
/// fields would need polars' `dtype-struct`, which this build leaves out; the fields are columns
/// `case.<field>` anyway.) Each file's metadata carries these notes.
const LABELS: &[(&str, &str)] = &[
    (
        "point",
        "label: the point's swept fields as `field=value`, space-separated (a value may hold spaces: split before each `name=`); its repeats share it",
    ),
    ("branch", "label: the sweep's branch the point lies on"),
    (
        "refinement_series",
        "label: the point's swept fields but `n` and what moves with it; the points of one grid refinement share it",
    ),
    (
        "scaling_series",
        "label: the point's swept fields but threads, ranks, px, py and what moves with them; the points of one scaling series share it",
    ),
];

/// Writes the tables, with the study's description in their metadata; `None` when no run of the
/// study is stored yet.
/// With `allow_mixed`, runs of several solver builds, hosts or instruction sets are tabulated
/// together; without it they are refused (see `mixed_provenance`).
pub fn collect(
    planned: &[Planned],
    store: &Store,
    study: &Study,
    allow_mixed: bool,
) -> Result<Option<Collected>, Fault> {
    let inputs = inputs_of(planned, store, study, allow_mixed);
    if let Some(collected) = made_already(store, &inputs) {
        return Ok(Some(collected));
    }
    // Superseded records go, and the segments of finished writers become one.
    if let Err(e) = store.compact(&HashSet::new()) {
        errln!("nlstudy: warning: the store was not compacted: {e}");
    }
    fits_in_memory(store.count(), available_memory())?;
    // Each record becomes the rows of the points it is as it is read (on every core), so that
    // the records are never all held: the rows hold all the tables need.
    let mut places: HashMap<&str, Vec<usize>> = HashMap::new();
    for (i, p) in planned.iter().enumerate() {
        places.entry(p.key.as_str()).or_default().push(i);
    }
    let scan = store.scan_map(|stored| {
        let places = places.get(stored.key.as_str())?;
        Some(
            places
                .iter()
                .map(|&i| (i, run_row(&planned[i], &stored)))
                .collect::<Vec<_>>(),
        )
    });
    for unreadable in &scan.unreadable[scan.unreadable.len() - scan.found_now..] {
        errln!("nlstudy: warning: {unreadable}");
    }
    let left_out = scan.records.iter().filter(|rows| rows.is_none()).count();
    let mut in_plan_order: Vec<Option<Row>> = (0..planned.len()).map(|_| None).collect();
    for (i, row) in scan.records.into_iter().flatten().flatten() {
        in_plan_order[i] = Some(row);
    }
    let rows: Vec<Row> = in_plan_order.into_iter().flatten().collect();
    let missing = planned.len() - rows.len();
    if rows.is_empty() {
        return Ok(None);
    }
    if let (Some(mixed), false) = (mixed_provenance(&rows), allow_mixed) {
        return Err(Fault::Input(format!(
            "{mixed}: one table would compare runs of different builds or machines; rerun the stale points (`nlstudy run`), or give --allow-mixed to tabulate them together"
        )));
    }
    let _outputs = store.lock_outputs()?;
    let runs = store.table(&format!("{}.parquet", store.study));
    let summary = store.table(&format!("{}-summary.parquet", store.study));
    let about = table::About {
        description: &study.description,
        notes: LABELS,
    };
    // The run table is written before the summary is made of its rows (taking them apart).
    let mut tables = table::Staged::new(&about);
    tables.stage(&runs, &rows)?;
    let run_count = rows.len();
    let summary_rows = summary::summarize(rows);
    tables.stage(&summary, &summary_rows)?;
    tables.commit()?;
    let swept = crate::model::study::fields_telling_apart(planned.iter().map(|p| &p.point));
    let collected = Collected {
        runs,
        summary,
        rows: run_count,
        points: summary_rows.len(),
        missing,
        left_out,
        overview: overview(&summary_rows, &swept),
        up_to_date: false,
    };
    // Said after the tables are whole; compaction above changed no record's sequence number.
    let made = Made { inputs, collected };
    if let Ok(text) = serde_json::to_vec(&made) {
        crate::store::write_atomically(&store.table(MADE), &text)?;
    }
    Ok(Some(made.collected))
}

/// The summary rows of the points whose records `records` (by key) holds, as `collect` would
/// write them: for comparing what two result sets derive (speedups, orders).
pub fn summary_of(planned: &[Planned], records: &HashMap<String, Stored>) -> Vec<Row> {
    summary::summarize(run_rows(planned, records))
}

/// The run rows of the points whose records `records` holds. Points of different branches may
/// be one case: each gets its row from the one record.
pub fn run_rows(planned: &[Planned], records: &HashMap<String, Stored>) -> Vec<Row> {
    planned
        .par_iter()
        .filter_map(|p| Some(run_row(p, records.get(p.key.as_str())?)))
        .collect()
}

/// What `collect` holds per stored run while it tabulates (its row, and its share of the run
/// table's frame or of the summary): 10.6 KB measured at 10⁵ runs (1.06 GB peak, of which the
/// plan 0.2 GB), with a margin.
const BYTES_PER_RUN: u64 = 12 << 10;

/// Refuses, before reading a record, a collect that would hold more than the machine has free:
/// better a sentence now than the kernel's OOM killer midway.
fn fits_in_memory(runs: usize, available: Option<u64>) -> Result<(), Fault> {
    let needed = runs as u64 * BYTES_PER_RUN;
    match available {
        Some(free) if needed > free => Err(Fault::Io(format!(
            "collect would hold about {} GB for {runs} stored runs, more than the {} GB this machine has free; collect on a machine with more memory, or split the study",
            crate::console::number(needed as f64 / 1e9),
            crate::console::number(free as f64 / 1e9)
        ))),
        _ => Ok(()),
    }
}

/// The memory free for this process: /proc/meminfo's MemAvailable, lowered to the limits of its
/// cgroup (v2) and the cgroups above it (a Slurm job's share of a node); `None` where /proc
/// does not tell.
fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(cgroup_limit().map_or(kib << 10, |l| l.min(kib << 10)))
}

/// The smallest `memory.max` of this process's cgroup and its ancestors (`max` is none).
fn cgroup_limit() -> Option<u64> {
    const ROOT: &str = "/sys/fs/cgroup";
    let membership = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let own = membership.lines().find_map(|l| l.strip_prefix("0::"))?;
    let mut dir = std::path::Path::new(ROOT).join(own.trim().trim_start_matches('/'));
    let mut limit: Option<u64> = None;
    while dir.starts_with(ROOT) {
        let here = std::fs::read_to_string(dir.join("memory.max"))
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok());
        limit = match (limit, here) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        if !dir.pop() {
            break;
        }
    }
    limit
}

/// What a timing or an error depends on, as the record's provenance names it.
const PROVENANCE: &[(&str, &str)] = &[
    ("solver fingerprints", columns::FINGERPRINT),
    ("hosts", columns::HOST),
    ("instruction sets", columns::INSTRUCTION_SET),
];

/// Whether the runs that measured something (`ok`, `diverged`) came from more than one solver
/// build, host or instruction set: the first such mix, said with each value and its run count.
pub fn mixed_provenance(rows: &[Row]) -> Option<String> {
    let measured: Vec<&Row> = rows
        .iter()
        .filter(|r| matches!(r.status(), Some(Status::Ok | Status::Diverged)))
        .collect();
    PROVENANCE.iter().find_map(|(what, column)| {
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for row in &measured {
            let value = row.text(column).unwrap_or("");
            match counts.iter_mut().find(|(v, _)| *v == value) {
                Some((_, n)) => *n += 1,
                None => counts.push((value, 1)),
            }
        }
        (counts.len() > 1).then(|| {
            let listed: Vec<String> = counts
                .iter()
                .map(|(v, n)| match (*what, *v) {
                    (_, "") => format!("unknown ({n} runs)"),
                    ("solver fingerprints", v) => format!("{} ({n} runs)", short(v)),
                    (_, v) => format!("{v:?} ({n} runs)"),
                })
                .collect();
            format!("the runs mix {what}: {}", listed.join(", "))
        })
    })
}

/// The summary's headline columns: the swept fields (as `(column, shown name)`: from the case,
/// or derived by the solver), then the headline results the study has.
fn headline_columns(summary: &[Row], swept: &[String]) -> Vec<(String, String)> {
    const RESULTS: &[&str] = &[
        columns::STATUS,
        "solve_s_median",
        "solve_s_iqr",
        columns::ERROR_L2_NORM,
        "order_l2",
        "speedup",
        "efficiency",
    ];
    let has = |name: &str| summary.iter().any(|row| row.get(name).is_some());
    let mut shown: Vec<(String, String)> = swept
        .iter()
        .filter_map(|field| {
            let column = [format!("case.{field}"), field.clone()]
                .into_iter()
                .find(|c| has(c))?;
            Some((column, field.clone()))
        })
        .collect();
    shown.extend(
        RESULTS
            .iter()
            .filter(|name| has(name))
            .map(|name| (name.to_string(), name.to_string())),
    );
    shown
}

/// The summary's headline columns as texts: their shown names, and one line per point.
pub fn headline(summary: &[Row], swept: &[String]) -> (Vec<String>, Vec<Vec<String>>) {
    let shown = headline_columns(summary, swept);
    let columns: Vec<&str> = shown.iter().map(|(column, _)| column.as_str()).collect();
    let names = shown.iter().map(|(_, name)| name.clone()).collect();
    (names, pivot::texts(summary, &columns))
}

/// How many points the overview shows: a screenful; the summary table holds them all.
const OVERVIEW_POINTS: usize = 40;

/// The summary at a glance, for the terminal: the headline columns of its first
/// `OVERVIEW_POINTS` rows, as Markdown, and how many more the table has.
pub fn overview(summary: &[Row], swept: &[String]) -> String {
    let shown = &summary[..summary.len().min(OVERVIEW_POINTS)];
    let (names, lines) = headline(shown, swept);
    let mut text = pivot::markdown_table(&names, &lines);
    if summary.len() > shown.len() {
        text += &format!(
            "… and {} more points in the summary table (`nlstudy table` pivots them)\n",
            summary.len() - shown.len()
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_collect_larger_than_free_memory_is_refused_before_it_reads() {
        assert!(fits_in_memory(1000, Some(1 << 30)).is_ok());
        assert!(fits_in_memory(10, None).is_ok(), "unknown: tried");
        let Err(Fault::Io(message)) = fits_in_memory(1_000_000, Some(8 << 30)) else {
            panic!("refused")
        };
        assert!(
            message.contains("1000000 stored runs") && message.contains("12.29 GB"),
            "{message}"
        );
    }

    /// A summary row of the study: one-digit numbers there, four significant digits here.
    fn summary_row(n: u64, solve_s: f64, error: f64) -> Row {
        let mut row = Row::default();
        row.set("point", json!(format!("n={n}")));
        row.set("case.n", json!(n));
        row.set("case.t_end", json!(4e-7));
        row.set("status", json!("ok"));
        row.set("solve_s_median", json!(solve_s));
        row.set("error_l2_norm", json!(error));
        row
    }

    #[test]
    fn runs_of_two_builds_or_hosts_are_a_mix_failed_ones_are_not() {
        let run = |status: &str, fingerprint: Option<&str>, host: &str| {
            let mut row = summary_row(16, 1.0, 1e-3);
            row.set("status", json!(status));
            if let Some(f) = fingerprint {
                row.set("provenance.fingerprint", json!(f));
            }
            row.set("provenance.host", json!(host));
            row
        };
        let (a, b) = ("a".repeat(64), "b".repeat(64));
        let same = [run("ok", Some(&a), "vm"), run("diverged", Some(&a), "vm")];
        // A failed run measured nothing (nlstudy wrote it): it mixes nothing in.
        let with_failed = [run("ok", Some(&a), "vm"), run("failed", None, "")];
        assert_eq!(mixed_provenance(&same), None);
        assert_eq!(mixed_provenance(&with_failed), None);
        let builds = [
            run("ok", Some(&a), "vm"),
            run("ok", Some(&b), "vm"),
            run("ok", None, "vm"),
        ];
        assert_eq!(
            mixed_provenance(&builds).as_deref(),
            Some("the runs mix solver fingerprints: aaaaaaaa (1 runs), bbbbbbbb (1 runs), unknown (1 runs)")
        );
        let hosts = [run("ok", Some(&a), "vm"), run("ok", Some(&a), "node2")];
        assert!(mixed_provenance(&hosts)
            .unwrap()
            .contains("hosts: \"vm\" (1 runs), \"node2\""));
    }

    #[test]
    fn the_overview_shows_four_significant_digits_one_notation_per_column() {
        let summary = [
            summary_row(16, 0.0002, 0.000003),
            summary_row(32, 1.5, 9.4513e-9),
        ];
        assert_eq!(
            overview(&summary, &["n".into(), "t_end".into()]),
            "| n | t_end | status | solve_s_median | error_l2_norm |\n\
             | --- | --- | --- | --- | --- |\n\
             | 16 | 4e-7 | ok | 0.0002 | 3e-6 |\n\
             | 32 | 4e-7 | ok | 1.5 | 9.451e-9 |\n"
        );
    }

    #[test]
    fn the_overview_of_a_large_study_shows_a_screenful_and_counts_the_rest() {
        let summary: Vec<Row> = (0..45).map(|n| summary_row(n, 1.0, 1e-3)).collect();
        let text = overview(&summary, &["n".into()]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2 + OVERVIEW_POINTS + 1, "{text}");
        assert!(
            lines[2 + OVERVIEW_POINTS - 1].starts_with("| 39 |"),
            "{text}"
        );
        assert_eq!(
            lines.last(),
            Some(&"… and 5 more points in the summary table (`nlstudy table` pivots them)")
        );
        assert!(!overview(&summary[..40], &["n".into()]).contains("more points"));
    }
}
