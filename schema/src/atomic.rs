//! Whole-or-nothing writes, for both binaries: a file is written beside its place under a
//! hidden name, then renamed over it, so a reader sees the old file or the new one, never a
//! half; and no write goes through a link planted where the file or its partial will be.

use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Where a file is written before it is renamed into place: hidden (readers skip dot files)
/// and named for this process, so that processes writing the same file do not mix.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

/// A new, empty regular file at `path` for writing: whatever stood there (a leftover, or a
/// link someone planted to make this write land elsewhere) is removed first, never followed,
/// and the file is created anew: `create_new` is O_CREAT | O_EXCL, which fails on a link rather
/// than follow it, so the bytes go only there.
pub fn create_fresh(path: &Path) -> io::Result<File> {
    let _ = std::fs::remove_file(path);
    File::options().write(true).create_new(true).open(path)
}

/// Writes `contents` to `path` whole or not at all: to its partial path, then a rename. On an
/// error no partial is left, and the error says which of the two paths failed.
pub fn write_atomically(path: &Path, contents: &[u8]) -> Result<(), (PathBuf, io::Error)> {
    write_through(&partial_path(path), path, contents)
}

/// Writes `contents` to `path` whole or not at all through the partial file `partial` (a name
/// of the writer's own, in the same directory).
pub fn write_through(
    partial: &Path,
    path: &Path,
    contents: &[u8],
) -> Result<(), (PathBuf, io::Error)> {
    create_fresh(partial)
        .and_then(|mut file| file.write_all(contents))
        .map_err(|e| (partial.to_path_buf(), e))
        .and_then(|()| std::fs::rename(partial, path).map_err(|e| (path.to_path_buf(), e)))
        .inspect_err(|_| {
            let _ = std::fs::remove_file(partial);
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_replaces_the_file_whole_and_never_follows_a_planted_link() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let target = dir.join("record.json");
        let precious = dir.join("precious");
        std::fs::write(&precious, b"keep").unwrap();
        std::os::unix::fs::symlink(&precious, partial_path(&target)).unwrap();
        write_atomically(&target, b"new").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        assert_eq!(std::fs::read(&precious).unwrap(), b"keep");
        assert!(!partial_path(&target).exists());
        // A destination that cannot be made: the error names it, and no partial stays.
        let (failed, _) = write_atomically(&dir.join("no/such/dir/x"), b"x").unwrap_err();
        assert_eq!(failed, partial_path(&dir.join("no/such/dir/x")));
    }
}
