//! Field output: the `.vti` frames and `.pvd` collection of `nlsolve run --write-vtk`, read back
//! by VTK's own readers (Python's `vtk`, installed by scripts/setup.sh), and the record's field
//! snapshot, both checked against the raw final field of `--write-field`.

use nonlocal_study::{nlsolve, record};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A scratch directory and its guard, which removes it however the test ends.
fn scratch() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().to_path_buf();
    (dir, path)
}

/// The frames of a `.pvd` collection as VTK reads them.
fn read_with_vtk(collection: &Path) -> Vec<Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scripts/read_vtk.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(collection)
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "VTK could not read {} (is Python's vtk installed? scripts/setup.sh installs it): {}",
        collection.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    match serde_json::from_slice(&out.stdout).expect("JSON frames") {
        Value::Array(frames) => frames,
        other => panic!("expected a list of frames, got {other}"),
    }
}

fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .expect("an array")
        .iter()
        .map(|v| v.as_f64().expect("a number"))
        .collect()
}

fn raw_field(path: &Path) -> Vec<f64> {
    std::fs::read(path)
        .expect("the field file")
        .chunks(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// `nlsolve run FLAGS`, also writing the raw field and the VTK frames into `dir`.
fn run(dir: &Path, flags: &str) -> (Value, Vec<f64>) {
    let field = dir.join("field.bin");
    let vtk = dir.join("vtk");
    let mut args = vec!["run"];
    args.extend(flags.split_whitespace());
    args.extend([
        "--write-field",
        field.to_str().expect("utf-8 path"),
        "--write-vtk",
        vtk.to_str().expect("utf-8 path"),
    ]);
    let out = nlsolve(&args, None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (record(&out), raw_field(&field))
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn vtk_frames_hold_the_field_at_each_output_time() {
    let (_scratch, dir) = scratch();
    let (record, field) = run(
        &dir,
        "--dim 2 --n 32 --m 3 --t-end 0.01 --cfl 0.5 --vtk-every 0.004 --diagnostics-every 0.004",
    );
    let frames = read_with_vtk(&dir.join("vtk/u.pvd"));
    let h = 1.0 / 32.0;
    // Frames at the times c_tot(t) is sampled at: t = 0, the first steps past 0.004 and 0.008,
    // and t_end; each holds h² Σ u = c_tot(t).
    let times = numbers(&record["c_tot"]["time"]);
    let c_tot = numbers(&record["c_tot"]["c_tot"]);
    assert_eq!(frames.len(), 4);
    for ((frame, &t), &mass) in frames.iter().zip(&times).zip(&c_tot) {
        assert_eq!(frame["time"].as_f64(), Some(t));
        assert_eq!(numbers(&frame["dimensions"]), [32.0, 32.0, 1.0]);
        assert_eq!(numbers(&frame["origin"]), [h / 2.0, h / 2.0, 0.0]);
        assert_eq!(numbers(&frame["spacing"]), [h, h, h]);
        let sum: f64 = numbers(&frame["u"]).iter().sum::<f64>() * h * h;
        assert!(
            (sum - mass).abs() <= 1e-14,
            "h² Σ u = {sum}, c_tot = {mass}"
        );
    }
    // The first frame is u₀ = sin(2πx) sin(2πy); the last, bit for bit, the final field.
    let u0 = numbers(&frames[0]["u"]);
    let tau = 2.0 * std::f64::consts::PI;
    for (i, &u) in u0.iter().enumerate() {
        let (x, y) = (((i % 32) as f64 + 0.5) * h, ((i / 32) as f64 + 0.5) * h);
        assert!((u - (tau * x).sin() * (tau * y).sin()).abs() < 1e-15);
    }
    assert_eq!(numbers(&frames[3]["u"]), field);
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn without_vtk_every_the_final_field_alone_is_written_on_its_own_grid() {
    let (_scratch, dir) = scratch();
    let (record, field) = run(
        &dir,
        "--method fd_explicit --problem eigenmode --dim 1 --n 99 --t-end 0.05 --cfl 0.9",
    );
    let frames = read_with_vtk(&dir.join("vtk/u.pvd"));
    assert_eq!(frames.len(), 1);
    let t_end = record["steps_done"].as_f64().unwrap() * record["dt"].as_f64().unwrap();
    assert_eq!(frames[0]["time"].as_f64(), Some(t_end));
    // FD stores the interior nodes of (−L/2, L/2) with h = L/(n + 1): the first at −1 + h.
    let h = 2.0 / 100.0;
    assert_eq!(numbers(&frames[0]["dimensions"]), [99.0, 1.0, 1.0]);
    let origin = numbers(&frames[0]["origin"]);
    assert!((origin[0] - (-1.0 + h)).abs() < 1e-15 && origin[1] == 0.0);
    assert_eq!(numbers(&frames[0]["u"]), field);
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn the_field_snapshot_is_block_means_of_the_final_field_and_its_error() {
    let (_scratch, dir) = scratch();
    let (record, field) = run(
        &dir,
        "--dim 2 --n 40 --m 3 --t-end 0.01 --cfl 0.5 --field-snapshot 16",
    );
    // n = 40 in at most 16 blocks per side: blocks of 3, the last of one node; 14 per side.
    let snapshot = &record["field"];
    assert_eq!(
        (snapshot["nx"].as_u64(), snapshot["ny"].as_u64()),
        (Some(14), Some(14))
    );
    assert_eq!(
        (snapshot["lower"].as_f64(), snapshot["upper"].as_f64()),
        (Some(0.0), Some(1.0))
    );
    let values = numbers(&snapshot["values"]);
    let mean = |bx: usize, by: usize| {
        let nodes: Vec<f64> = (by * 3..(by * 3 + 3).min(40))
            .flat_map(|y| (bx * 3..(bx * 3 + 3).min(40)).map(move |x| (x, y)))
            .map(|(x, y)| field[y * 40 + x])
            .collect();
        nodes.iter().sum::<f64>() / nodes.len() as f64
    };
    for by in 0..14 {
        for bx in 0..14 {
            assert!((values[by * 14 + bx] - mean(bx, by)).abs() < 1e-15);
        }
    }
    // A block mean of the error is bounded by the max-norm error, and the error is not zero.
    let error = numbers(&snapshot["error"]);
    let largest = error.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let error_max = record["error_max"].as_f64().unwrap();
    assert!(
        largest > 0.0 && largest <= error_max,
        "{largest} vs {error_max}"
    );
}
