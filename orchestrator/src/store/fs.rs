//! The file-system primitives under the store and the study's outputs: whole-or-nothing writes,
//! lock files, and the removal of leftovers, which never follows a symbolic link out of the
//! results. Every failure names its path.

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};

/// A file-system failure and the path it happened on.
#[derive(Debug, thiserror::Error)]
#[error("cannot {action} {}: {source}", path.display())]
pub struct FileError {
    /// What was tried: "write", "create", "read", "lock".
    pub action: &'static str,
    pub path: PathBuf,
    pub source: io::Error,
}

impl FileError {
    pub fn new(action: &'static str, path: &Path, source: io::Error) -> FileError {
        FileError {
            action,
            path: path.to_path_buf(),
            source,
        }
    }

    /// A `map_err` for an action on `path`.
    pub fn on<'a>(
        action: &'static str,
        path: &'a Path,
    ) -> impl FnOnce(io::Error) -> FileError + 'a {
        move |source| FileError::new(action, path, source)
    }
}

/// Why a step that reads or writes the results did not happen, by kind, for the exit status
/// (`schema::exit`): a request that cannot be met as made, or a file or program that failed.
#[derive(Debug, thiserror::Error)]
pub enum Fault {
    /// A bad value or a request the data cannot answer (nothing stored to collect).
    #[error("{0}")]
    Input(String),
    /// The results could not be read or written, or a program could not be started.
    #[error("{0}")]
    Io(String),
}

impl Fault {
    pub fn message(&self) -> &str {
        match self {
            Fault::Input(message) | Fault::Io(message) => message,
        }
    }

    /// The same fault with `context` before its message (`cannot collect: …`).
    pub fn within(self, context: &str) -> Fault {
        match self {
            Fault::Input(m) => Fault::Input(format!("{context}: {m}")),
            Fault::Io(m) => Fault::Io(format!("{context}: {m}")),
        }
    }
}

impl From<FileError> for Fault {
    fn from(e: FileError) -> Fault {
        Fault::Io(e.to_string())
    }
}

/// The most a record or a history entry may hold. A record is a few KB; the largest the solver
/// writes are a patch test's profiles (three f64 per node along the bar: about 1.3 MB at 20,000
/// nodes) and a long c_tot(t) series, so 64 MiB leaves a wide margin and still stops a file that
/// is not a record (a link to /dev/zero, a log) from being read until memory runs out.
pub const RECORD_CAP: u64 = 64 << 20;

/// The most a small bookkeeping file (the owner file, a figure's stamp, a table's sum) may hold.
pub const SMALL_FILE_CAP: u64 = 1 << 20;

/// Opens `path` only if it is a regular file (`schema::regular::open`: a link is not followed,
/// a FIFO or device does not block the open, the descriptor's own `fstat` decides). The error
/// says what the file is instead.
pub fn open_regular(path: &Path) -> Result<(File, u64), String> {
    schema::regular::open(path).map_err(|e| e.to_string())
}

/// The text of the regular file `path`, refused (not read to its end, never waited on) when it is
/// not a regular file, is larger than `cap` bytes or is not UTF-8. The error says why, without
/// the path (callers name it).
pub fn read_regular(path: &Path, cap: u64) -> Result<String, String> {
    use std::io::Read;
    let (file, len) = open_regular(path)?;
    let too_large = |size: u64| {
        format!(
            "{size} bytes, more than the {} MiB a file of the store may hold",
            cap >> 20
        )
    };
    if len > cap {
        return Err(too_large(len));
    }
    // The size may change after fstat: read at most one byte past the cap to know.
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(cap + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > cap {
        return Err(too_large(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string())
}

/// Runs `read`, a reader of a file that may be corrupt, turning a panic inside a library (polars
/// panics on some corrupt Parquet footers) into an error; the default hook's report of such a
/// panic is silenced meanwhile, on every thread (polars reads on its pool), so that the user sees
/// one sentence. A panic elsewhere at the same moment goes unprinted, but still unwinds.
pub fn without_panicking<T>(read: impl FnOnce() -> T) -> Result<T, String> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static QUIET: AtomicUsize = AtomicUsize::new(0);
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let report = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if QUIET.load(Ordering::SeqCst) == 0 {
                report(info);
            }
        }));
    });
    QUIET.fetch_add(1, Ordering::SeqCst);
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
    QUIET.fetch_sub(1, Ordering::SeqCst);
    outcome.map_err(|panic| {
        let said = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        format!("its reader failed: {said}")
    })
}

pub use schema::atomic::{create_fresh, partial_path};

