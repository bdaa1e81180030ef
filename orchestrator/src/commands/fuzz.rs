//! Every reader of a file the tool did not write in this process, given byte-mutated copies of
//! real files of its kind: a stored record and a superseded one, study files in JSON, JSONC and
//! TOML, site profiles in TOML and JSON, the jobs ledger, the owner file, the Parquet tables
//! (read, then pivoted and drawn as `table` and `plot` would) and the run timelines (read, then
//! split into phases, tabled, charted and simulated as `status --timeline` and `plan
//! --simulate` would). Each must answer (a value or an error), never panic, hang or abort.
//!
//! `make test` runs `FUZZ_CASES` (10⁴ by default) cases per kind from the seed `FUZZ_SEED`
//! (printed, so that a failure replays); a longer run:
//! `FUZZ_CASES=1000000 cargo test --release -p orchestrator fuzz -- --nocapture`.
//! A case that panics is saved under `target/fuzz-failures/` before the test fails.

use crate::model::site::Site;
use crate::model::study::Study;
use crate::store::Store;
use fastrand::Rng;
use sha2::Digest;
use std::path::{Path, PathBuf};

/// Readers whose own text the tool is given: these files live beside the crate.
const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures");
const WORKSPACE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/..");

fn cases() -> usize {
    std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(10_000)
}

fn seed() -> u64 {
    std::env::var("FUZZ_SEED")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(0x5eed_f11e)
}

/// Bytes a mutation may insert: JSON and TOML punctuation, numbers no reader should take as
/// values, and characters that are not printable text.
const TOKENS: &[&str] = &[
    "1e400",
    "-0",
    "nan",
    "inf",
    "-inf",
    "null",
    "true",
    "\"\"",
    "{}",
    "[]",
    "[",
    "]",
    "{",
    "}",
    ",",
    ":",
    "=",
    "\"",
    "\\",
    "\n",
    "\u{202e}",
    "\u{feff}",
    "\u{0}",
    "1979-05-27",
    "18446744073709551616",
    "-1",
    "0",
    "1e-320",
    "/..",
    "..",
];

/// One to four mutations of `bytes`: a bit flipped, a byte replaced, a range deleted or
/// duplicated, a token inserted, the tail cut.
fn mutate(random: &mut Rng, bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    for _ in 0..1 + random.usize(..4) {
        let at = random.usize(..out.len() + 1);
        match random.usize(..6) {
            0 if at < out.len() => out[at] ^= 1 << random.u32(..8),
            1 if at < out.len() => out[at] = random.u8(..),
            2 => {
                let end = (at + 1 + random.usize(..16)).min(out.len());
                out.drain(at.min(end)..end);
            }
            3 => {
                let end = (at + 1 + random.usize(..32)).min(out.len());
                let copy = out[at.min(end)..end].to_vec();
                out.splice(at..at, copy);
            }
            4 => {
                let token = TOKENS[random.usize(..TOKENS.len())].as_bytes();
                out.splice(at..at, token.iter().copied());
            }
            _ => out.truncate(at),
        }
    }
    out
}

/// Runs `read` on `cases()` mutations of the corpus; a panic fails the test, its input saved.
fn fuzz(kind: &str, corpus: &[Vec<u8>], mut read: impl FnMut(&[u8])) {
    assert!(!corpus.is_empty(), "{kind}: no corpus");
    let seed = seed()
        ^ kind
            .bytes()
            .fold(0u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)));
    let mut random = Rng::with_seed(seed);
    let count = cases();
    for case in 0..count {
        let base = &corpus[random.usize(..corpus.len())];
        let input = mutate(&mut random, base);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read(&input)));
        if outcome.is_err() {
            let saved = Path::new(WORKSPACE).join("target/fuzz-failures");
            let _ = std::fs::create_dir_all(&saved);
            let path = saved.join(format!("{kind}-{case}.bin"));
            let _ = std::fs::write(&path, &input);
            panic!(
                "{kind}: case {case} of seed {seed} panicked; its input is {}",
                path.display()
            );
        }
    }
    println!("fuzz {kind}: {count} cases of seed {seed}, no panic");
}

fn read(path: impl AsRef<Path>) -> Vec<u8> {
    let path = path.as_ref();
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The files of `dir` whose names end in one of `extensions`.
fn files(dir: &str, extensions: &[&str]) -> Vec<PathBuf> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.to_string_lossy();
            extensions.iter().any(|x| name.ends_with(x))
        })
        .collect();
    paths.sort();
    paths
}

