//! The timeline of each `nlstudy run`: `results/<study>/timeline/<run id>.jsonl`, one JSON line
//! per event, written as the pool runs (so a killed run keeps what it saw) and read by
//! `status --timeline` and `report`. Times are seconds since the epoch of the host that ran the
//! pool (one process: one clock, whichever nodes its workers ran on).
//!
//! A file is this tool's own: created new (never through a link or over another file), read
//! only when regular, and a line that does not parse (the last one of a killed run) is skipped.

use super::fs::{create_dir, read_regular, FileError};
use super::Store;
use serde::{Deserialize, Serialize};
use std::io::{BufWriter, Write};
use std::path::PathBuf;

/// One event of a run's pool.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum Event {
    /// A batch of cases the pool was given (a study, a round of a search) and when it ended.
    Batch { begin: f64, end: f64 },
    /// A case on a worker's lane: started (sent to a worker or its process spawned), answered
    /// (its record heard), saved (stored). `fresh`: its worker or process started for it, so
    /// the time before its solver's own is the start's. The solver's phases where it ran.
    Case {
        node: String,
        lane: usize,
        key: String,
        started: f64,
        answered: f64,
        saved: f64,
        fresh: bool,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        phases: Option<Phases>,
    },
    /// A lane with nothing to run while its batch went on.
    Idle {
        node: String,
        lane: usize,
        from: f64,
        to: f64,
    },
}

/// What a run's record says its solver spent: set-up, time loop, and its whole wall time (the
/// rest of which is the spectrum's ends and the errors measured after the loop).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Phases {
    pub setup_s: f64,
    pub solve_s: f64,
    pub wall_s: f64,
}

/// The events of one run, and its file's name (the run's id).
pub struct RunTimeline {
    pub run: String,
    pub events: Vec<Event>,
}

impl RunTimeline {
    /// The run's batches, (begin, end), by their begin.
    pub fn batches(&self) -> Vec<(f64, f64)> {
        let mut batches: Vec<(f64, f64)> = self
            .events
            .iter()
            .filter_map(|e| match e {
                Event::Batch { begin, end } => Some((*begin, *end)),
                _ => None,
            })
            .collect();
        batches.sort_by(|a, b| a.0.total_cmp(&b.0));
        batches
    }
}

/// Where a study's timelines are.
pub fn dir(store: &Store) -> PathBuf {
    store.table("timeline")
}

/// A run's timeline being written.
pub struct Writer {
    out: BufWriter<std::fs::File>,
    path: PathBuf,
}

impl Writer {
    /// A new timeline file in `dir` (a study's, `dir`) for the run `run_id` (unique: host,
    /// start and process id).
    pub fn create(dir: &std::path::Path, run_id: &str) -> Result<Writer, FileError> {
        create_dir(dir)?;
        let path = dir.join(format!("{run_id}.jsonl"));
        // O_CREAT | O_EXCL: never through a link, never over a file already there.
        let file = std::fs::File::options()
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(FileError::on("create", &path))?;
        Ok(Writer {
            out: BufWriter::new(file),
            path,
        })
    }

    pub fn write(&mut self, event: &Event) -> Result<(), FileError> {
        let line = serde_json::to_string(event).expect("an event serializes");
        writeln!(self.out, "{line}").map_err(FileError::on("write", &self.path))
    }

    /// Writes what is buffered: at a batch's end, so a run killed later keeps it.
    pub fn flush(&mut self) -> Result<(), FileError> {
        self.out.flush().map_err(FileError::on("write", &self.path))
    }
}

/// The runs whose timelines `status --timeline` shows, and `clean` keeps (a round of a
/// cluster's jobs is one run each).
pub const LATEST: usize = 8;

/// The largest timeline read: about 400 bytes an event, a million events.
const TIMELINE_CAP: u64 = 512 << 20;

/// The study's latest `last` run timelines, oldest first (by the start in their names, so across
/// hosts), each with the events that parse, and how many runs left timelines in all. Only those
/// are read: each run of a study adds one. Files that cannot be read are skipped with a warning.
pub fn latest(store: &Store, last: usize) -> (usize, Vec<RunTimeline>) {
    let names = by_start(store);
    let all = names.len();
    let runs = names[all.saturating_sub(last)..]
        .iter()
        .filter_map(|(path, name)| {
            let text = read_regular(path, TIMELINE_CAP)
                .inspect_err(|e| log::warn!("the timeline {} is not read: {e}", path.display()))
                .ok()?;
            let events = text
                .lines()
                .filter_map(|line| serde_json::from_str(line).ok())
                .collect();
            Some(RunTimeline {
                run: name.clone(),
                events,
            })
        })
        .collect();
    (all, runs)
}

