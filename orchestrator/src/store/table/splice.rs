//! A table remade from the table it was and the rows that changed, as `data_frame` would make
//! it of all its rows: the columns follow from the rows' shapes (`shape`), the kept rows' cells
//! from the old frame, and only the new rows are read cell by cell.

use crate::store::table::shape::{ColumnType, Schema, Shapes};
use crate::store::table::{data_frame_as, Row};
use polars::prelude::*;

/// Where a row of a spliced table comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Source {
    /// Row k of the old table.
    Kept(usize),
    /// The j-th new row.
    New(usize),
}

/// The table whose rows are `order`'s (each new row once), and its rows' shapes; `None` where
/// the old frame cannot give the cells the whole table would hold (a column whose type
/// narrows once some rows are gone, or widens to text), or does not match `old_shapes`.
pub fn splice(
    old: &DataFrame,
    old_shapes: &Shapes,
    new: &[Row],
    order: &[Source],
) -> Option<(DataFrame, Shapes)> {
    if old.height() != old_shapes.rows() {
        return None;
    }
    let mut unplaced: Vec<Option<&Row>> = new.iter().map(Some).collect();
    let mut shapes = Shapes::shapes_of(old_shapes);
    for &source in order {
        match source {
            Source::Kept(k) if k < old.height() => shapes.push_row_of(old_shapes, k),
            Source::New(j) => shapes.push_cells(unplaced.get_mut(j)?.take()?.typed_cells()),
            Source::Kept(_) => return None,
        }
    }
    let schema = shapes.schema();
    let all = conform(old, &schema)?
        .vstack(&data_frame_as(new, &schema)?)
        .ok()?;
    let index: Vec<IdxSize> = order
        .iter()
        .map(|source| match *source {
            Source::Kept(k) => k as IdxSize,
            Source::New(j) => (old.height() + j) as IdxSize,
        })
        .collect();
    let mut frame = rows_at(&all, index)?;
    frame.rechunk_mut_par();
    Some((frame, shapes))
}

/// The rows of `all` at `index`: slices of its runs of consecutive rows where they are few (a
/// table that grew or lost a few points is a few runs, and a slice costs no copy), else
/// gathered one by one (a row at a time costs a copy of each cell, text the most).
fn rows_at(all: &DataFrame, index: Vec<IdxSize>) -> Option<DataFrame> {
    const MOST_RUNS: usize = 1024;
    let mut runs: Vec<(IdxSize, IdxSize)> = Vec::new();
    for &k in &index {
        if let Some((_, length)) = runs.last_mut().filter(|(s, l)| *s + *l == k) {
            *length += 1;
        } else if runs.len() == MOST_RUNS {
            return all.take(&IdxCa::from_vec(PlSmallStr::EMPTY, index)).ok();
        } else {
            runs.push((k, 1));
        }
    }
    let mut frame = all.clear();
    for (start, length) in runs {
        frame
            .vstack_mut(&all.slice(start as i64, length as usize))
            .ok()?;
    }
    Some(frame)
}

/// The old frame's columns as `schema` has them: a column it lacks all null, integers widened
/// to floats, a column of nulls only of any type; `None` if a column's cells cannot be of the
/// type `schema` gives it.
pub fn conform(old: &DataFrame, schema: &Schema) -> Option<DataFrame> {
    let columns = schema
        .iter()
        .map(|(name, kind)| {
            let name = PlSmallStr::from(&**name);
            let want = data_type(*kind);
            let nulls = || Series::full_null(name.clone(), old.height(), &want).into_column();
            match old.column(&name) {
                Err(_) => Some(nulls()),
                Ok(column) if column_type(column.dtype()) == Some(*kind) => Some(column.clone()),
                Ok(column) if column.null_count() == column.len() => Some(nulls()),
                Ok(column) if *kind == ColumnType::Float && column.dtype() == &DataType::Int64 => {
                    column.cast(&DataType::Float64).ok()
                }
                Ok(_) => None,
            }
        })
        .collect::<Option<Vec<Column>>>()?;
    DataFrame::new(old.height(), columns).ok()
}

/// The columns of a frame of `schema` as polars has them (`conform` makes them so).
pub fn frame_columns(schema: &Schema) -> polars::prelude::Schema {
    (schema.iter())
        .map(|(name, kind)| Field::new(PlSmallStr::from(&**name), data_type(*kind)))
        .collect()
}

/// The polars type of a column of `kind`, as `table::data_frame` makes it.
fn data_type(kind: ColumnType) -> DataType {
    match kind {
        ColumnType::Boolean => DataType::Boolean,
        ColumnType::Integer => DataType::Int64,
        ColumnType::Float => DataType::Float64,
        ColumnType::Floats => DataType::List(Box::new(DataType::Float64)),
        ColumnType::Text => DataType::String,
    }
}

fn column_type(dtype: &DataType) -> Option<ColumnType> {
    [
        ColumnType::Boolean,
        ColumnType::Integer,
        ColumnType::Float,
        ColumnType::Floats,
        ColumnType::Text,
    ]
    .into_iter()
    .find(|kind| data_type(*kind) == *dtype)
}
