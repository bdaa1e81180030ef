//! The record store of a study, `results/<study>/runs/`: records packed into append-only
//! segments (`segment`), each record whole or absent after a crash, and a catalog of where each
//! key's latest record lies (`catalog`), which `plan` and `status` read instead of the records.
//! A store of the older layout, one file per record (`runs/<key>.json`), is read as it is and
//! moved into segments by the first process that writes (`migrate`); `collect` compacts the
//! segments (`compact`), dropping superseded records.
//!
//! Several `nlstudy` processes may share a store (two terminals, a workstation and a cluster
//! job): a point runs only under its key's lock (a byte of `runs/.work/keys.lock` locked by an
//! open file description of its own, `F_OFD_SETLK`, which the kernel drops when its holder
//! exits, however it exits; one file for every key, so a point creates no lock file), a
//! `failed` record never replaces a result, and a file that is not a whole record is reported and treated as absent, never trusted.

use rayon::prelude::*;
use schema::protocol::ProgressUnit;
use schema::record::{Status, Stored};
use serde_json::Value;
use std::collections::HashMap;
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

pub mod catalog;
pub mod fs;
pub mod owner;
pub mod record;
pub mod segment;
pub mod shared;
pub mod table;
pub mod timeline;
pub mod timestamp;

use catalog::{Catalog, KeyMap, Location};
use fs::{create_dir, lock_file, read_regular, remove_where, RECORD_CAP};
pub use fs::{write_atomically, Fault, FileError};
pub use record::{case_id_and_key, fingerprint_of, hex, Id, Recorded, Unreadable};
use record::{check_identity, listing, read_indexed, read_record, read_superseded, Indexed};
use segment::Appender;
pub use shared::{shared, Shared};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

pub struct Store {
    pub study: String,
    pub runs: PathBuf,
    /// The catalog as this process last read it (loaded on first use).
    catalog: Mutex<Option<Catalog>>,
    /// The segment this process appends to (taken on its first record).
    appender: Mutex<Option<Appender>>,
    /// The records `stored_shared` parsed, each with where it lay.
    parsed: Mutex<KeyMap<(Location, Arc<Stored>)>>,
}

impl Store {
    pub fn open(results: &Path, study: &str) -> Store {
        Store {
            study: study.to_string(),
            runs: results.join(study).join("runs"),
            catalog: Mutex::new(None),
            appender: Mutex::new(None),
            parsed: Mutex::default(),
        }
    }

    fn segments(&self) -> PathBuf {
        self.runs.join(segment::DIR)
    }

