//! Rows of named JSON cells, and their Parquet form: a column's type is read off its cells
//! (booleans, integers, floats, arrays of numbers as lists of floats, else text), and each file
//! says what it holds in its key–value metadata: `description` (the study's), `unit:<column>`
//! for each column with a unit (read off its name, `unit`) and `note:<column>` for each column
//! its writer explains.
//!
//! Beside each table, `<table>.sha256` holds its SHA-256 in `sha256sum`'s format (so
//! `sha256sum -c quick.parquet.sha256` checks it by hand). A reader checks it before polars
//! parses a byte: polars aborts the process on some corrupt data pages (it reserves what a
//! corrupt length asks for), which no `catch_unwind` can stop. A table copied without its sum is
//! read unchecked, under the footer check and `catch_unwind`, which catch most corruption.

pub mod shape;
pub mod splice;

use crate::model::expression::Filter;
use crate::store::fs::Fault;
use crate::store::shared::{shared, Shared};
use polars::prelude::*;
use rayon::prelude::*;
use schema::record::columns;
use schema::record::Status;
use serde_json::{Map, Value};
use sha2::Digest;
use shape::{column_type, ColumnType, Schema};
// A frame's columns as polars has them (`Schema` is the table's, of `shape`).
use polars::prelude::Schema as Columns;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

/// A column's name as rows hold it, shared by every row that has the column: a study's rows
/// repeat the same hundred names, so each is made once, not once per cell (half of what a
/// collect of 10⁵ runs allocated).
pub type Name = Shared;

/// A table row: named cells in column order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Row(Vec<(Name, Value)>);

impl IntoIterator for Row {
    type Item = (Name, Value);
    type IntoIter = std::vec::IntoIter<(Name, Value)>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl FromIterator<(Name, Value)> for Row {
    /// A row of `cells`, whose names must differ (as another row's do): no name is looked for.
    fn from_iter<I: IntoIterator<Item = (Name, Value)>>(cells: I) -> Row {
        Row(cells.into_iter().collect())
    }
}

impl Row {
    /// A row as expression names, as a study's own `where` reads them
    /// (`expression::fields_of_columns`).
    pub fn expression_fields(&self) -> Map<String, Value> {
        crate::model::expression::fields_of_columns(&self.0)
    }

    /// The cell an expression's name reads (`expression_fields`): the case's field of that
    /// name unless null, else the column.
    fn expression_field(&self, name: &str) -> Option<&Value> {
        let case = self
            .cells()
            .find(|(n, v)| n.strip_prefix("case.") == Some(name) && !v.is_null());
        case.map(|(_, v)| v).or_else(|| self.get(name))
    }

    /// Whether the row meets `filter`'s conditions (the first that cannot be evaluated here
    /// says which and why).
    pub fn meets(&self, filter: &Filter) -> Result<bool, (usize, String)> {
        filter.keeps(
            |name| self.expression_field(name),
            || self.expression_fields(),
        )
    }

    pub fn get(&self, name: &str) -> Option<&Value> {
        self.0.iter().find(|(n, _)| **n == *name).map(|(_, v)| v)
    }

    pub fn number(&self, name: &str) -> Option<f64> {
        self.get(name).and_then(Value::as_f64)
    }

    /// A cell holding a whole number of things (threads, workers, repeats).
    pub fn count(&self, name: &str) -> Option<u64> {
        self.get(name).and_then(Value::as_u64)
    }

    pub fn text(&self, name: &str) -> Option<&str> {
        self.get(name).and_then(Value::as_str)
    }

    /// The run's status (`None` for a summary row whose repeats are `mixed`).
    pub fn status(&self) -> Option<Status> {
        self.text(columns::STATUS).and_then(Status::parse)
    }

    /// Sets a cell, in place if the column is there, else as a new last column.
    pub fn set(&mut self, name: &str, value: Value) {
        match self.0.iter_mut().find(|(n, _)| **n == *name) {
            Some((_, cell)) => *cell = value,
            None => self.0.push((shared(name), value)),
        }
    }

