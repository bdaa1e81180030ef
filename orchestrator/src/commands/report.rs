//! `nlstudy report`: the study's one-page HTML report.

use super::failure::Failure;
use super::open::{open_store, read_study};
use crate::cli::args::CommonArgs;
use crate::console::Reply;
use crate::model::study::fields_telling_apart;

/// Needs no solver: a report of a results folder copied to a laptop is made from its tables.
pub(super) fn report(args: &CommonArgs) -> Result<Reply, Failure> {
    let study = read_study(&args.study)?;
    let store = open_store(args, &study, true)?;
    let points = study.expand()?;
    let swept = fields_telling_apart(&points);
    let page = crate::output::report::write(&study, &store, &swept)?;
    let mut reply = Reply::default();
    reply.line(format!("report: {}", page.display()));
    Ok(reply)
}
