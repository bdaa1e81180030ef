//! `nlstudy history`: a metric of each point under every build that ran it, by date.

use super::builds::{repeats_by_point, superseded};
use super::failure::Failure;
use super::open::planned;
use crate::cli::args::HistoryArgs;
use crate::console::Reply;
use crate::run::plan::Options;

pub(super) fn history(args: &HistoryArgs) -> Result<Reply, Failure> {
    let (study, _, store, planned) = planned(&args.common, &Options::default(), true)?;
    let mut records = store.records();
    records.extend(superseded(&store));
    let chart = crate::output::history::chart(
        &study.name,
        &args.metric,
        &repeats_by_point(&planned),
        &records,
    )
    .map_err(Failure::BadInput)?;
    let path = store.table("history.svg");
    let svg = crate::output::draw::render(&chart).map_err(Failure::CaseFailed)?;
    crate::store::write_atomically(&path, svg.as_bytes())?;
    let mut reply = Reply::default();
    reply.line(format!("history: {}", path.display()));
    Ok(reply)
}
