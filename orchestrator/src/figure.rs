//! A study's figures: their specs as the study file lists them, and the charts each kind makes of
//! the summary table (one row per point).

use crate::draw::{self, Axis, Chart, Guide, HeatMap, Panel, Series};
use crate::expression::{self, Scope};
use crate::table::Row;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

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

/// How columns read on an axis.
fn describe(column: &str) -> String {
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
        let panels = solver_comparison(&kept, &series_columns, &x, &y);
        return Ok(Chart { title, panels });
    }
    if spec.kind == Kind::Throughput {
        let panels = throughput(&kept, &series_columns, &x, &y);
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
        Kind::StrongScaling => strong_scaling(&groups, &x, &y),
        Kind::WeakScaling => vec![weak_scaling(&groups, &x, &y)],
        Kind::Convergence => vec![convergence(&groups, &x, &y)],
        Kind::WorkPrecision => vec![work_precision(&groups, &x, &y)],
        Kind::Stability => vec![stability(&groups, &x, &y)],
        Kind::TimeSeries => vec![time_series(&groups, &x, &y)],
        Kind::Throughput => unreachable!("drawn above, one panel per n"),
        Kind::SolverComparison => unreachable!("drawn above, two panels"),
        Kind::Field => field(&kept, &x, &y).map_err(|e| fault(k, "where", e))?,
    };
    if matches!(spec.kind, Kind::StrongScaling | Kind::WeakScaling) {
        mark_oversubscribed(&kept, &x, &mut panels, &mut title);
    }
    Ok(Chart { title, panels })
}

/// A row as expression names: its columns, and the case's fields by their own names.
pub(crate) fn fields(row: &Row) -> Map<String, Value> {
    let mut fields = Map::new();
    for (name, value) in row.cells() {
        fields.insert(name.to_string(), value.clone());
    }
    for (name, value) in row.cells() {
        if let Some(field) = name.strip_prefix("case.") {
            fields
                .entry(field.to_string())
                .or_insert_with(|| value.clone());
        }
    }
    fields
}

/// Rows of one series, with its label.
struct Group<'a> {
    label: String,
    rows: Vec<&'a Row>,
}

