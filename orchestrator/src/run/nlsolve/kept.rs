//! The solver's verdicts on a study's cases, kept beside its store (`results/<study>/.verdicts`)
//! so that a plan asks `nlsolve check` only of the cases this solver build has not checked
//! before: at 10⁵ points the check was two thirds of a plan's CPU time, and every command plans.
//!
//! A verdict is the solver build's alone (a case's fields in; its canonical and resolved forms,
//! or the refusal, out), so the file is kept under the solver's version and fingerprint and
//! started afresh for another (a solver without a fingerprint keeps none). The one part of a
//! verdict that is the machine's is whether it could run the case (`machine`): the case's
//! threads and the memory it needs are kept, and a kept case is taken where it fits the machine
//! as `nlsolve machine` finds it now. One with more threads than the machine runs keeps the
//! solver's sentence with the most threads it was said of, and is taken where that has not
//! changed; any other is checked again, for the solver to say why (memory comes and goes).
//!
//! The file is only appended to, a line per verdict (and one per distinct resolution), each
//! with its CRC-32: a line cut short by a crash, or two writers' lines run together, fail their
//! check and are asked again. It holds every case this build was asked about, so it grows with
//! the study's distinct cases and starts over with each new build.

use super::{Checked, Resolved};
use crate::store::{shared, Shared};
use schema::protocol::{Machine, Needs};
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::io::{BufRead as _, Write as _};
use std::os::unix::fs::OpenOptionsExt as _;
use std::path::PathBuf;
use std::sync::Arc;

/// The first line: the format, then the solver's version and fingerprint.
const FORMAT: &str = "nlstudy verdicts 1";

/// The most a file of verdicts may hold (about 0.45 KB a case: some 4·10⁶ cases).
const CAP: u64 = 1 << 31;

/// A case's fields as `nlsolve check` reads them, hashed: what a verdict is kept under.
pub(super) type FieldsKey = [u8; 16];

/// A map by `FieldsKey` (or resolution id): hashed fast, for the 10⁵–10⁶ of a plan.
pub(super) type KeyMap<V> = HashMap<FieldsKey, V, foldhash::fast::RandomState>;

pub(super) fn fields_key(fields_line: &[u8]) -> FieldsKey {
    let digest = Sha256::digest(fields_line);
    digest[..16].try_into().expect("16 of 32 bytes")
}

/// `resources::fit` in the solver, on its numbers: the threads are checked first.
fn fit(needs: &Needs, offer: &Machine) -> Fit {
    if needs.threads > offer.most_threads {
        Fit::TooManyThreads
    } else if offer
        .available_bytes
        .is_some_and(|available| needs.bytes > available)
    {
        Fit::TooLittleMemory
    } else {
        Fit::Fits
    }
}

#[derive(PartialEq)]
enum Fit {
    Fits,
    TooManyThreads,
    TooLittleMemory,
}

/// The solver's sentence on a case with more threads than a machine runs, and that machine's
/// `most_threads`. (Shared: the sentence names only the case's threads and the machine's
/// cores, so most points of a study on many threads repeat one of a few.)
type Crowded = Option<(u64, Shared)>;

enum Verdict {
    Case {
        needs: Needs,
        crowded: Crowded,
        resolution: u64,
        /// Moved out to the first point that takes it (empty then; the entry stays, so the key
        /// is known to be kept).
        canonical: Box<str>,
    },
    Refused(String),
}

pub(super) struct Kept {
    path: PathBuf,
    /// `FORMAT`, version and fingerprint: the first line the file must have.
    header: String,
    /// The file is missing, unreadable or another solver's: it is written afresh.
    afresh: bool,
    /// The file's last line is cut short: what is appended starts on a line of its own.
    cut_short: bool,
    resolutions: HashMap<u64, Resolved, foldhash::fast::RandomState>,
    verdicts: KeyMap<Verdict>,
    /// Where what is kept goes (the file, or a fresh one beside it), once something is;
    /// `Err` after a write failed.
    out: Result<Option<std::io::BufWriter<std::fs::File>>, ()>,
}

/// A resolution's id: its kind and text, hashed.
fn resolution_id(resolved: &Resolved) -> u64 {
    let (kind, text) = kind_and_text(resolved);
    let digest = Sha256::new()
        .chain_update(kind)
        .chain_update(text)
        .finalize();
    u64::from_le_bytes(digest[..8].try_into().expect("8 of 32 bytes"))
}

