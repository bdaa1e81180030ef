use super::splice::{splice, Source};
use super::*;
use serde_json::json;

fn row(value: Value) -> Row {
    let mut row = Row::default();
    for (name, value) in value.as_object().unwrap() {
        row.set_flattened(name, value.clone());
    }
    row
}

#[test]
fn columns_take_the_narrowest_type_of_their_cells() {
    let rows = [
        row(json!({"n": 8, "h": 1, "ok": true, "case": {"dim": 2}, "c_tot": [1.0, 2.0]})),
        row(json!({"n": 16, "h": 0.5, "ok": false, "message": "no", "tags": ["a", 1]})),
    ];
    let frame = data_frame(&rows).unwrap();
    let names: Vec<&str> = frame
        .get_column_names()
        .iter()
        .map(|n| n.as_str())
        .collect();
    // JSON objects iterate in name order; a column first seen in a later row comes last.
    assert_eq!(
        names,
        ["c_tot", "case.dim", "h", "n", "ok", "message", "tags"]
    );
    let dtype = |name: &str| frame.column(name).unwrap().dtype().clone();
    assert_eq!(dtype("n"), DataType::Int64);
    assert_eq!(dtype("h"), DataType::Float64);
    assert_eq!(dtype("ok"), DataType::Boolean);
    assert_eq!(dtype("c_tot"), DataType::List(Box::new(DataType::Float64)));
    let c_tot = frame.column("c_tot").unwrap().list().unwrap();
    let first = c_tot.get_as_series(0).unwrap();
    assert_eq!(first.f64().unwrap().to_vec(), [Some(1.0), Some(2.0)]);
    assert_eq!(c_tot.get_as_series(1), None);
    // An array that is not numbers stays JSON text.
    assert_eq!(dtype("tags"), DataType::String);
    assert_eq!(
        frame.column("tags").unwrap().get(1).unwrap(),
        AnyValue::String("[\"a\",1]")
    );
    assert_eq!(
        frame.column("h").unwrap().get(1).unwrap(),
        AnyValue::Float64(0.5)
    );
}

/// A row where the case and the record differ: FETI's record holds p² subdomains and the
/// backend `auto` chose, the case p and `auto`; the case leaves `collar` out.
fn feti_row() -> Row {
    let mut row = Row::default();
    row.set("subdomains", json!(16));
    row.set("backend", json!("stencil"));
    row.set("collar", json!("zero"));
    row.set("case.subdomains", json!(4));
    row.set("case.backend", json!("auto"));
    row.set("case.collar", serde_json::Value::Null);
    row
}

#[test]
fn a_case_field_wins_over_the_record_column_of_the_same_name() {
    // A figure's `where` speaks the study's language: the case's.
    let row = feti_row();
    let named = row.expression_fields();
    assert_eq!(named["subdomains"], json!(4));
    assert_eq!(named["backend"], json!("auto"));
    // A field the case leaves out is the record's resolved value.
    assert_eq!(named["collar"], json!("zero"));
}

#[test]
fn a_filter_reads_a_row_as_its_expression_fields_do() {
    use crate::model::expression::{condition, Filter, Scope};
    let mut row = feti_row();
    row.set("h", json!(0.5));
    row.set("case.n", json!(63));
    let everything = Scope::from_fields(&row.expression_fields());
    for text in [
        "subdomains == 4",
        "subdomains == 16",
        "backend == 'auto'",
        "collar == 'zero'",
        "case.subdomains == 4 && case.collar == 'zero'",
        "h == 1/32",
        "n * h < 2",
        "absent > 1",
    ] {
        let filter = Filter::parse(&[text.to_string()]).unwrap();
        let kept = row.meets(&filter).map_err(|(_, e)| e);
        assert_eq!(kept, condition(text, &everything), "{text}");
    }
    // In order, stopping at the first that does not hold; one that cannot be evaluated says
    // which, with the row's names.
    let filter = |texts: [&str; 2]| Filter::parse(&texts.map(String::from)).unwrap();
    assert_eq!(
        row.meets(&filter(["subdomains == 16", "absent > 1"])),
        Ok(false)
    );
    let (k, why) = row
        .meets(&filter(["subdomains == 4", "absent > 1"]))
        .unwrap_err();
    assert_eq!(k, 1);
    assert!(
        why.contains("unknown name `absent`") && why.contains("subdomains"),
        "{why}"
    );
}

