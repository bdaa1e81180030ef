use super::*;
use schema::record::example::record_json;
use serde_json::json;

/// Keys are the first 16 bytes of SHA-256 of the case's compact JSON, the solver version
/// and the repeat, joined by newlines (values computed by Python's hashlib): records
/// stored by earlier versions of nlstudy keep their keys.
#[test]
fn keys_are_the_hashes_they_always_were_and_a_point_prints_as_its_case() {
    let case = r#"{"dim":1,"m":2,"n":16}"#;
    let (case_id, key) = case_id_and_key(case, "0.1.0", 0);
    assert_eq!(case_id.as_str(), "b37555f0171b457510a13b46362b7615");
    assert_eq!(key.as_str(), "1d4e5939b0079690e5b28ce7cde5d851");
    let (_, repeated) = case_id_and_key(case, "0.1.0", 2);
    assert_eq!(repeated.as_str(), "52596724b90431acd907190c9ed73ac4");
    // A refused point is keyed by its fields printed as a map: the text a `Value` prints.
    let fields =
        serde_json::json!({"z": null, "a": 1.5e-300, "s": "é\n\"q\"", "o": {"k": [1, 0.1]}});
    let map = fields.as_object().unwrap();
    assert_eq!(serde_json::to_string(map).unwrap(), fields.to_string());
}

/// A store in a scratch directory, removed with the guard however the test ends.
fn scratch() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(dir.path(), "s");
    (dir, store)
}

/// A record of the case `{"n": n}` with `status`, keyed as the pool keys it, and its key.
fn keyed(n: u64, status: &str) -> (String, Value) {
    let case = json!({ "n": n });
    let (_, key) = case_id_and_key(&case.to_string(), "0.1.0", 0);
    let record = record_json(json!({"key": key, "case": case, "solver_version": "0.1.0",
                        "repeat": 0, "status": status, "message": status}));
    (key.to_string(), record)
}

fn with_fingerprint(mut record: Value, fingerprint: &str) -> Value {
    record["provenance"]["fingerprint"] = json!(fingerprint);
    record
}

/// The record as the store takes it.
fn typed(record: &Value) -> Stored {
    serde_json::from_value(record.clone()).expect("a whole record")
}

#[test]
fn a_failed_record_never_replaces_a_result_but_a_result_replaces_a_failure() {
    let (_dir, store) = scratch();
    let record = |status: &str| keyed(1, status);
    let (k, _) = record("ok");
    assert!(store.save(&k, &typed(&record("failed").1)).unwrap());
    assert!(store.save(&k, &typed(&record("ok").1)).unwrap());
    assert!(!store.save(&k, &typed(&record("failed").1)).unwrap());
    assert_eq!(store.status(&k), Some(Status::Ok));
    assert!(
        store.save(&k, &typed(&record("diverged").1)).unwrap(),
        "a result replaces a result"
    );
    assert_eq!(store.status(&k), Some(Status::Diverged));
}

/// A result is never deleted: replaced by a run of the same build (`--force`), it moves to
/// the history too, each replaced one under a name of its own.
#[test]
fn a_replaced_result_moves_to_history_even_from_the_same_build() {
    let (_dir, store) = scratch();
    let build = "ab".repeat(32);
    let (k, record) = keyed(2, "ok");
    let record = with_fingerprint(record, &build);
    for message in ["first", "second", "third"] {
        let mut record = record.clone();
        record["message"] = json!(message);
        assert!(store.save(&k, &typed(&record)).unwrap());
    }
    let history = store.history();
    assert!(history.unreadable.is_empty(), "{:?}", history.unreadable);
    assert_eq!(history.records.len(), 2, "two results were replaced");
    let order: Vec<&str> = history.records.iter().map(|r| r.message()).collect();
    assert_eq!(
        order,
        ["first", "second"],
        "in the order they were superseded"
    );
    let names: Vec<String> = listing(&store.table("history"))
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [format!("{k}.{build}.2.json"), format!("{k}.{build}.json")]
    );
    // A failed record of the same build is not a result: it is replaced, not kept.
    let (k3, failed) = keyed(3, "failed");
    store.save(&k3, &typed(&failed)).unwrap();
    store.save(&k3, &typed(&keyed(3, "ok").1)).unwrap();
    assert_eq!(store.history().records.len(), 2);
}

/// A search asks for all its probes' records every round: each is read once while it lies where
/// it lay, and read again once another writer (here another process's store) stored it anew.
#[test]
fn shared_records_are_parsed_once_and_read_again_once_stored_again() {
    let (dir, store) = scratch();
    let (k, record) = keyed(4, "ok");
    let mut first = record.clone();
    first["message"] = json!("first");
    assert!(store.save(&k, &typed(&first)).unwrap());
    let (missing, _) = keyed(5, "ok");
    let once = store.stored_shared([k.as_str(), missing.as_str()]);
    assert_eq!(once[0].as_ref().unwrap().message(), "first");
    assert!(once[1].is_none(), "a key with no record has none");
    let again = store.stored_shared([k.as_str()]);
    assert!(Arc::ptr_eq(
        once[0].as_ref().unwrap(),
        again[0].as_ref().unwrap()
    ));
    let other = Store::open(dir.path(), "s");
    let mut second = record;
    second["message"] = json!("second");
    assert!(other.save(&k, &typed(&second)).unwrap());
    other.persist_catalog();
    let now = store.stored_shared([k.as_str()]);
    assert_eq!(now[0].as_ref().unwrap().message(), "second");
}

