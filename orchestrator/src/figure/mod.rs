//! A study's figures: their specs as the study file lists them, and the charts each kind makes of
//! the summary table (one row per point).

use crate::draw::Chart;
use crate::expression::{self, Scope};
use crate::table::Row;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

mod convergence;
mod field;
mod scaling;
mod series;
mod solver_comparison;
mod stability;
mod throughput;
mod time_series;
mod work_precision;

pub use convergence::fitted_slope;
pub use work_precision::pareto_front;

use series::{group, shared_by_all};

/// One figure of a study file, e.g.
/// `{"name": "convergence", "kind": "convergence", "series": ["method"], "where": ["dim == 2"]}`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FigureSpec {
    /// The file: `results/<study>/figures/<name>.svg`.
    pub name: String,
    pub kind: Kind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub title: Option<String>,
    /// Columns of the summary table (a case field may be named without `case.`); each kind has
    /// defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<String>,
    /// A column, or `abs(column)` for its magnitude (signed values on a log axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y: Option<String>,
    /// Columns whose values tell the series apart.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<Vec<String>>,
    /// Conditions on a row, as in a study's `where`.
    #[serde(default, rename = "where", skip_serializing_if = "Vec::is_empty")]
    pub filter: Vec<String>,
}

#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Time, speedup and efficiency against workers, with ideal lines and min–max bands.
    StrongScaling,
    /// Efficiency T(p₀)/T(p) against workers, the problem growing with them.
    WeakScaling,
    /// Error against h on log–log axes, the fitted slope written on each series.
    Convergence,
    /// Run time against error, one series per method, the Pareto front marked.
    WorkPrecision,
    /// max|u| at the end against dt/dt_stable, diverged runs as crosses, the bound at 1.
    Stability,
    /// c_tot(t) of each point.
    TimeSeries,
    /// Bond updates per second against the horizon m, one panel per grid size n, one series per
    /// backend that ran, and the measured crossover where the FFT overtakes the stencil marked.
    Throughput,
    /// Heat maps (profiles in 1D) of one point's final field and of its error, from the
    /// snapshot the case's `field_snapshot` puts into the record.
    Field,
    /// Steady solvers (seed 001): iterations and solve time against the subdomains, one series
    /// per method and preconditioner. CG has no subdomains: its points sit at the subdomain count
    /// of the FETI points that solve the same L.
    SolverComparison,
}

impl Kind {
    /// Default x, y and series columns.
    fn defaults(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Kind::StrongScaling | Kind::WeakScaling => {
                ("workers", "solve_s_median", "scaling_series")
            }
            Kind::Convergence => ("h", "error_l2_norm", "refinement_series"),
            Kind::WorkPrecision => ("error_l2_norm", "solve_s_median", "case.method"),
            Kind::Stability => ("case.cfl", "max_abs", "case.method"),
            Kind::TimeSeries => ("c_tot.time", "c_tot.c_tot", "point"),
            Kind::Throughput => ("case.m", "bond_updates_per_s", "backend"),
            Kind::Field => ("field.values", "field.error", "point"),
            Kind::SolverComparison => ("subdomains", "iterations", "case.method"),
        }
    }
}

/// A figure's failure, naming the spec field at fault.
fn fault(k: usize, field: &str, message: impl std::fmt::Display) -> String {
    format!("figures[{k}].{field}: {message}")
}

/// The column a spec names: as written, else the case field of that name.
fn column(rows: &[Row], name: &str) -> Option<String> {
    [name.to_string(), format!("case.{name}")]
        .into_iter()
        .find(|c| rows.iter().any(|r| r.get(c).is_some_and(|v| !v.is_null())))
}

