//! A study's figure specs checked against the columns its summary table will have, before
//! anything runs: a misspelt column is a bad study file, said at `plan`, not a failed figure
//! after every case has run.

use crate::analysis::{boundaries, summary};
use crate::model::expression;
use crate::model::figure_spec::{FigureKind, FigureSpec};
use crate::model::study::{Study, StudyError};
use schema::case::Case;
use schema::record::columns;

/// Refuses the first figure that names a column no summary table has, with a guess.
pub fn check(study: &Study) -> Result<(), StudyError> {
    for (k, figure) in study.figures.iter().enumerate() {
        let place = |what: &str| format!("figures[{k}] ({}).{what}", figure.name);
        let named = figure_names(figure).map_err(|e| StudyError::new(place("where"), e))?;
        for (what, name) in named {
            if figure.kind == FigureKind::Boundaries {
                if !is_boundary_column(&name) {
                    return Err(StudyError::new(
                        place(what),
                        format!("no column `{name}` in the boundary table (its columns: the swept case fields, `branch`, and {})", boundaries::NOTES.iter().map(|(c, _)| format!("`{c}`")).collect::<Vec<_>>().join(", ")),
                    ));
                }
            } else if !is_known(&name) {
                let guess =
                    guess(&name).map_or(String::new(), |g| format!("; did you mean `{g}`?"));
                return Err(StudyError::new(
                    place(what),
                    format!("no column `{name}` in the summary table{guess} (the columns: the case's fields, the record's, and what the summary derives; see the guide, docs/guide/results.md)"),
                ));
            }
        }
    }
    Ok(())
}

/// `column`, read as a measurement at `place`: a number of the record.
pub fn measured(place: &str, column: &str) -> Result<(), StudyError> {
    match columns::column(&columns::every_field(), column) {
        Some(value) if value.is_number() => Ok(()),
        Some(value) => Err(StudyError::new(
            place,
            format!("`{column}` is no number of the record (it holds {value}); give an error or cost column such as `error_l2_norm` or `solve_s`"),
        )),
        None => {
            let guess = guess(column).map_or(String::new(), |g| format!("; did you mean `{g}`?"));
            Err(StudyError::new(place, format!("no column `{column}` in a probe's record{guess}")))
        }
    }
}

/// The names a figure reads, with the place each stands in.
fn figure_names(figure: &FigureSpec) -> Result<Vec<(&'static str, String)>, String> {
    let mut names = Vec::new();
    if let Some(x) = &figure.x {
        names.push(("x", x.clone()));
    }
    if let Some(y) = &figure.y {
        let column = y.strip_prefix("abs(").and_then(|c| c.strip_suffix(')'));
        names.push(("y", column.unwrap_or(y).to_string()));
    }
    for series in figure.series.iter().flatten() {
        names.push(("series", series.clone()));
    }
    for condition in &figure.filter {
        names.extend(
            expression::names(condition)?
                .into_iter()
                .map(|n| ("where", n)),
        );
    }
    Ok(names)
}

/// A case field (bare, or as `case.<field>`, nested objects by their first part) or a summary
/// column.
fn is_known(name: &str) -> bool {
    let field = name.strip_prefix("case.").unwrap_or(name);
    let top = field.split('.').next().unwrap_or(field);
    Case::field_names().contains(&top) || (!name.starts_with("case.") && summary::is_column(name))
}

/// A column of the boundary table: a case field (bare), the branch, or the answer's.
fn is_boundary_column(name: &str) -> bool {
    let top = name.split('.').next().unwrap_or(name);
    Case::field_names().contains(&top)
        || name == "branch"
        || boundaries::NOTES.iter().any(|(column, _)| *column == name)
}