    /// Adds the cell of a column the row lacks, last; the caller knows it lacks it (nothing is
    /// looked for).
    pub fn push_new(&mut self, name: Name, value: Value) {
        self.0.push((name, value));
    }

    /// A row of the given cells, a JSON object's fields in their order (for tests).
    #[cfg(test)]
    pub(crate) fn of_cells(cells: Value) -> Row {
        let mut row = Row::default();
        for (name, value) in cells.as_object().expect("cells as a JSON object") {
            row.set(name, value.clone());
        }
        row
    }

    /// The row's shape, cell by cell: its columns' names in order, each with its cell's type.
    pub fn typed_cells(&self) -> impl Iterator<Item = (&Name, Option<ColumnType>)> + Clone {
        self.0.iter().map(|(n, v)| (n, shape::column_type_of(v)))
    }

    pub fn cells(&self) -> impl Iterator<Item = (&str, &Value)> {
        self.0.iter().map(|(n, v)| (&**n, v))
    }

    fn named_cells(&self) -> impl Iterator<Item = (&Name, &Value)> {
        self.0.iter().map(|(n, v)| (n, v))
    }

    /// Sets a cell, or one cell per field of an object, named `name.field` (recursively).
    pub fn set_flattened(&mut self, name: &str, value: Value) {
        self.set_all_flattened([(name, value)]);
    }

    /// `set_flattened` of each of `fields`, whose names differ and, if they are more than one,
    /// hold no `.`: so the fields' flattened names differ from each other's, and each is looked
    /// for only among the cells the row had before. (A record's hundred columns then cost a
    /// hundred short lookups, not five thousand long ones.)
    pub fn set_all_flattened<N: AsRef<str>>(
        &mut self,
        fields: impl IntoIterator<Item = (N, Value)>,
    ) {
        let before = self.0.len();
        for (name, value) in fields {
            columns::flatten(
                name.as_ref(),
                value,
                &mut |name, value| match self.0[..before].iter_mut().find(|(n, _)| **n == *name) {
                    Some((_, cell)) => *cell = value,
                    None => self.0.push((shared(name), value)),
                },
            );
        }
    }
}

/// The cells of the text column `name` of `frame`; `None` if it has no text column so named.
pub fn texts<'a>(frame: &'a DataFrame, name: &str) -> Option<Vec<Option<&'a str>>> {
    let column = frame.column(name).ok()?;
    (column.dtype() == &DataType::String).then_some(())?;
    Some(column.as_materialized_series().str().ok()?.iter().collect())
}

/// The shapes of `rows`, in order.
#[cfg(test)]
pub fn shapes(rows: &[Row]) -> shape::Shapes {
    let mut shapes = shape::Shapes::default();
    for row in rows {
        shapes.push_cells(row.typed_cells());
    }
    shapes
}

/// The cells of column `name`, one per row, null where a row lacks it.
pub fn column<'a>(rows: &'a [Row], name: &str) -> Vec<&'a Value> {
    rows.iter()
        .map(|row| row.get(name).unwrap_or(&Value::Null))
        .collect()
}

/// The rows as a data frame; its columns are the union of the rows' cells in first-seen order,
/// a cell a row lacks being null.
pub fn data_frame(rows: &[Row]) -> PolarsResult<DataFrame> {
    let (names, columns) = deal(rows);
    let columns = names
        .into_par_iter()
        .zip(columns)
        .map(|(name, cells)| {
            let kind = column_type(cells.iter().copied());
            typed_column(name, &cells, kind)
        })
        .collect();
    DataFrame::new(rows.len(), columns)
}

