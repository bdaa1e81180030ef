//! What an adaptive study found, a line per point of its sweep for the terminal: each search's
//! boundary against the theory's, each refinement's orders and why it stopped, the candidates
//! for an error target by cost.

use crate::analysis::boundaries::prediction;
use crate::console::number;
use crate::model::adaptive::{Budget, Spent};
use crate::model::boundary::{BoundarySpec, Ended, Search};
use crate::model::refine::Refinement;
use crate::model::target::{Aimed, Reached, TargetSpec};
use crate::run::search::Searched;

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

/// The candidates by cost: `1. method=adi: n = 384, error 9.1e-07, solve_s 0.41 [0.39, 0.44]
/// over 3 repeats (5 runs)`, candidates that tie within noise as one place (`1–2 (tie within
/// noise): …`), and those that found no answer after them, with why.
pub fn target_lines(spec: &TargetSpec, aimed: &[Searched<Aimed>]) -> Vec<String> {
    let ranked = crate::analysis::target::ranked(spec, aimed);
    let mut places: Vec<(usize, usize, Vec<String>)> = Vec::new();
    let mut unanswered = Vec::new();
    for (ranked, s) in ranked.iter().zip(aimed) {
        let runs = s.outcome.runs();
        let label = s.origin.shown();
        let erratic = (s.outcome.erratic(spec)).map_or(String::new(), |e| format!("; {e}"));
        let Some(r) = ranked else {
            let why = (s.outcome.reached.as_ref()).map_or_else(String::new, ToString::to_string);
            let why = format!("{why}{erratic}");
            unanswered.push(format!("–. {label}: no answer: {why} ({runs} runs)"));
            continue;
        };
        let l = &r.answer;
        let mut resolution = format!("{} = {}", spec.field, number(l.value));
        if let (Some(time), Some(value)) = (&spec.time, l.time) {
            resolution.push_str(&format!(", {} = {}", time.field, number(value)));
        }
        let cost = match r.repeats {
            1 => number(r.cost),
            k => format!(
                "{} [{}, {}] over {k} repeats",
                number(r.cost),
                number(r.interval.0),
                number(r.interval.1)
            ),
        };
        // An answer not narrowed to the tolerance says why.
        let caveat = match &s.outcome.reached {
            Some(Reached::Found) | None => erratic,
            Some(reached) => format!("; {reached}{erratic}"),
        };
        let line = format!(
            "{label}: {resolution}, error {}, {} {cost} ({runs} runs{caveat})",
            number(l.error),
            spec.cost
        );
        match places.iter_mut().find(|(rank, _, _)| *rank == r.rank) {
            Some((_, _, lines)) => lines.push(line),
            None => places.push((r.rank, r.tied_to, vec![line])),
        }
    }
    places.sort_by_key(|(rank, _, _)| *rank);
    let mut said = vec![format!(
        "to reach {} ≤ {} ({}):",
        spec.error,
        number(spec.below),
        spec.cheapest_means()
    )];
    for (rank, tied_to, lines) in places {
        match lines.as_slice() {
            [one] => said.push(format!("{rank}. {one}")),
            many => {
                said.push(format!("{rank}–{tied_to} (tie within noise):"));
                said.extend(many.iter().map(|line| format!("   {line}")));
            }
        }
    }
    said.extend(unanswered);
    said
}

/// Each search's answer: `m=4 integrator=rk4: cfl = 1.0004 (predicted 1, +0.04 %), 12 probes`.
pub fn boundary_lines(spec: &BoundarySpec, searched: &[Searched<Search>]) -> Vec<String> {
    let field = spec.field.as_str();
    searched
        .iter()
        .map(|s| {
            let search = &s.outcome;
            let predicted = s.record.as_ref().and_then(|r| prediction(spec, r));
            let mut answer = match (search.boundary(), predicted) {
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
            // A spent budget's estimate comes with its bracket and the reason it is that wide.
            if let Some(ended @ (Ended::Budget | Ended::StudyBudget)) = &search.ended {
                answer += &format!(
                    " in [{}, {}]: {ended}",
                    number(search.below),
                    number(search.above)
                );
            }
            format!("{}: {answer}, {} probes", s.origin.shown(), search.probes)
        })
        .collect()
}

/// Each refinement's answer: `method=adi: order 2.001 (fitted 2.000) from n = 64, order
/// established at n = 512, 5 levels`.
pub fn refinement_lines(field: &str, refined: &[Searched<Refinement>]) -> Vec<String> {
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
                s.origin.shown(),
                order(r.finest_order()),
                order(r.fitted_order()),
                r.levels.len()
            )
        })
        .collect()
}