#[test]
fn a_table_reads_back_typed_with_its_description_units_and_notes() {
    let temporary = tempfile::tempdir().unwrap();
    let dir = temporary.path().to_path_buf();
    let path = dir.join("t.parquet");
    let rows = [
        row(json!({"point": "n=16", "workers": 2, "solve_s_median": 0.5,
            "peak_memory_bytes": 1024, "bond_updates_per_s": 1e9, "error_l2_norm": 1e-3,
            "c_tot": {"time": [0.0, 0.5], "c_tot": [1.0, 0.99]}})),
        row(json!({"point": "n=32", "workers": 4, "c_tot": {"time": [], "c_tot": null}})),
    ];
    let about = About {
        description: "Heat in a square.",
        notes: &[("point", "a label"), ("absent", "not in this table")],
    };
    write_parquet_about(&[(&path, &rows)], &about).unwrap();
    let mut reader = ParquetReader::new(std::fs::File::open(&path).unwrap());
    let mut metadata: Vec<(String, String)> = reader
        .get_metadata()
        .unwrap()
        .key_value_metadata
        .iter()
        .flatten()
        .filter(|kv| kv.key != "ARROW:schema")
        .map(|kv| (kv.key.clone(), kv.value.clone().unwrap_or_default()))
        .collect();
    metadata.sort();
    let expected = [
        ("description", "Heat in a square."),
        ("note:point", "a label"),
        ("unit:bond_updates_per_s", "1/s"),
        ("unit:peak_memory_bytes", "bytes"),
        ("unit:solve_s_median", "s"),
    ];
    let expected: Vec<(String, String)> = expected
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    assert_eq!(metadata, expected);

    let frame = reader.finish().unwrap();
    let workers = frame.column("workers").unwrap().i64().unwrap();
    assert_eq!(workers.to_vec(), [Some(2), Some(4)]);
    let time = frame.column("c_tot.time").unwrap().list().unwrap();
    let time: Vec<Option<Vec<Option<f64>>>> = (0..time.len())
        .map(|i| time.get_as_series(i).map(|s| s.f64().unwrap().to_vec()))
        .collect();
    assert_eq!(time, [Some(vec![Some(0.0), Some(0.5)]), Some(vec![])]);

    // read_parquet gives lists back as JSON arrays, as the figures read them.
    let back = read_parquet(&path).unwrap();
    assert_eq!(back[0].get("c_tot.c_tot"), Some(&json!([1.0, 0.99])));
    assert_eq!(back[1].get("c_tot.time"), Some(&json!([])));
    assert_eq!(back[1].get("c_tot.c_tot"), Some(&Value::Null));
    assert_eq!(back[1].get("workers"), Some(&json!(4)));
}

#[test]
fn units_are_read_off_column_names() {
    let units = [
        ("solve_s", Some("s")),
        ("step_s_iqr", Some("s")),
        ("feti_phases.coarse_s", Some("s")),
        ("bond_updates_per_s", Some("1/s")),
        ("halo_bytes", Some("bytes")),
        ("speedup", None),
        ("steps", None),
        ("case.t_end", None),
        ("error_l2_norm", None),
    ];
    for (column, expected) in units {
        assert_eq!(unit(column), expected, "{column}");
    }
}

/// A frame's Parquet bytes, as a table file holds them.
fn parquet_bytes(frame: &mut DataFrame) -> Vec<u8> {
    let mut bytes = Vec::new();
    ParquetWriter::new(&mut bytes).finish(frame).unwrap();
    bytes
}

/// A frame as it reads back from its file.
fn read_back(frame: &mut DataFrame) -> DataFrame {
    let bytes = parquet_bytes(frame);
    ParquetReader::new(std::io::Cursor::new(bytes))
        .finish()
        .unwrap()
}

/// Rows of a few columns each, mostly of one type per column, sometimes null or of another
/// type, with columns sometimes missing: a small random table (seeded, so that a failure
/// repeats).
struct Rows(fastrand::Rng);

