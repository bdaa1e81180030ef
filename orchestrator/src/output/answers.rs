//! What an adaptive study found, a line per point of its sweep for the terminal: each search's
//! boundary against the theory's, each refinement's orders and why it stopped, the candidates
//! for an error target by cost.

use crate::analysis::boundaries::prediction;
use crate::console::number;
use crate::model::adaptive::{Budget, Spent};
use crate::model::boundary::{BoundarySpec, Search};
use crate::model::refine::Refinement;
use crate::model::target::{Aimed, TargetSpec};
use crate::run::search::{Answered, Searched};

/// What the study's budget allowed and what its probes spent: `budget: 312 of 400 runs, 18.2 of
/// 60 core-seconds`.
pub fn budget_line(budget: &Budget, spent: &Spent) -> String {
    let mut parts = Vec::new();
    if let Some(runs) = budget.runs {
        parts.push(format!("{} of {runs} runs", spent.runs));
    }
    if let Some(seconds) = budget.core_seconds {
        parts.push(format!(
            "{} of {} core-seconds",
            number(spent.core_seconds),
            number(seconds)
        ));
    }
    format!("budget: {}", parts.join(", "))
}

/// The lines of `answered`, the answers to a study's question.
pub fn lines(answered: &Answered) -> Vec<String> {
    match answered {
        Answered::Boundaries(spec, searched) => boundary_lines(spec, searched),
        Answered::Refinements(spec, refined) => refinement_lines(&spec.field, refined),
        Answered::Targets(spec, aimed) => target_lines(spec, aimed),
    }
}

/// The candidates by cost: `1. method=adi: n = 384, error 9.1e-07, solve_s 0.41 (5 runs)`, and
/// those that found no answer after them.
fn target_lines(spec: &TargetSpec, aimed: &[Searched<Aimed>]) -> Vec<String> {
    let mut lines: Vec<(usize, String)> = crate::analysis::target::ranked(spec, aimed)
        .into_iter()
        .zip(aimed)
        .map(|((answer, rank), s)| {
            let runs = s.outcome.levels.len();
            let label = s.origin.label();
            match (answer, rank) {
                (Some(l), Some(rank)) => (
                    rank,
                    format!(
                        "{rank}. {label}: {} = {}, error {}, {} {} ({runs} runs)",
                        spec.field,
                        number(l.value),
                        number(l.error),
                        spec.cost,
                        number(l.cost)
                    ),
                ),
                _ => {
                    let why = s
                        .outcome
                        .reached
                        .as_ref()
                        .map_or_else(String::new, ToString::to_string);
                    (
                        usize::MAX,
                        format!("–. {label}: no answer: {why} ({runs} runs)"),
                    )
                }
            }
        })
        .collect();
    lines.sort_by_key(|(rank, _)| *rank);
    let mut said = vec![format!("to reach {} ≤ {}:", spec.error, number(spec.below))];
    said.extend(lines.into_iter().map(|(_, line)| line));
    said
}

/// Each search's answer: `m=4 integrator=rk4: cfl = 1.0004 (predicted 1, +0.04 %), 12 probes`.
fn boundary_lines(spec: &BoundarySpec, searched: &[Searched<Search>]) -> Vec<String> {
    let field = spec.field.as_str();
    searched
        .iter()
        .map(|s| {
            let search = &s.outcome;
            let predicted = s.record.as_ref().and_then(|r| prediction(spec, r));
            let answer = match (search.boundary(), predicted) {
                (Some(b), Some(p)) => format!(
                    "{field} = {} (predicted {}, {:+.2} %)",
                    number(b),
                    number(p),
                    100.0 * (b / p - 1.0)
                ),
                // Along whole values the answer is a pair of neighbours.
                (Some(_), None) if spec.whole() => format!(
                    "{field} = {} holds, {} does not",
                    number(search.above),
                    number(search.below)
                ),
                (Some(b), None) => format!("{field} = {}", number(b)),
                (None, _) => search
                    .ended
                    .as_ref()
                    .map_or_else(String::new, ToString::to_string),
            };
            format!("{}: {answer}, {} probes", s.origin.label(), search.probes)
        })
        .collect()
}

/// Each refinement's answer: `method=adi: order 2.001 (fitted 2.000) from n = 64, order
/// established at n = 512, 5 levels`.
fn refinement_lines(field: &str, refined: &[Searched<Refinement>]) -> Vec<String> {
    refined
        .iter()
        .map(|s| {
            let r = &s.outcome;
            let order = |p: Option<f64>| p.map_or("–".to_string(), number);
            let from = r
                .asymptotic_from()
                .map_or(String::new(), |v| format!(" from {field} = {}", number(v)));
            let stopped = r
                .stopped
                .as_ref()
                .map_or_else(String::new, ToString::to_string);
            let finest = r.levels.last().map_or(String::new(), |l| number(l.0));
            format!(
                "{}: order {} (fitted {}){from}; {stopped} at {field} = {finest}, {} levels",
                s.origin.label(),
                order(r.finest_order()),
                order(r.fitted_order()),
                r.levels.len()
            )
        })
        .collect()
}
