//! A fourth kind of adaptive question, sketched as a new kind is added: this one module and its
//! line in a registry. `first_below` walks a field's given values in order, a round each, and
//! answers the first whose error is below a bound (the coarsest grid of a list that is accurate
//! enough, say), running none of the finer ones.

use super::kind::{AdaptiveKind, Outcome};
use super::{Registry, SHIPPED};
use crate::analysis::answer_table::{self, measured};
use crate::model::adaptive::{positive, Adaptive, Lookup, Probe};
use crate::model::study::{Study, StudyError};
use crate::run::search::Searched;
use crate::store::table::Row;
use crate::store::{Fault, Store};
use schema::record::columns;
use serde::Deserialize;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::sync::Arc;

/// The section `first_below`: `field`'s `values` in order, until `error` is below `below`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FirstBelowSpec {
    field: String,
    values: Vec<f64>,
    error: String,
    below: f64,
}

/// Where a walk ended: the first value below the bound, or none of them (with why).
#[derive(Debug, PartialEq)]
enum Walked {
    Found {
        value: f64,
        error: f64,
        probes: usize,
    },
    NotFound(String),
    Walking,
}

impl Adaptive for FirstBelowSpec {
    type Outcome = Walked;
    const SECTION: &'static str = "first_below";
    const SEARCHES: &'static str = "walks";
    const TABLE: &'static str = "first_below";
    const TITLE: &'static str = "First value below the error bound";

    fn fields(&self) -> Vec<&str> {
        vec![&self.field]
    }

    fn worst_case_probes(&self) -> usize {
        self.values.len()
    }

    fn worst_case_rounds(&self) -> Option<usize> {
        Some(self.values.len())
    }

    fn out_of_budget(&self, outcome: &mut Walked) {
        if *outcome == Walked::Walking {
            *outcome = Walked::NotFound("the study's budget is spent".into());
        }
    }

    fn replay(&self, record: &mut Lookup) -> (Walked, Vec<Probe>) {
        for (k, &value) in self.values.iter().enumerate() {
            let error = match record(&[value]) {
                None => return (Walked::Walking, vec![vec![value]]),
                Some(stored) => stored.and_then(|s| positive(&self.error, &s)),
            };
            match error {
                Err(why) => return (Walked::NotFound(why), Vec::new()),
                Ok(error) if error < self.below => {
                    let probes = k + 1;
                    return (
                        Walked::Found {
                            value,
                            error,
                            probes,
                        },
                        Vec::new(),
                    );
                }
                Ok(_) => {}
            }
        }
        (Walked::NotFound("no value is below".into()), Vec::new())
    }
}

struct FirstBelow;

impl AdaptiveKind for FirstBelow {
    type Spec = FirstBelowSpec;

    fn rules(spec: &FirstBelowSpec) -> Result<(), StudyError> {
        match spec.values.is_empty() {
            true => Err(StudyError::new(
                "first_below.values",
                "give at least one value",
            )),
            false => Ok(()),
        }
    }

    fn check(spec: &FirstBelowSpec, _: &Study) -> Result<(), StudyError> {
        crate::analysis::figure_columns::measured("first_below.error", &spec.error)
    }

    fn write(
        spec: &FirstBelowSpec,
        searched: &[Searched<Outcome<Self>>],
        study: &Study,
        store: &Store,
    ) -> Result<PathBuf, Fault> {
        let rows = answer_table::origin_rows(searched)
            .into_iter()
            .zip(searched);
        let rows: Vec<Row> = rows
            .map(|(mut row, s)| {
                let found = match s.outcome {
                    Walked::Found { value, .. } => Some(value),
                    _ => None,
                };
                row.set(&spec.field, measured(found));
                row
            })
            .collect();
        answer_table::write(
            study,
            store,
            FirstBelowSpec::TABLE,
            &rows,
            &[("first", "the value")],
        )
    }

    fn lines(spec: &FirstBelowSpec, searched: &[Searched<Outcome<Self>>]) -> Vec<String> {
        let line = |s: &Searched<Walked>| match &s.outcome {
            Walked::Found { value, probes, .. } => {
                format!(
                    "{}: {} = {value} ({probes} runs)",
                    s.origin.shown(),
                    spec.field
                )
            }
            Walked::NotFound(why) => format!("{}: none: {why}", s.origin.shown()),
            Walked::Walking => format!("{}: walking", s.origin.shown()),
        };
        searched.iter().map(line).collect()
    }
}