/// Writes a file whole or not at all (`schema::atomic`), the path that failed named.
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<(), FileError> {
    schema::atomic::write_atomically(path, contents)
        .map_err(|(failed, e)| FileError::new("write", &failed, e))
}

/// A file's modification time in nanoseconds since the epoch: what tells a segment written
/// over in place, or a file of the old store changed, since it was read.
pub fn modified_ns(meta: &std::fs::Metadata) -> i128 {
    use std::os::unix::fs::MetadataExt;
    i128::from(meta.mtime()) * 1_000_000_000 + i128::from(meta.mtime_nsec())
}

/// Makes `dir` and its parents.
pub fn create_dir(dir: &Path) -> Result<(), FileError> {
    std::fs::create_dir_all(dir).map_err(FileError::on("create", dir))
}

/// The lock file `name` in `dir` (both made when missing), not yet locked. Only a regular file
/// is taken: a link is not followed (`O_NOFOLLOW`) and a FIFO does not block the open
/// (`O_NONBLOCK`: with no reader it fails at once), so a planted one is an error naming it.
pub fn lock_file(dir: &Path, name: &str) -> Result<File, FileError> {
    use std::os::unix::fs::OpenOptionsExt;
    create_dir(dir)?;
    let path = dir.join(name);
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(&path)
        .map_err(FileError::on("open", &path))?;
    match file
        .metadata()
        .map_err(FileError::on("open", &path))?
        .is_file()
    {
        true => Ok(file),
        false => Err(FileError::new(
            "lock",
            &path,
            io::Error::other("not a regular file"),
        )),
    }
}

/// A write lock of the one byte at `offset`, for `fcntl`.
fn write_lock_of_byte(offset: i64) -> libc::flock {
    // SAFETY: a zeroed `flock` is a valid value of the plain C struct; its fields are set below.
    let mut lock: libc::flock = unsafe { std::mem::zeroed() };
    lock.l_type = libc::F_WRLCK as libc::c_short;
    lock.l_whence = libc::SEEK_SET as libc::c_short;
    lock.l_start = offset;
    lock.l_len = 1;
    lock
}

/// Locks byte `offset` of `file` for writing, as an open file description lock (`F_OFD_SETLK`):
/// held until every descriptor of this opening is closed, and refused (false) while another
/// opening, in this process or another, holds it.
pub fn lock_byte(file: &File, offset: i64) -> io::Result<bool> {
    use std::os::fd::AsRawFd;
    let lock = write_lock_of_byte(offset);
    // SAFETY: the descriptor is open for as long as `file`, and `lock` outlives the call.
    if unsafe { libc::fcntl(file.as_raw_fd(), libc::F_OFD_SETLK, &lock) } == 0 {
        return Ok(true);
    }
    let error = io::Error::last_os_error();
    match error.raw_os_error() {
        Some(libc::EAGAIN | libc::EACCES) => Ok(false),
        _ => Err(error),
    }
}

/// Whether another opening holds a lock on byte `offset` of `file` (`F_OFD_GETLK`: nothing is
/// locked by asking).
pub fn byte_locked(file: &File, offset: i64) -> io::Result<bool> {
    use std::os::fd::AsRawFd;
    let mut lock = write_lock_of_byte(offset);
    // SAFETY: the descriptor is open for as long as `file`; the kernel fills `lock` in.
    if unsafe { libc::fcntl(file.as_raw_fd(), libc::F_OFD_GETLK, &mut lock) } != 0 {
        return Err(io::Error::last_os_error());
    }
    Ok(lock.l_type != libc::F_UNLCK as libc::c_short)
}