impl Rows {
    fn next(&mut self, below: u64) -> u64 {
        self.0.u64(..below)
    }

    fn row(&mut self) -> Row {
        let mut row = Row::default();
        for (k, name) in ["status", "n", "h", "ok", "c_tot", "message", "case.m"]
            .into_iter()
            .enumerate()
        {
            if self.next(6) == 0 {
                continue;
            }
            let kind = match self.next(30) {
                0..=2 => 9,
                3 => self.next(6),
                _ => k as u64 % 6,
            };
            let value = match kind {
                0 => json!(["ok", "failed"][self.next(2) as usize]),
                1 => json!(self.next(100)),
                2 => json!(self.next(100) as f64 / 7.0),
                3 => json!(self.next(2) == 0),
                4 => json!([self.next(9) as f64 / 3.0, null]),
                5 => json!(self.next(100)),
                _ => Value::Null,
            };
            row.set(name, value);
        }
        row
    }
}

/// A table spliced from its old frame, its rows' shapes and the rows that changed is the
/// table of all its rows, byte for byte, with their shapes; or the splice says it cannot.
#[test]
fn a_spliced_table_is_byte_for_byte_the_table_of_its_rows() {
    let (mut spliced, mut gathered) = (0, 0);
    for seed in 0..300 {
        let mut random = Rows(fastrand::Rng::with_seed(seed));
        // One table in ten long enough to be spliced of more runs than are sliced.
        let most = if seed % 10 == 0 { 3000 } else { 10 };
        let old: Vec<Row> = (0..1 + random.next(most)).map(|_| random.row()).collect();
        let (mut order, mut rows, mut new) = (Vec::new(), Vec::new(), Vec::new());
        for (k, row) in old.iter().enumerate() {
            if random.next(4) == 0 {
                order.push(Source::New(new.len()));
                new.push(random.row());
                rows.push(new.last().unwrap().clone());
            }
            match random.next(5) {
                0 => {} // gone
                1 => {
                    order.push(Source::New(new.len()));
                    new.push(random.row());
                    rows.push(new.last().unwrap().clone());
                }
                _ => {
                    order.push(Source::Kept(k));
                    rows.push(row.clone());
                }
            }
        }
        if rows.is_empty() {
            continue;
        }
        let old_frame = read_back(&mut data_frame(&old).unwrap());
        let Some((mut frame, shapes)) = splice(&old_frame, &shapes(&old), &new, &order) else {
            continue;
        };
        spliced += 1;
        let at = |source: &Source| match *source {
            Source::Kept(k) => k,
            Source::New(j) => old.len() + j,
        };
        let breaks = order.windows(2).filter(|w| at(&w[0]) + 1 != at(&w[1]));
        gathered += usize::from(breaks.count() >= 1024);
        let mut whole = data_frame(&rows).unwrap();
        assert_eq!(frame.schema(), whole.schema(), "seed {seed}");
        assert!(
            parquet_bytes(&mut frame) == parquet_bytes(&mut whole),
            "seed {seed}: {frame}\nagainst\n{whole}"
        );
        assert_eq!(shapes.kept(), super::shapes(&rows).kept(), "seed {seed}");
        assert_eq!(shapes.schema().len(), whole.width(), "seed {seed}");
    }
    assert!(
        spliced > 150,
        "only {spliced} of 300 tables could be spliced"
    );
    assert!(
        gathered > 0,
        "no table was spliced of more runs than are sliced"
    );
}

/// Where the rows that go were the only floats of a column of integers, the old frame no longer
/// holds the integers the whole table would: the splice says so rather than guess.
#[test]
fn a_splice_that_would_narrow_a_column_declines() {
    let old = [row(json!({"n": 1})), row(json!({"n": 0.5}))];
    let frame = read_back(&mut data_frame(&old).unwrap());
    assert!(splice(&frame, &shapes(&old), &[], &[Source::Kept(0)]).is_none());
    let widened = splice(
        &frame,
        &shapes(&old),
        &[row(json!({"n": 2.5}))],
        &[Source::Kept(0), Source::New(0)],
    );
    assert!(widened.is_some());
}

