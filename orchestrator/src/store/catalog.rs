//! The catalog: where the latest record of each key lies and what `plan` and `status` need of
//! it, so that they read one file instead of every record (`runs/segments/catalog`).
//!
//! It is a cache of the segments, never the truth: each segment's entry says how far it was
//! read, so a reader reads only what was appended since; a segment gone or shorter than read
//! (compacted away, cut by hand) makes it read every segment again, and a catalog that cannot
//! be read is rebuilt. Records of the old store, one file per key (`runs/<key>.json`), are read
//! beside it until a writer moves them into a segment (`Store::migrate`).

use super::fs::modified_ns;
use super::record::{listing, read_indexed, Indexed, Unreadable};
use super::segment::{self, Frame};
use super::shared::{shared, Shared};
use rayon::prelude::*;
use schema::record::Status;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The catalog's file, among the segments (its name has no `.seg`).
pub const FILE: &str = "catalog";
/// Bumped when what the catalog holds changes: an older one is rebuilt. (4: records indexed only
/// when they read whole as the typed record, and the file under a checksum.)
const FORMAT: u32 = 4;

/// A map by record key (or case id): 10⁵–10⁶ of them in a plan, hashed fast (the keys are
/// hashes themselves, and the seed is random).
pub type KeyMap<V> = HashMap<String, V, foldhash::fast::RandomState>;

/// Where a record lies.
#[derive(Clone, Debug, PartialEq)]
pub enum Location {
    /// A frame of a segment (its name).
    Segment { name: Shared, span: Range<u64> },
    /// A file of the old store, `runs/<key>.json`.
    File(PathBuf),
}

/// What the catalog keeps of one whole record.
#[derive(Clone, Debug)]
pub struct Entry {
    pub at: Location,
    pub seq: u64,
    pub status: Status,
    /// The fingerprint of the solver that made it ("" when it does not say).
    pub fingerprint: Shared,
    pub wall_s: Option<f64>,
    pub case_id: Option<String>,
    pub solver_version: Shared,
    pub noisy: bool,
    /// The first line of a failed record's message.
    pub failure: Option<String>,
}

impl Entry {
    fn new(indexed: Indexed, at: Location, seq: u64) -> (String, Entry) {
        let entry = Entry {
            at,
            seq,
            status: indexed.stored.status,
            fingerprint: indexed.stored.fingerprint,
            wall_s: indexed.stored.wall_s,
            case_id: indexed.case_id,
            solver_version: shared(indexed.solver_version.as_deref().unwrap_or_default()),
            noisy: indexed.noisy,
            failure: indexed.failure,
        };
        (indexed.key, entry)
    }

    pub fn bytes(&self) -> u64 {
        match &self.at {
            Location::Segment { span, .. } => span.end - span.start,
            Location::File(_) => 0,
        }
    }
}

/// What was read of one segment.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct SegmentState {
    /// Where its whole frames (and reported corruption) end: reading resumes here.
    pub end: u64,
    /// Its modification time (ns) when it was last read: a segment of the same size and
    /// another time was written over in place (by hand, by a restore), and is read again.
    pub modified: i128,
    /// Bytes of frames a later frame of their key superseded: what compaction frees.
    pub superseded: u64,
    /// Byte ranges that are not whole frames.
    pub corrupt: Vec<Range<u64>>,
    /// Whole frames that are not whole records: where, and why.
    pub unreadable: Vec<(Range<u64>, String)>,
}

impl SegmentState {
    /// Whether all its bytes were read as records.
    pub fn clean(&self) -> bool {
        self.corrupt.is_empty() && self.unreadable.is_empty()
    }
}

