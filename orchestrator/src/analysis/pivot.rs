//! `nlstudy table`: values of a study's summary table as a Markdown pivot, rows named by some
//! fields and columns by another (e.g. observed orders by path and quadrature against n), or one
//! column per value (e.g. errors and orders by n, as a convergence table), for results pages
//! that are regenerated rather than copied by hand. Also the Markdown table and the cell texts
//! every table people read is made of: numbers with four significant digits, one notation per
//! column.

use crate::console::numbers_alike;
use crate::model::expression::{Filter, GRID_SPACING_READS};
use crate::store::table::Row;
use schema::record::columns;
use serde_json::{Map, Value};

pub struct PivotSpec {
    pub rows: Vec<String>,
    /// The field whose values head the columns; without it, each value is one column.
    pub column: Option<String>,
    /// The summary columns in the cells, side by side under each column heading.
    pub values: Vec<String>,
    pub filter: Vec<String>,
}

impl PivotSpec {
    /// The columns the pivot reads of a table with the columns `names`, so that a table of
    /// 10⁵ rows and a hundred columns is read for the few it shows: its fields' and values'
    /// columns (by their own names and as case fields), the columns its `--where` names (and
    /// those `h` is computed from), and the points' labels its errors name. A field or value
    /// the table lacks is refused here, naming the columns close to it.
    pub fn columns(&self, names: &[&str]) -> Result<Vec<String>, String> {
        self.refuse_missing(|| names.iter().copied())?;
        let filter = Filter::parse(&self.filter).map_err(at_where)?;
        let mut read: Vec<&str> = (self.rows.iter().chain(&self.column).chain(&self.values))
            .chain(filter.names())
            .map(String::as_str)
            .chain(["point", columns::CASE_ID])
            .collect();
        if read.contains(&"h") {
            read.extend(GRID_SPACING_READS);
        }
        Ok((names.iter())
            .filter(|column| read.iter().any(|name| is_column(column, name)))
            .map(|column| column.to_string())
            .collect())
    }

    /// Refuses the first of the pivot's fields and values that none of `columns` holds, naming
    /// the columns close to it.
    fn refuse_missing<'a, I: Iterator<Item = &'a str>>(
        &self,
        columns: impl Fn() -> I,
    ) -> Result<(), String> {
        for name in self.rows.iter().chain(&self.column).chain(&self.values) {
            if !columns().any(|column| is_column(column, name)) {
                return Err(no_column(name, columns()));
            }
        }
        Ok(())
    }
}

/// Whether the table column `column` holds the field `name`: by its name, or as a case field.
fn is_column(column: &str, name: &str) -> bool {
    column == name || column.strip_prefix("case.") == Some(name)
}

/// A `--where` condition that cannot be read: which, and why.
fn at_where((k, e): (usize, String)) -> String {
    format!("--where {k}: {e}")
}

/// A line of the pivot: its row fields' values, and its cells by column index.
type Line = (Vec<Value>, Vec<(usize, Value)>);

