//! The record store of a study, `results/<study>/runs/<key>.json`: one file per run, written
//! through a temporary file and a rename, so that a file is either whole or absent.
//!
//! Several `nlstudy` processes may share a store (two terminals, a workstation and a cluster
//! job): a point runs only under its key's lock (a byte of `runs/.work/keys.lock` locked by an
//! open file description of its own, `F_OFD_SETLK`, which the kernel drops when its holder
//! exits, however it exits; one file for every key, so a point creates no lock file), a
//! `failed` record never replaces a result, and a file that is not a whole record is reported and treated as absent, never trusted.

use rayon::prelude::*;
use schema::record::{Status, Stored};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

#[cfg(test)]
pub mod example;
pub mod fs;
pub mod owner;
pub mod table;
pub mod timestamp;

use fs::{create_dir, lock_file, read_regular, remove_where, write_through, RECORD_CAP};
pub use fs::{write_atomically, Fault, FileError};

pub struct Store {
    pub study: String,
    pub runs: PathBuf,
}

pub fn hex(bytes: &[u8]) -> String {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut text = String::with_capacity(2 * bytes.len());
    for b in bytes {
        text.push(DIGITS[usize::from(b >> 4)] as char);
        text.push(DIGITS[usize::from(b & 15)] as char);
    }
    text
}

/// A run's key or a case's id: the first 16 bytes of a SHA-256, as 32 hex digits, held inline
/// (as a `String` it would be one allocation more per point, two million at 10⁶ points).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Id([u8; 32]);

impl Id {
    fn from_digest(digest: &[u8]) -> Id {
        const DIGITS: &[u8; 16] = b"0123456789abcdef";
        let mut id = [0; 32];
        for (k, b) in digest[..16].iter().enumerate() {
            id[2 * k] = DIGITS[usize::from(b >> 4)];
            id[2 * k + 1] = DIGITS[usize::from(b & 15)];
        }
        Id(id)
    }

    pub fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).expect("hex digits are ASCII")
    }

    /// The 128 bits the digits spell.
    pub fn bits(&self) -> u128 {
        u128::from_str_radix(self.as_str(), 16).expect("hex digits")
    }
}

impl Default for Id {
    fn default() -> Id {
        Id([b'0'; 32])
    }
}

