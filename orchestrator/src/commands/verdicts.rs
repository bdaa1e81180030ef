//! What `compare` says of a comparison, however its sides were made (stored runs, or
//! interleaved reruns): the verdicts as Markdown, `compare.parquet` and `compare.svg` beside the
//! study's tables, and the exit status (1 when something got worse).

use super::failure::Failure;
use crate::analysis::compare;
use crate::console::Reply;
use crate::model::study::Study;
use crate::store::Store;
use schema::exit;
use std::process::ExitCode;

/// `reply` with a comparison's verdicts: writes `compare.parquet` and `compare.svg` beside the
/// study's tables, says where, and exits 1 when something got worse.
#[allow(clippy::too_many_arguments)] // (what a comparison is reported with, each once)
pub(super) fn report(
    mut reply: Reply,
    comparison: &compare::Comparison,
    study: &Study,
    store: &Store,
    against: &str,
    title: &str,
    threshold: f64,
    points: usize,
) -> Result<Reply, Failure> {
    reply.result(compare::markdown(comparison));
    for (side, points) in [("A", &comparison.only_a), ("B", &comparison.only_b)] {
        for point in points {
            reply.line(format!("only in {side}: {point}"));
        }
    }
    let table = store.table("compare.parquet");
    crate::store::table::write_parquet_about(
        &[(&table, &compare::rows(comparison))],
        &crate::store::table::About {
            description: &format!("{} against {against}", study.name),
            notes: &[],
        },
    )?;
    let figure = store.table("compare.svg");
    let chart = crate::output::compare_figure::chart(comparison, title, threshold);
    // A figure that cannot be drawn stops nothing: the table holds every verdict.
    match crate::output::draw::render(&chart) {
        Ok(svg) => crate::store::write_atomically(&figure, svg.as_bytes())?,
        Err(why) => {
            reply.warn(format!("the comparison's figure is not drawn: {why}"));
        }
    }
    let regressions = comparison.regressions();
    reply.note(format!(
        "compare: {} metrics of {points} points, {regressions} worse; table: {}, figure: {}",
        comparison.changes.len(),
        table.display(),
        figure.display()
    ));
    Ok(match regressions {
        0 => reply,
        _ => reply.ending(ExitCode::from(exit::CASE_FAILED)),
    })
}
