//! Reading files another process (or a person) may have put in place, for both binaries: only a
//! regular file is read, never waited on and never past a cap. A symbolic link is not followed
//! (`O_NOFOLLOW`), a FIFO or device does not block the open (`O_NONBLOCK`), and the open
//! descriptor's own `fstat` decides, so nothing swapped in between is read.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Opens `path` only if it is a regular file, with its length. The error says what the file is
/// instead, without the path (callers name it).
pub fn open(path: &Path) -> std::io::Result<(File, u64)> {
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    let file = File::options()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| match e.raw_os_error() {
            Some(libc::ELOOP) => std::io::Error::other("a symbolic link, which is not followed"),
            _ => e,
        })?;
    let meta = file.metadata()?;
    let kind = meta.file_type();
    if !kind.is_file() {
        let what = if kind.is_dir() {
            "a directory"
        } else if kind.is_fifo() {
            "a FIFO"
        } else if kind.is_socket() {
            "a socket"
        } else if kind.is_char_device() || kind.is_block_device() {
            "a device"
        } else {
            "not a regular file"
        };
        return Err(std::io::Error::other(format!(
            "{what}, not a regular file; it is not read"
        )));
    }
    Ok((file, meta.len()))
}

/// A file by its device and inode number: the one a process opened, told apart from whatever
/// stands at its path later.
pub type FileId = (u64, u64);

/// The bytes of the regular file `path`, refused (not read to its end) when it holds more than
/// `cap` bytes; `what` names the kind of file in that refusal ("a checkpoint").
pub fn read(path: &Path, cap: u64, what: &str) -> std::io::Result<Vec<u8>> {
    read_identified(path, cap, what).map(|(bytes, _)| bytes)
}

/// `read`, with the identity of the file the bytes came from (its descriptor's own `fstat`).
pub fn read_identified(path: &Path, cap: u64, what: &str) -> std::io::Result<(Vec<u8>, FileId)> {
    use std::os::unix::fs::MetadataExt;
    let (file, len) = open(path)?;
    let meta = file.metadata()?;
    let id = (meta.dev(), meta.ino());
    let too_large = |size: u64| {
        std::io::Error::other(format!(
            "{size} bytes or more, more than the {cap} bytes {what} may hold"
        ))
    };
    if len > cap {
        return Err(too_large(len));
    }
    // The size may change after fstat: read at most one byte past the cap to know.
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_large(bytes.len() as u64));
    }
    Ok((bytes, id))
}

/// The bytes of `path`, whatever kind of file it is (a study given as `<(…)` is a FIFO), refused
/// once it holds more than `cap` bytes (a device such as /dev/zero is never read to its end).
pub fn read_at_most(path: &Path, cap: u64, what: &str) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    File::open(path)?.take(cap + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(std::io::Error::other(format!(
            "more than the {} MiB {what} may hold",
            cap >> 20
        )));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_regular_file_under_its_cap_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("file");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(read(&file, 5, "a test file").unwrap(), b"12345");
        let over = read(&file, 4, "a test file").unwrap_err().to_string();
        assert!(
            over.contains("more than the 4 bytes a test file may hold"),
            "{over}"
        );
        let link = dir.path().join("link");
        std::os::unix::fs::symlink(&file, &link).unwrap();
        assert!(read(&link, 5, "x")
            .unwrap_err()
            .to_string()
            .contains("symbolic link"));
        // A FIFO is not waited on: the open does not block and the file is refused.
        let fifo = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        assert!(read(&fifo, 5, "x")
            .unwrap_err()
            .to_string()
            .contains("a FIFO"));
        assert!(read(Path::new("/dev/zero"), 5, "x")
            .unwrap_err()
            .to_string()
            .contains("a device"));
        assert!(read(dir.path(), 5, "x")
            .unwrap_err()
            .to_string()
            .contains("a directory"));
    }
}