/// Fields flattened together are the cells each flattened in turn would make, where their
/// names hold no `.` (as `run_row` calls it); a cell the row had before takes the new value.
#[test]
fn fields_flattened_together_are_those_flattened_one_by_one() {
    let fields = json!({"case": {"n": 8, "dim": {"x": 1}}, "h": 0.5, "point": "n=8", "c": []});
    let mut one_by_one = Row::default();
    let mut together = Row::default();
    for row in [&mut one_by_one, &mut together] {
        row.set("point", json!("before"));
    }
    for (name, value) in fields.as_object().unwrap() {
        one_by_one.set_flattened(name, value.clone());
    }
    together.set_all_flattened(fields.as_object().unwrap().clone());
    assert_eq!(together, one_by_one);
    let names: Vec<&str> = together.cells().map(|(name, _)| name).collect();
    assert_eq!(names, ["point", "c", "case.dim.x", "case.n", "h"]);
    assert_eq!(together.text("point"), Some("n=8"));
}

/// A row with two cells of one name (a record's unknown field holding both `a.b` and `a: {b}`,
/// flattened alike) is one cell of its column, the later, in whichever place the row stands:
/// never a second cell that shifts the rows after it.
#[test]
fn two_cells_of_one_name_in_a_row_are_one_cell_of_its_column() {
    let mut twice = Row::default();
    twice.set_flattened("extra", json!({"a.b": 1, "a": {"b": 2}}));
    assert_eq!(twice.cells().count(), 2, "flattened alike: {twice:?}");
    let other = Row::of_cells(json!({"x": 1}));
    let later = twice.cells().last().unwrap().1.as_i64();
    for (rows, at) in [([twice.clone(), other.clone()], 0), ([other, twice], 1)] {
        let frame = data_frame(&rows).unwrap();
        assert_eq!(frame.shape(), (2, 2));
        let column = frame.column("extra.a.b").unwrap().i64().unwrap().to_vec();
        let mut expected = vec![None, None];
        expected[at] = later;
        assert_eq!(column, expected);
    }
}

/// However a table's rows are handed to its writer (whole, or in slices of any size), its file
/// is the same bytes, in row groups of the writer's size; and it reads back as the frame.
#[test]
fn a_table_written_in_slices_is_the_bytes_of_the_table_written_whole() {
    let dir = tempfile::tempdir().unwrap();
    let about = About {
        description: "a study",
        notes: &[("status", "what became of the run")],
    };
    for seed in 0..20 {
        let mut random = Rows(fastrand::Rng::with_seed(seed));
        let rows: Vec<Row> = (0..1 + random.next(120)).map(|_| random.row()).collect();
        let frame = data_frame(&rows).unwrap();
        let written = |slices: &[usize]| -> Vec<u8> {
            let path = dir.path().join("t.parquet");
            let mut writer = TableWriter::create(&path, &path, frame.schema(), &about, 16).unwrap();
            let mut start = 0;
            for &length in slices {
                writer.write(frame.slice(start as i64, length)).unwrap();
                start += length;
            }
            writer.finish().unwrap();
            std::fs::read(&path).unwrap()
        };
        let whole = written(&[frame.height()]);
        let mut slices = Vec::new();
        let mut left = frame.height();
        while left > 0 {
            let length = (random.next(40) as usize).min(left);
            slices.push(length); // (an empty slice among them, now and then)
            left -= length;
        }
        assert!(written(&slices) == whole, "seed {seed}: slices {slices:?}");
        let mut reader = ParquetReader::new(std::io::Cursor::new(whole));
        let groups = reader.get_metadata().unwrap().row_groups.len();
        assert_eq!(groups, frame.height().div_ceil(16), "seed {seed}");
        assert!(
            reader.finish().unwrap().equals_missing(&frame),
            "seed {seed}"
        );
    }
}

/// A table of no rows is written and reads back as no rows.
#[test]
fn a_table_of_no_rows_reads_back_empty() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.parquet");
    write_parquet(&[(path.as_path(), &[])]).unwrap();
    assert!(read_parquet(&path).unwrap().is_empty());
}
