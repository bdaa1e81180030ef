//! The jobs ledger of a study, `results/<study>/jobs/ledger/<id>.json`: one entry per job
//! `nlstudy submit` handed to the scheduler (its id, name and keys, and an array's elements).
//! `submit` leaves out the points of jobs the scheduler still holds; `status` shows each job's
//! state (each element's) and how many of its points are stored.

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

/// Adds a submitted job to the ledger.
pub fn add(store: &Store, entry: &LedgerEntry) -> Result<(), FileError> {
    let dir = ledger_dir(store);
    create_dir(&dir)?;
    let path = dir.join(format!("{}.json", entry.id));
    let text = serde_json::to_string_pretty(entry).expect("an entry serializes");
    write_atomically(&path, text.as_bytes())
}

/// Every job submitted for the study, oldest first; unreadable entries are skipped.
pub fn entries(store: &Store) -> Vec<LedgerEntry> {
    let mut entries: Vec<LedgerEntry> = std::fs::read_dir(ledger_dir(store))
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .filter_map(|e| serde_json::from_str(&read_regular(&e.path(), RECORD_CAP).ok()?).ok())
        .collect();
    entries.sort_by_key(|e: &LedgerEntry| (e.submitted, e.id.parse::<u64>().unwrap_or(0)));
    entries
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
    let entries = entries(store);
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
