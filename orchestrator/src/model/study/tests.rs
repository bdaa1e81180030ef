use super::*;
use serde_json::json;

fn points(study: Value) -> Result<Vec<Map<String, Value>>, StudyError> {
    let study = crate::kinds::parse(&study.to_string())?;
    Ok(study.expand()?.into_iter().map(|p| p.fields()).collect())
}

fn fields(value: Value) -> Map<String, Value> {
    value.as_object().expect("an object").clone()
}

#[test]
fn a_point_writes_its_fields_as_their_map_prints_and_a_swept_value_beats_the_base() {
    let study = crate::kinds::parse(
        &json!({
            "name": "t",
            "base": {"z": null, "a": 1.5e-300, "n": 8, "s": "é \"q\"", "o": {"k": [1, 0.1]}},
            "sweep": [{"product": {"n": [16], "b": ["x"]}}, {"zip": {"m": [2], "a": [3]}}],
            "derive": {"eps": "m * h"},
        })
        .to_string(),
    )
    .unwrap();
    let points = study.expand().unwrap();
    let point = &points[0];
    let mut written = Vec::new();
    point.write_fields(&mut written).unwrap();
    let fields = point.fields();
    assert_eq!(
        String::from_utf8(written).unwrap(),
        Value::Object(fields.clone()).to_string()
    );
    assert_eq!(
        (fields["n"].clone(), fields["a"].clone()),
        (json!(16), json!(3))
    );
    assert_eq!(point.get("eps"), Some(&json!(2.0 / 16.0)));
    assert_eq!(point.get("z"), Some(&Value::Null));
    assert_eq!(point.label(), "b=x n=16 a=3 m=2 eps=0.125");
}

#[test]
fn a_sweep_is_counted_before_it_is_made_and_refused_past_the_limit() {
    let values: Vec<u64> = (0..100).collect();
    let huge = json!({
        "name": "s", "base": {},
        "sweep": [{"product": {"a": values, "b": values, "c": values}},
                  {"branches": {"x": [{"zip": {"d": values}}], "y": [{"path": {"kind": "fixed_m", "m": 2, "n": values}}]}}],
        "repeat": 3
    });
    let e = points(huge).unwrap_err();
    assert_eq!(e.field, "sweep");
    // 100³ × (100 + 100) × 3, none of them made.
    assert!(
        e.message.contains("expands to 600000000 points"),
        "{}",
        e.message
    );
    let fits = json!({"name": "s", "base": {}, "sweep": [{"product": {"a": values, "b": values}}], "repeat": 3});
    assert_eq!(points(fits).unwrap().len(), 30_000);
}

#[test]
fn a_control_character_anywhere_is_refused_naming_its_place() {
    let study = |extra: Value| {
        let mut s = json!({"name": "s", "base": {"dim": 1}, "description": "line one\nline two"});
        s.as_object_mut().unwrap().extend(fields(extra));
        crate::kinds::parse(&s.to_string())
    };
    assert!(study(json!({})).is_ok(), "prose may hold newlines");
    let cases = [
        (
            json!({"sweep": [{"branches": {"a\u{1b}[31m": []}}]}),
            "sweep[0].branches.a\\u{1b}[31m",
        ),
        (json!({"where": ["n > 1\n"]}), "where[0]"),
        (
            json!({"figures": [{"name": "f", "kind": "convergence", "title": "t\r"}]}),
            "figures[0].title",
        ),
        (
            json!({"resources": {"queue": "debug\ntouch /tmp/pwned"}}),
            "resources.queue",
        ),
    ];
    for (extra, place) in cases {
        let e = study(extra).unwrap_err();
        assert_eq!(e.field, place);
        assert!(e.message.contains("control character"), "{}", e.message);
    }
}

