use super::*;
use crate::model::figure_spec::FigureKind;
use crate::output::draw::Glyph;
use crate::store::table::Row;
use serde_json::{json, Value};

/// A summary table with two methods, each on three grids and two worker counts, a
/// stability sweep with one diverged point, and c_tot series.
fn summary() -> Vec<Row> {
    let mut rows = Vec::new();
    for (method, cost) in [("nonlocal", 1.0), ("pse", 3.0)] {
        for n in [16.0, 32.0, 64.0] {
            for workers in [1.0, 2.0] {
                let mut row = Row::default();
                let h = 1.0 / n;
                let time = cost * n * n / (1.0 + 0.8 * (workers - 1.0));
                for (name, value) in [
                    (
                        "point",
                        json!(format!("method={method} n={n} threads={workers}")),
                    ),
                    ("scaling_series", json!(format!("method={method} n={n}"))),
                    (
                        "refinement_series",
                        json!(format!("method={method} threads={workers}")),
                    ),
                    ("status", json!("ok")),
                    ("repeats", json!(3)),
                    ("case.method", json!(method)),
                    ("case.n", json!(n)),
                    ("case.threads", json!(workers)),
                    ("case.cfl", json!(0.25 * n / 16.0)),
                    ("workers", json!(workers)),
                    ("h", json!(h)),
                    ("error_l2_norm", json!(cost * h * h)),
                    ("max_abs", json!(1.0 + n / 64.0)),
                    ("solve_s_median", json!(time)),
                    ("solve_s_min", json!(0.9 * time)),
                    ("solve_s_max", json!(1.2 * time)),
                    ("c_tot.time", json!("[0.0,0.5,1.0]")),
                    (
                        "c_tot.c_tot",
                        json!(format!("[1.0,{},{}]", 1.0 - h, 1.0 - 2.0 * h)),
                    ),
                ] {
                    row.set(name, value);
                }
                rows.push(row);
            }
        }
    }
    rows[10].set("status", json!("diverged"));
    // A 4 × 4 field snapshot on the coarsest grid: u = ix + 4 iy, error (ix − iy)/10.
    for row in rows.iter_mut().filter(|r| r.number("case.n") == Some(16.0)) {
        let values: Vec<f64> = (0..16).map(f64::from).collect();
        let error: Vec<f64> = (0..16).map(|i| f64::from(i % 4 - i / 4) / 10.0).collect();
        for (name, value) in [
            ("field.nx", json!(4)),
            ("field.ny", json!(4)),
            ("field.lower", json!(0.0)),
            ("field.upper", json!(1.0)),
            (
                "field.values",
                json!(serde_json::to_string(&values).unwrap()),
            ),
            ("field.error", json!(serde_json::to_string(&error).unwrap())),
        ] {
            row.set(name, value);
        }
    }
    rows
}

fn spec(name: &str, kind: FigureKind, filter: &[&str]) -> FigureSpec {
    FigureSpec {
        name: name.into(),
        kind,
        title: None,
        x: None,
        y: None,
        series: None,
        filter: filter.iter().map(|f| f.to_string()).collect(),
    }
}

fn specs() -> Vec<FigureSpec> {
    let mut work = spec("work", FigureKind::WorkPrecision, &["threads == 1"]);
    work.series = Some(vec!["method".into()]);
    let mut stability = spec("stability", FigureKind::Stability, &["threads == 1"]);
    stability.series = Some(vec!["method".into()]);
    vec![
        spec("strong", FigureKind::StrongScaling, &["n == 64"]),
        spec("weak", FigureKind::WeakScaling, &["n == 64"]),
        spec("convergence", FigureKind::Convergence, &[]),
        work,
        stability,
        spec(
            "series",
            FigureKind::TimeSeries,
            &["threads == 1", "method == 'pse'"],
        ),
        spec(
            "field",
            FigureKind::Field,
            &["n == 16", "threads == 1", "method == 'nonlocal'"],
        ),
    ]
}

/// The texts of an SVG, which must parse as XML.
fn texts(svg: &str) -> Vec<String> {
    let document = roxmltree::Document::parse(svg).expect("well-formed SVG");
    document
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| n.text().unwrap_or("").trim().to_string())
        .collect()
}