/// The rows as a data frame of the columns `schema` names, of its types (a column no row has
/// is all null); `None` if a row has a column `schema` lacks or a cell its type cannot hold.
pub fn data_frame_as(rows: &[Row], schema: &Schema) -> Option<DataFrame> {
    let (names, mut cells) = deal(rows);
    let mut at: HashMap<&str, usize> = names.iter().enumerate().map(|(k, n)| (&***n, k)).collect();
    static NULL: Value = Value::Null;
    let nulls = vec![&NULL; rows.len()];
    let columns: Vec<(&Name, Vec<&Value>, ColumnType)> = schema
        .iter()
        .map(|(name, kind)| {
            let column = at.remove(&**name).map(|k| std::mem::take(&mut cells[k]));
            (name, column.unwrap_or_else(|| nulls.clone()), *kind)
        })
        .collect();
    let fits = |cells: &[&Value], kind| {
        cells
            .iter()
            .copied()
            .map(shape::column_type_of)
            .fold(Some(kind), shape::join)
            == Some(kind)
    };
    if !at.is_empty() || !columns.iter().all(|(_, cells, kind)| fits(cells, *kind)) {
        return None;
    }
    let columns = columns
        .into_par_iter()
        .map(|(name, cells, kind)| typed_column(name, &cells, kind))
        .collect();
    DataFrame::new(rows.len(), columns).ok()
}

/// The rows' cells dealt into their columns in one pass (a row's names are distinct): the
/// columns' names in first-seen order, and each column's cells, null where a row lacks it.
fn deal(rows: &[Row]) -> (Vec<&Name>, Vec<Vec<&Value>>) {
    // Rows mostly have the columns of the row before, in its order: a cell's column is looked
    // up by name only where it is not the one the row before had in its place.
    static NULL: Value = Value::Null;
    let mut index: HashMap<&str, usize> = HashMap::new();
    let mut names: Vec<&Name> = Vec::new();
    let mut columns: Vec<Vec<&Value>> = Vec::new();
    let mut before: Vec<usize> = Vec::new();
    for (r, row) in rows.iter().enumerate() {
        for (place, (name, value)) in row.named_cells().enumerate() {
            let k = match before.get(place) {
                Some(&k) if names[k] == name => k,
                _ => *index.entry(name).or_insert_with(|| {
                    names.push(name);
                    columns.push(vec![&NULL; r]);
                    names.len() - 1
                }),
            };
            match before.get_mut(place) {
                Some(slot) => *slot = k,
                None => before.push(k),
            }
            match columns[k].len() > r {
                // A second cell of one name in this row (a record's field `a.b` beside a group
                // `a`, flattened alike): the later stands, as the later of two equal keys does
                // in a JSON object; a second push would shift every row after it.
                true => *columns[k].last_mut().expect("this row's cell") = value,
                false => columns[k].push(value),
            }
        }
        for column in columns.iter_mut().filter(|c| c.len() == r) {
            column.push(&NULL);
        }
    }
    (names, columns)
}

/// The column `name` of `cells`, of type `kind` (which holds every cell).
fn typed_column(name: &Name, cells: &[&Value], kind: ColumnType) -> Column {
    let name = PlSmallStr::from(&**name);
    match kind {
        ColumnType::Boolean => {
            Column::new(name, cells.iter().map(|v| v.as_bool()).collect::<Vec<_>>())
        }
        ColumnType::Integer => {
            Column::new(name, cells.iter().map(|v| v.as_i64()).collect::<Vec<_>>())
        }
        ColumnType::Float => {
            Column::new(name, cells.iter().map(|v| v.as_f64()).collect::<Vec<_>>())
        }
        ColumnType::Floats => {
            let lists: Vec<Option<Series>> = cells
                .iter()
                .map(|v| {
                    let items = v.as_array()?.iter().map(Value::as_f64);
                    Some(Series::new(PlSmallStr::EMPTY, items.collect::<Vec<_>>()))
                })
                .collect();
            Column::new(name, lists)
        }
        ColumnType::Text => {
            let texts: Vec<Option<Cow<str>>> = cells.iter().map(|v| text_of(v)).collect();
            let texts: Vec<Option<&str>> = texts.iter().map(Option::as_deref).collect();
            Column::new(name, texts)
        }
    }
}