/// The chart of figure `k` of a study whose summary table is `rows`.
pub fn chart(spec: &FigureSpec, k: usize, rows: &[Row]) -> Result<Chart, String> {
    let (dx, dy, ds) = spec.kind.defaults();
    let magnitude = spec
        .y
        .as_deref()
        .and_then(|y| y.strip_prefix("abs(")?.strip_suffix(')'));
    let with_magnitude: Vec<Row>;
    let rows = match magnitude {
        Some(name) => {
            let source = column(rows, name).ok_or_else(|| {
                fault(
                    k,
                    "y",
                    format!("the table has no column `{name}` to take abs() of"),
                )
            })?;
            with_magnitude = rows
                .iter()
                .map(|row| {
                    let mut row = row.clone();
                    let value = row.number(&source).map(f64::abs);
                    row.set(&format!("|{name}|"), serde_json::json!(value));
                    row
                })
                .collect();
            &with_magnitude[..]
        }
        None => rows,
    };
    let resolve = |field: &str, name: &str| {
        column(rows, name).ok_or_else(|| {
            fault(k, field, format!("the table has no column `{name}`; name one of the summary's columns (`nlstudy collect` lists them in results/<study>/<study>-summary.parquet)"))
        })
    };
    let x = resolve("x", spec.x.as_deref().unwrap_or(dx))?;
    let magnitude_name = magnitude.map(|name| format!("|{name}|"));
    let y_name = magnitude_name
        .as_deref()
        .or(spec.y.as_deref())
        .unwrap_or(dy);
    let y = match spec.kind {
        // A problem without an exact solution has no error to map.
        Kind::Field => column(rows, y_name).unwrap_or_else(|| y_name.to_string()),
        _ => resolve("y", y_name)?,
    };
    let series_columns: Vec<String> = match &spec.series {
        Some(names) => names
            .iter()
            .map(|n| resolve("series", n))
            .collect::<Result<_, _>>()?,
        None => vec![ds.to_string()],
    };
    let mut kept = Vec::new();
    for row in rows {
        let scope = Scope::of(&fields(row));
        let mut keep = true;
        for (j, condition) in spec.filter.iter().enumerate() {
            keep &= expression::condition(condition, &scope)
                .map_err(|e| fault(k, &format!("where[{j}]"), e))?;
        }
        if keep {
            kept.push(row);
        }
    }
    if spec.kind == Kind::SolverComparison {
        let title = spec
            .title
            .clone()
            .unwrap_or_else(|| spec.name.replace('_', " "));
        let panels = solver_comparison::solver_comparison(&kept, &series_columns, &x, &y);
        return Ok(Chart { title, panels });
    }
    if spec.kind == Kind::Throughput {
        let panels = throughput::throughput(&kept, &series_columns, &x, &y);
        let title = spec
            .title
            .clone()
            .unwrap_or_else(|| spec.name.replace('_', " "));
        return Ok(Chart { title, panels });
    }
    let mut groups = group(&kept, &series_columns);
    let mut title = spec
        .title
        .clone()
        .unwrap_or_else(|| spec.name.replace('_', " "));
    let common = shared_by_all(&mut groups);
    if !common.is_empty() {
        title = format!("{title}: {common}");
    }
    let mut panels = match spec.kind {
        Kind::StrongScaling => scaling::strong_scaling(&groups, &x, &y),
        Kind::WeakScaling => vec![scaling::weak_scaling(&groups, &x, &y)],
        Kind::Convergence => vec![convergence::convergence(&groups, &x, &y)],
        Kind::WorkPrecision => vec![work_precision::work_precision(&groups, &x, &y)],
        Kind::Stability => vec![stability::stability(&groups, &x, &y)],
        Kind::TimeSeries => vec![time_series::time_series(&groups, &x, &y)],
        Kind::Throughput => unreachable!("drawn above, one panel per n"),
        Kind::SolverComparison => unreachable!("drawn above, two panels"),
        Kind::Field => field::field(&kept, &x, &y).map_err(|e| fault(k, "where", e))?,
    };
    if matches!(spec.kind, Kind::StrongScaling | Kind::WeakScaling) {
        scaling::mark_oversubscribed(&kept, &x, &mut panels, &mut title);
    }
    Ok(Chart { title, panels })
}

/// A row as expression names, as a study's own `where` reads them: the case's fields by their
/// own names, then the other columns. A case field wins over a record column of the same name
/// (the record's `subdomains` is p², the case's p; its `backend` is the one `auto` chose), so a
/// figure's `where` means what the study's does; the record's value is the column when the case
/// leaves the field out.
pub(crate) fn fields(row: &Row) -> Map<String, Value> {
    let mut fields = Map::new();
    for (name, value) in row.cells() {
        if let Some(field) = name.strip_prefix("case.") {
            if !value.is_null() {
                fields.insert(field.to_string(), value.clone());
            }
        }
    }
    for (name, value) in row.cells() {
        fields
            .entry(name.to_string())
            .or_insert_with(|| value.clone());
    }
    fields
}

#[cfg(test)]
mod tests {
    use super::fields;
    use crate::table::Row;
    use serde_json::json;

    #[test]
    fn a_case_field_wins_over_the_record_column_of_the_same_name() {
        // FETI's record holds p² subdomains and the backend `auto` chose; the case holds p and
        // `auto`. A figure's `where` speaks the study's language: the case's.
        let mut row = Row::default();
        row.set("subdomains", json!(16));
        row.set("backend", json!("stencil"));
        row.set("collar", json!("zero"));
        row.set("case.subdomains", json!(4));
        row.set("case.backend", json!("auto"));
        row.set("case.collar", serde_json::Value::Null);
        let named = fields(&row);
        assert_eq!(named["subdomains"], json!(4));
        assert_eq!(named["backend"], json!("auto"));
        // A field the case leaves out is the record's resolved value.
        assert_eq!(named["collar"], json!("zero"));
    }
}
