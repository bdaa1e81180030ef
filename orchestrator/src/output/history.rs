//! `nlstudy history`: a study's points under every solver build that ran them (the current
//! records and the superseded ones in `history/`), each point's metric against the date its
//! build first ran, as asv draws benchmarks against commits.

use crate::output::draw::{Axis, Chart, Guide, Panel, Series};
use crate::statistics::median;
use crate::store::{fingerprint_of, provenance};
use serde_json::Value;
use std::collections::BTreeMap;

/// The chart of `metric` (a record field, or `<field>_median` for the median over the
/// repeats) for each point (its repeats' keys), over the fingerprints of `records`.
pub fn chart(
    study: &str,
    metric: &str,
    points: &[(String, Vec<String>)],
    records: &[Value],
) -> Result<Chart, String> {
    let field = metric.strip_suffix("_median").unwrap_or(metric);
    // Each build by its first run's day.
    let mut first_day: BTreeMap<String, f64> = BTreeMap::new();
    for record in records {
        let Some(day) = day_of(provenance(record, "timestamp")) else {
            continue;
        };
        let entry = first_day
            .entry(fingerprint_of(record).to_string())
            .or_insert(day);
        *entry = entry.min(day);
    }
    let origin = first_day.values().copied().fold(f64::INFINITY, f64::min);
    let mut series = Vec::new();
    for (label, keys) in points {
        let mut by_build: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for record in records.iter().filter(|r| {
            r.get("key")
                .and_then(Value::as_str)
                .is_some_and(|k| keys.iter().any(|key| key == k))
        }) {
            if let Some(x) = record
                .get(field)
                .and_then(Value::as_f64)
                .filter(|x| x.is_finite())
            {
                by_build
                    .entry(fingerprint_of(record).to_string())
                    .or_default()
                    .push(x);
            }
        }
        let mut line: Vec<(f64, f64)> = by_build
            .iter()
            .filter_map(|(build, values)| Some((first_day.get(build)? - origin, median(values))))
            .collect();
        line.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !line.is_empty() {
            series.push(Series::line(label.clone(), line));
        }
    }
    if series.is_empty() {
        return Err(format!(
            "no stored record of study {study} has `{field}`; name a field of the records, or `<field>_median`"
        ));
    }
    let mut in_order: Vec<(&String, &f64)> = first_day.iter().collect();
    in_order.sort_by(|a, b| a.1.total_cmp(b.1));
    let builds: Vec<Guide> = in_order
        .iter()
        .enumerate()
        .map(|(k, (build, day))| Guide::Vertical {
            label: format!("build {}: {}", k + 1, crate::run::plan::short(build)),
            x: *day - origin,
        })
        .collect();
    Ok(Chart::new(
        format!("study {study}: {metric} under each solver build"),
        format!(
            "{} builds; x: days since the first one ran",
            first_day.len()
        ),
        vec![Panel {
            title: String::new(),
            x: Axis {
                label: "days since the first build ran".into(),
                log: false,
                include: vec![0.0],
                whole: false,
            },
            y: Axis {
                label: metric.to_string(),
                log: true,
                include: vec![],
                whole: false,
            },
            series,
            guides: builds,
            heat: None,
        }],
    ))
}

/// Days since 1970 of an RFC 3339 UTC time such as `2026-11-23T22:35:40Z`.
fn day_of(stamp: &str) -> Option<f64> {
    let (date, time) = stamp.trim_end_matches('Z').split_once('T')?;
    let mut date = date.split('-').map(|p| p.parse::<i64>());
    let (y, m, d) = (date.next()?.ok()?, date.next()?.ok()?, date.next()?.ok()?);
    let mut clock = time.split(':').map(|p| p.parse::<f64>());
    let (h, min, s) = (
        clock.next()?.ok()?,
        clock.next()?.ok()?,
        clock.next()?.ok()?,
    );
    // Days from civil (Howard Hinnant's algorithm).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let day_of_year = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + d - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    let days = era * 146_097 + day_of_era - 719_468;
    Some(days as f64 + (h * 3600.0 + min * 60.0 + s) / 86_400.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn each_point_follows_its_metric_over_the_builds() {
        assert_eq!(day_of("1970-01-02T12:00:00Z"), Some(1.5));
        assert_eq!(day_of("2000-03-01T00:00:00Z"), Some(11_017.0));
        let run = |key: &str, build: &str, stamp: &str, step: f64| json!({"key": key, "step_s": step, "provenance": {"fingerprint": build, "timestamp": stamp}});
        let (old, new) = ("0a".repeat(32), "0b".repeat(32));
        let records = [
            run("a0", &old, "2026-01-01T00:00:00Z", 2.0),
            run("a1", &old, "2026-01-01T00:01:00Z", 4.0),
            run("a0", &new, "2026-01-03T00:00:00Z", 1.0),
            run("b0", &new, "2026-01-03T00:02:00Z", 5.0),
        ];
        let points = [
            ("n=8".to_string(), vec!["a0".into(), "a1".into()]),
            ("n=16".to_string(), vec!["b0".into()]),
        ];
        let drawn = chart("s", "step_s_median", &points, &records).unwrap();
        let series = &drawn.panels[0].series;
        assert_eq!(
            series[0].points,
            [(0.0, 3.0), (2.0, 1.0)],
            "median of the old build's repeats, then the new"
        );
        assert_eq!(series[1].points, [(2.0, 5.0)], "at its build's first day");
        assert_eq!(drawn.panels[0].guides.len(), 2, "one line per build");
        assert!(chart("s", "nothing", &points, &records).is_err());
    }
}
