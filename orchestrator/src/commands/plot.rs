//! `nlstudy plot`: the study's figures drawn from its summary table.

use super::failure::Failure;
use super::open::{figures_drawn, open_store, read_study};
use crate::cli::args::CommonArgs;
use crate::console::Reply;

pub(super) fn plot(args: &CommonArgs) -> Result<Reply, Failure> {
    let study = read_study(&args.study)?;
    if study.figures.is_empty() {
        return Err(Failure::BadInput(format!(
            "study {} lists no figures; add a `figures` list to {}",
            study.name,
            args.study.display()
        )));
    }
    let store = open_store(args, &study, true)?;
    let figures = crate::output::plot::plot(&study.figures, study.question(), &store)?;
    let mut reply = Reply::default();
    figures_drawn(&mut reply, &figures);
    match crate::output::plot::all_drawn(&figures) {
        Ok(()) => Ok(reply),
        Err(why) => Ok(Failure::CaseFailed(why).after(reply)),
    }
}