/// A cell of a text column: a string as it is, anything else as its JSON.
fn text_of(value: &Value) -> Option<Cow<'_, str>> {
    match value {
        Value::Null => None,
        Value::String(s) => Some(Cow::Borrowed(s)),
        other => Some(Cow::Owned(other.to_string())),
    }
}

/// What a table's file says about itself beside its columns (its Parquet key–value metadata);
/// each column's unit comes from its name.
#[derive(Default)]
pub struct About<'a> {
    /// The study's description, as `description`.
    pub description: &'a str,
    /// What a column holds where its name does not tell, as `(column, note)`; written as
    /// `note:<column>` for the columns the table has.
    pub notes: &'a [(&'a str, &'a str)],
}

/// `write_parquet_about` with no description or notes: the tables tests make by hand.
#[cfg(test)]
pub fn write_parquet(tables: &[(&Path, &[Row])]) -> Result<(), Fault> {
    write_parquet_about(tables, &About::default())
}

/// Writes tables as Parquet, all or none (see `Staged`).
/// Every failure is the file system's (`Fault::Io`): the rows are whatever the records held.
pub fn write_parquet_about(tables: &[(&Path, &[Row])], about: &About) -> Result<(), Fault> {
    let mut staged = Staged::new(about);
    for (path, rows) in tables {
        staged.stage(path, rows)?;
    }
    staged.commit().map(drop)
}

/// Tables written all or none: each is staged in a temporary file (named for this process)
/// that is synced, and only `commit` renames them into place, so that a writer may let go of
/// one table's rows before it makes the next's. Dropped uncommitted, the staged files go.
pub struct Staged<'a> {
    about: &'a About<'a>,
    /// Each staged file and the table it becomes.
    written: Vec<(std::path::PathBuf, std::path::PathBuf)>,
}

impl<'a> Staged<'a> {
    pub fn new(about: &'a About<'a>) -> Staged<'a> {
        Staged {
            about,
            written: Vec::new(),
        }
    }

    /// Writes the table `path` of `rows` to its temporary file.
    pub fn stage(&mut self, path: &Path, rows: &[Row]) -> Result<(), Fault> {
        let frame = data_frame(rows)
            .map_err(|e| Fault::Io(format!("cannot write {}: {e}", path.display())))?;
        self.stage_frame(path, &frame, ROW_GROUP)
    }

    /// Writes the table `path` of `frame` to its temporary file, in row groups of `group` rows.
    pub fn stage_frame(
        &mut self,
        path: &Path,
        frame: &DataFrame,
        group: usize,
    ) -> Result<(), Fault> {
        let mut writer = self.begin(path, frame.schema(), group)?;
        writer.write(frame.clone())?;
        writer.finish()
    }

    /// Begins the table `path` of the columns `schema` in its temporary file, to be written a
    /// batch of rows at a time in row groups of `group` rows (staged once its writer is
    /// finished). A table begun again is written afresh.
    pub fn begin(
        &mut self,
        path: &Path,
        schema: &Columns,
        group: usize,
    ) -> Result<TableWriter, Fault> {
        let partial = crate::store::fs::partial_path(path);
        if !self.written.iter().any(|(_, p)| p == path) {
            self.written.push((partial.clone(), path.to_path_buf()));
        }
        TableWriter::create(&partial, path, schema, self.about, group)
    }

    /// Puts every staged table in place: each table's sum, then the table. A reader (under the
    /// outputs lock, as every reader of the tables is) sees both of one collect; a writer killed
    /// between them leaves a table its sum refuses, which the next collect rebuilds.
    /// Returns each table's SHA-256, in the order they were staged.
    pub fn commit(self) -> Result<Vec<String>, Fault> {
        let mut sums = Vec::new();
        for (partial, path) in &self.written {
            let sum = sum_text(partial, path)?;
            crate::store::write_atomically(&sum_path(path), sum.as_bytes())?;
            std::fs::rename(partial, path)
                .map_err(|e| Fault::Io(format!("cannot write {}: {e}", path.display())))?;
            sums.extend(sum.split_whitespace().next().map(str::to_string));
        }
        Ok(sums)
    }
}