/// A stored record's fingerprint reaches a file name only as 64 hex digits: a traversal, a
/// slash or 300 characters move the record to `<key>.unknown.json`, inside the history,
/// and the file the traversal aimed at stays as it was.
#[test]
fn a_fingerprint_that_is_not_hex_never_reaches_a_path() {
    let (_dir, store) = scratch();
    let root = store.runs.parent().unwrap().parent().unwrap().to_path_buf();
    let (k, record) = keyed(4, "ok");
    // The directory the traversal needs, and its target (inside the scratch directory).
    std::fs::create_dir_all(store.table("history").join(format!("{k}."))).unwrap();
    let target = root.join("PWN_target.json");
    std::fs::write(&target, "precious").unwrap();
    let hostile = [
        // history/<key>./../../.. is the scratch root: the old name was root/PWN_target.json.
        "/../../../PWN_target".to_string(),
        "a/b".to_string(),
        "f".repeat(300),
        "AB".repeat(32),
    ];
    for fingerprint in &hostile {
        std::fs::create_dir_all(&store.runs).unwrap();
        let stored = with_fingerprint(record.clone(), fingerprint);
        std::fs::write(store.path(&k), stored.to_string()).unwrap();
        // Newer than the record saved the round before: a file's time is the kernel's coarse
        // clock, which can fall behind a segment record's (read at once) within a tick, and
        // then the store rightly takes the segment's record as the latest (1 run in 20).
        let later = std::time::SystemTime::now() + std::time::Duration::from_secs(1);
        (std::fs::File::options().write(true).open(store.path(&k)))
            .and_then(|file| file.set_modified(later))
            .unwrap();
        assert_eq!(
            fingerprint_of(&typed(&stored)),
            "",
            "{fingerprint} is not a fingerprint"
        );
        let new = with_fingerprint(record.clone(), &"0".repeat(64));
        // As the pool does: the key's status read, then its record saved.
        assert_eq!(store.status(&k), Some(Status::Ok));
        assert!(store.save(&k, &typed(&new)).unwrap(), "{fingerprint}");
    }
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "precious");
    let history = store.history();
    assert_eq!(history.records.len(), hostile.len());
    assert!(listing(&store.table("history"))
        .iter()
        .filter(|p| p.is_file())
        .all(|p| p.to_string_lossy().contains(&format!("{k}.unknown"))));
}

/// Runs `read` on another thread: `None` when it has not returned within `limit` (a hang).
fn within<T: Send + 'static>(
    limit: std::time::Duration,
    read: impl FnOnce() -> T + Send + 'static,
) -> Option<T> {
    let (done, answer) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = done.send(read());
    });
    answer.recv_timeout(limit).ok()
}

/// Files that are not regular files are named and skipped, never followed, read to their
/// end or waited on: a link to /dev/zero, a FIFO, a directory, an oversized file.
#[test]
fn files_that_are_not_regular_files_are_reported_never_read() {
    let (_dir, store) = scratch();
    let history = store.table("history");
    std::fs::create_dir_all(&store.runs).unwrap();
    std::fs::create_dir_all(&history).unwrap();
    let (k, record) = keyed(5, "ok");
    std::fs::write(store.path(&k), record.to_string()).unwrap();
    std::os::unix::fs::symlink("/dev/zero", store.path(&"a".repeat(32))).unwrap();
    std::os::unix::fs::symlink(store.path(&k), store.path(&"b".repeat(32))).unwrap();
    std::os::unix::fs::symlink("/dev/zero", history.join("c.unknown.json")).unwrap();
    for fifo in [store.path(&"d".repeat(32)), history.join("e.unknown.json")] {
        let path = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(path.as_ptr(), 0o644) }, 0);
    }
    std::fs::create_dir(store.path(&"f".repeat(32))).unwrap();
    let big = store.path(&"0".repeat(32));
    std::fs::File::create(&big)
        .unwrap()
        .set_len(RECORD_CAP + 1)
        .unwrap();
    let limit = std::time::Duration::from_secs(20);
    let runs = Store::open(store.runs.parent().unwrap().parent().unwrap(), "s");
    let index = within(limit, move || runs.index()).expect("the index hangs");
    assert_eq!(index.stored.len(), 1, "the one whole record");
    let problems: Vec<&str> = index
        .unreadable
        .iter()
        .map(|u| u.problem.as_str())
        .collect();
    assert_eq!(problems.len(), 5, "{problems:?}");
    for what in ["symbolic link", "FIFO", "directory", "more than the 64 MiB"] {
        assert!(
            problems.iter().any(|p| p.contains(what)),
            "{what}: {problems:?}"
        );
    }
    let runs = Store::open(store.runs.parent().unwrap().parent().unwrap(), "s");
    let scan = within(limit, move || (runs.scan(), runs.history())).expect("a scan hangs");
    assert_eq!((scan.0.records.len(), scan.0.unreadable.len()), (1, 5));
    assert_eq!((scan.1.records.len(), scan.1.unreadable.len()), (0, 2));
}

