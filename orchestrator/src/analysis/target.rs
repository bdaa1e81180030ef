//! The error-target table, `<study>-target.parquet`: one row per candidate configuration (a
//! point of the sweep, its repeats one candidate), with the swept fields that tell them apart,
//! the resolution found to meet the target (both fields, in space and time), its error, its cost
//! over the answer's repeats (median and interval), the candidates' rank by that cost (1: the
//! cheapest; candidates whose intervals overlap share a rank, a tie within noise), the fitted
//! orders, the runs spent and how each search ended.

use crate::analysis::answer_table::{self, measured, origin_rows, text};
use crate::model::adaptive::Adaptive as _;
use crate::model::study::Study;
use crate::model::target::{Aimed, Level, TargetSpec};
use crate::run::search::Searched;
use crate::store::table::Row;
use crate::store::{Fault, Store};
use serde_json::Value;
use std::path::PathBuf;

/// A candidate's answer as ranked: its level, the cost over its repeats, and its place.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranked {
    pub answer: Level,
    /// The median cost over the answer's repeats, and its interval.
    pub cost: f64,
    pub interval: (f64, f64),
    pub repeats: usize,
    /// Its place by cost, 1 the cheapest, and the last place of the candidates it ties with
    /// (the same as the first when it ties with none).
    pub rank: usize,
    pub tied_to: usize,
}

/// Each candidate's ranked answer (none for one that found none), in the order of the sweep.
/// The candidates are ordered by their median cost; one whose interval overlaps the interval of
/// the first of a group ties with it.
pub fn ranked(spec: &TargetSpec, searched: &[Searched<Aimed>]) -> Vec<Option<Ranked>> {
    let mut answers: Vec<Option<Ranked>> = searched
        .iter()
        .map(|s| {
            let answer = s.outcome.answer(spec)?;
            let mut costs = s.outcome.answer_costs.clone();
            if costs.is_empty() {
                costs.push(answer.cost);
            }
            let label = s.origin.label();
            let (cost, interval) = crate::analysis::compare::median_interval(&label, &costs);
            Some(Ranked {
                answer,
                cost,
                interval,
                repeats: costs.len(),
                rank: 0,
                tied_to: 0,
            })
        })
        .collect();
    let mut order: Vec<usize> = (0..answers.len())
        .filter(|&k| answers[k].is_some())
        .collect();
    let cost = |k: usize| answers[k].as_ref().map_or(f64::INFINITY, |r| r.cost);
    order.sort_by(|&a, &b| cost(a).total_cmp(&cost(b)));
    let mut place = 0;
    while place < order.len() {
        let leader = answers[order[place]].clone().expect("ranked");
        let mut last = place;
        while last + 1 < order.len() {
            let next = answers[order[last + 1]].as_ref().expect("ranked");
            if next.interval.0 > leader.interval.1 {
                break;
            }
            last += 1;
        }
        for &k in &order[place..=last] {
            let ranked = answers[k].as_mut().expect("ranked");
            (ranked.rank, ranked.tied_to) = (place + 1, last + 1);
        }
        place = last + 1;
    }
    answers
}

/// The table's rows, in the order of the sweep.
pub fn rows(spec: &TargetSpec, searched: &[Searched<Aimed>]) -> Vec<Row> {
    let time = spec.time.as_ref();
    origin_rows(searched)
        .into_iter()
        .zip(searched.iter().zip(ranked(spec, searched)))
        .map(|(mut row, (s, ranked))| {
            let answer = ranked.as_ref().map(|r| &r.answer);
            let model = s.outcome.model.as_ref();
            row.set("field", Value::from(spec.field.as_str()));
            row.set("target", Value::from(spec.below));
            row.set("resolution", measured(answer.map(|l| l.value)));
            if let Some(time) = time {
                row.set("time_field", Value::from(time.field.as_str()));
                row.set("time_resolution", measured(answer.and_then(|l| l.time)));
            }
            row.set("h", measured(answer.map(|l| l.h)));
            row.set("dt", measured(answer.map(|l| l.dt)));
            row.set("error", measured(answer.map(|l| l.error)));
            row.set("cost", measured(ranked.as_ref().map(|r| r.cost)));
            row.set("cost_low", measured(ranked.as_ref().map(|r| r.interval.0)));
            row.set("cost_high", measured(ranked.as_ref().map(|r| r.interval.1)));
            row.set(
                "repeats",
                ranked
                    .as_ref()
                    .map_or(Value::Null, |r| Value::from(r.repeats)),
            );
            row.set(
                "rank",
                ranked.as_ref().map_or(Value::Null, |r| Value::from(r.rank)),
            );
            row.set(
                "tied_to",
                ranked
                    .as_ref()
                    .map_or(Value::Null, |r| Value::from(r.tied_to)),
            );
            if time.is_some() {
                let p = (model.map(|m| m.p), model.and_then(|m| m.p_interval));
                let q = (model.map(|m| m.q), model.and_then(|m| m.q_interval));
                for ([name, low, high], (order, interval)) in
                    [(["p", "p_low", "p_high"], p), (["q", "q_low", "q_high"], q)]
                {
                    row.set(name, measured(order));
                    row.set(low, measured(interval.map(|i| i.0)));
                    row.set(high, measured(interval.map(|i| i.1)));
                }
            }
            let runs = s.outcome.runs();
            row.set("probes", Value::from(runs));
            let reached = s.outcome.reached.as_ref().map(ToString::to_string);
            row.set("reached", text(reached));
            row
        })
        .collect()
}

