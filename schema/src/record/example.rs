//! Whole records for tests: a complete `ok` run of a small case, with the fields a test cares
//! about set over it, so that every test record reads back through `Stored` as the store's do.
//! Here, outside any `cfg(test)`, so that the tests of every layer of the orchestrator share it.

use super::Stored;
use serde_json::Value;

/// The JSON of a whole record: `fields` set over a complete run of the case `{"n": 16}`
/// (objects such as `provenance` merged field by field).
pub fn record_json(fields: Value) -> Value {
    let mut record: Value = serde_json::from_str(WHOLE).expect("the example is JSON");
    merge(&mut record, fields);
    record
}

/// `record_json(fields)` as the store reads it.
pub fn record(fields: Value) -> Stored {
    let json = record_json(fields);
    serde_json::from_value(json.clone()).unwrap_or_else(|e| panic!("{e}: {json}"))
}

fn merge(into: &mut Value, fields: Value) {
    match (into, fields) {
        (Value::Object(into), Value::Object(fields)) => {
            for (name, value) in fields {
                match into.get_mut(&name) {
                    Some(slot) if slot.is_object() && value.is_object() => merge(slot, value),
                    _ => {
                        into.insert(name, value);
                    }
                }
            }
        }
        (into, fields) => *into = fields,
    }
}

/// A complete `ok` record (with `record_json`'s key, made up: the store's tests key their own).
const WHOLE: &str = r#"{
    "key": "k", "case_id": "c", "repeat": 0, "solver_version": "0.1.0",
    "case": {"n": 16}, "status": "ok", "message": "",
    "h": 0.0625, "eps": null, "m": null, "c": null, "dt": 0.001, "dt_stable": 0.002,
    "steps": 10, "nodes": 16, "bonds": 32, "steps_done": 10,
    "setup_s": 0.01, "solve_s": 0.1, "step_s": 0.01,
    "error_l2": 1e-8, "error_l2_norm": 1e-4, "error_max": 2e-4, "error_total": null,
    "mass": 1.0, "max_abs": 1.0, "diverged_step": null, "diverged_time": null,
    "ranks": 1, "partition": "block", "px": 1, "py": 1, "halo_nodes": 0, "halo_bytes": 0,
    "imbalance": 1.0, "comm_s": 0.0, "oversubscribed": false,
    "provenance": {
        "solver_version": "0.1.0", "fingerprint": "", "git_revision": null,
        "host": "host", "cpu": "cpu", "threads": 1, "ranks": 1,
        "timestamp": "2026-01-01T00:00:00Z", "instruction_set": "avx2",
        "dirty_tree": false, "cores_online": 2, "noisy": false
    }
}"#;