#[test]
fn every_kind_draws_its_series_and_axes() {
    let rows = summary();
    // (figure, series in its legend, axis labels it must carry)
    let expected: [(&str, usize, &[&str]); 7] = [
        (
            "strong",
            2,
            &[
                "workers (threads × ranks)",
                "solve time, median of 3 repeats (s)",
                "speedup T(p₀) / T(p)",
            ],
        ),
        (
            "weak",
            2,
            &[
                "workers (threads × ranks)",
                "weak-scaling efficiency T(p₀) / T(p)",
            ],
        ),
        ("convergence", 4, &["grid spacing h", "discrete L² error"]),
        (
            "work",
            2,
            &["discrete L² error", "solve time, median of 3 repeats (s)"],
        ),
        (
            "stability",
            2,
            &["dt / dt_stable", "max|u| at the final time"],
        ),
        ("series", 3, &["time t", "total concentration c_tot(t)"]),
        (
            "field",
            0,
            &["x", "y", "u at the final time", "error u − u_exact"],
        ),
    ];
    for (k, spec) in specs().iter().enumerate() {
        let chart = figure::chart(spec, k, &rows, None).unwrap();
        let (name, series, labels) = expected[k];
        assert_eq!(spec.name, name);
        assert_eq!(chart.panels[0].series.len(), series, "{name}");
        let texts = texts(&draw::render(&chart).unwrap());
        for label in labels {
            assert!(
                texts.iter().any(|t| t == label),
                "{name} lacks `{label}`: {texts:?}"
            );
        }
        for s in &chart.panels[0].series {
            assert!(
                texts.contains(&s.label),
                "{name}: no legend entry `{}`",
                s.label
            );
        }
    }
}

#[test]
fn points_of_two_builds_never_share_a_line() {
    let mut rows = summary();
    let one = figure::chart(&specs()[2], 2, &rows, None).unwrap().panels[0]
        .series
        .len();
    // The finest grid rerun by another build: it leaves each refinement line.
    for row in rows.iter_mut() {
        let build = match row.number("case.n") {
            Some(64.0) => "bbbbbbbb",
            _ => "aaaaaaaa",
        };
        row.set("build", json!(build));
    }
    let chart = figure::chart(&specs()[2], 2, &rows, None).unwrap();
    let series = &chart.panels[0].series;
    assert!(series.len() > one, "{} series", series.len());
    assert!(
        series.iter().all(|s| s.label.contains("build = ")),
        "{:?}",
        series.iter().map(|s| &s.label).collect::<Vec<_>>()
    );
}

#[test]
fn figures_hold_what_the_table_says() {
    let rows = summary();
    let specs = specs();
    // Convergence: e = c h² gives slope 2 on every series.
    let chart = figure::chart(&specs[2], 2, &rows, None).unwrap();
    let slopes: Vec<Option<&str>> = chart.panels[0]
        .series
        .iter()
        .map(|s| s.note.as_deref())
        .collect();
    assert_eq!(slopes, [Some("2"); 4]);
    // Strong scaling: speedup 1.8 at two workers, efficiency 0.9.
    let chart = figure::chart(&specs[0], 0, &rows, None).unwrap();
    let speedup = &chart.panels[1].series[0].points;
    assert!((speedup[1].1 - 1.8).abs() < 1e-12, "{speedup:?}");
    let efficiency = &chart.panels[2].series[0].points;
    assert!((efficiency[1].1 - 0.9).abs() < 1e-12);
    assert!(chart.panels.iter().all(|p| p.series[0].marks.is_empty()));
    // Points run on more workers than cores are crossed out in every panel, and said so.
    let mut crowded = rows.clone();
    for row in crowded
        .iter_mut()
        .filter(|r| r.number("workers") == Some(2.0))
    {
        row.set("oversubscribed", json!(true));
    }
    let chart = figure::chart(&specs[0], 0, &crowded, None).unwrap();
    for panel in &chart.panels {
        let crossed: Vec<(f64, f64)> = panel.series[0].marks.iter().map(|m| m.0).collect();
        assert_eq!(crossed, panel.series[0].points[1..], "{}", panel.title);
    }
    assert!(
        chart
            .glyphs
            .iter()
            .any(|(g, m)| *g == Glyph::Cross && m.contains("contention")),
        "the legend says what a cross means"
    );
    // Stability: the diverged pse point is a cross, not a point of the line.
    let chart = figure::chart(&specs[4], 4, &rows, None).unwrap();
    let pse = &chart.panels[0].series[1];
    assert_eq!((pse.points.len(), pse.marks.len()), (2, 1));
}

