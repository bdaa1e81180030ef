//! `nlstudy compare`: two result sets of a study, point by point, with verdicts only where a
//! change clears the noise of this machine; exits 1 when something got worse.

use super::builds::{latest_superseded, of_build, repeats_by_point, superseded, Side};
use super::failure::Failure;
use super::open::{claim, planned};
use crate::analysis::compare::{self, NoiseModel};
use crate::cli::args::{CommonArgs, CompareArgs};
use crate::console::Reply;
use crate::model::study::Study;
use crate::run::plan::Options;
use crate::store::{by_key, Store};
use schema::record::Stored;
use sha2::Digest;
use std::collections::HashSet;

pub(super) fn compare(args: &CompareArgs) -> Result<Reply, Failure> {
    if !(args.threshold > 0.0 && args.threshold < 10.0) {
        let what = match args.threshold.is_finite() {
            true => "a fraction of change",
            false => "a finite number",
        };
        return Err(Failure::BadInput(format!(
            "--threshold: {} is not {what}; give e.g. 0.1 for 10 %",
            schema::text::exact(args.threshold)
        )));
    }
    if let Some(path) = args.against.strip_prefix("solver:") {
        return super::interleaved::compare(args, std::path::Path::new(path));
    }
    // Read only until every check has passed: a refused compare takes no results directory.
    let (study, _, store, planned) = planned(&args.common, &Options::default(), false)?;
    let b = match &args.of {
        Some(build) => match build.strip_prefix("fingerprint:") {
            Some(prefix) => of_build(prefix, "--of", &study, &store)?,
            None => {
                return Err(Failure::BadInput(format!(
                    "--of {build:?}: give fingerprint:PREFIX, a build's fingerprint or its start"
                )))
            }
        },
        None => by_key(store.records()),
    };
    let a = baseline(&args.against, &study, &store, &args.common)?;
    let points = repeats_by_point(&planned);
    // A side that mixes builds or machines is said first: that is why its points may not
    // pair with the other side's.
    for (name, side) in [("A", &a), ("B", &b)] {
        let rows = crate::analysis::collect::run_rows(&planned, side);
        if let (Some(mixed), false) = (
            crate::analysis::collect::mixed_provenance(&rows),
            args.allow_mixed,
        ) {
            return Err(Failure::BadInput(format!(
                "side {name}: {mixed}; its timings would be a blend of builds or machines; rerun the stale points, or give --allow-mixed"
            )));
        }
    }
    let paired = compare::pair(&points, &a, &b);
    if paired.iter().all(|p| p.a.is_empty() || p.b.is_empty()) {
        return Err(Failure::BadInput(format!(
            "--against {:?}: no point of study {} is stored on both sides",
            args.against, study.name
        )));
    }
    if paired.iter().all(|p| p.a.len() < 2 && p.b.len() < 2) {
        return Err(Failure::BadInput(format!(
            "study {} runs each point once, so no interval can be formed for its timings; set `repeat` to 5 or more and run both sides again",
            study.name
        )));
    }
    let side = |records: Vec<&Stored>| compare::machines(&records);
    let (machines_a, machines_b) = (
        side(paired.iter().flat_map(|p| p.a.iter().copied()).collect()),
        side(paired.iter().flat_map(|p| p.b.iter().copied()).collect()),
    );
    if machines_a != machines_b && !args.allow_unlike {
        return Err(Failure::BadInput(format!(
            "the two sides ran on unlike machines (A: {}; B: {}), whose timings do not compare; give --allow-unlike to compare them anyway",
            machines_a.join(", "),
            machines_b.join(", ")
        )));
    }
    let noise = noise_model(&store, &b);
    let mut comparison = compare::compare(&paired, args.threshold, &noise);
    let summary = |side: &Side| crate::analysis::collect::summary_of(&planned, side);
    let (summary_a, summary_b) = (summary(&a), summary(&b));
    comparison.changes.extend(compare::compare_speedups(
        &paired,
        &scaling_baselines(&summary_a),
        args.threshold,
        &noise,
    ));
    comparison
        .changes
        .extend(compare::compare_orders(&summary_a, &summary_b));
    claim(&args.common, &study, &store, true)?;
    let title = format!(
        "study {}: B = {} against A = {}",
        study.name,
        args.of.as_deref().unwrap_or("the current runs"),
        args.against
    );
    let mut reply = Reply::default();
    reply.note(noise.describe());
    super::verdicts::report(
        reply,
        &comparison,
        &study,
        &store,
        &args.against,
        &title,
        args.threshold,
        points.len(),
    )
}