    /// The catalog, brought up to date with the segments; stored again when it had news and
    /// `persist` (a reader's catalog saves the next reader the reading).
    fn catalog(&self, persist: bool) -> MutexGuard<'_, Option<Catalog>> {
        let mut guard = self.catalog_as_read();
        let catalog = guard.as_mut().expect("loaded");
        catalog.unsaved |= catalog.refresh(&self.runs);
        if persist && catalog.unsaved {
            catalog.persist(&self.runs);
        }
        guard
    }

    /// The catalog as this process last read it (loaded on first use), without looking for
    /// what other processes stored since.
    fn catalog_as_read(&self) -> MutexGuard<'_, Option<Catalog>> {
        let mut guard = self.catalog.lock().unwrap_or_else(PoisonError::into_inner);
        guard.get_or_insert_with(|| Catalog::load(&self.runs));
        guard
    }

    /// Syncs this process's segment and stores the catalog as this process knows it (after a
    /// run appended records).
    pub fn persist_catalog(&self) {
        if let Some(appender) = self
            .appender
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_mut()
        {
            appender.sync();
        }
        let mut guard = self.catalog.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(catalog) = guard.as_mut() {
            catalog.persist(&self.runs);
        }
    }

    /// Appends `bodies` (records' JSON) to this process's segment, synced now if `sync`; the
    /// catalog learns them.
    fn append(&self, bodies: &[(String, Indexed)], sync: bool) -> Result<(), FileError> {
        let dir = self.segments();
        let mut appender = self.appender.lock().unwrap_or_else(PoisonError::into_inner);
        let mut guard = self.catalog_as_read();
        let catalog = guard.as_mut().expect("loaded");
        if appender.as_ref().is_none_or(Appender::full) {
            let candidates: Vec<(String, u64)> = catalog
                .segments
                .iter()
                .filter(|(_, s)| s.clean() && s.end < segment::TARGET_BYTES)
                .map(|(name, s)| (name.clone(), s.end))
                .collect();
            let opened = Appender::open(&dir, &candidates)?;
            if let Some(cut) = &opened.cut {
                log::warn!(
                    "segment runs/{}/{} ended in {} bytes of a frame cut short (a write torn by a crash, or a frame's length changed): cut off; the record they held is not counted (its point runs again, unless an earlier record of it stands)",
                    segment::DIR,
                    opened.name,
                    cut.end - cut.start
                );
            }
            *appender = Some(opened);
        }
        let appender = appender.as_mut().expect("opened above");
        let texts: Vec<&[u8]> = bodies.iter().map(|(b, _)| b.as_bytes()).collect();
        let frames = appender.append(&dir, &texts, sync)?;
        for (frame, (_, indexed)) in frames.iter().zip(bodies) {
            catalog.appended(&appender.name, frame, indexed.clone());
        }
        catalog.written(&appender.name, appender.modified());
        Ok(())
    }

    /// Moves the old store's record files (`runs/<key>.json`) into a segment, a thousand at a
    /// time: each file is removed only once its record is on disk in the segment, and a key
    /// some process is running is left for its run. Returns how many moved.
    pub fn migrate(&self) -> Result<usize, FileError> {
        let files: Vec<PathBuf> = self
            .catalog(false)
            .as_ref()
            .expect("loaded")
            .record_files()
            .into_iter()
            .map(Path::to_path_buf)
            .collect();
        let mut moved = 0;
        for chunk in files.chunks(1000) {
            let mut batch = Vec::new();
            let mut locks = Vec::new();
            for path in chunk {
                let Ok(text) = read_regular(path, RECORD_CAP) else {
                    continue;
                };
                let Ok(indexed) = read_indexed(Some(path), &text) else {
                    continue;
                };
                let Some(lock) = self.lock(&indexed.key)? else {
                    continue;
                };
                locks.push(lock);
                let Ok(value) = serde_json::from_str::<Value>(&text) else {
                    continue;
                };
                batch.push((path, (value.to_string(), indexed)));
            }
            let bodies: Vec<(String, Indexed)> = batch.iter().map(|(_, b)| b.clone()).collect();
            // On disk before the files go.
            self.append(&bodies, true)?;
            for (path, _) in &batch {
                std::fs::remove_file(path).map_err(FileError::on("remove", path))?;
            }
            moved += batch.len();
        }
        if moved > 0 {
            self.persist_catalog();
        }
        Ok(moved)
    }

    /// Rewrites the segments no writer holds that are small, or hold superseded records or
    /// records of `forget` (`clean --yes`), into new ones of at most `segment::TARGET_BYTES`
    /// without those records; a segment with bytes
    /// that are not whole records is kept as it is (reported, never dropped). The old store's
    /// files are not touched: every command that writes has moved them in (`migrate`) when it
    /// opened the store. Forgetting a key whose record lies in a segment another process is
    /// writing is refused. One compaction at a time: another one running means this one is
    /// not needed.
    ///
    /// Long because it is one transaction under the compaction lock and the appender's: which
    /// segments to rewrite, their records rewritten, the catalog replaced, the old segments
    /// removed, in that order.
    pub fn compact(&self, forget: &std::collections::HashSet<String>) -> Result<(), Fault> {
        let dir = self.segments();
        let compacting = lock_file(&dir, ".compact.lock")?;
        if compacting.try_lock().is_err() {
            return Ok(());
        }
        // A compaction killed midway left its partial segment.
        remove_where(&dir, |n| n.starts_with('.') && n.ends_with(".partial"));
        let own = self
            .appender
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .map(|a| a.name.clone());
        let mut guard = self.catalog(false);
        let catalog = guard.as_mut().expect("loaded");
        // Segments worth rewriting: small ones (merged), ones with superseded records, and
        // ones holding a record to forget.
        let forgotten_in: std::collections::HashSet<String> = forget
            .iter()
            .filter_map(|key| catalog.entries.get(key).and_then(located))
            .map(str::to_string)
            .collect();
        let mut held = std::collections::BTreeMap::new();
        for (name, state) in &catalog.segments {
            let worth = state.superseded > 0
                || state.end < segment::TARGET_BYTES / 2
                || forgotten_in.contains(name);
            if Some(name) != own.as_ref() && state.clean() && worth {
                if let Some(file) = segment::hold(&dir.join(name)) {
                    held.insert(name.clone(), file);
                }
            }
        }
        // What a writer appended to a held segment before letting it go: read now that no one
        // can append to it, or its records would not be copied before it goes.
        catalog.refresh(&self.runs);
        held.retain(|name, _| catalog.segments.get(name).is_some_and(|s| s.clean()));
        for key in forget {
            if let Some(name) = catalog.entries.get(key).and_then(located) {
                if !held.contains_key(name) {
                    return Err(Fault::Io(format!(
                        "the record of {key} lies in segment runs/{}/{name}, which another nlstudy is writing; clean when it ends",
                        segment::DIR
                    )));
                }
            }
        }
        // The records to keep, by segment in offset order.
        let mut kept: std::collections::BTreeMap<Shared, Vec<(String, std::ops::Range<u64>)>> =
            Default::default();
        let mut dropped = held
            .keys()
            .map(|n| catalog.segments[n].superseded)
            .sum::<u64>();
        for (key, entry) in &catalog.entries {
            let Location::Segment { name, span } = &entry.at else {
                continue;
            };
            if !held.contains_key(&**name) {
                continue;
            }
            if forget.contains(key) {
                dropped += entry.bytes();
            } else {
                kept.entry(name.clone())
                    .or_default()
                    .push((key.clone(), span.clone()));
            }
        }
        if held.len() < 2 && dropped == 0 {
            return Ok(());
        }
        // New segments of at most `TARGET_BYTES` each.
        let mut written = Vec::new();
        let mut writer = segment::Rewriter::create(&dir)?;
        let mut moved = Vec::new();
        let mut merged = Vec::new();
        let mut changed = false;
        for name in held.keys() {
            let mut frames = kept.remove(name.as_str()).unwrap_or_default();
            frames.sort_by_key(|(_, span)| span.start);
            let path = dir.join(name);
            let bytes = segment::read_from(&path, 0).map_err(FileError::on("read", &path))?;
            // A frame that changed since it was read keeps its segment as it is; the next
            // reader reads all again and reports it.
            if frames
                .iter()
                .any(|(_, span)| segment::body_at(&bytes, span).is_none())
            {
                changed = true;
                continue;
            }
            for (key, span) in frames {
                let frame = &bytes[span.start as usize..span.end as usize];
                if writer.size() > 0 && writer.size() + frame.len() as u64 > segment::TARGET_BYTES {
                    let full = std::mem::replace(&mut writer, segment::Rewriter::create(&dir)?);
                    written.push(full.finish()?);
                }
                let at = writer.copy(frame)?;
                moved.push((key, written.len(), at));
            }
            merged.push(name.clone());
        }
        if merged.is_empty() {
            writer.abandon();
            catalog.invalidate();
            return Ok(());
        }
        written.push(writer.finish()?);
        for name in &merged {
            std::fs::remove_file(dir.join(name))
                .map_err(FileError::on("remove", &dir.join(name)))?;
            catalog.segments.remove(name);
        }
        drop(held);
        if changed {
            catalog.invalidate();
        }
        for key in forget {
            if catalog.entries.get(key).and_then(located).is_some() {
                catalog.entries.remove(key);
            }
        }
        for (key, k, span) in moved {
            if let Some(entry) = catalog.entries.get_mut(&key) {
                entry.at = Location::Segment {
                    name: shared(&written[k].name),
                    span,
                };
            }
        }
        for new in written {
            catalog.segments.insert(
                new.name,
                catalog::SegmentState {
                    end: new.end,
                    modified: new.modified,
                    ..Default::default()
                },
            );
        }
        catalog.persist(&self.runs);
        Ok(())
    }

    /// A table of the study, beside its runs: `results/<study>/<name>`.
    pub fn table(&self, name: &str) -> PathBuf {
        self.runs.with_file_name(name)
    }

    /// The file of `key`'s record in the old layout of the store.
    #[cfg(test)]
    pub fn path(&self, key: &str) -> PathBuf {
        self.runs.join(format!("{key}.json"))
    }

    /// The scratch file `name` (one of `SCRATCH`) of a run of `key`.
    pub fn scratch(&self, key: &str, name: &str) -> PathBuf {
        self.work_dir().join(format!("{key}.{name}"))
    }

    /// Where a run whose case sets `vtk_every` writes its VTK frames: `results/<study>/fields/<key>/`.
    pub fn fields(&self, key: &str) -> PathBuf {
        self.table("fields").join(key)
    }

    /// The ends of L_h's spectra the study's runs share (`nlsolve run --spectra`): one entry
    /// per operator, `results/<study>/spectra/`.
    pub fn spectra(&self) -> PathBuf {
        self.table("spectra")
    }

    /// Scratch space of runs in progress (case files, captured output).
    pub fn work_dir(&self) -> PathBuf {
        self.runs.join(".work")
    }

    /// Stores `record` as the record of `key`, unless it is `failed` and the stored one is a
    /// result (`ok`, `diverged`): a run's fault does not erase what an earlier run computed.
    /// Returns whether it was stored. Call it holding the key's lock (`lock`), after `status`
    /// read the key's record since: it reads the catalog as last read, not the store again.
    /// A stored result, or a record made by another solver (another fingerprint), is not
    /// overwritten: it moves to the study's history first (`history/<key>.<fingerprint>.json`,
    /// see `history_path`), so nothing computed is lost and old and new can be compared.
    pub fn save(&self, key: &str, record: &Stored) -> Result<bool, FileError> {
        let failed = record.status() == Status::Failed;
        // The key is this process's (`lock`) since `status` read the store: no other process
        // has stored it since, so the catalog as last read knows its record.
        let stored = self.stored_text(key, false);
        let result_stored = stored
            .as_ref()
            .is_some_and(|(s, _, _)| s.status() != Status::Failed);
        if failed && result_stored {
            return Ok(false);
        }
        if let Some((stored, text, _)) = &stored {
            let old = fingerprint_of(stored);
            if result_stored || old != fingerprint_of(record) {
                let history = self.table("history");
                create_dir(&history)?;
                write_atomically(&history_path(&history, key, old), text.as_bytes())?;
            }
        }
        let body = record.to_value().to_string();
        let indexed = read_indexed(None, &body).map_err(|problem| {
            FileError::new("store", &self.runs, std::io::Error::other(problem))
        })?;
        self.append(&[(body, indexed)], false)?;
        // A record of the old layout is superseded: its file goes (history has it if it was
        // a result).
        if let Some((_, _, Location::File(path))) = stored {
            let _ = std::fs::remove_file(path);
        }
        Ok(true)
    }

    /// The status of the stored record of `key`, as last read; `None` when absent.
    pub fn status(&self, key: &str) -> Option<Status> {
        Some(self.catalog(false).as_ref()?.get(key)?.status)
    }

    /// The stored record of `key`, read now, if whole.
    pub fn stored(&self, key: &str) -> Option<Stored> {
        Some(self.stored_text(key, true)?.0)
    }

    /// The stored records of `keys` after one look at what the store gained (not one a key),
    /// each read and parsed once a process: a search's every round asks again for the records
    /// of all its rounds before (the stability map's driver, about 10⁵ of them over its rounds).
    /// A record stored again lies elsewhere, and is read again.
    pub fn stored_shared<'k>(
        &self,
        keys: impl IntoIterator<Item = &'k str>,
    ) -> Vec<Option<Arc<Stored>>> {
        drop(self.catalog(false));
        keys.into_iter().map(|key| self.parsed(key)).collect()
    }

    fn parsed(&self, key: &str) -> Option<Arc<Stored>> {
        let at = self.catalog_as_read().as_ref()?.get(key)?.at.clone();
        let lock = || self.parsed.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((was, stored)) = lock().get(key) {
            if *was == at {
                return Some(stored.clone());
            }
        }
        let (stored, _, at) = self.stored_text(key, false)?;
        let stored = Arc::new(stored);
        lock().insert(key.to_string(), (at, stored.clone()));
        Some(stored)
    }

    /// The stored record of `key` where the catalog last saw it (without looking for what
    /// others stored since), if whole.
    pub fn stored_as_read(&self, key: &str) -> Option<Stored> {
        Some(self.stored_text(key, false)?.0)
    }

    /// The stored record of `key`, its text and where it lies, as the catalog knows it after
    /// reading what the store gained since (`refresh`), or as last read.
    fn stored_text(&self, key: &str, refresh: bool) -> Option<(Stored, String, Location)> {
        self.stored_text_once(key, refresh).or_else(|| {
            // A frame that is not its key's whole record: the catalog is read again.
            let cataloged = self.catalog_as_read().as_ref()?.get(key).is_some();
            cataloged.then(|| self.reread_catalog())?;
            self.stored_text_once(key, false)
        })
    }

    fn stored_text_once(&self, key: &str, refresh: bool) -> Option<(Stored, String, Location)> {
        let at = match refresh {
            true => self.catalog(false).as_ref()?.get(key)?.at.clone(),
            false => self.catalog_as_read().as_ref()?.get(key)?.at.clone(),
        };
        let text = match &at {
            Location::Segment { name, span } => {
                String::from_utf8(segment::read_frame(&self.segments().join(&**name), span)?)
                    .ok()?
            }
            Location::File(path) => read_regular(path, RECORD_CAP).ok()?,
        };
        Some((check_identity(key, &text).ok()?, text, at))
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

    /// Removes the checkpoint of `key`: its file and, over ranks, the other ranks' files beside
    /// it (`<key>.checkpoint.rank<r>`). Call it holding the key's lock.
    pub fn remove_checkpoint(&self, key: &str) {
        let first = format!("{key}.{CHECKPOINT}");
        let others = format!("{first}.rank");
        remove_where(&self.work_dir(), |name| {
            name == first || name.starts_with(&others)
        });
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
        // A checkpoint's partial file, left by a solver killed while writing it
        // (`schema::atomic::partial_path`: `.<name>.<pid>.partial`).
        let partial = format!(".{key}.{CHECKPOINT}.");
        remove_where(&work, |name| {
            name.starts_with(&partial) && name.ends_with(".partial")
        });
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

    /// Every stored record (the latest of each key, in key order), and what the store holds that
    /// is not a whole record.
    pub fn scan(&self) -> Scan {
        let mut scan = self.scan_map(|record| record);
        scan.records.sort_unstable_by(|a, b| a.key.cmp(&b.key));
        scan
    }

    /// `scan`, each record made into what `make` keeps of it as it is read (in no order), so
    /// that a reader of every record need not hold them all. The segments are read one at a
    /// time, their records parsed on every core.
    /// Where a frame the catalog pointed at is not a whole record of its key, the segments are
    /// read again and so is the store.
    pub fn scan_map<T: Send>(&self, make: impl Fn(Stored) -> T + Sync) -> Scan<T> {
        let scan = self.scan_once(&make);
        if scan.found_now == 0 {
            return scan;
        }
        self.reread_catalog();
        self.scan_once(&make)
    }

    /// `scan_map` through the catalog as it stands.
    fn scan_once<T: Send>(&self, make: &(impl Fn(Stored) -> T + Sync)) -> Scan<T> {
        let (mut by_segment, files, unreadable) = {
            let guard = self.catalog(true);
            let catalog = guard.as_ref().expect("loaded");
            let mut by_segment: std::collections::BTreeMap<
                Shared,
                Vec<(String, std::ops::Range<u64>)>,
            > = Default::default();
            let mut files = Vec::new();
            for (key, entry) in catalog.latest() {
                match &entry.at {
                    Location::Segment { name, span } => by_segment
                        .entry(name.clone())
                        .or_default()
                        .push((key.to_string(), span.clone())),
                    Location::File(path) => files.push((key.to_string(), path.clone())),
                }
            }
            (by_segment, files, catalog.unreadable(&self.runs))
        };
        let known_unreadable = unreadable.len();
        let mut scan = Scan {
            records: Vec::new(),
            unreadable,
            found_now: 0,
        };
        let dir = self.segments();
        for (name, frames) in std::mem::take(&mut by_segment) {
            let path = dir.join(&*name);
            let bytes = segment::read_from(&path, 0).unwrap_or_default();
            let read: Vec<Result<T, Unreadable>> = frames
                .into_par_iter()
                .map(|(key, span)| {
                    record_in(&key, segment::body_at(&bytes, &span))
                        .map(make)
                        .map_err(|problem| Unreadable {
                            path: path.clone(),
                            at: Some(span),
                            problem,
                        })
                })
                .collect();
            scan.take(read);
        }
        let read: Vec<Result<T, Unreadable>> = files
            .into_par_iter()
            .map(|(_, path)| {
                read_regular(&path, RECORD_CAP)
                    .and_then(|t| read_record(&path, &t))
                    .map(make)
                    .map_err(|problem| Unreadable {
                        path,
                        at: None,
                        problem,
                    })
            })
            .collect();
        scan.take(read);
        scan.found_now = scan.unreadable.len() - known_unreadable;
        scan
    }

    /// The stored record of each of `keys`, made into what `make` keeps of it (given the key's
    /// place in `keys`), on every core; `None` where a key has none. Each segment is opened
    /// once and only its frames of `keys` are read, so a reader that takes the store a slice of
    /// keys at a time holds one slice. The catalog is a cache: where a frame it points at is
    /// not a whole record of its key, every segment is read again and those keys are looked
    /// for where the segments have them; what is still not a whole record is reported as
    /// `scan_map` reports it.
    pub fn read_each<T: Send>(
        &self,
        keys: &[&str],
        make: impl Fn(usize, Stored) -> T + Sync,
    ) -> (Vec<Option<T>>, Vec<Unreadable>) {
        let all: Vec<usize> = (0..keys.len()).collect();
        let mut made: Vec<Option<T>> = (0..keys.len()).map(|_| None).collect();
        let mut failed = self.read_at(keys, &all, &make, &mut made);
        if !failed.is_empty() {
            self.reread_catalog();
            let again: Vec<usize> = failed.iter().map(|(i, _)| *i).collect();
            failed = self.read_at(keys, &again, &make, &mut made);
        }
        (made, failed.into_iter().map(|(_, e)| e).collect())
    }

    /// `read_each` of the keys at `which`, once, where the catalog puts them: what it made goes
    /// into `made`; returns the places whose frames were not whole records of their keys.
    fn read_at<T: Send>(
        &self,
        keys: &[&str],
        which: &[usize],
        make: &(impl Fn(usize, Stored) -> T + Sync),
        made: &mut [Option<T>],
    ) -> Vec<(usize, Unreadable)> {
        let places: Vec<Option<Location>> = {
            // (Brought up to date: a compaction since the last slice moved the records.)
            let guard = self.catalog(false);
            let catalog = guard.as_ref().expect("loaded");
            which
                .iter()
                .map(|&i| Some(catalog.get(keys[i])?.at.clone()))
                .collect()
        };
        let dir = self.segments();
        let mut open: HashMap<Shared, Option<File>> = HashMap::new();
        for place in places.iter().flatten() {
            if let Location::Segment { name, .. } = place {
                open.entry(name.clone())
                    .or_insert_with(|| fs::open_regular(&dir.join(&**name)).ok().map(|f| f.0));
            }
        }
        let read: Vec<Option<Result<T, Unreadable>>> = (places.into_par_iter().zip(which))
            .map(|(place, &i)| {
                let (stored, path, at) = match place? {
                    Location::Segment { name, span } => {
                        let body = (open.get(&name)?.as_ref())
                            .and_then(|file| segment::read_frame_of(file, &span));
                        let stored = record_in(keys[i], body.as_deref());
                        (stored, dir.join(&*name), Some(span))
                    }
                    Location::File(path) => {
                        let text = read_regular(&path, RECORD_CAP);
                        (text.and_then(|t| check_identity(keys[i], &t)), path, None)
                    }
                };
                Some(
                    stored
                        .map(|stored| make(i, stored))
                        .map_err(|problem| Unreadable { path, at, problem }),
                )
            })
            .collect();
        let mut failed = Vec::new();
        for (read, &i) in read.into_iter().zip(which) {
            match read {
                Some(Ok(one)) => made[i] = Some(one),
                Some(Err(e)) => failed.push((i, e)),
                None => {}
            }
        }
        failed
    }

    /// Reads every segment again, now: a frame the catalog pointed at was not a whole record
    /// of its key (the catalog is a cache, never the truth).
    fn reread_catalog(&self) {
        let mut guard = self.catalog.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(catalog) = guard.as_mut() {
            catalog.invalidate();
            catalog.unsaved |= catalog.refresh(&self.runs);
            catalog.persist(&self.runs);
        }
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
                Err(problem) => scan.unreadable.push(Unreadable {
                    path,
                    at: None,
                    problem,
                }),
            }
        }
        scan
    }

    /// What the stored records say, from the catalog: the status of each key and the solver
    /// version each case id was run with. What is not a whole record is reported, and its point
    /// counts as not run.
    pub fn index(&self) -> Index {
        let guard = self.catalog(true);
        let catalog = guard.as_ref().expect("loaded");
        let mut index = Index {
            unreadable: catalog.unreadable(&self.runs),
            ..Index::default()
        };
        for (key, entry) in catalog.latest() {
            if let Some(id) = &entry.case_id {
                index
                    .version_by_case
                    .insert(id.clone(), entry.solver_version.clone());
            }
            index.noisy += usize::from(entry.noisy);
            if let Some(message) = &entry.failure {
                index.failed.push((key.to_string(), message.clone()));
            }
            index.stored.insert(
                key.to_string(),
                Recorded {
                    status: entry.status,
                    fingerprint: entry.fingerprint.clone(),
                    wall_s: entry.wall_s,
                },
            );
        }
        index.failed.sort();
        index
    }

    /// The sequence number of each key's latest record (0 when none is stored): what changes
    /// when a record is stored, replaced or lost.
    pub fn sequence_numbers(&self, keys: &[&str]) -> Vec<u64> {
        let guard = self.catalog(false);
        let catalog = guard.as_ref().expect("loaded");
        keys.iter()
            .map(|key| catalog.get(key).map_or(0, |e| e.seq))
            .collect()
    }

    /// How many stored records (the latest of each key) are of none of `keys`.
    pub fn count_besides(&self, keys: &std::collections::HashSet<&str>) -> usize {
        let guard = self.catalog(false);
        let catalog = guard.as_ref().expect("loaded");
        catalog.latest_keys().filter(|k| !keys.contains(k)).count()
    }

    /// How many records the store holds (the latest of each key), and what it holds that is not
    /// a whole record: what a scan would read.
    pub fn count(&self) -> usize {
        let guard = self.catalog(false);
        let catalog = guard.as_ref().expect("loaded");
        catalog.latest_keys().count() + catalog.unreadable(&self.runs).len()
    }
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

