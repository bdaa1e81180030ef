//! Every figure of every shipped study, drawn and rendered as a reader sees it. A stand-in solver
//! (`tests/scripts/synthetic-nlsolve`) answers each case at once with a record of the shape the
//! solver writes for its method, so that `nlstudy run` plans (with the real `nlsolve check`),
//! stores, collects and draws each study's figures in seconds. Every figure must be drawn (a
//! chart with an empty subtitle part, an unnamed axis, a glyph the legend does not explain or an
//! entry nothing draws is refused by `draw::lint`, and its figure is then not drawn); each SVG
//! must parse with no empty or dangling text; and headless Chromium renders each to PNG, which
//! must hold ink.

use nonlocal_study::{binary, chromium, measured, python_stub, screenshot, text, Scratch};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

fn studies() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("studies");
    let mut studies: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "json" || x == "jsonc"))
        .collect();
    studies.sort();
    studies
}

/// The texts of an SVG, which must parse as XML.
fn texts(svg: &str, path: &Path) -> Vec<String> {
    let document = roxmltree::Document::parse(svg)
        .unwrap_or_else(|e| panic!("{} is not well-formed: {e}", path.display()));
    document
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .map(|n| n.text().unwrap_or("").trim().to_string())
        .collect()
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn every_shipped_study_draws_every_figure_and_chromium_renders_each() {
    let scratch = Scratch::new("figures", &json!({}));
    let stub = python_stub(&scratch.dir, "synthetic-nlsolve");
    let fingerprint = text(
        &Command::new(binary("nlsolve"))
            .arg("fingerprint")
            .output()
            .unwrap(),
    );
    let results = scratch.dir.join("results");
    let mut figures: Vec<PathBuf> = Vec::new();
    for study in studies() {
        let out = Command::new(binary("nlstudy"))
            .arg("run")
            .arg(&study)
            .arg("--results")
            .arg(&results)
            .arg("--solver")
            .arg(&stub)
            .args(["--launcher", "env RANKS={ranks}", "-j", "2", "--quiet"])
            .env("NLSOLVE_REAL", binary("nlsolve"))
            .env("NLSOLVE_FINGERPRINT", fingerprint.trim())
            .output()
            .unwrap();
        let said = text(&out);
        assert!(out.status.success(), "{}: {said}", study.display());
        assert!(!said.contains("not drawn"), "{}: {said}", study.display());
        let name: Value = serde_json::from_str(&{
            let plain = std::fs::read_to_string(&study).unwrap();
            let start = plain.find("\"name\"").unwrap();
            let value = plain[start..]
                .split(':')
                .nth(1)
                .unwrap()
                .split(',')
                .next()
                .unwrap();
            value.trim().to_string()
        })
        .unwrap();
        let drawn = results.join(name.as_str().unwrap()).join("figures");
        for entry in std::fs::read_dir(&drawn).into_iter().flatten().flatten() {
            if entry.path().extension().is_some_and(|x| x == "svg") {
                figures.push(entry.path());
            }
        }
    }
    assert!(figures.len() >= 35, "{} figures", figures.len());
    for path in &figures {
        let svg = std::fs::read_to_string(path).unwrap();
        for text in texts(&svg, path) {
            assert!(
                !text.is_empty() && text != "=" && !text.starts_with("= ") && !text.ends_with(" ="),
                "{}: an empty text or an `=` without its field or value: {text:?}",
                path.display()
            );
        }
    }
    // One page holding every figure as an image; each is drawn onto a canvas, and its ink (the
    // pixels that are not white) counted.
    let images: Vec<String> = figures
        .iter()
        .map(|p| format!("<img src=\"file://{}\">", p.display()))
        .collect();
    let page = scratch.dir.join("figures.html");
    std::fs::write(
        &page,
        format!(
            r#"<!DOCTYPE html><html><body>{}
<pre id="measured">not loaded</pre>
<script>
window.addEventListener('load', () => {{
  const measured = [...document.images].map(image => {{
    const canvas = document.createElement('canvas');
    canvas.width = image.naturalWidth; canvas.height = image.naturalHeight;
    const context = canvas.getContext('2d');
    context.drawImage(image, 0, 0);
    let ink = 0;
    if (canvas.width > 0) {{
      const pixels = context.getImageData(0, 0, canvas.width, canvas.height).data;
      for (let k = 0; k < pixels.length; k += 4) {{
        if (pixels[k] < 200 || pixels[k + 1] < 200 || pixels[k + 2] < 200) ink++;
      }}
    }}
    return {{src: image.src, width: image.naturalWidth, height: image.naturalHeight, ink: ink}};
  }});
  document.getElementById('measured').textContent = JSON.stringify(measured);
}});
</script></body></html>"#,
            images.join("\n")
        ),
    )
    .unwrap();
    let loaded = chromium(
        &scratch,
        &page,
        &[
            "--allow-file-access-from-files",
            "--virtual-time-budget=20000",
            "--dump-dom",
        ],
    );
    assert!(
        loaded.status.success(),
        "{}",
        String::from_utf8_lossy(&loaded.stderr)
    );
    let measured = measured(&String::from_utf8_lossy(&loaded.stdout));
    let measured = measured.as_array().expect("one measure per figure");
    assert_eq!(measured.len(), figures.len());
    for figure in measured {
        let (width, height, ink) = (
            figure["width"].as_f64().unwrap(),
            figure["height"].as_f64().unwrap(),
            figure["ink"].as_f64().unwrap(),
        );
        assert!(width >= 480.0 && height >= 300.0, "not rendered: {figure}");
        assert!(ink > 0.01 * width * height, "a blank figure: {figure}");
    }
    // And as a picture, for whoever looks: every figure on one page, rendered to PNG.
    let png = screenshot(
        &scratch,
        &page,
        "1200,4000",
        &["--allow-file-access-from-files"],
    );
    assert!(png.len() > 10_000);
}
