//! Printing that never panics. `println!` and `eprintln!` panic when their stream is closed or
//! full, which would end a study after its first case under `| head` or a `tee` that died. Here
//! a message to stderr that cannot be written is dropped and the work goes on; on stdout a
//! closed pipe ends the output quietly (as Unix tools do under `| head`), and any other failure
//! (a full disk) is kept for `nlstudy` to report with its exit status.
//!
//! It is also the one reporter of what the layers below the commands have to say while they
//! work: they say it through the `log` facade (`log::warn!` for a warning, `log::info!` for a
//! note), never by printing, and `Reporter` prints it to stderr as `nlstudy: warning: …` or
//! `nlstudy: …`.

use std::fmt;
use std::io::{self, Write};
use std::sync::Mutex;

/// The first failure to write stdout other than a closed pipe.
static STDOUT_FAILURE: Mutex<Option<String>> = Mutex::new(None);

/// Writes to stdout; see the module's doc.
pub fn out(args: fmt::Arguments) {
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

/// Prints what the layers below the commands say through `log` (see the module's doc).
struct Reporter;

impl log::Log for Reporter {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Info
    }

    fn log(&self, record: &log::Record) {
        match record.level() {
            log::Level::Error | log::Level::Warn => {
                err(format_args!("nlstudy: warning: {}\n", record.args()))
            }
            log::Level::Info => err(format_args!("nlstudy: {}\n", record.args())),
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
