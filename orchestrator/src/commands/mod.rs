//! Each `nlstudy` command, one module each, given its parsed flags (`cli::args`); what they
//! share in opening a study is in `open`. A command prints nothing: it returns a
//! `console::Reply` (what it has to say and its exit status), or a `Failure` whose kind decides
//! the status (the table is `schema::exit`, shared with `nlsolve`), and `main` prints either
//! through the one reporter, `console`.

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
use crate::console::{self, Reply};
use std::process::ExitCode;

pub use failure::Failure;

/// Runs one `nlstudy` command and says how it ended.
pub fn main(cli: Cli) -> ExitCode {
    console::report_through_log();
    console::set_quiet(cli.quiet);
    let reply = execute(cli).unwrap_or_else(|failure| failure.after(Reply::default()));
    console::print(&reply.said);
    match console::stdout_failure() {
        Some(why) => {
            let why = Failure::Io(format!("cannot write to standard output: {why}"));
            let reply = why.after(Reply::default());
            console::print(&reply.said);
            reply.code
        }
        None => reply.code,
    }
}

/// Runs one `nlstudy` command.
pub fn execute(cli: Cli) -> Result<Reply, Failure> {
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
