//! Rows of the summary grouped into labelled series, and the words an axis shows for a column.

use crate::analysis::summary::BOND_UPDATES_PER_S;
use crate::console::number;
use crate::output::draw::{span, Series};
use crate::store::table::Row;
use schema::record::columns;
use schema::record::Status;
use serde_json::Value;

/// How a column reads on an axis. A statistic over repeats (a timing's median) says how many
/// repeats of `groups` it is over; errors, orders and counts are deterministic and do not.
pub(super) fn describe(column: &str, groups: &[Group]) -> String {
    let known = [
        ("workers", "workers (threads × ranks)"),
        (columns::H, "grid spacing h"),
        (columns::EPS, "horizon ε"),
        ("case.cfl", "dt / dt_stable"),
        (columns::MAX_ABS, "max|u| at the final time"),
        (columns::ERROR_L2_NORM, "discrete L² error"),
        (columns::ERROR_MAX, "max-norm error"),
        (columns::C_TOT_TIME, "time t"),
        ("case.m", "horizon m = ε/h"),
        (BOND_UPDATES_PER_S, "bond updates per second"),
        (columns::C_TOT, "total concentration c_tot(t)"),
        (columns::SUBDOMAINS, "subdomains p²"),
        (columns::ITERATIONS, "iterations"),
        ("patch.x", "x along the bar"),
        ("patch.l_u", "L_h u"),
        (
            "patch.ghost_force",
            "ghost force max |L_h u − k u''| away from the ends",
        ),
    ];
    if let Some((_, text)) = known.iter().find(|(c, _)| *c == column) {
        return text.to_string();
    }
    let name = column.strip_prefix("case.").unwrap_or(column);
    for (suffix, statistic) in [("_s_median", "median"), ("_s_min", "min"), ("_s", "")] {
        if let Some(what) = name.strip_suffix(suffix) {
            let over = match (statistic, repeats(groups)) {
                ("", _) => String::new(),
                (statistic, Some(repeats)) => format!(", {statistic} of {repeats}"),
                (statistic, None) => format!(", {statistic}"),
            };
            return format!("{what} time{over} (s)");
        }
    }
    name.to_string()
}

/// Rows of one series, with the `field = value` parts that tell it apart.
#[derive(Clone)]
pub(super) struct Group<'a> {
    pub parts: Vec<(String, String)>,
    pub rows: Vec<&'a Row>,
}

/// `name = value` parts joined for people: `quadrature = ac, n = 64`.
fn read_parts(parts: &[(String, String)]) -> String {
    let parts: Vec<String> = parts.iter().map(|(f, v)| format!("{f} = {v}")).collect();
    parts.join(", ")
}

/// A value as a label shows it: numbers with `console::number`, text as it is.
fn value_text(value: &str) -> String {
    match value.parse::<f64>() {
        Ok(x) => number(x),
        Err(_) => value.to_string(),
    }
}

pub(super) fn group<'a>(rows: &[&'a Row], columns: &[String]) -> Vec<Group<'a>> {
    let mut groups: Vec<Group<'a>> = Vec::new();
    for row in rows {
        let mut parts: Vec<(String, String)> = Vec::new();
        for c in columns {
            let value = match row.get(c) {
                Some(Value::String(s)) => s.clone(),
                Some(v) => v.to_string(),
                None => "?".into(),
            };
            match c.as_str() {
                // Series columns already read `name=value name=value`.
                "point" | "scaling_series" | "refinement_series" => {
                    parts.extend(crate::model::study::label_parts(&value));
                }
                _ => parts.push((c.strip_prefix("case.").unwrap_or(c).to_string(), value)),
            }
        }
        // `m=null` (a field a zip leaves out for some points) tells nothing apart.
        let parts: Vec<(String, String)> = parts
            .into_iter()
            .filter(|(_, v)| v != "null")
            .map(|(f, v)| (f, value_text(&v)))
            .collect();
        match groups.iter_mut().find(|g| g.parts == parts) {
            Some(g) => g.rows.push(row),
            None => groups.push(Group {
                parts,
                rows: vec![row],
            }),
        }
    }
    groups
}