/// A record is used only when its key is the hash of its case, solver version and repeat:
/// an edited case, a record copied under another key, a changed repeat are reported.
#[test]
fn a_record_whose_key_is_not_its_identity_is_reported_not_used() {
    let (_dir, store) = scratch();
    std::fs::create_dir_all(&store.runs).unwrap();
    let (k, record) = keyed(6, "ok");
    let (other, _) = keyed(7, "ok");
    let mut edited = record.clone();
    edited["case"]["n"] = json!(60);
    let mut repeated = record.clone();
    repeated["repeat"] = json!(1);
    let mut versionless = record.clone();
    versionless
        .as_object_mut()
        .unwrap()
        .remove("solver_version");
    for bad in [edited, repeated, versionless] {
        std::fs::write(store.path(&k), bad.to_string()).unwrap();
        assert_eq!(store.status(&k), None, "{bad}");
        assert_eq!(store.scan().unreadable.len(), 1);
        assert!(store.index().stored.is_empty());
    }
    let mut moved = record.clone();
    moved["key"] = json!(other);
    std::fs::remove_file(store.path(&k)).unwrap();
    std::fs::write(store.path(&other), moved.to_string()).unwrap();
    let problem = &store.index().unreadable[0].problem;
    assert!(problem.contains("edited or moved"), "{problem}");
    std::fs::remove_file(store.path(&other)).unwrap();
    std::fs::write(store.path(&k), record.to_string()).unwrap();
    assert_eq!(store.status(&k), Some(Status::Ok));
}

#[test]
fn a_key_is_locked_once_and_its_leftovers_are_cleared_by_the_next_holder() {
    let (_dir, store) = scratch();
    std::fs::create_dir_all(store.work_dir()).unwrap();
    let leftover = store.work_dir().join("k.out");
    std::fs::write(&leftover, "half").unwrap();
    let held = store.lock("k").unwrap().expect("free");
    assert!(!leftover.exists());
    assert!(store.lock("k").unwrap().is_none(), "a held key is refused");
    assert!(store.lock("other").unwrap().is_some());
    drop(held);
    assert!(store.lock("k").unwrap().is_some(), "released with its file");
}

/// Every key's lock is a byte of one file: locking a thousand keys creates one file, each is
/// held by its own opening (in this process as in another) and released when that closes.
#[test]
fn key_locks_are_bytes_of_one_file_each_held_by_its_own_opening() {
    let (_dir, store) = scratch();
    let keys: Vec<String> = (0..1000).map(|k| format!("{k:032x}")).collect();
    let held: Vec<_> = keys
        .iter()
        .map(|key| store.lock(key).unwrap().expect("free"))
        .collect();
    let files: Vec<_> = std::fs::read_dir(store.work_dir()).unwrap().collect();
    assert_eq!(files.len(), 1, "one lock file for every key");
    assert!(keys.iter().all(|key| store.lock(key).unwrap().is_none()));
    drop(held);
    assert!(keys.iter().all(|key| store.lock(key).unwrap().is_some()));
}

#[test]
fn abandoned_output_partials_are_cleared_only_while_no_writer_holds_the_outputs() {
    let (_dir, store) = scratch();
    std::fs::create_dir_all(&store.runs).unwrap();
    let partial = store.table(".t.parquet.999.partial");
    std::fs::write(&partial, "PAR1").unwrap();
    let writer = store.lock_outputs().unwrap();
    std::fs::write(&partial, "PAR1").unwrap();
    store.clear_abandoned_outputs().unwrap();
    assert!(partial.exists(), "a live writer's partial file is kept");
    drop(writer);
    store.clear_abandoned_outputs().unwrap();
    assert!(!partial.exists(), "an abandoned partial file is cleared");
}

/// The index's quick read names its fields as `Stored` and `Record` do: whole records read the
/// same through both (a field renamed in the schema and not in the index fails here).
#[test]
fn the_index_reads_what_the_typed_record_says() {
    let (_dir, store) = scratch();
    let keyed = |mut stored: Stored| {
        let (case_id, key) = case_id_and_key(&stored.case().to_string(), &stored.solver_version, 0);
        (stored.key, stored.case_id) = (key.to_string(), Some(case_id.to_string()));
        store.save(&stored.key.clone(), &stored).unwrap();
        stored
    };
    let mut whole = schema::record::every_field();
    let record = whole.record_mut().unwrap();
    record.provenance.noisy = true;
    record.provenance.fingerprint = "ab".repeat(32);
    let whole = keyed(whole);
    let mut failed = schema::record::every_field();
    failed.outcome = schema::record::Outcome::Failed(schema::record::Failure {
        case: json!({"n": 3}),
        message: "refused\nsecond line".into(),
    });
    let failed = keyed(failed);
    let index = store.index();
    assert!(index.unreadable.is_empty(), "{:?}", index.unreadable);
    let recorded = &index.stored[&whole.key];
    let record = whole.record().unwrap();
    assert_eq!(recorded.status, whole.status());
    assert_eq!(&*recorded.fingerprint, fingerprint_of(&whole));
    // The whole run's wall time where the record has it, else set-up and solve.
    assert_eq!(recorded.wall_s, record.wall_s);
    assert_ne!(record.wall_s, Some(record.setup_s + record.solve_s));
    assert_eq!(index.noisy, 1);
    let case_id = whole.case_id.as_deref().unwrap();
    assert_eq!(&*index.version_by_case[case_id], whole.solver_version);
    assert_eq!(index.stored[&failed.key].status, Status::Failed);
    assert_eq!(index.failed, [(failed.key.clone(), "refused".to_string())]);
    assert_eq!(store.records().len(), 2);
}

