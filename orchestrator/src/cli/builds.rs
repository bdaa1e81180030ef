//! The commands that look across runs of a study: `compare` (two result sets, point by point)
//! and `history` (a metric under every build), and how they find their records: the current
//! store, its history, another results directory, or a build named by its fingerprint.

use super::{claim, exit, planned, CommonArgs, CompareArgs, Failure, HistoryArgs};
use crate::analysis::compare::{self, NoiseModel};
use crate::model::study::Study;
use crate::run::plan::{Options, Planned};
use crate::store::{by_key, fingerprint_of, provenance, Store};
use serde_json::Value;
use sha2::Digest;
use std::collections::{HashMap, HashSet};
use std::process::ExitCode;

/// Records by key, as one side of a comparison holds them.
type Side = HashMap<String, Value>;

pub(super) fn compare_command(args: &CompareArgs) -> Result<ExitCode, Failure> {
    if !(args.threshold > 0.0 && args.threshold < 10.0) {
        let what = match args.threshold.is_finite() {
            true => "a fraction of change",
            false => "a finite number",
        };
        return Err(format!(
            "--threshold: {} is not {what}; give e.g. 0.1 for 10 %",
            args.threshold
        )
        .into());
    }
    // Read only until every check has passed: a refused compare takes no results directory.
    let (study, _, store, planned) = planned(&args.common, &Options::default(), false)?;
    let b = match &args.of {
        Some(build) => match build.strip_prefix("fingerprint:") {
            Some(prefix) => of_build(prefix, "--of", &study, &store)?,
            None => {
                return Err(format!(
                    "--of {build:?}: give fingerprint:PREFIX, a build's fingerprint or its start"
                )
                .into())
            }
        },
        None => by_key(store.records()),
    };
    let a = baseline(&args.against, &study, &store, &args.common)?;
    let points = repeats_by_point(&planned);
    let paired = compare::pair(&points, &a, &b);
    if paired.iter().all(|p| p.a.is_empty() || p.b.is_empty()) {
        return Err(format!(
            "--against {:?}: no point of study {} is stored on both sides",
            args.against, study.name
        )
        .into());
    }
    if paired.iter().all(|p| p.a.len() < 2 && p.b.len() < 2) {
        return Err(format!(
            "study {} runs each point once, so no interval can be formed for its timings; set `repeat` to 5 or more and run both sides again",
            study.name
        )
        .into());
    }
    for (name, side) in [("A", &a), ("B", &b)] {
        let rows = crate::analysis::collect::run_rows(&planned, side);
        if let (Some(mixed), false) = (
            crate::analysis::collect::mixed_provenance(&rows),
            args.allow_mixed,
        ) {
            return Err(format!(
                "side {name}: {mixed}; its timings would be a blend of builds or machines; rerun the stale points, or give --allow-mixed"
            )
            .into());
        }
    }
    let side = |records: Vec<&Value>| compare::machines(&records);
    let (machines_a, machines_b) = (
        side(paired.iter().flat_map(|p| p.a.iter().copied()).collect()),
        side(paired.iter().flat_map(|p| p.b.iter().copied()).collect()),
    );
    if machines_a != machines_b && !args.allow_unlike {
        return Err(format!(
            "the two sides ran on unlike machines (A: {}; B: {}), whose timings do not compare; give --allow-unlike to compare them anyway",
            machines_a.join(", "),
            machines_b.join(", ")
        )
        .into());
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
    tell_raw!("{}", compare::markdown(&comparison));
    for (side, points) in [("A", &comparison.only_a), ("B", &comparison.only_b)] {
        for point in points {
            tell!("only in {side}: {point}");
        }
    }
    let table = store.table("compare.parquet");
    crate::store::table::write_parquet_about(
        &[(&table, &compare::rows(&comparison))],
        &crate::store::table::About {
            description: &format!("{} against {}", study.name, args.against),
            notes: &[],
        },
    )?;
    let figure = store.table("compare.svg");
    let title = format!(
        "study {}: B = {} against A = {}",
        study.name,
        args.of.as_deref().unwrap_or("the current runs"),
        args.against
    );
    let chart = crate::output::compare_figure::chart(&comparison, &title, args.threshold);
    // A figure that cannot be drawn stops nothing: the table holds every verdict.
    match crate::output::draw::render(&chart) {
        Ok(svg) => crate::store::write_atomically(&figure, svg.as_bytes())?,
        Err(why) => say!("nlstudy: the comparison's figure is not drawn: {why}"),
    }
    let regressions = comparison.regressions();
    say!("{}", noise.describe());
    say!(
        "compare: {} metrics of {} points, {regressions} worse; table: {}, figure: {}",
        comparison.changes.len(),
        points.len(),
        table.display(),
        figure.display()
    );
    Ok(match regressions {
        0 => ExitCode::SUCCESS,
        _ => ExitCode::from(exit::CASE_FAILED),
    })
}

/// The drift of this study's runs on this machine: A/A pairs of its stored and superseded
/// records, those of side B left out (B is what is judged).
fn noise_model(store: &Store, b: &Side) -> NoiseModel {
    let judged: HashSet<(&str, &str)> = b
        .values()
        .map(|r| (r["key"].as_str().unwrap_or(""), provenance(r, "timestamp")))
        .collect();
    let mut known = superseded(store);
    known.extend(store.records());
    let calibration: Vec<&Value> = known
        .iter()
        .filter(|r| {
            !judged.contains(&(r["key"].as_str().unwrap_or(""), provenance(r, "timestamp")))
        })
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

/// The study's superseded records; the history's files that are not whole records are named
/// and left out.
fn superseded(store: &Store) -> Vec<Value> {
    let history = store.history();
    for unreadable in &history.unreadable {
        say!(
            "nlstudy: warning: {} is not a whole superseded record ({}); it is left out",
            unreadable.path.display(),
            unreadable.problem
        );
    }
    history.records
}

/// Each key's most recent superseded record: what the current runs replaced, whether a new
/// build or `run --force` replaced it.
fn latest_superseded(history: Vec<Value>) -> Option<Side> {
    let mut latest: Side = HashMap::new();
    for record in history {
        let Some(key) = record["key"].as_str().map(str::to_string) else {
            continue;
        };
        // A record whose time does not read is never the latest.
        let time = |r: &Value| crate::store::timestamp::of(r).unwrap_or(f64::NEG_INFINITY);
        let newer = latest
            .get(&key)
            .is_none_or(|kept| time(&record) >= time(kept));
        if newer {
            latest.insert(key, record);
        }
    }
    (!latest.is_empty()).then_some(latest)
}

/// Each point's label and the keys of its repeats, in the study's order.
fn repeats_by_point(planned: &[Planned]) -> Vec<(String, Vec<String>)> {
    let mut points: Vec<(String, Vec<String>)> = Vec::new();
    for p in planned {
        let label = p.point.label_without_repeat();
        match points.iter_mut().find(|(l, _)| *l == label) {
            Some((_, keys)) => keys.push(p.key.to_string()),
            None => points.push((label, vec![p.key.to_string()])),
        }
    }
    points
}

pub(super) fn history_command(args: &HistoryArgs) -> Result<ExitCode, Failure> {
    let (study, _, store, planned) = planned(&args.common, &Options::default(), true)?;
    let mut records = store.records();
    records.extend(superseded(&store));
    let chart = crate::output::history::chart(
        &study.name,
        &args.metric,
        &repeats_by_point(&planned),
        &records,
    )?;
    let path = store.table("history.svg");
    let svg = crate::output::draw::render(&chart).map_err(|message| Failure {
        message,
        code: exit::CASE_FAILED,
    })?;
    crate::store::write_atomically(&path, svg.as_bytes())?;
    tell!("history: {}", path.display());
    Ok(ExitCode::SUCCESS)
}

/// The stored or superseded records of the one build whose fingerprint starts with `prefix`,
/// by key; `flag` names where the prefix came from, for the message.
fn of_build(prefix: &str, flag: &str, study: &Study, store: &Store) -> Result<Side, Failure> {
    if prefix.is_empty() || !prefix.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!(
            "{flag} fingerprint:{prefix:?}: a fingerprint is hex digits (`nlsolve fingerprint`, `nlstudy history`)"
        )
        .into());
    }
    let mut records = superseded(store);
    records.extend(store.records());
    records.retain(|r| fingerprint_of(r).starts_with(prefix));
    let mut builds: Vec<&str> = records.iter().map(fingerprint_of).collect();
    builds.sort_unstable();
    builds.dedup();
    match builds.len() {
        0 => Err(format!(
            "{flag} fingerprint:{prefix}: no stored or superseded record of study {} was made by a solver whose fingerprint starts with {prefix}; `nlstudy history` shows the builds",
            study.name
        )
        .into()),
        1 => Ok(latest_superseded(records).unwrap_or_default()),
        n => Err(format!(
            "{flag} fingerprint:{prefix}: {n} builds start so ({}); give more of the fingerprint",
            builds.iter().map(|b| &b[..12]).collect::<Vec<_>>().join(", ")
        )
        .into()),
    }
}

