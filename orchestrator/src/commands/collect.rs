//! `nlstudy collect`: the stored records gathered into the study's run and summary tables.

use super::failure::Failure;
use super::open::{planned, tables_written};
use crate::analysis::collect::ToCollect;
use crate::cli::args::CollectArgs;
use crate::console::Reply;
use crate::run::plan::Options;

pub(super) fn collect(args: &CollectArgs) -> Result<Reply, Failure> {
    let allow_mixed = args.allow_mixed;
    let args = &args.common;
    let (study, _, store, planned) = planned(args, &Options::default(), true)?;
    // (The plan let go before the records are read: the tables need little of it.)
    let to_collect = ToCollect::from_planned(&planned);
    drop(planned);
    let collected = crate::analysis::collect::collect(to_collect, &store, &study, allow_mixed)?
        .ok_or_else(|| {
            Failure::BadInput(format!(
                "nothing to collect: no run of study {} is stored yet; `nlstudy run` it first",
                store.study
            ))
        })?;
    let mut reply = Reply::default();
    tables_written(&mut reply, &collected);
    reply.result(collected.overview);
    Ok(reply)
}
