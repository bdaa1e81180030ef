//! The record store of a study, `results/<study>/runs/<key>.json`: one file per run, written
//! through a temporary file and a rename, so that a file is either whole or absent.
//!
//! Several `nlstudy` processes may share a store (two terminals, a workstation and a cluster
//! job): a point runs only under its key's lock (`runs/.work/<key>.lock`, an advisory file lock
//! the kernel drops when its holder exits, however it exits), a `failed` record never replaces a
//! result, and a file that is not a whole record is reported and treated as absent, never trusted.

use schema::record::Status;
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

pub mod fs;
pub mod owner;
pub mod table;

use fs::{create_dir, lock_file, remove_where};
pub use fs::{write_atomically, FileError};

pub struct Store {
    pub study: String,
    pub runs: PathBuf,
}

/// The first 16 bytes of SHA-256, in hex.
fn digest(text: &str) -> String {
    hex(&Sha256::digest(text.as_bytes())[..16])
}

pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The identity of a case whatever the solver version: the hash of its canonical JSON.
pub fn case_id(case: &Value) -> String {
    digest(&case.to_string())
}

/// The key of one run: the case, the solver version and, beyond the first, the repeat.
pub fn key(case: &Value, solver_version: &str, repeat: usize) -> String {
    let mut text = format!("{case}\n{solver_version}");
    if repeat > 0 {
        text.push_str(&format!("\nrepeat {repeat}"));
    }
    digest(&text)
}

impl Store {
    pub fn open(results: &Path, study: &str) -> Store {
        Store {
            study: study.to_string(),
            runs: results.join(study).join("runs"),
        }
    }

    /// A table of the study, beside its runs: `results/<study>/<name>`.
    pub fn table(&self, name: &str) -> PathBuf {
        self.runs.with_file_name(name)
    }

    pub fn path(&self, key: &str) -> PathBuf {
        self.runs.join(format!("{key}.json"))
    }

    /// Where a run whose case sets `vtk_every` writes its VTK frames: `results/<study>/fields/<key>/`.
    pub fn fields(&self, key: &str) -> PathBuf {
        self.table("fields").join(key)
    }

    /// Scratch space of runs in progress (case files, captured output).
    pub fn work_dir(&self) -> PathBuf {
        self.runs.join(".work")
    }

    /// Stores `record` as the record of `key`, unless it is `failed` and the stored one is a
    /// result (`ok`, `diverged`): a run's fault does not erase what an earlier run computed.
    /// Returns whether it was stored. Call it holding the key's lock.
    /// A record made by another solver (another fingerprint) is not overwritten: it moves to
    /// the study's history first (`history/<key>.<fingerprint>.json`), so nothing computed is
    /// lost and old and new can be compared.
    pub fn save(&self, key: &str, record: &Value) -> Result<bool, FileError> {
        let failed = Status::of(record).is_none_or(|s| s == Status::Failed);
        let stored = self.stored(key);
        let result_stored = stored
            .as_ref()
            .and_then(Status::of)
            .is_some_and(|s| s != Status::Failed);
        if failed && result_stored {
            return Ok(false);
        }
        if let Some(stored) = stored {
            let old = fingerprint_of(&stored);
            if old != fingerprint_of(record) {
                let history = self.table("history");
                create_dir(&history)?;
                let name = format!(
                    "{key}.{}.json",
                    if old.is_empty() { "unknown" } else { old }
                );
                std::fs::rename(self.path(key), history.join(&name))
                    .map_err(FileError::on("move to history", &self.path(key)))?;
            }
        }
        create_dir(&self.runs)?;
        write_atomically(&self.path(key), format!("{record}\n").as_bytes())?;
        Ok(true)
    }

    /// Removes the lock file of `key` once its point holds a result: taken by the holder of the
    /// lock, so a process that opened the file before sees the result when it gets the lock,
    /// and one that comes later makes a new file and sees it too. The lock of a failed point
    /// stays, so two reruns of it never hold different files.
    pub fn release_lock_file(&self, key: &str) {
        if self.status(key).is_some_and(|s| s != Status::Failed) {
            let _ = std::fs::remove_file(self.work_dir().join(format!("{key}.lock")));
        }
    }

    /// The status of the stored record of `key`, read now; `None` when absent or not whole.
    pub fn status(&self, key: &str) -> Option<Status> {
        Status::of(&self.stored(key)?)
    }

    /// The stored record of `key`, read now, if whole.
    pub fn stored(&self, key: &str) -> Option<Value> {
        let path = self.path(key);
        read_record(&path, &std::fs::read_to_string(&path).ok()?).ok()
    }

