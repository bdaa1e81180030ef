//! Each `nlstudy` command, one module each, given its parsed flags (`cli::args`); what they
//! share in opening a study is in `open`. A command returns its exit status, or a `Failure`
//! whose kind decides it (the table is `schema::exit`, shared with `nlsolve`).

mod builds;
mod clean;
mod collect;
mod compare;
mod failure;
#[cfg(test)]
mod fuzz;
mod history;
mod interleaved;
mod open;
mod plan;
mod plot;
mod report;
mod run;
mod show;
mod status;
mod submit;
mod table;
mod verdicts;

use crate::cli::args::{Cli, Command};
use schema::exit;
use std::process::ExitCode;

pub use failure::Failure;

/// Runs one `nlstudy` command and says how it ended.
pub fn main(cli: Cli) -> ExitCode {
    crate::console::report_through_log();
    let code = match execute(cli) {
        Ok(code) => code,
        Err(failure) => {
            errln!("nlstudy: {failure}");
            ExitCode::from(failure.code())
        }
    };
    match crate::console::stdout_failure() {
        Some(why) => {
            errln!("nlstudy: cannot write to standard output: {why}");
            ExitCode::from(exit::IO)
        }
        None => code,
    }
}

/// Runs one `nlstudy` command.
pub fn execute(cli: Cli) -> Result<ExitCode, Failure> {
    match cli.command {
        Command::Plan(args) => plan::plan(&args),
        Command::Run(args) => run::run(&args),
        Command::Collect(args) => collect::collect(&args),
        Command::Plot(args) => plot::plot(&args),
        Command::Status(args) => status::status(&args),
        Command::Report(args) => report::report(&args),
        Command::Table(args) => table::table(&args),
        Command::Submit(args) => submit::submit(&args),
        Command::Clean(args) => clean::clean(&args),
        Command::Compare(args) => compare::compare(&args),
        Command::Show(args) => show::show(&args),
        Command::History(args) => history::history(&args),
    }
}
