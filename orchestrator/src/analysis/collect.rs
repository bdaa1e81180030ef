//! `nlstudy collect`: the stored records of the study's current points as two Parquet tables,
//! `<study>.parquet` (one row per run and repeat) and `<study>-summary.parquet` (one row per
//! point; see `summary`). Records of points the study no longer has (removed from the sweep,
//! or run by another solver version) stay stored but are left out.

mod from_scratch;
mod run_row;

use crate::analysis::incremental::{self, Identity};
use crate::analysis::{pivot, summary};
use crate::model::study::Study;
use crate::run::nlsolve::Resolved;
use crate::run::plan::{short, Planned};
use crate::store::table::{self, Row, ROW_GROUP, STREAMED_ROW_GROUP};
use crate::store::Store;
use crate::store::{Fault, Id};
use polars::prelude::DataFrame;
use rayon::prelude::*;
use run_row::run_row;
use schema::record::columns;
use schema::record::{Status, Stored};
use std::collections::{HashMap, HashSet};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Clone, serde::Serialize, serde::Deserialize)]
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
    /// How many run rows were read from their records, when the tables were spliced (the rest
    /// kept from the tables as they were); `None` when they were made from scratch.
    #[serde(skip)]
    pub spliced: Option<usize>,
}

/// What the last collect made the tables of and said, beside them: when nothing it read has
/// changed since, the tables stand (make-style) and a collect costs a plan; when some records
/// changed, `rows` lets the next splice them in (`incremental`).
#[derive(serde::Serialize, serde::Deserialize)]
struct Made {
    inputs: String,
    collected: Collected,
    #[serde(default)]
    rows: Option<incremental::Rows>,
}

/// The file `Made` is kept in, in the study's results directory.
const MADE: &str = ".collected.json";

/// A signature of what the tables depend on besides the records: this build of nlstudy, the
/// study's description and `allow_mixed`.
fn header_of(study: &Study, allow_mixed: bool) -> String {
    use sha2::Digest;
    let mut hasher = sha2::Sha256::new();
    if let Ok(meta) = std::env::current_exe().and_then(std::fs::metadata) {
        hasher.update(format!("{} {:?}\n", meta.len(), meta.modified().ok()));
    }
    hasher.update(format!("{:?} {allow_mixed}\n", study.description));
    crate::store::hex(&hasher.finalize())
}

/// A signature of everything the tables are made of: the header, each planned point's
/// identity (key, labels, resolved case) and the sequence number of its stored record (a rerun,
/// a new record or one gone changes it), and the records in all (those left out count).
fn inputs_of(header: &str, identities: &[Identity], seqs: &[u64], records: usize) -> String {
    use sha2::Digest;
    let mut hasher = sha2::Sha256::new();
    hasher.update(format!("{header} {records}\n"));
    for (identity, seq) in identities.iter().zip(seqs) {
        hasher.update(format!("{} {seq}\n", identity.signature));
    }
    crate::store::hex(&hasher.finalize())
}

/// The most `MADE` may hold: its rows take about 60 bytes a run.
const MADE_CAP: u64 = 1 << 30;

/// What the last collect said it made, if it said it, and which file said it. The tables it
/// names are this results folder's own (it names them by file name): a folder copied or moved
/// elsewhere reads its own tables, never the original's.
fn made_before(store: &Store) -> Option<(Made, Said)> {
    let path = store.table(MADE);
    let said = said_by(&path)?;
    let text = crate::store::fs::read_regular(&path, MADE_CAP).ok()?;
    let mut made: Made = serde_json::from_str(&text).ok()?;
    for table in [&mut made.collected.runs, &mut made.collected.summary] {
        *table = store.table(table.file_name()?.to_str()?);
    }
    Some((made, said))
}

/// A file of `MADE` as its metadata tells it apart: device, inode, size and time (a collect
/// writes it afresh and renames it over the last).
type Said = (u64, u64, u64, i128);

