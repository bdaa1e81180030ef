//! What a stored record is: its key (the hash of its case, solver version and repeat), and
//! reading one from text, checked against its key, whole (`Stored`) or only the fields the
//! catalog keeps (`Indexed`); what is not a whole record is an `Unreadable`, named and skipped.

use schema::record::{Status, Stored};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

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

/// The paths in `dir` (hidden ones left out), in name order; none when `dir` cannot be listed.
pub(super) fn listing(dir: &Path) -> Vec<PathBuf> {
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

/// What the catalog keeps of one whole record (its identity checked as `read_record` checks it).
#[derive(Clone)]
pub(crate) struct Indexed {
    pub(super) key: String,
    pub(super) stored: Recorded,
    pub(super) case_id: Option<String>,
    pub(super) solver_version: Option<String>,
    pub(super) noisy: bool,
    /// The first line of a failed record's message.
    pub(super) failure: Option<String>,
}

/// `text` as a record, what the catalog keeps of it: read whole as the typed record, as every
/// other reader reads it (a record `collect` would drop is no record for `plan` and `status`
/// either: its point runs again), its key checked against its case and, for a file of the old
/// store, against the file's name (`path`).
pub(crate) fn read_indexed(path: Option<&Path>, text: &str) -> Result<Indexed, String> {
    let file_key = path.map(record_key).transpose()?;
    let stored = check_identity_as(file_key.as_deref(), text)?;
    Ok(Indexed::from_stored(stored))
}

impl Indexed {
    fn from_stored(stored: Stored) -> Indexed {
        let status = stored.status();
        // The whole run where the record has it (the spectrum and errors measured after the
        // solve are most of a stability probe's time), else its set-up and solve.
        let wall_s = stored
            .record()
            .map(|r| r.wall_s.unwrap_or(r.setup_s + r.solve_s))
            .filter(|w| w.is_finite() && *w >= 0.0);
        let failure = (status == Status::Failed)
            .then(|| stored.message().lines().next().unwrap_or("").to_string());
        Indexed {
            stored: Recorded {
                status,
                fingerprint: super::shared::shared(fingerprint_of(&stored)),
                wall_s,
            },
            noisy: stored.noisy(),
            failure,
            case_id: stored.case_id,
            solver_version: Some(stored.solver_version),
            key: stored.key,
        }
    }
}

/// The fingerprint of the solver that made `record`: 64 hex digits, as `nlsolve fingerprint`
/// prints them, or "" when the record does not say or says something else (a record's text is
/// never trusted: this one reaches file names, see `history_path`).
pub fn fingerprint_of(record: &Stored) -> &str {
    checked_fingerprint(record.provenance().map(|p| p.fingerprint.as_str()))
}

pub(super) fn checked_fingerprint(text: Option<&str>) -> &str {
    let text = text.unwrap_or("");
    let valid = text.len() == 64 && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'));
    if valid {
        text
    } else {
        ""
    }
}

const IDENTITY_MISSING: &str =
    "it does not carry the `key`, `case` and `solver_version` its key is made of";
const STATUS_UNKNOWN: &str = "it has no known `status`";

/// Whether a record's `key` is `file_key` (its file's name) and the hash of its case, solver
/// version and repeat.
pub(super) fn check_key(
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
pub(super) fn read_record(path: &Path, text: &str) -> Result<Stored, String> {
    check_identity(&record_key(path)?, text)
}

/// `text`, read from `path` in the history, as a superseded record: as `read_record`, its key
/// the first part of the file's name (`<key>.<fingerprint>[.<k>].json`).
pub(super) fn read_superseded(path: &Path, text: &str) -> Result<Stored, String> {
    let key = record_key(path)?;
    let key = key.split('.').next().unwrap_or_default();
    check_identity(key, text)
}

pub(super) fn check_identity(file_key: &str, text: &str) -> Result<Stored, String> {
    check_identity_as(Some(file_key), text)
}

/// `check_identity`, against the record's own `key` where no file names it (`None`: a frame of a
/// segment).
fn check_identity_as(file_key: Option<&str>, text: &str) -> Result<Stored, String> {
    // Most records are whole runs, read straight from their text; anything else is read again
    // through its tree, which names what is wrong.
    if let Some(stored) = Stored::from_ran_text(text) {
        let (key, version) = (&stored.key, &stored.solver_version);
        let file_key = file_key.unwrap_or(key);
        if check_key(file_key, key, stored.case(), version, stored.repeat).is_ok() {
            return Ok(stored);
        }
    }
    check_identity_of_tree(file_key, text)
}

/// `check_identity` through the parsed tree of `text`: every record, and every error named.
pub(super) fn check_identity_of_tree(file_key: Option<&str>, text: &str) -> Result<Stored, String> {
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
    check_key(file_key.unwrap_or(key), key, case, version, repeat)?;
    if text_of("status").and_then(Status::parse).is_none() {
        return Err(STATUS_UNKNOWN.into());
    }
    Stored::from_value(record).map_err(|e| format!("not a whole record ({e})"))
}

/// The key a record's path names: its file's name without `.json`.
pub(super) fn record_key(path: &Path) -> Result<String, String> {
    match path.extension().is_some_and(|x| x == "json") {
        true => Ok(path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()),
        false => Err("not a record (records are <key>.json)".into()),
    }
}

/// What the index keeps of a whole record.
#[derive(Clone)]
pub struct Recorded {
    pub status: Status,
    /// The fingerprint of the solver that made it ("" when it does not say).
    pub fingerprint: super::shared::Shared,
    /// Its wall time in seconds, the whole run's (else set-up + solve), when it says.
    pub wall_s: Option<f64>,
}

/// A file of the store that is not a whole record: truncated, garbage, or not a record at all.
#[derive(Clone, Debug)]
pub struct Unreadable {
    pub path: PathBuf,
    /// The bytes of a segment that are not a whole record (`None`: the whole file).
    pub at: Option<std::ops::Range<u64>>,
    pub problem: String,
}

impl std::fmt::Display for Unreadable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.at {
            None => write!(
                f,
                "{} is not a whole record ({}); its point runs again",
                self.path.display(),
                self.problem
            ),
            Some(at) => write!(
                f,
                "{} bytes {}–{} are not a whole record ({}), kept where they are: the record they held is not counted (its point runs again, unless an earlier record of it stands)",
                self.path.display(),
                at.start,
                at.end,
                self.problem
            ),
        }
    }
}
