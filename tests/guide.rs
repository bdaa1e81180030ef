//! Every example of the README and the user guide runs here, so that what a newcomer copies
//! works and what the pages show is what the tools print.
//!
//! Each page runs in a scratch directory of its own, its fenced blocks in order, with
//! `target/release` first on `PATH` and the repository's `studies/`, `cases/`, `sites/` and
//! `scripts/` beside it (as a reader in a clone has them). What a block's info string says:
//!
//! - `console`: `$ command` lines run in bash; the lines after one are its output (stdout and
//!   stderr, as a terminal interleaves them), matched line by line, where a line `...` stands
//!   for any number of lines, `[..]` for any text within a line, and a last line `(exit N)`
//!   for the exit status (else it must be 0);
//! - `sh`: the block runs as one bash script, each line of which must succeed;
//! - `sh no-run`: each line is `make TARGET`, and the Makefile has that target (`make test` is
//!   this suite; `make run` is the README's main job);
//! - `file=NAME`: the block is written to NAME, for the commands after it;
//! - `same-as=PATH`: the block is the repository's file PATH, byte for byte;
//! - `fragment=PATH`: the block is keys of a study file (`"refine": {…}`): set into the shipped
//!   study PATH, `nlstudy plan` accepts the study;
//! - anything else (`text`, an output shown without its command) is prose.
//!
//! Pages with `python` blocks (pyarrow) or `sh system` blocks (a local Slurm) are system tests,
//! which install what they need first.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The README and the guide's pages.
fn pages() -> Vec<PathBuf> {
    let mut pages = vec![root().join("README.md")];
    let mut chapters: Vec<PathBuf> = std::fs::read_dir(root().join("docs/guide"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "md"))
        .collect();
    chapters.sort();
    pages.extend(chapters);
    pages
}

/// A fenced block: its info string's words and its lines.
struct Block {
    info: Vec<String>,
    lines: Vec<String>,
    /// The page's line of its opening fence, for messages.
    at: usize,
}

impl Block {
    fn attribute(&self, key: &str) -> Option<&str> {
        self.info
            .iter()
            .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
    }

    fn text(&self) -> String {
        self.lines.iter().map(|line| format!("{line}\n")).collect()
    }
}

fn blocks(page: &str) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut open: Option<Block> = None;
    for (number, line) in page.lines().enumerate() {
        match (open.take(), line.strip_prefix("```")) {
            (None, Some(info)) => {
                open = Some(Block {
                    info: info.split_whitespace().map(str::to_string).collect(),
                    lines: Vec::new(),
                    at: number + 1,
                })
            }
            (Some(block), Some("")) => blocks.push(block),
            (Some(mut block), _) => {
                block.lines.push(line.to_string());
                open = Some(block);
            }
            (None, None) => {}
        }
    }
    if let Some(block) = open {
        panic!("the fenced block of line {} is not closed", block.at);
    }
    blocks
}

/// Whether `shown` (the page's lines, with `...` for any lines) is what `said` printed.
fn matches(shown: &[String], said: &[&str]) -> bool {
    match shown.split_first() {
        None => said.is_empty(),
        Some((first, rest)) if first == "..." => {
            (0..=said.len()).any(|skip| matches(rest, &said[skip..]))
        }
        Some((first, rest)) => said
            .split_first()
            .is_some_and(|(line, after)| line_matches(first, line) && matches(rest, after)),
    }
}