fn said_by(path: &std::path::Path) -> Option<Said> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::symlink_metadata(path).ok()?;
    let time = crate::store::fs::modified_ns(&meta);
    Some((meta.dev(), meta.ino(), meta.len(), time))
}

/// Transparent huge pages off for this process while it collects, on again after. The
/// allocator (mimalloc) asks for huge pages on its arenas and gives freed pages back to the
/// system after a second: a collect makes and frees millions of small values, and each page
/// touched again after it was given back costs the kernel zeroing a whole 2 MiB. Off, a
/// collect of 10⁵ records took 0.6 s less (1.3 s less of system time) and 70 MB less
/// (docs/performance.md). Only for the collect: the setting passes to child processes, and
/// the solvers a run starts keep the machine's (a process that had them off keeps them off).
struct SmallPages(bool);

impl SmallPages {
    fn while_collecting() -> SmallPages {
        // SAFETY: prctl with integer arguments only; a kernel without them says EINVAL (-1).
        let on = unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) } == 0;
        SmallPages(on && unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) } == 0)
    }
}

impl Drop for SmallPages {
    fn drop(&mut self) {
        if self.0 {
            // SAFETY: as above.
            unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 0, 0, 0, 0) };
        }
    }
}

/// What the tables read of a planned point: its key, the branch it lies on and how the solver
/// resolves its case (`None`: refused); its plan's texts of the case and its fields are let go.
pub struct Tabulated {
    key: Id,
    branch: Option<Arc<str>>,
    resolution: Option<Resolved>,
}

/// What a collect reads of a study's plan: each point as `Tabulated`, its identity, and the
/// fields that tell the points apart. (At 10⁵ points the plan holds about 70 MB the tables
/// never read: a collect that is given its plan lets it go.)
pub struct ToCollect {
    points: Vec<Tabulated>,
    identities: Vec<Identity>,
    swept: Vec<String>,
}

impl ToCollect {
    pub fn from_planned(planned: &[Planned]) -> ToCollect {
        let points = (planned.iter())
            .map(|p| Tabulated {
                key: p.key,
                branch: p.point.branch.clone(),
                resolution: p.case.as_ref().ok().map(|case| case.resolution().clone()),
            })
            .collect();
        ToCollect {
            points,
            identities: incremental::identities(planned),
            swept: crate::model::study::fields_telling_apart(planned.iter().map(|p| &p.point)),
        }
    }