/// The study's timeline files and their run ids, oldest first (by the start in their names).
fn by_start(store: &Store) -> Vec<(PathBuf, String)> {
    let Ok(entries) = std::fs::read_dir(dir(store)) else {
        return Vec::new();
    };
    let mut names: Vec<(PathBuf, String)> = entries
        .flatten()
        .filter_map(|entry| {
            let name = entry
                .file_name()
                .to_str()?
                .strip_suffix(".jsonl")?
                .to_string();
            Some((entry.path(), name))
        })
        .collect();
    names.sort_by_key(|(_, name)| started_ns(name));
    names
}

/// Removes the study's timelines but its latest `keep` (each run adds one, about 5 MB for the
/// stability map's): only regular files named as a run names them (`<host>-<start>-<pid>.jsonl`),
/// never through a link. Returns how many went and their bytes.
pub fn remove_older(store: &Store, keep: usize) -> (usize, u64) {
    let names = by_start(store);
    let older = &names[..names.len().saturating_sub(keep)];
    let (mut removed, mut bytes) = (0, 0);
    for (path, name) in older {
        let own = started_ns(name) > 0 && name.rsplit('-').next().is_some_and(is_number);
        let Ok(meta) = std::fs::symlink_metadata(path) else {
            continue;
        };
        if own && meta.is_file() && std::fs::remove_file(path).is_ok() {
            removed += 1;
            bytes += meta.len();
        }
    }
    (removed, bytes)
}

fn is_number(text: &str) -> bool {
    !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit())
}

/// A run id's start in nanoseconds (`<host>-<start>-<pid>`), for ordering runs of any host.
fn started_ns(run: &str) -> u128 {
    let mut parts = run.rsplitn(3, '-');
    let _pid = parts.next();
    parts.next().and_then(|s| s.parse().ok()).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_written_are_read_back_and_a_torn_last_line_is_skipped() {
        let scratch = tempfile::tempdir().unwrap();
        let store = Store::open(scratch.path(), "s");
        let mut writer = Writer::create(&dir(&store), "host-200-7").unwrap();
        let case = Event::Case {
            node: "n1".into(),
            lane: 0,
            key: "k".into(),
            started: 1.0,
            answered: 2.0,
            saved: 2.5,
            fresh: true,
            phases: Some(Phases {
                setup_s: 0.1,
                solve_s: 0.5,
                wall_s: 0.9,
            }),
        };
        let batch = Event::Batch {
            begin: 0.5,
            end: 3.0,
        };
        writer.write(&case).unwrap();
        writer.write(&batch).unwrap();
        writer.flush().unwrap();
        drop(writer);
        let path = dir(&store).join("host-200-7.jsonl");
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("{\"event\":\"idle\",\"node\":");
        std::fs::write(&path, text).unwrap();
        Writer::create(&dir(&store), "other-100-9").unwrap();
        let (all, runs) = latest(&store, 2);
        assert_eq!((all, runs.len()), (2, 2));
        assert_eq!(
            latest(&store, 1).1[0].run,
            "host-200-7",
            "only the latest read"
        );
        assert_eq!(runs[0].run, "other-100-9", "the earlier start first");
        assert_eq!(runs[1].events, vec![case, batch]);
        assert!(
            Writer::create(&dir(&store), "host-200-7").is_err(),
            "never over a file already there"
        );
    }

    /// `clean`'s rule: the latest timelines stay, older ones go; a file that is no run's
    /// timeline (another name, a link to one) stays whatever its age.
    #[test]
    fn older_timelines_go_and_the_latest_and_what_is_not_a_timeline_stay() {
        let scratch = tempfile::tempdir().unwrap();
        let store = Store::open(scratch.path(), "s");
        for start in 1..=5 {
            let mut writer = Writer::create(&dir(&store), &format!("host-{start}00-7")).unwrap();
            writer
                .write(&Event::Batch {
                    begin: 0.0,
                    end: 1.0,
                })
                .unwrap();
            writer.flush().unwrap();
        }
        let notes = dir(&store).join("notes.jsonl");
        std::fs::write(&notes, "mine").unwrap();
        let link = dir(&store).join("host-50-7.jsonl");
        std::os::unix::fs::symlink(dir(&store).join("host-500-7.jsonl"), &link).unwrap();
        let (removed, bytes) = remove_older(&store, 2);
        assert_eq!(removed, 3);
        assert_eq!(bytes, 3 * 40);
        let mut left: Vec<String> = std::fs::read_dir(dir(&store))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                "host-400-7.jsonl",
                "host-50-7.jsonl",
                "host-500-7.jsonl",
                "notes.jsonl"
            ]
        );
    }
}
