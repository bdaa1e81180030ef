//! Both tables made from the records alone, a slice of the plan at a time: each slice's runs
//! become their rows, the rows a slice of each table's frame (typed columns) and the rows'
//! shapes, and are let go. So a collect holds the frames, not a row of named cells per run
//! (about 7 KB each): the tables come out as `table::data_frame` of all the rows would make
//! them, their columns following from the shapes (`table::shape`).
//!
//! A slice ends only where every point begun in it has all its runs (a point's repeats lie
//! together in the plan), so each point's summary row is reduced within one slice. What the
//! scaling and refinement series derive reads other slices' points: it is derived at the end
//! from each point's `summary::SeriesPoint`, which is all it reads.

use super::{fits_in_memory, run_row, Provenances, Tabulated, Written};
use crate::analysis::incremental::{self, Identity};
use crate::analysis::summary::{self, Labels, SeriesPoint};
use crate::store::table::shape::{Schema, Shapes};
use crate::store::table::splice::{conform, frame_columns};
use crate::store::table::{self, Row, TableWriter, ROW_GROUP, STREAMED_ROW_GROUP};
use crate::store::{shared, Fault, Store};
use polars::prelude::{Column, DataFrame, PolarsError};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Planned points per slice, at most (more only to keep a point's runs together): about 15 MB
/// of rows at a time. (8192 held 40 MB more at 10⁵ runs, and took as long.)
const SLICE: usize = 2048;

/// `SLICE`, or `NLSTUDY_COLLECT_SLICE` where it is a whole number from 1: the tests slice small
/// studies as large ones are sliced.
fn slice_size() -> usize {
    (std::env::var("NLSTUDY_COLLECT_SLICE").ok())
        .and_then(|size| size.parse().ok())
        .filter(|&size| size > 0)
        .unwrap_or(SLICE)
}

/// A table's slices: each one's planned points and its rows' frame.
type Parts = Vec<(Range<usize>, DataFrame)>;

/// A slice's runs: the places in the plan of the points with a record, and their rows.
type Runs = (Vec<usize>, Vec<Row>);

/// The slices tabulated so far: the run table, the summary's parts, both tables' rows' shapes,
/// and what the series derive from.
#[derive(Default)]
struct Slices {
    /// The places in the plan of the points with a record.
    points: Vec<usize>,
    runs: RunTable,
    run_shapes: Shapes,
    /// The runs' provenances, for `refuse_mixed`.
    provenances: Provenances,
    reduced_parts: Parts,
    reduced_shapes: Shapes,
    /// What the series derive from, point by point.
    series: Vec<SeriesPoint>,
    /// The series' labels, each kept once.
    labels: Labels,
}

/// The run table as its slices come: written to its file while every slice keeps the columns
/// the first had (the table's columns are then known from it: a study's runs mostly have the
/// same), else held, to be stacked at the end.
#[derive(Default)]
enum RunTable {
    #[default]
    Begun,
    /// Written through the plan's point `through` (excluded), of the columns `schema`.
    Writing {
        writer: Box<TableWriter>, // (boxed: the other variants are a word or three)
        schema: Schema,
        through: usize,
    },
    Held(Parts),
}

impl Slices {
    /// The slice `slice`'s runs as both tables' parts.
    fn add(
        &mut self,
        slice: Range<usize>,
        (indices, rows): Runs,
        staged: &mut table::Staged,
        paths: &(PathBuf, PathBuf),
    ) -> Result<(), Fault> {
        if rows.is_empty() {
            return Ok(());
        }
        self.points.extend(indices);
        let known = self.run_shapes.known();
        (rows.iter()).for_each(|row| self.run_shapes.push_cells(row.typed_cells()));
        // (The whole schema, made again only when the slice brought a shape: each time would
        // go over every row so far, quadratic in the study.)
        let same_columns = |shapes: &Shapes, schema: &Schema| {
            shapes.known() == known || shapes.schema() == *schema
        };
        let frame = table::data_frame(&rows).map_err(unwritable(&paths.0))?;
        self.provenances.count_frame(&frame);
        self.runs = match std::mem::take(&mut self.runs) {
            RunTable::Begun => {
                let schema = self.run_shapes.schema();
                let writer = staged.begin(&paths.0, &frame_columns(&schema), STREAMED_ROW_GROUP)?;
                write_slice(Box::new(writer), schema, slice.end, frame, &rows, &paths.0)?
            }
            RunTable::Writing { writer, schema, .. } if same_columns(&self.run_shapes, &schema) => {
                write_slice(writer, schema, slice.end, frame, &rows, &paths.0)?
            }
            RunTable::Writing {
                writer, through, ..
            } => {
                // A slice with a column the first lacked, or of another type: what was written
                // is read back to be stacked with the rest.
                let written = writer.read_back()?;
                RunTable::Held(vec![(0..through, written), (slice.clone(), frame)])
            }
            RunTable::Held(mut parts) => {
                parts.push((slice.clone(), frame));
                RunTable::Held(parts)
            }
        };
        let reduced = summary::reduce_points(rows);
        for row in &reduced {
            self.reduced_shapes.push_cells(row.typed_cells());
            self.series
                .push(SeriesPoint::from_row(row, &mut self.labels));
        }
        let frame = table::data_frame(&reduced).map_err(unwritable(&paths.1))?;
        self.reduced_parts.push((slice, frame));
        Ok(())
    }
}

/// The slice ending at the plan's point `through`, of `frame` (made of `rows`), written as a
/// part of the table of the columns `schema`.
fn write_slice(
    mut writer: Box<TableWriter>,
    schema: Schema,
    through: usize,
    frame: DataFrame,
    rows: &[Row],
    path: &Path,
) -> Result<RunTable, Fault> {
    // (A column of text where the slice has numbers is made again of its rows.)
    let part = conform(&frame, &schema).or_else(|| {
        drop(frame);
        table::data_frame_as(rows, &schema)
    });
    writer.write(part.ok_or_else(|| changed(path))?)?;
    Ok(RunTable::Writing {
        writer,
        schema,
        through,
    })
}

/// Every stored record of the study's points read into both tables, which are staged (the run
/// table written as its slices come, or before the summary is stacked); `None` when no point
/// has a record. `keyed` is the points and their keys; `identity` the header, each
/// point's identity and sequence number.
pub(super) fn from_scratch(
    (points, keys): (&[Tabulated], &[&str]),
    (header, identities, seqs): (String, &[Identity], &[u64]),
    store: &Store,
    staged: &mut table::Staged,
    paths: &(PathBuf, PathBuf),
    allow_mixed: bool,
) -> Result<Option<Written>, Fault> {
    fits_in_memory(store.count(), super::available_memory())?;
    let runs_of = |slice: Range<usize>| -> Runs {
        let (rows, unreadable) = store.read_each(&keys[slice.clone()], |j, stored| {
            let i = slice.start + j;
            run_row(&points[i], &identities[i], &stored)
        });
        for unreadable in &unreadable {
            log::warn!("{unreadable}");
        }
        (rows.into_iter().enumerate())
            .filter_map(|(j, row)| Some((slice.start + j, row?)))
            .unzip()
    };
    let mut made = Slices::default();
    // Each slice is tabulated while the next one's records are read: the reading runs on
    // every core, the tabulating mostly on one.
    let mut read: Option<(Range<usize>, Runs)> = None;
    for slice in slices(identities, slice_size())
        .into_iter()
        .map(Some)
        .chain([None])
    {
        let (next, tabulated) = rayon::join(
            || slice.map(|slice| (slice.clone(), runs_of(slice))),
            || {
                read.take()
                    .map_or(Ok(()), |(slice, runs)| made.add(slice, runs, staged, paths))
            },
        );
        tabulated?;
        read = next;
    }
    let Slices {
        points,
        runs,
        run_shapes,
        provenances,
        reduced_parts,
        reduced_shapes,
        series,
        labels: _,
    } = made;
    if points.is_empty() {
        return Ok(None);
    }
    provenances.refuse_mixed(allow_mixed)?;
    match runs {
        RunTable::Writing { writer, .. } => writer.finish()?,
        RunTable::Held(parts) => {
            // A slice whose frame cannot be conformed to the whole table's columns (a column of
            // numbers there, of text in the whole) is made again of its rows.
            let run_schema = run_shapes.schema();
            let runs = stack(parts, &run_schema, &|slice| {
                let rows = runs_of(slice).1;
                table::data_frame_as(&rows, &run_schema)
            })
            .ok_or_else(|| changed(&paths.0))?;
            staged.stage_frame(&paths.0, &runs, STREAMED_ROW_GROUP)?;
        }
        RunTable::Begun => unreachable!("a slice with runs begins the table"),
    }

    let remake = |slice| summary::reduce_points(runs_of(slice).1);
    let (summary, summary_shapes) =
        summary_frame(reduced_parts, &reduced_shapes, series, &remake, &paths.1)?;
    staged.stage_frame(&paths.1, &summary, ROW_GROUP)?;
    Ok(Some(Written {
        rows: incremental::Rows::from_points(
            header,
            identities,
            seqs,
            &points,
            (&run_shapes, &summary_shapes),
        ),
        summary,
        spliced: None,
    }))
}

/// The summary's frame and its rows' shapes: the slices' reduced rows (`parts`, of the shapes
/// `reduced_shapes`; made again of their runs by `remake` where they cannot be stacked) with
/// the cells the series derive from `series` (what they read of each point) in their columns'
/// places, as one frame of whole summary rows would have them.
fn summary_frame(
    parts: Parts,
    reduced_shapes: &Shapes,
    mut series: Vec<SeriesPoint>,
    remake: &dyn Fn(Range<usize>) -> Vec<Row>,
    path: &Path,
) -> Result<(DataFrame, Shapes), Fault> {
    summary::derive_series(&mut series);
    let derived: Vec<Row> = (series.into_par_iter())
        .map(|point| (point.derived.into_iter()).map(|(name, value)| (shared(name), value)))
        .map(Row::from_iter)
        .collect();
    let mut shapes = Shapes::default();
    for (k, cells) in derived.iter().enumerate() {
        let reduced = (reduced_shapes.of_row(k).iter()).map(|(name, kind)| (name, *kind));
        shapes.push_cells(reduced.chain(cells.typed_cells()));
    }
    let schema = shapes.schema();
    let derived_names: HashSet<&str> = (derived.iter())
        .flat_map(|row| row.cells().map(|(name, _)| name))
        .collect();
    let (derived_schema, reduced_schema): (Schema, Schema) =
        (schema.iter().cloned()).partition(|(name, _)| derived_names.contains(&**name));
    if (reduced_shapes.schema().iter()).any(|(name, _)| derived_names.contains(&**name)) {
        // (No record has a column the series derive: `summary`'s tests hold it.)
        return Err(Fault::Io(format!(
            "cannot write {}: a run's row has a column the summary derives",
            path.display()
        )));
    }
    let reduced = stack(parts, &reduced_schema, &|slice| {
        table::data_frame_as(&remake(slice), &reduced_schema)
    })
    .ok_or_else(|| changed(path))?;
    let derived = table::data_frame_as(&derived, &derived_schema).ok_or_else(|| changed(path))?;
    let column = |name: &str| -> Column {
        (derived.column(name).or_else(|_| reduced.column(name)))
            .expect("a column of the schema")
            .clone()
    };
    let columns = schema.iter().map(|(name, _)| column(name)).collect();
    let frame = DataFrame::new(reduced.height(), columns).map_err(unwritable(path))?;
    Ok((frame, shapes))
}

fn unwritable(path: &Path) -> impl Fn(PolarsError) -> Fault + '_ {
    move |e| Fault::Io(format!("cannot write {}: {e}", path.display()))
}