#[derive(Default)]
pub struct Catalog {
    format: u32,
    pub segments: BTreeMap<String, SegmentState>,
    /// The latest record of each key among the segments.
    pub entries: KeyMap<Entry>,
    /// The old store's files, by key, as last read (with the modification time and size they
    /// had then, so an unchanged file is not read again).
    files: HashMap<PathBuf, (FileStamp, FileRead)>,
    /// Read news that the stored catalog lacks (a reader that does not persist found them):
    /// the next that may persist does.
    pub unsaved: bool,
    /// Names of `*.seg` that are no regular file, and what they are, as last listed.
    foreign: Vec<(String, String)>,
}

/// What a file of the old store was read as: its key and entry, or why it is not a record.
type FileRead = Result<(String, Entry), String>;

/// A file's size and modification time (ns), to tell whether it changed since it was read.
type FileStamp = (u64, i128);

impl Catalog {
    /// The catalog stored in `runs`, or an empty one (to be read from the segments) when there
    /// is none or it is not whole.
    pub fn load(runs: &Path) -> Catalog {
        let path = runs.join(segment::DIR).join(FILE);
        super::fs::read_regular(&path, 1 << 30)
            .ok()
            .and_then(|text| Persisted::read(&text))
            .filter(|p| p.head.format == FORMAT)
            .and_then(Persisted::into_catalog)
            .unwrap_or_default()
    }

    /// Stores the catalog whole or not at all. A failure (a read-only store, a full disk) only
    /// costs the next reader a longer read.
    pub fn persist(&mut self, runs: &Path) {
        let dir = runs.join(segment::DIR);
        if !dir.is_dir() {
            return;
        }
        if let Ok(text) = Persisted::from_catalog(self).text() {
            self.unsaved &= super::fs::write_atomically(&dir.join(FILE), &text).is_err();
        }
    }

    /// Reads what was appended to the segments of `runs` since, and the old store's files;
    /// returns whether any segment had news.
    pub fn refresh(&mut self, runs: &Path) -> bool {
        let (listed, foreign) = listed(&runs.join(segment::DIR));
        self.foreign = foreign;
        self.refresh_as_listed(runs, listed)
    }

    /// `refresh` with the segments as `listed` (size and time of each), which may be behind the
    /// files: their writers go on appending.
    fn refresh_as_listed(&mut self, runs: &Path, listed: BTreeMap<String, FileStamp>) -> bool {
        let dir = runs.join(segment::DIR);
        // A segment shorter than what was read, changed at the same size, or grown where no
        // frame starts at the old end, was written over, not appended to: read everything anew.
        let stale = self.segments.iter().any(|(name, state)| {
            listed.get(name).is_none_or(|&(size, modified)| {
                size < state.end
                    || (size == state.end && modified != state.modified)
                    || (size > state.end
                        && state.end > 0
                        && !segment::frame_starts_at(&dir.join(name), state.end))
            })
        });
        if stale || self.format != FORMAT {
            self.segments.clear();
            self.entries.clear();
            self.format = FORMAT;
        }
        let mut news = stale;
        for (name, (size, modified)) in listed {
            let from = self.segments.get(&name).map_or(0, |s| s.end);
            if size > from {
                news |= self.read_segment(&dir, &name, from..size);
            }
            self.segments.entry(name).or_default().modified = modified;
        }
        self.read_files(runs);
        news
    }

