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

#[test]
fn a_case_field_wins_over_the_record_column_of_the_same_name() {
    // FETI's record holds p² subdomains and the backend `auto` chose; the case holds p and
    // `auto`. A figure's `where` speaks the study's language: the case's.
    let mut row = Row::default();
    row.set("subdomains", json!(16));
    row.set("backend", json!("stencil"));
    row.set("collar", json!("zero"));
    row.set("case.subdomains", json!(4));
    row.set("case.backend", json!("auto"));
    row.set("case.collar", serde_json::Value::Null);
    let named = row.expression_fields();
    assert_eq!(named["subdomains"], json!(4));
    assert_eq!(named["backend"], json!("auto"));
    // A field the case leaves out is the record's resolved value.
    assert_eq!(named["collar"], json!("zero"));
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
