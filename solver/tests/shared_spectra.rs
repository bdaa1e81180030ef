//! Spectra shared through a study's directory (`nlsolve run --spectra DIR`): a second process
//! takes the first's entry and gives the record a measurement of its own gives, bit for bit; an
//! entry that is damaged, cut short, another operator's or a link is not believed, but measured
//! again and replaced; two processes measuring one operator at once leave one whole entry.

mod common;

use common::{nlsolve, numbers_of};
use serde_json::{json, Value};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::process::Stdio;

/// A stability probe of the map: the step's amplification from L_h's spectrum.
fn probe(m: u64, integrator: &str, cfl: f64) -> Value {
    json!({"dim": 2, "n": 8 * m, "m": m, "problem": "bump", "t_end": 1e-6, "cfl": cfl,
           "integrator": integrator, "allow_unstable": true, "amplification_steps": 400})
}

/// The record of `case` run alone, sharing through `spectra` when given.
fn record(case: &Value, spectra: Option<&Path>) -> Value {
    let mut args = vec!["run", "--case", "-"];
    let dir;
    if let Some(spectra) = spectra {
        dir = spectra.display().to_string();
        args.extend(["--spectra", dir.as_str()]);
    }
    let out = nlsolve(&args, Some(&case.to_string()), Stdio::piped());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let record: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        record["amplification_low"].is_number(),
        "measured from the spectrum: {record}"
    );
    numbers_of(record)
}

/// The entries in `dir`, and whether anything else but their locks is there.
fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        match name.rsplit('.').next() {
            Some("spectrum") => found.push(path),
            Some("lock") => {}
            _ => panic!("{name}: neither an entry nor its lock (a partial left behind?)"),
        }
    }
    found
}

/// Puts a bad entry in place.
type Plant<'a> = Box<dyn Fn(&Path) + 'a>;

#[test]
fn a_second_process_takes_the_first_ones_spectrum_and_distrusts_a_bad_entry() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("spectra");
    std::fs::create_dir(&dir).unwrap();
    let first = probe(4, "heun", 1.0);
    assert_eq!(record(&first, Some(&dir)), record(&first, None));
    let [entry] = &entries(&dir)[..] else {
        panic!("one entry per operator: {:?}", entries(&dir));
    };
    let written = std::fs::read(entry).unwrap();
    let inode = std::fs::metadata(entry).unwrap().ino();

    // Another integrator (another budget) and step of the operator: the entry serves it, as it
    // is (not measured again, so not rewritten), and the record is the one of its own
    // measurement.
    let second = probe(4, "rk4", 0.5);
    assert_eq!(record(&second, Some(&dir)), record(&second, None));
    assert_eq!(
        std::fs::metadata(entry).unwrap().ino(),
        inode,
        "read, not replaced"
    );
    assert_eq!(entries(&dir).len(), 1);

    // Another operator's entry, to plant under this one's name.
    let other_dir = scratch.path().join("other");
    std::fs::create_dir(&other_dir).unwrap();
    record(&probe(3, "heun", 1.0), Some(&other_dir));
    let foreign = std::fs::read(&entries(&other_dir)[0]).unwrap();
    assert_ne!(foreign, written);

    // A digit of λ_min's bits changed (to another hex digit): believed, it would change the
    // record.
    let mut damaged = written.clone();
    let ends = String::from_utf8_lossy(&written).find("\nends ").unwrap() + "\nends ".len();
    let digit = (ends + 4..).find(|&i| written[i].is_ascii_digit()).unwrap();
    damaged[digit] ^= 0x01;
    let planted: [(&str, Plant); 4] = [
        (
            "damaged",
            Box::new(|p| std::fs::write(p, &damaged).unwrap()),
        ),
        (
            "cut short",
            Box::new(|p| std::fs::write(p, &written[..written.len() - 5]).unwrap()),
        ),
        (
            "foreign",
            Box::new(|p| std::fs::write(p, &foreign).unwrap()),
        ),
        (
            "a link to a whole entry",
            Box::new(|p| {
                let elsewhere = scratch.path().join("elsewhere.spectrum");
                std::fs::write(&elsewhere, &written).unwrap();
                std::os::unix::fs::symlink(&elsewhere, p).unwrap();
            }),
        ),
    ];
    for (what, plant) in &planted {
        std::fs::remove_file(entry).unwrap();
        plant(entry);
        // Another step, the same budget: the same entry, bit for bit, when measured again.
        let probe = probe(4, "heun", 0.9);
        assert_eq!(record(&probe, Some(&dir)), record(&probe, None), "{what}");
        let replaced = std::fs::symlink_metadata(entry).unwrap();
        assert!(replaced.file_type().is_file(), "{what}: replaced by a file");
        assert_eq!(
            std::fs::read(entry).unwrap(),
            written,
            "{what}: measured again"
        );
    }
    assert_eq!(
        std::fs::read(scratch.path().join("elsewhere.spectrum")).unwrap(),
        written,
        "a link's target is neither read nor written"
    );
}

#[test]
fn two_processes_measuring_one_operator_at_once_leave_one_whole_entry() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path().join("spectra");
    std::fs::create_dir(&dir).unwrap();
    let case = probe(6, "heun", 1.0);
    let expected = record(&case, None);
    let binary = env!("CARGO_BIN_EXE_nlsolve");
    let started: Vec<_> = (0..2)
        .map(|_| {
            let mut child = std::process::Command::new(binary)
                .args(["run", "--case", "-", "--spectra"])
                .arg(&dir)
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            use std::io::Write;
            let mut stdin = child.stdin.take().unwrap();
            stdin.write_all(case.to_string().as_bytes()).unwrap();
            child
        })
        .collect();
    for child in started {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let record: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(numbers_of(record), expected);
    }
    let [entry] = &entries(&dir)[..] else {
        panic!("{:?}", entries(&dir));
    };
    // Whole: a third process takes it as it is.
    let inode = std::fs::metadata(entry).unwrap().ino();
    assert_eq!(record(&case, Some(&dir)), expected);
    assert_eq!(std::fs::metadata(entry).unwrap().ino(), inode);
}