fn group<'a>(rows: &[&'a Row], columns: &[String]) -> Vec<Group<'a>> {
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
fn shared_by_all(groups: &mut [Group]) -> String {
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
    fn points(&self, x: &str, y: &str) -> Vec<(f64, f64)> {
        let mut points: Vec<(f64, f64)> = self
            .rows
            .iter()
            .filter(|r| r.text("status") == Some("ok"))
            .filter_map(|r| Some((r.number(x)?, r.number(y)?)))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        points
    }

    /// The label with the repeats behind its points: `… (3 repeats)` or `(1–3 repeats)`.
    fn legend(&self) -> String {
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

fn series(label: String, points: Vec<(f64, f64)>) -> Series {
    Series {
        label,
        points,
        band: Vec::new(),
        crosses: Vec::new(),
        note: None,
    }
}

fn all<'a>(panel: impl Iterator<Item = &'a Series>, pick: fn(&(f64, f64)) -> f64) -> Vec<f64> {
    panel.flat_map(|s| s.points.iter().map(pick)).collect()
}

/// The statistic's band columns: `solve_s_median` → `solve_s_min`, `solve_s_max`.
fn band_columns(y: &str) -> Option<(String, String)> {
    let stem = y.strip_suffix("_median")?;
    Some((format!("{stem}_min"), format!("{stem}_max")))
}

fn strong_scaling(groups: &[Group], x: &str, y: &str) -> Vec<Panel> {
    let (mut times, mut speedups, mut efficiencies) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ideal_time, mut ideal_speedup) = (Vec::new(), Vec::new());
    for (k, g) in groups.iter().enumerate() {
        let points = g.points(x, y);
        let Some(&(p0, t0)) = points.first() else {
            continue;
        };
        let mut time = series(g.legend(), points.clone());
        if let Some((lo, hi)) = band_columns(y) {
            let rows = g.rows.iter().filter(|r| r.text("status") == Some("ok"));
            time.band = rows
                .filter_map(|r| Some((r.number(x)?, r.number(&lo)?, r.number(&hi)?)))
                .collect();
            time.band.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        let speedup: Vec<(f64, f64)> = points.iter().map(|&(p, t)| (p, t0 / t)).collect();
        let efficiency = speedup.iter().map(|&(p, s)| (p, s * p0 / p)).collect();
        let label = |first: bool| first.then(|| "ideal".to_string());
        ideal_time.push(Guide::Dashed {
            label: label(k == 0),
            of: Some(k),
            points: points.iter().map(|&(p, _)| (p, t0 * p0 / p)).collect(),
        });
        ideal_speedup.push(Guide::Dashed {
            label: label(k == 0),
            of: Some(k),
            points: points.iter().map(|&(p, _)| (p, p / p0)).collect(),
        });
        times.push(time);
        speedups.push(series(g.legend(), speedup));
        efficiencies.push(series(g.legend(), efficiency));
    }
    let workers = all(times.iter(), |p| p.0);
    let x_axis = || Axis::fitting(describe(x), workers.iter().copied()).counting();
    let mut efficiency_axis = Axis::linear("parallel efficiency T(p₀)·p₀ / (T(p)·p)");
    efficiency_axis.include = vec![0.0, 1.0];
    vec![
        Panel {
            title: "time".into(),
            x: x_axis(),
            y: Axis::fitting(describe(y), all(times.iter(), |p| p.1)),
            series: times,
            guides: ideal_time,
            heat: None,
        },
        Panel {
            title: "speedup".into(),
            x: x_axis(),
            y: Axis::fitting("speedup T(p₀) / T(p)", all(speedups.iter(), |p| p.1)),
            series: speedups,
            guides: ideal_speedup,
            heat: None,
        },
        Panel {
            title: "parallel efficiency".into(),
            x: x_axis(),
            y: efficiency_axis,
            series: efficiencies,
            guides: vec![ideal_efficiency(&workers)],
            heat: None,
        },
    ]
}

/// Crosses over the points run with more workers than the machine had cores (the record's
/// `oversubscribed`), and a note in the title: their times measure contention, not scaling.
fn mark_oversubscribed(rows: &[&Row], x: &str, panels: &mut [Panel], title: &mut String) {
    let beyond: Vec<f64> = rows
        .iter()
        .filter(|r| r.get("oversubscribed") == Some(&Value::Bool(true)))
        .filter_map(|r| r.number(x))
        .collect();
    if beyond.is_empty() {
        return;
    }
    for line in panels.iter_mut().flat_map(|p| p.series.iter_mut()) {
        line.crosses = line
            .points
            .iter()
            .filter(|p| beyond.contains(&p.0))
            .copied()
            .collect();
    }
    title.push_str(" (×: more workers than cores, not performance data)");
}

/// Efficiency 1 across the workers shown.
fn ideal_efficiency(workers: &[f64]) -> Guide {
    let (lo, hi) = draw::span(workers.iter().copied());
    Guide::Dashed {
        label: Some("ideal".into()),
        of: None,
        points: match lo <= hi {
            true => vec![(lo, 1.0), (hi, 1.0)],
            false => Vec::new(),
        },
    }
}

fn weak_scaling(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .filter_map(|g| {
            let points = g.points(x, y);
            let &(_, t0) = points.first()?;
            Some(series(
                g.legend(),
                points.iter().map(|&(p, t)| (p, t0 / t)).collect(),
            ))
        })
        .collect();
    let workers = all(lines.iter(), |p| p.0);
    let mut y_axis = Axis::linear("weak-scaling efficiency T(p₀) / T(p)");
    y_axis.include = vec![0.0, 1.0];
    Panel {
        title: "weak scaling".into(),
        x: Axis::fitting(describe(x), workers.iter().copied()).counting(),
        y: y_axis,
        heat: None,
        guides: vec![ideal_efficiency(&workers)],
        series: lines,
    }
}

/// The least-squares slope of log y against log x.
pub fn fitted_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let (mx, my) = logs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

fn convergence(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| {
            let points = g.points(x, y);
            let slope = fitted_slope(&points);
            let mut line = series(
                match slope {
                    Some(s) => format!("{} slope {s:.2}", g.legend()),
                    None => g.legend(),
                },
                points,
            );
            line.note = slope.map(|s| format!("  {s:.2}"));
            line
        })
        .collect();
    Panel {
        title: "convergence".into(),
        x: Axis::fitting(describe(x), all(lines.iter(), |p| p.0)),
        y: Axis::fitting(describe(y), all(lines.iter(), |p| p.1)),
        series: lines,
        guides: Vec::new(),
        heat: None,
    }
}

/// The points no other point beats in both error and time, by increasing error.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut sorted = points.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in sorted {
        if front.last().is_none_or(|last| p.1 < last.1) {
            front.push(p);
        }
    }
    front
}

fn work_precision(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| series(g.legend(), g.points(x, y)))
        .collect();
    let everything: Vec<(f64, f64)> = lines.iter().flat_map(|s| s.points.clone()).collect();
    Panel {
        title: "work–precision".into(),
        x: Axis::fitting(describe(x), all(lines.iter(), |p| p.0)),
        y: Axis::fitting(describe(y), all(lines.iter(), |p| p.1)),
        series: lines,
        heat: None,
        guides: vec![Guide::Dashed {
            label: Some("Pareto front".into()),
            of: None,
            points: pareto_front(&everything),
        }],
    }
}