/// The pivot as a Markdown table; a cell no row fills stays empty, one that several fill is an
/// error (the row fields do not tell the points apart).
pub fn markdown(spec: &PivotSpec, table: &[Row]) -> Result<String, String> {
    if spec.values.is_empty() {
        return Err("give at least one --value".into());
    }
    let kept = kept_rows(spec, table)?;
    spec.refuse_missing(|| table.iter().flat_map(Row::cells).map(|(column, _)| column))?;
    let fields: Vec<&String> = spec.rows.iter().chain(&spec.column).collect();
    for name in &fields {
        let null: Vec<&Row> = kept
            .iter()
            .filter(|(_, named)| named.get(name.as_str()).is_none_or(Value::is_null))
            .map(|(row, _)| *row)
            .collect();
        if !null.is_empty() {
            return Err(null_in(name, &null, kept.len()));
        }
    }
    // A column is (the column field's value, or null without one; the value's index).
    let mut columns: Vec<(Value, usize)> = Vec::new();
    let mut lines: Vec<Line> = Vec::new();
    for (_, named) in &kept {
        let cell = |name: &str| named.get(name).cloned().unwrap_or(Value::Null);
        let key: Vec<Value> = spec.rows.iter().map(|name| cell(name)).collect();
        let heading = spec.column.as_deref().map_or(Value::Null, cell);
        let line = match lines.iter().position(|(k, _)| *k == key) {
            Some(l) => l,
            None => {
                lines.push((key.clone(), Vec::new()));
                lines.len() - 1
            }
        };
        for (v, name) in spec.values.iter().enumerate() {
            let column = (heading.clone(), v);
            let c = match columns.iter().position(|c| *c == column) {
                Some(c) => c,
                None => {
                    columns.push(column);
                    columns.len() - 1
                }
            };
            if lines[line].1.iter().any(|(filled, _)| *filled == c) {
                let texts: Vec<String> = key.iter().map(|v| column_texts(&[v]).remove(0)).collect();
                let heading = column_texts(&[&columns[c].0]).remove(0);
                return Err(format!(
                    "several points share the cell {} / {}; add the field that tells them apart to --rows or --where",
                    texts.join(", "),
                    header(spec, &heading, v)
                ));
            }
            lines[line].1.push((c, cell(name)));
        }
    }
    let mut order: Vec<usize> = (0..columns.len()).collect();
    order.sort_by(|&a, &b| {
        let ((x, i), (y, j)) = (&columns[a], &columns[b]);
        let by_heading = match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => x.total_cmp(&y),
            _ => x.to_string().cmp(&y.to_string()),
        };
        by_heading.then(i.cmp(j))
    });
    let headings = column_texts(&order.iter().map(|&c| &columns[c].0).collect::<Vec<_>>());
    let header: Vec<String> = spec
        .rows
        .iter()
        .cloned()
        .chain(
            order
                .iter()
                .zip(&headings)
                .map(|(&c, heading)| header(spec, heading, columns[c].1)),
        )
        .collect();
    // The table column by column, each in one notation: the row fields, then the pivot's.
    let key_columns = (0..spec.rows.len())
        .map(|k| column_texts(&lines.iter().map(|(key, _)| &key[k]).collect::<Vec<_>>()));
    let value_columns = order.iter().map(|&c| {
        let cells: Vec<&Value> = lines
            .iter()
            .map(|(_, cells)| {
                cells
                    .iter()
                    .find(|(filled, _)| *filled == c)
                    .map_or(&Value::Null, |(_, v)| v)
            })
            .collect();
        column_texts(&cells)
    });
    let by_column: Vec<Vec<String>> = key_columns.chain(value_columns).collect();
    Ok(markdown_table(&header, &transpose(by_column, lines.len())))
}

/// A row the filter keeps, and its fields as expressions name them.
type Kept<'a> = (&'a Row, Map<String, Value>);

/// The table's rows the filter keeps.
fn kept_rows<'a>(spec: &PivotSpec, table: &'a [Row]) -> Result<Vec<Kept<'a>>, String> {
    let filter = Filter::parse(&spec.filter).map_err(at_where)?;
    let mut kept = Vec::new();
    for row in table {
        if row.meets(&filter).map_err(at_where)? {
            kept.push((row, row.expression_fields()));
        }
    }
    Ok(kept)
}

/// "No such column", with those of `columns` whose names are close to it.
fn no_column<'a>(name: &str, columns: impl IntoIterator<Item = &'a str>) -> String {
    let mut names: Vec<&str> = Vec::new();
    for column in columns {
        for known in [column, column.strip_prefix("case.").unwrap_or(column)] {
            if !names.contains(&known) {
                names.push(known);
            }
        }
    }
    // Headline results first (`error_l2_norm` before `error_l2`, the norm's square), then the
    // nearest.
    let mut close: Vec<(bool, usize, &str)> = names
        .into_iter()
        .filter_map(|known| {
            let distance = strsim::damerau_levenshtein(name, known);
            // A typo (an edit per three letters), or a longer name holding it (`solve_s` for
            // `solve_s_median`).
            let near = distance <= (name.chars().count() / 3).max(1)
                || (name.len() >= 3 && known.contains(name));
            let headline = crate::analysis::summary::HEADLINE_RESULTS.contains(&known);
            near.then_some((!headline, distance, known))
        })
        .collect();
    close.sort();
    let close: Vec<String> = close
        .iter()
        .take(5)
        .map(|(_, _, n)| format!("`{n}`"))
        .collect();
    match close.is_empty() {
        true => format!("the summary table has no column `{name}`"),
        false => format!(
            "the summary table has no column `{name}`; close: {}",
            close.join(", ")
        ),
    }
}

