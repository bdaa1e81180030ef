//! `nlstudy plan`: every point of the study, whether it would run and why; nothing runs.

use super::failure::Failure;
use super::open::{no_refusals, planned, say_what_does_not_fit};
use crate::cli::args::PlanArgs;
use crate::run::plan::Decision;
use std::fmt::Write as _;
use std::process::ExitCode;

pub(super) fn plan(args: &PlanArgs) -> Result<ExitCode, Failure> {
    let (study, solver, _, planned) = planned(&args.common, &args.options(), false)?;
    outln!(
        "study {}: {} points, solver {}",
        study.name,
        planned.len(),
        solver.version
    );
    if !study.description.is_empty() {
        outln!("{}", study.description);
    }
    // Written 64 kB at a time: a line at a time is a system call each at 10⁵ points, and all
    // at once a hundred megabytes at 10⁶.
    let mut listing = String::new();
    for p in &planned {
        if listing.len() >= 1 << 16 {
            out!("{listing}");
            listing.clear();
        }
        let what = match &p.decision {
            Decision::Run(reason) => format!("run   ({reason})"),
            Decision::Skip(status) => format!("skip  ({status})"),
            Decision::Duplicate => "skip  (the same case as an earlier point)".into(),
        };
        // Said once per distinct sentence below.
        let refused = match &p.case {
            Err(_) => "  refused",
            Ok(_) => "",
        };
        let _ = writeln!(
            listing,
            "{}  {what:<40} {}{refused}",
            p.key,
            p.point.label()
        );
    }
    out!("{listing}");
    let runs = planned.iter().filter(|p| p.runs()).count();
    let duplicates = planned
        .iter()
        .filter(|p| p.decision == Decision::Duplicate)
        .count();
    let shared = match duplicates {
        0 => String::new(),
        n => format!(", {n} the same case as an earlier point"),
    };
    outln!(
        "{runs} to run, {} stored{shared}",
        planned.len() - runs - duplicates
    );
    // What an adaptive study's plan shows: the probes so far and the next round, and the most
    // runs its questions can take.
    if let Some(question) = study.question() {
        let questions = study.expand().map_or(0, |points| points.len());
        let most = question.worst_case_probes();
        outln!(
            "{} along `{}`: {questions} {}; the points above are the probes stored and the next round, {most} runs each at most ({} in all)",
            question.section(),
            question.field(),
            question.searches(),
            questions * most
        );
    }
    say_what_does_not_fit(&planned);
    no_refusals(&planned, args.allow_refused)?;
    Ok(ExitCode::SUCCESS)
}