    /// The fields that tell the points apart (`fields_telling_apart`): the tables' label columns.
    pub fn swept(&self) -> &[String] {
        &self.swept
    }
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

/// The records the run table at `path` holds, one per row, as the table has them: every field
/// of the stored record (a list of text, such as `hosts`, read back from its JSON), with the
/// case resolved as the table holds it (the solver's defaults filled in) and without the row's
/// labels. What `report` shows of a results folder copied without its runs.
pub fn records_of_run_table(path: &std::path::Path) -> Result<Vec<Stored>, Fault> {
    let labels: HashSet<&str> = (LABELS.iter().map(|(name, _)| *name))
        .chain([columns::THREADS])
        .collect();
    table::read_parquet(path)?
        .iter()
        .enumerate()
        .map(|(k, row)| {
            let cells = row.cells().filter(|(name, _)| !labels.contains(name));
            serde_path_to_error::deserialize(columns::unflatten_row(cells)).map_err(|e| {
                Fault::Input(format!(
                    "{}: row {} is not a run's record (`{}`: {}); collect the study again",
                    path.display(),
                    k + 1,
                    e.path(),
                    e.inner()
                ))
            })
        })
        .collect()
}

/// Writes the tables, with the study's description in their metadata; `None` when no run of the
/// study is stored yet. Tables made before of records some of which changed since are
/// spliced (`incremental`), else made from scratch.
/// With `allow_mixed`, runs of several solver builds, hosts or instruction sets are tabulated
/// together; without it they are refused (see `mixed_provenance`).
///
/// Long because it is one pass under the outputs' lock: what changed since the last read, the
/// splice or the full build, the provenance check and both tables written, so that no figure reads
/// half of it.
pub fn collect(
    to_collect: ToCollect,
    store: &Store,
    study: &Study,
    allow_mixed: bool,
) -> Result<Option<Collected>, Fault> {
    let ToCollect {
        points,
        identities,
        swept,
    } = to_collect;
    let keys: Vec<&str> = points.iter().map(|p| p.key.as_str()).collect();
    let seqs = store.sequence_numbers(&keys);
    let header = header_of(study, allow_mixed);
    let inputs = inputs_of(&header, &identities, &seqs, store.count());
    let before = made_before(store);
    if let Some((made, _)) = before.as_ref().filter(|(made, _)| made.inputs == inputs) {
        // The tables whole, and the ones it said it made (not those of a collect killed before
        // it said what it made).
        let sums = [&made.collected.runs, &made.collected.summary].map(|t| table::sum_if_whole(t));
        let said = made
            .rows
            .as_ref()
            .map(|rows| rows.sums.iter().cloned().map(Some));
        if said.is_some_and(|said| said.eq(sums)) {
            let (made, _) = before.expect("matched above");
            return Ok(Some(Collected {
                up_to_date: true,
                ..made.collected
            }));
        }
    }
    // Superseded records go, and the segments of finished writers become one.
    if let Err(e) = store.compact(&HashSet::new()) {
        log::warn!("the store was not compacted: {e}");
    }
    // From here until the tables and what they are made of are in place, no other collect
    // writes them (nor reads them, as figures do).
    let _outputs = store.lock_outputs()?;
    // What was read before the lock, unless another collect has said more since.
    let made = match before {
        Some((made, said)) if said_by(&store.table(MADE)) == Some(said) => Some(made),
        _ => made_before(store).map(|(made, _)| made),
    };
    let prior = made.and_then(|made| made.rows.filter(|r| r.header == header));
    let paths = (
        store.table(&format!("{}.parquet", store.study)),
        store.table(&format!("{}-summary.parquet", store.study)),
    );
    let about = table::About {
        description: &study.description,
        notes: LABELS,
    };
    let mut staged = table::Staged::new(&about);
    let make_row = |i: usize, stored: &Stored| run_row(&points[i], &identities[i], stored);
    let _pages = SmallPages::while_collecting();
    let spliced = prior.and_then(|prior| {
        let paths = (paths.0.as_path(), paths.1.as_path());
        incremental::spliced(&keys, &identities, &seqs, store, prior, paths, &make_row)
    });
    let written = match spliced {
        Some(tables) => {
            Provenances::of_frame(&tables.runs).refuse_mixed(allow_mixed)?;
            staged.stage_frame(&paths.0, &tables.runs, STREAMED_ROW_GROUP)?;
            staged.stage_frame(&paths.1, &tables.summary, ROW_GROUP)?;
            Written {
                rows: tables.rows,
                summary: tables.summary,
                spliced: Some(tables.read),
            }
        }
        None => {
            let identity = (header, identities.as_slice(), seqs.as_slice());
            let keyed = (points.as_slice(), keys.as_slice());
            match from_scratch::from_scratch(
                keyed,
                identity,
                store,
                &mut staged,
                &paths,
                allow_mixed,
            )? {
                Some(written) => written,
                None => return Ok(None),
            }
        }
    };
    let mut written = written;
    written.rows.sums = staged.commit()?;
    let planned_keys: HashSet<&str> = keys.iter().copied().collect();
    let collected = Collected {
        runs: paths.0,
        summary: paths.1,
        rows: written.rows.runs.len(),
        points: written.summary.height(),
        missing: points.len() - written.rows.runs.len(),
        left_out: store.count_besides(&planned_keys),
        overview: overview_of(&written.summary, &swept),
        up_to_date: false,
        spliced: written.spliced,
    };
    // Said after the tables are whole; compaction above changed no record's sequence number.
    // The tables are named by file name, beside the file that says it (`made_before`).
    let named = |path: &PathBuf| PathBuf::from(path.file_name().unwrap_or_default());
    let made = Made {
        inputs,
        collected: Collected {
            runs: named(&collected.runs),
            summary: named(&collected.summary),
            ..collected.clone()
        },
        rows: Some(written.rows),
    };
    if let Ok(text) = serde_json::to_vec(&made) {
        crate::store::write_atomically(&store.table(MADE), &text)?;
    }
    Ok(Some(collected))
}

/// Both tables staged, and what they are made of.
struct Written {
    rows: incremental::Rows,
    summary: DataFrame,
    /// How many run rows were read from their records when the tables were spliced.
    spliced: Option<usize>,
}

/// The summary rows of the points whose records `records` (by key) holds, as `collect` would
/// write them: for comparing what two result sets derive (speedups, orders).
pub fn summary_of(planned: &[Planned], records: &HashMap<String, Stored>) -> Vec<Row> {
    summary::summarize(run_rows(planned, records))
}

/// The run rows of the points whose records `records` holds. Points of different branches may
/// be one case: each gets its row from the one record.
pub fn run_rows(planned: &[Planned], records: &HashMap<String, Stored>) -> Vec<Row> {
    let to_collect = ToCollect::from_planned(planned);
    (to_collect.points.par_iter().zip(&to_collect.identities))
        .filter_map(|(p, id)| Some(run_row(p, id, records.get(p.key.as_str())?)))
        .collect()
}

/// What `collect` holds per stored run while it tabulates (its point's plan, and its share of
/// the summary's frame): 4.5 KB measured at 10⁵ runs (446 MB peak) and 4.1 KB at 10⁶ (4.1 GB)
/// with the plan held throughout, as `nlstudy run` holds it (`nlstudy collect` lets it go: 3.8
/// and 3.1 KB), with a margin for records of more columns.
const BYTES_PER_RUN: u64 = 7 << 10;

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
const PROVENANCE: [(&str, &str); 3] = [
    ("solver fingerprints", columns::FINGERPRINT),
    ("hosts", columns::HOST),
    ("instruction sets", columns::INSTRUCTION_SET),
];

/// Whether the runs that measured something (`ok`, `diverged`) came from more than one solver
/// build, host or instruction set: the first such mix, said with each value and its run count.
pub fn mixed_provenance(rows: &[Row]) -> Option<String> {
    let measured = rows
        .iter()
        .filter(|r| matches!(r.status(), Some(Status::Ok | Status::Diverged)))
        .map(|row| PROVENANCE.map(|(_, column)| row.text(column)));
    let mut provenances = Provenances::default();
    provenances.count(measured);
    provenances.mixed()
}

/// How many measured runs (`ok`, `diverged`) have each value of each of `PROVENANCE`, the values
/// in first-seen order: counted a table, or a table's slice, at a time.
#[derive(Default)]
struct Provenances([Vec<(String, usize)>; 3]);

impl Provenances {
    /// The counts of a run table's frame.
    fn of_frame(runs: &DataFrame) -> Provenances {
        let mut provenances = Provenances::default();
        provenances.count_frame(runs);
        provenances
    }