#[test]
fn branches_are_alternatives_named_in_the_tables_but_not_the_case() {
    let study = crate::kinds::parse(
        &json!({
            "name": "s", "base": {"dim": 1},
            "sweep": [
                {"branches": {
                    "fixed_m": [{"product": {"m": [2, 4], "source": ["local"]}},
                                {"product": {"n": [8, 16]}}],
                    "fixed_eps": [{"path": {"kind": "fixed_eps", "eps": 0.25, "n": [8, 16]}}]
                }},
                {"product": {"kernel": ["constant", "linear"]}}
            ],
            "where": ["branch != 'fixed_eps' || kernel == 'linear'"]
        })
        .to_string(),
    )
    .unwrap();
    let points = study.expand().unwrap();
    let on = |b: &str| {
        points
            .iter()
            .filter(|p| p.branch.as_deref() == Some(b))
            .count()
    };
    assert_eq!((on("fixed_m"), on("fixed_eps"), points.len()), (8, 2, 10));
    for p in &points {
        assert!(
            !p.fields().contains_key("branch"),
            "the solver must not see it"
        );
        assert!(p
            .label()
            .starts_with(&format!("branch={}", p.branch.as_ref().unwrap())));
    }
    // The tables' columns: the branch, then what any branch sweeps.
    assert_eq!(
        fields_telling_apart(&points),
        ["branch", "n", "eps", "kernel", "m", "source"]
    );
    // A refinement series runs along n within one branch.
    let eps_series: Vec<String> = points
        .iter()
        .filter(|p| p.branch.as_deref() == Some("fixed_eps"))
        .map(|p| p.series().refinement)
        .collect();
    assert_eq!(eps_series, ["branch=fixed_eps kernel=linear"; 2]);
    // The other branch's path moves m with n; this one's m stays in its series.
    let m_series = points
        .iter()
        .find(|p| p.branch.as_deref() == Some("fixed_m"))
        .map(|p| p.series().refinement);
    assert_eq!(
        m_series.as_deref(),
        Some("branch=fixed_m m=2 source=local kernel=constant")
    );
    let bad = crate::kinds::parse(
        &json!({"name": "s", "base": {}, "sweep": [{"branches": {"a": [{"product": {"n": []}}]}}]})
            .to_string(),
    )
    .unwrap()
    .expand()
    .unwrap_err();
    assert_eq!(bad.field, "sweep[0].branches.a[0].product.n", "{bad}");
}

#[test]
fn a_branch_may_have_its_own_where_and_repeat() {
    let study = crate::kinds::parse(
        &json!({
            "name": "s", "base": {"dim": 1, "n": 16},
            "sweep": [{"branches": {
                "threads": {"sweep": [{"product": {"threads": [1, 2, 4]}}],
                            "where": ["threads <= 2"], "repeat": 3},
                "steps": [{"zip": {"cfl": [0.25, 0.5], "dt": [null, 0.001]}}]
            }}],
            // Spans branches: `threads` is read only where the branch has it.
            "where": ["branch != 'threads' || threads >= 1"]
        })
        .to_string(),
    )
    .unwrap();
    let points = study.expand().unwrap();
    let on = |b: &str| {
        points
            .iter()
            .filter(|p| p.branch.as_deref() == Some(b))
            .map(|p| (p.get("threads").cloned(), p.repeat))
            .collect::<Vec<_>>()
    };
    let threads: Vec<_> = [1, 2]
        .iter()
        .flat_map(|&t| (0..3).map(move |r| (Some(json!(t)), r)))
        .collect();
    assert_eq!(on("threads"), threads);
    assert_eq!(on("steps"), [(None, 0), (None, 0)]);
    // `null` in a zip leaves the field out of the case (here: dt from cfl).
    assert_eq!(points[0].get("dt"), Some(&Value::Null));

    let refused = |branches: Value| {
        crate::kinds::parse(
            &json!({"name": "s", "base": {}, "sweep": [{"branches": branches}]}).to_string(),
        )
        .and_then(|s| s.expand())
        .unwrap_err()
    };
    let e = refused(json!({"a": {"sweep": [], "where": ["thread > 1"]}}));
    assert_eq!(e.field, "sweep[0].branches.a.where[0]", "{e}");
    assert!(e.message.contains("unknown name `thread`"), "{e}");
    let e = refused(json!({"a": {"repeat": 0}}));
    assert_eq!(e.field, "sweep[0].branches.a.repeat", "{e}");
    let e = refused(json!({"a": {"sweep": [{"branches": {"a": []}}]}}));
    assert!(e.message.contains("give each branch its own name"), "{e}");
    let e = refused(json!({"a": {"repeats": 2}}));
    assert!(e.message.contains("did you mean `repeat`?"), "{e}");
}

