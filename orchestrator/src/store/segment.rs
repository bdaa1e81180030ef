//! Segments: the files records are packed into (`runs/segments/<name>.seg`), append-only, so
//! that a study of 10⁵ points writes tens of files, not 10⁵ (an inode quota of a parallel file
//! system, and its metadata server, feel the difference).
//!
//! A segment is a run of frames, each a header line and the record's JSON:
//!
//! ```text
//! nlrecord <seq> <length> <crc32 of the body, 8 hex digits>\n<body: length bytes, the record and a newline>
//! ```
//!
//! `seq` orders the frames of one key (the latest wins): the writer's clock in nanoseconds,
//! increasing within a writer. A frame is written by one `write`; the writer `fdatasync`s at
//! most a second after it (group commit: a sync per record cost half a millisecond per point)
//! and when it closes, so a crash of the process loses nothing written and a power cut at most
//! the last second's records, which run again. Whatever a crash leaves (a frame cut short at the end) fails its
//! length or its checksum and is not a record; the next writer of the segment cuts it off. A
//! frame that fails its checksum before the end (corruption) is reported and skipped: reading
//! resumes at the next header.
//!
//! One writer appends to a segment at a time: it holds the segment's `flock` for as long as it
//! writes (the kernel drops it when the process ends, however it ends).

use super::fs::{create_dir, modified_ns, FileError};
use std::fs::File;
use std::io;
use std::ops::Range;
use std::os::unix::fs::{FileExt, MetadataExt};
use std::path::Path;

/// The folder of the segments in `runs/`.
pub const DIR: &str = "segments";
/// A segment's file name ends so.
pub const SUFFIX: &str = ".seg";
/// A writer moves on to a new segment past this size (and takes an old one only below it).
pub const TARGET_BYTES: u64 = 64 << 20;

const MAGIC: &[u8] = b"nlrecord ";
/// The longest header line: the magic, two 20-digit numbers, 8 hex digits, spaces, newline.
const HEADER_MAX: usize = 64;

/// The frame of `body` (a record's JSON, without its newline) with sequence number `seq`.
pub fn encode(seq: u64, body: &[u8]) -> Vec<u8> {
    let crc = checksum(body, true);
    let mut frame = format!("nlrecord {seq} {} {crc:08x}\n", body.len() + 1).into_bytes();
    frame.reserve(body.len() + 1);
    frame.extend_from_slice(body);
    frame.push(b'\n');
    frame
}

/// CRC-32 of a body (with its final newline when `newline`).
fn checksum(body: &[u8], newline: bool) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(body);
    if newline {
        hasher.update(b"\n");
    }
    hasher.finalize()
}

/// One whole frame of a segment: where it lies (offsets within the segment) and its order.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub seq: u64,
    /// The whole frame, header included.
    pub span: Range<u64>,
    /// The record's JSON, newline excluded.
    pub body: Range<u64>,
}

/// What reading a segment's bytes found: its whole frames, the byte ranges that are not
/// (corruption, reported), and where whole frames end (a cut-short frame after it is a torn
/// write, not corruption).
#[derive(Debug, Default, PartialEq)]
pub struct Read {
    pub frames: Vec<Frame>,
    pub corrupt: Vec<Range<u64>>,
    pub end: u64,
}

enum Next {
    Whole(Frame),
    /// Cut short by the end of the bytes: a write in progress or torn by a crash.
    Short,
    Bad,
}

/// The frames of `bytes`, which start at offset `base` of their segment.
pub fn read(bytes: &[u8], base: u64) -> Read {
    let mut read = Read {
        end: base,
        ..Read::default()
    };
    let mut at = 0;
    while at < bytes.len() {
        match next(bytes, at, base) {
            Next::Whole(frame) => {
                at = (frame.span.end - base) as usize;
                read.end = frame.span.end;
                read.frames.push(frame);
            }
            // A frame cut short with another header after it was not cut by a crash.
            Next::Short if find(&bytes[at + 1..], MAGIC).is_none() => break,
            Next::Short | Next::Bad => {
                // Resume at the next header (a false one, in a record's text, is bad in turn).
                let resume = find(&bytes[at + 1..], MAGIC).map(|k| at + 1 + k);
                let stop = resume.unwrap_or(bytes.len());
                read.corrupt.push(base + at as u64..base + stop as u64);
                read.end = base + stop as u64;
                at = stop;
            }
        }
    }
    read
}

