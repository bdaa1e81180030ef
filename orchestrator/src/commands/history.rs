//! `nlstudy history`: a metric of each point under every build that ran it, by date.

use super::builds::{repeats_by_point, superseded};
use super::failure::Failure;
use super::open::planned;
use crate::cli::args::HistoryArgs;
use crate::run::plan::Options;
use schema::exit;
use std::process::ExitCode;

pub(super) fn history(args: &HistoryArgs) -> Result<ExitCode, Failure> {
    let (study, _, store, planned) = planned(&args.common, &Options::default(), true)?;
    let mut records = store.records();
    records.extend(superseded(&store));
    let chart = crate::output::history::chart(
        &study.name,
        &args.metric,
        &repeats_by_point(&planned),
        &records,
    )?;
    let path = store.table("history.svg");
    let svg = crate::output::draw::render(&chart).map_err(|message| Failure {
        message,
        code: exit::CASE_FAILED,
    })?;
    crate::store::write_atomically(&path, svg.as_bytes())?;
    outln!("history: {}", path.display());
    Ok(ExitCode::SUCCESS)
}
