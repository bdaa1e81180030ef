//! The record store of a study, `results/<study>/runs/<key>.json`: one file per run, written
//! through a temporary file and a rename, so that a file is either whole or absent.

use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::io;
use std::path::{Path, PathBuf};

pub struct Store {
    pub study: String,
    pub runs: PathBuf,
}

/// The first 16 bytes of SHA-256, in hex.
fn digest(text: &str) -> String {
    hex(&Sha256::digest(text.as_bytes())[..16])
}

/// Where a file is written before it is renamed into place: hidden (readers skip dot files)
/// and named for this process, so that processes writing the same file do not mix.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

/// Writes a file whole or not at all: to its partial path, then a rename.
pub fn write_atomically(path: &Path, contents: &[u8]) -> io::Result<()> {
    let partial = partial_path(path);
    std::fs::write(&partial, contents)
        .and_then(|_| std::fs::rename(&partial, path))
        .inspect_err(|_| {
            let _ = std::fs::remove_file(&partial);
        })
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

    pub fn save(&self, key: &str, record: &Value) -> io::Result<()> {
        std::fs::create_dir_all(&self.runs)?;
        write_atomically(&self.path(key), format!("{record}\n").as_bytes())
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

    /// What the stored records say, read once: the status of each key and the solver version
    /// each case id was run with. An unreadable file counts as absent (it is rewritten).
    pub fn index(&self) -> Index {
        let mut index = Index::default();
        for record in self.records() {
            let text = |field: &str| record.get(field)?.as_str().map(str::to_string);
            if let (Some(key), Some(status)) = (text("key"), text("status")) {
                index.status.insert(key, status);
            }
            if let (Some(id), Some(version)) = (text("case_id"), text("solver_version")) {
                index.version_by_case.insert(id, version);
            }
        }
        index
    }
}

#[derive(Default)]
pub struct Index {
    pub status: HashMap<String, String>,
    pub version_by_case: HashMap<String, String>,
}