fn next(bytes: &[u8], at: usize, base: u64) -> Next {
    let rest = &bytes[at..];
    let Some(newline) = rest.iter().take(HEADER_MAX).position(|&b| b == b'\n') else {
        let could_be_header = rest.len() < HEADER_MAX
            && rest.iter().zip(MAGIC).all(|(a, b)| a == b)
            && rest.iter().all(|b| b.is_ascii_graphic() || *b == b' ');
        return if could_be_header {
            Next::Short
        } else {
            Next::Bad
        };
    };
    let Some(header) = rest[..newline].strip_prefix(MAGIC) else {
        return Next::Bad;
    };
    let fields: Vec<&str> = std::str::from_utf8(header)
        .unwrap_or("")
        .split(' ')
        .collect();
    let [seq, length, crc] = fields.as_slice() else {
        return Next::Bad;
    };
    let (Ok(seq), Ok(length), Ok(crc)) = (
        seq.parse::<u64>(),
        length.parse::<usize>(),
        u32::from_str_radix(crc, 16),
    ) else {
        return Next::Bad;
    };
    let start = newline + 1;
    if length == 0 {
        return Next::Bad;
    }
    if rest.len() - start < length {
        return Next::Short;
    }
    let body = &rest[start..start + length];
    if body[length - 1] != b'\n' || checksum(body, false) != crc {
        return Next::Bad;
    }
    let offset = base + at as u64;
    Next::Whole(Frame {
        seq,
        span: offset..offset + (start + length) as u64,
        body: offset + start as u64..offset + (start + length - 1) as u64,
    })
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// The bytes of `path` from `from` to its end: read whole frames from them.
pub fn read_from(path: &Path, from: u64) -> io::Result<Vec<u8>> {
    read_between(path, from, u64::MAX)
}

/// The bytes of `path` from `from` to `to` (or its end, if sooner).
pub fn read_between(path: &Path, from: u64, to: u64) -> io::Result<Vec<u8>> {
    let (file, len) = super::fs::open_regular(path).map_err(io::Error::other)?;
    let mut bytes = vec![0; len.min(to).saturating_sub(from) as usize];
    let n = read_at_most(&file, &mut bytes, from)?;
    bytes.truncate(n);
    Ok(bytes)
}

/// Whether a frame's header starts at `offset` of the segment `path`: what an append leaves at
/// the end a reader last saw. Anything else there means the segment was written over in place,
/// and what was read of it before is no longer to be trusted.
pub fn frame_starts_at(path: &Path, offset: u64) -> bool {
    let Ok((file, _)) = super::fs::open_regular(path) else {
        return false;
    };
    let mut head = [0u8; MAGIC.len()];
    read_at_most(&file, &mut head, offset).is_ok_and(|n| n == head.len()) && head == MAGIC
}

fn read_at_most(file: &File, buffer: &mut [u8], offset: u64) -> io::Result<usize> {
    let mut done = 0;
    while done < buffer.len() {
        match file.read_at(&mut buffer[done..], offset + done as u64) {
            Ok(0) => break,
            Ok(n) => done += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(done)
}

/// The body of the frame at `span` of segment `path`, checked again (the file may have changed
/// since it was indexed).
pub fn read_frame(path: &Path, span: &Range<u64>) -> Option<Vec<u8>> {
    read_frame_of(&super::fs::open_regular(path).ok()?.0, span)
}

/// `read_frame` of a segment held open.
pub fn read_frame_of(file: &File, span: &Range<u64>) -> Option<Vec<u8>> {
    let mut bytes = vec![0; (span.end - span.start) as usize];
    if read_at_most(file, &mut bytes, span.start).ok()? != bytes.len() {
        return None;
    }
    let body = body_at(&bytes, &(0..bytes.len() as u64))?.to_vec();
    Some(body)
}

/// The body of the whole frame at `span` of `segment` (a segment's bytes from its start),
/// checked again: `None` when it is not the whole frame there.
pub fn body_at<'a>(segment: &'a [u8], span: &Range<u64>) -> Option<&'a [u8]> {
    let bytes = segment.get(..usize::try_from(span.end).ok()?)?;
    match next(bytes, usize::try_from(span.start).ok()?, 0) {
        Next::Whole(frame) if frame.span == *span => {
            Some(&bytes[frame.body.start as usize..frame.body.end as usize])
        }
        _ => None,
    }
}

/// A segment held for appending: its `flock` is held while this lives.
pub struct Appender {
    file: File,
    pub name: String,
    end: u64,
    last_seq: u64,
    /// When the segment was last synced, if something was written since.
    unsynced_since: Option<std::time::Instant>,
    /// The bytes of a frame cut short that opening it cut off (a write torn by a crash, or a
    /// last frame whose length was changed: no record either way, and its point runs again).
    pub cut: Option<Range<u64>>,
}

/// How long a record may wait in the page cache for its `fdatasync`.
const SYNC_WITHIN: std::time::Duration = std::time::Duration::from_secs(1);

/// A segment's name: when and by which process it was begun, so names never repeat.
fn fresh_name() -> String {
    format!("{:016x}-{}{SUFFIX}", now_ns(), std::process::id())
}

/// Opens `path` for appending if no one else holds it and it is still the file at its path
/// (a compaction may have removed it while this waited); `None` otherwise.
fn take(path: &Path) -> io::Result<Option<File>> {
    use std::os::unix::fs::OpenOptionsExt;
    let file = File::options()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)?;
    match file.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => return Ok(None),
        Err(std::fs::TryLockError::Error(e)) => return Err(e),
    }
    let held = file.metadata()?;
    let there = std::fs::symlink_metadata(path);
    let same = there.is_ok_and(|m| m.ino() == held.ino() && m.dev() == held.dev());
    Ok((same && held.is_file()).then_some(file))
}