/// A scratch directory and its guard, which removes it however the test ends.
fn scratch() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().to_path_buf();
    (dir, path)
}

fn records() -> Vec<Vec<u8>> {
    files(FIXTURES, &[".json"])
        .iter()
        .filter(|p| p.to_string_lossy().contains("record-"))
        .map(read)
        .collect()
}

#[test]
fn fuzz_records_and_history_entries() {
    let (_scratch, root) = scratch();
    let store = Store::open(&root, "s");
    std::fs::create_dir_all(&store.runs).unwrap();
    std::fs::create_dir_all(store.table("history")).unwrap();
    let corpus = records();
    // Under its own key's name, so that mutations of the key and the case are what is tested.
    let key = |bytes: &[u8]| -> String {
        let text = String::from_utf8_lossy(bytes);
        let start = text.find("\"key\":\"").map_or(0, |at| at + 7);
        text[start..]
            .chars()
            .take(32)
            .filter(char::is_ascii_hexdigit)
            .collect()
    };
    let keys: Vec<String> = corpus.iter().map(|r| key(r)).collect();
    assert!(keys.iter().all(|k| k.len() == 32), "{keys:?}");
    for (bytes, name) in corpus.iter().zip(&keys) {
        std::fs::write(store.path(name), bytes).unwrap();
        assert!(
            store.stored(name).is_some(),
            "the corpus holds whole records"
        );
    }
    let mut k = 0;
    fuzz("record", &corpus, |bytes| {
        k += 1;
        let name = &keys[k % keys.len()];
        std::fs::write(store.path(name), bytes).unwrap();
        let history = store
            .table("history")
            .join(format!("{name}.{}.json", "ab".repeat(32)));
        std::fs::write(&history, bytes).unwrap();
        let _ = store.scan();
        let _ = store.index();
        let _ = store.history();
        let _ = store.status(name);
    });
}

/// Every shipped study, as JSON (comments included) and as TOML.
fn studies() -> (Vec<Vec<u8>>, Vec<Vec<u8>>) {
    let json: Vec<Vec<u8>> = files(&format!("{WORKSPACE}/studies"), &[".json", ".jsonc"])
        .iter()
        .map(read)
        .collect();
    // Those TOML can hold (it has no null), written as TOML.
    let toml: Vec<Vec<u8>> = json
        .iter()
        .filter_map(|text| {
            let mut plain = String::new();
            std::io::Read::read_to_string(
                &mut json_comments::StripComments::new(text.as_slice()),
                &mut plain,
            )
            .ok()?;
            let value = schema::json::parse(&plain).ok()?;
            (!value.to_string().contains("null")).then_some(())?;
            toml::to_string(&value).ok().map(String::into_bytes)
        })
        .collect();
    (json, toml)
}

/// A study as `read_study` takes it: parsed, expanded and its figures checked against the
/// columns.
fn take_study(study: Result<Study, crate::model::study::StudyError>) {
    if let Ok(study) = study {
        if study.expand().is_ok() {
            let _ = crate::analysis::figure_columns::check(&study);
        }
    }
}

#[test]
fn fuzz_study_files() {
    let (json, toml) = studies();
    assert!(
        json.len() >= 10 && !toml.is_empty(),
        "{} {}",
        json.len(),
        toml.len()
    );
    fuzz("study-json", &json, |bytes| {
        take_study(crate::kinds::parse(&String::from_utf8_lossy(bytes)))
    });
    fuzz("study-toml", &toml, |bytes| {
        take_study(crate::kinds::parse_toml(&String::from_utf8_lossy(bytes)))
    });
}

#[test]
fn fuzz_site_profiles() {
    let toml: Vec<Vec<u8>> = files(&format!("{WORKSPACE}/sites"), &[".toml"])
        .iter()
        .map(read)
        .collect();
    let json: Vec<Vec<u8>> = toml
        .iter()
        .map(|text| {
            let value: serde_json::Value =
                toml::from_str(std::str::from_utf8(text).unwrap()).unwrap();
            value.to_string().into_bytes()
        })
        .collect();
    fuzz("site-toml", &toml, |bytes| {
        let _ = Site::parse(&String::from_utf8_lossy(bytes), true);
    });
    fuzz("site-json", &json, |bytes| {
        let _ = Site::parse(&String::from_utf8_lossy(bytes), false);
    });
}