/// "The column is there but null in these rows", naming their points.
fn null_in(name: &str, rows: &[&Row], kept: usize) -> String {
    const SHOWN: usize = 3;
    let points: Vec<&str> = rows
        .iter()
        .take(SHOWN)
        .map(|row| {
            row.text("point")
                .or(row.text(columns::CASE_ID))
                .unwrap_or("(no label)")
        })
        .collect();
    let more = match rows.len() > SHOWN {
        true => format!(" and {} more", rows.len() - SHOWN),
        false => String::new(),
    };
    format!(
        "column `{name}` is null in {} of the {kept} rows (points {}{more}); leave them out with --where, or choose another field",
        rows.len(),
        points.join("; ")
    )
}

/// A column's heading: `column=value`, the value's name after it when there are several, or the
/// value's name alone without a column field.
fn header(spec: &PivotSpec, heading: &str, v: usize) -> String {
    match (&spec.column, spec.values.len()) {
        (Some(column), 1) => format!("{column}={heading}"),
        (Some(column), _) => format!("{column}={heading} {}", spec.values[v]),
        (None, _) => spec.values[v].clone(),
    }
}

/// The texts of one column's cells: its numbers in one notation with four significant digits
/// (`console::numbers_alike`), text as it is, null as empty, anything else as JSON.
pub fn column_texts(cells: &[&Value]) -> Vec<String> {
    let numbers: Vec<f64> = cells.iter().filter_map(|v| v.as_f64()).collect();
    let mut numbers = numbers_alike(&numbers).into_iter();
    cells
        .iter()
        .map(|cell| match cell {
            Value::Number(_) => numbers.next().unwrap_or_default(),
            Value::Null => String::new(),
            Value::String(s) => s.clone(),
            other => other.to_string(),
        })
        .collect()
}

/// The cells of `rows` under `columns`, as lines of texts, each column in one notation.
pub fn texts(rows: &[Row], columns: &[&str]) -> Vec<Vec<String>> {
    let by_column = columns
        .iter()
        .map(|&name| column_texts(&crate::store::table::column(rows, name)))
        .collect();
    transpose(by_column, rows.len())
}

/// Columns of texts as lines.
fn transpose(columns: Vec<Vec<String>>, lines: usize) -> Vec<Vec<String>> {
    let mut out = vec![Vec::with_capacity(columns.len()); lines];
    for column in columns {
        for (line, text) in out.iter_mut().zip(column) {
            line.push(text);
        }
    }
    out
}

/// A Markdown table: the header, its rule, one line per row; every cell through `cell`.
pub fn markdown_table(header: &[String], lines: &[Vec<String>]) -> String {
    let joined = |cells: &[String]| {
        let cells: Vec<String> = cells.iter().map(|c| cell(c)).collect();
        cells.join(" | ")
    };
    let mut out = format!("| {} |\n", joined(header));
    out.push_str(&format!("|{}\n", " --- |".repeat(header.len())));
    for line in lines {
        out.push_str(&format!("| {} |\n", joined(line)));
    }
    out
}

