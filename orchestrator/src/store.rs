//! The record store of a study, `results/<study>/runs/<key>.json`: one file per run, written
//! through a temporary file and a rename, so that a file is either whole or absent.

use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::io;
use std::path::{Path, PathBuf};

pub struct Store {
    pub runs: PathBuf,
}

/// The first 16 bytes of SHA-256, in hex.
fn digest(text: &str) -> String {
    Sha256::digest(text.as_bytes())[..16]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
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
            runs: results.join(study).join("runs"),
        }
    }

    pub fn path(&self, key: &str) -> PathBuf {
        self.runs.join(format!("{key}.json"))
    }

    /// Scratch space of runs in progress (case files, captured output).
    pub fn work_dir(&self) -> PathBuf {
        self.runs.join(".work")
    }

    /// The stored record of `key`; an unreadable file counts as absent (it is rewritten).
    pub fn load(&self, key: &str) -> Option<Value> {
        let text = std::fs::read_to_string(self.path(key)).ok()?;
        serde_json::from_str(&text).ok()
    }

    pub fn save(&self, key: &str, record: &Value) -> io::Result<()> {
        std::fs::create_dir_all(&self.runs)?;
        let path = self.path(key);
        let partial = self.runs.join(format!(".{key}.json.partial"));
        std::fs::write(&partial, format!("{record}\n"))?;
        std::fs::rename(&partial, &path)
    }

    /// Every stored record.
    pub fn records(&self) -> Vec<Value> {
        let Ok(entries) = std::fs::read_dir(&self.runs) else {
            return Vec::new();
        };
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "json"))
            .filter(|p| {
                !p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            })
            .collect();
        paths.sort();
        paths
            .iter()
            .filter_map(|p| serde_json::from_str(&std::fs::read_to_string(p).ok()?).ok())
            .collect()
    }

    /// The solver version each stored case id was last run with.
    pub fn versions_by_case(&self) -> HashMap<String, String> {
        self.records()
            .iter()
            .filter_map(|r| {
                let id = r.get("case_id")?.as_str()?;
                let version = r.get("solver_version")?.as_str()?;
                Some((id.to_string(), version.to_string()))
            })
            .collect()
    }
}