impl Appender {
    /// A segment of `dir` to append to: one of `candidates` (names of clean segments below
    /// `TARGET_BYTES`, with the end of their whole frames as last read) that no other writer
    /// holds, its torn end cut off; else a new one.
    pub fn open(dir: &Path, candidates: &[(String, u64)]) -> Result<Appender, FileError> {
        create_dir(dir)?;
        for (name, known_end) in candidates {
            let path = dir.join(name);
            let Ok(Some(file)) = take(&path) else {
                continue;
            };
            // Frames a writer added since they were read, then a torn end, if any.
            let Ok(tail) = read_from(&path, *known_end) else {
                continue;
            };
            let read = read(&tail, *known_end);
            if !read.corrupt.is_empty() {
                continue;
            }
            let length = *known_end + tail.len() as u64;
            if file
                .set_len(read.end)
                .and_then(|()| file.sync_data())
                .is_err()
            {
                continue;
            }
            let last_seq = read.frames.last().map_or(0, |f| f.seq);
            return Ok(Appender {
                file,
                name: name.clone(),
                end: read.end,
                last_seq,
                unsynced_since: None,
                cut: (length > read.end).then_some(read.end..length),
            });
        }
        let name = fresh_name();
        let path = dir.join(&name);
        let file = File::options()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(FileError::on("create", &path))?;
        file.lock().map_err(FileError::on("lock", &path))?;
        // The new name must outlive a crash before its first frame is counted on.
        if let Ok(dir) = File::open(dir) {
            let _ = dir.sync_all();
        }
        Ok(Appender {
            file,
            name,
            end: 0,
            last_seq: 0,
            unsynced_since: None,
            cut: None,
        })
    }

    /// Appends the frames of `bodies` by one write, synced now if `sync` (or if the oldest
    /// unsynced frame is a second old); returns the frames. On an error (a full disk) the
    /// segment is cut back to its whole frames.
    pub fn append(
        &mut self,
        dir: &Path,
        bodies: &[&[u8]],
        sync: bool,
    ) -> Result<Vec<Frame>, FileError> {
        let mut bytes = Vec::new();
        let mut frames = Vec::with_capacity(bodies.len());
        let mut seq = self.last_seq;
        for body in bodies {
            seq = now_ns().max(seq + 1);
            let start = self.end + bytes.len() as u64;
            let frame = encode(seq, body);
            let header = (frame.len() - body.len() - 1) as u64;
            let end = start + frame.len() as u64;
            bytes.extend_from_slice(&frame);
            frames.push(Frame {
                seq,
                span: start..end,
                body: start + header..end - 1,
            });
        }
        let since = *self
            .unsynced_since
            .get_or_insert_with(std::time::Instant::now);
        let sync = sync || since.elapsed() >= SYNC_WITHIN;
        let written = self.file.write_all_at(&bytes, self.end).and_then(|()| {
            if sync {
                self.file.sync_data()?;
                self.unsynced_since = None;
            }
            Ok(())
        });
        if let Err(e) = written {
            let _ = self.file.set_len(self.end);
            return Err(FileError::new("write", &dir.join(&self.name), e));
        }
        self.end += bytes.len() as u64;
        self.last_seq = seq;
        Ok(frames)
    }

    /// Syncs what was written since the last sync.
    pub fn sync(&mut self) {
        if self.unsynced_since.take().is_some() {
            let _ = self.file.sync_data();
        }
    }

    /// The segment's modification time (ns) now, as the catalog notes it.
    pub fn modified(&self) -> i128 {
        self.file.metadata().map_or(0, |m| modified_ns(&m))
    }

    /// Whether this segment has grown past `TARGET_BYTES` (its writer moves on).
    pub fn full(&self) -> bool {
        self.end >= TARGET_BYTES
    }
}

impl Drop for Appender {
    fn drop(&mut self) {
        self.sync();
    }
}

/// Nanoseconds since the epoch: a frame's order among the frames of its key.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Holds the `flock` of segment `path` if no writer does, and it is still there.
pub fn hold(path: &Path) -> Option<File> {
    take(path).ok().flatten()
}

