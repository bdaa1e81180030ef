//! Standard output that never loses a record silently (a closed or full descriptor is an error
//! with exit status 3), and standard error that never turns a finished run into a crash.

use crate::ErrorExit;
use std::io::Write;
use std::os::fd::AsFd;

/// Writes one line to standard error, ignoring a failure: a closed or full stderr must not turn
/// a finished run into a crash (`eprintln!` panics), and there is nowhere left to report it.
pub(crate) fn note(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Standard output as a file of its own (a duplicate of descriptor 1). `std::io::stdout`
/// reports a write to a closed descriptor as a success, so a record written there would be lost
/// with exit status 0; through this file every failure (EBADF, EPIPE, ENOSPC) is an error, and
/// so is a standard output that was closed when nlsolve started.
pub(crate) fn standard_output() -> std::io::Result<std::fs::File> {
    if standard_output_was_closed() {
        return Err(std::io::Error::other("it was closed when nlsolve started"));
    }
    let descriptor = std::io::stdout().as_fd().try_clone_to_owned()?;
    Ok(std::fs::File::from(descriptor))
}

/// Was standard output closed when nlsolve started (`nlsolve run … >&-`)? Rust's runtime opens
/// /dev/null in its place before `main` (so that no later file takes descriptor 1), after which a
/// closed descriptor and a /dev/null a caller chose (`>/dev/null`, Python's
/// `subprocess.DEVNULL`, opened for reading and writing) look alike. So the descriptor is looked
/// at before the runtime starts, by a function the loader runs first (`.init_array`).
pub(crate) fn standard_output_was_closed() -> bool {
    CLOSED_AT_START.load(std::sync::atomic::Ordering::Relaxed)
}

pub(crate) static CLOSED_AT_START: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);

/// Run by the loader before `main` and before Rust's runtime reopens a closed descriptor:
/// /proc/self/fd/1 names no file when descriptor 1 is closed. (Where /proc does not tell, every
/// descriptor counts as open.)
extern "C" fn note_a_closed_standard_output() {
    let closed = std::fs::symlink_metadata("/proc/self/fd")
        .is_ok_and(|_| std::fs::read_link("/proc/self/fd/1").is_err());
    CLOSED_AT_START.store(closed, std::sync::atomic::Ordering::Relaxed);
}

#[used]
#[link_section = ".init_array"]
static NOTE_A_CLOSED_STANDARD_OUTPUT: extern "C" fn() = note_a_closed_standard_output;

/// Writes `line` and a newline to standard output; `what` names it in the error (`the record`).
pub(crate) fn print_line(line: &str, what: &str) -> Result<(), ErrorExit> {
    let failed = |e: std::io::Error| {
        ErrorExit::Output(format!("cannot write {what} to standard output: {e}"))
    };
    let mut out = standard_output().map_err(failed)?;
    out.write_all(format!("{line}\n").as_bytes())
        .map_err(failed)
}