#[test]
fn a_field_figure_maps_one_points_field_and_its_error() {
    let mut rows = summary();
    let specs = specs();
    let chart = figure::chart(&specs[6], 6, &rows, None).unwrap();
    let heat = |k: usize| chart.panels[k].heat.as_ref().expect("a heat map");
    assert_eq!(chart.panels.len(), 2);
    assert_eq!((heat(0).nx, heat(0).ny, heat(0).values[5]), (4, 4, 5.0));
    assert!(!heat(0).diverging && heat(1).diverging);
    assert_eq!(heat(1).values[1], 0.1);
    // 16 cells per map, and 64 levels per colour bar.
    let svg = draw::render(&chart).unwrap();
    let document = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    let rects = document
        .descendants()
        .filter(|n| n.has_tag_name("rect"))
        .count();
    assert!(rects >= 2 * (16 + 64), "{rects} rectangles");

    // A 1D snapshot is drawn as profiles over x, at the cells' centres.
    rows[0].set("field.nx", json!(16));
    rows[0].set("field.ny", json!(1));
    let chart = figure::chart(&specs[6], 6, &rows, None).unwrap();
    let profile = &chart.panels[0].series[0].points;
    assert!(chart.panels[0].heat.is_none());
    assert_eq!((profile[0], profile.len()), ((1.0 / 32.0, 0.0), 16));

    // Without an exact solution there is no error column, and only the field is drawn.
    let without_error: Vec<Row> = rows
        .iter()
        .map(|r| {
            let mut kept = Row::default();
            for (name, value) in r.cells().filter(|(name, _)| *name != "field.error") {
                kept.set(name, value.clone());
            }
            kept
        })
        .collect();
    let chart = figure::chart(&specs[6], 6, &without_error, None).unwrap();
    assert_eq!(chart.panels.len(), 1);

    // The figure shows one point: a filter selecting two is refused, naming `where`.
    let mut both = specs[6].clone();
    both.filter.pop();
    let error = figure::chart(&both, 6, &rows, None).err().unwrap();
    assert!(
        error.starts_with("figures[6] (field): where selects 2 points"),
        "{error}"
    );
    let mut none = specs[6].clone();
    none.filter = vec![
        "n == 32".into(),
        "threads == 1".into(),
        "method == 'pse'".into(),
    ];
    let error = figure::chart(&none, 6, &rows, None).err().unwrap();
    assert!(error.contains("set `field_snapshot`"), "{error}");
}

#[test]
fn a_figure_is_redrawn_only_when_its_table_or_spec_changes() {
    let temporary = tempfile::tempdir().unwrap();
    let dir = temporary.path().to_path_buf();
    let store = Store::open(&dir, "synthetic");
    std::fs::create_dir_all(store.table("")).unwrap();
    let table = store.table("synthetic-summary.parquet");
    let rows = summary();
    table::write_parquet(&[(&table, &rows)]).unwrap();
    let mut specs = specs();
    let redrawn = |drawn: Vec<Figure>| {
        let outcomes = drawn.iter().map(|d| &d.outcome);
        outcomes.filter(|o| **o == Outcome::Drawn).count()
    };

    assert_eq!(redrawn(plot(&specs, None, &store).unwrap()), 7);
    let first = std::fs::read(&plot(&specs, None, &store).unwrap()[2].path).unwrap();
    assert_eq!(
        redrawn(plot(&specs, None, &store).unwrap()),
        0,
        "nothing changed"
    );

    // The same table written again gives the same bytes, and so the same figures.
    table::write_parquet(&[(&table, &rows)]).unwrap();
    assert_eq!(redrawn(plot(&specs, None, &store).unwrap()), 0);
    let svg = dir.join("synthetic/figures/convergence.svg");
    std::fs::remove_file(&svg).unwrap();
    assert_eq!(redrawn(plot(&specs, None, &store).unwrap()), 1);
    assert_eq!(std::fs::read(&svg).unwrap(), first, "byte-identical");

    specs[2].title = Some("orders".into());
    assert_eq!(
        redrawn(plot(&specs, None, &store).unwrap()),
        1,
        "only the changed spec"
    );
    let mut changed = rows.clone();
    changed[0].set("error_l2_norm", json!(0.5));
    table::write_parquet(&[(&table, &changed)]).unwrap();
    assert_eq!(
        redrawn(plot(&specs, None, &store).unwrap()),
        7,
        "a changed table redraws all"
    );
}

/// The `<text>` elements of an SVG: (text, font size, x, y, fill).
fn text_elements(svg: &str) -> Vec<(String, f64, f64, f64, String)> {
    let document = roxmltree::Document::parse(svg).expect("well-formed SVG");
    let number = |n: &roxmltree::Node, a: &str| -> f64 {
        n.attribute(a)
            .and_then(|v| v.parse().ok())
            .unwrap_or(f64::NAN)
    };
    document
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| {
            let text = n.text().unwrap_or("").trim().to_string();
            let fill = n.attribute("fill").unwrap_or("").to_string();
            (
                text,
                number(&n, "font-size"),
                number(&n, "x"),
                number(&n, "y"),
                fill,
            )
        })
        .collect()
}