impl Drop for Staged<'_> {
    fn drop(&mut self) {
        for (partial, _) in &self.written {
            let _ = std::fs::remove_file(partial);
        }
    }
}

/// A column's unit, from its name: the measured times `*_s` (and their statistics `*_s_median`,
/// `_min`, `_max`, `_iqr`) in seconds, rates `*_per_s` per second, sizes `*_bytes` in bytes.
/// `None` for the rest: the model's quantities (t, dt, h, errors) are dimensionless, and counts,
/// ratios and text have none.
fn unit(column: &str) -> Option<&'static str> {
    let measured = ["_median", "_min", "_max", "_iqr"]
        .iter()
        .find_map(|statistic| column.strip_suffix(statistic))
        .unwrap_or(column);
    if measured.ends_with("_per_s") {
        Some("1/s")
    } else if measured.ends_with("_s") {
        Some("s")
    } else if measured.ends_with("_bytes") {
        Some("bytes")
    } else {
        None
    }
}

/// The key–value metadata of the file holding a table of the columns `schema`.
fn metadata(schema: &Columns, about: &About) -> Vec<(String, String)> {
    let mut pairs = Vec::new();
    if !about.description.is_empty() {
        pairs.push(("description".to_string(), about.description.to_string()));
    }
    for name in schema.iter_names() {
        if let Some(unit) = unit(name) {
            pairs.push((format!("unit:{name}"), unit.to_string()));
        }
    }
    for (column, note) in about.notes {
        if schema.contains(column) {
            pairs.push((format!("note:{column}"), note.to_string()));
        }
    }
    pairs
}

/// The rows of a Parquet file (as `write_parquet` wrote them; NaN reads back as null, a list
/// as a JSON array). A missing table is asked for too early (`Fault::Input`); one that is not a
/// regular file or not a whole Parquet table is a fault of the results (`Fault::Io`), never a
/// panic: polars panics on some corrupt footers, so the read runs under `catch_unwind`, after a
/// check of the frame's magic and footer length.
pub fn read_parquet(path: &Path) -> Result<Vec<Row>, Fault> {
    read_parquet_hashed(path).map(|(rows, _)| rows)
}

/// `read_parquet`, and the SHA-256 of the bytes it parsed (what a figure's stamp records).
pub fn read_parquet_hashed(path: &Path) -> Result<(Vec<Row>, String), Fault> {
    let (frame, sum) = read_frame(path)?;
    Ok((rows_of_table(path, &frame)?, sum))
}

/// The rows of a Parquet file (as `read_parquet`), of the columns `pick` chooses from the
/// table's column names: only they are parsed and made into rows. `pick` refuses with an input
/// fault (e.g. a column the table lacks).
pub fn read_parquet_columns(
    path: &Path,
    pick: impl FnOnce(&[&str]) -> Result<Vec<String>, String>,
) -> Result<Vec<Row>, Fault> {
    let (frame, _) = read_frame_picking(path, |names| pick(names).map(Some))?;
    rows_of_table(path, &frame)
}

/// The rows of the frame read from `path` (`rows_of`); one it cannot make is not whole.
fn rows_of_table(path: &Path, frame: &DataFrame) -> Result<Vec<Row>, Fault> {
    match crate::store::fs::without_panicking(|| rows_of(frame)) {
        Ok(Ok(rows)) => Ok(rows),
        Ok(Err(e)) | Err(e) => Err(not_whole(path, &e)),
    }
}

/// The data frame of a Parquet file as `read_parquet` reads it, and the SHA-256 of its bytes.
pub fn read_frame(path: &Path) -> Result<(DataFrame, String), Fault> {
    read_frame_picking(path, |_| Ok(None))
}