/// The record of `key` in the body of its segment's frame, as read (`None`: the frame is no
/// longer whole where the catalog says it lies).
fn record_in(key: &str, body: Option<&[u8]>) -> Result<Stored, String> {
    let body = body.ok_or("it changed since it was read")?;
    check_identity(key, std::str::from_utf8(body).map_err(|e| e.to_string())?)
}

/// Records by their key.
pub fn by_key(records: Vec<Stored>) -> HashMap<String, Stored> {
    records.into_iter().map(|r| (r.key.clone(), r)).collect()
}

/// The file whose bytes are the keys' locks, in the work directory.
const KEY_LOCKS: &str = "keys.lock";

/// The byte of `KEY_LOCKS` that locks `key`: its 64-bit FNV-1a hash within 62 bits (a lock's
/// offset is a signed 64-bit number); two keys share a byte once in 10¹⁸ pairs, when one waits.
fn key_byte(key: &str) -> i64 {
    let mut hash = fnv::FnvHasher::default();
    std::hash::Hasher::write(&mut hash, key.as_bytes());
    (std::hash::Hasher::finish(&hash) >> 2) as i64
}

/// The checkpoint of a point run as a process (`<key>.checkpoint` in the work directory): kept
/// when a run stops, so that the next one resumes it; the solver removes it with its record.
pub const CHECKPOINT: &str = "checkpoint";

