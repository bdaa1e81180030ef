//! The files `--write-vtk` asks for, each written whole or not at all.

use crate::ErrorExit;
use solver::output::vtk;
use solver::Outcome;
use std::path::Path;

/// Writes the outcome's frames (or its final field) into `dir` as `.vti` files, then the `.pvd`
/// collection: a reader that finds the collection finds every frame it lists.
pub(crate) fn write_vtk(dir: &Path, outcome: &Outcome) -> Result<(), ErrorExit> {
    let t_final = outcome.record.steps_done as f64 * outcome.record.resolved.dt;
    let frames: Vec<(f64, &[f64])> = match outcome.frames.is_empty() {
        true => vec![(t_final, &outcome.field)],
        false => outcome
            .frames
            .iter()
            .map(|f| (f.time, &f.values[..]))
            .collect(),
    };
    std::fs::create_dir_all(dir).map_err(|e| {
        ErrorExit::Output(format!(
            "cannot create {}: {e}; check the path given to --write-vtk",
            dir.display()
        ))
    })?;
    let names = vtk::frame_names(frames.len());
    for ((_, values), name) in frames.iter().zip(&names) {
        let bytes = vtk::image_data(&outcome.lattice, "u", values);
        write_atomically(&dir.join(name), &bytes, "--write-vtk")?;
    }
    let entries: Vec<(f64, String)> = frames.iter().map(|f| f.0).zip(names).collect();
    let collection = vtk::collection(&entries);
    write_atomically(&dir.join("u.pvd"), collection.as_bytes(), "--write-vtk")
}

/// Writes `bytes` to `path` whole or not at all (`schema::atomic`, as nlstudy writes); a
/// failure names the path and exits with `exit::IO` (an output lost, not a bad case).
pub(crate) fn write_atomically(path: &Path, bytes: &[u8], flag: &str) -> Result<(), ErrorExit> {
    schema::atomic::write_atomically(path, bytes).map_err(|(_, e)| {
        ErrorExit::Output(format!(
            "cannot write {}: {e}; check the path given to {flag}",
            path.display()
        ))
    })
}