/// The drift of this study's runs on this machine: A/A pairs of its stored and superseded
/// records, those of side B left out (B is what is judged).
fn noise_model(store: &Store, b: &Side) -> NoiseModel {
    let made = |r: &Stored| -> (String, String) {
        let timestamp = r.provenance().map(|p| p.timestamp.clone());
        (r.key.clone(), timestamp.unwrap_or_default())
    };
    let judged: HashSet<(String, String)> = b.values().map(made).collect();
    let mut known = superseded(store);
    known.extend(store.records());
    let calibration: Vec<&Stored> = known
        .iter()
        .filter(|r| !judged.contains(&made(r)))
        .collect();
    NoiseModel::calibrate(&calibration)
}

/// Each point with a speedup, and the point of its scaling series it is measured against (the
/// one with the baseline's workers).
fn scaling_baselines(summary: &[crate::store::table::Row]) -> Vec<(String, String)> {
    summary
        .iter()
        .filter(|row| row.number("speedup").is_some())
        .filter_map(|row| {
            let series = row.text("scaling_series")?;
            let workers = row.count("baseline_workers")?;
            let base = summary.iter().find(|r| {
                r.text("scaling_series") == Some(series) && r.count("workers") == Some(workers)
            })?;
            let (point, base) = (row.text("point")?, base.text("point")?);
            (point != base).then(|| (point.to_string(), base.to_string()))
        })
        .collect()
}

/// `compare`'s baseline A, by key: what `--against` names (see `CompareArgs::against`).
fn baseline(
    against: &str,
    study: &Study,
    store: &Store,
    common: &CommonArgs,
) -> Result<Side, Failure> {
    if against == "history" {
        return latest_superseded(superseded(store)).ok_or_else(|| {
            Failure::BadInput(format!(
                "study {} has no history yet: records move there when their points run again (a new build, or `run --force`)",
                study.name
            ))
        });
    }
    if let Some(prefix) = against.strip_prefix("fingerprint:") {
        return of_build(prefix, "--against", study, store);
    }
    let directory = std::path::Path::new(against);
    if !directory.is_dir() {
        return Err(Failure::BadInput(format!(
            "--against {against:?}: no such directory; give `history`, `fingerprint:PREFIX` or a results directory"
        )));
    }
    let other = Store::open(directory, &study.name);
    if !other.runs.is_dir() {
        return Err(Failure::BadInput(format!(
            "--against {against:?}: it holds no runs of study {} ({} does not exist)",
            study.name,
            other.runs.display()
        )));
    }
    // The same study is the same file or the same text, wherever it lies (another checkout).
    if let Some(theirs) = other.owner() {
        let same_text = crate::store::hex(&sha2::Sha256::digest(&study.text)) == theirs.sha256;
        let same_file = std::fs::canonicalize(&common.study).is_ok_and(|p| p == theirs.study_file);
        if !(same_text || same_file) {
            return Err(Failure::BadInput(format!(
                "--against {against:?}: its results of study {} were made by {}, whose text differs from {}; compare result sets of one study",
                study.name,
                theirs.study_file.display(),
                common.study.display()
            )));
        }
    }
    Ok(by_key(other.records()))
}