#[test]
fn figures_read_on_a_page_at_100_percent() {
    let rows = summary();
    for (k, spec) in specs().iter().enumerate() {
        let svg = draw::render(&figure::chart(spec, k, &rows, None).unwrap()).unwrap();
        let document = roxmltree::Document::parse(&svg).unwrap();
        let width: f64 = document
            .root_element()
            .attribute("width")
            .unwrap()
            .parse()
            .unwrap();
        assert!(width <= 1040.0, "{}: {width} px wide", spec.name);
        for (text, size, ..) in text_elements(&svg) {
            assert!(size >= 14.0, "{}: `{text}` at {size} px", spec.name);
        }
    }
    // Strong scaling's three panels wrap two to a row, each at least 480 px wide.
    let svg = draw::render(&figure::chart(&specs()[0], 0, &rows, None).unwrap()).unwrap();
    let texts = text_elements(&svg);
    let caption = |name: &str| {
        let found = texts.iter().find(|t| t.0.starts_with(name));
        found.map(|t| (t.2, t.3)).expect(name)
    };
    let (time, speedup, efficiency) = (
        caption("time"),
        caption("speedup"),
        caption("parallel efficiency"),
    );
    assert_eq!(time.1, speedup.1, "one row");
    assert!(speedup.0 - time.0 >= 480.0, "{time:?} {speedup:?}");
    assert!(
        efficiency.1 > time.1 + 300.0,
        "the third wraps: {efficiency:?}"
    );
}

#[test]
fn titles_are_written_for_people() {
    let rows = summary();
    let chart = figure::chart(&specs()[0], 0, &rows, None).unwrap();
    assert_eq!(
        (&chart.title[..], &chart.subtitle[..]),
        ("strong", "n = 64")
    );
    let labels: Vec<&str> = chart.panels[0]
        .series
        .iter()
        .map(|s| &s.label[..])
        .collect();
    assert_eq!(labels, ["method = nonlocal", "method = pse"]);
    // No `key=value` dump in any text of any figure.
    for (k, spec) in specs().iter().enumerate() {
        let svg = draw::render(&figure::chart(spec, k, &rows, None).unwrap()).unwrap();
        for text in texts(&svg) {
            let dumped = text.contains('=') && !text.contains(" = ");
            assert!(!dumped, "{}: `{text}`", spec.name);
        }
    }
}

#[test]
fn repeats_are_counted_only_where_a_statistic_is_over_them() {
    let rows = summary();
    let specs = specs();
    let convergence = figure::chart(&specs[2], 2, &rows, None).unwrap();
    let labels: Vec<&str> = convergence.panels[0]
        .series
        .iter()
        .map(|s| &s.label[..])
        .collect();
    assert_eq!(
        labels[0],
        "method = nonlocal, threads = 1: order 2 fitted, 2 finest pair"
    );
    let svg = draw::render(&convergence).unwrap();
    assert!(!svg.contains("repeat"), "errors are deterministic");
    let work = figure::chart(&specs[3], 3, &rows, None).unwrap();
    assert_eq!(
        work.panels[0].y.label,
        "solve time, median of 3 repeats (s)"
    );
    assert!(work.panels[0]
        .series
        .iter()
        .all(|s| !s.label.contains("repeat")));
}

#[test]
fn notes_beside_coinciding_lines_do_not_overlap() {
    // Threads do not change the error: both series of each method lie on one line, and
    // their notes would be written on top of each other.
    let svg = draw::render(&figure::chart(&specs()[2], 2, &summary(), None).unwrap()).unwrap();
    let mut notes: Vec<f64> = text_elements(&svg)
        .into_iter()
        .filter(|t| t.0 == "2" && t.4 != "#000000")
        .map(|t| t.3)
        .collect();
    assert_eq!(notes.len(), 4, "{notes:?}");
    notes.sort_by(f64::total_cmp);
    for pair in notes.windows(2) {
        assert!(pair[1] - pair[0] >= 14.0, "{notes:?}");
    }
}

#[test]
fn a_where_that_selects_nothing_names_its_figure() {
    let mut none = specs()[2].clone();
    none.filter = vec!["n == 7".into()];
    let error = figure::chart(&none, 2, &summary(), None).err().unwrap();
    assert!(
        error.starts_with(
            "figures[2] (convergence): where selects no row of the summary table (12 rows)"
        ),
        "{error}"
    );
}