fn kind_and_text(resolved: &Resolved) -> (&'static str, &str) {
    match resolved {
        Resolved::Adds(adds) => ("A", adds),
        Resolved::Whole(whole) => ("W", whole),
    }
}

impl Kept {
    /// The verdicts kept at `path` for this solver (`version`, `fingerprint`); none where the
    /// file is missing or another solver's.
    pub fn load(path: PathBuf, version: &str, fingerprint: &str) -> Kept {
        let header = format!("{FORMAT}\t{version}\t{fingerprint}");
        let mut kept = Kept {
            path,
            header,
            afresh: true,
            cut_short: false,
            resolutions: HashMap::default(),
            verdicts: KeyMap::default(),
            out: Ok(None),
        };
        let Ok((file, length)) = crate::store::fs::open_regular(&kept.path) else {
            return kept;
        };
        if length > CAP {
            return kept;
        }
        let mut file = std::io::BufReader::with_capacity(1 << 16, file);
        let mut line = String::new();
        if file.read_line(&mut line).is_err() || line.trim_end_matches('\n') != kept.header {
            return kept;
        }
        kept.afresh = false;
        loop {
            line.clear();
            match file.read_line(&mut line) {
                Ok(0) => break,
                Ok(_) => {}
                // (Not UTF-8: that line is lost, the rest read on.)
                Err(e) if e.kind() == std::io::ErrorKind::InvalidData => continue,
                Err(_) => break,
            }
            kept.cut_short = !line.ends_with('\n');
            // A case whose resolution is not read yet (two writers' lines interleaved) is lost,
            // and asked again.
            match checked_line(&line) {
                Some(("R", rest)) => kept.read_resolution(rest),
                Some(("C", rest)) => kept.read_case(rest),
                Some(("E", rest)) => kept.read_refusal(rest),
                _ => None,
            };
        }
        kept
    }

    /// A resolution, once per id: its id is its text's hash, so the points that share it
    /// share one text.
    fn read_resolution(&mut self, rest: &str) -> Option<()> {
        let (id, rest) = rest.split_once('\t')?;
        let (kind, text) = rest.split_once('\t')?;
        let resolved = match kind {
            "A" => Resolved::Adds(Arc::from(text)),
            "W" => Resolved::Whole(text.into()),
            _ => return None,
        };
        self.resolutions
            .insert(u64::from_str_radix(id, 16).ok()?, resolved);
        Some(())
    }

    fn read_case(&mut self, rest: &str) -> Option<()> {
        let mut fields = rest.splitn(6, '\t');
        let key = parse_key(fields.next()?)?;
        let threads = fields.next()?.parse().ok()?;
        let bytes = fields.next()?.parse().ok()?;
        let resolution = u64::from_str_radix(fields.next()?, 16).ok()?;
        let crowded = match fields.next()? {
            "-" => None,
            note => {
                let (most, sentence) = note.split_once(':')?;
                let sentence: String = serde_json::from_str(sentence).ok()?;
                Some((most.parse().ok()?, shared(&sentence)))
            }
        };
        let canonical = fields.next()?;
        if !self.resolutions.contains_key(&resolution) {
            return None;
        }
        let verdict = Verdict::Case {
            needs: Needs { threads, bytes },
            crowded,
            resolution,
            canonical: canonical.into(),
        };
        self.verdicts.insert(key, verdict);
        Some(())
    }

    fn read_refusal(&mut self, rest: &str) -> Option<()> {
        let (key, message) = rest.split_once('\t')?;
        let message = serde_json::from_str(message).ok()?;
        self.verdicts
            .insert(parse_key(key)?, Verdict::Refused(message));
        Some(())
    }

    /// The kept verdict on the case of `key`, if it stands on this machine (`offer`, where it
    /// is known): a refusal always, a case where it fits or its sentence on too many threads
    /// was said of the same machine. A case is given once (its texts move out): the caller
    /// shares it among points of the same fields.
    pub fn take(
        &mut self,
        key: &FieldsKey,
        offer: Option<&Machine>,
    ) -> Option<Result<Checked, String>> {
        match self.verdicts.get_mut(key)? {
            Verdict::Refused(message) => Some(Err(message.clone())),
            Verdict::Case {
                needs,
                crowded,
                resolution,
                canonical,
            } => {
                let offer = offer?;
                let machine = match (fit(needs, offer), crowded) {
                    _ if canonical.is_empty() => return None,
                    (Fit::Fits, _) => None,
                    (Fit::TooManyThreads, Some((most, sentence)))
                        if *most == offer.most_threads =>
                    {
                        Some(sentence.clone())
                    }
                    _ => return None,
                };
                Some(Ok(Checked {
                    canonical: std::mem::take(canonical),
                    resolved: self.resolutions[resolution].clone(),
                    machine,
                }))
            }
        }
    }