    /// Reads the bytes `span` of segment `name`; whether they held anything new. The span ends
    /// at the size listed with the time kept for the segment: a frame its writer appended since
    /// is read next time, not now, or the segment would next be listed at the size read and a
    /// newer time, which says it was written over in place (and reads the whole store again:
    /// with 64 writers at once, their every refresh did).
    fn read_segment(&mut self, dir: &Path, name: &str, span: Range<u64>) -> bool {
        let (path, from) = (dir.join(name), span.start);
        let Ok(bytes) = segment::read_between(&path, span.start, span.end) else {
            return false;
        };
        let read = segment::read(&bytes, from);
        let parsed: Vec<(Frame, Result<Indexed, String>)> = read
            .frames
            .into_par_iter()
            .map(|frame| {
                let body =
                    &bytes[(frame.body.start - from) as usize..(frame.body.end - from) as usize];
                let indexed = std::str::from_utf8(body)
                    .map_err(|_| "not UTF-8 text".to_string())
                    .and_then(|text| read_indexed(None, text));
                (frame, indexed)
            })
            .collect();
        let news = !parsed.is_empty() || !read.corrupt.is_empty();
        let state = self.segments.entry(name.to_string()).or_default();
        state.end = read.end;
        state.corrupt.extend(read.corrupt);
        let mut superseded = Vec::new();
        for (frame, indexed) in parsed {
            let indexed = match indexed {
                Ok(indexed) => indexed,
                Err(problem) => {
                    let state = self.segments.get_mut(name).expect("entered above");
                    state.unreadable.push((frame.span, problem));
                    continue;
                }
            };
            let at = Location::Segment {
                name: shared(name),
                span: frame.span.clone(),
            };
            let (key, entry) = Entry::new(indexed, at, frame.seq);
            match self.entries.get(&key) {
                Some(old) if old.seq > entry.seq => superseded.push(entry),
                _ => {
                    if let Some(old) = self.entries.insert(key, entry) {
                        superseded.push(old);
                    }
                }
            }
        }
        for old in superseded {
            self.count_superseded(&old);
        }
        news
    }

    fn count_superseded(&mut self, old: &Entry) {
        if let Location::Segment { name, .. } = &old.at {
            if let Some(state) = self.segments.get_mut(&**name) {
                state.superseded += old.bytes();
            }
        }
    }

    /// Forgets what was read, so that the next refresh reads every segment again (a frame the
    /// catalog counted on turned out not whole).
    pub fn invalidate(&mut self) {
        self.format = 0;
    }

    /// Notes a frame this process appended (so it need not read it back).
    pub fn appended(&mut self, name: &str, frame: &Frame, indexed: Indexed) {
        let state = self.segments.entry(name.to_string()).or_default();
        if state.end == frame.span.start {
            state.end = frame.span.end;
        }
        let at = Location::Segment {
            name: shared(name),
            span: frame.span.clone(),
        };
        let (key, entry) = Entry::new(indexed, at, frame.seq);
        if let Some(old) = self.entries.insert(key, entry) {
            self.count_superseded(&old);
        }
    }

    /// Notes the modification time of a segment this process wrote last.
    pub fn written(&mut self, name: &str, modified: i128) {
        self.segments.entry(name.to_string()).or_default().modified = modified;
    }

    /// Reads the old store's record files (`runs/*.json` and whatever else is not hidden).
    fn read_files(&mut self, runs: &Path) {
        let mut files = std::mem::take(&mut self.files);
        let mut paths = listing(runs);
        paths.retain(|path| path.file_name().is_none_or(|n| n != segment::DIR));
        if paths.is_empty() {
            // The common case once a writer has moved the files: no threads woken per record.
            return;
        }
        let read: Vec<_> = paths
            .into_par_iter()
            .map(|path| {
                let stamp = stamp(&path);
                match files.get(&path) {
                    Some((known, _)) if Some(*known) == stamp => (path, None),
                    _ => {
                        let entry = super::fs::read_regular(&path, super::fs::RECORD_CAP)
                            .and_then(|text| read_indexed(Some(&path), &text))
                            .map(|indexed| {
                                let seq = stamp.map_or(0, |(_, ns)| ns.max(0) as u64);
                                Entry::new(indexed, Location::File(path.clone()), seq)
                            });
                        (path, Some((stamp.unwrap_or_default(), entry)))
                    }
                }
            })
            .collect();
        let mut now = HashMap::with_capacity(read.len());
        for (path, fresh) in read {
            let value = match fresh {
                Some(value) => value,
                None => files.remove(&path).expect("known above"),
            };
            now.insert(path, value);
        }
        self.files = now;
    }