/// Text as one Markdown table cell: a `|` (a branch named `a|b`) would end the cell, so it is
/// escaped, a line break would end the row, so it becomes a space, and a control character
/// (a stored message's ESC) would act on the terminal, so it is shown as its code.
pub fn cell(text: &str) -> String {
    let text = text.replace('|', "\\|").replace(['\n', '\r'], " ");
    schema::text::printable(&text).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn row(cells: Value) -> Row {
        Row::of_cells(cells)
    }

    #[test]
    fn a_bar_in_a_label_stays_inside_its_cell() {
        let table = markdown_table(
            &["branch".into(), "n|m".into()],
            &[vec!["a|b".into(), "1".into()]],
        );
        assert!(
            table.contains("a\\|b") && table.contains("n\\|m"),
            "{table}"
        );
        for line in table.lines() {
            let bars = line.replace("\\|", "").matches('|').count();
            assert_eq!(bars, 3, "{line}");
        }
    }

    #[test]
    fn a_control_character_in_a_cell_is_shown_as_its_code() {
        let table = markdown_table(
            &["message".into()],
            &[vec!["boom \u{1b}[31mRED\u{1b}]0;pwned\u{7}".into()]],
        );
        assert!(
            !table.contains('\u{1b}') && !table.contains('\u{7}'),
            "{table:?}"
        );
        assert!(table.contains("boom \\u{1b}[31mRED"), "{table}");
    }

    #[test]
    fn values_land_in_their_row_and_column_in_numeric_order() {
        let table = [
            row(json!({"case.quadrature": "ac", "n": 128, "order": 2.013})),
            row(json!({"case.quadrature": "ac", "n": 64, "order": 1.97})),
            row(json!({"case.quadrature": "midpoint", "n": 128, "order": 0.0012346})),
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
            "| quadrature | n=64 | n=128 |\n| --- | --- | --- |\n| ac | 1.97 | 2.013 |\n| midpoint |  | 0.001235 |\n"
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
            "| n | e | order |\n| --- | --- | --- |\n| 16 | 0.004 | 1.9 |\n| 8 | 0.016 |  |\n"
        );
        let by_column = PivotSpec {
            rows: vec![],
            column: Some("n".into()),
            ..spec
        };
        assert_eq!(
            markdown(&by_column, &table).unwrap(),
            "| n=8 e | n=8 order | n=16 e | n=16 order |\n| --- | --- | --- | --- |\n| 0.016 |  | 0.004 | 1.9 |\n"
        );
    }

    #[test]
    fn cells_and_headings_keep_four_significant_digits_one_notation_per_column() {
        // The table: a column of one-digit 0.000003 beside 9.4513e-9, and `cfl=0.0312`
        // heading the column of 0.03125.
        let table = [
            row(json!({"dt": 1e-3, "case.cfl": 0.5, "e": 0.000003})),
            row(json!({"dt": 1e-3, "case.cfl": 0.03125, "e": 0.25})),
            row(json!({"dt": 2.5e-4, "case.cfl": 0.5, "e": 9.4513e-9})),
            row(json!({"dt": 2.5e-4, "case.cfl": 0.03125, "e": 0.5})),
        ];
        let spec = PivotSpec {
            rows: vec!["dt".into()],
            column: Some("cfl".into()),
            values: vec!["e".into()],
            filter: vec![],
        };
        assert_eq!(
            markdown(&spec, &table).unwrap(),
            "| dt | cfl=0.03125 | cfl=0.5 |\n| --- | --- | --- |\n| 0.001 | 0.25 | 3e-6 |\n| 0.00025 | 0.5 | 9.451e-9 |\n"
        );
    }

    /// `nlstudy table` reads only the columns `PivotSpec::columns` names: the pivot of those is
    /// the pivot of the whole table, with `h` computed from the case's grid fields.
    #[test]
    fn the_pivot_reads_only_the_columns_it_shows_filters_or_labels_by() {
        let full = |n: u32, method: &str, threads: u32| {
            json!({"point": format!("method={method} n={n} threads={threads}"),
                "case_id": format!("{method}{n}{threads}"), "case.n": n, "n": n,
                "case.method": method, "case.length": null, "case.threads": threads,
                "threads": threads, "error_l2_norm": 1.0 / f64::from(n * threads),
                "solve_s_median": 0.5 * f64::from(n), "memory": 1e6})
        };
        let table: Vec<Value> = [(16, "nonlocal"), (64, "nonlocal"), (64, "adi")]
            .into_iter()
            .flat_map(|(n, method)| [1, 2].map(|t| full(n, method, t)))
            .collect();
        let names: Vec<&str> = table[0]
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        let spec = PivotSpec {
            rows: vec!["threads".into()],
            column: Some("method".into()),
            values: vec!["error_l2_norm".into()],
            filter: vec!["h < 0.05".into()],
        };
        let mut read = spec.columns(&names).unwrap();
        read.sort();
        assert_eq!(
            read,
            [
                "case.length",
                "case.method",
                "case.n",
                "case.threads",
                "case_id",
                "error_l2_norm",
                "n",
                "point",
                "threads"
            ]
        );
        let pick = |cells: &Value| {
            let mut cells = cells.clone();
            cells
                .as_object_mut()
                .unwrap()
                .retain(|name, _| read.contains(name));
            row(cells)
        };
        let whole: Vec<Row> = table.iter().cloned().map(row).collect();
        let picked: Vec<Row> = table.iter().map(pick).collect();
        let pivot = markdown(&spec, &picked).unwrap();
        assert_eq!(pivot, markdown(&spec, &whole).unwrap());
        assert_eq!(pivot.lines().count(), 4, "n = 64 only: {pivot}");
        // Without a filter naming h, nor the grid fields; a value the table lacks is refused
        // naming the table's close columns, a condition that cannot be read naming itself.
        let plain = PivotSpec {
            filter: vec![],
            ..spec
        };
        let mut read = plain.columns(&names).unwrap();
        read.sort();
        assert_eq!(
            read,
            [
                "case.method",
                "case.threads",
                "case_id",
                "error_l2_norm",
                "point",
                "threads"
            ]
        );
        let typo = PivotSpec {
            values: vec!["solve_s".into()],
            ..plain
        };
        assert_eq!(
            typo.columns(&names).unwrap_err(),
            "the summary table has no column `solve_s`; close: `solve_s_median`"
        );
        let unread = PivotSpec {
            values: vec!["memory".into()],
            filter: vec!["method == 'adi".into()],
            ..typo
        };
        assert!(unread
            .columns(&names)
            .unwrap_err()
            .starts_with("--where 0: "));
    }

    #[test]
    fn a_missing_column_is_told_from_one_that_is_null_in_some_points() {
        let table = [
            row(
                json!({"point": "method=nonlocal n=16", "n": 16, "case.cfl": 0.5, "solve_s_median": 1.0}),
            ),
            row(
                json!({"point": "method=adi n=16", "n": 16, "case.cfl": null, "solve_s_median": 2.0}),
            ),
            row(
                json!({"point": "method=adi n=32", "n": 32, "case.cfl": null, "solve_s_median": 3.0}),
            ),
        ];
        let spec = |column: &str, value: &str| PivotSpec {
            rows: vec!["n".into()],
            column: Some(column.into()),
            values: vec![value.into()],
            filter: vec![],
        };
        let null = markdown(&spec("cfl", "solve_s_median"), &table).unwrap_err();
        assert_eq!(
            null,
            "column `cfl` is null in 2 of the 3 rows (points method=adi n=16; method=adi n=32); leave them out with --where, or choose another field"
        );
        let typo = markdown(&spec("clf", "solve_s_median"), &table).unwrap_err();
        assert_eq!(typo, "the summary table has no column `clf`; close: `cfl`");
        let stem = markdown(&spec("n", "solve_s"), &table).unwrap_err();
        assert!(stem.ends_with("close: `solve_s_median`"), "{stem}");
        let far = markdown(&spec("n", "bandwidth"), &table).unwrap_err();
        assert_eq!(far, "the summary table has no column `bandwidth`");
        // A headline result before a nearer name: the norm, not its square.
        let errors = [row(
            json!({"point": "n=16", "n": 16, "error_l2": 1e-6, "error_l2_norm": 1e-3, "error_max": 2e-3}),
        )];
        let error = markdown(&spec("n", "error"), &errors).unwrap_err();
        assert_eq!(
            error,
            "the summary table has no column `error`; close: `error_l2_norm`, `error_l2`, `error_max`"
        );
        // The rows the filter leaves hold no null: the pivot is made.
        let only_nonlocal = PivotSpec {
            filter: vec!["method == 'nonlocal'".into()],
            ..spec("cfl", "solve_s_median")
        };
        let mut table = table.to_vec();
        for row in &mut table {
            let method = if row.get("case.cfl") == Some(&Value::Null) {
                "adi"
            } else {
                "nonlocal"
            };
            row.set("case.method", json!(method));
        }
        assert_eq!(
            markdown(&only_nonlocal, &table).unwrap(),
            "| n | cfl=0.5 |\n| --- | --- |\n| 16 | 1 |\n"
        );
    }
}
