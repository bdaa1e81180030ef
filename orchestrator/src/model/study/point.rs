//! A point of a study: its case fields before the solver checks them, the fields the sweep
//! set, its label, and the series of the study's tables it lies on.

use crate::model::expression::Scope;
use serde_json::{Map, Value};
use std::sync::Arc;

/// The pseudo-field through which a branch's name travels with its points' assignments.
pub(super) const BRANCH: &str = "branch";

/// A list of swept field names, shared.
pub(super) type Names = Arc<[String]>;
/// One point of a study: the case fields before the solver checks them, which of them the
/// sweep set (for messages and tables), and the series the point belongs to.
///
/// A point holds only what sets it apart: the study's `base` and the list of swept names are
/// shared by every point that has them, so 10⁶ points cost a few hundred bytes each, not the
/// kilobyte and more of a full map.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub(super) base: Arc<Map<String, Value>>,
    /// The fields the sweep set and `derive` computed, in that order; `values` holds theirs.
    pub(super) swept: Names,
    pub(super) values: Vec<Value>,
    /// The `branches` alternative the point lies on, if any.
    pub branch: Option<Arc<str>>,
    pub repeat: usize,
    /// The fields that move along its series, shared by its branch's points.
    pub(super) moving: Arc<Moving>,
}

/// The fields a refinement moves, and those a scaling moves.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Moving {
    pub(super) refined: Vec<String>,
    pub(super) scaled: Vec<String>,
}

/// The lines of a study's tables a point lies on, named by the swept fields held fixed along
/// them: the points of one refinement series differ only in the grid (and what the sweep moves
/// with it: the horizon of a path, the partners of `n` in a zip); those of one scaling series
/// only in the workers (threads, ranks, px, py and their zip partners). Derived fields follow
/// the swept ones, so they are left out of the names.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointSeries {
    pub refinement: String,
    pub scaling: String,
}

/// The fields whose change makes a refinement, and a scaling.
pub(super) const REFINED: &[&str] = &["n"];
pub(super) const SCALED: &[&str] = &["threads", "ranks", "px", "py"];

impl Point {
    /// A point of `fields` alone, none of them swept.
    pub fn from_fields(fields: Map<String, Value>) -> Point {
        Point {
            base: Arc::new(fields),
            swept: Arc::from([]),
            values: Vec::new(),
            branch: None,
            repeat: 0,
            moving: Arc::default(),
        }
    }

    /// Whether the sweep (or `derive`) sets `field`.
    pub fn sweeps(&self, field: &str) -> bool {
        self.swept.iter().any(|f| f == field)
    }

    /// The point with `field` swept to `value` too (a boundary search's probe): the same base,
    /// branch and repeat, and the field last in its label.
    pub fn with(&self, field: &str, value: Value) -> Point {
        let mut point = self.clone();
        match point.swept.iter().position(|f| f == field) {
            Some(k) => point.values[k] = value,
            None => {
                point.swept = point
                    .swept
                    .iter()
                    .cloned()
                    .chain([field.to_string()])
                    .collect();
                point.values.push(value);
            }
        }
        point
    }

    /// The series the point lies on, named by the fields that stay along them.
    pub fn series(&self) -> PointSeries {
        PointSeries {
            refinement: self.label_without(&self.moving.refined),
            scaling: self.label_without(&self.moving.scaled),
        }
    }

    /// The field's value, swept or from `base`.
    pub fn get(&self, field: &str) -> Option<&Value> {
        match self.swept.iter().position(|f| f == field) {
            Some(k) => Some(&self.values[k]),
            None => self.base.get(field),
        }
    }

    /// A column of the tables (`fields_telling_apart` names them): the branch, or a field.
    pub fn column(&self, name: &str) -> Option<Value> {
        match (name, &self.branch) {
            (BRANCH, Some(branch)) => Some(Value::from(&**branch)),
            _ => self.get(name).cloned(),
        }
    }

    /// Every field, keys sorted: the case as written.
    pub fn fields(&self) -> Map<String, Value> {
        let mut fields = (*self.base).clone();
        for (field, value) in self.swept.iter().zip(&self.values) {
            fields.insert(field.clone(), value.clone());
        }
        fields
    }