    /// The latest record of each key, the old store's files included.
    pub fn latest(&self) -> HashMap<&str, &Entry, foldhash::fast::RandomState> {
        let mut latest: HashMap<&str, &Entry, _> =
            self.entries.iter().map(|(k, e)| (k.as_str(), e)).collect();
        for (key, entry) in self.files.values().filter_map(|(_, r)| r.as_ref().ok()) {
            match latest.get(key.as_str()) {
                Some(old) if old.seq > entry.seq => {}
                _ => {
                    latest.insert(key, entry);
                }
            }
        }
        latest
    }

    /// The keys `latest()` holds, without making it (a map of 10⁵–10⁶ to count them).
    pub fn latest_keys(&self) -> impl Iterator<Item = &str> {
        let mut seen = std::collections::HashSet::new();
        let files = (self.files.values())
            .filter_map(|(_, read)| Some(read.as_ref().ok()?.0.as_str()))
            .filter(move |key| !self.entries.contains_key(*key) && seen.insert(*key));
        self.entries.keys().map(String::as_str).chain(files)
    }

    /// The latest record of `key`.
    pub fn get(&self, key: &str) -> Option<&Entry> {
        let in_segment = self.entries.get(key);
        let in_file = self.files.values().find_map(|(_, r)| match r {
            Ok((k, e)) if k == key => Some(e),
            _ => None,
        });
        match (in_segment, in_file) {
            (Some(s), Some(f)) => Some(if f.seq > s.seq { f } else { s }),
            (s, f) => s.or(f),
        }
    }

    /// The old store's files that are whole records (to be moved into a segment).
    pub fn record_files(&self) -> Vec<&Path> {
        let mut paths: Vec<&Path> = self
            .files
            .iter()
            .filter(|(_, (_, r))| r.is_ok())
            .map(|(p, _)| p.as_path())
            .collect();
        paths.sort();
        paths
    }

    /// What is not a whole record: files of the old store, frames and bytes of segments.
    pub fn unreadable(&self, runs: &Path) -> Vec<Unreadable> {
        let dir = runs.join(segment::DIR);
        let mut found: Vec<Unreadable> = self
            .files
            .iter()
            .filter_map(|(path, (_, r))| match r {
                Err(problem) => Some(Unreadable {
                    path: path.clone(),
                    at: None,
                    problem: problem.clone(),
                }),
                Ok(_) => None,
            })
            .collect();
        for (name, what) in &self.foreign {
            found.push(Unreadable {
                path: dir.join(name),
                at: None,
                problem: format!("{what}; no segment is read through it"),
            });
        }
        for (name, state) in &self.segments {
            for range in &state.corrupt {
                found.push(Unreadable {
                    path: dir.join(name),
                    at: Some(range.clone()),
                    problem: "not whole frames: corrupt".into(),
                });
            }
            for (range, problem) in &state.unreadable {
                found.push(Unreadable {
                    path: dir.join(name),
                    at: Some(range.clone()),
                    problem: problem.clone(),
                });
            }
        }
        found.sort_by(|a, b| {
            (&a.path, a.at.as_ref().map(|r| r.start))
                .cmp(&(&b.path, b.at.as_ref().map(|r| r.start)))
        });
        found
    }
}

/// The catalog as its file holds it: a line of what the entries share, then a line per entry,
/// as an array, its segment, fingerprint and solver version as indices into the lists of the
/// first line (a 10⁵-record catalog: 15 MB, not 38). Lines, so that both cores read it.
struct Persisted {
    head: Head,
    entries: Vec<PersistedEntry>,
}

#[derive(Serialize, Deserialize)]
struct Head {
    format: u32,
    segments: BTreeMap<String, SegmentState>,
    fingerprints: Vec<String>,
    versions: Vec<String>,
    /// How many entry lines follow: a file cut short at a line's end is not whole either.
    entries: usize,
}

/// key, segment (its index among `segments`), start, end, seq, status, fingerprint, wall_s,
/// case id, solver version, noisy, failure.
#[derive(Serialize, Deserialize)]
struct PersistedEntry(
    String,
    usize,
    u64,
    u64,
    u64,
    Status,
    usize,
    Option<f64>,
    Option<String>,
    usize,
    bool,
    Option<String>,
);