#[test]
fn study_files_may_carry_comments_or_be_toml() {
    let commented = r#"
        // a first study
        {
          "name": "s", /* results/s/ */
          "base": {"dim": 1, "note": "a // in a string stays"},
          "sweep": [{"product": {"n": [8, 16]}}]  # shell style too
        }"#;
    let toml = r#"
        name = "s"
        [base]
        dim = 1
        note = "a // in a string stays"
        [[sweep]]
        product = { n = [8, 16] }
    "#;
    let json = crate::kinds::parse(commented).unwrap().expand().unwrap();
    let from_toml = crate::kinds::parse_toml(toml).unwrap().expand().unwrap();
    assert_eq!(json, from_toml);
    assert_eq!(json[1].fields()["note"], "a // in a string stays");
    // Comments become spaces: an error still names its line in the file.
    let error = crate::kinds::parse("// one\n// two\n{\"name\": }").unwrap_err();
    assert!(error.message.contains("line 3"), "{error}");
    let error = crate::kinds::parse_toml("name = \"s\"\nname = \"t\"").unwrap_err();
    assert!(error.message.contains("not valid TOML"), "{error}");
    // nan and inf are no values (a `Value` would hold them as null: "not given"), and a
    // date is no number.
    for (text, place) in [
        ("[base]\ndt = nan", "base.dt"),
        (
            "[[sweep]]\nproduct = { dt = [0.1, inf] }",
            "sweep[0].product.dt[1]",
        ),
        ("timeout_s = inf", "timeout_s"),
    ] {
        let error = crate::kinds::parse_toml(&format!("name = \"s\"\n{text}")).unwrap_err();
        assert!(
            error.message.contains(place) && error.message.contains("not a finite number"),
            "{text}: {error}"
        );
    }
    let error = crate::kinds::parse_toml("name = \"s\"\n[base]\nt_end = 1979-05-27").unwrap_err();
    assert!(error.message.contains("quote it"), "{error}");
    let error = crate::kinds::parse("\u{feff}{\"name\": \"s\", \"base\": {}}").unwrap_err();
    assert!(error.message.contains("byte-order mark"), "{error}");
    let error = crate::kinds::parse_toml("name = \"s\"\n[base]\n[[sweep]]\nproduct = { n = [] }")
        .unwrap()
        .expand()
        .unwrap_err();
    assert_eq!(error.field, "sweep[0].product.n");
}

#[test]
fn product_and_zip_groups_multiply() {
    let got = points(json!({
        "name": "s", "base": {"dim": 1},
        "sweep": [
            {"product": {"n": [8, 16], "m": [2, 3]}},
            {"zip": {"threads": [1, 2], "ranks": [2, 1]}}
        ]
    }))
    .unwrap();
    let mut expected = Vec::new();
    for (m, n) in [(2, 8), (3, 8), (2, 16), (3, 16)] {
        for (threads, ranks) in [(1, 2), (2, 1)] {
            expected.push(fields(json!({
                "dim": 1, "n": n, "m": m, "threads": threads, "ranks": ranks
            })));
        }
    }
    // Axes of a product vary in name order, the last fastest.
    expected.sort_by_key(|f| (f["m"].as_u64(), f["n"].as_u64()));
    let mut got_sorted = got.clone();
    got_sorted.sort_by_key(|f| (f["m"].as_u64(), f["n"].as_u64()));
    assert_eq!(got.len(), 8);
    assert_eq!(got_sorted, expected);
}

#[test]
fn derived_fields_paths_filters_and_repeats() {
    let study = crate::kinds::parse(
        &json!({
            "name": "s", "base": {"dim": 2},
            "sweep": [
                {"path": {"kind": "fixed_m", "m": 3, "n": [16, 32]}},
                {"product": {"px": [1, 2], "py": [1, 2]}}
            ],
            "derive": {"ranks": "px * py", "eps_check": "m * h"},
            "where": ["ranks <= 2"],
            "repeat": 2
        })
        .to_string(),
    )
    .unwrap();
    let points = study.expand().unwrap();
    // 2 sizes × 3 shapes with px·py ≤ 2, twice each.
    assert_eq!(points.len(), 12);
    let first = points[0].fields();
    assert_eq!(first["n"], json!(16));
    assert_eq!(first["m"], json!(3));
    assert_eq!(first["ranks"], json!(1));
    assert_eq!(first["eps_check"], json!(3.0 / 16.0));
    assert_eq!((points[0].repeat, points[1].repeat), (0, 1));
    assert!(points
        .iter()
        .all(|p| p.fields()["ranks"].as_u64() <= Some(2)));

    let eps_paths = points_of_path(json!({"kind": "fixed_eps", "eps": 0.25, "n": [8, 16]}));
    assert_eq!(eps_paths, vec![(8, json!(0.25)), (16, json!(0.25))]);
    let power = points_of_path(json!({"kind": "power", "c": 2.0, "alpha": 0.5, "n": [4, 16]}));
    assert_eq!(power, vec![(4, json!(1.0)), (16, json!(0.5))]);
}

