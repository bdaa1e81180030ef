//! `nlstudy history`: a study's points under every run of them that is kept (the current records
//! and the superseded ones in `history/`), each point's metric against the time of the run that
//! measured it, a dashed line where each solver build first ran, as asv draws benchmarks against
//! commits. A rerun of one build (`run --force`) is a run of its own: the drift between two of
//! them is what `compare` calibrates its noise floor by.

use crate::output::draw::{Axis, Chart, Guide, Panel, Series};
use crate::statistics::median;
use crate::store::{fingerprint_of, timestamp};
use schema::record::{column, Stored};
use std::collections::{BTreeMap, HashMap};

/// A run: the build that made it and the `nlstudy` process (`run_id`; records made before it was
/// kept are one run per build).
type Run = (String, String);

fn run_of(record: &Stored) -> Run {
    let id = record.run_id.as_deref().unwrap_or("");
    (fingerprint_of(record).to_string(), id.to_string())
}

/// The chart of `metric` (a record field, or `<field>_median` for the median over the
/// repeats) for each point (its repeats' keys), over the runs of `records`.
pub fn chart(
    study: &str,
    metric: &str,
    points: &[(String, Vec<String>)],
    records: &[Stored],
) -> Result<Chart, String> {
    let field = metric.strip_suffix("_median").unwrap_or(metric);
    // Each run at the median time of its records; records whose time does not read are left out.
    let mut times: BTreeMap<Run, Vec<f64>> = BTreeMap::new();
    for record in records {
        if let Some(t) = timestamp::record_time(record) {
            times.entry(run_of(record)).or_default().push(t);
        }
    }
    let at: BTreeMap<Run, f64> = times
        .iter()
        .map(|(run, t)| (run.clone(), median(t)))
        .collect();
    let origin = at.values().copied().fold(f64::INFINITY, f64::min);
    let last = at.values().copied().fold(f64::NEG_INFINITY, f64::max);
    let (unit, seconds) = unit_for(last - origin);
    let x = |t: f64| (t - origin) / seconds;
    let mut by_key: HashMap<&str, Vec<&Stored>> = HashMap::new();
    for record in records {
        by_key.entry(record.key.as_str()).or_default().push(record);
    }
    let mut series = Vec::new();
    for (label, keys) in points {
        let mut by_run: BTreeMap<Run, Vec<f64>> = BTreeMap::new();
        let ran = keys
            .iter()
            .flat_map(|key| by_key.get(key.as_str()))
            .flatten();
        for record in ran {
            let value = column(record, field).and_then(|v| v.as_f64());
            if let Some(v) = value.filter(|v| v.is_finite() && *v > 0.0) {
                by_run.entry(run_of(record)).or_default().push(v);
            }
        }
        let mut line: Vec<(f64, f64)> = by_run
            .iter()
            .filter_map(|(run, values)| Some((x(*at.get(run)?), median(values))))
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !line.is_empty() {
            series.push(Series::line(label.clone(), line));
        }
    }
    if series.is_empty() {
        return Err(format!(
            "no stored record of study {study} has a positive `{field}` with a readable time; name a field of the records, or `<field>_median`"
        ));
    }
    // Each build at its first run.
    let mut first: BTreeMap<&str, f64> = BTreeMap::new();
    for ((build, _), t) in &at {
        let entry = first.entry(build.as_str()).or_insert(*t);
        *entry = entry.min(*t);
    }
    let mut in_order: Vec<(&str, f64)> = first.into_iter().collect();
    in_order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let builds: Vec<Guide> = in_order
        .iter()
        .enumerate()
        .map(|(k, (build, t))| Guide::Vertical {
            label: match build.is_empty() {
                true => format!("build {}: unknown", k + 1),
                false => format!("build {}: {}", k + 1, crate::run::plan::short(build)),
            },
            x: x(*t),
        })
        .collect();
    Ok(Chart::new(
        format!("study {study}: {metric} under each run"),
        format!("{} runs of {} builds", at.len(), in_order.len()),
        vec![Panel {
            title: String::new(),
            x: Axis {
                include: vec![0.0],
                ..Axis::linear(format!("{unit} since the first run"))
            },
            y: Axis {
                log: true,
                ..Axis::linear(metric)
            },
            series,
            guides: builds,
            heat: None,
        }],
    ))
}

/// The unit a span of `seconds` reads in, and its length in seconds.
fn unit_for(seconds: f64) -> (&'static str, f64) {
    match seconds {
        s if s < 2.0 * 3600.0 => ("minutes", 60.0),
        s if s < 3.0 * 86_400.0 => ("hours", 3600.0),
        _ => ("days", 86_400.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record;
    use serde_json::json;

    #[test]
    fn each_point_follows_its_metric_over_the_runs() {
        let run = |key: &str, build: &str, id: &str, stamp: &str, step: f64| {
            record(json!({"key": key, "step_s": step, "run_id": id,
                   "provenance": {"fingerprint": build, "timestamp": stamp}}))
        };
        let (old, new) = ("0a".repeat(32), "0b".repeat(32));
        let records = [
            run("a0", &old, "1", "2026-01-01T00:00:00Z", 2.0),
            run("a1", &old, "1", "2026-01-01T00:00:00Z", 4.0),
            run("a0", &old, "2", "2026-01-02T00:00:00Z", 2.5),
            run("a0", &new, "3", "2026-01-05T00:00:00Z", 1.0),
            run("b0", &new, "3", "2026-01-05T00:00:00Z", 5.0),
            run("b0", &new, "4", "2026-01-05T00:00:00NaNZ", 9.0),
        ];
        let points = [
            ("n=8".to_string(), vec!["a0".into(), "a1".into()]),
            ("n=16".to_string(), vec!["b0".into()]),
        ];
        let drawn = chart("s", "step_s_median", &points, &records).unwrap();
        assert_eq!(drawn.panels[0].x.label, "days since the first run");
        let series = &drawn.panels[0].series;
        assert_eq!(
            series[0].points,
            [(0.0, 3.0), (1.0, 2.5), (4.0, 1.0)],
            "each run of the old build, then the new"
        );
        assert_eq!(
            series[1].points,
            [(4.0, 5.0)],
            "a record whose time does not read is left out"
        );
        assert_eq!(drawn.panels[0].guides.len(), 2, "one line per build");
        assert!(chart("s", "nothing", &points, &records).is_err());
        // Two runs of one build minutes apart read in minutes.
        let minutes = [
            run("a0", &old, "1", "2026-01-01T00:00:00Z", 2.0),
            run("a0", &old, "2", "2026-01-01T00:03:00Z", 2.0),
        ];
        let drawn = chart("s", "step_s", &points, &minutes).unwrap();
        assert_eq!(drawn.panels[0].series[0].points, [(0.0, 2.0), (3.0, 2.0)]);
    }
}