/// The segments of a store, by name.
fn segment_names(store: &Store) -> Vec<String> {
    catalog::segments(&store.segments()).into_keys().collect()
}

#[test]
fn a_thousand_records_make_one_segment_and_a_catalog_a_new_process_reads() {
    let (dir, store) = scratch();
    let saved: Vec<(String, Value)> = (0..1000).map(|n| keyed(n, "ok")).collect();
    for (key, record) in &saved {
        assert!(store.save(key, &typed(record)).unwrap());
    }
    store.persist_catalog();
    assert_eq!(segment_names(&store).len(), 1);
    let files = std::fs::read_dir(store.segments()).unwrap().count();
    assert_eq!(files, 2, "one segment and the catalog");
    // Another process: the catalog says it all, the records read back as saved.
    let again = Store::open(dir.path(), "s");
    let index = again.index();
    assert_eq!(index.stored.len(), 1000);
    assert!(index.unreadable.is_empty());
    let records = again.records();
    assert_eq!(records.len(), 1000);
    for (key, record) in &saved {
        assert_eq!(
            again.stored(key).unwrap().to_value(),
            typed(record).to_value()
        );
    }
}

/// A scratch store of 20 records, its catalog stored, and the catalog's file (the store
/// kept open by the caller, as a writer that has not ended).
fn twenty_with_their_catalog() -> (tempfile::TempDir, Store, std::path::PathBuf) {
    let (dir, store) = scratch();
    for (key, record) in (0..20).map(|n| keyed(n, "ok")) {
        assert!(store.save(&key, &typed(&record)).unwrap());
    }
    store.persist_catalog();
    let file = store.segments().join(catalog::FILE);
    (dir, store, file)
}

/// A catalog cut short at the end of an entry's line is not whole either: it is made again
/// from the segments, and no record goes missing from the index.
#[test]
fn a_catalog_cut_at_the_end_of_a_line_is_made_again() {
    let (dir, _store, file) = twenty_with_their_catalog();
    let text = std::fs::read_to_string(&file).unwrap();
    assert_eq!(
        text.lines().count(),
        22,
        "a line of what they share, a line per entry, its checksum"
    );
    let lines: Vec<&str> = text.lines().collect();
    // The last entry and the checksum cut; the checksum alone cut.
    for kept in [20, 21] {
        std::fs::write(&file, lines[..kept].join("\n")).unwrap();
        let again = Store::open(dir.path(), "s");
        assert_eq!(again.index().stored.len(), 20);
    }
}

/// The catalog is a cache: one edited by hand (a digit of an entry's span, another key's span,
/// a status) is no catalog, and the store reads its segments instead; every record is found
/// where it lies, with its own status.
#[test]
fn a_catalog_edited_by_hand_is_refused_and_made_again_from_the_segments() {
    let (dir, store, file) = twenty_with_their_catalog();
    let keys: Vec<String> = store.records().into_iter().map(|r| r.key).collect();
    let text = std::fs::read_to_string(&file).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let entry = |k: usize| -> Vec<serde_json::Value> { serde_json::from_str(lines[k]).unwrap() };
    type Edit<'a> = &'a dyn Fn(&mut Vec<serde_json::Value>);
    let edits: [Edit; 3] = [
        &|e| e[2] = (e[2].as_u64().unwrap() + 1).into(),
        &|e| (e[2], e[3]) = (entry(2)[2].clone(), entry(2)[3].clone()),
        &|e| e[5] = "failed".into(),
    ];
    for edit in edits {
        let mut edited: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        let mut first = entry(1);
        edit(&mut first);
        edited[1] = serde_json::to_string(&first).unwrap();
        std::fs::write(&file, edited.join("\n")).unwrap();
        let again = Store::open(dir.path(), "s");
        let index = again.index();
        assert_eq!(index.stored.len(), 20);
        assert!(index.stored.values().all(|r| r.status == Status::Ok));
        let key_refs: Vec<&str> = keys.iter().map(String::as_str).collect();
        let (read, unreadable) = again.read_each(&key_refs, |_, stored| stored.key);
        assert!(unreadable.is_empty(), "{unreadable:?}");
        assert_eq!(read.into_iter().flatten().collect::<Vec<_>>(), keys);
    }
}

