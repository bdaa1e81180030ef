//! The charts each figure kind makes of a study's summary table (one row per point).

use crate::model::adaptive::Kind;
use crate::model::boundary::BoundarySpec;
use crate::model::expression::Filter;
use crate::model::figure_spec::{FigureKind, FigureSpec};
use crate::model::target::TargetSpec;
use crate::output::draw::{Chart, Glyph, Panel};
use crate::store::table::Row;
use schema::record::Status;

mod boundaries;
mod convergence;
mod field;
mod scaling;
mod scaling_model;
mod series;
mod solver_comparison;
mod stability;
mod throughput;
mod time_series;
mod work_precision;

use series::{group, shared_by_all, subtitle};

/// A figure's failure: `figures[2] (convergence): ` and a sentence naming the spec field at
/// fault.
pub fn fault(k: usize, spec: &FigureSpec, message: impl std::fmt::Display) -> String {
    format!("figures[{k}] ({}): {message}", spec.name)
}

/// The column a spec names: as written, else the case field of that name.
fn column(rows: &[Row], name: &str) -> Option<String> {
    [name.to_string(), format!("case.{name}")]
        .into_iter()
        .find(|c| rows.iter().any(|r| r.get(c).is_some_and(|v| !v.is_null())))
}

/// The rows of the summary table that figure `k`'s `where` keeps.
pub fn selected<'a>(spec: &FigureSpec, k: usize, rows: &'a [Row]) -> Result<Vec<&'a Row>, String> {
    let at = |(j, e)| fault(k, spec, format!("where[{j}]: {e}"));
    let filter = Filter::parse(&spec.filter).map_err(at)?;
    let mut kept = Vec::new();
    for row in rows {
        if row.meets(&filter).map_err(at)? {
            kept.push(row);
        }
    }
    Ok(kept)
}

/// The answers of a study's adaptive question, from the table `run` wrote
/// (`<study>-<question.table()>.parquet`), for the figures that draw them.
#[derive(Clone, Copy)]
pub struct Answers<'a> {
    pub question: &'a dyn Kind,
    pub rows: &'a [Row],
}

impl<'a> Answers<'a> {
    /// The question's spec, if it is of kind `S` (the figure draws that kind's answers).
    fn spec<S: 'static>(&self) -> Option<&'a S> {
        self.question.as_any().downcast_ref()
    }
}

/// The figure's title: as the spec gives it, else its name.
fn title(spec: &FigureSpec) -> String {
    spec.title
        .clone()
        .unwrap_or_else(|| spec.name.replace('_', " "))
}

