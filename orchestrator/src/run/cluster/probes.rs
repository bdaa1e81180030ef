//! A job's probes, written beside its script: for each key of an adaptive study's round, the
//! point of the sweep its search starts from and the values it probes. With them the job plans
//! its share at once (`search::plan_given`); without, it replays every search from the store to
//! find them, seconds a round and more each round (docs/performance.md). The file is a hint,
//! never trusted: a probe that no longer plans to its key (the study or the solver changed),
//! or a file unreadable or missing a key, sends the job back to the replay.

use crate::run::plan::{Planned, ProbeOf};
use crate::store::fs::{read_regular, FileError, RECORD_CAP};
use crate::store::write_atomically;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// What the file holds of one probe. Its values are their bits: a decimal written and read
/// again need not be the same double, and the key is of the double.
#[derive(Serialize, Deserialize)]
struct Entry {
    key: String,
    origin: usize,
    at: Vec<u64>,
}

/// The probes file of the job script `script`: `<job>.probes.json` beside it.
pub fn beside(script: &Path) -> PathBuf {
    script.with_extension("probes.json")
}

/// Whether `path` is a probes file (archived with the scripts of its submit).
pub fn is_probes_file(path: &Path) -> bool {
    path.file_name()
        .and_then(|name| name.to_str())
        .is_some_and(|name| name.ends_with(".probes.json"))
}

/// Writes the probes of `points` to `path`; false (nothing written) when some point is no
/// probe of a search (a fixed sweep's point, an error target's timing repeat): such a job plans
/// the study as a job always did.
pub fn write<'a>(
    path: &Path,
    points: impl IntoIterator<Item = &'a Planned>,
) -> Result<bool, FileError> {
    let entries: Option<Vec<Entry>> = points
        .into_iter()
        .map(|p| {
            let probe = p.probe.as_ref()?;
            Some(Entry {
                key: p.key.to_string(),
                origin: probe.origin,
                at: probe.at.iter().map(|v| v.to_bits()).collect(),
            })
        })
        .collect();
    let Some(entries) = entries else {
        return Ok(false);
    };
    let text = serde_json::to_string(&entries).expect("probes print");
    write_atomically(path, text.as_bytes())?;
    Ok(true)
}

/// The probes of `only` in the file `path`, each with its key; an error says why the file
/// does not give them all.
pub fn read(path: &Path, only: &HashSet<String>) -> Result<Vec<(String, ProbeOf)>, String> {
    let text = read_regular(path, RECORD_CAP)?;
    let entries: Vec<Entry> = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let mut given: Vec<(String, ProbeOf)> = Vec::with_capacity(only.len());
    let mut seen = HashSet::with_capacity(only.len());
    for entry in entries {
        if only.contains(&entry.key) && seen.insert(entry.key.clone()) {
            let at = entry.at.into_iter().map(f64::from_bits).collect();
            let probe = ProbeOf {
                origin: entry.origin,
                at,
            };
            given.push((entry.key, probe));
        }
    }
    match given.len() == only.len() {
        true => Ok(given),
        false => Err(format!(
            "it gives {} of the job's {} keys",
            given.len(),
            only.len()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::study::Point;
    use crate::run::plan::{Decision, Reason};

    fn planned(key: &str, probe: Option<ProbeOf>) -> Planned {
        Planned {
            point: Point::from_fields(Default::default()),
            case: Err("not checked".into()),
            key: crate::store::case_id_and_key(key, "", 0).1,
            case_id: Default::default(),
            decision: Decision::Run(Reason::Missing),
            probe,
        }
    }

    /// Values come back with their bits (0.1 + 0.2 is no short decimal, nor is a NaN's
    /// payload); only the job's keys are read, and a file without one of them is refused.
    #[test]
    fn probes_come_back_bit_for_bit_and_a_missing_key_is_said() {
        let dir = tempfile::tempdir().unwrap();
        let path = beside(&dir.path().join("job.sbatch"));
        assert!(is_probes_file(&path));
        let at = |v: Vec<f64>| Some(ProbeOf { origin: 3, at: v });
        let points = [
            planned(
                "a",
                at(vec![0.1 + 0.2, f64::from_bits(0x7ff8_0000_0000_0001)]),
            ),
            planned("b", at(vec![-0.0, 1e-300])),
            planned("c", at(vec![2.0, 3.0])),
        ];
        assert!(write(&path, &points).unwrap());
        let only: HashSet<String> = [&points[0], &points[1]]
            .iter()
            .map(|p| p.key.to_string())
            .collect();
        let given = read(&path, &only).unwrap();
        assert_eq!(given.len(), 2);
        for (key, probe) in given {
            let p = points.iter().find(|p| p.key.as_str() == key).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let expected = p.probe.as_ref().unwrap();
            assert_eq!(probe.origin, expected.origin);
            assert_eq!(bits(&probe.at), bits(&expected.at));
        }
        let mut more = only.clone();
        more.insert("ffff".into());
        assert_eq!(
            read(&path, &more).unwrap_err(),
            "it gives 2 of the job's 3 keys"
        );
        // A point that is no probe: no file.
        let other = dir.path().join("other.probes.json");
        let fixed = [points[0].clone(), planned("d", None)];
        assert!(!write(&other, &fixed).unwrap());
        assert!(!other.exists());
    }
}