    /// Counts the measured runs of a run table's frame (or a slice of it).
    fn count_frame(&mut self, runs: &DataFrame) {
        let texts = |name| table::texts(runs, name).unwrap_or_else(|| vec![None; runs.height()]);
        let status = texts(columns::STATUS);
        let provenance = PROVENANCE.map(|(_, column)| texts(column));
        let measured = (0..runs.height())
            .filter(|&i| {
                let status = status[i].and_then(Status::parse);
                matches!(status, Some(Status::Ok | Status::Diverged))
            })
            .map(|i| [provenance[0][i], provenance[1][i], provenance[2][i]]);
        self.count(measured);
    }

    /// Counts runs, each given by its values of `PROVENANCE`.
    fn count<'a>(&mut self, measured: impl Iterator<Item = [Option<&'a str>; 3]>) {
        for run in measured {
            for (counts, value) in self.0.iter_mut().zip(run) {
                let value = value.unwrap_or("");
                match counts.iter_mut().find(|(v, _)| v == value) {
                    Some((_, n)) => *n += 1,
                    None => counts.push((value.to_string(), 1)),
                }
            }
        }
    }

    /// The first provenance of `PROVENANCE` the runs have more than one value of, said.
    fn mixed(&self) -> Option<String> {
        (PROVENANCE.iter().zip(&self.0)).find_map(|((what, _), counts)| {
            (counts.len() > 1).then(|| {
                let listed: Vec<String> = counts
                    .iter()
                    .map(|(v, n)| match (*what, v.as_str()) {
                        (_, "") => format!("unknown ({n} runs)"),
                        ("solver fingerprints", v) => format!("{} ({n} runs)", short(v)),
                        (_, v) => format!("{v:?} ({n} runs)"),
                    })
                    .collect();
                format!("the runs mix {what}: {}", listed.join(", "))
            })
        })
    }

    /// Refuses runs of several builds or machines in one table, unless `allow_mixed`.
    fn refuse_mixed(&self, allow_mixed: bool) -> Result<(), Fault> {
        match (self.mixed(), allow_mixed) {
            (Some(mixed), false) => Err(Fault::Input(format!(
                "{mixed}: one table would compare runs of different builds or machines; rerun the stale points (`nlstudy run`), or give --allow-mixed to tabulate them together"
            ))),
            _ => Ok(()),
        }
    }
}

