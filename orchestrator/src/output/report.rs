//! `nlstudy report`: a study as one self-contained HTML page, `results/<study>/report.html`: its
//! description, its figures inline, the summary table, the runs by status, the failures with
//! their messages, and what the runs were made with and where (solver version, git revision,
//! host, CPU, dates). One file to open in a browser or pass on, as Snakemake's `--report` gives
//! its users. Written from the store, the summary table and the drawn figures alone.

use crate::analysis::boundaries;
use crate::analysis::collect::headline;
use crate::model::boundary::BoundarySpec;
use crate::model::study::Study;
use crate::output::status::counts_by_status;
use crate::store::fs::{read_regular, Fault, RECORD_CAP};
use crate::store::table::{self, Row};
use crate::store::{write_atomically, Store};
use maud::{html, Markup, PreEscaped, DOCTYPE};
use schema::record::columns;
use schema::record::{Provenance, Status, Stored};
use schema::text::printable;
use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

/// Writes the report of `study` (whose swept fields are `swept`) and returns its path. It needs
/// no solver: the records come from the store, or, when it holds none (a results folder copied
/// without its runs), from the run table, which keeps each run's status, message, case and
/// provenance; the page says which.
pub fn write(study: &Study, store: &Store, swept: &[String]) -> Result<PathBuf, Fault> {
    // The tables and their sums as one collect wrote them.
    let _outputs = store.lock_outputs()?;
    let mut records = store.scan().records;
    let run_table = store.table(&format!("{}.parquet", study.name));
    let from_table = records.is_empty() && run_table.exists();
    if from_table {
        records = crate::analysis::collect::records_of_run_table(&run_table)?;
    }
    let summary_path = store.table(&format!("{}-summary.parquet", study.name));
    let summary = match summary_path.exists() {
        true => table::read_parquet(&summary_path)?,
        false => Vec::new(),
    };
    let title = format!("Study {}", study.name);
    // maud escapes every value it interpolates: no string of the study or the store becomes
    // markup of the page.
    let page = html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                title { (title) }
                style { (PreEscaped(STYLE)) }
            }
            body {
                h1 { (title) }
                @if !study.description.is_empty() {
                    p.description { (study.description) }
                }
                @if from_table {
                    p.source {
                        "Built from the run table "
                        (run_table.file_name().unwrap_or_default().to_string_lossy())
                        " alone: the stored records are not in this folder, so what they alone hold (the c_tot series, field snapshots, the history of earlier builds) is not shown."
                    }
                }
                (runs_section(&records))
                (adaptive_section(study, store)?)
                (figures_section(study, store, &summary, &records))
                (summary_section(&summary, swept))
                (comparison_section(store))
                (timeline_section(store)?)
                (failures_section(&records))
                (provenance_section(&records))
            }
        }
    };
    let path = store.table("report.html");
    write_atomically(&path, page.into_string().as_bytes())?;
    Ok(path)
}

const STYLE: &str =
    "body{font-family:sans-serif;max-width:70em;margin:2em auto;padding:0 1em;color:#222}\
figure{margin:1.5em 0}figure img{max-width:100%;height:auto;border:1px solid #ddd}\
figcaption{font-style:italic;margin-top:.3em}table{border-collapse:collapse;font-size:.85em}\
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:right}th{background:#f3f3f3}\
pre{white-space:pre-wrap;background:#f8f8f8;padding:.5em}.description{max-width:60em}\
.finding{color:#b00000;font-weight:bold}tr.finding td{background:#fde8e8}";

/// The stored runs counted by status.
fn runs_section(records: &[Stored]) -> Markup {
    html! {
        h2 { "Runs" }
        p { (records.len()) " stored runs: " (counts_by_status(records).join(", ")) "." }
    }
}

/// Each figure of the study inline, its title as the caption with the builds and machines its
/// points were run on; one not drawn yet is named.
fn figures_section(study: &Study, store: &Store, summary: &[Row], records: &[Stored]) -> Markup {
    if study.figures.is_empty() {
        return html! {};
    }
    html! {
        h2 { "Figures" }
        @for (k, spec) in study.figures.iter().enumerate() {
            @let [svg, _] = crate::output::plot::files(&spec.name);
            @let caption = spec.title.as_deref().unwrap_or(&spec.name);
            @match read_regular(&store.table("figures").join(svg), RECORD_CAP) {
                Ok(svg) => figure id=(format!("figure-{}", spec.name)) {
                    (image(&svg, caption))
                    figcaption { (caption) (made_by(spec, k, summary, records)) }
                },
                Err(_) => p {
                    "Figure " em { (caption) } " is not drawn: `nlstudy plot` draws it or says why it cannot."
                },
            }
        }
    }
}