/// Iterations (`y`) and median solve time against the subdomains, a series per solver; a row
/// without subdomains (CG) is drawn at every subdomain count of the rows with its n.
fn solver_comparison(rows: &[&Row], series_columns: &[String], x: &str, y: &str) -> Vec<Panel> {
    let subdomains_of_n: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| Some((r.number("case.n")?, r.number(x)?)))
        .collect();
    let mut placed: Vec<Row> = Vec::new();
    for &row in rows {
        if row.number(x).is_some() {
            placed.push(row.clone());
            continue;
        }
        let n = row.number("case.n");
        let mut at: Vec<f64> = subdomains_of_n
            .iter()
            .filter(|(m, _)| Some(*m) == n)
            .map(|&(_, s)| s)
            .collect();
        at.sort_by(f64::total_cmp);
        at.dedup();
        for s in at {
            let mut copy = row.clone();
            copy.set(x, serde_json::json!(s));
            placed.push(copy);
        }
    }
    let placed: Vec<&Row> = placed.iter().collect();
    let mut groups = group(&placed, series_columns);
    shared_by_all(&mut groups);
    [(y, "iterations"), ("solve_s_median", "solve time")]
        .into_iter()
        .map(|(column, title)| {
            let lines: Vec<Series> = groups
                .iter()
                .map(|g| series(g.legend(), g.points(x, column)))
                .collect();
            Panel {
                title: title.into(),
                x: Axis::fitting(describe(x), all(lines.iter(), |p| p.0)),
                y: Axis::fitting(describe(column), all(lines.iter(), |p| p.1)),
                series: lines,
                heat: None,
                guides: Vec::new(),
            }
        })
        .collect()
}

/// One panel per grid size n: a series per backend, and the crossover where the FFT overtakes
/// the stencil.
fn throughput(rows: &[&Row], series_columns: &[String], x: &str, y: &str) -> Vec<Panel> {
    let mut sizes: Vec<f64> = rows.iter().filter_map(|r| r.number("case.n")).collect();
    sizes.sort_by(f64::total_cmp);
    sizes.dedup();
    sizes
        .iter()
        .map(|&n| {
            let of_size: Vec<&Row> = rows
                .iter()
                .copied()
                .filter(|r| r.number("case.n") == Some(n))
                .collect();
            let mut groups = group(&of_size, series_columns);
            shared_by_all(&mut groups);
            let lines: Vec<Series> = groups
                .iter()
                .map(|g| series(g.legend(), g.points(x, y)))
                .collect();
            let backend_points = |name: &str| {
                groups
                    .iter()
                    .find(|g| g.rows.iter().all(|r| r.text("backend") == Some(name)))
                    .map(|g| g.points(x, y))
            };
            let guides = match (backend_points("stencil"), backend_points("fft")) {
                (Some(stencil), Some(fft)) => crossover(&stencil, &fft)
                    .map(|m| Guide::Vertical {
                        label: format!("n = {n}: FFT faster from m ≈ {m:.1}"),
                        x: m,
                    })
                    .into_iter()
                    .collect(),
                _ => Vec::new(),
            };
            Panel {
                title: format!("n = {n}"),
                x: Axis::fitting(describe(x), all(lines.iter(), |p| p.0)),
                y: Axis::fitting(describe(y), all(lines.iter(), |p| p.1)),
                series: lines,
                guides,
                heat: None,
            }
        })
        .collect()
}

/// The m where `fast_for_large` (throughput against m) first overtakes `fast_for_small`,
/// interpolated linearly in log m on the log of their ratio between the m's both measured.
fn crossover(fast_for_small: &[(f64, f64)], fast_for_large: &[(f64, f64)]) -> Option<f64> {
    let advantage: Vec<(f64, f64)> = fast_for_small
        .iter()
        .filter_map(|&(m, small)| {
            let &(_, large) = fast_for_large.iter().find(|p| p.0 == m)?;
            Some((m.ln(), (large / small).ln()))
        })
        .collect();
    advantage.windows(2).find_map(|pair| {
        let [(m0, a0), (m1, a1)] = [pair[0], pair[1]];
        (a0 < 0.0 && a1 >= 0.0).then(|| (m0 + (m1 - m0) * a0 / (a0 - a1)).exp())
    })
}

fn stability(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .map(|g| {
            let mut line = series(g.legend(), g.points(x, y));
            // A diverged run stops where |u| passed the bound; its cross sits at what it reached.
            line.crosses = g
                .rows
                .iter()
                .filter(|r| r.text("status") == Some("diverged"))
                .filter_map(|r| Some((r.number(x)?, r.number(y).filter(|v| v.is_finite())?)))
                .collect();
            line
        })
        .collect();
    let ys = lines
        .iter()
        .flat_map(|s| s.points.iter().chain(&s.crosses).map(|p| p.1))
        .collect::<Vec<_>>();
    let mut x_axis = Axis::linear(describe(x));
    x_axis.include = vec![1.0];
    Panel {
        title: "stability (× diverged)".into(),
        x: x_axis,
        y: Axis::fitting(describe(y), ys),
        series: lines,
        heat: None,
        guides: vec![Guide::Vertical {
            label: "dt = dt_stable".into(),
            x: 1.0,
        }],
    }
}

