//! A run's row of the run table: the point's labels, then its record's fields flattened, as
//! `Stored` serializes them. Most records of a study have one of a few shapes (a run's, a
//! failure's), so each thread keeps how the leaves of the shapes it met become cells (their
//! order and their shared names) instead of making the record's tree again and walking it.

use super::Tabulated;
use crate::analysis::incremental::Identity;
use crate::store::shared;
use crate::store::table::{Name, Row};
use schema::record::columns;
use schema::record::Stored;
use serde_json::{json, Value};
use std::cell::RefCell;

/// The fields that lead a run's row; the case follows, then the results, then provenance.
const LEADING: [&str; 5] = [
    columns::KEY,
    columns::CASE_ID,
    columns::REPEAT,
    columns::STATUS,
    columns::MESSAGE,
];

/// Where a record's top-level field goes among the cells after `LEADING` (stable: fields stay
/// in the order of their names within a rank).
fn rank(field: &str) -> u8 {
    match field {
        "case" => 0,
        "provenance" => 2,
        _ => 1,
    }
}

/// One run's row: the point's label and series (as its `identity` has them), then the record,
/// flattened: its columns are what `Stored` serializes.
pub(super) fn run_row(point: &Tabulated, identity: &Identity, stored: &Stored) -> Row {
    thread_local! {
        static SHAPES: RefCell<Shapes> = RefCell::default();
    }
    // (The row grows cell by cell, to twice the room it needs at most: room its summary row,
    // made in place of it, fills.)
    let mut row = Row::default();
    row.set("point", json!(identity.label));
    if let Some(branch) = &point.branch {
        row.set("branch", json!(&**branch));
    }
    row.set("refinement_series", json!(identity.refinement));
    row.set("scaling_series", json!(identity.scaling));
    // The case with its defaults filled in, as the solver resolves it now (records keep the
    // case as keyed, which leaves some defaults out; the record's case is the planned one,
    // since its key is the point's).
    let resolve = |case: Value| match &point.resolution {
        Some(resolution) => resolution.resolve(case),
        None => case,
    };
    let placed = SHAPES.with_borrow_mut(|shapes| shapes.place(&mut row, stored, &resolve));
    if !placed && !cells_of_tree(&mut row, stored, &resolve) {
        return Row::default();
    }
    // Beside `ranks` (the record's), the threads each rank ran: what `where` and figure specs
    // call `threads`.
    if let Some(threads) = row.get("case.threads").cloned() {
        row.set(columns::THREADS, threads);
    }
    row
}

/// How many record shapes a thread keeps: a study's records have a few.
const KEPT_SHAPES: usize = 8;

/// The record shapes a thread met lately, and what it reads of the record at hand.
#[derive(Default)]
struct Shapes {
    /// The leaves' names of the record at hand as `columns::each_leaf` spells them, in the order
    /// it gives them, one after another; where each ends; and their values.
    names: String,
    ends: Vec<usize>,
    values: Vec<Value>,
    /// The shapes met, the latest last.
    known: Vec<Shape>,
}

/// A record shape: its leaves' names (as `Shapes` holds them) and how they become cells.
struct Shape {
    names: String,
    ends: Vec<usize>,
    /// `None` where the leaves are not placed this way, for the tree to place them: names that
    /// clash, a leading field that is a group, a field named as a label.
    cells: Option<Cells>,
}

/// Where a shape's leaves go, each by its place in the order they are given.
struct Cells {
    /// The leaf of each `LEADING` field, if the record has it.
    leading: [Option<usize>; LEADING.len()],
    /// Whether the record has a case (one leaf: its value is read off the typed record and
    /// flattened once resolved).
    case: bool,
    /// The other leaves in the row's order (by `rank`, then as the tree's names sort), with
    /// their cells' names.
    rest: Vec<(usize, Name)>,
}

impl Shapes {
    /// Adds `stored`'s cells to `row` (its case as `resolve` makes it) as `cells_of_tree` would:
    /// false, adding none, where its shape is not placed this way.
    fn place(&mut self, row: &mut Row, stored: &Stored, resolve: &dyn Fn(Value) -> Value) -> bool {
        let Shapes {
            names,
            ends,
            values,
            known,
        } = self;
        names.clear();
        ends.clear();
        values.clear();
        let read = columns::each_leaf(stored, &["case"], &mut |name, value| {
            names.push_str(name);
            ends.push(names.len());
            values.push(value);
        });
        if read.is_none() {
            return false;
        }
        let at = match known
            .iter()
            .rposition(|s| s.names == *names && s.ends == *ends)
        {
            Some(at) => at,
            None => {
                if known.len() == KEPT_SHAPES {
                    known.remove(0);
                }
                known.push(Shape::new(names.clone(), ends.clone()));
                known.len() - 1
            }
        };
        let Some(cells) = &known[at].cells else {
            return false;
        };
        let mut take = |k: usize| std::mem::take(&mut values[k]);
        for (field, k) in LEADING.iter().zip(cells.leading) {
            row.set(field, k.map_or(Value::Null, &mut take));
        }
        if cells.case {
            row.set_all_flattened([("case", resolve(stored.case().clone()))]);
        }
        for (k, name) in &cells.rest {
            row.push_new(name.clone(), take(*k));
        }
        true
    }
}

