//! The import graph of the three crates has no cycle, between files or between folders, and the
//! solver's layers import only the layers below them (the order of `solver/src/lib.rs`).
//!
//! A module's imports are the paths its non-test code names: `crate::a::b`, `super::a`,
//! `super::*`, `crate::{a, b::c}` and `child::x` for a child module it declares, each resolved to
//! the longest module path that exists. A parent using its child and the child using its parent
//! is a cycle too.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The solver's top-level modules, lowest first.
const SOLVER_LAYERS: [&str; 10] = [
    "case",
    "threads",
    "linalg",
    "discretization",
    "problem",
    "operator",
    "output",
    "parallel",
    "integrate",
    "methods",
];

/// The orchestrator's top-level modules (its folders), lowest first.
const ORCHESTRATOR_LAYERS: [&str; 11] = [
    "allocator",
    "console",
    "statistics",
    "model",
    "store",
    "run",
    "analysis",
    "output",
    "kinds",
    "cli",
    "commands",
];

type Graph = BTreeMap<String, BTreeSet<String>>;

#[test]
fn the_solver_has_no_import_cycle_and_its_layers_only_look_down() {
    let graph = imports(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("solver/src")
            .as_path(),
    );
    assert_acyclic("solver", &graph);
    assert_acyclic("solver (folders)", &folders(&graph));
    assert_layers_look_down("solver", &SOLVER_LAYERS, &graph);
}

#[test]
fn the_orchestrator_has_no_import_cycle_and_its_layers_only_look_down() {
    let graph = imports(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("orchestrator/src")
            .as_path(),
    );
    assert!(graph.contains_key("run::plan") && graph.contains_key("output::figure::scaling"));
    assert_acyclic("orchestrator", &graph);
    assert_acyclic("orchestrator (folders)", &folders(&graph));
    assert_layers_look_down("orchestrator", &ORCHESTRATOR_LAYERS, &graph);
}

/// Every module of `graph` is in one of `layers` (by its top-level module) and imports only
/// modules of its own layer or the ones before it.
fn assert_layers_look_down(krate: &str, layers: &[&str], graph: &Graph) {
    let layer = |module: &str| {
        let top = module.split("::").next().unwrap_or_default();
        layers.iter().position(|l| *l == top).unwrap_or_else(|| {
            panic!("{krate} module `{top}` is in no layer; add it to the layers of tests/architecture.rs and to lib.rs")
        })
    };
    for (from, targets) in graph {
        for to in targets {
            assert!(
                layer(to) <= layer(from),
                "{krate}: `{from}` imports `{to}`, a higher layer"
            );
        }
    }
}

#[test]
fn the_layer_check_sees_an_arrow_up() {
    let graph = Graph::from([
        (
            "model::study".to_string(),
            BTreeSet::from(["store".to_string()]),
        ),
        ("store".to_string(), BTreeSet::new()),
    ]);
    let upward = std::panic::catch_unwind(|| {
        assert_layers_look_down("orchestrator", &ORCHESTRATOR_LAYERS, &graph)
    });
    assert!(upward.is_err(), "model importing store went unseen");
}

/// The schema both binaries read is plain serde data (and strsim, for "did you mean" in its
/// errors; libc, for opening files others may have put in place without following a link or
/// waiting on a FIFO; crc32fast, for the checkpoint's checksum both binaries check): it links no
/// numerics, tables or plots, so the orchestrator never compiles the solver to read a case, a
/// record or a checkpoint. clap comes only with the feature `cli` (nlsolve's flags), and
/// `workspace-hack` adds only crates the workspace builds anyway, for their features (see its
/// Cargo.toml).
#[test]
fn the_schema_is_serde_only_and_acyclic() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("schema");
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let lines: Vec<&str> = manifest
        .split("[dependencies]")
        .nth(1)
        .unwrap_or_default()
        .lines()
        .take_while(|line| !line.starts_with('['))
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .collect();
    fn name<'a>(line: &&'a str) -> &'a str {
        line.split(['.', ' ', '=']).next().unwrap_or_default()
    }
    let (optional, always): (Vec<&str>, Vec<&str>) = lines
        .iter()
        .partition(|line| line.contains("optional = true"));
    assert_eq!(
        always.iter().map(name).collect::<Vec<_>>(),
        [
            "serde",
            "workspace-hack",
            "serde_json",
            "serde_path_to_error",
            "strsim",
            "libc",
            "crc32fast"
        ]
    );
    assert_eq!(optional.iter().map(name).collect::<Vec<_>>(), ["clap"]);
    let graph = imports(root.join("src").as_path());
    assert!(graph.contains_key("case") && graph.contains_key("record"));
    assert_acyclic("schema", &graph);
}

