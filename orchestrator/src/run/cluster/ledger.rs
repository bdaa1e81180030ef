//! The jobs ledger of a study, `results/<study>/jobs/ledger/<id>.json`: one entry per job
//! `nlstudy submit` handed to the scheduler (its id, name and keys, and an array's elements).
//! `submit` leaves out the points of jobs the scheduler still holds; `status` shows each job's
//! state (each element's) and how many of its points are stored.
//!
//! A job is entered twice: as `submitting-<token>.json` before it is handed to the scheduler,
//! marked with the token, and under its id once the scheduler has given one. A submit killed in
//! between leaves the first, which the next look at the ledger settles by asking the scheduler
//! for the job of that mark: no job is submitted twice for want of its entry.

use super::scheduler::{self, Scheduler};
use crate::store::fs::{create_dir, read_regular, RECORD_CAP};
use crate::store::{write_atomically, FileError, Store};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LedgerEntry {
    pub scheduler: Scheduler,
    pub id: String,
    pub name: String,
    pub keys: Vec<String>,
    /// An array's elements: the keys of each, by index from 0 (none for a plain job).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub elements: Vec<Vec<String>>,
    /// Seconds since the Unix epoch.
    pub submitted: u64,
    /// A job that runs the whole study (`submit --whole`), every round of it: while it is held,
    /// every point of the study is.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub whole: bool,
}

impl LedgerEntry {
    /// What the scheduler tracks of this job, each with its keys: the job itself, or each
    /// element of an array (`42_3`, `42[4]`).
    pub fn parts(&self) -> Vec<(String, &[String])> {
        match self.elements.is_empty() {
            true => vec![(self.id.clone(), &self.keys[..])],
            false => self
                .elements
                .iter()
                .enumerate()
                .map(|(k, keys)| {
                    (
                        scheduler::element_id(self.scheduler, &self.id, k),
                        &keys[..],
                    )
                })
                .collect(),
        }
    }
}

fn ledger_dir(store: &Store) -> PathBuf {
    store.table("jobs").join("ledger")
}

/// The prefix of an entry written before its job was submitted: its id is the job's mark.
const SUBMITTING: &str = "submitting-";

/// Adds a submitted job to the ledger.
pub fn add(store: &Store, entry: &LedgerEntry) -> Result<(), FileError> {
    let dir = ledger_dir(store);
    create_dir(&dir)?;
    let path = dir.join(format!("{}.json", entry.id));
    let text = serde_json::to_string_pretty(entry).expect("an entry serializes");
    write_atomically(&path, text.as_bytes())
}

/// A mark for a job about to be submitted, unique to this process and moment.
pub fn token() -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    format!("nlstudy-{nanos}-{}", std::process::id())
}

/// Enters `entry` before its job is submitted, under its mark `token` (see the module).
pub fn intend(store: &Store, entry: &LedgerEntry, token: &str) -> Result<(), FileError> {
    add(
        store,
        &LedgerEntry {
            id: format!("{SUBMITTING}{token}"),
            ..entry.clone()
        },
    )
}

/// Enters `entry` under the id the scheduler gave its job, marked `token`, in place of its
/// entry of before (`intend`).
pub fn settle(store: &Store, entry: &LedgerEntry, token: &str) -> Result<(), FileError> {
    add(store, entry)?;
    forget(store, token)
}

/// Removes the entry `intend` wrote under `token`: its job was refused, or is not held. One
/// already gone is no error (another submit's look at the ledger may have settled it).
pub fn forget(store: &Store, token: &str) -> Result<(), FileError> {
    let intended = ledger_dir(store).join(format!("{SUBMITTING}{token}.json"));
    match std::fs::remove_file(&intended) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(FileError::on("remove", &intended)(e))
        }
        _ => Ok(()),
    }
}

/// Every job submitted for the study, oldest first; unreadable entries, and those of jobs not
/// yet submitted (`intend`), are skipped.
pub fn entries(store: &Store) -> Vec<LedgerEntry> {
    submitted(all_entries(store))
}

