//! Which study file a results directory belongs to: `results/<study>/study-file.json` holds its
//! path and the hash of its text when last used. A second file with the same `name` would
//! otherwise write its tables and figures over the first's without a word.

use crate::store::{hex, write_atomically, FileError, Store};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

#[derive(Debug, Deserialize, PartialEq, Serialize)]
pub struct Owner {
    /// The study file, as an absolute path with links resolved.
    pub study_file: PathBuf,
    /// SHA-256 of its text when a command last used it (it may change: a study is edited).
    pub sha256: String,
}

/// Why a study may not use a results directory.
#[derive(Debug)]
pub enum Refusal {
    /// Another study file owns it.
    OwnedBy(PathBuf),
    Io(FileError),
}

const FILE: &str = "study-file.json";

impl Store {
    /// The owner of the results directory, if one is written.
    pub fn owner(&self) -> Option<Owner> {
        let text =
            crate::store::fs::read_regular(&self.table(FILE), crate::store::fs::SMALL_FILE_CAP)
                .ok()?;
        serde_json::from_str(&text).ok()
    }

    /// Checks that `study_file` (whose text is `text`) owns the results directory, and with
    /// `write` records it as the owner when none is, when it `adopt`s the directory, or when
    /// its text changed. A directory another file owns is refused unless `adopt`. A writer
    /// reads, decides and writes under the directory's owner lock: of two commands claiming one
    /// new directory at once (`--adopt` or not), the second sees the first's claim.
    pub fn claim(
        &self,
        study_file: &Path,
        text: &str,
        adopt: bool,
        write: bool,
    ) -> Result<(), Refusal> {
        let path = std::fs::canonicalize(study_file).unwrap_or_else(|_| study_file.to_path_buf());
        let me = Owner {
            study_file: path,
            sha256: hex(&Sha256::digest(text.as_bytes())),
        };
        let _held = match write {
            true => {
                let lock = crate::store::fs::lock_file(&self.table(""), ".owner.lock")
                    .map_err(Refusal::Io)?;
                lock.lock().map_err(|e| {
                    Refusal::Io(FileError::new("lock", &self.table(".owner.lock"), e))
                })?;
                Some(lock)
            }
            false => None,
        };
        let owner = self.owner();
        // The same text is the same study wherever its file lies (another checkout, a results
        // folder copied to a laptop); another file of another text needs `adopt`.
        let another =
            |owner: &Owner| owner.study_file != me.study_file && owner.sha256 != me.sha256;
        match &owner {
            Some(owner) if another(owner) && !adopt => {
                return Err(Refusal::OwnedBy(owner.study_file.clone()))
            }
            Some(owner) if *owner == me => return Ok(()),
            _ if !write => return Ok(()),
            _ => {}
        }
        let directory = self.table("");
        crate::store::fs::create_dir(&directory).map_err(Refusal::Io)?;
        let json = serde_json::to_string_pretty(&me).expect("an owner serializes");
        write_atomically(&self.table(FILE), json.as_bytes()).map_err(Refusal::Io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_file_of_the_same_name_is_refused_unless_it_adopts() {
        let temporary = tempfile::tempdir().unwrap();
        let dir = temporary.path().to_path_buf();
        let (first, second) = (dir.join("a.json"), dir.join("b.json"));
        std::fs::write(&first, "{}").unwrap();
        std::fs::write(&second, "{\"other\": 1}").unwrap();
        let store = Store::open(&dir.join("results"), "s");

        // Reading does not write; the first command that writes makes the file the owner.
        store.claim(&first, "{}", false, false).unwrap();
        assert_eq!(store.owner(), None);
        store.claim(&first, "{}", false, true).unwrap();
        let owner = store.owner().unwrap();
        assert_eq!(owner.study_file, std::fs::canonicalize(&first).unwrap());
        // An edited study is the same study; its new hash is kept.
        store.claim(&first, "{\"edited\": 1}", false, true).unwrap();
        assert_ne!(store.owner().unwrap().sha256, owner.sha256);

        match store.claim(&second, "{}", false, true) {
            Err(Refusal::OwnedBy(path)) => assert_eq!(path, owner.study_file),
            other => panic!("{other:?}"),
        }
        store.claim(&second, "{}", true, true).unwrap();
        assert_eq!(
            store.owner().unwrap().study_file,
            std::fs::canonicalize(&second).unwrap()
        );
        // The same text at another path (a checkout elsewhere, a copied folder) is the same study.
        let copy = dir.join("copy.json");
        std::fs::write(&copy, "{}").unwrap();
        store.claim(&copy, "{}", false, false).unwrap();
    }

    /// Two commands of two study files claim one new results directory at once: one owns it,
    /// the other is refused, every time.
    #[test]
    fn of_two_claims_at_once_one_wins() {
        let temporary = tempfile::tempdir().unwrap();
        let dir = temporary.path().to_path_buf();
        let files = [dir.join("a.json"), dir.join("b.json")];
        for file in &files {
            std::fs::write(file, "{}").unwrap();
        }
        for k in 0..40 {
            let results = dir.join(format!("results-{k}"));
            let won: Vec<bool> = std::thread::scope(|scope| {
                let claims: Vec<_> = files
                    .iter()
                    .map(|file| {
                        let store = Store::open(&results, "s");
                        let text = file.display().to_string();
                        scope.spawn(move || store.claim(file, &text, false, true).is_ok())
                    })
                    .collect();
                claims.into_iter().map(|c| c.join().unwrap()).collect()
            });
            assert_eq!(won.iter().filter(|w| **w).count(), 1, "round {k}: {won:?}");
        }
    }
}