    /// Keeps the solver's verdict on the case of `key`, said on a machine that offered
    /// `offer` (a case only with what it needs, as `check` says it).
    pub fn keep(
        &mut self,
        key: &FieldsKey,
        verdict: &Result<Checked, String>,
        needs: Option<Needs>,
        offer: Option<&Machine>,
    ) {
        if self.verdicts.contains_key(key) {
            return;
        }
        let key_hex = crate::store::hex(key);
        let line = match (verdict, needs) {
            (Ok(checked), Some(needs)) => {
                // The sentence on too many threads is the machine's cores' alone; on memory,
                // of the moment.
                let crowded = match (&checked.machine, offer) {
                    (Some(sentence), Some(offer)) if fit(&needs, offer) == Fit::TooManyThreads => {
                        Some((offer.most_threads, sentence.clone()))
                    }
                    _ => None,
                };
                let note = match &crowded {
                    None => "-".to_string(),
                    Some((most, sentence)) => {
                        format!(
                            "{most}:{}",
                            serde_json::to_string(&**sentence).expect("a string serializes")
                        )
                    }
                };
                let resolution = resolution_id(&checked.resolved);
                if !self.resolutions.contains_key(&resolution) {
                    let (kind, text) = kind_and_text(&checked.resolved);
                    self.write_line(&format!("R\t{resolution:016x}\t{kind}\t{text}"));
                    self.resolutions
                        .insert(resolution, checked.resolved.clone());
                }
                self.verdicts.insert(
                    *key,
                    Verdict::Case {
                        needs,
                        crowded,
                        resolution,
                        canonical: Box::default(),
                    },
                );
                format!(
                    "C\t{key_hex}\t{}\t{}\t{resolution:016x}\t{note}\t{}",
                    needs.threads, needs.bytes, checked.canonical
                )
            }
            (Ok(_), None) => return,
            (Err(message), _) => {
                self.verdicts
                    .insert(*key, Verdict::Refused(message.clone()));
                let message = serde_json::to_string(message).expect("a string serializes");
                format!("E\t{key_hex}\t{message}")
            }
        };
        self.write_line(&line);
    }

    /// The fresh file written beside the kept one (renamed over it by `save`).
    fn fresh(&self) -> PathBuf {
        crate::store::fs::partial_path(&self.path)
    }

    /// Writes `line` with its CRC-32, opening the file (or a fresh one) at the first.
    fn write_line(&mut self, line: &str) {
        if matches!(self.out, Ok(None)) {
            let opened = match self.afresh {
                true => crate::store::fs::create_fresh(&self.fresh()).and_then(|mut file| {
                    writeln!(file, "{}", self.header)?;
                    Ok(file)
                }),
                // (Not through a link planted since the file was read.)
                false => std::fs::OpenOptions::new()
                    .append(true)
                    .custom_flags(libc::O_NOFOLLOW)
                    .open(&self.path)
                    .and_then(|mut file| {
                        if self.cut_short {
                            file.write_all(b"\n")?;
                        }
                        Ok(file)
                    }),
            };
            self.out = opened
                .map(|file| Some(std::io::BufWriter::with_capacity(1 << 16, file)))
                .map_err(|_| ());
        }
        let Ok(Some(out)) = &mut self.out else { return };
        let crc = crc32fast::hash(line.as_bytes());
        if writeln!(out, "{crc:08x}\t{line}").is_err() {
            self.out = Err(());
        }
    }

    /// Puts in place what was kept since `load`: the fresh file renamed over the kept one, or
    /// the lines appended flushed. Where they cannot be written (no results directory yet, a
    /// full disk), the verdicts are asked again next time: they are a cache. A line cut short
    /// (or run into another writer's) fails its CRC when read.
    pub fn save(self) {
        let (afresh, fresh, path) = (self.afresh, self.fresh(), self.path);
        let written = match self.out {
            Ok(Some(out)) => out.into_inner().is_ok(),
            Ok(None) => return,
            Err(()) => false,
        };
        if afresh && !(written && std::fs::rename(&fresh, &path).is_ok()) {
            let _ = std::fs::remove_file(&fresh);
        }
    }
}