impl Shape {
    fn new(names: String, ends: Vec<usize>) -> Shape {
        let starts = std::iter::once(0).chain(ends.iter().copied());
        let parts: Vec<&str> = starts.zip(&ends).map(|(a, &b)| &names[a..b]).collect();
        let cells = Cells::parse(&parts);
        Shape { names, ends, cells }
    }
}

impl Cells {
    /// Where the leaves named `parts` (as `each_leaf` spells them) go.
    fn parse(parts: &[&str]) -> Option<Cells> {
        let mut cells = Cells {
            leading: [None; LEADING.len()],
            case: false,
            rest: Vec::new(),
        };
        let mut ranked = Vec::with_capacity(parts.len());
        for k in columns::tree_order(parts)? {
            let name = parts[k];
            let field = name.split('\0').next().unwrap_or(name);
            match (LEADING.iter().position(|f| *f == name), field) {
                (Some(j), _) => cells.leading[j] = Some(k),
                // A leading field's cell holds it whole, a group too: the tree places it.
                (None, field) if LEADING.contains(&field) => return None,
                (None, "case") if name == "case" => cells.case = true,
                (None, field) => {
                    let dotted = columns::dotted(name);
                    // (The record's cell would take the label's place.)
                    if super::LABELS.iter().any(|(label, _)| *label == dotted) {
                        return None;
                    }
                    ranked.push((rank(field), k, shared(&dotted)));
                }
            }
        }
        ranked.sort_by_key(|(rank, ..)| *rank); // stable: the tree's order within a rank
        cells.rest = ranked.into_iter().map(|(_, k, name)| (k, name)).collect();
        Some(cells)
    }
}

/// `stored`'s cells added to `row` (its case as `resolve` makes it) from its JSON tree: every
/// record. False for a record that is no JSON object (none is).
fn cells_of_tree(row: &mut Row, stored: &Stored, resolve: &dyn Fn(Value) -> Value) -> bool {
    let Value::Object(mut record) = stored.to_value() else {
        return false;
    };
    if let Some(case) = record.get_mut("case") {
        *case = resolve(case.take());
    }
    for field in LEADING {
        row.set(field, record.remove(field).unwrap_or(Value::Null));
    }
    let mut rest: Vec<(String, Value)> = record.into_iter().collect();
    rest.sort_by_key(|(name, _)| rank(name)); // stable: names stay sorted within a rank
    match rest.iter().any(|(name, _)| name.contains('.')) {
        false => row.set_all_flattened(rest),
        // (A field named like a group's flattened one, `case.n` beside `case`: the later cell
        // takes the name's place, field by field.)
        true => (rest.into_iter()).for_each(|(name, value)| row.set_flattened(&name, value)),
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record_json;

    /// A record's cells placed by its shape are those its tree gives, in the same order, for
    /// records of every kind met one after another (shapes met again, and more shapes than a
    /// thread keeps): every field, a failure, a newer solver's fields, an old build's record;
    /// the case resolved alike; and a record whose shape is not placed this way (a field named
    /// as a label, a leading field that is a group) is left to the tree.
    #[test]
    fn a_records_cells_placed_by_its_shape_are_its_trees() {
        let read = |value: Value| Stored::from_value(value).unwrap();
        let mut records = vec![
            schema::record::every_field(),
            read(record_json(json!({"run_id": "r", "attempt": 2}))),
            read(record_json(
                json!({"newer": {"b": [1, 2], "a": {}, "c.d": 1}}),
            )),
            read(record_json(
                json!({"status": "diverged", "diverged_step": 4}),
            )),
            read(
                json!({"key": "k", "solver_version": "v", "status": "failed",
                        "case": {"n": 1}, "message": "refused"}),
            ),
            read(serde_json::from_str(include_str!("../../../fixtures/record-rk4.json")).unwrap()),
            read(
                serde_json::from_str(include_str!("../../../fixtures/record-threads.json"))
                    .unwrap(),
            ),
        ];
        records
            .extend((0..KEPT_SHAPES).map(|k| read(record_json(json!({ format!("new{k}"): k })))));
        let named_as_labels = [
            read(record_json(json!({"point": "mine"}))),
            read(record_json(json!({"branch": "mine", "other": 1}))),
        ];
        let resolve = |mut case: Value| {
            case["added_default"] = json!(1.5);
            case
        };
        let labelled = || Row::of_cells(json!({"point": "n=8", "refinement_series": "m=2"}));
        let mut shapes = Shapes::default();
        let mut left = Vec::new();
        for stored in records.iter().chain(&records).chain(&named_as_labels) {
            let (mut placed, mut from_tree) = (labelled(), labelled());
            assert!(cells_of_tree(&mut from_tree, stored, &resolve));
            if shapes.place(&mut placed, stored, &resolve) {
                assert_eq!(placed, from_tree);
                assert_eq!(placed.number("case.added_default"), Some(1.5));
            } else {
                assert_eq!(placed, labelled(), "nothing placed");
                left.push(stored);
            }
        }
        assert_eq!(left, named_as_labels.iter().collect::<Vec<_>>());
        assert_eq!(shapes.known.len(), KEPT_SHAPES);
    }
}