/// Where a catalog that reads whole points at a frame that is not its key's whole record (a
/// segment changed under it), a reader reads the segments again and finds each record where
/// it lies.
#[test]
fn a_frame_that_is_not_where_the_catalog_says_is_looked_for_in_the_segments() {
    let (dir, store, _) = twenty_with_their_catalog();
    let keys: Vec<String> = store.records().into_iter().map(|r| r.key).collect();
    // Two catalogs' worth of entries swapped under a valid checksum: as a catalog of another
    // moment would point.
    let mut guard = store.catalog_as_read();
    let catalog = guard.as_mut().unwrap();
    let (a, b) = (keys[0].clone(), keys[1].clone());
    let (at_a, at_b) = (
        catalog.entries[&a].at.clone(),
        catalog.entries[&b].at.clone(),
    );
    catalog.entries.get_mut(&a).unwrap().at = at_b;
    catalog.entries.get_mut(&b).unwrap().at = at_a;
    catalog.persist(&store.runs);
    drop(guard);
    let again = Store::open(dir.path(), "s");
    let key_refs: Vec<&str> = keys.iter().map(String::as_str).collect();
    let (read, unreadable) = again.read_each(&key_refs, |_, stored| stored.key);
    assert!(unreadable.is_empty(), "{unreadable:?}");
    assert_eq!(read.into_iter().flatten().collect::<Vec<_>>(), keys);
    assert_eq!(again.stored(&a).unwrap().key, a);
    assert_eq!(Store::open(dir.path(), "s").records().len(), 20);
}

/// A segment written over in place and grown (a record edited, its checksum made to match,
/// the edit longer than the text it replaced): no frame starts where the catalog's reading
/// ended, so the catalog reads it anew rather than trust what it read before, and the edited
/// record, whose fields do not parse, counts as not run (its point runs again) at once.
#[test]
fn a_segment_grown_in_place_is_read_anew_and_an_edited_record_counts_as_not_run() {
    let (dir, store, _) = twenty_with_their_catalog();
    drop(store);
    let reader = Store::open(dir.path(), "s");
    let path = reader.segments().join(&segment_names(&reader)[0]);
    let bytes = std::fs::read(&path).unwrap();
    let frames = segment::read(&bytes, 0).frames;
    let first = &frames[0];
    let body = &bytes[first.body.start as usize..first.body.end as usize];
    let mut record: Value = serde_json::from_slice(body).unwrap();
    let key = record["key"].as_str().unwrap().to_string();
    record["error_l2_norm"] = json!("not a number, and longer than one");
    let mut edited = segment::encode(first.seq, record.to_string().as_bytes());
    edited.extend_from_slice(&bytes[first.span.end as usize..]);
    assert!(edited.len() > bytes.len());
    std::fs::write(&path, &edited).unwrap();
    let again = Store::open(dir.path(), "s");
    let index = again.index();
    assert!(
        !index.stored.contains_key(key.as_str()),
        "the edited record is trusted"
    );
    assert_eq!(index.stored.len(), 19);
    assert!(
        index
            .unreadable
            .iter()
            .any(|u| u.problem.contains("error_l2_norm")),
        "the edit is named"
    );
}

/// A catalog that is gone (or not whole) is made again from the segments by whoever reads
/// the store first, and stored by the first that may: a migrating command reads without
/// storing, and what it read is not lost to the next reader (which would read every record
/// again: a second of a collect at 10⁵ records).
#[test]
fn a_catalog_made_again_by_a_reader_that_does_not_store_it_is_stored_by_the_next() {
    let (dir, _store, file) = twenty_with_their_catalog();
    std::fs::remove_file(&file).unwrap();
    let again = Store::open(dir.path(), "s");
    assert_eq!(again.migrate().unwrap(), 0);
    assert!(!file.exists(), "migrate reads, it does not store");
    assert_eq!(again.index().stored.len(), 20);
    assert!(file.exists(), "the index stores what migrate read");
    assert_eq!(Store::open(dir.path(), "s").index().stored.len(), 20);
}

#[test]
fn the_old_layout_is_read_as_it_is_and_moved_into_a_segment_whole() {
    let (dir, store) = scratch();
    std::fs::create_dir_all(&store.runs).unwrap();
    let old: Vec<(String, Value)> = (0..30).map(|n| keyed(n, "ok")).collect();
    for (key, record) in &old {
        std::fs::write(store.path(key), format!("{record:#}\n")).unwrap();
    }
    let stray = store.runs.join("notes.txt");
    std::fs::write(&stray, "mine").unwrap();
    assert_eq!(store.index().stored.len(), 30, "read before any move");
    assert_eq!(store.migrate().unwrap(), 30);
    for (key, record) in &old {
        assert!(!store.path(key).exists());
        let again = Store::open(dir.path(), "s");
        assert_eq!(
            again.stored(key).unwrap().to_value(),
            typed(record).to_value()
        );
    }
    assert!(stray.exists(), "what is not a record stays, reported");
    let index = Store::open(dir.path(), "s").index();
    assert_eq!(index.stored.len(), 30);
    assert_eq!(index.unreadable.len(), 1, "{:?}", index.unreadable);
}