impl Persisted {
    fn from_catalog(catalog: &Catalog) -> Persisted {
        let names: HashMap<&str, usize> = catalog
            .segments
            .keys()
            .enumerate()
            .map(|(k, n)| (n.as_str(), k))
            .collect();
        let mut fingerprints = Interned::default();
        let mut versions = Interned::default();
        let entries: Vec<PersistedEntry> = catalog
            .entries
            .iter()
            .filter_map(|(key, e)| {
                let Location::Segment { name, span } = &e.at else {
                    return None;
                };
                Some(PersistedEntry(
                    key.clone(),
                    *names.get(&**name)?,
                    span.start,
                    span.end,
                    e.seq,
                    e.status,
                    fingerprints.index(&e.fingerprint),
                    e.wall_s,
                    e.case_id.clone(),
                    versions.index(&e.solver_version),
                    e.noisy,
                    e.failure.clone(),
                ))
            })
            .collect();
        let head = Head {
            format: catalog.format,
            segments: catalog.segments.clone(),
            fingerprints: fingerprints.values,
            versions: versions.values,
            entries: entries.len(),
        };
        Persisted { head, entries }
    }

    /// The head's line, an entry's line each, then `crc32 <8 hex digits>` of all before it: a
    /// catalog changed by hand (an entry's span, its status) is no catalog, and is rebuilt from
    /// the segments.
    fn text(&self) -> serde_json::Result<Vec<u8>> {
        let mut text = serde_json::to_vec(&self.head)?;
        for entry in &self.entries {
            text.push(b'\n');
            serde_json::to_writer(&mut text, entry)?;
        }
        let crc = crc32fast::hash(&text);
        text.extend_from_slice(format!("\ncrc32 {crc:08x}").as_bytes());
        Ok(text)
    }

    /// What `text` holds; `None` unless its checksum matches and every line is whole.
    fn read(text: &str) -> Option<Persisted> {
        let (text, sum) = text.rsplit_once('\n')?;
        let crc = u32::from_str_radix(sum.strip_prefix("crc32 ")?, 16).ok()?;
        if crc32fast::hash(text.as_bytes()) != crc {
            return None;
        }
        let (head, entries) = text.split_once('\n').unwrap_or((text, ""));
        let entries = entries
            .par_lines()
            .map(|line| serde_json::from_str(line).ok());
        let persisted = Persisted {
            head: serde_json::from_str(head).ok()?,
            entries: entries.collect::<Option<_>>()?,
        };
        (persisted.entries.len() == persisted.head.entries).then_some(persisted)
    }

    /// The catalog, `None` when an index points nowhere.
    fn into_catalog(self) -> Option<Catalog> {
        let head = self.head;
        let names: Vec<Shared> = head.segments.keys().map(|n| shared(n)).collect();
        let fingerprints: Vec<Shared> = head.fingerprints.iter().map(|f| shared(f)).collect();
        let versions: Vec<Shared> = head.versions.iter().map(|v| shared(v)).collect();
        let mut entries = KeyMap::with_capacity_and_hasher(self.entries.len(), Default::default());
        for e in self.entries {
            let entry = Entry {
                at: Location::Segment {
                    name: names.get(e.1)?.clone(),
                    span: e.2..e.3,
                },
                seq: e.4,
                status: e.5,
                fingerprint: fingerprints.get(e.6)?.clone(),
                wall_s: e.7,
                case_id: e.8,
                solver_version: versions.get(e.9)?.clone(),
                noisy: e.10,
                failure: e.11,
            };
            entries.insert(e.0, entry);
        }
        Some(Catalog {
            format: head.format,
            segments: head.segments,
            entries,
            files: HashMap::new(),
            unsaved: false,
            foreign: Vec::new(),
        })
    }
}

