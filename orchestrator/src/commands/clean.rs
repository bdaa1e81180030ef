//! `nlstudy clean`: what a study's results directory holds that the study no longer makes.
//! Figures no spec draws are removed (they are drawn from the tables, and would be mistaken for
//! current ones), and so are the run timelines older than the latest few (each run adds one);
//! records no point of the study has are listed, and deleted only when asked: they were
//! computed, and an edit of the study may bring their points back.

use super::failure::Failure;
use super::open::planned;
use crate::cli::args::CleanArgs;
use crate::console::counted;
use crate::console::Reply;
use crate::model::study::Study;
use crate::run::plan::{Options, Planned};
use crate::store::fs::remove_where;
use crate::store::timeline::{self, LATEST};
use crate::store::{Fault, Store, CHECKPOINT};
use schema::record::Stored;
use serde_json::Value;
use std::collections::HashSet;

pub(super) fn clean(args: &CleanArgs) -> Result<Reply, Failure> {
    let (study, _, store, planned) = planned(&args.common, &Options::default(), true)?;
    let cleaned = clean_results(&study, &store, &planned, args.yes)?;
    let mut reply = Reply::default();
    for figure in &cleaned.figures {
        reply.line(format!(
            "removed figures/{figure}: no figure of the study draws it"
        ));
    }
    if cleaned.timelines.0 > 0 {
        reply.line(format!(
            "removed {} older than the latest {LATEST} ({} kB): `status --timeline`, `report` and `plan --simulate` read the latest",
            counted(cleaned.timelines.0, "timeline"),
            crate::console::number((cleaned.timelines.1 as f64 / 1e3).ceil())
        ));
    }
    for key in &cleaned.checkpoints {
        reply.line(format!(
            "removed runs/.work/{key}.{CHECKPOINT}: its point is stored or no point of the study"
        ));
    }
    if cleaned.orphans.is_empty() {
        reply.line(format!(
            "every stored record is a point of study {}",
            study.name
        ));
        return Ok(reply);
    }
    for (key, case) in &cleaned.orphans {
        // A record on disk may hold anything: escaped for the terminal.
        reply.line(format!("{key}  {}", case.escape_debug()));
    }
    let count = cleaned.orphans.len();
    reply.line(match cleaned.deleted {
        true => format!(
            "deleted {count} records that are no point of study {}",
            study.name
        ),
        false => format!(
            "{count} stored records are no point of study {} (removed from its sweep, or run by another solver version); `nlstudy clean --yes` deletes them",
            study.name
        ),
    });
    Ok(reply)
}

/// What `clean` removed and found.
struct Cleaned {
    /// Figure files removed (`old.svg` and its stamp).
    figures: Vec<String>,
    /// Records of no current point: (key, label of their case).
    orphans: Vec<(String, String)>,
    /// Whether the orphans were deleted.
    deleted: bool,
    /// Keys whose checkpoints were removed: no run will resume them.
    checkpoints: Vec<String>,
    /// Run timelines removed, and their bytes: all but the latest `LATEST`.
    timelines: (usize, u64),
}

fn clean_results(
    study: &Study,
    store: &Store,
    planned: &[Planned],
    delete_orphans: bool,
) -> Result<Cleaned, Fault> {
    let _outputs = store.lock_outputs()?;
    let figures = store.table("figures");
    let drawn: HashSet<String> = study
        .figures
        .iter()
        .flat_map(|f| crate::output::plot::files(&f.name))
        .collect();
    let stale =
        |name: &str| (name.ends_with(".svg") || name.ends_with(".stamp")) && !drawn.contains(name);
    let mut removed: Vec<String> = std::fs::read_dir(&figures)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| stale(name) && name.ends_with(".svg"))
        .collect();
    removed.sort();
    remove_where(&figures, stale);

    let current: HashSet<&str> = planned.iter().map(|p| p.key.as_str()).collect();
    let mut orphans: Vec<(String, String)> = store
        .records()
        .iter()
        .filter(|record| !current.contains(record.key.as_str()))
        .map(|record| (record.key.clone(), case_label(record)))
        .collect();
    orphans.sort();
    if delete_orphans {
        let doomed: HashSet<String> = orphans.iter().map(|(k, _)| k.clone()).collect();
        store.compact(&doomed)?;
    }
    Ok(Cleaned {
        figures: removed,
        orphans,
        deleted: delete_orphans,
        checkpoints: stale_checkpoints(store, planned)?,
        timelines: timeline::remove_older(store, LATEST),
    })
}

/// Removes the checkpoints no run will resume (`--keep-checkpoints` kept them, or the study
/// dropped their point): those of points that are stored or not in the study, and that no
/// process is running now (a running solver's checkpoint is its own). Returns their keys.
fn stale_checkpoints(store: &Store, planned: &[Planned]) -> Result<Vec<String>, Fault> {
    let to_run: HashSet<&str> = planned
        .iter()
        .filter(|p| p.runs())
        .map(|p| p.key.as_str())
        .collect();
    let keys = store
        .scratch_keys(CHECKPOINT)
        .into_iter()
        .filter(|key| !to_run.contains(key.as_str()));
    let mut removed = Vec::new();
    for key in keys {
        if let Some(_lock) = store.lock(&key)? {
            store.remove_checkpoint(&key);
            removed.push(key);
        }
    }
    Ok(removed)
}

/// `method=nonlocal n=64 …`: a record's case, for the list.
fn case_label(record: &Stored) -> String {
    let Some(case) = record.case().as_object() else {
        return String::new();
    };
    case.iter()
        .filter(|(_, v)| !v.is_null())
        .map(|(k, v)| match v {
            Value::String(s) => format!("{k}={s}"),
            v => format!("{k}={v}"),
        })
        .collect::<Vec<_>>()
        .join(" ")
}