/// Takes the parts every series shares out of the series (they go into the subtitle), so that
/// legends say only what tells the series apart; returns them sorted by field.
pub(super) fn shared_by_all(groups: &mut [Group]) -> Vec<(String, String)> {
    let Some(first) = groups.first() else {
        return Vec::new();
    };
    let mut shared: Vec<(String, String)> = first
        .parts
        .iter()
        .filter(|part| groups.iter().all(|g| g.parts.contains(part)))
        .cloned()
        .collect();
    for g in groups.iter_mut() {
        g.parts.retain(|p| !shared.contains(p));
    }
    shared.sort();
    shared
}

/// The subtitle of a chart: the fields its series share. `branch`, the name of a part of the
/// study file, is left out: it says nothing about the cases.
pub(super) fn subtitle(shared: &[(String, String)]) -> String {
    let fields: Vec<(String, String)> = shared
        .iter()
        .filter(|(field, value)| field != "branch" && !field.is_empty() && !value.is_empty())
        .cloned()
        .collect();
    read_parts(&fields)
}

/// How many repeats the rows' statistics are over: `3 repeats`, `1–3 repeats`.
fn repeats(groups: &[Group]) -> Option<String> {
    let counts = groups
        .iter()
        .flat_map(|g| &g.rows)
        .filter_map(|r| r.number("repeats"));
    let (lo, hi) = span(counts);
    if !lo.is_finite() {
        None
    } else if lo < hi {
        Some(format!("{}–{} repeats", number(lo), number(hi)))
    } else {
        let s = if lo == 1.0 { "" } else { "s" };
        Some(format!("{} repeat{s}", number(lo)))
    }
}

impl Group<'_> {
    /// The legend's words for the series: its own parts, or `all points` when it has none.
    pub(super) fn label(&self) -> String {
        match self.parts.is_empty() {
            true => "all points".into(),
            false => read_parts(&self.parts),
        }
    }

    /// The x of the ok rows whose repeats were all or partly timed on a busy machine.
    pub(super) fn noisy_xs(&self, x: &str) -> Vec<f64> {
        self.ok_xs(x, |r| r.number("noisy_repeats").is_some_and(|n| n > 0.0))
    }

    /// The x of the ok rows run with more workers than cores.
    pub(super) fn oversubscribed_xs(&self, x: &str) -> Vec<f64> {
        self.ok_xs(x, |r| {
            r.get(columns::OVERSUBSCRIBED) == Some(&Value::Bool(true))
        })
    }

    fn ok_xs(&self, x: &str, marked: impl Fn(&Row) -> bool) -> Vec<f64> {
        self.rows
            .iter()
            .filter(|r| r.status() == Some(Status::Ok) && marked(r))
            .filter_map(|r| r.number(x))
            .collect()
    }

    /// The ok rows' (x, y), sorted by x.
    pub(super) fn points(&self, x: &str, y: &str) -> Vec<(f64, f64)> {
        let mut points: Vec<(f64, f64)> = self
            .rows
            .iter()
            .filter(|r| r.status() == Some(Status::Ok))
            .filter_map(|r| Some((r.number(x)?, r.number(y)?)))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points
    }
}

pub(super) fn series(label: String, points: Vec<(f64, f64)>) -> Series {
    Series::line(label, points)
}

pub(super) fn all<'a>(
    panel: impl Iterator<Item = &'a Series>,
    pick: fn(&(f64, f64)) -> f64,
) -> Vec<f64> {
    panel.flat_map(|s| s.points.iter().map(pick)).collect()
}

/// The statistic's band columns: `solve_s_median` → `solve_s_min`, `solve_s_max`.
pub(super) fn band_columns(y: &str) -> Option<(String, String)> {
    let stem = y.strip_suffix("_median")?;
    Some((format!("{stem}_min"), format!("{stem}_max")))
}

/// A column holding an array of numbers (stored as JSON text in the tables).
pub(super) fn numbers(value: Option<&Value>) -> Vec<f64> {
    let parsed = match value {
        Some(Value::String(text)) => serde_json::from_str::<Vec<f64>>(text).ok(),
        Some(Value::Array(items)) => items.iter().map(Value::as_f64).collect(),
        _ => None,
    };
    parsed.unwrap_or_default()
}
