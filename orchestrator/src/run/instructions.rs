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
    let counts = scratch.join("cachegrind.out");
    let _ = std::fs::remove_file(&counts);
    create_fresh(&case_file)
        .and_then(|mut f| std::io::Write::write_all(&mut f, case.canonical_text().as_bytes()))
        .map_err(|e| format!("cannot write {}: {e}", case_file.display()))?;
    let out = Command::new(VALGRIND)
        .arg("--tool=cachegrind")
        .arg("--cache-sim=no")
        // Into the solver a wrapper script `exec`s (a module load, an environment): its count is
        // the one written last, at the solver's exit.
        .arg("--trace-children=yes")
        .arg(format!("--cachegrind-out-file={}", counts.display()))
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
    let written =
        read_regular(&counts, RECORD_CAP).map_err(|e| format!("{}: {e}", counts.display()))?;
    let instructions = total(&written)
        .ok_or_else(|| format!("{} holds no instruction count", counts.display()))?;
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
}
