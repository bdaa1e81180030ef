//! The solver's fingerprint: one hash of everything that decides the numbers of a record, so
//! that a record can say which build made it. Computed by build.rs at build time (it includes
//! this file) and tested on a copy of the sources by tests/fingerprint.rs.
//!
//! In it: the sources and manifests of the `schema` and `solver` crates (and this build
//! script), the workspace manifest (its profiles) and Cargo.lock, the compiler (`rustc -vV`),
//! the target, its enabled CPU features and RUSTFLAGS, the profile and optimisation level, and
//! the crate features. Not in it: the orchestrator, tests, benches and docs (they compute no
//! record), the git revision (the sources are hashed themselves, dirty or not), and what the
//! run meets at run time (the machine, its instruction set, the MPI library), which the
//! record's provenance names.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The files and folders below the workspace root whose bytes are hashed.
pub const SOURCES: &[&str] = &[
    "Cargo.toml",
    "Cargo.lock",
    "schema/Cargo.toml",
    "schema/src",
    "solver/Cargo.toml",
    "solver/build.rs",
    "solver/build",
    "solver/src",
];

/// SHA-256, in hex, of each file below `root`'s `sources` (folders walked, in path order) as
/// its relative path and bytes, then of each `(name, value)` setting. A missing source is
/// hashed as missing.
pub fn fingerprint(root: &Path, sources: &[&str], settings: &[(&str, String)]) -> String {
    let mut hasher = Sha256::new();
    for source in sources {
        let mut files = Vec::new();
        collect(&root.join(source), &mut files);
        if files.is_empty() {
            hasher.update(format!("missing {source}\n"));
        }
        files.sort();
        for file in files {
            let relative = file.strip_prefix(root).unwrap_or(&file);
            let bytes = std::fs::read(&file).unwrap_or_default();
            hasher.update(format!("file {} {}\n", relative.display(), bytes.len()));
            hasher.update(&bytes);
        }
    }
    for (name, value) in settings {
        hasher.update(format!("setting {name} {}\n{value}\n", value.len()));
    }
    hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The files at `path`: itself, or every file below it.
fn collect(path: &Path, files: &mut Vec<PathBuf>) {
    match std::fs::read_dir(path) {
        Ok(entries) => {
            for entry in entries.flatten() {
                collect(&entry.path(), files);
            }
        }
        Err(_) if path.is_file() => files.push(path.to_path_buf()),
        Err(_) => {}
    }
}
