//! The cluster schedulers, and the jobs ledger of a study, `results/<study>/jobs/ledger/<id>.json`: one entry per job
//! `nlstudy submit` handed to the scheduler (its id, name and keys), and what the scheduler says
//! of those jobs now (`squeue`, `bjobs`). `submit` leaves out the points of jobs still queued or
//! running; `status` shows each job's state and how many of its points are stored.

use crate::store::{write_atomically, Store};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Command;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheduler {
    Slurm,
    Lsf,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LedgerEntry {
    pub scheduler: Scheduler,
    pub id: String,
    pub name: String,
    pub keys: Vec<String>,
    /// Seconds since the Unix epoch.
    pub submitted: u64,
}

fn ledger_dir(store: &Store) -> PathBuf {
    store.table("jobs").join("ledger")
}

/// Records a submitted job.
pub fn record(store: &Store, entry: &LedgerEntry) -> Result<(), String> {
    let dir = ledger_dir(store);
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let path = dir.join(format!("{}.json", entry.id));
    let text = serde_json::to_string_pretty(entry).expect("an entry serializes");
    write_atomically(&path, text.as_bytes())
        .map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Every job submitted for the study, oldest first; unreadable entries are skipped.
pub fn entries(store: &Store) -> Vec<LedgerEntry> {
    let mut entries: Vec<LedgerEntry> = std::fs::read_dir(ledger_dir(store))
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .filter_map(|e| serde_json::from_str(&std::fs::read_to_string(e.path()).ok()?).ok())
        .collect();
    entries.sort_by_key(|e: &LedgerEntry| (e.submitted, e.id.parse::<u64>().unwrap_or(0)));
    entries
}

/// The scheduler's state of each job it still holds (queued, running, completing…), by id.
pub fn live_jobs(scheduler: Scheduler) -> Result<HashMap<String, String>, String> {
    let (program, args): (&str, &[&str]) = match scheduler {
        Scheduler::Slurm => ("squeue", &["-h", "-o", "%i %T"]),
        Scheduler::Lsf => ("bjobs", &["-noheader", "-o", "jobid stat"]),
    };
    let output = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| format!("cannot run {program}: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "{program} failed: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    Ok(String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            Some((words.next()?.to_string(), words.next()?.to_string()))
        })
        // LSF keeps finished jobs listed for a while.
        .filter(|(_, state)| !matches!(state.as_str(), "DONE" | "EXIT"))
        .collect())
}

/// The job id in what the scheduler printed on submission: `Submitted batch job 42` (sbatch),
/// `Job <42> is submitted to queue <normal>.` (bsub).
pub fn submitted_id(scheduler: Scheduler, printed: &str) -> Option<String> {
    let id = match scheduler {
        Scheduler::Slurm => printed
            .lines()
            .find_map(|l| l.strip_prefix("Submitted batch job "))?
            .trim(),
        Scheduler::Lsf => printed.split_once('<')?.1.split_once('>')?.0,
    };
    (!id.is_empty() && id.chars().all(|c| c.is_ascii_digit())).then(|| id.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_ids_are_read_from_what_either_scheduler_prints() {
        assert_eq!(
            submitted_id(Scheduler::Slurm, "Submitted batch job 42\n").as_deref(),
            Some("42")
        );
        assert_eq!(
            submitted_id(Scheduler::Lsf, "Job <7> is submitted to queue <normal>.\n").as_deref(),
            Some("7")
        );
        assert_eq!(submitted_id(Scheduler::Slurm, "sbatch: error: …"), None);
    }
}