/// Points scaled over threads and over ranks in one series are two lines, each from the
/// serial point; the subtitle holds what is fixed and nothing empty; a noisy point is ringed
/// and the legend says what a ring is.
#[test]
fn scaling_lines_split_by_kind_of_parallelism_and_noisy_points_are_ringed() {
    let row = |threads: u64, ranks: u64, time: f64, noisy: u64| {
        let kind = match (threads > 1, ranks > 1) {
            (false, false) => "serial",
            (true, false) => "threads",
            _ => "ranks",
        };
        Row::of_cells(json!({
            "point": format!("threads={threads} ranks={ranks}"), "scaling_series": "",
            "status": "ok", "repeats": 3, "case.threads": threads, "case.ranks": ranks,
            "workers": threads * ranks, "parallelism": kind, "solve_s_median": time,
            "noisy_repeats": noisy,
        }))
    };
    let rows = [row(1, 1, 1.0, 0), row(2, 1, 0.55, 1), row(1, 2, 0.52, 0)];
    let spec = spec("scaling", FigureKind::StrongScaling, &[]);
    let chart = figure::chart(&spec, 0, &rows, None).unwrap();
    assert!(draw::lint(&chart).is_empty(), "{:?}", draw::lint(&chart));
    assert!(
        !chart.subtitle.contains('='),
        "no lone `=`: {:?}",
        chart.subtitle
    );
    let times = &chart.panels[0].series;
    let labels: Vec<&str> = times.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(labels, ["parallelism = ranks", "parallelism = threads"]);
    assert_eq!(times[0].points, [(1.0, 1.0), (2.0, 0.52)]);
    assert_eq!(times[1].points, [(1.0, 1.0), (2.0, 0.55)]);
    assert_eq!(times[1].marks, [((2.0, 0.55), Glyph::Ring)]);
    assert!(chart
        .glyphs
        .iter()
        .any(|(g, m)| *g == Glyph::Ring && m.contains("noisy")));
    let svg = draw::render(&chart).unwrap();
    assert!(
        svg.contains("noisy: timed while"),
        "the ring is in the legend"
    );
}

/// A figure that cannot be made says why in the reader's terms: every run failed (not a
/// column the spec names), one worker count for a scaling figure.
#[test]
fn a_figure_that_cannot_be_made_says_why() {
    let failed: Vec<Row> = summary()
        .into_iter()
        .map(|mut r| {
            r.set("status", json!("failed"));
            r.set("error_l2_norm", Value::Null);
            r
        })
        .collect();
    let error = figure::chart(&specs()[2], 2, &failed, None).err().unwrap();
    assert!(error.contains("every run failed"), "{error}");
    // A stability sweep where nothing diverged is drawn, and its legend explains no cross.
    let stable: Vec<Row> = summary()
        .into_iter()
        .map(|mut r| {
            r.set("status", json!("ok"));
            r
        })
        .collect();
    let chart = figure::chart(&specs()[4], 4, &stable, None).unwrap();
    assert!(draw::lint(&chart).is_empty() && chart.glyphs.is_empty());
    let mut one = specs()[0].clone();
    one.filter = vec!["n == 64".into(), "threads == 1".into()];
    let error = figure::chart(&one, 0, &summary(), None).err().unwrap();
    assert!(error.contains("one worker count (1)"), "{error}");
}

#[test]
fn a_failing_figure_leaves_the_others_drawn() {
    let temporary = tempfile::tempdir().unwrap();
    let dir = temporary.path().to_path_buf();
    let store = Store::open(&dir, "synthetic");
    std::fs::create_dir_all(store.table("")).unwrap();
    let table = store.table("synthetic-summary.parquet");
    table::write_parquet(&[(&table, &summary())]).unwrap();
    let mut specs = specs();
    assert!(all_drawn(&plot(&specs, None, &store).unwrap()).is_ok());
    // A misspelt column in the second figure: the first and the third are still drawn,
    // and the second's figure of the earlier spec is gone.
    specs[1].x = Some("wrkers".into());
    specs[2].title = Some("orders".into());
    let figures = plot(&specs, None, &store).unwrap();
    let outcomes: Vec<&Outcome> = figures.iter().map(|f| &f.outcome).collect();
    let Outcome::Failed(message) = outcomes[1] else {
        panic!("{outcomes:?}")
    };
    assert!(
        message.starts_with("figures[1] (weak): x names no column `wrkers`"),
        "{message}"
    );
    assert_eq!(
        (outcomes[0], outcomes[2]),
        (&Outcome::UpToDate, &Outcome::Drawn)
    );
    assert!(!figures[1].path.exists() && figures[2].path.exists());
    let summary = all_drawn(&figures).err().unwrap();
    assert!(
        summary.starts_with("1 of 7 figures not drawn: figures[1] (weak)"),
        "{summary}"
    );
}