#[test]
fn a_torn_end_is_no_record_and_the_next_writer_cuts_it_off() {
    let (dir, store) = scratch();
    let (a, first) = keyed(1, "ok");
    let (b, second) = keyed(2, "ok");
    store.save(&a, &typed(&first)).unwrap();
    store.save(&b, &typed(&second)).unwrap();
    drop(store);
    let reader = Store::open(dir.path(), "s");
    let segment = reader.segments().join(&segment_names(&reader)[0]);
    let whole = std::fs::read(&segment).unwrap();
    let cut = whole.len() - 40;
    std::fs::write(&segment, &whole[..cut]).unwrap();
    let index = reader.index();
    assert_eq!(index.stored.len(), 1, "the torn record counts as not run");
    assert!(
        index.unreadable.is_empty(),
        "a torn end is a crash's, not corruption"
    );
    let writer = Store::open(dir.path(), "s");
    writer.save(&b, &typed(&second)).unwrap();
    assert_eq!(
        segment_names(&writer).len(),
        1,
        "the writer took the segment back"
    );
    let again = Store::open(dir.path(), "s");
    assert_eq!(again.index().stored.len(), 2);
    assert_eq!(
        again.stored(&b).unwrap().to_value(),
        typed(&second).to_value()
    );
}

#[test]
fn corrupt_bytes_are_reported_the_records_around_them_stand_and_compaction_keeps_them() {
    let (dir, store) = scratch();
    let saved: Vec<(String, Value)> = (0..3).map(|n| keyed(n, "ok")).collect();
    for (key, record) in &saved {
        store.save(key, &typed(record)).unwrap();
    }
    drop(store);
    let store = Store::open(dir.path(), "s");
    let name = segment_names(&store)[0].clone();
    let segment = store.segments().join(&name);
    let mut bytes = std::fs::read(&segment).unwrap();
    let frames = segment::read(&bytes, 0).frames;
    let middle = frames[1].body.start as usize + 20;
    bytes[middle] ^= 0x20;
    std::fs::write(&segment, &bytes).unwrap();
    let index = store.index();
    assert_eq!(index.stored.len(), 2);
    assert_eq!(index.unreadable.len(), 1);
    let said = index.unreadable[0].to_string();
    assert!(said.contains(&name) && said.contains("corrupt"), "{said}");
    assert!(!index.stored.contains_key(&saved[1].0));
    store.compact(&Default::default()).unwrap();
    assert!(
        segment.exists(),
        "a segment with bytes it cannot read is kept"
    );
    assert_eq!(Store::open(dir.path(), "s").records().len(), 2);
}

#[test]
fn compaction_drops_superseded_records_and_leaves_a_writers_segment_alone() {
    let (dir, first) = scratch();
    let (k, record) = keyed(1, "failed");
    for n in 0..5 {
        let mut record = record.clone();
        record["message"] = json!(format!("try {n}"));
        first.save(&k, &typed(&record)).unwrap();
    }
    let (ok, done) = keyed(2, "ok");
    first.save(&ok, &typed(&done)).unwrap();
    // A second writer, still running, holds a segment of its own.
    let held = Store::open(dir.path(), "s");
    held.save(&keyed(3, "ok").0, &typed(&keyed(3, "ok").1))
        .unwrap();
    drop(first);
    let writer = Store::open(dir.path(), "s");
    let before = segment_names(&writer);
    assert_eq!(before.len(), 2);
    let size = |s: &Store| -> u64 {
        segment_names(s)
            .iter()
            .map(|n| std::fs::metadata(s.segments().join(n)).unwrap().len())
            .sum()
    };
    let bytes_before = size(&writer);
    writer.compact(&Default::default()).unwrap();
    assert!(
        size(&writer) < bytes_before,
        "the four superseded tries are gone"
    );
    let after = Store::open(dir.path(), "s");
    let records = after.records();
    assert_eq!(records.len(), 3);
    assert_eq!(
        after.stored(&k).unwrap().to_value()["message"],
        json!("try 4")
    );
    // Forgetting a record the running writer's segment holds is refused, not half done.
    let forget = [keyed(3, "ok").0].into_iter().collect();
    assert!(after.compact(&forget).is_err());
    drop(held);
    after.compact(&forget).unwrap();
    assert_eq!(Store::open(dir.path(), "s").records().len(), 2);
}

