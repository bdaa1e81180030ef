//! `nlstudy status`: the stored records counted by status, the failures and the jobs.

use super::failure::Failure;
use super::open::planned_and_index;
use crate::cli::args::CommonArgs;
use crate::console::Reply;
use crate::output::status;
use crate::run::plan::Options;

pub(super) fn status(args: &CommonArgs) -> Result<Reply, Failure> {
    let (study, solver, store, index, planned) =
        planned_and_index(args, &Options::default(), false)?;
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