    /// Takes the lock of `key` for this process: `None` when another process holds it (that
    /// process is running the point). Taking it clears what an earlier holder killed midway
    /// left behind: its scratch files and its partly written record.
    pub fn lock(&self, key: &str) -> Result<Option<File>, FileError> {
        let work = self.work_dir();
        let name = format!("{key}.lock");
        let file = lock_file(&work, &name)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => return Ok(None),
            Err(TryLockError::Error(e)) => return Err(FileError::new("lock", &work.join(name), e)),
        }
        let scratch = format!("{key}.");
        remove_where(&work, |n| n.starts_with(&scratch) && !n.ends_with(".lock"));
        let partial = format!(".{key}.json.");
        remove_where(&self.runs, |n| n.starts_with(&partial));
        Ok(Some(file))
    }

    /// Takes the lock of the study's tables and figures, waiting while another process writes
    /// them, and clears the partial files a writer killed midway left behind.
    pub fn lock_outputs(&self) -> Result<File, FileError> {
        let file = lock_file(&self.study_dir(), ".outputs.lock")?;
        file.lock().map_err(FileError::on(
            "lock",
            &self.study_dir().join(".outputs.lock"),
        ))?;
        self.clear_output_partials();
        Ok(file)
    }

    /// Clears the partial tables and figures a writer killed midway left behind, when no
    /// process writes the outputs now (a run that does not collect still leaves a whole store).
    pub fn clear_abandoned_outputs(&self) -> Result<(), FileError> {
        let file = lock_file(&self.study_dir(), ".outputs.lock")?;
        match file.try_lock() {
            Ok(()) => self.clear_output_partials(),
            Err(TryLockError::WouldBlock) => {}
            Err(TryLockError::Error(e)) => {
                return Err(FileError::new(
                    "lock",
                    &self.study_dir().join(".outputs.lock"),
                    e,
                ))
            }
        }
        Ok(())
    }

    fn study_dir(&self) -> PathBuf {
        self.runs.parent().unwrap_or(Path::new(".")).to_path_buf()
    }

    fn clear_output_partials(&self) {
        let partial = |n: &str| n.starts_with('.') && n.ends_with(".partial");
        remove_where(&self.study_dir(), partial);
        remove_where(&self.table("figures"), partial);
    }

    /// Every stored record, and the files of the store that are not whole records.
    pub fn scan(&self) -> Scan {
        let mut scan = Scan::default();
        let Ok(entries) = std::fs::read_dir(&self.runs) else {
            return scan;
        };
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                !p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            })
            .collect();
        paths.sort();
        for path in paths {
            let read = std::fs::read_to_string(&path).map_err(|e| e.to_string());
            match read.and_then(|text| read_record(&path, &text)) {
                Ok(record) => scan.records.push(record),
                Err(problem) => scan.unreadable.push(Unreadable { path, problem }),
            }
        }
        scan
    }

    /// Every stored record.
    pub fn records(&self) -> Vec<Value> {
        self.scan().records
    }

    /// The superseded records in `history/` (`<key>.<fingerprint>.json`, see `save`): whole
    /// JSON objects with a key and a known status; anything else is left out.
    pub fn history(&self) -> Vec<Value> {
        let Ok(entries) = std::fs::read_dir(self.table("history")) else {
            return Vec::new();
        };
        let mut paths: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
        paths.sort();
        paths
            .iter()
            .filter_map(|path| {
                serde_json::from_str::<Value>(&std::fs::read_to_string(path).ok()?).ok()
            })
            .filter(|record| {
                record.get("key").is_some_and(Value::is_string) && Status::of(record).is_some()
            })
            .collect()
    }

    /// What the stored records say, read once: the status of each key and the solver version
    /// each case id was run with. An unreadable file counts as absent (its point runs again).
    pub fn index(&self) -> Index {
        let scan = self.scan();
        let mut index = Index {
            unreadable: scan.unreadable,
            ..Index::default()
        };
        for record in scan.records {
            let text = |field: &str| record.get(field)?.as_str().map(str::to_string);
            if let (Some(key), Some(status)) = (text("key"), Status::of(&record)) {
                index.status.insert(key, status);
            }
            if let (Some(id), Some(version)) = (text("case_id"), text("solver_version")) {
                index.version_by_case.insert(id, version);
            }
            if let Some(key) = text("key") {
                index
                    .fingerprint
                    .insert(key, fingerprint_of(&record).to_string());
            }
        }
        index
    }
}

/// Records by their key (a record without one is left out).
pub fn by_key(records: Vec<Value>) -> HashMap<String, Value> {
    records
        .into_iter()
        .filter_map(|r| Some((r.get("key")?.as_str()?.to_string(), r)))
        .collect()
}

/// A text field of `record`'s provenance (`host`, `timestamp`, …; "" when it does not say).
pub fn provenance<'a>(record: &'a Value, field: &str) -> &'a str {
    record
        .get("provenance")
        .and_then(|p| p.get(field))
        .and_then(Value::as_str)
        .unwrap_or("")
}

/// The fingerprint of the solver that made `record` ("" when it does not say).
pub fn fingerprint_of(record: &Value) -> &str {
    provenance(record, "fingerprint")
}

