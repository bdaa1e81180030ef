//! The study report as a person sees it: `nlstudy run` writes `results/<study>/report.html`, and
//! a real headless Chromium (Debian's, installed by `scripts/setup.sh --tests`, which `make test`
//! runs) loads it: every figure must render at a non-zero size, no console message may appear,
//! and a screenshot is saved beside the study.

use nonlocal_study::{chromium, measured, screenshot, text, Scratch, CHROMIUM};
use serde_json::json;
use std::path::Path;

/// The run's timeline, summed here from its events (not by nlstudy's own analysis): each lane's
/// cases, idle spans and the gaps between batches cover at least 95 % of the lane's wall time,
/// without overlapping; each case that ran is on it once with its solver's phases; and `status
/// --timeline` says the same share.
fn timeline_accounts_for_the_workers_time(scratch: &Scratch) {
    // A run that finds everything stored runs no case, and leaves no timeline of its own.
    let again = scratch.nlstudy("run", &["--allow-refused"]);
    assert!(text(&again).contains("report:"), "{}", text(&again));
    let dir = scratch.dir.join("results/report/timeline");
    let files: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    assert_eq!(files.len(), 1, "one run that ran cases, one timeline");
    let text = std::fs::read_to_string(files[0].path()).unwrap();
    let events: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let of = |kind: &str| -> Vec<&serde_json::Value> {
        events.iter().filter(|e| e["event"] == kind).collect()
    };
    let f = |e: &serde_json::Value, field: &str| e[field].as_f64().unwrap();
    let (batches, cases, idle) = (of("batch"), of("case"), of("idle"));
    assert_eq!(cases.len(), 3, "the three grids that ran: {text}");
    assert!(
        cases.iter().all(|c| f(&c["phases"], "wall_s") > 0.0),
        "{text}"
    );
    let begin = batches
        .iter()
        .map(|b| f(b, "begin"))
        .fold(f64::INFINITY, f64::min);
    let end = batches.iter().map(|b| f(b, "end")).fold(0.0, f64::max);
    let planning: f64 = {
        let mut spans: Vec<(f64, f64)> = batches
            .iter()
            .map(|b| (f(b, "begin"), f(b, "end")))
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        spans.windows(2).map(|w| w[1].0 - w[0].1).sum()
    };
    let mut lanes: Vec<(String, u64)> = cases
        .iter()
        .chain(&idle)
        .map(|e| {
            (
                e["node"].as_str().unwrap().to_string(),
                e["lane"].as_u64().unwrap(),
            )
        })
        .collect();
    lanes.sort();
    lanes.dedup();
    for (node, lane) in &lanes {
        let on = |e: &&&serde_json::Value| e["node"] == node.as_str() && e["lane"] == *lane;
        let mut spans: Vec<(f64, f64)> = cases
            .iter()
            .filter(on)
            .map(|c| (f(c, "started"), f(c, "saved")))
            .chain(idle.iter().filter(on).map(|i| (f(i, "from"), f(i, "to"))))
            .collect();
        spans.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(
            spans.windows(2).all(|w| w[1].0 >= w[0].1 - 1e-6),
            "lane {node} #{lane} overlaps: {spans:?}"
        );
        let covered: f64 = spans.iter().map(|s| s.1 - s.0).sum::<f64>() + planning;
        let share = covered / (end - begin);
        assert!(
            (0.95..=1.0 + 1e-6).contains(&share),
            "lane {node} #{lane}: {share} of its wall time accounted for"
        );
    }
    let status = scratch.nlstudy("status", &["--timeline"]);
    let said = nonlocal_study::text(&status);
    assert!(status.status.success(), "{said}");
    let shares: Vec<f64> = said
        .lines()
        .filter_map(|l| {
            l.trim_end()
                .strip_suffix(" %")?
                .split_whitespace()
                .last()?
                .parse()
                .ok()
        })
        .collect();
    assert_eq!(shares.len(), lanes.len(), "{said}");
    assert!(shares.iter().all(|s| *s >= 95.0), "{said}");
    assert!(said.contains("3 cases on 1 lane of 1 node"), "{said}");
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn the_report_opens_in_a_browser_with_every_figure_drawn() {
    assert!(
        Path::new(CHROMIUM).exists(),
        "{CHROMIUM} is missing: `scripts/setup.sh --tests` (run by `make test`) installs Debian's chromium"
    );
    // Three grids converge; n = 3 is refused (ε = 2h above 1/2), so the report has a failure.
    let study = json!({
        "name": "report",
        "description": "The nonlocal solver in 1D at fixed m against h, for the report's test.",
        "base": {"dim": 1, "m": 2, "t_end": 0.001, "cfl": 0.5, "source": "local"},
        "sweep": [{"product": {"n": [16, 32, 64, 3]}}],
        "figures": [
            {"name": "convergence", "kind": "convergence", "title": "Error against h at m = 2",
             "where": ["n > 3"]},
            {"name": "cost", "kind": "work_precision", "title": "Error against time",
             "where": ["n > 3"]}
        ]
    });
    let scratch = Scratch::new("report", &study);
    let run = scratch.nlstudy("run", &["--allow-refused"]);
    assert_eq!(
        run.status.code(),
        Some(1),
        "one point fails: {}",
        text(&run)
    );
    let report = scratch.dir.join("results/report/report.html");
    assert!(
        text(&run).contains(&format!("report: {}", report.display())),
        "{}",
        text(&run)
    );
    let page = std::fs::read_to_string(&report).expect("the run wrote its report");
    timeline_accounts_for_the_workers_time(&scratch);
    // Each figure names the build and machine of its runs.
    let build = text(
        &std::process::Command::new(nonlocal_study::binary("nlsolve"))
            .arg("fingerprint")
            .output()
            .unwrap(),
    );
    assert_eq!(
        page.matches(&format!("(runs of build {} on ", &build.trim()[..8]))
            .count(),
        2,
        "{page}"
    );
    for expected in [
        "The nonlocal solver in 1D at fixed m against h",
        "4 stored runs:",
        "3 ok",
        "1 failed",
        "ε = m/n",
        "Provenance",
    ] {
        assert!(page.contains(expected), "the report lacks {expected:?}");
    }

    // The page loaded in a frame of a harness that measures each figure once it has loaded
    // (the frame shares the harness's file origin with --allow-file-access-from-files).
    let harness = scratch.dir.join("harness.html");
    std::fs::write(
        &harness,
        r#"<!DOCTYPE html><html><body>
<iframe id="report" src="results/report/report.html" style="width:1200px;height:3000px"></iframe>
<pre id="measured">not loaded</pre>
<script>
const frame = document.getElementById('report');
frame.addEventListener('load', () => {
  const doc = frame.contentDocument;
  const figures = [...doc.querySelectorAll('figure')].map(figure => {
    const image = figure.querySelector('img');
    const box = image ? image.getBoundingClientRect() : {width: 0, height: 0};
    const caption = figure.querySelector('figcaption');
    return {id: figure.id, width: box.width, height: box.height,
            decoded: image ? image.complete && image.naturalWidth > 0 : false,
            caption: caption ? caption.textContent : ''};
  });
  const rows = doc.querySelectorAll('tr').length;
  document.getElementById('measured').textContent =
    JSON.stringify({title: doc.title, figures: figures, rows: rows});
});
</script></body></html>"#,
    )
    .unwrap();
    let loaded = chromium(
        &scratch,
        &harness,
        &[
            "--allow-file-access-from-files",
            "--virtual-time-budget=10000",
            "--dump-dom",
        ],
    );
    let log = String::from_utf8_lossy(&loaded.stderr);
    assert!(loaded.status.success(), "chromium failed: {log}");
    let measured = measured(&String::from_utf8_lossy(&loaded.stdout));
    eprintln!("measured in chromium: {measured}");
    assert_eq!(measured["title"], "Study report");
    let figures = measured["figures"].as_array().unwrap();
    assert_eq!(figures.len(), 3, "{measured}");
    assert_eq!(figures[2]["id"], "timeline", "{measured}");
    for figure in figures {
        assert!(
            figure["decoded"] == true
                && figure["width"].as_f64().unwrap() > 100.0
                && figure["height"].as_f64().unwrap() > 100.0,
            "a figure did not render: {figure}"
        );
    }
    let caption = figures[0]["caption"].as_str().unwrap();
    assert!(
        caption.starts_with("Error against h at m = 2 (runs of build "),
        "{caption}"
    );
    assert!(measured["rows"].as_u64().unwrap() > 4, "{measured}");
    let console: Vec<&str> = log.lines().filter(|l| l.contains("CONSOLE")).collect();
    assert!(console.is_empty(), "console messages: {console:?}");

    let bytes = screenshot(&scratch, &report, "1200,2400", &[]);
    assert!(
        bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000,
        "{} bytes",
        bytes.len()
    );

    // The tables alone, copied to a laptop without the runs and without the solver: the report
    // is made from the run table, and says so; its counts and provenance are the records'.
    let laptop = scratch.dir.join("laptop");
    let copied = laptop.join("report");
    std::fs::create_dir_all(copied.join("figures")).unwrap();
    let results = scratch.dir.join("results/report");
    for entry in std::fs::read_dir(&results).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let table = name.ends_with(".parquet") || name.ends_with(".sha256");
        if table || name == "study-file.json" {
            std::fs::copy(entry.path(), copied.join(&name)).unwrap();
        }
    }
    // The study file too, elsewhere: the owner file names the cluster's path, the text is the same.
    let study = laptop.join("study.json");
    std::fs::copy(scratch.study(), &study).unwrap();
    for entry in std::fs::read_dir(results.join("figures"))
        .unwrap()
        .flatten()
    {
        std::fs::copy(entry.path(), copied.join("figures").join(entry.file_name())).unwrap();
    }
    // Someone who can write to the results plants a figure with a script: the page shows it as
    // an image, which runs no script, and holds none of its markup.
    std::fs::write(
        copied.join("figures/convergence.svg"),
        r#"<svg xmlns="http://www.w3.org/2000/svg" onload="alert(1)"><script>alert(2)</script></svg>"#,
    )
    .unwrap();
    let offline = std::process::Command::new(nonlocal_study::binary("nlstudy"))
        .arg("report")
        .arg(&study)
        .arg("--results")
        .arg(&laptop)
        .args(["--solver", "/nonexistent/nlsolve"])
        .env_remove("NLSOLVE")
        .output()
        .unwrap();
    assert!(offline.status.success(), "{}", text(&offline));
    let page = std::fs::read_to_string(copied.join("report.html")).unwrap();
    let noisy = nonlocal_study::records(&results.join("runs"))
        .iter()
        .filter(|r| r["provenance"]["noisy"] == json!(true))
        .count();
    for expected in [
        "Built from the run table report.parquet alone",
        "4 stored runs:",
        "3 ok",
        "1 failed",
        &build.trim()[..8],
    ] {
        assert!(
            page.contains(expected),
            "the offline report lacks {expected:?}"
        );
    }
    let figure = std::fs::read_to_string(copied.join("figures/convergence.svg")).unwrap();
    assert!(
        figure.contains("alert(2)"),
        "the planted figure is the one shown"
    );
    for planted in ["<script", "onload", "alert("] {
        assert!(!page.contains(planted), "the page holds {planted:?}");
    }
    match noisy {
        0 => assert!(page.contains("no run is noisy"), "no run is noisy"),
        n => assert!(page.contains(&format!("{n} of ")), "{n} noisy runs: {page}"),
    }
}
