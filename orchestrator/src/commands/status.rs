//! `nlstudy status`: the stored records counted by status, the failures and the jobs; with
//! `--timeline`, where the workers' time went in the latest runs.

use super::failure::Failure;
use super::open::{open_store, planned_and_index, read_study};
use crate::analysis::timeline::Timeline;
use crate::cli::args::StatusArgs;
use crate::console::Reply;
use crate::output::status;
use crate::run::plan::Options;
use crate::store::timeline::LATEST;

pub(super) fn status(args: &StatusArgs) -> Result<Reply, Failure> {
    if args.timeline {
        return timeline(args);
    }
    let (study, solver, store, index, planned) =
        planned_and_index(&args.common, &Options::default(), false)?;
    let fingerprint = solver.fingerprint.as_deref();
    let mut reply = Reply::default();
    reply.result(status::render(
        &study.name,
        &store,
        &index,
        &planned,
        fingerprint,
    ));
    Ok(reply)
}

/// Needs no solver, as the timelines are files of the study's folder.
fn timeline(args: &StatusArgs) -> Result<Reply, Failure> {
    let study = read_study(&args.common.study)?;
    let store = open_store(&args.common, &study, false)?;
    let (all, read) = crate::store::timeline::latest(&store, LATEST);
    let runs: Vec<Timeline> = read.iter().filter_map(Timeline::of).collect();
    let mut reply = Reply::default();
    if runs.is_empty() {
        reply.line(format!(
            "no timeline of study {}: `nlstudy run` records one for each run that runs a case",
            study.name
        ));
        return Ok(reply);
    }
    let skipped = all.saturating_sub(LATEST);
    if skipped > 0 {
        reply.line(format!("({skipped} earlier runs not shown)"));
    }
    for run in &runs {
        reply.line(crate::output::timeline::table(run).join("\n"));
    }
    // The latest, read above: drawn without reading it again.
    if let Some(latest) = runs.last() {
        let (path, _) = crate::output::timeline::write(&store, latest)?;
        reply.note(format!("timeline: {}", path.display()));
    }
    Ok(reply)
}
