//! The checkpoint file of a stopped run (`nlsolve run --checkpoint FILE`), written by the solver
//! and read by both binaries: the solver resumes from it, `nlstudy status` and the cluster's time
//! limits read how far it got. One reader for both, so neither trusts what the other would refuse.
//!
//! The file is `MAGIC`, the header as one line of JSON, the values (little-endian f64, the parts
//! in the header's order), then the CRC-32 of every byte before it (4 bytes, little-endian): an
//! edit anywhere, the header's step as much as a value, is a damaged file. A reader takes only a
//! regular file (never a link, a FIFO or a device), and no more bytes than the case can need
//! (`most_bytes`); a file that fails any of this is refused with the reason, and the run starts
//! afresh.

use crate::case::Case;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// The first line of every checkpoint file (its format's version: 1 had the values alone under
/// an FNV-1a written in the header).
pub const MAGIC: &[u8] = b"nlsolve checkpoint 2\n";
/// The format `MAGIC` names.
const FORMAT: u32 = 2;
/// What the first line of a checkpoint of any format starts with: a file that starts otherwise
/// is not nlsolve's, and nlsolve never writes over it or removes it.
pub const PREFIX: &[u8] = b"nlsolve checkpoint ";

/// The format a checkpoint's first line names (`nlsolve checkpoint N`), if it names one.
fn format_of(bytes: &[u8]) -> Option<u32> {
    let rest = bytes.strip_prefix(PREFIX)?;
    let digits = &rest[..rest.iter().position(|&b| b == b'\n')?];
    std::str::from_utf8(digits).ok()?.parse().ok()
}

/// Whose run a checkpoint is: a checkpoint of another build, case, rank count or rank is
/// refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Identity {
    pub fingerprint: String,
    /// The canonical case without its thread count, as compact JSON.
    pub case: String,
    pub ranks: usize,
    /// The rank whose share of the run it holds (0 for a run of one process).
    pub rank: usize,
}

impl Identity {
    /// The case as an identity holds it: its canonical JSON without the thread count, which
    /// changes no bit of a run (a run may resume on other threads).
    pub fn case_text(canonical: &serde_json::Value) -> String {
        let mut keyed = canonical.clone();
        if let Some(fields) = keyed.as_object_mut() {
            fields.remove("threads");
        }
        keyed.to_string()
    }

    /// Why a checkpoint that `theirs` wrote is not one this run resumes from, if it is not.
    pub fn refuses(&self, theirs: &Identity) -> Option<String> {
        let short = |f: &str| crate::text::first_chars(f, 8).to_string();
        if theirs.fingerprint != self.fingerprint {
            return Some(format!(
                "another solver build wrote it (fingerprint {} here {})",
                short(&theirs.fingerprint),
                short(&self.fingerprint)
            ));
        }
        if theirs.case != self.case {
            return Some(format!(
                "it is the checkpoint of another case ({})",
                theirs.case
            ));
        }
        if theirs.ranks != self.ranks {
            return Some(format!(
                "it was written on {} ranks, this run has {}",
                theirs.ranks, self.ranks
            ));
        }
        (theirs.rank != self.rank).then(|| {
            format!(
                "it holds rank {}'s share, not rank {}'s",
                theirs.rank, self.rank
            )
        })
    }
}

/// A checkpoint's header: whose run, how far, and the parts' names and lengths in the order
/// their values follow.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub identity: Identity,
    /// Steps done (a steady solve's: CG iterations).
    pub step: usize,
    /// The run's steps in all, when it has a number of them (`nlstudy status` shows step of
    /// steps); a checkpoint past them is refused.
    pub steps: Option<usize>,
    pub parts: Vec<(String, usize)>,
}

/// The most header bytes a reader takes (the case's JSON is most of it).
const HEADER_CAP: u64 = 1 << 20;