/// `read_frame` of the columns `pick` chooses from the table's column names (all on `None`).
fn read_frame_picking(
    path: &Path,
    pick: impl FnOnce(&[&str]) -> Result<Option<Vec<String>>, String>,
) -> Result<(DataFrame, String), Fault> {
    if std::fs::symlink_metadata(path).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) {
        return Err(Fault::Input(format!(
            "{} does not exist; `nlstudy collect` writes it from the stored runs",
            path.display()
        )));
    }
    let corrupt = |why: &dyn std::fmt::Display| not_whole(path, why);
    let bytes = read_whole(path).map_err(|e| corrupt(&e))?;
    let sum = crate::store::hex(&sha2::Sha256::digest(&bytes));
    check_sum(path, &sum).map_err(|e| corrupt(&e))?;
    check_frame(&bytes).map_err(|e| corrupt(&e))?;
    let mut reader = ParquetReader::new(std::io::Cursor::new(bytes));
    let schema = crate::store::fs::without_panicking(|| reader.schema().map_err(|e| e.to_string()));
    let schema = schema.and_then(|read| read).map_err(|e| corrupt(&e))?;
    let names: Vec<&str> = schema.iter_names().map(|name| name.as_str()).collect();
    let columns = pick(&names).map_err(Fault::Input)?;
    let parse = || reader.with_columns(columns).finish();
    match crate::store::fs::without_panicking(|| parse().map_err(|e| e.to_string())) {
        Ok(Ok(frame)) => Ok((frame, sum)),
        Ok(Err(e)) | Err(e) => Err(corrupt(&e)),
    }
}

/// The fault of a table that is not whole.
fn not_whole(path: &Path, why: &dyn std::fmt::Display) -> Fault {
    Fault::Io(format!(
        "{} is not a whole Parquet table ({why}); `nlstudy collect` rebuilds it from the stored runs",
        path.display()
    ))
}

/// The most a table may hold: 8 GiB, beyond any study's (10⁶ runs make about 1 GB), so that a
/// sparse file of a terabyte is refused before it is read, not allocated.
const TABLE_CAP: u64 = 8 << 30;

/// The bytes of the regular file `path`, at most `TABLE_CAP` of them.
fn read_whole(path: &Path) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let (file, length) = crate::store::fs::open_regular(path)?;
    if length > TABLE_CAP {
        return Err(format!(
            "{length} bytes, more than the 8 GiB a table may hold"
        ));
    }
    let mut bytes = Vec::with_capacity(length as usize);
    file.take(TABLE_CAP + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// The SHA-256 of the table `path`, if it has its sum beside it and its bytes match it: whole
/// as `collect` wrote it.
pub fn sum_if_whole(path: &Path) -> Option<String> {
    if !sum_path(path).is_file() {
        return None;
    }
    let sum = crate::store::hex(&sha2::Sha256::digest(read_whole(path).ok()?));
    check_sum(path, &sum).ok().map(|()| sum)
}

/// Where the sum of the table `path` is kept: `<table>.sha256`.
pub fn sum_path(path: &Path) -> std::path::PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".sha256");
    path.with_file_name(name)
}

/// The sum of the bytes of `written` as `sha256sum` prints it for the table `path`.
fn sum_text(written: &Path, path: &Path) -> Result<String, Fault> {
    let bytes = std::fs::read(written).map_err(crate::store::FileError::on("read", written))?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    Ok(format!(
        "{}  {name}\n",
        crate::store::hex(&sha2::Sha256::digest(&bytes))
    ))
}

/// Checks `actual`, the sum of the bytes read from the table `path`, against its recorded sum
/// when it has one.
fn check_sum(path: &Path, actual: &str) -> Result<(), String> {
    let sum = sum_path(path);
    let recorded = match crate::store::fs::read_regular(&sum, crate::store::fs::SMALL_FILE_CAP) {
        Ok(text) => text,
        Err(_) if std::fs::symlink_metadata(&sum).is_err() => return Ok(()),
        Err(why) => return Err(format!("its sum {} cannot be read: {why}", sum.display())),
    };
    let recorded = recorded.split_whitespace().next().unwrap_or_default();
    match recorded == actual {
        true => Ok(()),
        false => Err(format!(
            "its bytes do not match {}: changed since `nlstudy collect` wrote it",
            sum.display()
        )),
    }
}