#[test]
fn fuzz_the_ledger_and_the_owner_file() {
    use crate::run::cluster::ledger::{self, LedgerEntry};
    use crate::run::cluster::scheduler::Scheduler;
    let (_scratch, root) = scratch();
    let store = Store::open(&root, "s");
    let entry = LedgerEntry {
        scheduler: Scheduler::Slurm,
        id: "4242".into(),
        name: "s-1".into(),
        keys: vec!["ab".repeat(16), "cd".repeat(16)],
        elements: vec![vec!["ab".repeat(16)], vec!["cd".repeat(16)]],
        submitted: 1_764_000_000,
        whole: false,
    };
    ledger::add(&store, &entry).unwrap();
    let ledger_file = store.table("jobs/ledger/4242.json");
    let corpus = [read(&ledger_file)];
    fuzz("ledger", &corpus, |bytes| {
        std::fs::write(&ledger_file, bytes).unwrap();
        let _ = ledger::entries(&store);
    });
    let study = root.join("study.json");
    std::fs::write(&study, "{}").unwrap();
    store.claim(&study, "{}", false, true).unwrap();
    let owner_file = store.table("study-file.json");
    let corpus = [read(&owner_file)];
    fuzz("owner", &corpus, |bytes| {
        std::fs::write(&owner_file, bytes).unwrap();
        let _ = store.owner();
        let _ = store.claim(&study, "{}", false, false);
    });
}

/// The tables `collect` wrote for `studies/first.jsonc`, each with its sum, read as `table`,
/// `plot` and `report` read them: the rows, a pivot, and the study's figures drawn from them.
#[test]
fn fuzz_parquet_tables() {
    let study = crate::kinds::read(Path::new(&format!("{WORKSPACE}/studies/first.jsonc"))).unwrap();
    let (_scratch, root) = scratch();
    let table = root.join("t.parquet");
    for name in ["first-summary", "first"] {
        let original = read(format!("{FIXTURES}/{name}.parquet"));
        // The sum `collect` wrote of the table before it was changed.
        let digest = crate::store::hex(&sha2::Sha256::digest(&original));
        std::fs::write(
            crate::store::table::sum_path(&table),
            format!("{digest}  t.parquet\n"),
        )
        .unwrap();
        std::fs::write(&table, &original).unwrap();
        assert!(
            crate::store::table::read_parquet(&table).is_ok(),
            "{name} reads whole"
        );
        let mut refused = 0;
        fuzz(&format!("parquet-{name}"), &[original], |bytes| {
            std::fs::write(&table, bytes).unwrap();
            let Ok(rows) = crate::store::table::read_parquet(&table) else {
                refused += 1;
                return;
            };
            let spec = crate::analysis::pivot::PivotSpec {
                rows: vec!["dt".into()],
                column: Some("integrator".into()),
                values: vec!["error_l2_norm".into()],
                filter: Vec::new(),
            };
            let _ = crate::analysis::pivot::markdown(&spec, &rows);
            for (k, figure) in study.figures.iter().enumerate() {
                if let Ok(chart) = crate::output::figure::chart(figure, k, &rows, None) {
                    let _ = crate::output::draw::render(&chart);
                }
            }
        });
        println!(
            "fuzz parquet-{name}: {refused} of {} changed tables refused",
            cases()
        );
    }
}

/// A checkpoint as the solver writes it (`schema::checkpoint`), mutated: read as the solver and
/// `nlstudy status` read it. None may panic, and none that differs from the written file may be
/// taken: every byte is under its checksum.
#[test]
fn fuzz_checkpoints() {
    use schema::checkpoint::{parse, write, Header, Identity};
    let header = Header {
        identity: Identity {
            fingerprint: "ab".repeat(32),
            case: r#"{"dim":1,"m":2,"n":64,"t_end":0.1}"#.into(),
            ranks: 1,
            rank: 0,
        },
        step: 300,
        steps: Some(400),
        parts: vec![
            ("field".into(), 64),
            ("steps".into(), 1),
            ("timing.step_seconds".into(), 30),
            ("c_tot.time".into(), 3),
        ],
    };
    let values = (0..98).map(|k| (k as f64).sin() * 1e-3);
    let mut original = Vec::new();
    write(&mut original, &header, values).unwrap();
    assert!(parse(original.clone()).is_ok());
    let (_scratch, root) = scratch();
    let path = root.join("k.checkpoint");
    let mut taken = 0;
    fuzz("checkpoint", std::slice::from_ref(&original), |bytes| {
        std::fs::write(&path, bytes).unwrap();
        let read = schema::checkpoint::read(&path, 1 << 20);
        if let Ok(Some(checkpoint)) = read {
            assert_eq!(bytes, original.as_slice(), "a changed checkpoint was taken");
            let _ = checkpoint.parts().count();
            taken += 1;
        }
    });
    println!("fuzz checkpoint: {taken} unchanged inputs taken");
}

