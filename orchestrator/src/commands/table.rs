//! `nlstudy table`: values of the summary table as a Markdown pivot.

use super::failure::Failure;
use super::open::{open_store, read_study};
use crate::cli::args::TableArgs;
use crate::console::Reply;

pub(super) fn table(args: &TableArgs) -> Result<Reply, Failure> {
    let study = read_study(&args.common.study)?;
    let store = open_store(&args.common, &study, false)?;
    let path = store.table(&format!("{}-summary.parquet", study.name));
    if !path.exists() {
        return Err(Failure::BadInput(format!(
            "{} does not exist; `nlstudy collect {}` writes it",
            path.display(),
            args.common.study.display()
        )));
    }
    // A table and its sum are read as one collect wrote them (on a read-only copy, unlocked).
    let _outputs = store.lock_outputs().ok();
    let spec = crate::analysis::pivot::PivotSpec {
        rows: args.rows.clone(),
        column: args.column.clone(),
        values: args.value.clone(),
        filter: args.filter.clone(),
    };
    let table = crate::store::table::read_parquet_columns(&path, |names| spec.columns(names))?;
    let mut reply = Reply::default();
    reply.result(crate::analysis::pivot::markdown(&spec, &table).map_err(Failure::BadInput)?);
    Ok(reply)
}
