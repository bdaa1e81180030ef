//! The solver's fingerprint (build/fingerprint.rs, run by build.rs) on a copy of the sources:
//! the same sources and settings give the same hash, an edited numeric source or another
//! setting a new one, and files outside the sources none.

#[path = "../build/fingerprint.rs"]
mod fingerprint;

use fingerprint::{fingerprint, SOURCES};
use std::path::Path;

/// A copy of the workspace's fingerprinted sources in a temporary folder, removed when dropped.
fn copy_of_the_sources() -> tempfile::TempDir {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let copy = tempfile::Builder::new()
        .prefix("nlsolve-fingerprint-")
        .tempdir()
        .unwrap();
    for source in SOURCES {
        copy_tree(&root.join(source), &copy.path().join(source));
    }
    copy
}

fn copy_tree(from: &Path, to: &Path) {
    if from.is_dir() {
        for entry in std::fs::read_dir(from).unwrap().flatten() {
            copy_tree(&entry.path(), &to.join(entry.file_name()));
        }
    } else if from.is_file() {
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(from, to).unwrap();
    }
}

#[test]
fn the_fingerprint_follows_the_sources_and_the_settings_and_nothing_else() {
    let settings = |profile: &str| [("profile", profile.to_string()), ("rustc", "1.95".into())];
    let scratch = copy_of_the_sources();
    let copy = scratch.path();
    let first = fingerprint(copy, SOURCES, &settings("release"));
    assert_eq!(first.len(), 64, "SHA-256 in hex: {first}");
    assert_eq!(
        fingerprint(copy, SOURCES, &settings("release")),
        first,
        "nothing changed"
    );

    // Outside the sources (the orchestrator, docs): no change.
    std::fs::create_dir_all(copy.join("orchestrator/src")).unwrap();
    std::fs::write(copy.join("orchestrator/src/lib.rs"), "// edited").unwrap();
    std::fs::write(copy.join("README.md"), "edited").unwrap();
    assert_eq!(fingerprint(copy, SOURCES, &settings("release")), first);

    // One byte of a numeric source, a new file, or another profile: a new fingerprint.
    let kernel = copy.join("solver/src/discretization/quadrature.rs");
    let text = std::fs::read_to_string(&kernel).unwrap();
    std::fs::write(&kernel, text.replacen("0.5", "0.6", 1)).unwrap();
    let edited = fingerprint(copy, SOURCES, &settings("release"));
    assert_ne!(edited, first);
    std::fs::write(&kernel, &text).unwrap();
    assert_eq!(
        fingerprint(copy, SOURCES, &settings("release")),
        first,
        "undone"
    );
    std::fs::write(copy.join("schema/src/new.rs"), "").unwrap();
    assert_ne!(fingerprint(copy, SOURCES, &settings("release")), first);
    std::fs::remove_file(copy.join("schema/src/new.rs")).unwrap();
    assert_ne!(fingerprint(copy, SOURCES, &settings("dev")), first);
}
