//! A collect after a collect: the tables remade from the tables they were and the records
//! stored, rerun or gone since, byte for byte as a collect from scratch would make them.
//!
//! Beside the tables, each collect keeps each run row's point (`Identity::signature`) with the
//! sequence number of the record it was made of, and both tables' row shapes
//! (`table::shape`). A run row whose point and record are as they were is kept from the old
//! table; the others are read from their records. A point's summary row is made again when its
//! runs changed or when a point of its refinement or scaling series did (orders and speedups
//! read the series): reduced from its runs, then derived along its series, whose other points
//! lend what the derivation reads from their rows in the old summary. The rest are kept.

use crate::analysis::summary::{self, Cell};
use crate::run::plan::Planned;
use crate::store::table::shape::{Kept, Shapes};
use crate::store::table::splice::{splice, Source};
use crate::store::table::{self, Row};
use crate::store::Store;
use polars::prelude::DataFrame;
use rayon::prelude::*;
use schema::record::Stored;
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// What sets a point's run row apart: its key, labels and resolved case, hashed
/// (`signature`), and the labels its summary row is grouped and derived by.
pub struct Identity {
    /// 128 bits of SHA-256 over the key, the labels and the solver's resolved case, in hex.
    pub signature: String,
    /// The point's label without its repeat: its summary row's.
    pub label: String,
    pub refinement: String,
    pub scaling: String,
}

/// Each planned point's identity, worked out on every core.
pub fn identities(planned: &[Planned]) -> Vec<Identity> {
    use sha2::Digest;
    planned
        .par_iter()
        .map(|p| {
            let label = p.point.label_without_repeat();
            let series = p.point.series();
            let resolution = match &p.case {
                Ok(checked) => checked.resolution_text(),
                Err(refusal) => refusal,
            };
            let line = format!(
                "{} {label:?} {:?} {:?} {:?} {resolution}",
                p.key, p.point.branch, series.refinement, series.scaling
            );
            let digest = sha2::Sha256::digest(line.as_bytes());
            Identity {
                signature: crate::store::hex(&digest[..16]),
                label,
                refinement: series.refinement,
                scaling: series.scaling,
            }
        })
        .collect()
}

/// What a collect's tables are made of, row by row, kept beside them for the next to splice.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct Rows {
    /// What else the tables depend on (the nlstudy build, the study's description, whether
    /// provenance may mix): tables made under another are not spliced.
    pub header: String,
    /// Each run row's point signature and its record's sequence number, in row order.
    pub runs: Vec<(String, u64)>,
    pub run_shapes: Kept,
    pub summary_shapes: Kept,
    /// The SHA-256 of the run table and of the summary these rows are of: rows of other tables
    /// (a collect killed before it said what it made) are not spliced.
    pub sums: Vec<String>,
}

/// Both tables as frames, and what they are made of.
pub struct Tables {
    pub runs: DataFrame,
    pub summary: DataFrame,
    pub rows: Rows,
    /// How many run rows were read from their records.
    pub read: usize,
}

/// The tables as the last collect made them (`prior`, its tables at `paths`) with the runs of
/// the points (by their `keys`) whose records changed since made from the store (`make_row`), and the summary
/// rows they change; `None` when they cannot be spliced (a table not whole, a column whose
/// type the change narrows) or when most runs changed: then a collect from scratch is as
/// quick.
pub fn spliced(
    keys: &[&str],
    identities: &[Identity],
    seqs: &[u64],
    store: &Store,
    prior: Rows,
    paths: (&Path, &Path),
    make_row: &(dyn Fn(usize, &Stored) -> Row + Sync),
) -> Option<Tables> {
    let (old_runs, runs_sum) = table::read_frame(paths.0).ok()?;
    let (old_summary, summary_sum) = table::read_frame(paths.1).ok()?;
    if prior.sums != [runs_sum, summary_sum] {
        return None;
    }
    let old_run_shapes = Shapes::from_kept(prior.run_shapes)?;
    let old_summary_shapes = Shapes::from_kept(prior.summary_shapes)?;
    if prior.runs.len() != old_runs.height() {
        return None;
    }
    let row_of = |i: usize| Some(make_row(i, &store.stored_as_read(keys[i])?));
    let runs = run_rows(identities, seqs, &prior.runs, &row_of)?;
    let (summary_order, new_summary) =
        summary_rows(identities, &runs, &old_runs, &old_summary, &row_of)?;
    let (runs_frame, run_shapes) = splice(&old_runs, &old_run_shapes, &runs.read, &runs.order)?;
    let (summary, summary_shapes) = splice(
        &old_summary,
        &old_summary_shapes,
        &new_summary,
        &summary_order,
    )?;
    Some(Tables {
        runs: runs_frame,
        summary,
        read: runs.read.len(),
        rows: Rows::from_points(
            prior.header,
            identities,
            seqs,
            &runs.points,
            (&run_shapes, &summary_shapes),
        ),
    })
}