/// A column holding an array of numbers (stored as JSON text in the tables).
fn numbers(value: Option<&Value>) -> Vec<f64> {
    let parsed = match value {
        Some(Value::String(text)) => serde_json::from_str::<Vec<f64>>(text).ok(),
        Some(Value::Array(items)) => items.iter().map(Value::as_f64).collect(),
        _ => None,
    };
    parsed.unwrap_or_default()
}

fn time_series(groups: &[Group], x: &str, y: &str) -> Panel {
    let lines: Vec<Series> = groups
        .iter()
        .flat_map(|g| g.rows.iter().map(move |r| (g, r)))
        .map(|(g, r)| {
            let points = numbers(r.get(x))
                .into_iter()
                .zip(numbers(r.get(y)))
                .collect();
            series(g.label.clone(), points)
        })
        .collect();
    // The whole range from 0, as seed 004 draws c_tot(t).
    let mut y_axis = Axis::linear(describe(y));
    y_axis.include = vec![0.0];
    Panel {
        title: "time series".into(),
        x: Axis::linear(describe(x)),
        y: y_axis,
        series: lines,
        guides: Vec::new(),
        heat: None,
    }
}

/// The final field of the one point `rows` holds (column `x`) and its error (column `y`): heat
/// maps in 2D, profiles in 1D.
fn field(rows: &[&Row], x: &str, y: &str) -> Result<Vec<Panel>, String> {
    let [row] = rows else {
        return Err(format!(
            "selects {} points, but a field figure shows one; narrow the conditions (e.g. `n == 128 && method == 'nonlocal'`)",
            rows.len()
        ));
    };
    let stem = x.strip_suffix(".values").unwrap_or("field");
    let size = |name: &str| row.number(&format!("{stem}.{name}"));
    let (Some(nx), Some(ny), Some(lower), Some(upper)) =
        (size("nx"), size("ny"), size("lower"), size("upper"))
    else {
        return Err(format!("the point has no `{stem}` snapshot; set `field_snapshot` (e.g. 64) in the study's base"));
    };
    let (nx, ny) = (nx as usize, ny as usize);
    let values = numbers(row.get(x));
    let error = numbers(row.get(y));
    let mut panels = vec![field_panel(
        "u at the final time",
        nx,
        ny,
        (lower, upper),
        values,
        false,
    )];
    if !error.is_empty() {
        panels.push(field_panel(
            "error u − u_exact",
            nx,
            ny,
            (lower, upper),
            error,
            true,
        ));
    }
    Ok(panels)
}

/// One field panel: cells coloured by value in 2D, the profile over x in 1D.
fn field_panel(
    title: &str,
    nx: usize,
    ny: usize,
    (lower, upper): (f64, f64),
    values: Vec<f64>,
    signed: bool,
) -> Panel {
    let (heat, series) = match ny > 1 {
        true => {
            let heat = HeatMap {
                nx,
                ny,
                lower,
                upper,
                values,
                diverging: signed,
            };
            (Some(heat), Vec::new())
        }
        false => {
            let dx = (upper - lower) / nx as f64;
            let profile = values
                .iter()
                .enumerate()
                .map(|(i, &v)| (lower + (i as f64 + 0.5) * dx, v))
                .collect();
            (None, vec![series(title.to_string(), profile)])
        }
    };
    let y_label = if heat.is_some() { "y" } else { title };
    Panel {
        title: title.to_string(),
        x: Axis::linear("x"),
        y: Axis::linear(y_label),
        series,
        guides: Vec::new(),
        heat,
    }
}

#[cfg(test)]
mod tests {
    use super::crossover;

    #[test]
    fn crossover_interpolates_in_log_m_where_the_ratio_changes_sign() {
        // The FFT's throughput grows like m² while the stencil's stays flat: they meet at m = 4.
        let stencil = [(1.0, 16.0), (2.0, 16.0), (8.0, 16.0)];
        let fft = [(1.0, 1.0), (2.0, 4.0), (8.0, 64.0)];
        let m = crossover(&stencil, &fft).expect("they cross");
        assert!((m - 4.0).abs() < 1e-12, "{m}");
        // Never overtaken: no crossover.
        assert_eq!(
            crossover(
                &fft[..2],
                &stencil[..2]
                    .iter()
                    .map(|&(m, _)| (m, 0.5))
                    .collect::<Vec<_>>()
            ),
            None
        );
    }
}