#[test]
fn series_hold_all_but_the_grid_or_the_workers_fixed() {
    let series = |study: Value| -> Vec<(String, String)> {
        let study = crate::kinds::parse(&study.to_string()).unwrap();
        let points = study.expand().unwrap();
        points
            .into_iter()
            .map(|p| p.series())
            .map(|s| (s.refinement, s.scaling))
            .collect()
    };
    // A product moves only its `n`; a zip moves all its fields with its worker counts.
    let got = series(json!({
        "name": "s", "base": {},
        "sweep": [
            {"product": {"n": [8, 16], "m": [2]}},
            {"zip": {"threads": [1, 2], "ranks": [2, 1]}}
        ]
    }));
    let expected = [
        ("m=2 ranks=2 threads=1", "m=2 n=8"),
        ("m=2 ranks=1 threads=2", "m=2 n=8"),
        ("m=2 ranks=2 threads=1", "m=2 n=16"),
        ("m=2 ranks=1 threads=2", "m=2 n=16"),
    ];
    let expected: Vec<(String, String)> = expected
        .iter()
        .map(|(r, s)| (r.to_string(), s.to_string()))
        .collect();
    assert_eq!(got, expected);
    // A path moves its horizon with n; derived fields are left out of the names.
    let got = series(json!({
        "name": "s", "base": {},
        "sweep": [
            {"path": {"kind": "power", "c": 1.0, "alpha": 0.5, "n": [4, 16]}},
            {"product": {"px": [1, 2], "method": ["nonlocal"]}}
        ],
        "derive": {"ranks": "px"}
    }));
    assert_eq!(
        got[0],
        (
            "method=nonlocal px=1".into(),
            "n=4 eps=0.5 method=nonlocal".into()
        )
    );
    assert_eq!(
        got[3],
        (
            "method=nonlocal px=2".into(),
            "n=16 eps=0.25 method=nonlocal".into()
        )
    );
}

fn points_of_path(path: Value) -> Vec<(u64, Value)> {
    points(json!({"name": "s", "base": {}, "sweep": [{"path": path}]}))
        .unwrap()
        .into_iter()
        .map(|f| (f["n"].as_u64().unwrap(), f["eps"].clone()))
        .collect()
}

#[test]
fn labels_split_into_their_parts_where_a_name_and_equals_follow() {
    assert_eq!(
        label_parts("branch=a b n=16 kernel=constant"),
        [
            ("branch".to_string(), "a b".to_string()),
            ("n".to_string(), "16".to_string()),
            ("kernel".to_string(), "constant".to_string())
        ]
    );
    assert!(label_parts("").is_empty());
    assert_eq!(label_parts("cfl=null dt=1e-8").len(), 2);
    assert_eq!(
        label_parts("branch=x=y z").len(),
        1,
        "a value may hold = and spaces"
    );
}

#[test]
fn malformed_studies_name_the_place() {
    let place = |study: Value| points(study).unwrap_err().field;
    assert_eq!(place(json!({"name": "s"})), "base");
    assert_eq!(
        place(json!({"name": "s", "base": {}, "colour": 1})),
        "colour"
    );
    assert_eq!(place(json!({"name": "a b", "base": {}})), "name");
    assert_eq!(
        place(json!({"name": "s", "base": {}, "repeat": 0})),
        "repeat"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {}, "sweep": [{"zip": {"n": [1, 2], "m": [1]}}]})),
        "sweep[0].zip.n"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {}, "sweep": [{"product": {"n": []}}]})),
        "sweep[0].product.n"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {}, "sweep": [
            {"product": {"n": [1]}}, {"product": {"n": [2]}}
        ]})),
        "sweep[1].n"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {"n": 4}, "derive": {"ranks": "px * 2"}})),
        "derive.ranks"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {"n": 4}, "where": ["n + 1"]})),
        "where[0]"
    );
    assert_eq!(
        place(
            json!({"name": "s", "base": {}, "sweep": [{"path": {"kind": "fixed_m", "m": 2, "n": [0]}}]})
        ),
        "sweep[0].path.n"
    );
    assert_eq!(place(json!({"name": "a".repeat(256), "base": {}})), "name");
    assert_eq!(
        place(json!({"name": "s", "base": {},
            "figures": [{"name": "f".repeat(201), "kind": "convergence"}]})),
        "figures[0].name"
    );
    assert_eq!(
        place(json!({"name": "s", "base": {}, "sweep": [
            {"path": {"kind": "power", "c": 1e300, "alpha": -100.0, "n": [4]}}
        ]})),
        "sweep[0].path"
    );
    // JSON text, not a Value: a key given twice in a map (`base`) would keep the last.
    let twice = crate::kinds::parse(r#"{"name": "s", "base": {"dim": 2, "n": 8, "dim": 1}}"#);
    let error = twice.map(|_| ()).unwrap_err();
    assert_eq!(error.field, "file");
    assert!(
        error.message.contains("the key `dim` is given twice"),
        "{error}"
    );
}

#[test]
fn a_boundaries_figure_needs_a_boundary_question() {
    let study = |extra: Value| {
        let mut s = json!({
            "name": "s", "base": {"dim": 1},
            "figures": [{"name": "limits", "kind": "boundaries"}]
        });
        s.as_object_mut().unwrap().extend(fields(extra));
        crate::kinds::parse(&s.to_string())
    };
    let e = study(json!({})).unwrap_err();
    assert_eq!(e.field, "figures[0].kind");
    assert!(
        e.message.contains("give the study a `boundary` question"),
        "{}",
        e.message
    );
    let asked = json!({"boundary": {"field": "cfl", "bracket": [0.5, 2], "flips": "amplification > 1", "rtol": 1e-3}});
    assert!(study(asked).is_ok());
}