/// `compare`'s baseline A, by key: what `--against` names (see `CompareArgs::against`).
fn baseline(
    against: &str,
    study: &Study,
    store: &Store,
    common: &CommonArgs,
) -> Result<Side, Failure> {
    if against == "history" {
        return Ok(latest_superseded(superseded(store)).ok_or_else(|| {
            format!(
                "study {} has no history yet: records move there when their points run again (a new build, or `run --force`)",
                study.name
            )
        })?);
    }
    if let Some(prefix) = against.strip_prefix("fingerprint:") {
        return of_build(prefix, "--against", study, store);
    }
    let directory = std::path::Path::new(against);
    if !directory.is_dir() {
        return Err(format!(
            "--against {against:?}: no such directory; give `history`, `fingerprint:PREFIX` or a results directory"
        )
        .into());
    }
    let other = Store::open(directory, &study.name);
    if !other.runs.is_dir() {
        return Err(format!(
            "--against {against:?}: it holds no runs of study {} ({} does not exist)",
            study.name,
            other.runs.display()
        )
        .into());
    }
    // The same study is the same file or the same text, wherever it lies (another checkout).
    if let Some(theirs) = other.owner() {
        let ours = std::fs::read(&common.study).unwrap_or_default();
        let same_text = crate::store::hex(&sha2::Sha256::digest(&ours)) == theirs.sha256;
        let same_file = std::fs::canonicalize(&common.study).is_ok_and(|p| p == theirs.study_file);
        if !(same_text || same_file) {
            return Err(format!(
                "--against {against:?}: its results of study {} were made by {}, whose text differs from {}; compare result sets of one study",
                study.name,
                theirs.study_file.display(),
                common.study.display()
            )
            .into());
        }
    }
    Ok(by_key(other.records()))
}