/// The case field or summary column nearest to `name`, for a refusal's "did you mean".
pub fn guess(name: &str) -> Option<String> {
    let columns = summary::column_names();
    let candidates = Case::field_names().iter().copied().chain(
        columns
            .iter()
            .map(String::as_str)
            .filter(|c| !c.ends_with('*')),
    );
    schema::error::nearest(name, candidates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn study(figures: serde_json::Value) -> Study {
        crate::kinds::parse(&json!({"name": "s", "base": {}, "figures": figures}).to_string())
            .unwrap()
    }

    /// What an adaptive question reads of a probe's record is checked at plan: a misspelt name
    /// in `flips`, a `flips` that is a number and not a condition, an error or cost column that
    /// is no number.
    #[test]
    fn a_question_reading_what_no_record_has_is_refused_at_plan() {
        let with = |question: serde_json::Value| {
            let mut study = json!({"name": "s", "base": {"dim": 1, "n": 32, "kernel": "linear"}});
            for (k, v) in question.as_object().unwrap() {
                study[k] = v.clone();
            }
            crate::kinds::check(&crate::kinds::parse(&study.to_string()).unwrap())
        };
        let boundary = |flips: &str| {
            with(
                json!({"boundary": {"field": "cfl", "bracket": [0.5, 2], "flips": flips, "rtol": 1e-2}}),
            )
        };
        assert_eq!(boundary("amplification > 1"), Ok(()));
        assert_eq!(
            boundary("kernel == 'linear' && status == 'diverged'"),
            Ok(())
        );
        let misspelt = boundary("amplificaton > 1").unwrap_err();
        assert_eq!(misspelt.field, "boundary.flips");
        assert!(
            misspelt.message.contains("did you mean `amplification`?"),
            "{misspelt}"
        );
        let number = boundary("amplification").unwrap_err();
        assert!(number.message.contains("must be true or false"), "{number}");
        let refine =
            |error: &str| with(json!({"refine": {"field": "n", "start": 16, "error": error}}));
        assert_eq!(refine("error_max"), Ok(()));
        assert_eq!(refine("status").unwrap_err().field, "refine.error");
        let target = with(
            json!({"target": {"field": "n", "start": 16, "below": 1e-3, "cost": "solve_sec"}}),
        );
        let target = target.unwrap_err();
        assert_eq!(target.field, "target.cost");
        assert!(
            target.message.contains("did you mean `solve_s`?"),
            "{target}"
        );
    }

    #[test]
    fn a_misspelt_column_is_refused_at_plan_with_a_guess() {
        let good = study(json!([
            {"name": "a", "kind": "convergence", "x": "dt", "y": "abs(error_max)", "series": ["integrator", "case.m"],
             "where": ["branch == 'x' && horizon_profile.kind == 'linear' && solve_s_median > 0 && patch.ghost_force < 1"]},
            {"name": "b", "kind": "strong_scaling", "where": ["workers <= 2 && c_tot.time != 0 && order_l2 > 1"]}
        ]));
        assert_eq!(check(&good), Ok(()));
        let cases = [
            (
                json!({"name": "c", "kind": "convergence", "y": "eror_l2_norm"}),
                "figures[0] (c).y",
                "error_l2_norm",
            ),
            (
                json!({"name": "c", "kind": "convergence", "series": ["integrater"]}),
                "figures[0] (c).series",
                "integrator",
            ),
            (
                json!({"name": "c", "kind": "convergence", "where": ["thread == 1"]}),
                "figures[0] (c).where",
                "threads",
            ),
            (
                json!({"name": "c", "kind": "convergence", "x": "solve_s_medain"}),
                "figures[0] (c).x",
                "solve_s_median",
            ),
        ];
        for (figure, place, guess) in cases {
            let error = check(&study(json!([figure]))).unwrap_err();
            assert_eq!(error.field, place);
            assert!(
                error.message.contains(&format!("did you mean `{guess}`?")),
                "{error}"
            );
        }
        // `case.` names only case fields.
        let error = check(&study(
            json!([{"name": "c", "kind": "convergence", "x": "case.h"}]),
        ))
        .unwrap_err();
        assert_eq!(error.field, "figures[0] (c).x");
    }

    #[test]
    fn a_boundaries_figure_names_the_columns_of_the_boundary_table() {
        let boundary = json!({"field": "cfl", "bracket": [0.5, 2], "flips": "amplification > 1", "rtol": 1e-3});
        let study = |figure: serde_json::Value| {
            let text = json!({"name": "s", "base": {}, "boundary": boundary, "figures": [figure]});
            crate::kinds::parse(&text.to_string()).unwrap()
        };
        let good = json!({"name": "b", "kind": "boundaries", "x": "m", "series": ["integrator"],
                          "where": ["branch == 'x' && gap > -0.01 && probes < 20"]});
        assert_eq!(check(&study(good)), Ok(()));
        let error = check(&study(
            json!({"name": "b", "kind": "boundaries", "where": ["solve_s_median > 0"]}),
        ))
        .unwrap_err();
        assert_eq!(error.field, "figures[0] (b).where");
        assert!(
            error
                .message
                .contains("no column `solve_s_median` in the boundary table"),
            "{error}"
        );
    }
}