impl std::ops::Deref for Id {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl std::fmt::Display for Id {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

impl std::fmt::Debug for Id {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl serde::Serialize for Id {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.as_str())
    }
}

/// A case's identity whatever the solver version (the first 16 bytes of the SHA-256 of its
/// canonical JSON, in hex), and the key of one run of it: the case, the solver version and,
/// beyond the first, the repeat. `case` is the compact JSON of the case (as `Value` prints it).
pub fn case_id_and_key(case: &str, solver_version: &str, repeat: usize) -> (Id, Id) {
    let mut hasher = Sha256::new();
    hasher.update(case.as_bytes());
    let case_id = Id::from_digest(&hasher.clone().finalize());
    hasher.update(b"\n");
    hasher.update(solver_version.as_bytes());
    if repeat > 0 {
        hasher.update(format!("\nrepeat {repeat}").as_bytes());
    }
    (case_id, Id::from_digest(&hasher.finalize()))
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

    /// The scratch file `name` (one of `SCRATCH`) of a run of `key`.
    pub fn scratch(&self, key: &str, name: &str) -> PathBuf {
        self.work_dir().join(format!("{key}.{name}"))
    }

    /// Where the record of `key` is written before it is renamed into place: one name, as only
    /// the holder of the key's lock writes it, so the next holder clears a leftover by its name
    /// rather than by listing the directory (10⁵ records: a listing per point is quadratic).
    fn partial(&self, key: &str) -> PathBuf {
        self.runs.join(format!(".{key}.json.partial"))
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
    /// A stored result, or a record made by another solver (another fingerprint), is not
    /// overwritten: it moves to the study's history first (`history/<key>.<fingerprint>.json`,
    /// see `history_path`), so nothing computed is lost and old and new can be compared.
    pub fn save(&self, key: &str, record: &Stored) -> Result<bool, FileError> {
        let failed = record.status() == Status::Failed;
        let stored = self.stored(key);
        let result_stored = stored
            .as_ref()
            .is_some_and(|s| s.status() != Status::Failed);
        if failed && result_stored {
            return Ok(false);
        }
        if let Some(stored) = stored {
            let old = fingerprint_of(&stored);
            if result_stored || old != fingerprint_of(record) {
                let history = self.table("history");
                create_dir(&history)?;
                std::fs::rename(self.path(key), history_path(&history, key, old))
                    .map_err(FileError::on("move to history", &self.path(key)))?;
            }
        }
        create_dir(&self.runs)?;
        write_through(
            &self.partial(key),
            &self.path(key),
            format!("{}\n", record.to_value()).as_bytes(),
        )?;
        Ok(true)
    }

    /// The status of the stored record of `key`, read now; `None` when absent or not whole.
    pub fn status(&self, key: &str) -> Option<Status> {
        Some(self.stored(key)?.status())
    }

    /// The stored record of `key`, read now, if whole.
    pub fn stored(&self, key: &str) -> Option<Stored> {
        let path = self.path(key);
        read_record(&path, &read_regular(&path, RECORD_CAP).ok()?).ok()
    }

    /// The keys with the scratch file `name` (one of `SCRATCH`, or `CHECKPOINT`) in the work
    /// directory, listed once (it holds a few files per running or stopped point).
    pub fn scratch_keys(&self, name: &str) -> std::collections::BTreeSet<String> {
        let suffix = format!(".{name}");
        std::fs::read_dir(self.work_dir())
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| Some(e.file_name().to_str()?.strip_suffix(&suffix)?.to_string()))
            .collect()
    }

    /// Is `key` locked, by this process or another: is its point running? The lock is not
    /// taken (as `lock` would, which a run starting the point then would take for another's).
    pub fn running(&self, key: &str) -> bool {
        let path = self.work_dir().join(KEY_LOCKS);
        let Ok((file, _)) = fs::open_regular(&path) else {
            return false;
        };
        fs::byte_locked(&file, key_byte(key)).unwrap_or(false)
    }

    /// Takes the lock of `key` for this process: `None` when another process holds it (that
    /// process is running the point). Taking it clears what an earlier holder killed midway
    /// left behind: its scratch files and its partly written record.
    pub fn lock(&self, key: &str) -> Result<Option<File>, FileError> {
        let work = self.work_dir();
        let file = lock_file(&work, KEY_LOCKS)?;
        if !fs::lock_byte(&file, key_byte(key))
            .map_err(FileError::on("lock", &work.join(KEY_LOCKS)))?
        {
            return Ok(None);
        }
        for name in SCRATCH {
            let _ = std::fs::remove_file(self.scratch(key, name));
        }
        let _ = std::fs::remove_file(self.partial(key));
        // A checkpoint's partial file, left by a solver killed while writing it.
        let _ = std::fs::remove_file(work.join(format!(".{key}.{CHECKPOINT}.partial")));
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
        // Read and parsed on every core, then taken in the listing's order.
        let read: Vec<(PathBuf, Result<Stored, String>)> = self
            .record_paths()
            .into_par_iter()
            .map(|path| {
                let record = read_regular(&path, RECORD_CAP).and_then(|t| read_record(&path, &t));
                (path, record)
            })
            .collect();
        let mut scan = Scan::default();
        for (path, record) in read {
            match record {
                Ok(record) => scan.records.push(record),
                Err(problem) => scan.unreadable.push(Unreadable { path, problem }),
            }
        }
        scan
    }

    /// Every stored record.
    pub fn records(&self) -> Vec<Stored> {
        self.scan().records
    }

    /// The superseded records in `history/` (see `save`), each key's in the order they were
    /// superseded (`<key>.<fp>.json`, then `.2`, `.3`, …: timestamps of one second may tie):
    /// whole records whose key is the first part of their file's name and matches their case;
    /// the rest is reported.
    pub fn history(&self) -> Scan {
        let mut scan = Scan::default();
        let mut paths = listing(&self.table("history"));
        paths.sort_by_cached_key(|path| {
            let name = path
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            let parts: Vec<&str> = name.split('.').collect();
            let k = match parts.as_slice() {
                [_, _, k, "json"] => k.parse::<u64>().unwrap_or(0),
                _ => 1,
            };
            (parts[0].to_string(), k, name.clone())
        });
        for path in paths {
            match read_regular(&path, RECORD_CAP).and_then(|text| read_superseded(&path, &text)) {
                Ok(record) => scan.records.push(record),
                Err(problem) => scan.unreadable.push(Unreadable { path, problem }),
            }
        }
        scan
    }

    /// What the stored records say, read once: the status of each key and the solver version
    /// each case id was run with. An unreadable file counts as absent (its point runs again).
    /// Only the fields the index keeps are parsed into values; the files are read on every
    /// core.
    pub fn index(&self) -> Index {
        use rayon::prelude::*;
        let read: Vec<Result<Indexed, Unreadable>> = self
            .record_paths()
            .into_par_iter()
            .map(|path| {
                read_regular(&path, RECORD_CAP)
                    .and_then(|text| read_indexed(&path, &text))
                    .map_err(|problem| Unreadable { path, problem })
            })
            .collect();
        let mut index = Index::default();
        for entry in read {
            let record = match entry {
                Ok(record) => record,
                Err(unreadable) => {
                    index.unreadable.push(unreadable);
                    continue;
                }
            };
            if let (Some(id), Some(version)) = (record.case_id, record.solver_version) {
                index.version_by_case.insert(id, version);
            }
            index.noisy += usize::from(record.noisy);
            if let Some(message) = record.failure {
                index.failed.push((record.key.clone(), message));
            }
            index.stored.insert(record.key, record.stored);
        }
        index
    }

    /// How many files the store holds (hidden ones left out): what a scan would read.
    pub fn count(&self) -> usize {
        std::fs::read_dir(&self.runs).map_or(0, |entries| {
            let visible = |e: &std::fs::DirEntry| !e.file_name().to_string_lossy().starts_with('.');
            entries.flatten().filter(visible).count()
        })
    }

    /// The paths of the store's files (hidden ones left out), in name order.
    fn record_paths(&self) -> Vec<PathBuf> {
        listing(&self.runs)
    }
}

/// The paths in `dir` (hidden ones left out), in name order; none when `dir` cannot be listed.
fn listing(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .collect();
    paths.sort_unstable();
    paths
}

/// Where a superseded record of `key`, made by the solver of `fingerprint` ("" when unknown),
/// goes in `history`: `<key>.<fingerprint>.json`, or `<key>.<fingerprint>.<k>.json` for the
/// k-th record of one build (a point rerun with `--force`). The fingerprint reaches the path
/// only as `fingerprint_of` checked it: 64 hex digits, or "unknown".
fn history_path(history: &Path, key: &str, fingerprint: &str) -> PathBuf {
    let build = if fingerprint.is_empty() {
        "unknown"
    } else {
        fingerprint
    };
    let first = history.join(format!("{key}.{build}.json"));
    if std::fs::symlink_metadata(&first).is_err() {
        return first;
    }
    (2..)
        .map(|k| history.join(format!("{key}.{build}.{k}.json")))
        .find(|path| std::fs::symlink_metadata(path).is_err())
        .expect("some index is free")
}

/// The fields of a record the index keeps; serde skips the rest without building values.
#[derive(serde::Deserialize)]
struct IndexedFields {
    // Named as `Stored` and `Record` name them (a test reads a whole record through both), not
    // a flattened `Stored`: flattening would buffer every other field of the record.
    key: Option<String>,
    status: Option<String>,
    case: Option<Value>,
    solver_version: Option<String>,
    repeat: Option<usize>,
    case_id: Option<Value>,
    provenance: Option<IndexedProvenance>,
    message: Option<Value>,
    setup_s: Option<Value>,
    solve_s: Option<Value>,
}

#[derive(serde::Deserialize)]
struct IndexedProvenance {
    fingerprint: Option<Value>,
    noisy: Option<Value>,
}

/// What the index keeps of one whole record (its identity checked as `read_record` checks it).
struct Indexed {
    key: String,
    stored: Recorded,
    case_id: Option<String>,
    solver_version: Option<String>,
    noisy: bool,
    /// The first line of a failed record's message.
    failure: Option<String>,
}

fn read_indexed(path: &Path, text: &str) -> Result<Indexed, String> {
    let fields: IndexedFields =
        serde_json::from_str(text).map_err(|e| format!("not whole JSON ({e})"))?;
    let (Some(key), Some(case), Some(version)) = (fields.key, &fields.case, fields.solver_version)
    else {
        return Err(IDENTITY_MISSING.into());
    };
    check_key(
        &record_key(path)?,
        &key,
        case,
        &version,
        fields.repeat.unwrap_or(0),
    )?;
    let status = fields
        .status
        .as_deref()
        .and_then(Status::parse)
        .ok_or(STATUS_UNKNOWN)?;
    let text = |v: &Option<Value>| v.as_ref().and_then(Value::as_str).map(str::to_string);
    let provenance = fields.provenance.as_ref();
    let seconds = |v: &Option<Value>| v.as_ref().and_then(Value::as_f64);
    let wall_s =
        seconds(&fields.solve_s).map(|solve| seconds(&fields.setup_s).unwrap_or(0.0) + solve);
    let fingerprint = provenance.and_then(|p| p.fingerprint.as_ref());
    Ok(Indexed {
        key,
        stored: Recorded {
            status,
            fingerprint: checked_fingerprint(fingerprint.and_then(Value::as_str)).to_string(),
            wall_s: wall_s.filter(|w| w.is_finite() && *w >= 0.0),
        },
        case_id: text(&fields.case_id),
        solver_version: Some(version),
        noisy: provenance.and_then(|p| p.noisy.as_ref()) == Some(&Value::Bool(true)),
        failure: (status == Status::Failed).then(|| {
            let message = text(&fields.message).unwrap_or_default();
            message.lines().next().unwrap_or("").to_string()
        }),
    })
}

/// Records by their key.
pub fn by_key(records: Vec<Stored>) -> HashMap<String, Stored> {
    records.into_iter().map(|r| (r.key.clone(), r)).collect()
}

/// The fingerprint of the solver that made `record`: 64 hex digits, as `nlsolve fingerprint`
/// prints them, or "" when the record does not say or says something else (a record's text is
/// never trusted: this one reaches file names, see `history_path`).
pub fn fingerprint_of(record: &Stored) -> &str {
    checked_fingerprint(record.provenance().map(|p| p.fingerprint.as_str()))
}

fn checked_fingerprint(text: Option<&str>) -> &str {
    let text = text.unwrap_or("");
    let valid = text.len() == 64 && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'));
    if valid {
        text
    } else {
        ""
    }
}

/// The file whose bytes are the keys' locks, in the work directory.
const KEY_LOCKS: &str = "keys.lock";

/// The byte of `KEY_LOCKS` that locks `key`: its 64-bit FNV-1a hash within 62 bits (a lock's
/// offset is a signed 64-bit number); two keys share a byte once in 10¹⁸ pairs, when one waits.
fn key_byte(key: &str) -> i64 {
    let hash = key.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |hash, byte| {
        (hash ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    (hash >> 2) as i64
}

/// The checkpoint of a point run as a process (`<key>.checkpoint` in the work directory): kept
/// when a run stops, so that the next one resumes it; the solver removes it with its record.
pub const CHECKPOINT: &str = "checkpoint";

/// How far a running case's time loop is, from its progress file (`<key>.progress`, which
/// nlsolve's `integrate::progress` writes): its step, its steps in all and the seconds left.
pub fn progress_of(path: &Path) -> Option<(u64, u64, f64)> {
    let text = fs::read_regular(path, 4096).ok()?;
    let progress: Value = serde_json::from_str(&text).ok()?;
    Some((
        progress["step"].as_u64()?,
        progress["steps"].as_u64()?,
        progress["left_s"].as_f64()?,
    ))
}

/// The step a checkpoint (`<key>.checkpoint`) was taken at and the run's steps in all, from its
/// header: the line after the file's first (nlsolve's `integrate::checkpoint` writes it).
pub fn checkpoint_steps(path: &Path) -> Option<(u64, Option<u64>)> {
    use std::io::BufRead;
    let (file, _) = fs::open_regular(path).ok()?;
    let mut lines = std::io::BufReader::new(file).split(b'\n');
    let magic = lines.next()?.ok()?;
    if !magic.starts_with(b"nlsolve checkpoint") {
        return None;
    }
    let header: Value = serde_json::from_slice(&lines.next()?.ok()?).ok()?;
    Some((header["step"].as_u64()?, header["steps"].as_u64()))
}

/// The scratch files of a point run as a process (in the work directory, `<key>.<name>`): its
/// case, standard output and standard error, and how far its time loop is (`PROGRESS`, written
/// by a worker's case too).
pub const SCRATCH: [&str; 4] = ["case.json", "out", "err", PROGRESS];

/// The scratch file where a running case's time loop says how far it is (`nlsolve --progress`).
pub const PROGRESS: &str = "progress";

const IDENTITY_MISSING: &str =
    "it does not carry the `key`, `case` and `solver_version` its key is made of";
const STATUS_UNKNOWN: &str = "it has no known `status`";

/// Whether a record's `key` is `file_key` (its file's name) and the hash of its case, solver
/// version and repeat.
fn check_key(
    file_key: &str,
    key: &str,
    case: &Value,
    version: &str,
    repeat: usize,
) -> Result<(), String> {
    if key != file_key {
        return Err("its `key` is not its file name".into());
    }
    let (_, made) = case_id_and_key(&case.to_string(), version, repeat);
    if made.as_str() != file_key {
        return Err(format!(
            "its key is not that of its `case`, `solver_version` and `repeat` ({made}): it was edited or moved"
        ));
    }
    Ok(())
}

/// `text`, read from `path`, as a record: a whole `Stored` record whose `key` is the file's name
/// and the hash of its case. Anything else is named in the error.
fn read_record(path: &Path, text: &str) -> Result<Stored, String> {
    check_identity(&record_key(path)?, text)
}

/// `text`, read from `path` in the history, as a superseded record: as `read_record`, its key
/// the first part of the file's name (`<key>.<fingerprint>[.<k>].json`).
fn read_superseded(path: &Path, text: &str) -> Result<Stored, String> {
    let key = record_key(path)?;
    let key = key.split('.').next().unwrap_or_default();
    check_identity(key, text)
}

fn check_identity(file_key: &str, text: &str) -> Result<Stored, String> {
    let record: Value = serde_json::from_str(text).map_err(|e| format!("not whole JSON ({e})"))?;
    let fields = record
        .as_object()
        .ok_or("not a record (not a JSON object)")?;
    let text_of = |name: &str| fields.get(name).and_then(Value::as_str);
    let (Some(key), Some(case), Some(version)) = (
        text_of("key"),
        fields.get("case"),
        text_of("solver_version"),
    ) else {
        return Err(IDENTITY_MISSING.into());
    };
    let repeat = fields.get("repeat").and_then(Value::as_u64).unwrap_or(0) as usize;
    check_key(file_key, key, case, version, repeat)?;
    if text_of("status").and_then(Status::parse).is_none() {
        return Err(STATUS_UNKNOWN.into());
    }
    serde_path_to_error::deserialize(record)
        .map_err(|e| format!("not a whole record (`{}`: {})", e.path(), e.inner()))
}

/// The key a record's path names: its file's name without `.json`.
fn record_key(path: &Path) -> Result<String, String> {
    match path.extension().is_some_and(|x| x == "json") {
        true => Ok(path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()),
        false => Err("not a record (records are <key>.json)".into()),
    }
}

/// What the index keeps of a whole record.
pub struct Recorded {
    pub status: Status,
    /// The fingerprint of the solver that made it ("" when it does not say).
    pub fingerprint: String,
    /// Its wall time, set-up + solve, in seconds, when it says.
    pub wall_s: Option<f64>,
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
    pub records: Vec<Stored>,
    pub unreadable: Vec<Unreadable>,
}

#[derive(Default)]
pub struct Index {
    /// What each whole record says, by key.
    pub stored: HashMap<String, Recorded>,
    pub version_by_case: HashMap<String, String>,
    pub unreadable: Vec<Unreadable>,
    /// Failed records, by key in name order, with the first line of their message.
    pub failed: Vec<(String, String)>,
    /// Records whose provenance says they were timed on a busy machine.
    pub noisy: usize,
}

#[cfg(test)]
mod tests;