/// The shipped kinds and the sketch: its registration line.
const WITH_FOURTH: Registry = Registry(&[
    &super::boundary::Boundary,
    &super::refine::Refine,
    &super::target::Target,
    &FirstBelow,
]);

fn study_text(section: Value) -> String {
    json!({
        "name": "walk",
        "base": {"dim": 1, "n": 16},
        "sweep": [{"product": {"m": [2, 4]}}],
        "first_below": section,
    })
    .to_string()
}

/// A record whose error is `error`.
fn with_error(error: f64) -> schema::record::Stored {
    let mut stored = columns::every_field();
    stored.record_mut().unwrap().error_l2_norm = Some(error);
    stored
}

#[test]
fn a_fourth_kind_is_one_module_and_its_registration() {
    let section =
        json!({"field": "n", "values": [16, 32, 64], "error": "error_l2_norm", "below": 1e-3});
    let study = Study::parse(&study_text(section.clone()), &WITH_FOURTH).unwrap();
    let question = study.question().expect("the study asks its question");
    assert!(study.asks::<FirstBelowSpec>());
    assert_eq!(
        (
            question.section(),
            question.field(),
            question.worst_case_rounds()
        ),
        ("first_below", "n", Some(3))
    );
    assert_eq!(WITH_FOURTH.of(question).section(), "first_below");
    assert_eq!(WITH_FOURTH.of(question).check(question, &study), Ok(()));

    // Its search, round by round: n = 16 then 32, whose error is below the bound.
    let spec: &FirstBelowSpec = question.as_any().downcast_ref().unwrap();
    let errors = [(16.0, 4e-3), (32.0, 9e-4)];
    let (walked, next) = spec.replay(&mut |v: &[f64]| {
        let error = errors.iter().find(|(n, _)| *n == v[0])?.1;
        Some(Ok(Arc::new(with_error(error))))
    });
    assert_eq!(next, Vec::<Probe>::new());
    assert_eq!(
        walked,
        Walked::Found {
            value: 32.0,
            error: 9e-4,
            probes: 2
        }
    );
    let (walking, next) =
        spec.replay(&mut |v: &[f64]| (v[0] == 16.0).then(|| Ok(Arc::new(with_error(4e-3)))));
    assert_eq!((walking, next), (Walked::Walking, vec![vec![32.0]]));

    // Its answers' lines and table.
    let points = study.expand().unwrap();
    let searched: Vec<Searched<Walked>> = points
        .into_iter()
        .map(|origin| Searched {
            origin,
            outcome: Walked::Found {
                value: 32.0,
                error: 9e-4,
                probes: 2,
            },
            record: None,
        })
        .collect();
    assert_eq!(
        FirstBelow::lines(spec, &searched),
        ["m=2: n = 32 (2 runs)", "m=4: n = 32 (2 runs)"]
    );
    let results = tempfile::tempdir().unwrap();
    let store = Store::open(results.path(), &study.name);
    let path = FirstBelow::write(spec, &searched, &study, &store).unwrap();
    let rows = crate::store::table::read_parquet(&path).unwrap();
    assert_eq!(rows.len(), 2);

    // Its rules, and the kinds that do not know it.
    let refused = Study::parse(
        &study_text(json!({"field": "n", "values": [], "error": "error_l2_norm", "below": 1e-3})),
        &WITH_FOURTH,
    );
    assert_eq!(refused.unwrap_err().field, "first_below.values");
    let unknown = Study::parse(&study_text(section), &SHIPPED).unwrap_err();
    assert_eq!(unknown.field, "first_below");
}

/// A study asks one question, whichever kinds are registered; the message names them all.
#[test]
fn a_second_section_is_refused_naming_every_kind() {
    let text = json!({
        "name": "two", "base": {},
        "refine": {"field": "n", "start": 8, "error": "error_l2_norm"},
        "first_below": {"field": "n", "values": [8], "error": "error_l2_norm", "below": 1.0},
    });
    let refused = Study::parse(&text.to_string(), &WITH_FOURTH).unwrap_err();
    assert_eq!(refused.field, "refine");
    assert!(
        refused
            .message
            .contains("`boundary`, `refine`, `target` and `first_below`"),
        "{}",
        refused.message
    );
}