#[test]
fn the_checker_sees_a_cycle_through_a_parent_and_its_child() {
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    std::fs::create_dir_all(dir.join("a")).unwrap();
    std::fs::write(dir.join("lib.rs"), "mod a;\nmod b;\n").unwrap();
    std::fs::write(dir.join("a/mod.rs"), "mod c;\nfn f() { c::g(); }\n").unwrap();
    std::fs::write(dir.join("a/c.rs"), "use super::*;\nuse crate::b::{x, y};\n").unwrap();
    std::fs::write(dir.join("b.rs"), "// crate::a is named in a comment only\n").unwrap();
    let graph = imports(dir);
    assert_eq!(graph["a"], BTreeSet::from(["a::c".to_string()]));
    assert_eq!(
        graph["a::c"],
        BTreeSet::from(["a".to_string(), "b".to_string()])
    );
    assert!(graph["b"].is_empty());
    assert!(!cycles(&graph).is_empty());
}

/// Module path ("" for lib.rs) → the modules it imports. Binaries are left out.
fn imports(root: &Path) -> Graph {
    let mut files = BTreeMap::new();
    collect_files(root, root, &mut files);
    let mut graph = Graph::new();
    for (module, path) in &files {
        let source = code_of(&std::fs::read_to_string(path).unwrap());
        let here: Vec<&str> = module.split("::").filter(|s| !s.is_empty()).collect();
        let is_folder = path.ends_with("mod.rs") || path.ends_with("lib.rs");
        let parent = &here[..here.len().saturating_sub(1)];
        let mut targets = BTreeSet::new();
        for (anchor, rest) in paths_in(&source) {
            let mut full: Vec<String> = match anchor.as_str() {
                "crate" => Vec::new(),
                "super" => parent.iter().map(|s| s.to_string()).collect(),
                _ => here.iter().map(|s| s.to_string()).collect(),
            };
            full.extend(rest);
            targets.insert(longest_module(&files, &full));
        }
        if is_folder {
            for child in declared_children(&source) {
                if mentions(&source, &format!("{child}::")) {
                    let mut full: Vec<String> = here.iter().map(|s| s.to_string()).collect();
                    full.push(child);
                    targets.insert(full.join("::"));
                }
            }
        }
        targets.remove(module);
        targets.remove("");
        if !module.is_empty() {
            graph.insert(module.clone(), targets);
        }
    }
    graph
}

fn collect_files(root: &Path, dir: &Path, files: &mut BTreeMap<String, std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n != "bin") {
                collect_files(root, &path, files);
            }
            continue;
        }
        let Some(relative) = path.strip_prefix(root).unwrap().to_str() else {
            continue;
        };
        let Some(stem) = relative.strip_suffix(".rs") else {
            continue;
        };
        if stem == "main" {
            continue;
        }
        // A `tests.rs` is test code: its parent's `#[cfg(test)] mod tests;`, as `code_of` leaves
        // out a `#[cfg(test)] mod tests { … }` written inline.
        if let Some(parent) = stem.strip_suffix("/tests") {
            let declared = [format!("{parent}.rs"), format!("{parent}/mod.rs")]
                .iter()
                .filter_map(|p| std::fs::read_to_string(root.join(p)).ok())
                .any(|code| code.contains("#[cfg(test)]\nmod tests;"));
            assert!(
                declared,
                "{relative} is not declared `#[cfg(test)] mod tests;`"
            );
            continue;
        }
        let mut parts: Vec<&str> = stem.split('/').collect();
        if matches!(parts.last(), Some(&"mod") | Some(&"lib")) {
            parts.pop();
        }
        files.insert(parts.join("::"), path);
    }
}

