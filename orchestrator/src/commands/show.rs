//! `nlstudy show`: stored records as JSON lines, for scripts and for bit-for-bit checks (records
//! live packed in segments, where no other tool reads them).

use super::failure::Failure;
use super::open::{open_store, read_study};
use crate::cli::args::ShowArgs;
use crate::console::Reply;

/// Needs no solver. A key asked for that has no record is bad input: nothing is printed.
pub(super) fn show(args: &ShowArgs) -> Result<Reply, Failure> {
    let study = read_study(&args.common.study)?;
    let store = open_store(&args.common, &study, false)?;
    let mut reply = Reply::default();
    let mut records = match args.from_table {
        true => crate::analysis::collect::records_of_run_table(
            &store.table(&format!("{}.parquet", study.name)),
        )?,
        false => {
            let scan = store.scan();
            for unreadable in &scan.unreadable {
                reply.warn(unreadable.to_string());
            }
            scan.records
        }
    };
    records.sort_by(|a, b| (&a.key, a.repeat).cmp(&(&b.key, b.repeat)));
    if let Some(keys) = &args.key {
        if let Some(missing) = keys.iter().find(|k| !records.iter().any(|r| &&r.key == k)) {
            return Err(Failure::BadInput(format!(
                "--key {missing:?}: no record of that key is stored; `nlstudy plan` lists the keys"
            )));
        }
        records.retain(|r| keys.contains(&r.key));
    }
    for record in &records {
        reply.line(record.to_value().to_string());
    }
    Ok(reply)
}