/// A Parquet file starts and ends with `PAR1`, and the 4 bytes before its last 4 give the length
/// of a footer that must fit in the file.
fn check_frame(bytes: &[u8]) -> Result<(), String> {
    let length = bytes.len();
    if length < 12 {
        return Err(format!("{length} bytes, less than a Parquet frame"));
    }
    let tail = &bytes[length - 8..];
    if &bytes[..4] != b"PAR1" || &tail[4..] != b"PAR1" {
        return Err("no PAR1 magic at both ends".into());
    }
    let footer = u32::from_le_bytes(tail[..4].try_into().expect("4 bytes")) as usize;
    if footer + 12 > length {
        return Err(format!("its footer claims {footer} bytes of {length}"));
    }
    Ok(())
}

/// The rows of a data frame as a Parquet file holds them (NaN as null, a list as a JSON array).
pub fn rows_of(frame: &DataFrame) -> Result<Vec<Row>, String> {
    let mut rows: Vec<Row> = (0..frame.height())
        .map(|_| Row(Vec::with_capacity(frame.width())))
        .collect();
    for column in frame.columns() {
        // (A frame's column names differ: each cell is pushed, none looked for, and the name
        // is made once for all the rows.)
        let name = shared(column.name());
        for (i, row) in rows.iter_mut().enumerate() {
            let value = match column.get(i).map_err(|e| e.to_string())? {
                AnyValue::Boolean(b) => Value::from(b),
                AnyValue::Int64(v) => Value::from(v),
                AnyValue::Float64(v) => json_number(Some(v)),
                AnyValue::String(s) => Value::from(s),
                AnyValue::StringOwned(s) => Value::from(s.as_str()),
                AnyValue::List(items) => {
                    let items = items.f64().map_err(|e| e.to_string())?;
                    Value::Array(items.iter().map(json_number).collect())
                }
                _ => Value::Null,
            };
            row.0.push((name.clone(), value));
        }
    }
    Ok(rows)
}

/// A float as JSON: null when missing or not finite.
fn json_number(x: Option<f64>) -> Value {
    x.and_then(serde_json::Number::from_f64)
        .map_or(Value::Null, Value::Number)
}

/// Rows per Parquet row group of a table written whole: polars' own size (a table of up to 2¹⁸
/// rows is one group). A table is written in groups of its size (the last fewer) however its
/// rows are handed to the writer, so a table written a slice at a time is the same bytes as the
/// one written whole.
pub const ROW_GROUP: usize = 512 * 512;

/// Rows per row group of a table written as its slices come (`collect`'s run table, in both of
/// its ways, from scratch and spliced, so that their bytes agree): few, so that the writer holds
/// little. (Each group costs its columns' pages: at 10⁵ rows, 2¹⁴-row groups took about 0.07 s
/// longer to write than one group.)
pub const STREAMED_ROW_GROUP: usize = 1 << 14;

/// A table written to its file a batch of rows at a time, in row groups of a given size: it
/// holds at most a group and a batch.
pub struct TableWriter {
    writer: BatchedWriter<Recorded>,
    /// The first error of the file under the writer (polars reports a full disk as "Invalid
    /// thrift: transport error"): the fault says it instead.
    failed: std::sync::Arc<std::sync::Mutex<Option<std::io::Error>>>,
    /// The file, for the sync once it is whole, and its path.
    file: std::fs::File,
    path: std::path::PathBuf,
    /// The table's path, for the faults.
    table: std::path::PathBuf,
    /// Rows handed to the writer and not yet in a group.
    pending: DataFrame,
    /// Rows per group.
    group: usize,
    /// Whether a group has been written.
    grouped: bool,
}