/// Whether a shown line is the said one, where `[..]` stands for any text within it.
fn line_matches(shown: &str, said: &str) -> bool {
    let said = said.trim_end();
    let mut parts = shown.split("[..]");
    let first = parts.next().unwrap_or_default();
    let Some(mut rest) = said.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for part in middle {
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

/// A page's scratch directory, where its commands run as in a clone.
struct Reader {
    dir: tempfile::TempDir,
    path: String,
}

impl Reader {
    fn new() -> Reader {
        let dir = tempfile::Builder::new()
            .prefix("nlstudy-guide-")
            .tempdir()
            .unwrap();
        for shared in ["studies", "cases", "sites", "scripts"] {
            std::os::unix::fs::symlink(root().join(shared), dir.path().join(shared)).unwrap();
        }
        let binaries = nonlocal_study::binary("nlstudy");
        let binaries = binaries.parent().unwrap();
        std::fs::create_dir(dir.path().join("target")).unwrap();
        std::os::unix::fs::symlink(binaries, dir.path().join("target/release")).unwrap();
        let path = format!(
            "{}:{}",
            binaries.display(),
            std::env::var("PATH").unwrap_or_default()
        );
        Reader { dir, path }
    }

    /// `run_once`, and once more if `command` met Open MPI's fault at a job's teardown
    /// (`open_mpi_teardown_fault`), which is the runtime's, not the page's.
    fn run(&self, command: &str) -> (i32, String) {
        let (status, said) = self.run_once(command);
        if status == 0 || !nonlocal_study::open_mpi_teardown_fault(&said) {
            return (status, said);
        }
        eprintln!("`{command}` met Open MPI's teardown fault; run once more:\n{said}");
        self.run_once(command)
    }

    /// Runs `command` in bash, stdout and stderr as one stream; its status and what it said.
    fn run_once(&self, command: &str) -> (i32, String) {
        let out = Command::new("bash")
            .arg("-c")
            .arg(format!("exec 2>&1\n{command}"))
            .current_dir(self.dir.path())
            .env("PATH", &self.path)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&out.stdout).into_owned();
        (out.status.code().unwrap_or(-1), said)
    }
}

/// The commands of a `console` block, each with the lines shown after it.
fn console(block: &Block) -> Vec<(String, Vec<String>)> {
    let mut commands: Vec<(String, Vec<String>)> = Vec::new();
    for line in &block.lines {
        match (line.strip_prefix("$ "), commands.last_mut()) {
            (Some(command), _) => commands.push((command.to_string(), Vec::new())),
            (None, Some((_, shown))) => shown.push(line.clone()),
            (None, None) => panic!("line {}: output before a `$ ` command", block.at),
        }
    }
    commands
}

/// Runs every example of `page`; the failures, each a paragraph.
fn run_page(page: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(page).unwrap();
    let name = page.strip_prefix(root()).unwrap().display().to_string();
    let reader = Reader::new();
    let mut failures = Vec::new();
    for block in blocks(&text) {
        let at = format!("{name}:{}", block.at);
        if let Some(file) = block.attribute("same-as") {
            let shipped = std::fs::read_to_string(root().join(file)).unwrap();
            if block.text() != shipped {
                failures.push(format!("{at}: the block is not {file} as it is"));
            }
        }
        if let Some(file) = block.attribute("file") {
            std::fs::write(reader.dir.path().join(file), block.text()).unwrap();
        }
        if let Some(file) = block.attribute("fragment") {
            let keys: serde_json::Map<String, serde_json::Value> =
                serde_json::from_str(&format!("{{{}}}", block.text()))
                    .unwrap_or_else(|e| panic!("{at}: not keys of a study file: {e}"));
            let shipped = std::fs::read_to_string(root().join(file)).unwrap();
            let mut study: serde_json::Value = serde_json::from_str(&shipped).unwrap();
            study.as_object_mut().unwrap().extend(keys);
            let path = reader.dir.path().join("fragment.json");
            std::fs::write(&path, study.to_string()).unwrap();
            let (status, said) = reader.run("nlstudy plan fragment.json >/dev/null");
            if status != 0 {
                failures.push(format!("{at}: {file} with these keys is refused:\n{said}"));
            }
        }
        let kind = block.info.first().map(String::as_str).unwrap_or_default();
        let no_run = block.info.iter().any(|word| word == "no-run");
        match kind {
            "sh" if no_run => {
                for line in block.lines.iter().filter(|l| !l.trim().is_empty()) {
                    let command = line.split(" #").next().unwrap().trim();
                    let target = command.strip_prefix("make ").unwrap_or_else(|| {
                        panic!("{at}: a no-run block holds only `make TARGET` lines")
                    });
                    let dry = Command::new("make")
                        .args(["-n", target])
                        .current_dir(root())
                        .output()
                        .unwrap();
                    if !dry.status.success() {
                        failures.push(format!("{at}: the Makefile has no target `{target}`"));
                    }
                }
            }
            "sh" => {
                // One shell for the block, as a reader pastes it: an `export` holds for the
                // lines after it, and the first line that fails stops the block.
                let (status, said) = reader.run(&format!("set -e\n{}", block.text()));
                if status != 0 {
                    failures.push(format!("{at}: the block exited {status}:\n{said}"));
                }
            }
            "console" => {
                for (command, mut shown) in console(&block) {
                    let expected = match shown.last().and_then(|l| l.strip_prefix("(exit ")) {
                        Some(code) => {
                            let code = code.trim_end_matches(')').parse().unwrap();
                            shown.pop();
                            code
                        }
                        None => 0,
                    };
                    let (status, said) = reader.run(&command);
                    let lines: Vec<&str> = said.lines().collect();
                    if status != expected || !matches(&shown, &lines) {
                        failures.push(format!(
                            "{at}: `{command}` exited {status} (the page says {expected}) and \
                             printed:\n{said}\nThe page shows:\n{}",
                            shown.join("\n")
                        ));
                    }
                }
            }
            _ => {}
        }
    }
    failures
}

/// Whether a page needs the system's components: pyarrow, or a local Slurm.
fn is_system(page: &Path) -> bool {
    blocks(&std::fs::read_to_string(page).unwrap())
        .iter()
        .any(|block| {
            block
                .info
                .iter()
                .any(|word| word == "python" || word == "system")
        })
}

fn run_pages(system: bool) {
    let mut ran = 0;
    let failures: Vec<String> = (pages().into_iter())
        .filter(|page| is_system(page) == system)
        .inspect(|_| ran += 1)
        .flat_map(|page| run_page(&page))
        .collect();
    assert!(ran > 0, "no page to run");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_example_of_the_readme_and_the_guide_runs_and_prints_what_it_shows() {
    run_pages(false);
}

#[test]
#[ignore = "system tests: off (make test runs them, as does cargo test -- --include-ignored)"]
fn every_example_with_pyarrow_or_slurm_runs() {
    let setup = Command::new(root().join("scripts/setup.sh"))
        .args(["--tests", "--slurm"])
        .output()
        .unwrap();
    assert!(
        setup.status.success(),
        "the set-up could not install pyarrow or Slurm: {}",
        String::from_utf8_lossy(&setup.stderr)
    );
    run_pages(true);
}

#[test]
fn the_output_matching_takes_dots_for_any_lines() {
    let shown = |lines: &[&str]| lines.iter().map(|l| l.to_string()).collect::<Vec<_>>();
    assert!(matches(&shown(&["a", "...", "d"]), &["a", "b", "c", "d"]));
    assert!(matches(&shown(&["...", "d"]), &["d"]));
    assert!(!matches(&shown(&["a", "d"]), &["a", "b", "d"]));
    assert!(!matches(&shown(&["a", "...", "e"]), &["a", "b", "d"]));
    assert!(!matches(&shown(&["a  "]), &["a"]));
    assert!(matches(&shown(&["a"]), &["a  "]));
    assert!(line_matches(
        "at [..]/mine.json; [..] owner",
        "at /tmp/x/mine.json; the owner"
    ));
    assert!(line_matches("[..]", ""));
    assert!(!line_matches("at [..]/mine.json", "at /tmp/x/theirs.json"));
    assert!(!line_matches("ab[..]ba", "aba"));
}

/// The study language's reference names every key the study reader knows: those it lists when
/// it refuses an unknown one, at each level of a study file.
#[test]
fn the_reference_names_every_key_of_a_study_file() {
    let reference = std::fs::read_to_string(root().join("docs/guide/study-language.md")).unwrap();
    let reader = Reader::new();
    let unknown = r#""zzzz": 1"#;
    let places = [
        unknown.to_string(),
        format!(r#""resources": {{{unknown}}}"#),
        format!(r#""figures": [{{"name": "a", "kind": "convergence", {unknown}}}]"#),
        format!(r#""boundary": {{{unknown}}}"#),
        format!(r#""refine": {{{unknown}}}"#),
        format!(r#""target": {{{unknown}}}"#),
        format!(r#""budget": {{{unknown}}}"#),
        format!(r#""sweep": [{{"branches": {{"a": {{{unknown}}}}}}}]"#),
        format!(r#""sweep": [{{{unknown}}}]"#),
    ];
    let mut keys = Vec::new();
    for place in places {
        let study = format!(r#"{{"name": "keys", "base": {{}}, {place}}}"#);
        std::fs::write(reader.dir.path().join("keys.json"), study).unwrap();
        let (status, said) = reader.run("nlstudy plan keys.json");
        assert_eq!(status, 2, "{said}");
        let listed = said
            .split_once("expected ")
            .unwrap_or_else(|| panic!("no list of keys in: {said}"))
            .1;
        let named: Vec<String> = (listed.split('`').skip(1).step_by(2))
            .map(str::to_string)
            .collect();
        assert!(named.len() >= 2, "{said}");
        keys.extend(named);
    }
    let missing: Vec<String> = (keys.into_iter())
        .filter(|key| !reference.contains(&format!("`{key}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/guide/study-language.md does not name {missing:?}"
    );
}

/// Every link of the README and the guide to a file of the repository finds it.
#[test]
fn every_link_between_the_pages_finds_its_file() {
    let mut broken = Vec::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for (at, _) in text.match_indices("](") {
            let target = &text[at + 2..];
            let target = &target[..target.find(')').unwrap_or(0)];
            let file = target.split('#').next().unwrap_or_default();
            if file.is_empty() || file.contains("://") {
                continue;
            }
            if !page.parent().unwrap().join(file).exists() {
                broken.push(format!("{}: {target}", page.display()));
            }
        }
    }
    assert!(broken.is_empty(), "links to no file: {broken:#?}");
}

/// The numbers the pages show between `<!--m:KEY-->` and `<!--/m-->` are the ones
/// docs/guide/measured.json holds (written by `scripts/measure-guide`, with the command that
/// measured each and the day): a number changed by hand, or a measurement no page shows, fails.
#[test]
fn every_measured_number_is_the_one_its_measurement_wrote() {
    let file = root().join("docs/guide/measured.json");
    let measured: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let numbers = measured["numbers"]
        .as_object()
        .expect("measured.json has `numbers`");
    let mut wrong = Vec::new();
    let mut shown = std::collections::BTreeSet::new();
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let name = page.file_name().unwrap().to_string_lossy().into_owned();
        for (at, _) in text.match_indices("<!--m:") {
            let rest = &text[at + "<!--m:".len()..];
            let Some((key, rest)) = rest.split_once("-->") else {
                wrong.push(format!("{name}: a marker is not closed"));
                continue;
            };
            // (A key is lower-case letters, digits, `_` and `.`: `<!--m:KEY-->` is prose.)
            let is_key = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || "_.".contains(c);
            if !key.chars().all(is_key) {
                continue;
            }
            let Some((shows, _)) = rest.split_once("<!--/m-->") else {
                wrong.push(format!("{name}: `{key}` has no <!--/m-->"));
                continue;
            };
            shown.insert(key.to_string());
            match numbers.get(key).and_then(|n| n["text"].as_str()) {
                Some(text) if text == shows => {}
                Some(text) => wrong.push(format!(
                    "{name}: `{key}` shows {shows:?}, measured {text:?}"
                )),
                None => wrong.push(format!("{name}: `{key}` is not in measured.json")),
            }
        }
    }
    for (key, number) in numbers {
        if !shown.contains(key) {
            wrong.push(format!("measured.json: `{key}` is shown by no page"));
        }
        for field in ["text", "command", "measured"] {
            if number[field].as_str().is_none_or(str::is_empty) {
                wrong.push(format!("measured.json: `{key}` has no `{field}`"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "{wrong:#?}\n(scripts/measure-guide measures the numbers and writes the pages)"
    );
    assert!(
        shown.len() >= 30,
        "only {} measured numbers shown",
        shown.len()
    );
}

/// The code spans of a page's prose (its fenced blocks left out), each as one line: a span may
/// run over a line break, and one of N backticks ends at the next run of exactly N.
fn code_spans(page: &str) -> Vec<String> {
    let mut prose = String::new();
    let mut fenced = false;
    for line in page.lines() {
        if line.starts_with("```") {
            fenced = !fenced;
            prose.push('\n');
        } else if !fenced {
            prose.push_str(line);
            prose.push('\n');
        }
    }
    // The runs of backticks, as (byte offset, length).
    let bytes = prose.as_bytes();
    let mut runs = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let length = bytes[at..].iter().take_while(|&&b| b == b'`').count();
        if length > 0 {
            runs.push((at, length));
        }
        at += length.max(1);
    }
    let mut spans = Vec::new();
    let mut runs = runs.into_iter();
    while let Some((open, length)) = runs.next() {
        if let Some((close, _)) = runs.find(|&(_, other)| other == length) {
            let body = &prose[open + length..close];
            spans.push(body.split_whitespace().collect::<Vec<_>>().join(" "));
        }
    }
    spans
}

/// Each subcommand of a tool (the tool itself as ""), with the flags its `--help` names.
type Help = std::collections::BTreeMap<String, std::collections::BTreeSet<String>>;

/// The subcommands and flags of `tool`, from its `--help` and each subcommand's.
fn flags_of(tool: &str) -> Help {
    let help = |args: &[&str]| {
        let out = Command::new(nonlocal_study::binary(tool))
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success(), "{tool} {args:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    let flags = |text: &str| -> std::collections::BTreeSet<String> {
        text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
            .filter(|word| word.starts_with('-') && word.len() > 1 && word != &"--")
            .map(str::to_string)
            .collect()
    };
    let top = help(&["--help"]);
    let commands: Vec<String> = top
        .split("Commands:")
        .nth(1)
        .unwrap_or_default()
        .split("Options:")
        .next()
        .unwrap()
        .lines()
        .filter_map(|line| line.strip_prefix("  ").filter(|l| !l.starts_with(' ')))
        .filter_map(|line| line.split_whitespace().next())
        .filter(|word| word.chars().all(|c| c.is_ascii_lowercase()) && *word != "help")
        .map(str::to_string)
        .collect();
    let mut all = std::collections::BTreeMap::from([(String::new(), flags(&top))]);
    for command in commands {
        let text = help(&[&command, "--help"]);
        all.insert(command, flags(&text));
    }
    all
}

/// The flags of other tools that the pages name (Slurm's, cargo's, the test harness's and
/// cargo-nextest's), which no `--help` of ours lists.
const OTHER_TOOLS_FLAGS: &[&str] = &[
    "--signal",              // sbatch
    "--open-mode",           // sbatch
    "--mem",                 // sbatch
    "--cpus-per-task",       // sbatch
    "--requeue",             // sbatch
    "--mpi",                 // srun
    "--no-default-features", // cargo
    "--nocapture",           // the test harness
    "--include-ignored",     // the test harness
    "--run-ignored",         // cargo-nextest
];

/// What is wrong in the code spans of `page` (named `name`) that name a command or a flag of
/// `tools`, and how many such spans it has.
fn wrong_commands_and_flags(
    name: &str,
    page: &str,
    tools: &[(&str, Help)],
) -> (Vec<String>, usize) {
    let any_tool = |flag: &str| {
        let prefix = flag.strip_suffix('*');
        tools.iter().any(|(_, commands)| {
            commands.values().flatten().any(|known| match prefix {
                Some(prefix) => known.starts_with(prefix),
                None => known == flag,
            })
        })
    };
    let flags_in = |words: &[&str]| -> Vec<String> {
        words
            .iter()
            .flat_map(|word| word.split('|'))
            .map(|word| word.trim_matches(|c| c == '[' || c == ']' || c == '…'))
            .filter(|word| word.starts_with("--") && word.len() > 2)
            .map(|word| word.split('=').next().unwrap().to_string())
            .collect()
    };
    let (mut wrong, mut checked) = (Vec::new(), 0);
    for span in code_spans(page) {
        let words: Vec<&str> = span.split(' ').collect();
        if let Some((_, commands)) = tools.iter().find(|(tool, _)| *tool == words[0]) {
            let command = words.get(1).filter(|word| commands.contains_key(**word));
            if let Some(word) = words.get(1) {
                let placeholder = word.starts_with('-') || word.starts_with('<');
                if command.is_none() && !placeholder {
                    wrong.push(format!("{name}: `{span}`: no command `{word}`"));
                    continue;
                }
            }
            let known = &commands[command.copied().unwrap_or("")];
            for flag in flags_in(&words) {
                if !known.contains(&flag) {
                    wrong.push(format!("{name}: `{span}`: no flag {flag}"));
                }
            }
            checked += 1;
        } else if words[0].starts_with("--") {
            for flag in flags_in(&words) {
                if !any_tool(&flag) && !OTHER_TOOLS_FLAGS.contains(&flag.as_str()) {
                    wrong.push(format!("{name}: `{span}`: no tool of ours has {flag}"));
                }
            }
            checked += 1;
        }
    }
    (wrong, checked)
}

/// Every `nlstudy …` and `nlsolve …` command a page names in its prose is a command the tool
/// has, with flags its `--help` lists, and every flag named alone is one of the tools' (or of
/// the few other tools the pages name): prose that names a renamed or removed flag fails here,
/// as the examples the pages run fail in the tests above.
#[test]
fn every_command_and_flag_the_prose_names_exists() {
    let tools = [
        ("nlstudy", flags_of("nlstudy")),
        ("nlsolve", flags_of("nlsolve")),
    ];
    let (mut wrong, mut checked) = (Vec::new(), 0);
    for page in pages() {
        let name = page.strip_prefix(root()).unwrap().display().to_string();
        let (page_wrong, page_checked) =
            wrong_commands_and_flags(&name, &std::fs::read_to_string(&page).unwrap(), &tools);
        wrong.extend(page_wrong);
        checked += page_checked;
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
    assert!(
        checked > 50,
        "only {checked} spans checked: is the parsing right?"
    );
    // And the check finds what it is for: a flag a command lacks, a command a tool lacks, a
    // flag no tool has, over a line break and inside a double-backtick span.
    let page = "Run `nlstudy run\n--no-such-flag` or `nlstudy frobnicate`; ``--nor-this `x` ``.\n";
    let (wrong, _) = wrong_commands_and_flags("page", page, &tools);
    assert_eq!(wrong.len(), 3, "{wrong:#?}");
}