/// The rows of a spliced run table.
struct RunRows {
    /// Where each row comes from.
    order: Vec<Source>,
    /// Each row's planned point.
    points: Vec<usize>,
    /// The rows read from their records.
    read: Vec<Row>,
    /// Whether each old row is kept.
    kept: Vec<bool>,
}

/// The run rows: each planned point's with a record, kept from the old table (whose rows were
/// made of `before`: each one's point signature and record sequence number) if its point and
/// record are as they were, else read (`row_of`); `None` if most are to be read.
fn run_rows(
    identities: &[Identity],
    seqs: &[u64],
    before: &[(String, u64)],
    row_of: &(dyn Fn(usize) -> Option<Row> + Sync),
) -> Option<RunRows> {
    let at: HashMap<&str, (usize, u64)> = (before.iter().enumerate())
        .map(|(k, (signature, seq))| (signature.as_str(), (k, *seq)))
        .collect();
    let mut kept = vec![false; before.len()];
    let mut stored: Vec<(usize, Option<usize>)> = Vec::new();
    for (i, identity) in identities.iter().enumerate() {
        let old = match at.get(identity.signature.as_str()) {
            Some(&(k, seq)) if seq == seqs[i] && !std::mem::replace(&mut kept[k], true) => Some(k),
            _ => None,
        };
        // (Sequence number 0: no record stored.)
        if old.is_some() || seqs[i] > 0 {
            stored.push((i, old));
        }
    }
    let to_read = stored.iter().filter(|(_, old)| old.is_none()).count();
    if 2 * to_read > stored.len() {
        return None;
    }
    let mut fresh = (stored.par_iter())
        .map(|&(i, old)| old.map_or_else(|| row_of(i), |_| None))
        .collect::<Vec<_>>()
        .into_iter();
    // A record gone unreadable since the catalog listed it leaves its point out, as a collect
    // from scratch would.
    let mut rows = RunRows {
        order: Vec::new(),
        points: Vec::new(),
        read: Vec::new(),
        kept,
    };
    for (i, old) in stored {
        match (old, fresh.next().flatten()) {
            (Some(k), _) => rows.order.push(Source::Kept(k)),
            (None, Some(row)) => {
                rows.order.push(Source::New(rows.read.len()));
                rows.read.push(row);
            }
            (None, None) => continue,
        }
        rows.points.push(i);
    }
    Some(rows)
}