/// How far a running case is, from its progress file (`<key>.progress`, which nlsolve's
/// `integrate::progress` writes).
pub struct Progress {
    /// What the running case last said (`schema::protocol::Progress`).
    pub said: schema::protocol::Progress,
    /// How long ago it said it: the case writes it each second it makes progress, so a long
    /// silence is a case stopped (SIGSTOP) or starved of its cores.
    pub silent_s: f64,
}

impl Progress {
    /// `step 930 of 3388`, or `iteration 30 of about 46`.
    pub fn steps_done(&self) -> String {
        let said = &self.said;
        match said.unit {
            ProgressUnit::Step => format!("step {} of {}", said.step, said.steps),
            ProgressUnit::Iteration => format!("iteration {} of about {}", said.step, said.steps),
        }
    }

    /// `~S s left`, or, after a silence of more than a few seconds, that it is not heard from.
    pub fn left(&self) -> String {
        match self.silent_s > SILENCE_S {
            true => format!(
                "no progress for {:.0} s (stopped, or starved of its cores)",
                self.silent_s
            ),
            false => format!("about {:.0} s left", self.said.left_s),
        }
    }
}

/// How long a running case may say nothing before `Progress::left` says so: it writes its
/// progress at most once a second.
const SILENCE_S: f64 = 5.0;