/// A line's kind and the rest, where its CRC-32 (the first field, of all after it) holds.
fn checked_line(line: &str) -> Option<(&str, &str)> {
    let line = line.strip_suffix('\n')?;
    let (crc, rest) = line.split_once('\t')?;
    if u32::from_str_radix(crc, 16).ok()? != crc32fast::hash(rest.as_bytes()) {
        return None;
    }
    rest.split_once('\t')
}

fn parse_key(hex: &str) -> Option<FieldsKey> {
    let mut key = [0u8; 16];
    if hex.len() != 32 {
        return None;
    }
    for (k, byte) in key.iter_mut().enumerate() {
        *byte = u8::from_str_radix(hex.get(2 * k..2 * k + 2)?, 16).ok()?;
    }
    Some(key)
}

#[cfg(test)]
mod tests {
    use super::*;

    const OFFER: Machine = Machine {
        cores: 8,
        most_threads: 8,
        available_bytes: Some(1000),
    };

    fn case(canonical: &str, machine: Option<&str>) -> Result<Checked, String> {
        Ok(Checked {
            canonical: canonical.into(),
            resolved: Resolved::Adds(Arc::from(r#"{"collar":"zero"}"#)),
            machine: machine.map(Into::into),
        })
    }

    fn needs(threads: u64, bytes: u64) -> Option<Needs> {
        Some(Needs { threads, bytes })
    }

    /// Five verdicts kept and saved: a case that fits, one with too many threads (its sentence
    /// said of `OFFER`), one that needs more memory than `OFFER` has, a refusal, and a case of a
    /// solver that does not say what it needs.
    fn kept_five(path: &std::path::Path) -> Vec<(FieldsKey, Result<Checked, String>)> {
        let verdicts = vec![
            (fields_key(b"fits"), case(r#"{"n":16}"#, None), needs(2, 10)),
            (
                fields_key(b"threads"),
                case(r#"{"n":32}"#, Some("too many threads")),
                needs(9, 10),
            ),
            (
                fields_key(b"memory"),
                case(r#"{"n":64}"#, Some("too little memory")),
                needs(1, 5000),
            ),
            (
                fields_key(b"refused"),
                Err("case field `m`: too big\tand a tab".to_string()),
                None,
            ),
            (fields_key(b"silent"), case(r#"{"n":128}"#, None), None),
        ];
        let mut kept = Kept::load(path.to_path_buf(), "nlsolve 1", "ab12");
        for (key, verdict, needs) in &verdicts {
            kept.keep(key, verdict, *needs, Some(&OFFER));
        }
        kept.save();
        verdicts.into_iter().map(|(k, v, _)| (k, v)).collect()
    }

    #[test]
    fn a_kept_verdict_is_taken_where_it_stands_on_the_machine_as_it_is_now() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".verdicts");
        let verdicts = kept_five(&path);
        let take = |k: usize, offer: &Machine| {
            Kept::load(path.clone(), "nlsolve 1", "ab12").take(&verdicts[k].0, Some(offer))
        };
        // As said, on the machine they were said on (the memory sentence is of its moment).
        for k in [0, 1, 3] {
            assert_eq!(
                take(k, &OFFER).as_ref(),
                Some(&verdicts[k].1),
                "verdict {k}"
            );
        }
        assert_eq!(take(2, &OFFER), None);
        assert_eq!(take(4, &OFFER), None, "what a case needs was not said");
        // A machine with more memory: the memory-hungry case fits, the rest stand.
        let roomy = Machine {
            available_bytes: Some(10_000),
            ..OFFER
        };
        assert_eq!(take(2, &roomy), case(r#"{"n":64}"#, None).ok().map(Ok));
        assert_eq!(take(1, &roomy).as_ref(), Some(&verdicts[1].1));
        // More cores: the crowded case fits; fewer: its sentence would name other numbers.
        let more = Machine {
            most_threads: 16,
            ..OFFER
        };
        assert_eq!(take(1, &more), case(r#"{"n":32}"#, None).ok().map(Ok));
        let fewer = Machine {
            most_threads: 4,
            ..OFFER
        };
        assert_eq!(take(0, &fewer).as_ref(), Some(&verdicts[0].1));
        assert_eq!(take(1, &fewer), None);
        // Memory unknown: only threads count.
        let unknown = Machine {
            available_bytes: None,
            ..OFFER
        };
        assert_eq!(take(2, &unknown), case(r#"{"n":64}"#, None).ok().map(Ok));
        // Without an offer only refusals stand; a case is given once.
        let mut kept = Kept::load(path.clone(), "nlsolve 1", "ab12");
        assert_eq!(kept.take(&verdicts[0].0, None), None);
        assert_eq!(
            kept.take(&verdicts[3].0, None).as_ref(),
            Some(&verdicts[3].1)
        );
        assert!(kept.take(&verdicts[0].0, Some(&OFFER)).is_some());
        assert_eq!(kept.take(&verdicts[0].0, Some(&OFFER)), None);
        assert_eq!(kept.take(&fields_key(b"never"), Some(&OFFER)), None);
    }

    #[test]
    fn another_solvers_verdicts_are_not_taken_and_are_written_over() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".verdicts");
        let verdicts = kept_five(&path);
        for (version, fingerprint) in [("nlsolve 2", "ab12"), ("nlsolve 1", "cd34")] {
            let mut kept = Kept::load(path.clone(), version, fingerprint);
            assert_eq!(kept.take(&verdicts[0].0, Some(&OFFER)), None);
            assert_eq!(kept.take(&verdicts[3].0, Some(&OFFER)), None);
        }
        let mut kept = Kept::load(path.clone(), "nlsolve 2", "ab12");
        kept.keep(&verdicts[3].0, &verdicts[3].1, None, None);
        kept.save();
        let mut kept = Kept::load(path.clone(), "nlsolve 2", "ab12");
        assert_eq!(
            kept.take(&verdicts[3].0, None).as_ref(),
            Some(&verdicts[3].1)
        );
        assert_eq!(
            kept.take(&verdicts[0].0, Some(&OFFER)),
            None,
            "the old lines are gone"
        );
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "no partial file is left");
    }

    #[test]
    fn a_damaged_line_is_asked_again_and_the_others_stand() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".verdicts");
        let verdicts = kept_five(&path);
        let text = std::fs::read_to_string(&path).unwrap();
        // Each kind of damage: a byte changed in the fits case's line, the file cut short in
        // the middle of its last line (the refusal).
        let fits_at = text.find(r#"{"n":16}"#).unwrap();
        let mut damaged = text.clone().into_bytes();
        damaged[fits_at + 6] = b'7';
        let refusal_at = text.find("too big").unwrap();
        damaged.truncate(refusal_at);
        std::fs::write(&path, &damaged).unwrap();
        let mut kept = Kept::load(path.clone(), "nlsolve 1", "ab12");
        assert_eq!(kept.take(&verdicts[0].0, Some(&OFFER)), None);
        assert_eq!(kept.take(&verdicts[3].0, Some(&OFFER)), None);
        assert_eq!(
            kept.take(&verdicts[1].0, Some(&OFFER)).as_ref(),
            Some(&verdicts[1].1)
        );
        // Asked again and appended, after the cut-short line, on lines of their own.
        kept.keep(&verdicts[0].0, &verdicts[0].1, needs(2, 10), Some(&OFFER));
        kept.keep(&verdicts[3].0, &verdicts[3].1, None, Some(&OFFER));
        kept.save();
        let mut kept = Kept::load(path.clone(), "nlsolve 1", "ab12");
        for k in [0, 1, 3] {
            assert_eq!(
                kept.take(&verdicts[k].0, Some(&OFFER)).as_ref(),
                Some(&verdicts[k].1)
            );
        }
    }

    #[test]
    fn a_link_planted_in_its_place_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(".verdicts");
        let precious = dir.path().join("precious");
        kept_five(&precious);
        let before = std::fs::read(&precious).unwrap();
        std::os::unix::fs::symlink(&precious, &path).unwrap();
        // Read as no file; kept afresh in a file of its own, the link replaced, not followed.
        let verdicts = kept_five(&path);
        assert_eq!(std::fs::read(&precious).unwrap(), before);
        assert!(!std::fs::symlink_metadata(&path).unwrap().is_symlink());
        let mut kept = Kept::load(path.clone(), "nlsolve 1", "ab12");
        assert_eq!(
            kept.take(&verdicts[3].0, None).as_ref(),
            Some(&verdicts[3].1)
        );
    }

    #[test]
    fn without_a_directory_nothing_is_kept_and_nothing_fails() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing").join(".verdicts");
        let verdicts = kept_five(&path);
        let mut kept = Kept::load(path.clone(), "nlsolve 1", "ab12");
        assert_eq!(kept.take(&verdicts[3].0, None), None);
        assert!(!path.exists());
    }
}