    /// `fields()` as compact JSON, written without building the map: what `nlsolve check`
    /// reads, and what keys a case the solver refused.
    pub fn write_fields(&self, out: impl std::io::Write) -> serde_json::Result<()> {
        let mut entries: Vec<(&str, &Value)> = self
            .base
            .iter()
            .filter(|(field, _)| !self.swept.contains(field))
            .map(|(field, value)| (field.as_str(), value))
            .chain(self.swept.iter().map(String::as_str).zip(&self.values))
            .collect();
        // The order of a `Map`, so the text is that of `fields()`.
        entries.sort_unstable_by_key(|(field, _)| *field);
        let mut serializer = serde_json::Serializer::new(out);
        serde::Serializer::collect_map(&mut serializer, entries)
    }

    /// `n=64 threads=2` – the swept fields, for messages.
    pub fn label(&self) -> String {
        let mut label = self.label_without_repeat();
        if self.repeat > 0 {
            label.push_str(&format!(" repeat={}", self.repeat));
        }
        label
    }

    /// The label as a message shows it: `the base case` where nothing is swept, rather than an
    /// empty name (`running :`).
    pub fn shown(&self) -> String {
        let label = self.label();
        match label.is_empty() {
            true => "the base case".to_string(),
            false => label,
        }
    }

    /// The label shared by the point's repeats.
    pub fn label_without_repeat(&self) -> String {
        self.label_without(&[])
    }

    /// The label without `field`: what the probes of one search share.
    pub fn label_without_field(&self, field: &str) -> String {
        self.label_without(&[field.to_string()])
    }

    fn label_without(&self, left_out: &[String]) -> String {
        use std::fmt::Write as _;
        let mut label = String::new();
        if let Some(branch) = &self.branch {
            label.push_str(BRANCH);
            label.push('=');
            label.push_str(branch);
        }
        let swept = self.swept.iter().zip(&self.values);
        for (field, value) in swept.filter(|(f, _)| !left_out.contains(f)) {
            if !label.is_empty() {
                label.push(' ');
            }
            label.push_str(field);
            label.push('=');
            match value {
                Value::String(s) => label.push_str(s),
                v => write!(label, "{v}").expect("a String takes any text"),
            }
        }
        label
    }

    /// `scope()` of only the fields `names` (the branch among them): all an expression reading
    /// no other name needs.
    pub(super) fn scope_of(&self, names: &[String]) -> Scope {
        let branch = self.branch.as_ref().map(|b| Value::from(&**b));
        Scope::of_names(names, |name| match (name, &branch) {
            (BRANCH, Some(branch)) => Some(branch),
            _ => self.get(name),
        })
    }

    /// The fields an expression sees: the case's, and the branch.
    pub(super) fn scope(&self) -> Scope {
        let mut fields = self.fields();
        if let Some(branch) = &self.branch {
            fields.insert(BRANCH.into(), Value::from(branch.to_string()));
        }
        Scope::from_fields(&fields)
    }
}

/// The fields that tell a study's points apart, for the columns of its tables: `branch` when
/// there are branches, then every field swept or derived on any branch, in first-seen order (the
/// fields of one branch alone would leave another's rows looking alike).
pub fn fields_telling_apart<'a>(points: impl IntoIterator<Item = &'a Point>) -> Vec<String> {
    let mut fields: Vec<String> = Vec::new();
    for point in points {
        if point.branch.is_some() && !fields.iter().any(|f| f == BRANCH) {
            fields.insert(0, BRANCH.to_string());
        }
        for field in point.swept.iter() {
            if !fields.contains(field) {
                fields.push(field.clone());
            }
        }
    }
    fields
}

/// The `field=value` parts of a label (`Point::label`, the tables' `point` and series columns),
/// split where a space is followed by a name and `=`: a value may hold spaces (a branch `a b`).
pub fn label_parts(label: &str) -> Vec<(String, String)> {
    let starts_part = |rest: &str| {
        let name_end = rest.find('=').unwrap_or(0);
        let name = &rest[..name_end];
        name_end > 0
            && name
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
    };
    let mut parts: Vec<(String, String)> = Vec::new();
    let mut rest = label;
    while !rest.is_empty() {
        // The next space that begins a part, or the end.
        let end = rest
            .match_indices(' ')
            .map(|(at, _)| at)
            .find(|&at| starts_part(&rest[at + 1..]))
            .unwrap_or(rest.len());
        let part = &rest[..end];
        if let Some((field, value)) = part.split_once('=') {
            parts.push((field.to_string(), value.to_string()));
        } else if let Some(last) = parts.last_mut() {
            last.1.push(' ');
            last.1.push_str(part);
        }
        rest = rest[end..].strip_prefix(' ').unwrap_or("");
    }
    parts
}