/// The chart of figure `k` of a study whose summary table is `rows`, with its adaptive
/// question's `answers` where it has them.
pub fn chart(
    spec: &FigureSpec,
    k: usize,
    rows: &[Row],
    answers: Option<Answers>,
) -> Result<Chart, String> {
    if spec.kind == FigureKind::Boundaries {
        return boundaries_chart(spec, k, answers);
    }
    // Before the columns are looked for: a column no run filled is no fault of the spec.
    let has_result = |r: &&Row| matches!(r.status(), Some(Status::Ok | Status::Diverged));
    if !rows.iter().any(|r| has_result(&r)) {
        return Err(fault(k, spec, format!("every run failed: none of the {} points of the summary table has a result to draw; `nlstudy status` lists why", rows.len())));
    }
    let (dx, dy, ds) = spec.kind.defaults();
    let magnitude = spec
        .y
        .as_deref()
        .and_then(|y| y.strip_prefix("abs(")?.strip_suffix(')'));
    let with_magnitude = magnitude
        .map(|name| {
            with_magnitude(rows, name).ok_or_else(|| {
                fault(
                    k,
                    spec,
                    format!("y takes abs() of `{name}`, which is no column of the summary table"),
                )
            })
        })
        .transpose()?;
    let rows = with_magnitude.as_deref().unwrap_or(rows);
    let resolve = |field: &str, name: &str| {
        column(rows, name).ok_or_else(|| {
            fault(k, spec, format!("{field} names no column `{name}` of the summary table; name one of its columns (`nlstudy collect` writes it to results/<study>/<study>-summary.parquet)"))
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
        FigureKind::Field => column(rows, y_name).unwrap_or_else(|| y_name.to_string()),
        _ => resolve("y", y_name)?,
    };
    let series_columns: Vec<String> = match &spec.series {
        Some(names) => names
            .iter()
            .map(|n| resolve("series", n))
            .collect::<Result<_, _>>()?,
        None => vec![ds.to_string()],
    };
    let kept = selected(spec, k, rows)?;
    if kept.is_empty() {
        return Err(fault(k, spec, format!("where selects no row of the summary table ({} rows); compare its conditions with the table's values (`nlstudy table` shows them)", rows.len())));
    }
    if !kept.iter().any(has_result) {
        return Err(fault(
            k,
            spec,
            format!(
                "every run of the {} points `where` selects failed; `nlstudy status` lists why",
                kept.len()
            ),
        ));
    }
    let series_columns = split_by_build(series_columns, &kept);
    let title = title(spec);
    let (panels, subtitle_text) = panels(spec, k, &kept, &series_columns, (&x, &y), answers)?;
    let drawn = |p: &Panel| {
        p.heat.is_some()
            || p.series
                .iter()
                .any(|s| !s.points.is_empty() || !s.marks.is_empty())
    };
    if !panels.iter().any(drawn) {
        return Err(fault(
            k,
            spec,
            format!(
                "where selects {} rows, but none has both `{x}` and `{y}` (with status ok) to draw",
                kept.len()
            ),
        ));
    }
    if matches!(
        spec.kind,
        FigureKind::StrongScaling | FigureKind::WeakScaling
    ) {
        two_worker_counts(&kept, &x).map_err(|e| fault(k, spec, e))?;
    }
    let mut chart = Chart::new(title, subtitle_text, panels);
    explain_glyphs(&mut chart, spec.kind);
    Ok(chart)
}

/// `rows` with the magnitude of column `name` beside it, as `|name|`; None when no column is
/// `name`.
fn with_magnitude(rows: &[Row], name: &str) -> Option<Vec<Row>> {
    let source = column(rows, name)?;
    let with = |row: &Row| {
        let mut row = row.clone();
        let value = row.number(&source).map(f64::abs);
        row.set(&format!("|{name}|"), serde_json::json!(value));
        row
    };
    Some(rows.iter().map(with).collect())
}

/// Points of several solver builds (a table collected with --allow-mixed) are never joined into
/// one line: the build splits the series and names them.
fn split_by_build(mut series_columns: Vec<String>, kept: &[&Row]) -> Vec<String> {
    let mut builds: Vec<&str> = kept.iter().filter_map(|r| r.text("build")).collect();
    builds.sort_unstable();
    builds.dedup();
    if builds.len() > 1 && !series_columns.iter().any(|c| c == "build") {
        series_columns.push("build".to_string());
    }
    series_columns
}

/// A scaling figure's rows ran on two worker counts or more (its x).
fn two_worker_counts(kept: &[&Row], x: &str) -> Result<(), String> {
    let mut workers: Vec<f64> = kept.iter().filter_map(|r| r.number(x)).collect();
    workers.sort_by(f64::total_cmp);
    workers.dedup();
    match workers.len() {
        0 | 1 => Err(format!("the points `where` selects ran on one worker count ({}); a scaling figure needs two or more", workers.first().map_or("none".to_string(), |w| crate::console::number(*w)))),
        _ => Ok(()),
    }
}

/// The panels of a figure of the summary table (every kind but `boundaries`), from its `kept`
/// rows, and its subtitle: what every series shares.
fn panels(
    spec: &FigureSpec,
    k: usize,
    kept: &[&Row],
    series_columns: &[String],
    (x, y): (&str, &str),
    answers: Option<Answers>,
) -> Result<(Vec<Panel>, String), String> {
    let mut subtitle_text = String::new();
    let panels = match spec.kind {
        FigureKind::SolverComparison => {
            solver_comparison::solver_comparison(kept, series_columns, x, y)
        }
        FigureKind::Throughput => throughput::throughput(kept, series_columns, x, y),
        FigureKind::ScalingModel => {
            let (panels, text) =
                scaling_model::scaling_model(kept).map_err(|e| fault(k, spec, e))?;
            subtitle_text = text;
            panels
        }
        FigureKind::Field => {
            field::field(kept, x, y).map_err(|e| fault(k, spec, format!("where {e}")))?
        }
        kind => {
            let mut groups = group(kept, series_columns);
            let scaling = matches!(kind, FigureKind::StrongScaling | FigureKind::WeakScaling);
            if scaling && spec.series.is_none() {
                groups = scaling::by_parallelism(groups);
            }
            subtitle_text = subtitle(&shared_by_all(&mut groups));
            match kind {
                FigureKind::StrongScaling => scaling::strong_scaling(&groups, x, y),
                FigureKind::WeakScaling => vec![scaling::weak_scaling(&groups, x, y)],
                FigureKind::Convergence => vec![convergence::convergence(&groups, x, y)],
                FigureKind::WorkPrecision => {
                    let mut panel = work_precision::work_precision(&groups, x, y);
                    let target = answers.and_then(|a| Some((a.spec::<TargetSpec>()?, a.rows)));
                    if let Some((target, rows)) = target {
                        work_precision::mark_target(&mut panel, &groups, (x, y), target, rows);
                    }
                    vec![panel]
                }
                FigureKind::Stability => vec![stability::stability(&groups, x, y)],
                FigureKind::TimeSeries => vec![time_series::time_series(&groups, x, y)],
                FigureKind::SolverComparison
                | FigureKind::Throughput
                | FigureKind::Field
                | FigureKind::ScalingModel
                | FigureKind::Boundaries => unreachable!("drawn from the rows above"),
            }
        }
    };
    Ok((panels, subtitle_text))
}

/// Each glyph's meaning, given only where some series draws it.
fn explain_glyphs(chart: &mut Chart, kind: FigureKind) {
    chart.explain(
        Glyph::Ring,
        "noisy: timed while other tasks wanted the cores",
    );
    chart.explain(
        Glyph::Square,
        "the coarsest resolution of its configuration that meets the error target",
    );
    chart.explain(
        Glyph::Cross,
        match kind {
            FigureKind::Stability => {
                "diverged (|u| passed the bound) or grew ten times past the problem's scale"
            }
            _ => "more workers than cores: contention, not scaling",
        },
    );
}

/// The boundaries figure: drawn from the boundary table of the study's `boundary` question.
fn boundaries_chart(
    spec: &FigureSpec,
    k: usize,
    answers: Option<Answers>,
) -> Result<Chart, String> {
    let Some((question, rows)) = answers.and_then(|a| Some((a.spec::<BoundarySpec>()?, a.rows)))
    else {
        return Err(fault(k, spec, "draws the table of the study's boundary searches, which is not written yet; `nlstudy run` writes it"));
    };
    let kept = selected(spec, k, rows)?;
    if kept.is_empty() {
        return Err(fault(
            k,
            spec,
            format!(
                "where selects no row of the boundary table ({} rows)",
                rows.len()
            ),
        ));
    }
    let swept = boundaries::swept(&kept);
    let numeric = |name: &str| kept.iter().any(|r| r.number(name).is_some());
    let x = match &spec.x {
        Some(x) if numeric(x) => x.clone(),
        Some(x) => return Err(fault(k, spec, format!("x names `{x}`, which is no numeric column of the boundary table; name a swept field such as {}", swept.join(", ")))),
        None => ["m".to_string()]
            .iter()
            .chain(&swept)
            .find(|name| numeric(name))
            .cloned()
            .ok_or_else(|| fault(k, spec, "the boundary table has no numeric swept field to draw the boundaries along; sweep one (m, n …) or give `x`"))?,
    };
    let series_columns: Vec<String> = match &spec.series {
        Some(names) => names.clone(),
        None => swept.into_iter().filter(|name| *name != x).collect(),
    };
    let (panels, subtitle_text) = boundaries::boundaries(&kept, &series_columns, &x, question.rtol);
    if !panels
        .iter()
        .any(|p| p.series.iter().any(|s| !s.points.is_empty()))
    {
        return Err(fault(k, spec, format!("none of the {} searches `where` selects found a boundary to draw; the table says how each ended", kept.len())));
    }
    let mut chart = Chart::new(title(spec), subtitle_text, panels);
    chart.explain(
        Glyph::Cross,
        "below the theory by more than the search's tolerance: the theory calls it stable, the measurement finds it unstable",
    );
    Ok(chart)
}
