//! `nlstudy clean`: what a study's results directory holds that the study no longer makes.
//! Figures no spec draws are removed (they are drawn from the tables, and would be mistaken for
//! current ones); records no point of the study has are listed, and deleted only when asked:
//! they were computed, and an edit of the study may bring their points back.

use crate::model::study::Study;
use crate::run::plan::Planned;
use crate::store::fs::remove_where;
use crate::store::Fault;
use crate::store::Store;
use serde_json::Value;
use std::collections::HashSet;

pub struct Cleaned {
    /// Figure files removed (`old.svg` and its stamp).
    pub figures: Vec<String>,
    /// Records of no current point: (key, label of their case).
    pub orphans: Vec<(String, String)>,
    /// Whether the orphans were deleted.
    pub deleted: bool,
}

pub fn clean(
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
        .filter_map(|record| {
            let key = record.get("key")?.as_str()?;
            (!current.contains(key)).then(|| (key.to_string(), case_label(record)))
        })
        .collect();
    orphans.sort();
    if delete_orphans {
        let doomed: HashSet<String> = orphans.iter().map(|(k, _)| format!("{k}.json")).collect();
        remove_where(&store.runs, |name| doomed.contains(name));
    }
    Ok(Cleaned {
        figures: removed,
        orphans,
        deleted: delete_orphans,
    })
}

/// `method=nonlocal n=64 …`: a record's case, for the list.
fn case_label(record: &Value) -> String {
    let Some(case) = record.get("case").and_then(Value::as_object) else {
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