/// Removes the files of `dir` whose names `stale` picks (a missing `dir` has none). A `dir`
/// that is a symbolic link is left alone, and so is what a link inside it points to (the link
/// itself may go): leftovers are cleared inside the results, never elsewhere.
pub fn remove_where(dir: &Path, stale: impl Fn(&str) -> bool) {
    let is_real_dir = std::fs::symlink_metadata(dir).is_ok_and(|m| m.file_type().is_dir());
    if !is_real_dir {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        // The entry's own type: a link is not followed.
        let removable = entry.file_type().is_ok_and(|t| !t.is_dir());
        if removable && stale(&entry.file_name().to_string_lossy()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The first symbolic link to a folder beneath a study's folder `study_dir`, walking its folders
/// without following any link. nlstudy writes only its own files there (records, history,
/// figures, job scripts), so a folder that is a link, planted at `history/` or `runs/segments`
/// say, would carry those writes anywhere: it is refused, never followed. (A link in a file's
/// place is never followed by a read or a write, `open_regular` and `create_fresh`, and is named
/// where it is read.) A link for the whole study folder (or above it) is the user's choice, and
/// allowed.
pub fn planted_link(study_dir: &Path) -> Option<PathBuf> {
    let mut folders = vec![study_dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            // The entry's own type (d_type, or lstat): a link is seen, not followed.
            match entry.file_type() {
                Ok(kind) if kind.is_symlink() && entry.path().is_dir() => {
                    return Some(entry.path())
                }
                Ok(kind) if kind.is_dir() => folders.push(entry.path()),
                _ => {}
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_inside_a_study_folder_is_found_and_one_for_the_whole_folder_is_not() {
        let scratch = tempfile::tempdir().unwrap();
        let (outside, results) = (
            scratch.path().join("outside"),
            scratch.path().join("results"),
        );
        let study = results.join("s");
        std::fs::create_dir_all(study.join("runs/segments")).unwrap();
        std::fs::create_dir_all(&outside).unwrap();
        assert_eq!(planted_link(&study), None);
        // The whole study folder a link: allowed.
        let linked = results.join("linked");
        std::os::unix::fs::symlink(&study, &linked).unwrap();
        assert_eq!(planted_link(&linked), None);
        for inside in ["history", "runs/.work", "figures/made.svg"] {
            let at = study.join(inside);
            std::fs::create_dir_all(at.parent().unwrap()).unwrap();
            std::os::unix::fs::symlink(&outside, &at).unwrap();
            assert_eq!(planted_link(&study), Some(at.clone()), "{inside}");
            std::fs::remove_file(&at).unwrap();
        }
        // A link in a file's place is for the readers and writers to refuse.
        std::fs::write(outside.join("file"), "").unwrap();
        std::os::unix::fs::symlink(outside.join("file"), study.join("runs/x.json")).unwrap();
        assert_eq!(planted_link(&study), None);
    }

    #[test]
    fn removal_never_reaches_through_a_symbolic_link() {
        let temporary = tempfile::tempdir().unwrap();
        let root = temporary.path().to_path_buf();
        let outside = root.join("outside");
        let results = root.join("results");
        std::fs::create_dir_all(&outside).unwrap();
        std::fs::create_dir_all(&results).unwrap();
        let precious = outside.join(".thesis.partial");
        std::fs::write(&precious, "years").unwrap();
        // A linked directory, and a link to a file, both named like leftovers.
        std::os::unix::fs::symlink(&outside, results.join("figures")).unwrap();
        std::os::unix::fs::symlink(&precious, results.join(".link.partial")).unwrap();
        let partial = |n: &str| n.ends_with(".partial");
        remove_where(&results.join("figures"), partial);
        remove_where(&results, partial);
        assert!(precious.exists(), "a file outside the results was removed");
        assert!(
            std::fs::symlink_metadata(results.join(".link.partial")).is_err(),
            "the link itself is a leftover and goes"
        );
    }

    /// A link planted where a write's partial file goes is removed, not followed; a FIFO or a
    /// link where a lock file goes is an error, never waited on.
    #[test]
    fn planted_links_and_fifos_never_take_a_write_or_a_lock() {
        let temporary = tempfile::tempdir().unwrap();
        let root = temporary.path().to_path_buf();
        let precious = root.join("precious");
        std::fs::write(&precious, "years").unwrap();
        let report = root.join("report.html");
        std::os::unix::fs::symlink(&precious, partial_path(&report)).unwrap();
        write_atomically(&report, b"<html>").unwrap();
        assert_eq!(std::fs::read_to_string(&precious).unwrap(), "years");
        assert_eq!(std::fs::read_to_string(&report).unwrap(), "<html>");
        let fifo = std::ffi::CString::new(root.join(".outputs.lock").to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o644) }, 0);
        assert!(
            lock_file(&root, ".outputs.lock").is_err(),
            "a FIFO is no lock file"
        );
        std::os::unix::fs::symlink(&precious, root.join(".owner.lock")).unwrap();
        assert!(
            lock_file(&root, ".owner.lock").is_err(),
            "a link is not followed"
        );
        assert_eq!(std::fs::read_to_string(&precious).unwrap(), "years");
    }

    #[test]
    fn a_failed_write_names_its_path_and_leaves_nothing() {
        let temporary = tempfile::tempdir().unwrap();
        let root = temporary.path().to_path_buf();
        std::fs::write(root.join("file"), "").unwrap();
        // A path under a regular file: "Not a directory".
        let path = root.join("file").join("record.json");
        let error = write_atomically(&path, b"{}").unwrap_err();
        assert!(error
            .to_string()
            .contains(&root.join("file").display().to_string()));
        let long = root.join("x".repeat(300));
        let error = write_atomically(&long, b"{}").unwrap_err();
        assert!(error.to_string().contains("xxxxxxxx"), "{error}");
    }
}
