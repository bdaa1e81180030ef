//! The instructions a case's run executes, counted by Valgrind's cachegrind (`valgrind
//! --tool=cachegrind --cache-sim=no`, its total of instructions read, `Ir`): a count no other
//! task on the machine can disturb, unlike a time, at the price of a run 20–50× slower. The
//! kernel's hardware counters (`perf_event_open`) would be cheaper, where the kernel lets a user
//! read them; the machines this tool is developed on do not (ENOENT), so the count here is
//! Valgrind's, and the record says so (`instructions_by`). One thread: the spinning of several
//! threads waiting on each other depends on timing, and so would the count.

use crate::run::nlsolve::Nlsolve;
use crate::run::plan::Planned;
use crate::store::fs::{create_fresh, read_regular, RECORD_CAP};
use schema::record::{Outcome, Record, Stored};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Stdio};

/// What the record of a counted run says counted it.
pub const BY: &str = "cachegrind";

/// The program that counts.
const VALGRIND: &str = "valgrind";

/// Runs `planned`'s case under cachegrind with `solver`, its files in `scratch` (a directory of
/// its own); returns its record with the count, ready to store, or why there is none.
pub fn count(planned: &Planned, solver: &Nlsolve, scratch: &Path) -> Result<Stored, String> {
    let case = planned.case.as_ref().map_err(Clone::clone)?;
    let case_file = scratch.join("case.json");
    // One file per process (`%p`): a wrapper's own instructions are never taken for the solver's.
    crate::store::fs::remove_where(scratch, |name| name.starts_with(COUNTS));
    create_fresh(&case_file)
        .and_then(|mut f| std::io::Write::write_all(&mut f, case.canonical_text().as_bytes()))
        .map_err(|e| format!("cannot write {}: {e}", case_file.display()))?;
    let out = Command::new(VALGRIND)
        .arg("--tool=cachegrind")
        .arg("--cache-sim=no")
        // Into the solver a wrapper script starts (a module load, an environment): each process
        // writes its own count, and the solver's is picked out by its command line.
        .arg("--trace-children=yes")
        .arg(format!("--cachegrind-out-file={}/{COUNTS}.%p", scratch.display()))
        .arg(&solver.binary)
        .args(["run", "--case"])
        .arg(&case_file)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => format!(
                "{VALGRIND} is not installed: instruction counts need it (Debian's package valgrind)"
            ),
            _ => format!("cannot start {VALGRIND}: {e}"),
        })?;
    if !out.status.success() {
        let said = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = said.lines().rev().take(5).collect();
        return Err(format!(
            "nlsolve under {VALGRIND} exited with {}: {}",
            out.status,
            schema::text::printable(&tail.into_iter().rev().collect::<Vec<_>>().join("\n"))
        ));
    }
    let instructions = solvers_count(scratch, &case_file)?;
    let printed = String::from_utf8_lossy(&out.stdout);
    let line = printed
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .ok_or("nlsolve printed no record")?;
    let mut record: Record<Value> = serde_json::from_str(line)
        .map_err(|e| format!("nlsolve printed a record that does not keep to the schema: {e}"))?;
    record.instructions = Some(instructions);
    record.instructions_by = Some(BY.into());
    Ok(Stored {
        key: planned.key.to_string(),
        case_id: Some(planned.case_id.to_string()),
        repeat: planned.point.repeat,
        solver_version: solver.version.clone(),
        run_id: None,
        attempt: None,
        outcome: Outcome::Ran(Box::new(record)),
    })
}

/// The name each counted process's file starts with (`<COUNTS>.<pid>`).
const COUNTS: &str = "cachegrind.out";

/// The instructions of the one process that ran the case as the solver does, `… run --case
/// <case_file>` (a wrapper's command line names its script first), among the files cachegrind
/// wrote in `scratch`. A wrapper that is a process of its own is so left out of the count; none
/// or several such processes is an error, rather than a count of something else.
fn solvers_count(scratch: &Path, case_file: &Path) -> Result<u64, String> {
    let ran_the_case = |command: &str| {
        let words: Vec<&str> = command.split_whitespace().collect();
        words.get(1..4) == Some(&["run", "--case", &case_file.to_string_lossy()][..])
    };
    let mut found = Vec::new();
    let mut processes = 0;
    let listed = std::fs::read_dir(scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    for entry in listed.flatten() {
        if !entry.file_name().to_string_lossy().starts_with(COUNTS) {
            continue;
        }
        let path = entry.path();
        processes += 1;
        let written =
            read_regular(&path, RECORD_CAP).map_err(|e| format!("{}: {e}", path.display()))?;
        let command = written
            .lines()
            .find_map(|l| l.strip_prefix("cmd:"))
            .unwrap_or("");
        if ran_the_case(command) {
            let count = total(&written)
                .ok_or_else(|| format!("{} holds no instruction count", path.display()))?;
            found.push(count);
        }
    }
    match found[..] {
        [count] => Ok(count),
        _ => Err(format!(
            "of the {processes} processes counted, {} ran the case as nlsolve does (`nlsolve run --case FILE`): give --solver the nlsolve binary itself, or a wrapper that execs it as that, to count its instructions",
            found.len()
        )),
    }
}

/// The count of instructions read in cachegrind's output: its `summary:` line (with
/// `--cache-sim=no` the one event, `Ir`).
fn total(output: &str) -> Option<u64> {
    let line = output.lines().find(|l| l.starts_with("summary:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_count_is_cachegrinds_summary() {
        let output =
            "desc: I1 cache: none\ncmd: nlsolve run\nevents: Ir\nfl=x\n1 5\nsummary: 123456789\n";
        assert_eq!(total(output), Some(123_456_789));
        assert_eq!(total("events: Ir\n"), None);
        assert_eq!(total("summary: many\n"), None);
    }

    /// A wrapper of its own process is counted apart and left out; the solver's count is taken.
    #[test]
    fn the_solvers_process_is_counted_not_its_wrappers() {
        let scratch = tempfile::tempdir().unwrap();
        let case = scratch.path().join("case.json");
        let write = |pid: u32, command: String, count: u64| {
            let text = format!("cmd: {command}\nevents: Ir\nsummary: {count}\n");
            std::fs::write(scratch.path().join(format!("{COUNTS}.{pid}")), text).unwrap();
        };
        let case_text = case.display().to_string();
        write(
            7,
            format!("/usr/bin/python3 /x/wrapper.py run --case {case_text}"),
            900,
        );
        let none = solvers_count(scratch.path(), &case).unwrap_err();
        assert!(
            none.contains("of the 1 processes counted, 0 ran the case"),
            "{none}"
        );
        write(8, format!("/x/nlsolve run --case {case_text}"), 500);
        assert_eq!(solvers_count(scratch.path(), &case), Ok(500));
        write(9, format!("/y/nlsolve run --case {case_text}"), 510);
        assert!(
            solvers_count(scratch.path(), &case).is_err(),
            "two solvers: which?"
        );
    }
}