/// Distinct strings, each stored once and named by its index.
#[derive(Default)]
struct Interned {
    values: Vec<String>,
    known: HashMap<String, usize>,
}

impl Interned {
    fn index(&mut self, value: &str) -> usize {
        if let Some(&k) = self.known.get(value) {
            return k;
        }
        self.values.push(value.to_string());
        self.known.insert(value.to_string(), self.values.len() - 1);
        self.values.len() - 1
    }
}

/// The segments of `dir` (regular files named `*.seg`), their sizes and modification times.
#[cfg(test)]
pub fn segments(dir: &Path) -> BTreeMap<String, FileStamp> {
    listed(dir).0
}

/// The segments of `dir`, and the names of `*.seg` there that are no regular file (a link, a
/// FIFO, a folder), which are not read: reported as what they are instead.
fn listed(dir: &Path) -> (BTreeMap<String, FileStamp>, Vec<(String, String)>) {
    let (mut segments, mut foreign) = (BTreeMap::new(), Vec::new());
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let Some(name) = entry.file_name().to_str().map(str::to_string) else {
            continue;
        };
        if !name.ends_with(segment::SUFFIX) || name.starts_with('.') {
            continue;
        }
        // The entry's own metadata: a link is not followed.
        let Ok(meta) = entry.metadata() else { continue };
        match meta.is_file() {
            true => {
                segments.insert(name, (meta.len(), modified_ns(&meta)));
            }
            false => {
                let what = match meta.file_type().is_symlink() {
                    true => "a symbolic link, which the store does not follow",
                    false => "not a regular file",
                };
                foreign.push((name, what.to_string()));
            }
        }
    }
    (segments, foreign)
}

fn stamp(path: &Path) -> Option<FileStamp> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    Some((meta.len(), modified_ns(&meta)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record_json;
    use std::time::{Duration, SystemTime};

    /// A frame of a whole record of the case `{"n": n}`.
    fn frame(n: u64) -> Vec<u8> {
        let case = serde_json::json!({ "n": n });
        let (_, key) = crate::store::case_id_and_key(&case.to_string(), "0.1.0", 0);
        let record = record_json(serde_json::json!({"key": key, "case": case,
            "solver_version": "0.1.0", "repeat": 0, "status": "ok", "message": "ok"}));
        segment::encode(n, record.to_string().as_bytes())
    }

    /// Another process appends to a segment between the catalog's listing of it and its read:
    /// the catalog reads up to the size listed, so that the time it keeps is that size's, and
    /// the next refresh reads the new frame as an append. (Reading to the file's end kept the
    /// older time with the larger size, and the next listing, at that size and a newer time,
    /// looked written over in place: the whole store read again, at each refresh of each of 64
    /// writers at once, 100 s for what took 18 s.)
    #[test]
    fn a_segment_grown_between_its_listing_and_its_read_is_read_as_listed() {
        let dir = tempfile::tempdir().unwrap();
        let segments = dir.path().join(segment::DIR);
        std::fs::create_dir(&segments).unwrap();
        let path = segments.join("a.seg");
        std::fs::write(&path, frame(1)).unwrap();
        let (as_listed, _) = listed(&segments);
        let first = as_listed["a.seg"];
        let mut file = std::fs::File::options().append(true).open(&path).unwrap();
        std::io::Write::write_all(&mut file, &frame(2)).unwrap();
        file.set_modified(SystemTime::now() + Duration::from_secs(1))
            .unwrap();
        let mut catalog = Catalog::default();
        assert!(catalog.refresh_as_listed(dir.path(), as_listed));
        let state = &catalog.segments["a.seg"];
        assert_eq!((state.end, state.modified), first, "read as listed");
        assert_eq!(catalog.entries.len(), 1);
        // The next refresh reads the new frame.
        assert!(catalog.refresh(dir.path()));
        assert_eq!(catalog.entries.len(), 2);
        let len = std::fs::metadata(&path).unwrap().len();
        assert_eq!(catalog.segments["a.seg"].end, len);
    }
}