/// The most bytes a checkpoint of `case` can hold: every array a run carries is at most the
/// nodes' count long, a few of them (the field, a steady solve's CG vectors, the stepper's
/// state), one per frame the case asks for, the c_tot series' two per sample, and the timings
/// of at most 2¹⁶ steps each (`MAX_TIMED_STEPS` of the solver's timed loop). Generous: it is a
/// bound that stops a file that is no checkpoint (a link to /dev/zero) from being read until
/// memory runs out, not a size check.
pub fn most_bytes(case: &Case) -> u64 {
    let nodes = ((case.n + 1) as u64).saturating_pow(case.dim.clamp(1, 3) as u32);
    let t_end = case
        .t_end
        .filter(|t| t.is_finite() && *t > 0.0)
        .unwrap_or(0.0);
    let count = |every: Option<f64>| match every.filter(|e| e.is_finite() && *e > 0.0) {
        Some(every) => ((t_end / every).min(1e9) as u64).saturating_add(2),
        None => 0,
    };
    let values = nodes
        .saturating_mul(16u64.saturating_add(count(case.vtk_every)))
        .saturating_add(2u64.saturating_mul(count(case.diagnostics_every)))
        .saturating_add(4 << 20);
    HEADER_CAP
        .saturating_add(values.saturating_mul(8))
        .saturating_add(MAGIC.len() as u64 + 4)
}

/// Writes a checkpoint: the header, then the values as they come, then the checksum of it all.
pub fn write(
    out: impl Write,
    header: &Header,
    values: impl IntoIterator<Item = f64>,
) -> std::io::Result<()> {
    let mut out = Summed {
        out,
        crc: crc32fast::Hasher::new(),
    };
    out.write_all(MAGIC)?;
    serde_json::to_writer(&mut out, header).map_err(std::io::Error::other)?;
    out.write_all(b"\n")?;
    for v in values {
        out.write_all(&v.to_le_bytes())?;
    }
    let crc = out.crc.finalize();
    out.out.write_all(&crc.to_le_bytes())?;
    out.out.flush()
}

/// A writer that sums what passes through it.
struct Summed<W> {
    out: W,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Summed<W> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        let written = self.out.write(bytes)?;
        self.crc.update(&bytes[..written]);
        Ok(written)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// A whole checkpoint as read: its header and its values' bytes.
#[derive(Debug)]
pub struct Checkpoint {
    pub header: Header,
    values: Vec<u8>,
    /// Where the values start in `values`.
    start: usize,
}

impl Checkpoint {
    /// Each part's name and values, in the header's order.
    pub fn parts(&self) -> impl Iterator<Item = (&str, Vec<f64>)> {
        let mut at = self.start;
        self.header.parts.iter().map(move |(name, len)| {
            let bytes = &self.values[at..at + 8 * len];
            at += 8 * len;
            let values = bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect();
            (name.as_str(), values)
        })
    }
}

/// The checkpoint at `path`: `Ok(None)` when there is none; an error saying why when the file is
/// not a whole checkpoint (not a regular file, larger than `cap`, cut short, damaged, or a
/// header past its own steps). Whose run it is, the caller checks (`Identity`).
pub fn read(path: &Path, cap: u64) -> Result<Option<Checkpoint>, String> {
    Ok(read_identified(path, cap)?.map(|(checkpoint, _)| checkpoint))
}

/// `read`, with the identity of the file it read (`regular::FileId`): what the run that resumes
/// from it may remove once it is over, and nothing else that stands at the path by then.
pub fn read_identified(
    path: &Path,
    cap: u64,
) -> Result<Option<(Checkpoint, crate::regular::FileId)>, String> {
    let (bytes, id) = match crate::regular::read_identified(path, cap, "a checkpoint of this case")
    {
        Ok(read) => read,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("it cannot be read ({e})")),
    };
    parse(bytes).map(|checkpoint| Some((checkpoint, id)))
}