/// The latest run's timeline: where each worker's time went (`output::timeline`).
fn timeline_section(store: &Store) -> Result<Markup, Fault> {
    let Some((_, svg)) = crate::output::timeline::write_latest(store)? else {
        return Ok(html! {});
    };
    Ok(html! {
        h2 { "Timeline" }
        figure id="timeline" {
            (image(&svg, "the latest run's timeline"))
            figcaption {
                "The latest run's workers, one row each: what each did when. "
                code { "nlstudy status --timeline" } " prints the totals."
            }
        }
    })
}

/// The last `nlstudy compare` of the study, if any: its figure and its verdicts counted.
fn comparison_section(store: &Store) -> Markup {
    let Ok(svg) = read_regular(&store.table("compare.svg"), RECORD_CAP) else {
        return html! {};
    };
    let verdicts = table::read_parquet(&store.table("compare.parquet"))
        .map(|rows| {
            let mut counts: BTreeMap<String, usize> = BTreeMap::new();
            for row in &rows {
                *counts
                    .entry(row.text("verdict").unwrap_or("?").to_string())
                    .or_default() += 1;
            }
            counts
                .iter()
                .map(|(v, n)| format!("{n} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default();
    html! {
        h2 { "Comparison" }
        p {
            "The last " code { "nlstudy compare" } ": " (verdicts)
            " (metrics of points; compare.parquet holds each)."
        }
        figure id="compare" { (image(&svg, "the last comparison")) }
    }
}

/// A figure of the results directory as an image, never as markup of the page: anyone who can
/// write there could plant an SVG with a script, and a browser runs none from an `<img>`.
fn image(svg: &str, alt: &str) -> Markup {
    use base64::Engine;
    let data = base64::engine::general_purpose::STANDARD.encode(svg);
    html! { img alt=(alt) src=(format!("data:image/svg+xml;base64,{data}")); }
}

/// ` (runs of build e27b0c1a on vm: Intel Xeon, avx512f)`: the builds and machines of the runs
/// behind figure `k`'s points (more than one only when tabulated with `--allow-mixed`).
fn made_by(
    spec: &crate::model::figure_spec::FigureSpec,
    k: usize,
    summary: &[Row],
    records: &[Stored],
) -> String {
    let Ok(rows) = crate::output::figure::selected(spec, k, summary) else {
        return String::new();
    };
    let cases: BTreeSet<&str> = rows
        .iter()
        .filter_map(|r| r.text(columns::CASE_ID))
        .collect();
    let behind: Vec<&Stored> = records
        .iter()
        .filter(|r| r.case_id.as_deref().is_some_and(|c| cases.contains(c)))
        .collect();
    let behind = crate::analysis::compare::measured(&behind);
    let of = |field: fn(&Provenance) -> &str| -> Vec<String> {
        let set: BTreeSet<String> = behind
            .iter()
            .map(|r| match r.provenance().map_or("", field) {
                "" => "unknown".to_string(),
                text => text.to_string(),
            })
            .collect();
        set.into_iter().collect()
    };
    let builds: Vec<String> = of(|p| &p.fingerprint)
        .iter()
        .map(|f| crate::run::plan::short(f).to_string())
        .collect();
    if builds.is_empty() {
        return String::new();
    }
    format!(
        " (runs of build {} on {}: {}, {})",
        builds.join(" and "),
        of(|p| &p.host).join(", "),
        of(|p| &p.cpu).join(", "),
        of(|p| &p.instruction_set).join(", ")
    )
}

/// The summary table's swept fields and headline results, one row per point.
fn summary_section(summary: &[Row], swept: &[String]) -> Markup {
    if summary.is_empty() {
        return html! {};
    }
    let (names, lines) = headline(summary, swept);
    html! {
        h2 { "Summary" }
        table {
            tr { @for name in &names { th { (name) } } }
            @for line in &lines {
                tr { @for cell in line { td { (cell) } } }
            }
        }
    }
}

/// The table of an adaptive study (its boundaries, refinements or the error target's ranking),
/// whole, from the file `run` wrote; none for a study of a fixed sweep, or before it ran.
fn adaptive_section(study: &Study, store: &Store) -> Result<Markup, Fault> {
    let Some(question) = study.question() else {
        return Ok(html! {});
    };
    let title = question.title();
    let path = crate::analysis::answer_table::path(store, question.table());
    if !path.exists() {
        return Ok(html! {});
    }
    let rows = table::read_parquet(&path)?;
    let boundary = question.as_any().downcast_ref::<BoundarySpec>();
    let rtol = boundary.map(|b| b.rtol);
    Ok(html! {
        h2 { (title) }
        (adaptive_table(&rows, rtol))
    })
}

/// An adaptive study's rows as a table. With a boundary search's `rtol`, a boundary that lies
/// below the theory's prediction by more than it is marked: the theory calls that step stable
/// and the measurement finds it unstable.
fn adaptive_table(rows: &[Row], rtol: Option<f64>) -> Markup {
    let columns: Vec<&str> = rows
        .first()
        .map(|row| row.cells().map(|(name, _)| name).collect())
        .unwrap_or_default();
    let below_theory = |row: &Row| rtol.is_some_and(|rtol| boundaries::below_theory(row, rtol));
    let findings = rows.iter().filter(|row| below_theory(row)).count();
    let texts = crate::analysis::pivot::texts(rows, &columns);
    html! {
        @if findings > 0 {
            p.finding {
                (findings) " of the boundaries lie below the theory's prediction by more than the search's tolerance: there the theory calls the step stable and the measurement finds it unstable."
            }
        }
        table {
            tr { @for name in &columns { th { (name) } } }
            @for (row, line) in rows.iter().zip(&texts) {
                tr class=[below_theory(row).then_some("finding")] {
                    @for cell in line { td { (cell) } }
                }
            }
        }
    }
}

/// Every failed run: its key, its case and its message.
fn failures_section(records: &[Stored]) -> Markup {
    let failed: Vec<&Stored> = records
        .iter()
        .filter(|r| r.status() == Status::Failed)
        .collect();
    if failed.is_empty() {
        return html! {};
    }
    html! {
        h2 { "Failures" }
        @for record in failed {
            h3 { (record.key) }
            p { "Case: " code { (record.case().to_string()) } }
            pre { (printable(record.message())) }
        }
    }
}

/// What the runs were made with and where, as the records tell it, and when.
fn provenance_section(records: &[Stored]) -> Markup {
    let values = |field: fn(&Provenance) -> Option<&str>| -> String {
        let set: BTreeSet<&str> = records
            .iter()
            .filter_map(|r| r.provenance().and_then(field))
            .collect();
        printable(&set.into_iter().collect::<Vec<_>>().join(", ")).into_owned()
    };
    let stamps = values(|p| Some(&p.timestamp));
    let first = stamps.split(", ").next().unwrap_or("");
    let last = stamps.split(", ").last().unwrap_or("");
    let rows = [
        ("solver version", values(|p| Some(&p.solver_version))),
        ("solver fingerprint", values(|p| Some(&p.fingerprint))),
        ("git revision", values(|p| p.git_revision.as_deref())),
        ("host", values(|p| Some(&p.host))),
        ("CPU", values(|p| Some(&p.cpu))),
        ("instruction set", values(|p| Some(&p.instruction_set))),
        (
            "busy machine",
            crate::output::status::noisy_runs(records).unwrap_or_else(|| "no run is noisy".into()),
        ),
        ("first run", first.to_string()),
        ("last run", last.to_string()),
        (
            "report by",
            format!("nlstudy {}", env!("CARGO_PKG_VERSION")),
        ),
    ];
    html! {
        h2 { "Provenance" }
        table {
            @for (name, value) in &rows {
                tr { th { (name) } td { (value) } }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_summary_shows_four_significant_digits_one_notation_per_column() {
        let summary: Vec<Row> = [(16, 0.000003), (32, 9.4513e-9)]
            .iter()
            .map(|&(n, error)| {
                let mut row = Row::default();
                row.set("case.n", json!(n));
                row.set("error_l2_norm", json!(error));
                row
            })
            .collect();
        let page = summary_section(&summary, &["n".to_string()]).into_string();
        assert!(
            page.contains("<tr><th>n</th><th>error_l2_norm</th></tr><tr><td>16</td><td>3e-6</td></tr><tr><td>32</td><td>9.451e-9</td></tr>"),
            "{page}"
        );
    }

    /// A boundary below the theory's prediction by more than the tolerance is a finding: its
    /// row is marked and said; one above it, or within the tolerance, is not.
    #[test]
    fn a_boundary_below_the_theory_is_marked() {
        let rows: Vec<Row> = [(1.002, 0.002), (0.99, -0.01), (0.9995, -0.0005)]
            .iter()
            .map(|&(boundary, gap)| {
                let mut row = Row::default();
                row.set("boundary", json!(boundary));
                row.set("predicted", json!(1.0));
                row.set("gap", json!(gap));
                row
            })
            .collect();
        let page = adaptive_table(&rows, Some(1e-3)).into_string();
        assert_eq!(page.matches(r#"<tr class="finding">"#).count(), 1, "{page}");
        assert!(page.contains("1 of the boundaries lie below"), "{page}");
        let refinements = adaptive_table(&rows, None).into_string();
        assert!(!refinements.contains("finding"), "{refinements}");
    }
}