pub fn progress_of(path: &Path) -> Option<Progress> {
    let (file, _) = fs::open_regular(path).ok()?;
    let modified = file.metadata().ok()?.modified().ok()?;
    let text = fs::read_regular(path, 4096).ok()?;
    Some(Progress {
        said: serde_json::from_str(&text).ok()?,
        silent_s: modified.elapsed().map_or(0.0, |d| d.as_secs_f64()),
    })
}

/// How far the stopped run of the case `canonical` over `ranks` ranks got, as its checkpoint at
/// `path` says, read as the solver `fingerprint` reads it (`schema::checkpoint`: a regular file
/// within the case's cap, whole under its checksum, of this build and case): `Ok` with the step
/// it was taken at and the run's steps in all, when the next run resumes from it; `Err` with why
/// the next run starts afresh instead; `None` when there is none.
pub fn checkpoint_of(
    path: &Path,
    canonical: &Value,
    ranks: usize,
    fingerprint: Option<&str>,
) -> Option<Result<(u64, Option<u64>), String>> {
    use schema::checkpoint::{most_bytes, read, Identity};
    let cap = schema::case::Case::parse(canonical.clone()).map_or(u64::MAX, |c| most_bytes(&c));
    let checkpoint = match read(path, cap) {
        Ok(checkpoint) => checkpoint?,
        Err(why) => return Some(Err(why)),
    };
    let header = checkpoint.header;
    let ours = Identity {
        fingerprint: fingerprint.unwrap_or_default().to_string(),
        case: Identity::case_text(canonical),
        ranks,
        rank: 0,
    };
    if let Some(why) = ours.refuses(&header.identity) {
        return Some(Err(why));
    }
    Some(Ok((header.step as u64, header.steps.map(|s| s as u64))))
}