/// Why what stands at `path` is not nlsolve's to write over or remove: not a regular file (a
/// link, a FIFO, a device, a folder), or a file that does not start as a checkpoint of any
/// format does. `None` when nothing stands there or it is a checkpoint (whole or not, of
/// whichever run). Only the first bytes are read, and a FIFO or device is not opened.
pub fn foreign(path: &Path) -> Option<String> {
    use std::io::Read;
    let (file, _) = match crate::regular::open(path) {
        Ok(opened) => opened,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
        Err(e) if e.kind() == std::io::ErrorKind::Other => return Some(format!("it is {e}")),
        Err(e) => return Some(format!("it cannot be opened ({e})")),
    };
    let mut first = Vec::with_capacity(PREFIX.len());
    match file.take(PREFIX.len() as u64).read_to_end(&mut first) {
        Ok(_) if first == PREFIX => None,
        Ok(_) => Some("it is a file that is not a checkpoint of nlsolve".into()),
        Err(e) => Some(format!("it cannot be read ({e})")),
    }
}

/// A checkpoint from its file's bytes.
pub fn parse(mut bytes: Vec<u8>) -> Result<Checkpoint, String> {
    if !bytes.starts_with(MAGIC) {
        return Err(match format_of(&bytes) {
            Some(v) if v > FORMAT => format!(
                "it is a checkpoint of format {v}, newer than this nlsolve's {FORMAT} (a newer nlsolve wrote it)"
            ),
            Some(v) => format!(
                "it is a checkpoint of format {v}, older than this nlsolve's {FORMAT} (an older nlsolve wrote it)"
            ),
            None if bytes.starts_with(PREFIX) => "it is a checkpoint of an unknown format".into(),
            None => "it is not a checkpoint of nlsolve".into(),
        });
    }
    let Some(summed) = bytes.len().checked_sub(4) else {
        return Err("it is cut short".into());
    };
    let crc = u32::from_le_bytes(bytes[summed..].try_into().expect("4 bytes"));
    if crc32fast::hash(&bytes[..summed]) != crc {
        return Err("it does not match its checksum (the file is cut short or damaged)".into());
    }
    bytes.truncate(summed);
    let rest = &bytes[MAGIC.len()..];
    let end = rest
        .iter()
        .position(|&b| b == b'\n')
        .ok_or("its header is cut short")?;
    let header: Header =
        serde_json::from_slice(&rest[..end]).map_err(|e| format!("its header is not one ({e})"))?;
    let start = MAGIC.len() + end + 1;
    let expected = header
        .parts
        .iter()
        .try_fold(0usize, |sum, (_, len)| sum.checked_add(len.checked_mul(8)?));
    if expected != Some(bytes.len() - start) {
        return Err(format!(
            "its values are {} bytes, its header says {}",
            bytes.len() - start,
            expected.map_or("more than there can be".into(), |e| e.to_string())
        ));
    }
    if let Some(steps) = header.steps.filter(|&steps| header.step > steps) {
        return Err(format!(
            "it is at step {} of a run of {steps} steps",
            header.step
        ));
    }
    Ok(Checkpoint {
        header,
        values: bytes,
        start,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(step: usize) -> Header {
        Header {
            identity: Identity {
                fingerprint: "ab".repeat(32),
                case: r#"{"dim":1,"n":16}"#.into(),
                ranks: 1,
                rank: 0,
            },
            step,
            steps: Some(40),
            parts: vec![("field".into(), 3), ("empty".into(), 0), ("n".into(), 1)],
        }
    }

    fn bytes(step: usize) -> Vec<u8> {
        let mut out = Vec::new();
        write(&mut out, &header(step), [0.1, -0.0, 1e300, 7.0]).unwrap();
        out
    }

    #[test]
    fn a_checkpoint_reads_back_bit_for_bit() {
        let read = parse(bytes(17)).unwrap();
        assert_eq!(read.header, header(17));
        let parts: Vec<(&str, Vec<u64>)> = read
            .parts()
            .map(|(n, v)| (n, v.iter().map(|x| x.to_bits()).collect()))
            .collect();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            parts,
            [
                ("field", bits(&[0.1, -0.0, 1e300])),
                ("empty", vec![]),
                ("n", bits(&[7.0]))
            ]
        );
    }

    /// Any byte changed, the header's as much as a value's, or a byte cut, and the file is
    /// refused.
    #[test]
    fn every_byte_is_under_the_checksum() {
        let whole = bytes(17);
        for at in 0..whole.len() {
            for flip in [1u8, 0x20, 0x80] {
                let mut damaged = whole.clone();
                damaged[at] ^= flip;
                assert!(parse(damaged).is_err(), "byte {at} ^ {flip}");
            }
            assert!(parse(whole[..at].to_vec()).is_err(), "cut at {at}");
        }
    }

    /// A header past its own steps is refused even with a checksum that matches (a writer's
    /// fault, not a damaged file).
    #[test]
    fn a_step_past_the_runs_steps_is_refused() {
        assert!(parse(bytes(40)).is_ok());
        let past = parse(bytes(41)).unwrap_err();
        assert!(past.contains("step 41 of a run of 40 steps"), "{past}");
    }

    /// A file of another format says which nlsolve wrote it, older or newer.
    #[test]
    fn another_format_is_named_older_or_newer() {
        let of = |first: &[u8]| {
            let mut file = first.to_vec();
            file.extend_from_slice(&bytes(3)[MAGIC.len()..]);
            parse(file).unwrap_err()
        };
        assert!(of(b"nlsolve checkpoint 1\n").contains("an older nlsolve"));
        let newer = of(b"nlsolve checkpoint 13\n");
        assert!(
            newer.contains("format 13, newer than this nlsolve's 2"),
            "{newer}"
        );
        assert!(of(b"nlsolve checkpoint x\n").contains("unknown format"));
        assert!(of(b"checkpoint 2\n").contains("not a checkpoint of nlsolve"));
    }

    /// What nlsolve may write over or remove: nothing but a checkpoint, of any format or run.
    #[test]
    fn only_a_checkpoint_is_nlsolves_own() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cp");
        assert_eq!(foreign(&path), None, "nothing there");
        std::fs::write(&path, b"nlsolve checkpoint 1\nold").unwrap();
        assert_eq!(foreign(&path), None, "an older checkpoint");
        std::fs::write(&path, b"thesis draft").unwrap();
        assert!(foreign(&path).unwrap().contains("not a checkpoint"));
        std::fs::write(&path, b"").unwrap();
        assert!(foreign(&path).is_some(), "an empty file");
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(dir.path().join("missing"), &link).unwrap();
        assert!(foreign(&link).unwrap().contains("symbolic link"));
        assert!(foreign(dir.path()).unwrap().contains("a directory"));
    }

    #[test]
    fn the_cap_bounds_what_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cp");
        assert!(read(&path, 1 << 20).unwrap().is_none(), "none yet");
        std::fs::write(&path, bytes(3)).unwrap();
        assert!(read(&path, 1 << 20).unwrap().is_some());
        let over = read(&path, 10).unwrap_err();
        assert!(over.contains("more than the 10 bytes"), "{over}");
        std::os::unix::fs::symlink("/dev/zero", dir.path().join("zero")).unwrap();
        assert!(read(&dir.path().join("zero"), u64::MAX)
            .unwrap_err()
            .contains("symbolic link"));
    }

    #[test]
    fn a_cases_cap_counts_its_nodes_frames_and_samples() {
        let case = |extra: serde_json::Value| {
            let mut fields =
                serde_json::json!({"dim": 2, "n": 64, "m": 2, "t_end": 1.0, "cfl": 0.5});
            for (k, v) in extra.as_object().unwrap() {
                fields[k] = v.clone();
            }
            Case::parse(fields).unwrap()
        };
        let plain = most_bytes(&case(serde_json::json!({})));
        let framed = most_bytes(&case(serde_json::json!({"vtk_every": 0.01})));
        assert!(plain > 8 * 65 * 65 * 16 && plain < 64 << 20, "{plain}");
        assert!(framed >= plain + 8 * 65 * 65 * 100, "{framed}");
    }
}