/// The source without comments and without its `#[cfg(test)]` module.
fn code_of(source: &str) -> String {
    let code = match source.find("#[cfg(test)]\nmod tests {") {
        Some(at) => &source[..at],
        None => source,
    };
    code.lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::…`, `super::…` and `self::…` path, braces expanded one level, as (anchor, the
/// segments after it). `super::*` is the parent itself.
fn paths_in(code: &str) -> Vec<(String, Vec<String>)> {
    let mut found = Vec::new();
    for anchor in ["crate", "super", "self"] {
        let needle = format!("{anchor}::");
        for (at, _) in code.match_indices(&needle) {
            let before = code[..at].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let rest = &code[at + needle.len()..];
            let head = segments(rest);
            let after = &rest[head_len(rest)..];
            if after.starts_with('{') {
                let inner = &after[1..after.find('}').unwrap_or(after.len())];
                for item in inner.split(',') {
                    let mut full = head.clone();
                    full.extend(segments(item.trim()));
                    found.push((anchor.to_string(), full));
                }
            } else {
                found.push((anchor.to_string(), head));
            }
        }
    }
    found
}

/// The identifiers of `a::b::c…` at the start of `text`.
fn segments(text: &str) -> Vec<String> {
    text[..head_len(text)]
        .split("::")
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty() && s != "self")
        .collect()
}

fn head_len(text: &str) -> usize {
    let mut end = 0;
    let bytes = text.as_bytes();
    while end < bytes.len() {
        let c = bytes[end] as char;
        if c.is_alphanumeric() || c == '_' {
            end += 1;
        } else if text[end..].starts_with("::") {
            end += 2;
        } else {
            break;
        }
    }
    end
}

fn longest_module(files: &BTreeMap<String, std::path::PathBuf>, full: &[String]) -> String {
    (0..=full.len())
        .rev()
        .map(|k| full[..k].join("::"))
        .find(|candidate| files.contains_key(candidate))
        .unwrap_or_default()
}

fn declared_children(code: &str) -> Vec<String> {
    code.lines()
        .filter_map(|line| {
            let line = line.trim();
            let rest = line
                .strip_prefix("pub mod ")
                .or_else(|| line.strip_prefix("pub(crate) mod "))
                .or_else(|| line.strip_prefix("mod "))?;
            Some(rest.strip_suffix(';')?.to_string())
        })
        .collect()
}

/// Does `code` name `prefix` other than as the tail of a longer path?
fn mentions(code: &str, prefix: &str) -> bool {
    code.match_indices(prefix).any(|(at, _)| {
        let before = code[..at].chars().next_back();
        !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
    })
}

/// The graph of top-level modules (folders and the files beside them).
fn folders(graph: &Graph) -> Graph {
    let top = |m: &str| m.split("::").next().unwrap_or_default().to_string();
    let mut folded = Graph::new();
    for (from, targets) in graph {
        let entry = folded.entry(top(from)).or_default();
        entry.extend(targets.iter().map(|t| top(t)).filter(|t| *t != top(from)));
    }
    folded
}

fn assert_acyclic(what: &str, graph: &Graph) {
    let found = cycles(graph);
    assert!(found.is_empty(), "{what}: import cycles {found:?}");
}

/// The strongly connected components with more than one module (Tarjan).
fn cycles(graph: &Graph) -> Vec<Vec<String>> {
    struct State<'a> {
        graph: &'a Graph,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        for w in s.graph.get(v).into_iter().flatten() {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if s.stack.contains(&w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let at = s.stack.iter().rposition(|x| *x == v).unwrap();
            let component: Vec<String> = s.stack.drain(at..).map(String::from).collect();
            if component.len() > 1 {
                s.found.push(component);
            }
        }
    }
    let mut state = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !state.index.contains_key(v.as_str()) {
            visit(&mut state, v);
        }
    }
    state.found
}

/// The README prints the exit statuses from the one table both binaries exit by.
#[test]
fn the_readme_prints_the_exit_status_table() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let printed = readme
        .split("<!-- exit statuses: begin -->\n")
        .nth(1)
        .and_then(|rest| rest.split("<!-- exit statuses: end -->").next())
        .expect("README.md holds the exit statuses between their markers");
    assert_eq!(
        printed,
        schema::exit::markdown(),
        "README.md's exit statuses differ from schema::exit: paste schema::exit::markdown()"
    );
}

/// Every path and file name the docs name in backticks or link to exists: from the repository's
/// root, the doc's own folder or a crate's `src` (`run/worker.rs`), or, for a bare file name, in
/// the tree. A `file.rs::item` names its file. Left out: outputs (`results/…`, `target/…`, a file
/// name starting with a dot), placeholders (`<…>`, `*`, `{…}`, an upper-case stem) and the guide's
/// own example files.
#[test]
fn every_path_the_docs_name_exists() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut docs = vec![root.join("README.md")];
    let mut names = BTreeSet::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.is_dir() {
                if !["target", "results", ".git"].contains(&name.as_str()) {
                    stack.push(path);
                }
            } else {
                if path.starts_with(root.join("docs")) && name.ends_with(".md") {
                    docs.push(path.clone());
                }
                names.insert(name);
            }
        }
    }
    let missing: Vec<String> = docs
        .iter()
        .flat_map(|doc| {
            let text = std::fs::read_to_string(doc).unwrap();
            named_paths(&text)
                .into_iter()
                .filter(|path| !exists(root, doc.parent().unwrap(), &names, path))
                .map(|path| format!("{}: {path}", doc.strip_prefix(root).unwrap().display()))
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(
        missing.is_empty(),
        "the docs name paths that do not exist: {missing:#?}"
    );
}

/// The paths a doc names: backticked spans and link targets that look like a file of the
/// repository (under one of its folders, or with a source or doc extension).
fn named_paths(text: &str) -> Vec<String> {
    const FOLDERS: [&str; 11] = [
        "orchestrator/",
        "solver/",
        "schema/",
        "scripts/",
        "studies/",
        "docs/",
        "tests/",
        "cases/",
        "sites/",
        "workspace-hack/",
        ".ci/",
    ];
    const EXTENSIONS: [&str; 6] = [".rs", ".md", ".toml", ".sh", ".py", ".json"];
    let spans = text
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| !s.contains('\n'));
    let links = text.split("](").skip(1).filter_map(|s| s.split(')').next());
    spans
        .chain(links)
        .filter_map(|span| {
            let path = span.split('#').next()?.trim().split("::").next()?;
            let plain = !path.is_empty()
                && path
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_.-/".contains(c));
            let file = path.rsplit('/').next()?;
            let stem = file.split('.').next()?;
            let placeholder = stem.chars().any(|c| c.is_ascii_uppercase())
                && stem.chars().all(|c| c.is_ascii_uppercase() || c == '_');
            let output = file.starts_with('.')
                || path.starts_with("results/")
                || path.starts_with("target/")
                || ["hello.json", "notes.json"].contains(&path);
            let looks = FOLDERS.iter().any(|f| path.starts_with(f))
                || EXTENSIONS.iter().any(|e| path.ends_with(e));
            (plain && looks && !placeholder && !output).then(|| path.to_string())
        })
        .collect()
}

fn exists(root: &Path, doc_dir: &Path, names: &BTreeSet<String>, path: &str) -> bool {
    let bases = [
        root.to_path_buf(),
        doc_dir.to_path_buf(),
        root.join("solver/src"),
        root.join("orchestrator/src"),
        root.join("schema/src"),
        root.join("solver/src/bin"),
    ];
    bases.iter().any(|base| base.join(path).exists())
        || (!path.contains('/') && names.contains(path))
}

#[test]
fn the_path_check_sees_a_missing_file_and_passes_placeholders() {
    let text = "see `run/worker.rs`, `run/gone.rs::f`, [x](../nowhere.md#a), `NAME.toml`, `results/q/x.json`, `--flag`";
    assert_eq!(
        named_paths(text),
        ["run/worker.rs", "run/gone.rs", "../nowhere.md"]
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let names = BTreeSet::new();
    assert!(exists(root, &root.join("docs"), &names, "run/worker.rs"));
    assert!(!exists(root, &root.join("docs"), &names, "run/gone.rs"));
}

/// Only the reporters print: `console` (`Reporter`, which prints what is said through `log`, and
/// `print`, which prints the `Reply` each command returns), `lib.rs`'s never-panicking `errln!`
/// and `run/progress.rs` (the bar and its lines). Everything else, the commands included,
/// returns what it has to say or tells `log`. Test modules (`#[cfg(test)] mod …;`) may print.
#[test]
fn only_the_reporters_print() {
    const REPORTERS: [&str; 4] = ["console.rs", "lib.rs", "main.rs", "run/progress.rs"];
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("orchestrator/src");
    let mut files = BTreeMap::new();
    collect_files(&src, &src, &mut files);
    let sources: BTreeMap<String, String> = (files.values())
        .map(|path| {
            let relative = path.strip_prefix(&src).unwrap().to_string_lossy();
            (
                relative.into_owned(),
                std::fs::read_to_string(path).unwrap(),
            )
        })
        .collect();
    let printing: BTreeSet<&String> = sources
        .iter()
        .filter(|(relative, source)| {
            let code = code_of(source);
            let prints = [
                "println!", "print!(", "eprint", "errln!", "outln!", "stdout()", "stderr()",
            ]
            .iter()
            .any(|p| code.contains(p));
            prints
                && !REPORTERS.contains(&relative.as_str())
                && !declared_for_tests(relative, &sources)
        })
        .map(|(relative, _)| relative)
        .collect();
    assert!(
        printing.is_empty(),
        "these modules print; return what they say (a command's `console::Reply`), or tell log: {printing:?}"
    );
}

/// Whether the module of file `relative` is test code: its parent declares it
/// `#[cfg(test)] mod NAME;`.
fn declared_for_tests(relative: &str, sources: &BTreeMap<String, String>) -> bool {
    let path = Path::new(relative);
    let name = path.file_stem().unwrap().to_string_lossy();
    let dir = path.parent().unwrap_or(Path::new(""));
    let parents = [
        dir.join("mod.rs"),
        dir.with_extension("rs"),
        "lib.rs".into(),
    ];
    parents
        .iter()
        .filter_map(|parent| sources.get(parent.to_str()?))
        .any(|source| source.contains(&format!("#[cfg(test)]\nmod {name};")))
}

/// The most lines a function of the crates' own code takes without saying why.
const LONGEST_FUNCTION: usize = 100;

/// No function of `schema`, `solver` or `orchestrator` (test code aside) is over
/// `LONGEST_FUNCTION` lines unless the comment above it says why (`Long because …`): a long
/// function is split, or its reason is read where it is.
#[test]
fn no_function_is_over_a_hundred_lines_without_saying_why() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut unexplained = Vec::new();
    for krate in ["schema/src", "solver/src", "orchestrator/src"] {
        let src = root.join(krate);
        let mut files = BTreeMap::new();
        collect_files(&src, &src, &mut files);
        for path in files.values() {
            let source = std::fs::read_to_string(path).unwrap();
            let code = match source.find("#[cfg(test)]\nmod tests {") {
                Some(at) => &source[..at],
                None => &source[..],
            };
            for (name, lines, why) in long_functions(code) {
                if !why {
                    let file = path.strip_prefix(root).unwrap().display();
                    unexplained.push(format!("{file}: {name} ({lines} lines)"));
                }
            }
        }
    }
    assert!(
        unexplained.is_empty(),
        "functions over {LONGEST_FUNCTION} lines with no `Long because` in the comment above them; split them or say why: {unexplained:#?}"
    );
}