/// A table's slices are not what its records make now: a record changed under the collect.
fn changed(path: &Path) -> Fault {
    Fault::Io(format!(
        "cannot write {}: the stored records changed while they were read; collect again",
        path.display()
    ))
}

/// The planned points in slices of about `size` (in plan order), each ending where every point
/// label begun in it has ended: a label seen again after a slice ended would split a point.
fn slices(identities: &[Identity], size: usize) -> Vec<Range<usize>> {
    let mut last: HashMap<&str, usize> = HashMap::new();
    for (i, identity) in identities.iter().enumerate() {
        last.insert(&identity.label, i);
    }
    let (mut slices, mut start, mut reach) = (Vec::new(), 0, 0);
    for (i, identity) in identities.iter().enumerate() {
        reach = reach.max(last[identity.label.as_str()]);
        if i == reach && i + 1 - start >= size {
            slices.push(start..i + 1);
            start = i + 1;
        }
    }
    if start < identities.len() {
        slices.push(start..identities.len());
    }
    slices
}

/// The slices' frames as one of the columns `schema` names, in order: each conformed to it, or
/// where it cannot be, made again (`remake`, of its slice's records). Put together a column at a
/// time, each slice's piece let go as its column is made, so that the table is held once and
/// a column, not twice.
fn stack(
    parts: Parts,
    schema: &Schema,
    remake: &dyn Fn(Range<usize>) -> Option<DataFrame>,
) -> Option<DataFrame> {
    let mut conformed = Vec::with_capacity(parts.len());
    for (slice, part) in parts {
        conformed.push(conform(&part, schema).or_else(|| {
            drop(part);
            remake(slice)
        })?);
    }
    let height = conformed.iter().map(DataFrame::height).sum();
    let columns = (schema.iter())
        .map(|(name, _)| {
            let mut pieces = conformed.iter_mut().map(|part| part.drop_in_place(name));
            let mut column = pieces.next()?.ok()?;
            for piece in pieces {
                column.append_owned(piece.ok()?).ok()?;
            }
            Some(column.rechunk())
        })
        .collect::<Option<Vec<Column>>>()?;
    DataFrame::new(height, columns).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{json, Value};

    fn identities(labels: &[&str]) -> Vec<Identity> {
        (labels.iter())
            .map(|label| Identity {
                signature: String::new(),
                label: label.to_string(),
                refinement: String::new(),
                scaling: String::new(),
            })
            .collect()
    }

    #[test]
    fn slices_are_stacked_as_one_frame_of_their_rows_would_be() {
        let row = |a: Value| Row::of_cells(json!({ "a": a, "b": 2 }));
        let rows = [
            row(json!(1)),
            row(json!(1.5)),
            row(json!(2)),
            row(json!("x")),
        ];
        let part = |slice: Range<usize>| (slice.clone(), table::data_frame(&rows[slice]).unwrap());
        let remade = std::cell::RefCell::new(Vec::new());
        let remake = |slice: Range<usize>| {
            remade.borrow_mut().push(slice.clone());
            table::data_frame_as(&rows[slice], &table::shapes(&rows).schema())
        };
        // Integers widen to floats in place; a slice of numbers where the table has text is
        // made again of its rows.
        let schema = table::shapes(&rows[..3]).schema();
        let floats = stack(vec![part(0..1), part(1..3)], &schema, &remake).unwrap();
        assert!(floats.equals_missing(&table::data_frame(&rows[..3]).unwrap()));
        assert!(remade.borrow().is_empty());
        let schema = table::shapes(&rows).schema();
        let texts = stack(vec![part(0..3), part(3..4)], &schema, &remake).unwrap();
        assert!(texts.equals_missing(&table::data_frame(&rows).unwrap()));
        assert_eq!(
            (remade.borrow().len(), remade.borrow()[0].clone()),
            (1, 0..3)
        );
    }

    #[test]
    fn slices_keep_each_points_runs_together() {
        let labels = ["a", "a", "b", "c", "c", "c", "d", "b", "e", "f"];
        let slices = slices(&identities(&labels), 2);
        // "b" comes again at 7, so the slice begun at 2 runs to 7.
        assert_eq!(slices, [0..2, 2..8, 8..10]);
        let whole = super::slices(&identities(&labels), 100);
        assert_eq!((whole.len(), whole[0].clone()), (1, 0..10));
        assert_eq!(
            super::slices(&identities(&["a", "b", "c"]), 1),
            [0..1, 1..2, 2..3]
        );
        assert!(super::slices(&identities(&[]), 4).is_empty());
    }
}