/// The scratch files of a point run as a process (in the work directory, `<key>.<name>`): its
/// case, standard output and standard error, and how far its time loop is (`PROGRESS`, written
/// by a worker's case too).
pub const SCRATCH: [&str; 4] = ["case.json", "out", "err", PROGRESS];

/// The scratch file where a running case's time loop says how far it is (`nlsolve --progress`).
pub const PROGRESS: &str = "progress";

/// The segment `entry` lies in (`None`: a file of the old store).
fn located(entry: &catalog::Entry) -> Option<&str> {
    match &entry.at {
        Location::Segment { name, .. } => Some(&**name),
        Location::File(_) => None,
    }
}

pub struct Scan<T = Stored> {
    pub records: Vec<T>,
    pub unreadable: Vec<Unreadable>,
    /// How many of `unreadable` (the last ones) this scan found: frames the catalog counted as
    /// records, which changed since.
    pub found_now: usize,
}

impl<T> Default for Scan<T> {
    fn default() -> Self {
        Scan {
            records: Vec::new(),
            unreadable: Vec::new(),
            found_now: 0,
        }
    }
}

impl<T> Scan<T> {
    /// Adds what was read: the whole records, and what is not one.
    fn take(&mut self, read: Vec<Result<T, Unreadable>>) {
        for record in read {
            match record {
                Ok(record) => self.records.push(record),
                Err(unreadable) => self.unreadable.push(unreadable),
            }
        }
    }
}

#[derive(Default)]
pub struct Index {
    /// What each whole record says, by key.
    pub stored: KeyMap<Recorded>,
    pub version_by_case: KeyMap<Shared>,
    pub unreadable: Vec<Unreadable>,
    /// Failed records, by key in name order, with the first line of their message.
    pub failed: Vec<(String, String)>,
    /// Records whose provenance says they were timed on a busy machine.
    pub noisy: usize,
}

#[cfg(test)]
mod tests;