/// The summary rows of a spliced summary table: where each comes from, and those made again.
///
/// Long because each summary row's source (kept, made again, gone) is decided in one walk over the
/// old and the new identities side by side.
fn summary_rows(
    identities: &[Identity],
    runs: &RunRows,
    old_runs: &DataFrame,
    old_summary: &DataFrame,
    row_of: &(dyn Fn(usize) -> Option<Row> + Sync),
) -> Option<(Vec<Source>, Vec<Row>)> {
    fn labels(id: &Identity) -> [&str; 3] {
        [&id.label, &id.refinement, &id.scaling]
    }
    // The points and series whose runs changed or went.
    let mut changed: [HashSet<&str>; 3] = Default::default();
    let gone = [
        table::texts(old_runs, "point")?,
        table::texts(old_runs, "refinement_series")?,
        table::texts(old_runs, "scaling_series")?,
    ];
    for k in (0..runs.kept.len()).filter(|&k| !runs.kept[k]) {
        for (set, column) in changed.iter_mut().zip(&gone) {
            set.extend(column[k]);
        }
    }
    for (source, &i) in runs.order.iter().zip(&runs.points) {
        if let Source::New(_) = source {
            for (set, label) in changed.iter_mut().zip(labels(&identities[i])) {
                set.insert(label);
            }
        }
    }
    let touches = |sets: &[HashSet<&str>; 3], id: &Identity| {
        (sets.iter().zip(labels(id))).any(|(set, label)| set.contains(label))
    };
    // The points made again: the changed ones and those on a changed series, reduced from
    // their runs. The other points on their series lend what the series derive from
    // (`summary::DERIVED_FROM`) from their rows in the old summary.
    let mut remade: [HashSet<&str>; 3] = Default::default();
    for id in runs.points.iter().map(|&i| &identities[i]) {
        if !touches(&changed, id) {
            continue;
        }
        for (set, label) in remade.iter_mut().zip(labels(id)) {
            set.insert(label);
        }
    }
    let inputs: Vec<(Source, usize)> = (runs.order.iter().zip(&runs.points))
        .filter(|(_, &i)| remade[0].contains(identities[i].label.as_str()))
        .map(|(&source, &i)| (source, i))
        .collect();
    let inputs = (inputs.par_iter())
        .map(|&(source, i)| match source {
            Source::New(j) => Some(runs.read[j].clone()),
            Source::Kept(_) => row_of(i),
        })
        .collect::<Option<Vec<Row>>>()?;
    let mut reduced: HashMap<String, Row> = (summary::reduce_points(inputs).into_iter())
        .filter_map(|row| Some((row.text("point")?.to_string(), row)))
        .collect();
    let old_row: HashMap<&str, usize> = (table::texts(old_summary, "point")?.into_iter())
        .enumerate()
        .filter_map(|(k, label)| Some((label?, k)))
        .collect();
    // The summary's points in order (where each first runs), and their sources.
    let mut seen: HashSet<&str> = HashSet::new();
    let points: Vec<&Identity> = (runs.points.iter().map(|&i| &identities[i]))
        .filter(|id| seen.insert(&id.label))
        .collect();
    let lenders: Vec<usize> = (points.iter())
        .filter(|id| !remade[0].contains(id.label.as_str()) && touches(&remade, id))
        .map(|id| old_row.get(id.label.as_str()).copied())
        .collect::<Option<_>>()?;
    let mut lent = lent_rows(old_summary, &lenders)?.into_iter();
    let mut series: Vec<Row> = Vec::new();
    let mut order = Vec::new();
    for id in &points {
        if remade[0].contains(id.label.as_str()) {
            order.push(Source::New(series.len()));
            series.push(reduced.remove(&id.label)?);
        } else {
            order.push(Source::Kept(*old_row.get(id.label.as_str())?));
            if touches(&remade, id) {
                series.push(lent.next()?);
            }
        }
    }
    summary::derive(&mut series);
    let rows = (order.iter())
        .filter_map(|source| match source {
            Source::New(j) => Some(std::mem::take(&mut series[*j])),
            Source::Kept(_) => None,
        })
        .collect();
    // (The remade rows were numbered by their place among the series' rows: renumber.)
    let mut next = 0;
    for source in &mut order {
        if let Source::New(j) = source {
            *j = next;
            next += 1;
        }
    }
    Some((order, rows))
}

/// Rows `rows` of the old summary as `summary::derive` reads them: the `DERIVED_FROM`
/// columns; `None` if one holds cells other than `derive` would read (text where a number
/// is read): the rows would not lend what the records would.
fn lent_rows(old_summary: &DataFrame, rows: &[usize]) -> Option<Vec<Row>> {
    use polars::prelude::{DataType, IdxCa, IdxSize, PlSmallStr};
    let mut names = Vec::new();
    for (name, cell) in summary::DERIVED_FROM {
        let Ok(column) = old_summary.column(name) else {
            continue;
        };
        let fits = match (cell, column.dtype()) {
            (_, _) if column.null_count() == column.len() => true,
            (Cell::Text, DataType::String) | (Cell::Count, DataType::Int64) => true,
            (Cell::Number, DataType::Int64 | DataType::Float64) => true,
            _ => false,
        };
        if !fits {
            return None;
        }
        names.push(*name);
    }
    let index = IdxCa::from_vec(
        PlSmallStr::EMPTY,
        rows.iter().map(|&k| k as IdxSize).collect(),
    );
    let lent = old_summary.select(names).ok()?.take(&index).ok()?;
    table::rows_of(&lent).ok()
}

impl Rows {
    /// What tables are made of: the run rows of `points` (planned indices, in row order) and
    /// the rows' shapes (their sums are said once they are written).
    pub fn from_points(
        header: String,
        identities: &[Identity],
        seqs: &[u64],
        points: &[usize],
        (runs, summary): (&Shapes, &Shapes),
    ) -> Rows {
        Rows {
            header,
            runs: points
                .iter()
                .map(|&i| (identities[i].signature.clone(), seqs[i]))
                .collect(),
            run_shapes: runs.kept(),
            summary_shapes: summary.kept(),
            sums: Vec::new(),
        }
    }
}