/// A store of the fixture records as segments (and their catalog), one file at a time mutated:
/// the store reads what is whole and reports the rest. None may panic; every record it reads
/// is one of those it stored, and a mutated catalog changes nothing it says is stored (the
/// catalog is a cache of the segments).
#[test]
fn fuzz_segments_and_the_catalog() {
    let (_scratch, root) = scratch();
    let store = Store::open(&root, "s");
    let records: Vec<schema::record::Stored> = records()
        .iter()
        .map(|bytes| serde_json::from_slice(bytes).unwrap())
        .collect();
    for record in &records {
        assert!(store.save(&record.key, record).unwrap());
    }
    store.persist_catalog();
    let dir = store.runs.join("segments");
    let segment = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "seg"))
        .unwrap();
    let catalog = dir.join(crate::store::catalog::FILE);
    let originals = [read(&segment), read(&catalog)];
    let stored = |store: &Store| -> Vec<(String, schema::record::Status)> {
        let mut stored: Vec<_> = (store.index().stored.into_iter())
            .map(|(key, recorded)| (key, recorded.status))
            .collect();
        stored.sort_by(|a, b| a.0.cmp(&b.0));
        stored
    };
    let whole = stored(&store);
    assert_eq!(whole.len(), records.len());
    let restore = || {
        std::fs::write(&segment, &originals[0]).unwrap();
        std::fs::write(&catalog, &originals[1]).unwrap();
    };
    fuzz("segment", &originals[..1], |bytes| {
        restore();
        std::fs::write(&segment, bytes).unwrap();
        let reader = Store::open(&root, "s");
        for record in reader.scan().records {
            assert!(records.contains(&record), "a changed record was read");
        }
        let _ = reader.index();
    });
    fuzz("catalog", &originals[1..], |bytes| {
        restore();
        std::fs::write(&catalog, bytes).unwrap();
        let reader = Store::open(&root, "s");
        assert_eq!(
            stored(&reader),
            whole,
            "a changed catalog changed what is stored"
        );
        for record in &records {
            assert_eq!(reader.stored(&record.key).as_ref(), Some(record));
        }
    });
}

/// A run's timeline (`store::timeline`), every kind of event, mutated: read as `status
/// --timeline`, `report` and `plan --simulate` read it, none may panic. Lines that no longer
/// parse are skipped; what parses may say anything (a lane of 2⁶⁴ − 1, a case before its
/// batch, no batch at all, times that run backwards).
#[test]
fn fuzz_timelines() {
    use crate::store::timeline::{dir, latest, Event, Phases, Writer};
    let (_scratch, root) = scratch();
    let store = Store::open(&root, "s");
    let run = "host-100-1";
    let mut writer = Writer::create(&dir(&store), run).unwrap();
    let case = |node: &str, lane, started: f64, fresh| Event::Case {
        node: node.into(),
        lane,
        key: format!("k{started}"),
        started,
        answered: started + 1.0,
        saved: started + 1.25,
        fresh,
        phases: fresh.then_some(Phases {
            setup_s: 0.125,
            solve_s: 0.5,
            wall_s: 0.75,
        }),
    };
    let events = [
        case("n1", 0, 1.0, true),
        case("n2", 1, 1.5, false),
        Event::Idle {
            node: "n1".into(),
            lane: 0,
            from: 2.25,
            to: 3.0,
        },
        Event::Batch {
            begin: 0.5,
            end: 3.0,
        },
        case("n1", 0, 3.5, false),
        Event::Batch {
            begin: 3.25,
            end: 4.75,
        },
    ];
    for event in &events {
        writer.write(event).unwrap();
    }
    writer.flush().unwrap();
    drop(writer);
    let path = dir(&store).join(format!("{run}.jsonl"));
    let original = read(&path);
    let (_, runs) = latest(&store, 1);
    assert_eq!(runs[0].events, events, "the corpus reads back whole");
    fuzz("timeline", &[original], |bytes| {
        std::fs::write(&path, bytes).unwrap();
        for run in latest(&store, 1).1 {
            if let Some(timeline) = crate::analysis::timeline::Timeline::of(&run) {
                let _ = crate::output::timeline::table(&timeline);
                let _ = crate::output::timeline::chart(&timeline);
            }
            if let Some(measured) = crate::analysis::simulate::Measured::of(&run) {
                let _ = (measured.on(1), measured.on(64));
            }
        }
    });
}
