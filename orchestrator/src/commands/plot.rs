//! `nlstudy plot`: the study's figures drawn from its summary table.

use super::failure::Failure;
use super::open::{open_store, print_figures_drawn, read_study};
use crate::cli::args::CommonArgs;
use std::process::ExitCode;

pub(super) fn plot(args: &CommonArgs) -> Result<ExitCode, Failure> {
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
    print_figures_drawn(&figures);
    crate::output::plot::all_drawn(&figures).map_err(Failure::CaseFailed)?;
    Ok(ExitCode::SUCCESS)
}