/// A new segment written by compaction: whole frames copied in, then `fsync`ed and renamed
/// into place, so it appears whole or not at all.
pub struct Rewriter {
    file: std::io::BufWriter<File>,
    partial: std::path::PathBuf,
    path: std::path::PathBuf,
    end: u64,
}

/// The segment a `Rewriter` made.
pub struct Written {
    pub name: String,
    pub end: u64,
    pub modified: i128,
}

impl Rewriter {
    pub fn create(dir: &Path) -> Result<Rewriter, FileError> {
        let name = fresh_name();
        let path = dir.join(&name);
        let partial = dir.join(format!(".{name}.partial"));
        let file = super::fs::create_fresh(&partial).map_err(FileError::on("create", &partial))?;
        Ok(Rewriter {
            file: std::io::BufWriter::with_capacity(1 << 20, file),
            partial,
            path,
            end: 0,
        })
    }

    /// Copies a whole frame in; returns where it lies in the new segment.
    pub fn copy(&mut self, frame: &[u8]) -> Result<Range<u64>, FileError> {
        use std::io::Write;
        self.file
            .write_all(frame)
            .map_err(FileError::on("write", &self.partial))?;
        let start = self.end;
        self.end += frame.len() as u64;
        Ok(start..self.end)
    }

    /// How many bytes it holds so far.
    pub fn size(&self) -> u64 {
        self.end
    }

    /// Removes what was written.
    pub fn abandon(self) {
        let _ = std::fs::remove_file(&self.partial);
    }

    pub fn finish(self) -> Result<Written, FileError> {
        let partial = self.partial.clone();
        let failed = |e| {
            let _ = std::fs::remove_file(&partial);
            FileError::new("write", &partial, e)
        };
        let file = self.file.into_inner().map_err(|e| failed(e.into_error()))?;
        file.sync_all().map_err(failed)?;
        let meta = file.metadata().map_err(failed)?;
        std::fs::rename(&self.partial, &self.path).map_err(failed)?;
        if let Some(dir) = self.path.parent().and_then(|d| File::open(d).ok()) {
            let _ = dir.sync_all();
        }
        Ok(Written {
            name: self
                .path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            end: self.end,
            modified: modified_ns(&meta),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(bodies: &[&str]) -> Vec<u8> {
        let mut bytes = Vec::new();
        for (k, body) in bodies.iter().enumerate() {
            bytes.extend(encode(10 + k as u64, body.as_bytes()));
        }
        bytes
    }

    fn bodies(bytes: &[u8], read: &Read) -> Vec<String> {
        read.frames
            .iter()
            .map(|f| {
                String::from_utf8(bytes[f.body.start as usize..f.body.end as usize].to_vec())
                    .unwrap()
            })
            .collect()
    }

    #[test]
    fn whole_frames_are_read_back_with_their_order() {
        let bytes = frames(&["{\"a\":1}", "{\"b\":2}"]);
        let read = read(&bytes, 0);
        assert_eq!(bodies(&bytes, &read), ["{\"a\":1}", "{\"b\":2}"]);
        assert_eq!(read.frames[1].seq, 11);
        assert_eq!(read.end, bytes.len() as u64);
        assert!(read.corrupt.is_empty());
    }

    #[test]
    fn a_frame_cut_anywhere_is_short_and_the_frames_before_it_stand() {
        let bytes = frames(&["{\"a\":1}", "{\"b\":22}"]);
        let first = encode(10, b"{\"a\":1}").len();
        for cut in first..bytes.len() {
            let read = read(&bytes[..cut], 0);
            assert_eq!(bodies(&bytes, &read), ["{\"a\":1}"], "cut at {cut}");
            assert_eq!(read.end, first as u64);
            assert!(read.corrupt.is_empty(), "cut at {cut}: {read:?}");
        }
    }

    #[test]
    fn a_flipped_byte_is_reported_and_reading_resumes_at_the_next_frame() {
        let clean = frames(&["{\"a\":1}", "{\"b\":2}", "{\"c\":3}"]);
        let first = encode(10, b"{\"a\":1}").len();
        let second = encode(11, b"{\"b\":2}").len();
        for at in first..first + second {
            let mut bytes = clean.clone();
            bytes[at] ^= 0x55;
            let read = read(&bytes, 0);
            assert_eq!(
                bodies(&bytes, &read),
                ["{\"a\":1}", "{\"c\":3}"],
                "flip at {at}"
            );
            let corrupt = first as u64..(first + second) as u64;
            assert_eq!(read.corrupt, vec![corrupt], "flip at {at}");
        }
    }

    #[test]
    fn an_offset_base_gives_segment_offsets() {
        let bytes = frames(&["{}"]);
        let read = read(&bytes, 100);
        assert_eq!(read.frames[0].span, 100..100 + bytes.len() as u64);
        assert_eq!(read.end, 100 + bytes.len() as u64);
    }
}
