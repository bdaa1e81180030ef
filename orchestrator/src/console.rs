//! The one reporter: everything `nlstudy` tells its user is printed here, and nowhere else.
//!
//! - A command returns a `Reply`, the value of what it has to say (its results for stdout, what
//!   it made and what it warns of for stderr); `commands::main` prints it with `print`.
//! - What a command or the layers below it have to say *while* they work (a warning, a note, a
//!   job submitted) goes through the `log` facade, never by printing: `log::warn!` prints as
//!   `nlstudy: warning: …`, `log::info!` as `nlstudy: …` (with `target: NOTE`, as it is), and
//!   `log::info!(target: OUT, …)` as a line of stdout.
//! - `--quiet` (`set_quiet`) drops the notes, here and in `run`'s progress (`run/progress.rs`,
//!   the bar on a terminal, lines elsewhere); results and warnings are printed still.
//!
//! Printing never panics. `println!` and `eprintln!` panic when their stream is closed or full,
//! which would end a study after its first case under `| head` or a `tee` that died. Here a
//! message to stderr that cannot be written is dropped and the work goes on; on stdout a closed
//! pipe ends the output quietly (as Unix tools do under `| head`), and any other failure (a full
//! disk) is kept for `nlstudy` to report with its exit status.

use std::fmt;
use std::io::{self, Write};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The first failure to write stdout other than a closed pipe.
static STDOUT_FAILURE: Mutex<Option<String>> = Mutex::new(None);

/// Writes to stdout; see the module's doc.
fn out(args: fmt::Arguments) {
    let written = io::stdout().lock().write_fmt(args);
    if let Err(e) = written {
        if e.kind() != io::ErrorKind::BrokenPipe {
            let mut failure = STDOUT_FAILURE.lock().unwrap_or_else(|p| p.into_inner());
            failure.get_or_insert_with(|| e.to_string());
        }
    }
}

/// Writes to stderr; a failure is dropped.
pub fn err(args: fmt::Arguments) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// The `log` target of a line for stdout, said while working (a job submitted, a round sent).
pub const OUT: &str = "nlstudy::out";

/// The `log` target of a note said as it is, without `nlstudy: ` (`interleaved: …`).
pub const NOTE: &str = "nlstudy::note";

/// Whether `--quiet` was given: notes are not printed.
static QUIET: AtomicBool = AtomicBool::new(false);

/// `--quiet`: from now on, notes are dropped (results and warnings are printed still).
pub fn set_quiet(quiet: bool) {
    QUIET.store(quiet, Ordering::Relaxed);
}

/// Whether notes are dropped (`--quiet`).
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// One thing a command says, by where it goes.
#[derive(Debug, Clone, PartialEq)]
pub enum Said {
    /// The command's result, a line of stdout (`plan`'s listing, `status`, a record).
    Result(String),
    /// What was made or done, a line of stderr (a table written, a figure drawn); not under
    /// `--quiet`.
    Note(String),
    /// What the user must hear even under `--quiet`, a line of stderr as `nlstudy: warning: …`.
    Warning(String),
    /// Why the command failed, a line of stderr as `nlstudy: …`, always.
    Failure(String),
}

/// What a command has to say once it is done, and how it ends: the value `commands::main`
/// prints (`print`) and exits with.
#[derive(Debug)]
pub struct Reply {
    pub said: Vec<Said>,
    pub code: ExitCode,
}

impl Default for Reply {
    fn default() -> Reply {
        Reply {
            said: Vec::new(),
            code: ExitCode::SUCCESS,
        }
    }
}

impl Reply {
    /// Text of the command's result (stdout), as given: its lines end as `text` does.
    pub fn result(&mut self, text: impl Into<String>) -> &mut Reply {
        self.said.push(Said::Result(text.into()));
        self
    }

    /// A line of the command's result (stdout).
    pub fn line(&mut self, line: impl Into<String>) -> &mut Reply {
        self.result(line.into() + "\n")
    }

    /// A line saying what was made or done (stderr, not under `--quiet`).
    pub fn note(&mut self, line: impl Into<String>) -> &mut Reply {
        self.said.push(Said::Note(line.into()));
        self
    }

    /// A warning (stderr, always).
    pub fn warn(&mut self, line: impl Into<String>) -> &mut Reply {
        self.said.push(Said::Warning(line.into()));
        self
    }

    /// The reply, ending with `code`.
    pub fn ending(mut self, code: ExitCode) -> Reply {
        self.code = code;
        self
    }

    /// The reply, ending in a failure: `why` said last (`nlstudy: …`), and `code`.
    pub fn failed(mut self, why: String, code: ExitCode) -> Reply {
        self.said.push(Said::Failure(why));
        self.ending(code)
    }
}

/// Prints `said`, each part where it goes (see `Said`).
pub fn print(said: &[Said]) {
    for part in said {
        say(part);
    }
}

/// Prints one thing said.
fn say(part: &Said) {
    match part {
        Said::Result(text) => out(format_args!("{text}")),
        Said::Note(_) if quiet() => {}
        Said::Note(line) => err(format_args!("{line}\n")),
        Said::Warning(line) => err(format_args!("nlstudy: warning: {line}\n")),
        Said::Failure(line) => err(format_args!("nlstudy: {line}\n")),
    }
}

/// Prints what is said through `log` while working (see the module's doc).
struct Reporter;

impl log::Log for Reporter {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record) {
        let text = record.args().to_string();
        match record.level() {
            log::Level::Error | log::Level::Warn => say(&Said::Warning(text)),
            log::Level::Info if record.target() == OUT => say(&Said::Result(text + "\n")),
            log::Level::Info if record.target() == NOTE => say(&Said::Note(text)),
            log::Level::Info => say(&Said::Note(format!("nlstudy: {text}"))),
            log::Level::Debug | log::Level::Trace => {}
        }
    }

    fn flush(&self) {}
}

/// Makes `Reporter` the one that prints what `log` is told (once per process; a second call,
/// as from tests, leaves the first in place).
pub fn report_through_log() {
    if log::set_logger(&Reporter).is_ok() {
        log::set_max_level(log::LevelFilter::Info);
    }
}

/// Why stdout could not be written, if it could not (a closed pipe is not a failure).
pub fn stdout_failure() -> Option<String> {
    let _ = io::stdout().flush();
    STDOUT_FAILURE
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .clone()
}

pub use schema::text::{number, numbers_alike};

/// `3 cases`, `1 case`: a count and its noun, plural where it is not one.
pub fn counted(n: usize, what: &str) -> String {
    match n {
        1 => format!("1 {what}"),
        _ => format!("{n} {what}s"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reply keeps what was said in the order it was said; a failure is said last and
    /// decides the exit status.
    #[test]
    fn a_reply_keeps_its_order_and_a_failure_ends_it() {
        let mut reply = Reply::default();
        reply.line("result").note("made").warn("careful");
        assert_eq!(reply.code, ExitCode::SUCCESS);
        let reply = reply.failed("stopped".into(), ExitCode::from(130));
        assert_eq!(
            reply.said,
            [
                Said::Result("result\n".into()),
                Said::Note("made".into()),
                Said::Warning("careful".into()),
                Said::Failure("stopped".into()),
            ]
        );
        assert_eq!(reply.code, ExitCode::from(130));
    }
}