impl TableWriter {
    /// A writer of the table `table` of the columns `schema` into the new file `path`, in row
    /// groups of `group` rows.
    fn create(
        path: &Path,
        table: &Path,
        schema: &Columns,
        about: &About,
        group: usize,
    ) -> Result<TableWriter, Fault> {
        let fault = cannot("write", table);
        let metadata = KeyValueMetadata::from_static(metadata(schema, about));
        let file = crate::store::fs::create_fresh(path).map_err(|e| fault(&e))?;
        let failed = std::sync::Arc::default();
        let writer = (file.try_clone())
            .map_err(|e| fault(&e))
            .and_then(|clone| {
                let recorded = Recorded {
                    file: clone,
                    failed: std::sync::Arc::clone(&failed),
                };
                (ParquetWriter::new(recorded).with_key_value_metadata(Some(metadata)))
                    .batched(schema)
                    .map_err(|e| fault(&e))
            })?;
        Ok(TableWriter {
            writer,
            failed,
            file,
            path: path.to_path_buf(),
            table: table.to_path_buf(),
            pending: DataFrame::empty_with_schema(schema),
            group,
            grouped: false,
        })
    }

    /// Writes `rows`, a frame of the table's columns in order: each group as it fills.
    pub fn write(&mut self, rows: DataFrame) -> Result<(), Fault> {
        let written = (|| -> PolarsResult<()> {
            self.pending.vstack_mut_owned(rows)?;
            while self.pending.height() >= self.group {
                let group = self.pending.slice(0, self.group);
                self.pending = self.pending.slice(self.group as i64, usize::MAX);
                self.write_group(group)?;
            }
            Ok(())
        })();
        written.map_err(|e| self.fault(&e))
    }

    /// The fault of a write that failed with `e`: the file's own error where it had one.
    fn fault(&self, e: &dyn std::fmt::Display) -> Fault {
        let failed = self.failed.lock().unwrap_or_else(|p| p.into_inner());
        match failed.as_ref() {
            Some(io) => cannot("write", &self.table)(io),
            None => cannot("write", &self.table)(e),
        }
    }

    fn write_group(&mut self, mut group: DataFrame) -> PolarsResult<()> {
        // (One chunk is one group: the writer writes a group per chunk.)
        group.rechunk_mut_par();
        self.grouped = true;
        self.writer.write_batch(&group)
    }

    /// Writes the rows still pending as the last group, the file's footer, and syncs it.
    pub fn finish(mut self) -> Result<(), Fault> {
        let rest = std::mem::take(&mut self.pending);
        if rest.height() > 0 || !self.grouped {
            self.write_group(rest).map_err(|e| self.fault(&e))?;
        }
        if let Err(e) = self.writer.finish() {
            return Err(self.fault(&e));
        }
        self.file.sync_all().map_err(|e| self.fault(&e))
    }

    /// `finish`, and the frame of the file written (no sum to check: this process wrote it).
    pub fn read_back(mut self) -> Result<DataFrame, Fault> {
        let path = std::mem::take(&mut self.path);
        self.finish()?;
        let fault = cannot("read", &path);
        let bytes = std::fs::read(&path).map_err(|e| fault(&e))?;
        (ParquetReader::new(std::io::Cursor::new(bytes)).finish()).map_err(|e| fault(&e))
    }
}

/// The file under a table's writer, keeping its first error.
struct Recorded {
    file: std::fs::File,
    failed: std::sync::Arc<std::sync::Mutex<Option<std::io::Error>>>,
}

impl Recorded {
    fn kept<T>(&self, done: std::io::Result<T>) -> std::io::Result<T> {
        if let Err(e) = &done {
            let mut failed = self.failed.lock().unwrap_or_else(|p| p.into_inner());
            failed.get_or_insert_with(|| std::io::Error::new(e.kind(), e.to_string()));
        }
        done
    }
}

impl std::io::Write for Recorded {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        let done = self.file.write(bytes);
        self.kept(done)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        let done = self.file.flush();
        self.kept(done)
    }
}

/// The fault of a file `path` that could not be `verb` ("write", "read").
fn cannot<'a>(verb: &'a str, path: &'a Path) -> impl Fn(&dyn std::fmt::Display) -> Fault + 'a {
    move |e| Fault::Io(format!("cannot {verb} {}: {e}", path.display()))
}

#[cfg(test)]
mod tests;