/// What the columns hold, in the file's metadata; the columns before them are the swept fields.
pub const NOTES: &[(&str, &str)] = &[
    ("field", "the resolution field searched (the spatial one, in space and time)"),
    ("target", "the error to reach (at most)"),
    (
        "resolution",
        "its value in the answer: the coarsest run that meets the target (in space and time, the cheapest); null if none was found",
    ),
    ("time_field", "the temporal field searched with it, in space and time"),
    ("time_resolution", "its value in the answer"),
    ("h", "the answer's grid spacing, as its record says"),
    ("dt", "the answer's time step, as its record says"),
    ("error", "its error"),
    (
        "cost",
        "its measured cost (the study's `cost` column, solve_s by default): the median over its repeats",
    ),
    ("cost_low", "the cost's 95 % bootstrap interval over the repeats, low end"),
    ("cost_high", "the same, high end"),
    ("repeats", "runs of the answer its cost is the median of"),
    (
        "rank",
        "the candidates' order by cost, 1 the cheapest; candidates whose cost intervals overlap share the first rank of their group",
    ),
    ("tied_to", "the last rank of the group it ties with (its own rank when it ties with none)"),
    ("p", "the fitted order in h of e ≈ C·h^p + D·dt^q + F, in space and time"),
    ("p_low", "its leave-one-out spread, low end"),
    ("p_high", "the same, high end"),
    ("q", "the fitted order in dt (the integrator's with fewer than five runs)"),
    ("q_low", "its leave-one-out spread, low end"),
    ("q_high", "the same, high end"),
    ("probes", "runs the candidate's search spent, diverged ones included (a step the solver refused never ran)"),
    ("reached", "how the search ended"),
];

/// Writes the table beside the study's others and returns its path.
pub fn write(
    study: &Study,
    store: &Store,
    spec: &TargetSpec,
    searched: &[Searched<Aimed>],
) -> Result<PathBuf, Fault> {
    answer_table::write(
        study,
        store,
        TargetSpec::TABLE,
        &rows(spec, searched),
        NOTES,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use schema::record::example::record;
    use serde_json::json;
    use std::sync::Arc;

    /// Candidates of costs drawn from one distribution tie; one twice as costly is ranked after
    /// them; the ranking reads the cost order (a mutant ranking the dearest first fails it).
    #[test]
    fn overlapping_costs_tie_and_a_dearer_candidate_ranks_after_them() {
        let spec: TargetSpec = serde_json::from_value(json!({
            "field": "n", "start": 16, "below": 1e-3, "cost": "steps_done"
        }))
        .unwrap();
        let study = crate::kinds::parse(
            &json!({"name": "t", "base": {"dim": 1}, "sweep": [{"product": {"kernel": ["constant", "linear", "gaussian"]}}]})
                .to_string(),
        )
        .unwrap();
        let origins = study.expand().unwrap();
        let costs: [&[f64]; 3] = [&[1.0, 1.2, 0.9], &[1.1, 0.95, 1.15], &[2.3, 2.2, 2.4]];
        let searched: Vec<Searched<Aimed>> = origins
            .into_iter()
            .zip(costs)
            .map(|(origin, costs)| {
                let stored = Arc::new(record(json!({"error_l2_norm": 1e-4, "steps_done": 10})));
                let (aimed, _) = spec.replay_levels(|_| Some(Ok(stored.clone())));
                Searched {
                    origin,
                    outcome: Aimed {
                        answer_costs: costs.to_vec(),
                        ..aimed
                    },
                    record: None,
                }
            })
            .collect();
        let ranked = ranked(&spec, &searched);
        let places: Vec<(usize, usize)> = ranked
            .iter()
            .map(|r| r.as_ref().map(|r| (r.rank, r.tied_to)).unwrap())
            .collect();
        assert_eq!(places, [(1, 2), (1, 2), (3, 3)]);
    }
}
