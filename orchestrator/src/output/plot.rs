//! `nlstudy plot`: draws a study's figures from its summary table alone (never a solver), each
//! only when its table, its spec or the program drawing it changed since it was drawn: a stamp
//! beside the SVG holds the hashes of the three.

use crate::model::adaptive::Kind;
use crate::model::boundary::BoundarySpec;
use crate::model::figure_spec::{FigureKind, FigureSpec};
use crate::model::target::TargetSpec;
use crate::output::draw;
use crate::output::figure;
use crate::store::fs::{create_dir, read_regular, Fault, SMALL_FILE_CAP};
use crate::store::table;
use crate::store::{self, Store};
use sha2::{Digest, Sha256};
use std::path::PathBuf;

/// What became of one figure.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    Drawn,
    UpToDate,
    /// Why it could not be drawn, naming the figure; its stale SVG is removed.
    Failed(String),
}

pub struct Figure {
    pub path: PathBuf,
    pub outcome: Outcome,
}

/// The files of the figure `name` in the study's `figures/`: its SVG, and the stamp that says
/// what it was drawn from.
pub fn files(name: &str) -> [String; 2] {
    [format!("{name}.svg"), format!(".{name}.stamp")]
}

/// Draws the figures whose stamps are stale, every one it can: a figure that cannot be made of
/// the table does not stop the others. Fails as a whole when the summary table cannot be read
/// or a figure cannot be written (the file system's fault, which the next figure would meet
/// too).
pub fn plot(
    figures: &[FigureSpec],
    question: Option<&dyn Kind>,
    store: &Store,
) -> Result<Vec<Figure>, Fault> {
    let _outputs = store.lock_outputs()?;
    let table_path = store.table(&format!("{}-summary.parquet", store.study));
    // The hash of the bytes parsed stamps the figures.
    let (rows, table_hash) = table::read_parquet_hashed(&table_path)?;
    // The table of the question's answers, for the figures that draw them; read once, if `run`
    // has written it.
    let answer_table = match question {
        Some(question) => {
            let path = crate::analysis::answer_table::path(store, question.table());
            match path.exists() {
                true => Some((question, table::read_parquet_hashed(&path)?)),
                false => None,
            }
        }
        None => None,
    };
    let program = std::env::current_exe()
        .and_then(std::fs::read)
        .map(|bytes| store::hex(&Sha256::digest(&bytes)))
        .unwrap_or_default();
    let directory = store.table("figures");
    let mut outcomes = Vec::new();
    for (k, spec) in figures.iter().enumerate() {
        let [svg, stamp_name] = files(&spec.name);
        let (path, stamp_path) = (directory.join(svg), directory.join(stamp_name));
        let answers = answer_table
            .as_ref()
            .filter(|(question, _)| draws_answers(spec.kind, *question));
        let stamp = format!(
            "table {table_hash}\nanswers {}\nspec {}\nnlstudy {program}\n",
            answers.map_or("none", |(_, (_, hash))| hash.as_str()),
            serde_json::to_string(spec).expect("a spec serializes"),
        );
        let current = read_regular(&stamp_path, SMALL_FILE_CAP).is_ok_and(|s| s == stamp);
        if current && path.exists() {
            outcomes.push(Figure {
                path,
                outcome: Outcome::UpToDate,
            });
            continue;
        }
        // `chart` names the figure in its messages itself.
        let answers = answers.map(|(question, (rows, _))| figure::Answers {
            question: *question,
            rows,
        });
        let drawn = figure::chart(spec, k, &rows, answers)
            .and_then(|chart| draw::render(&chart).map_err(|e| figure::fault(k, spec, e)));
        // A figure of an earlier table would pass for this one's.
        let remove_stale = || {
            let _ = std::fs::remove_file(&path);
            let _ = std::fs::remove_file(&stamp_path);
        };
        let outcome = match drawn {
            Err(message) => {
                remove_stale();
                Outcome::Failed(message)
            }
            Ok(svg) => {
                let written = create_dir(&directory)
                    .and_then(|_| store::write_atomically(&path, svg.as_bytes()))
                    .and_then(|_| store::write_atomically(&stamp_path, stamp.as_bytes()));
                if let Err(e) = written {
                    remove_stale();
                    return Err(Fault::Io(figure::fault(k, spec, e)));
                }
                Outcome::Drawn
            }
        };
        outcomes.push(Figure { path, outcome });
    }
    Ok(outcomes)
}

/// Whether a figure of `kind` draws the answers of `question`: the boundaries figure those of
/// a boundary search, a work–precision figure the answers of an error target.
fn draws_answers(kind: FigureKind, question: &dyn Kind) -> bool {
    let asks = question.as_any();
    match kind {
        FigureKind::Boundaries => asks.is::<BoundarySpec>(),
        FigureKind::WorkPrecision => asks.is::<TargetSpec>(),
        _ => false,
    }
}

/// Ok when every figure is drawn or up to date, else the messages of those that failed.
pub fn all_drawn(figures: &[Figure]) -> Result<(), String> {
    let failed: Vec<&str> = figures
        .iter()
        .filter_map(|f| match &f.outcome {
            Outcome::Failed(message) => Some(message.as_str()),
            _ => None,
        })
        .collect();
    match failed.len() {
        0 => Ok(()),
        n => Err(format!(
            "{n} of {} figures not drawn: {}",
            figures.len(),
            failed.join("; ")
        )),
    }
}

#[cfg(test)]
mod tests;
