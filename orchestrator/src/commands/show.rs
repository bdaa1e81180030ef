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
    // What of the store could not be read: said with the records, and with a key not found
    // (a damaged stretch may have held it).
    let mut damaged = Vec::new();
    let mut records = match args.from_table {
        true => crate::analysis::collect::records_of_run_table(
            &store.table(&format!("{}.parquet", study.name)),
        )?,
        false => {
            let scan = store.scan();
            damaged = scan.unreadable.iter().map(ToString::to_string).collect();
            scan.records
        }
    };
    records.sort_by(|a, b| (&a.key, a.repeat).cmp(&(&b.key, b.repeat)));
    if let Some(keys) = &args.key {
        if let Some(missing) = keys.iter().find(|k| !records.iter().any(|r| &&r.key == k)) {
            let mut message = format!("--key {missing:?}: no record of that key is stored");
            if !damaged.is_empty() {
                message += &format!(
                    " that can be read; damaged, the store's {} may have held it: {}; `nlstudy run` runs what they held again",
                    crate::console::counted(damaged.len(), "unreadable part"),
                    damaged.join("; ")
                );
            }
            message += "; `nlstudy plan` lists the keys";
            return Err(Failure::BadInput(message));
        }
        records.retain(|r| keys.contains(&r.key));
    }
    for unreadable in damaged {
        reply.warn(unreadable);
    }
    for record in &records {
        reply.line(record.to_value().to_string());
    }
    Ok(reply)
}
