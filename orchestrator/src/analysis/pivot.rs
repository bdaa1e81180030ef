//! `nlstudy table`: values of a study's summary table as a Markdown pivot, rows named by some
//! fields and columns by another (e.g. observed orders by path and quadrature against n), or one
//! column per value (e.g. errors and orders by n, as a convergence table), for results pages
//! that are regenerated rather than copied by hand.

use crate::model::expression::{self, Scope};
use crate::store::table::Row;
use serde_json::Value;

pub struct PivotSpec {
    pub rows: Vec<String>,
    /// The field whose values head the columns; without it, each value is one column.
    pub column: Option<String>,
    /// The summary columns in the cells, side by side under each column heading.
    pub values: Vec<String>,
    pub filter: Vec<String>,
}

/// The pivot as a Markdown table; a cell no row fills stays empty, one that several fill is an
/// error (the row fields do not tell the points apart).
/// A line of the pivot: its row fields' texts, and its cells by column index.
type Line = (Vec<String>, Vec<(usize, String)>);

pub fn markdown(spec: &PivotSpec, table: &[Row]) -> Result<String, String> {
    if spec.values.is_empty() {
        return Err("give at least one --value".into());
    }
    // A column is (the column field's value, or null without one; the value's index).
    let mut columns: Vec<(Value, usize)> = Vec::new();
    let mut lines: Vec<Line> = Vec::new();
    for row in table {
        let named = row.expression_fields();
        let scope = Scope::of(&named);
        let mut keep = true;
        for (k, condition) in spec.filter.iter().enumerate() {
            keep &= expression::condition(condition, &scope)
                .map_err(|e| format!("--where {k}: {e}"))?;
        }
        if !keep {
            continue;
        }
        let lookup = |name: &str| {
            named
                .get(name)
                .cloned()
                .ok_or_else(|| format!("the table has no column `{name}`; see `nlstudy collect`'s output for the columns"))
        };
        let key: Vec<String> = spec
            .rows
            .iter()
            .map(|name| lookup(name).map(|v| text(&v)))
            .collect::<Result<_, _>>()?;
        let heading = match &spec.column {
            Some(column) => lookup(column)?,
            None => Value::Null,
        };
        let line = match lines.iter().position(|(k, _)| *k == key) {
            Some(l) => l,
            None => {
                lines.push((key.clone(), Vec::new()));
                lines.len() - 1
            }
        };
        for (v, name) in spec.values.iter().enumerate() {
            let value = text(&lookup(name)?);
            let column = (heading.clone(), v);
            let c = match columns.iter().position(|c| *c == column) {
                Some(c) => c,
                None => {
                    columns.push(column);
                    columns.len() - 1
                }
            };
            if lines[line].1.iter().any(|(filled, _)| *filled == c) {
                return Err(format!(
                    "several points share the cell {} / {}; add the field that tells them apart to --rows or --where",
                    key.join(", "),
                    header(spec, &columns[c])
                ));
            }
            lines[line].1.push((c, value));
        }
    }
    let mut order: Vec<usize> = (0..columns.len()).collect();
    order.sort_by(|&a, &b| {
        let ((x, i), (y, j)) = (&columns[a], &columns[b]);
        let by_heading = match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => x.total_cmp(&y),
            _ => text(x).cmp(&text(y)),
        };
        by_heading.then(i.cmp(j))
    });
    let mut out = String::new();
    let header: Vec<String> = spec
        .rows
        .iter()
        .cloned()
        .chain(order.iter().map(|&c| header(spec, &columns[c])))
        .collect();
    out.push_str(&format!("| {} |\n", header.join(" | ")));
    out.push_str(&format!("|{}\n", " --- |".repeat(header.len())));
    for (key, cells) in &lines {
        let values = order.iter().map(|&c| {
            cells
                .iter()
                .find(|(filled, _)| *filled == c)
                .map_or(String::new(), |(_, v)| v.clone())
        });
        let line: Vec<String> = key.iter().cloned().chain(values).collect();
        out.push_str(&format!("| {} |\n", line.join(" | ")));
    }
    Ok(out)
}

/// A column's heading: `column=value`, the value's name after it when there are several, or the
/// value's name alone without a column field.
fn header(spec: &PivotSpec, (heading, v): &(Value, usize)) -> String {
    match (&spec.column, spec.values.len()) {
        (Some(column), 1) => format!("{column}={}", text(heading)),
        (Some(column), _) => format!("{column}={} {}", text(heading), spec.values[*v]),
        (None, _) => spec.values[*v].clone(),
    }
}

/// A cell's text: numbers to three significant digits, null as empty.
pub(crate) fn text(value: &Value) -> String {
    match value {
        Value::Null => String::new(),
        Value::String(s) => s.clone(),
        Value::Number(n) if n.is_i64() || n.is_u64() => n.to_string(),
        Value::Number(n) => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            let decade = x.abs().log10().floor();
            if x == 0.0 || !x.is_finite() {
                x.to_string()
            } else if (-2.0..4.0).contains(&decade) {
                let decimals = (2.0 - decade).max(0.0) as usize;
                format!("{x:.decimals$}")
            } else {
                format!("{x:.2e}")
            }
        }
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn row(cells: Value) -> Row {
        let mut row = Row::default();
        for (name, value) in cells.as_object().unwrap() {
            row.set(name, value.clone());
        }
        row
    }

    #[test]
    fn values_land_in_their_row_and_column_in_numeric_order() {
        let table = [
            row(json!({"case.quadrature": "ac", "n": 128, "order": 2.013})),
            row(json!({"case.quadrature": "ac", "n": 64, "order": 1.97})),
            row(json!({"case.quadrature": "midpoint", "n": 128, "order": 0.0012345})),
            row(json!({"case.quadrature": "midpoint", "n": 32, "order": null})),
        ];
        let spec = PivotSpec {
            rows: vec!["quadrature".into()],
            column: Some("n".into()),
            values: vec!["order".into()],
            filter: vec!["n >= 64".into()],
        };
        assert_eq!(
            markdown(&spec, &table).unwrap(),
            "| quadrature | n=64 | n=128 |\n| --- | --- | --- |\n| ac | 1.97 | 2.01 |\n| midpoint |  | 1.23e-3 |\n"
        );
        let clash = PivotSpec {
            rows: vec![],
            ..spec
        };
        assert!(markdown(&clash, &table).unwrap_err().contains("--rows"));
    }

    #[test]
    fn several_values_sit_side_by_side_as_a_convergence_table() {
        let table = [
            row(json!({"n": 16, "e": 0.004, "order": 1.9})),
            row(json!({"n": 8, "e": 0.016, "order": null})),
        ];
        let spec = PivotSpec {
            rows: vec!["n".into()],
            column: None,
            values: vec!["e".into(), "order".into()],
            filter: vec![],
        };
        assert_eq!(
            markdown(&spec, &table).unwrap(),
            "| n | e | order |\n| --- | --- | --- |\n| 16 | 4.00e-3 | 1.90 |\n| 8 | 0.0160 |  |\n"
        );
        let by_column = PivotSpec {
            rows: vec![],
            column: Some("n".into()),
            ..spec
        };
        assert_eq!(
            markdown(&by_column, &table).unwrap(),
            "| n=8 e | n=8 order | n=16 e | n=16 order |\n| --- | --- | --- | --- |\n| 0.0160 |  | 4.00e-3 | 1.90 |\n"
        );
    }
}