/// The functions of `code` over `LONGEST_FUNCTION` lines (from `fn` to the brace that closes
/// it at the same indent), with whether the comment above says why.
fn long_functions(code: &str) -> Vec<(String, usize, bool)> {
    let lines: Vec<&str> = code.lines().collect();
    let mut long = Vec::new();
    for (at, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let signature = [
            "pub fn ",
            "pub(crate) fn ",
            "pub(super) fn ",
            "fn ",
            "const fn ",
        ];
        let Some(rest) = signature.iter().find_map(|s| trimmed.strip_prefix(s)) else {
            continue;
        };
        let name: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let close = format!("{indent}}}");
        let Some(end) = lines[at..].iter().position(|l| *l == close) else {
            continue;
        };
        // A declaration without a body (a trait's) ends at its `;` before any brace.
        let body = lines[at..].iter().position(|l| l.trim_end().ends_with('{'));
        let declared = lines[at..].iter().position(|l| l.trim_end().ends_with(';'));
        if declared.is_some_and(|d| body.is_none_or(|b| d < b)) {
            continue;
        }
        if end + 1 > LONGEST_FUNCTION {
            let comment = lines[..at]
                .iter()
                .rev()
                .take_while(|l| {
                    let l = l.trim_start();
                    l.starts_with("//") || l.starts_with("#[")
                })
                .any(|l| l.contains("Long because"));
            long.push((name, end + 1, comment));
        }
    }
    long
}

#[test]
fn the_length_check_sees_a_long_function_and_its_reason() {
    let body = "    x += 1;\n".repeat(LONGEST_FUNCTION);
    let code = format!("/// Adds.\nfn long(x: &mut u32) {{\n{body}}}\n\nfn short() {{}}\n");
    assert_eq!(
        long_functions(&code),
        [("long".to_string(), LONGEST_FUNCTION + 2, false)]
    );
    let explained = code.replace("/// Adds.", "/// Adds. Long because it is a test.");
    assert!(long_functions(&explained)[0].2);
}