/// The entries of submitted jobs among `all`, oldest first.
fn submitted(all: Vec<LedgerEntry>) -> Vec<LedgerEntry> {
    let mut entries: Vec<LedgerEntry> = all
        .into_iter()
        .filter(|e| !e.id.starts_with(SUBMITTING))
        .collect();
    entries.sort_by_key(|e: &LedgerEntry| (e.submitted, e.id.parse::<u64>().unwrap_or(0)));
    entries
}

fn all_entries(store: &Store) -> Vec<LedgerEntry> {
    std::fs::read_dir(ledger_dir(store))
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .filter_map(|e| serde_json::from_str(&read_regular(&e.path(), RECORD_CAP).ok()?).ok())
        .collect()
}

/// The entries of submitted jobs, the ledger read once, after settling those of a submit
/// stopped between writing one and learning its job's id: the job of `scheduler` held with
/// that mark gets its entry; with none held (never submitted, or ended already, its records
/// then stored), the entry goes.
fn settled_entries(store: &Store, scheduler: Scheduler) -> Result<Vec<LedgerEntry>, String> {
    let mut all = all_entries(store);
    for entry in &mut all {
        let Some(token) = entry.id.strip_prefix(SUBMITTING).map(str::to_string) else {
            continue;
        };
        if entry.scheduler != scheduler {
            continue;
        }
        let settled = match scheduler::job_marked(scheduler, &token)? {
            Some(id) => {
                entry.id = id;
                settle(store, entry, &token)
            }
            None => forget(store, &token),
        };
        settled.map_err(|e| e.to_string())?;
    }
    Ok(submitted(all))
}

/// A job (or array element) of the ledger that the scheduler still holds.
pub struct Held {
    pub id: String,
    /// The scheduler's word for it: `PENDING`, `RUNNING`, `PEND`, `RUN`…
    pub state: String,
    pub keys: Vec<String>,
    /// A job of the whole study (see `LedgerEntry::whole`).
    pub whole: bool,
}

impl Held {
    /// Whether it waits for its allocation rather than runs (see `scheduler::phase`).
    pub fn pending(&self) -> bool {
        scheduler::phase(&self.state) == Some(scheduler::Phase::Waiting)
    }
}

/// The ledger's jobs of `scheduler` that it still holds, by one question to it; nothing held
/// (and no question) when the ledger is empty.
pub fn held(store: &Store, scheduler: Scheduler) -> Result<Vec<Held>, String> {
    let entries = settled_entries(store, scheduler)?;
    if entries.is_empty() {
        return Ok(Vec::new());
    }
    let live = scheduler::live_jobs(scheduler)?;
    Ok(entries
        .iter()
        .filter(|e| e.scheduler == scheduler)
        .flat_map(|e| e.parts().into_iter().map(|(id, keys)| (id, keys, e.whole)))
        .filter_map(|(id, keys, whole)| {
            Some(Held {
                state: live.get(&id)?.clone(),
                keys: keys.to_vec(),
                id,
                whole,
            })
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry written before its job is submitted is no job of the ledger until it is
    /// settled under the scheduler's id; forgotten, it leaves nothing.
    #[test]
    fn a_job_is_in_the_ledger_once_submitted_under_its_id() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path(), "s");
        let entry = |id: &str| LedgerEntry {
            scheduler: Scheduler::Slurm,
            id: id.into(),
            name: "nlstudy-s-0".into(),
            keys: vec!["ab".repeat(16)],
            elements: Vec::new(),
            submitted: 1_764_000_000,
            whole: false,
        };
        let ids =
            |store: &Store| -> Vec<String> { entries(store).into_iter().map(|e| e.id).collect() };
        intend(&store, &entry(""), "nlstudy-1-2").unwrap();
        assert!(ids(&store).is_empty());
        assert_eq!(all_entries(&store)[0].id, "submitting-nlstudy-1-2");
        settle(&store, &entry("42"), "nlstudy-1-2").unwrap();
        assert_eq!(ids(&store), ["42"]);
        assert_eq!(all_entries(&store).len(), 1);
        intend(&store, &entry(""), "nlstudy-1-3").unwrap();
        forget(&store, "nlstudy-1-3").unwrap();
        assert_eq!(all_entries(&store).len(), 1);
        forget(&store, "nlstudy-1-3").expect("gone already is no error");
    }
}
