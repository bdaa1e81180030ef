//! Rows of the summary grouped into labelled series, and the words an axis shows for a column.

use crate::output::draw::Series;
use crate::store::table::Row;
use schema::record::Status;
use serde_json::Value;

/// How columns read on an axis.
pub(super) fn describe(column: &str) -> String {
    let known = [
        ("workers", "workers (threads × ranks)"),
        ("h", "grid spacing h"),
        ("eps", "horizon ε"),
        ("case.cfl", "dt / dt_stable"),
        ("max_abs", "max|u| at the final time"),
        ("error_l2_norm", "discrete L² error"),
        ("error_max", "max-norm error"),
        ("c_tot.time", "time t"),
        ("case.m", "horizon m = ε/h"),
        ("bond_updates_per_s", "bond updates per second"),
        ("c_tot.c_tot", "total concentration c_tot(t)"),
        ("subdomains", "subdomains p²"),
        ("iterations", "iterations"),
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
            return format!(
                "{what} time{} (s)",
                if statistic.is_empty() {
                    String::new()
                } else {
                    format!(", {statistic}")
                }
            );
        }
    }
    name.to_string()
}

/// Rows of one series, with its label.
pub(super) struct Group<'a> {
    pub label: String,
    pub rows: Vec<&'a Row>,
}

pub(super) fn group<'a>(rows: &[&'a Row], columns: &[String]) -> Vec<Group<'a>> {
    let mut groups: Vec<Group<'a>> = Vec::new();
    for row in rows {
        let parts: Vec<String> = columns
            .iter()
            .map(|c| {
                let value = match row.get(c) {
                    Some(Value::String(s)) => s.clone(),
                    Some(v) => v.to_string(),
                    None => "?".into(),
                };
                // Series columns already read `name=value`.
                match c.as_str() {
                    "point" | "scaling_series" | "refinement_series" => value,
                    _ => format!("{}={value}", c.strip_prefix("case.").unwrap_or(c)),
                }
            })
            .collect();
        // `m=null` (a field a zip leaves out for some points) tells nothing apart.
        let label = parts
            .iter()
            .flat_map(|p| p.split(' '))
            .filter(|p| !p.ends_with("=null"))
            .collect::<Vec<_>>()
            .join(" ");
        match groups.iter_mut().find(|g| g.label == label) {
            Some(g) => g.rows.push(row),
            None => groups.push(Group {
                label,
                rows: vec![row],
            }),
        }
    }
    groups
}

/// Takes the `field=value` parts every series label shares out of the labels (they go into the
/// title), so that legends say only what tells the series apart.
pub(super) fn shared_by_all(groups: &mut [Group]) -> String {
    let Some(first) = groups.first() else {
        return String::new();
    };
    let shared: Vec<String> = first
        .label
        .split(' ')
        .filter(|part| {
            groups
                .iter()
                .all(|g| g.label.split(' ').any(|p| p == *part))
        })
        .map(str::to_string)
        .collect();
    for g in groups.iter_mut() {
        let own: Vec<&str> = g
            .label
            .split(' ')
            .filter(|p| !shared.iter().any(|s| s == p))
            .collect();
        g.label = match own.is_empty() {
            true => "all points".into(),
            false => own.join(" "),
        };
    }
    shared.join(" ")
}

impl Group<'_> {
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

    /// The label with the repeats behind its points: `… (3 repeats)` or `(1–3 repeats)`.
    pub(super) fn legend(&self) -> String {
        let repeats = self.rows.iter().filter_map(|r| r.number("repeats"));
        let (lo, hi) = repeats.fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
            (lo.min(r), hi.max(r))
        });
        match (lo, hi) {
            (lo, _) if !lo.is_finite() => self.label.clone(),
            (lo, hi) if lo == hi => format!(
                "{} ({lo} repeat{})",
                self.label,
                if lo == 1.0 { "" } else { "s" }
            ),
            (lo, hi) => format!("{} ({lo}–{hi} repeats)", self.label),
        }
    }
}

pub(super) fn series(label: String, points: Vec<(f64, f64)>) -> Series {
    Series {
        label,
        points,
        band: Vec::new(),
        crosses: Vec::new(),
        note: None,
    }
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
