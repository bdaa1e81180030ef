//! What a table's columns are, read off its rows' shapes rather than their cells: a row's shape
//! is its column names in order, each with its cell's type. A table's columns (names in
//! first-seen order, each typed to hold every cell) follow from the shapes its rows have, in
//! the order each first appears; a table's rows share a few dozen shapes at most. So a table
//! whose rows change in part can be remade from its shapes and the changed rows alone, as the
//! whole would make it (`collect` splices its tables that way).

use crate::store::shared::{shared, Shared};
use serde_json::Value;
use std::collections::HashMap;

/// The type of a column, or of one cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum ColumnType {
    Boolean,
    Integer,
    Float,
    /// Arrays of numbers (nulls allowed): `c_tot.time`, a field's values.
    Floats,
    Text,
}

/// A cell's type; `None` for null, which any column holds.
pub fn column_type_of(value: &Value) -> Option<ColumnType> {
    match value {
        Value::Null => None,
        Value::Bool(_) => Some(ColumnType::Boolean),
        Value::Number(n) if n.is_i64() => Some(ColumnType::Integer),
        Value::Number(_) => Some(ColumnType::Float),
        Value::Array(items) if items.iter().all(|v| v.is_number() || v.is_null()) => {
            Some(ColumnType::Floats)
        }
        _ => Some(ColumnType::Text),
    }
}

/// The narrowest type holding cells of both types: integers widen to floats, anything else
/// mixed to text. (A join: the order cells come in does not matter.)
pub fn join(a: Option<ColumnType>, b: Option<ColumnType>) -> Option<ColumnType> {
    use ColumnType::{Float, Integer, Text};
    match (a, b) {
        (None, k) | (k, None) => k,
        (Some(a), Some(b)) if a == b => Some(a),
        (Some(Integer | Float), Some(Integer | Float)) => Some(Float),
        _ => Some(Text),
    }
}

/// The type of a column of these cells; a column of nulls only is a float column.
pub fn column_type<'a>(cells: impl Iterator<Item = &'a Value>) -> ColumnType {
    cells
        .map(column_type_of)
        .fold(None, join)
        .unwrap_or(ColumnType::Float)
}

/// A row's shape: its columns' names in order, each with its cell's type.
pub type Shape = Vec<(Shared, Option<ColumnType>)>;

/// A table's columns: names in first-seen order, each with its type.
pub type Schema = Vec<(Shared, ColumnType)>;

/// The shapes of a table's rows: each distinct shape once, and each row's by its number.
#[derive(Clone, Debug, Default)]
pub struct Shapes {
    distinct: Vec<Shape>,
    number: HashMap<Shape, u32>,
    of_rows: Vec<u32>,
}

impl Shapes {
    /// Adds a row whose cells are these names and types: made into a shape only when it is not
    /// the shape of the row before (rows mostly are).
    pub fn push_cells<'a>(
        &mut self,
        cells: impl Iterator<Item = (&'a Shared, Option<ColumnType>)> + Clone,
    ) {
        if let Some(&n) = self.of_rows.last() {
            let last = &self.distinct[n as usize];
            let same = (last.len() == cells.clone().count())
                && (last.iter().zip(cells.clone())).all(|((a, k), (b, l))| *k == l && a == b);
            if same {
                self.of_rows.push(n);
                return;
            }
        }
        let shape: Shape = cells.map(|(n, k)| (n.clone(), k)).collect();
        let number = match self.number.get(&shape) {
            Some(&n) => n,
            None => {
                let n = self.distinct.len() as u32;
                self.number.insert(shape.clone(), n);
                self.distinct.push(shape);
                n
            }
        };
        self.of_rows.push(number);
    }

    /// No rows yet, and the shapes of `other`'s: a row of `other` added (`push_row_of`) keeps
    /// its shape's number.
    pub fn shapes_of(other: &Shapes) -> Shapes {
        Shapes {
            distinct: other.distinct.clone(),
            number: other.number.clone(),
            of_rows: Vec::new(),
        }
    }

    /// Adds a row of the shape of row `row` of `other`, whose shapes these began as.
    pub fn push_row_of(&mut self, other: &Shapes, row: usize) {
        self.of_rows.push(other.of_rows[row]);
    }

    pub fn rows(&self) -> usize {
        self.of_rows.len()
    }

    /// How many distinct shapes are known. Rows added by `push_cells` change the `schema` only
    /// where they make this grow (a row of a shape seen before adds no name and no type).
    pub fn known(&self) -> usize {
        self.distinct.len()
    }

    /// The shape of row `row`.
    pub fn of_row(&self, row: usize) -> &Shape {
        &self.distinct[self.of_rows[row] as usize]
    }

    /// The columns a table of these rows has, as `table::data_frame` makes them: each name
    /// where it is first seen, typed to hold every cell.
    pub fn schema(&self) -> Schema {
        let mut seen = vec![false; self.distinct.len()];
        let mut at: HashMap<&str, usize> = HashMap::new();
        let mut columns: Vec<(Shared, Option<ColumnType>)> = Vec::new();
        for &n in &self.of_rows {
            if std::mem::replace(&mut seen[n as usize], true) {
                continue; // a shape seen before adds no name and no type
            }
            for (name, kind) in &self.distinct[n as usize] {
                match at.get(&**name) {
                    Some(&k) => columns[k].1 = join(columns[k].1, *kind),
                    None => {
                        at.insert(name, columns.len());
                        columns.push((name.clone(), *kind));
                    }
                }
            }
        }
        columns
            .into_iter()
            .map(|(name, kind)| (name, kind.unwrap_or(ColumnType::Float)))
            .collect()
    }

    /// As kept beside a table (see `Kept`): the shapes its rows have, numbered as they first
    /// appear.
    pub fn kept(&self) -> Kept {
        let mut renumbered: HashMap<u32, u32> = HashMap::new();
        let mut distinct = Vec::new();
        let of_rows = (self.of_rows.iter())
            .map(|&n| {
                *renumbered.entry(n).or_insert_with(|| {
                    let shape = &self.distinct[n as usize];
                    distinct.push(shape.iter().map(|(n, k)| (n.to_string(), *k)).collect());
                    distinct.len() as u32 - 1
                })
            })
            .collect();
        Kept { distinct, of_rows }
    }

    /// As kept; `None` if a row's number names no shape.
    pub fn from_kept(kept: Kept) -> Option<Shapes> {
        let distinct: Vec<Shape> = kept
            .distinct
            .into_iter()
            .map(|shape| shape.into_iter().map(|(n, k)| (shared(&n), k)).collect())
            .collect();
        if kept.of_rows.iter().any(|&n| n as usize >= distinct.len()) {
            return None;
        }
        let number = (0..).zip(&distinct).map(|(n, s)| (s.clone(), n)).collect();
        Some(Shapes {
            distinct,
            number,
            of_rows: kept.of_rows,
        })
    }
}

/// `Shapes` as a file keeps them: the distinct shapes, and each row's number.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Kept {
    distinct: Vec<Vec<(String, Option<ColumnType>)>>,
    of_rows: Vec<u32>,
}