/// A record reads through `Stored::from_value` (serde's `Deserialize` is the same reader): its
/// own fields, with their defaults where it leaves them out, and the outcome its `status` says;
/// what it cannot read is refused, naming the field.
#[test]
fn a_record_reads_its_fields_with_their_defaults_and_refuses_a_wrong_one() {
    let read = |value: &Value| Stored::from_value(value.clone()).unwrap();
    let full = record_json(json!({"run_id": "r", "attempt": 2, "repeat": 3, "extra": 1}));
    let stored = read(&full);
    assert_eq!(stored.key, "k");
    assert_eq!(stored.case_id.as_deref(), Some("c"));
    assert_eq!(
        (stored.run_id.as_deref(), stored.attempt),
        (Some("r"), Some(2))
    );
    assert_eq!((stored.repeat, stored.status()), (3, Status::Ok));
    assert_eq!(read(&stored.to_value()), stored, "it reads back as itself");
    let mut bare = record_json(json!({}));
    for optional in ["case_id", "repeat", "run_id", "attempt"] {
        bare.as_object_mut().unwrap().remove(optional);
    }
    let stored = read(&bare);
    assert_eq!(
        (stored.case_id, stored.run_id, stored.attempt),
        (None, None, None)
    );
    assert_eq!(stored.repeat, 0);
    let diverged = record_json(json!({"status": "diverged", "diverged_step": 4}));
    let stored = read(&diverged);
    assert_eq!(stored.status(), Status::Diverged);
    assert_eq!(stored.record().unwrap().diverged_step, Some(4));
    let refused = json!({"key": "k", "solver_version": "v", "status": "failed",
                         "case": {"n": 1}, "message": "refused"});
    let stored = read(&refused);
    assert_eq!(
        (stored.status(), stored.message()),
        (Status::Failed, "refused")
    );
    assert_eq!((stored.case(), stored.record()), (&json!({"n": 1}), None));
    let said_nothing = json!({"key": "k", "solver_version": "v", "status": "failed"});
    let stored = read(&said_nothing);
    assert_eq!((stored.message(), stored.case()), ("", &Value::Null));
    for value in [full, bare, diverged, refused, said_nothing] {
        assert_eq!(
            serde_json::from_value::<Stored>(value.clone()).unwrap(),
            read(&value)
        );
    }
    let unreadable = [
        json!([1]),
        json!({"solver_version": "v", "status": "failed"}),
        json!({"key": "k", "solver_version": "v", "status": "unknown"}),
        json!({"key": "k", "solver_version": "v", "status": "failed", "repeat": "x"}),
        record_json(json!({"solve_s": "fast"})),
        {
            let mut r = record_json(json!({}));
            r.as_object_mut().unwrap().remove("steps");
            r
        },
    ];
    for value in unreadable {
        assert!(
            serde_json::from_value::<Stored>(value.clone()).is_err(),
            "{value}"
        );
        let refused = Stored::from_value(value.clone()).unwrap_err();
        assert!(!refused.is_empty(), "{value}");
    }
    let named = Stored::from_value(record_json(json!({"solve_s": "fast"}))).unwrap_err();
    assert!(named.contains("`solve_s`"), "{named}");
}

/// A record read straight from its text (`Stored::from_ran_text`, how a collect reads whole
/// runs) is the record read from its parsed tree, whatever its fields: optional ones left out,
/// a newer solver's, a whole number where a real is read, a name written twice; what it does
/// not read (a failure, a record that is not whole) is read from the tree, which names why.
#[test]
fn a_record_read_from_its_text_is_the_record_read_from_its_tree() {
    let mut bare = record_json(json!({}));
    for optional in ["case_id", "repeat", "run_id", "attempt", "error_l2"] {
        bare.as_object_mut().unwrap().remove(optional);
    }
    let every_field = schema::record::every_field().to_value().to_string();
    let whole = [
        record_json(json!({"run_id": "r", "attempt": 2, "repeat": 3})).to_string(),
        bare.to_string(),
        record_json(json!({"status": "diverged", "diverged_step": 4})).to_string(),
        record_json(json!({"newer": {"b": [1, 2], "a": null}, "solve_s": 2})).to_string(),
        every_field.clone(),
        include_str!("../../fixtures/record-rk4.json").to_string(),
        include_str!("../../fixtures/record-threads.json").to_string(),
        // A newer solver's field twice: the later one, as a parsed tree keeps it.
        every_field.replacen('{', r#"{"newer":1,"newer":2,"#, 1),
    ];
    let read_from_tree = |text: &str| Stored::from_value(serde_json::from_str(text).unwrap());
    for text in &whole {
        let from_text = Stored::from_ran_text(text).unwrap_or_else(|| panic!("{text}"));
        assert_eq!(Ok(from_text), read_from_tree(text), "{text}");
    }
    let not_read = [
        json!({"key": "k", "solver_version": "v", "status": "failed", "case": {"n": 1}, "message": "m"})
            .to_string(),
        record_json(json!({"solve_s": "fast"})).to_string(),
        record_json(json!({"repeat": "x"})).to_string(),
        record_json(json!({"status": "unknown"})).to_string(),
        // Failed, though every field of a run is there: a failure, as the tree reads it.
        record_json(json!({"status": "failed"})).to_string(),
        every_field.replacen('{', r#"{"solve_s":1,"#, 1),
    ];
    for text in &not_read {
        assert_eq!(Stored::from_ran_text(text), None, "{text}");
    }
    // And `check_identity` takes the record from either reading alike, its key checked.
    for text in whole.iter().chain(&not_read) {
        let Ok(value) = serde_json::from_str::<Value>(text) else {
            continue;
        };
        let key = value["key"].as_str().unwrap_or_default();
        let file_key = match (value.get("case"), value["solver_version"].as_str()) {
            (Some(case), Some(version)) => {
                let repeat = value["repeat"].as_u64().unwrap_or(0) as usize;
                case_id_and_key(&case.to_string(), version, repeat)
                    .1
                    .to_string()
            }
            _ => key.to_string(),
        };
        let mut rekeyed = value.clone();
        rekeyed["key"] = json!(file_key);
        let text = rekeyed.to_string();
        assert_eq!(
            record::check_identity(&file_key, &text),
            record::check_identity_of_tree(Some(&file_key), &text),
            "{text}"
        );
        // A key that is not the case's is refused by both.
        assert!(record::check_identity(&"0".repeat(32), &text).is_err());
    }
}

/// A frame whose checksum holds but whose record does not read as the typed record (a string
/// where a number goes) is no record for `plan` and `status` either, as it is none for
/// `collect`: it is reported once, and its point counts as not run.
#[test]
fn a_whole_frame_that_is_not_a_typed_record_is_not_counted_stored() {
    let (dir, store, _) = twenty_with_their_catalog();
    let (key, mut record) = keyed(100, "ok");
    record["solve_s"] = json!("fast");
    let segment = store.segments().join("hand.seg");
    let frame = segment::encode(segment::now_ns(), record.to_string().as_bytes());
    std::fs::write(&segment, frame).unwrap();
    for store in [store, Store::open(dir.path(), "s")] {
        let index = store.index();
        assert_eq!(
            index.stored.len(),
            20,
            "the hand-made record is not counted"
        );
        assert!(!index.stored.contains_key(&key));
        let said: Vec<String> = index.unreadable.iter().map(|u| u.to_string()).collect();
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].contains("solve_s"), "{said:?}");
        assert!(store.stored(&key).is_none());
    }
}

