//! The exit statuses of both binaries, as one table: `nlstudy` and `nlsolve` exit with these
//! codes, `nlstudy` reads `nlsolve`'s by them, and the README's table is `markdown()` (a test
//! holds them equal).
//!
//! A failed write is 3 for both. `nlsolve` used sysexits' EX_IOERR (74), the one sysexits code
//! in a table whose bad input is 2 (not EX_USAGE's 64): a script driving both had two codes for
//! one kind of failure.

/// The command did what it was asked: every case ran and is stored `ok` or `diverged` (a
/// divergence is a result), or `nlsolve` wrote its record.
pub const OK: u8 = 0;
/// A case failed (its record is stored `failed`), a table or figure could not be made of the
/// runs, or `compare` found something worse; for `nlsolve`, MPI could not start.
pub const CASE_FAILED: u8 = 1;
/// A bad study file, case, flag or value: nothing ran.
pub const BAD_INPUT: u8 = 2;
/// A file could not be read or written (a full disk, a closed standard output, a path that is
/// not a directory, a table whose bytes changed), or a program could not be started: nothing is
/// stored for what was running, and the next run takes it up again.
pub const IO: u8 = 3;
/// Stopped by Ctrl-C (SIGINT): what finished is stored. SIGTERM exits 143 and SIGHUP 129, 128 +
/// the signal as the shell's.
pub const INTERRUPTED: u8 = 130;

/// One row of the table: the code, and what it means for each binary.
pub struct Status {
    pub code: &'static str,
    pub nlstudy: &'static str,
    pub nlsolve: &'static str,
}

/// Every exit status, lowest first.
pub const TABLE: [Status; 5] = [
    Status {
        code: "0",
        nlstudy: "nothing failed: every case stored `ok` or `diverged` (a divergence is a result)",
        nlsolve: "the record (the report, the verdicts) was written",
    },
    Status {
        code: "1",
        nlstudy: "a case failed (stored `failed`), a table or figure could not be made of the runs, or `compare` found a metric `worse` beyond its noise floor",
        nlsolve: "MPI could not start",
    },
    Status {
        code: "2",
        nlstudy: "a bad study file, flag or value (one sentence naming the field): nothing ran",
        nlsolve: "a bad case or flag (one line on stderr naming the field): nothing ran",
    },
    Status {
        code: "3",
        nlstudy: "the results could not be read or written, or a program (the solver, `sbatch`, `bsub`) could not be started or refused the work: nothing is stored for the cases that were running",
        nlsolve: "the record, the verdicts or a `--write-*` file could not be written (standard output closed or full, a broken pipe, a path that cannot be written)",
    },
    Status {
        code: "130, 143, 129",
        nlstudy: "stopped by Ctrl-C, SIGTERM (a scheduler's warning, `scancel`, a preemption) or SIGHUP: what finished is stored, and the next `run` resumes",
        nlsolve: "stopped by the signal; with `--checkpoint`, in the time loop, once its checkpoint is written (no record)",
    },
];

/// The table as Markdown, as the README prints it.
pub fn markdown() -> String {
    let mut out = String::from("| exit status | `nlstudy` | `nlsolve` |\n|---|---|---|\n");
    for row in &TABLE {
        out += &format!("| {} | {} | {} |\n", row.code, row.nlstudy, row.nlsolve);
    }
    out
}

/// `nlsolve`'s column as plain lines, as `nlsolve --help` prints it.
pub fn nlsolve_help() -> String {
    let mut out = String::from("Exit status:\n");
    for row in &TABLE {
        out += &format!("  {:<14} {}\n", row.code, row.nlsolve);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_codes_and_the_table_agree() {
        let codes: Vec<&str> = TABLE.iter().map(|r| r.code).collect();
        for code in [OK, CASE_FAILED, BAD_INPUT, IO, INTERRUPTED] {
            assert!(
                codes
                    .iter()
                    .any(|c| c.split(", ").next() == Some(&code.to_string())),
                "{code} has no row"
            );
        }
    }
}