/// The summary's headline columns: the swept fields (as `(column, shown name)`: from the case,
/// or derived by the solver), then the headline results the study has.
fn headline_columns(summary: &[Row], swept: &[String]) -> Vec<(String, String)> {
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
        summary::HEADLINE_RESULTS
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

/// `overview` of a summary table's frame: its first rows as the table holds them (a null cell
/// is no cell).
fn overview_of(summary: &DataFrame, swept: &[String]) -> String {
    let head = summary.head(Some(OVERVIEW_POINTS));
    let shown: Vec<Row> = (table::rows_of(&head).unwrap_or_default().into_iter())
        .map(|row| row.into_iter().filter(|(_, v)| !v.is_null()).collect())
        .collect();
    overview_of_rows(&shown, summary.height(), swept)
}

/// The summary at a glance, for the terminal: the headline columns of `shown`, its first
/// `OVERVIEW_POINTS` rows (of `points`), as Markdown, and how many more the table has.
fn overview_of_rows(shown: &[Row], points: usize, swept: &[String]) -> String {
    let (names, lines) = headline(shown, swept);
    let mut text = pivot::markdown_table(&names, &lines);
    if points > shown.len() {
        text += &format!(
            "… and {} more points in the summary table (`nlstudy table` pivots them)\n",
            points - shown.len()
        );
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Huge pages are off while a collect holds `SmallPages` and on again after, so that what
    /// the process starts later (a run's solvers) keeps the machine's setting.
    #[test]
    fn huge_pages_are_off_only_while_collecting() {
        let disabled = || unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) };
        assert_eq!(disabled(), 0);
        let pages = SmallPages::while_collecting();
        assert_eq!(disabled(), 1);
        drop(pages);
        assert_eq!(disabled(), 0);
    }

    #[test]
    fn a_collect_larger_than_free_memory_is_refused_before_it_reads() {
        assert!(fits_in_memory(1000, Some(1 << 30)).is_ok());
        assert!(fits_in_memory(10, None).is_ok(), "unknown: tried");
        let Err(Fault::Io(message)) = fits_in_memory(1_000_000, Some(4 << 30)) else {
            panic!("refused")
        };
        assert!(
            message.contains("1000000 stored runs") && message.contains("7.168 GB"),
            "{message}"
        );
    }

    fn overview(summary: &[Row], swept: &[String]) -> String {
        overview_of_rows(
            &summary[..summary.len().min(OVERVIEW_POINTS)],
            summary.len(),
            swept,
        )
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