/// Such a frame written over a stored key (a later sequence number): the earlier record
/// stands, and the report says that it may, rather than that the point counts as not run.
#[test]
fn a_whole_frame_that_is_not_a_record_leaves_an_earlier_record_of_its_key_standing() {
    let (dir, store, _) = twenty_with_their_catalog();
    let (key, mut record) = keyed(3, "ok");
    record["error_l2_norm"] = json!("abc");
    let frame = segment::encode(segment::now_ns(), record.to_string().as_bytes());
    std::fs::write(store.segments().join("hand.seg"), frame).unwrap();
    let again = Store::open(dir.path(), "s");
    let index = again.index();
    assert_eq!(index.stored.len(), 20);
    assert_eq!(
        again.status(&key),
        Some(Status::Ok),
        "the earlier record stands"
    );
    let said: Vec<String> = index.unreadable.iter().map(|u| u.to_string()).collect();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0].contains("hand.seg")
            && said[0].contains("kept where they are")
            && said[0].contains("unless an earlier record of it stands"),
        "{said:?}"
    );
}

/// A `*.seg` that is a symbolic link (to a segment of the store, or anywhere) is not read
/// through, and is said, not passed over in silence.
#[test]
fn a_segment_that_is_a_link_is_reported_not_read() {
    let (dir, store, _) = twenty_with_their_catalog();
    let real = catalog::segments(&store.segments())
        .into_keys()
        .next()
        .unwrap();
    std::os::unix::fs::symlink(
        store.segments().join(&real),
        store.segments().join("linked.seg"),
    )
    .unwrap();
    let again = Store::open(dir.path(), "s");
    let index = again.index();
    assert_eq!(index.stored.len(), 20);
    let said: Vec<String> = index.unreadable.iter().map(|u| u.to_string()).collect();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0].contains("linked.seg") && said[0].contains("symbolic link"),
        "{said:?}"
    );
}

/// A running case's progress file is typed (`schema::protocol::Progress`, as nlsolve writes it);
/// one not rewritten for more than a few seconds says so instead of a time left that no longer
/// holds (a worker stopped by SIGSTOP said "about 2 s left" for as long as it was stopped).
#[test]
fn a_progress_file_says_how_far_and_whether_it_is_still_heard_from() {
    let (dir, _) = scratch();
    let path = dir.path().join("k.progress");
    std::fs::write(
        &path,
        r#"{"step": 930, "steps": 3388, "elapsed_s": 1.5, "left_s": 4.0, "unit": "step"}"#,
    )
    .unwrap();
    let mut progress = progress_of(&path).unwrap();
    assert_eq!(progress.steps_done(), "step 930 of 3388");
    assert_eq!(progress.left(), "about 4 s left");
    progress.silent_s = 15.0;
    assert_eq!(
        progress.left(),
        "no progress for 15 s (stopped, or starved of its cores)"
    );
    std::fs::write(
        &path,
        r#"{"step": 3, "steps": 40, "elapsed_s": 1, "left_s": 9, "unit": "iteration"}"#,
    )
    .unwrap();
    assert_eq!(
        progress_of(&path).unwrap().steps_done(),
        "iteration 3 of about 40"
    );
    std::fs::write(&path, r#"{"step": "3"}"#).unwrap();
    assert!(progress_of(&path).is_none());
}