/// `text`, read from `path`, as a record: a JSON object whose `key` is the file's name and
/// whose `status` is one the schema knows. Anything else is named in the error.
fn read_record(path: &Path, text: &str) -> Result<Value, String> {
    if path.extension().is_none_or(|x| x != "json") {
        return Err("not a record (records are <key>.json)".into());
    }
    let record: Value = serde_json::from_str(text).map_err(|e| format!("not whole JSON ({e})"))?;
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    if record.get("key").and_then(Value::as_str) != stem.as_deref() {
        return Err("its `key` is not its file name".into());
    }
    if Status::of(&record).is_none() {
        return Err("it has no known `status`".into());
    }
    Ok(record)
}

/// A file of the store that is not a whole record: truncated, garbage, or not a record at all.
#[derive(Clone, Debug)]
pub struct Unreadable {
    pub path: PathBuf,
    pub problem: String,
}

impl std::fmt::Display for Unreadable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} is not a whole record ({}); its point counts as not run",
            self.path.display(),
            self.problem
        )
    }
}

#[derive(Default)]
pub struct Scan {
    pub records: Vec<Value>,
    pub unreadable: Vec<Unreadable>,
}

#[derive(Default)]
pub struct Index {
    pub status: HashMap<String, Status>,
    /// The fingerprint of the solver that made each key's record ("" when it does not say).
    pub fingerprint: HashMap<String, String>,
    pub version_by_case: HashMap<String, String>,
    pub unreadable: Vec<Unreadable>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn scratch(name: &str) -> Store {
        let dir = std::env::temp_dir().join(format!("store-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        Store::open(&dir, "s")
    }

    #[test]
    fn a_failed_record_never_replaces_a_result_but_a_result_replaces_a_failure() {
        let store = scratch("replace");
        let record = |status: &str| json!({"key": "k", "status": status, "message": status});
        assert!(store.save("k", &record("failed")).unwrap());
        assert!(store.save("k", &record("ok")).unwrap());
        assert!(!store.save("k", &record("failed")).unwrap());
        assert_eq!(store.status("k"), Some(Status::Ok));
        assert!(
            store.save("k", &record("diverged")).unwrap(),
            "a result replaces a result"
        );
        let _ = std::fs::remove_dir_all(store.runs.parent().unwrap().parent().unwrap());
    }

    #[test]
    fn a_key_is_locked_once_and_its_leftovers_are_cleared_by_the_next_holder() {
        let store = scratch("lock");
        std::fs::create_dir_all(store.work_dir()).unwrap();
        let leftover = store.work_dir().join("k.out");
        let partial = store.runs.join(".k.json.999.partial");
        std::fs::write(&leftover, "half").unwrap();
        std::fs::write(&partial, "{").unwrap();
        let held = store.lock("k").unwrap().expect("free");
        assert!(!leftover.exists() && !partial.exists());
        assert!(store.lock("k").unwrap().is_none(), "a held key is refused");
        assert!(store.lock("other").unwrap().is_some());
        drop(held);
        assert!(store.lock("k").unwrap().is_some(), "released with its file");
        let _ = std::fs::remove_dir_all(store.runs.parent().unwrap().parent().unwrap());
    }

    #[test]
    fn a_lock_file_goes_once_its_point_holds_a_result_and_stays_while_it_failed() {
        let store = scratch("lock-files");
        let lock_path = |key: &str| store.work_dir().join(format!("{key}.lock"));
        for (key, status) in [("done", "ok"), ("broken", "failed")] {
            let held = store.lock(key).unwrap().expect("free");
            let record = json!({"key": key, "status": status, "message": ""});
            assert!(store.save(key, &record).unwrap());
            store.release_lock_file(key);
            drop(held);
        }
        assert!(
            !lock_path("done").exists(),
            "a stored result's lock file stays"
        );
        assert!(
            lock_path("broken").exists(),
            "a failed point's lock file is its reruns'"
        );
        // A later process takes a new lock file and finds the result stored.
        let again = store.lock("done").unwrap().expect("free");
        assert_eq!(store.status("done"), Some(Status::Ok));
        drop(again);
        let _ = std::fs::remove_dir_all(store.runs.parent().unwrap().parent().unwrap());
    }

    #[test]
    fn abandoned_output_partials_are_cleared_only_while_no_writer_holds_the_outputs() {
        let store = scratch("outputs");
        std::fs::create_dir_all(&store.runs).unwrap();
        let partial = store.table(".t.parquet.999.partial");
        std::fs::write(&partial, "PAR1").unwrap();
        let writer = store.lock_outputs().unwrap();
        std::fs::write(&partial, "PAR1").unwrap();
        store.clear_abandoned_outputs().unwrap();
        assert!(partial.exists(), "a live writer's partial file is kept");
        drop(writer);
        store.clear_abandoned_outputs().unwrap();
        assert!(!partial.exists(), "an abandoned partial file is cleared");
        let _ = std::fs::remove_dir_all(store.runs.parent().unwrap().parent().unwrap());
    }
}
