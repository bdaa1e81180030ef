//! The record's columns: the names its fields take in the tables (`field`, or `group.field`
//! for a member of a nested group, flattened), the one place a record field is named as text.

use super::field::{FieldSnapshot, Histogram, MassSeries};
use super::method::{Coupling, PatchTest, Spectrum};
use super::provenance::{Load, Provenance};
use super::run::{
    Distribution, FetiPhases, ImplicitSolves, Record, Resolved, SteadySolve, Traffic,
};
use super::status::Status;
use super::stored::{Outcome, Stored};
use crate::choices::{Backend, Collar, Integrator, Partition, Quadrature};
use serde_json::{json, Map, Value};
use std::sync::OnceLock;

mod leaves;
pub use leaves::{dotted, each_leaf, tree_order};

/// The record's timings in seconds (setup, time loop, median step, the whole run, communication
/// per step, the set-up's and the solve's CPU, the solve's wait for a core): the fields whose
/// repeats the orchestrator's summary reduces to min, median and max.
pub const TIMINGS: [&str; 8] = [
    "setup_s",
    "solve_s",
    "step_s",
    "wall_s",
    "comm_s",
    "setup_cpu_s",
    "solve_cpu_s",
    "solve_wait_s",
];

/// Declares each column the orchestrator reads by name off a table's rows, and `NAMED`, all of
/// them (a test checks each is one of `columns()`).
macro_rules! named {
    ($($(#[$doc:meta])* $name:ident = $text:literal,)*) => {
        $($(#[$doc])* pub const $name: &str = $text;)*
        /// Every column named here.
        pub const NAMED: &[&str] = &[$($name),*];
    };
}

named! {
    KEY = "key",
    CASE_ID = "case_id",
    REPEAT = "repeat",
    RUN_ID = "run_id",
    STATUS = "status",
    MESSAGE = "message",
    H = "h",
    EPS = "eps",
    M = "m",
    BONDS = "bonds",
    STEPS_DONE = "steps_done",
    SETUP_S = "setup_s",
    SOLVE_S = "solve_s",
    SOLVE_CPU_S = "solve_cpu_s",
    INSTRUCTIONS = "instructions",
    STEP_S = "step_s",
    ERROR_L2_NORM = "error_l2_norm",
    ERROR_MAX = "error_max",
    MAX_ABS = "max_abs",
    GROWTH = "growth",
    AMPLIFICATION = "amplification",
    POSITIVITY = "positivity",
    PEAK_MEMORY_BYTES = "peak_memory_bytes",
    RANKS = "ranks",
    HALO_NODES = "halo_nodes",
    OVERSUBSCRIBED = "oversubscribed",
    HOSTS = "hosts",
    ITERATIONS = "iterations",
    SUBDOMAINS = "subdomains",
    SOLVE_ITERATIONS_MEAN = "solve_iterations_mean",
    BACKEND = "backend",
    THREADS = "threads",
    FINGERPRINT = "provenance.fingerprint",
    HOST = "provenance.host",
    INSTRUCTION_SET = "provenance.instruction_set",
    NOISY = "provenance.noisy",
    HALO_EXCHANGES = "traffic.halo_exchanges",
    TRAFFIC_HALO_BYTES = "traffic.halo_bytes",
    ALL_TO_ALLS = "traffic.all_to_alls",
    ALL_TO_ALL_BYTES = "traffic.all_to_all_bytes",
    C_TOT_TIME = "c_tot.time",
    C_TOT = "c_tot.c_tot",
    FIELD_VALUES = "field.values",
    FIELD_ERROR = "field.error",
}

/// The record's results that do not depend on how the run was spread or timed: what the
/// end-to-end tests compare between serial, threaded and distributed runs of one case.
pub const RESULTS: [&str; 14] = [
    "h",
    "eps",
    "c",
    "dt",
    "dt_stable",
    "steps",
    "nodes",
    "bonds",
    "error_l2",
    "error_l2_norm",
    "error_max",
    "error_total",
    "mass",
    "max_abs",
];

/// What `collect` adds to each run's row beside the record: the threads each rank ran (the
/// case's), which figures and `where` call `threads`.
pub const TABULATED: &[&str] = &["threads"];

/// Every column a record gives the tables, flattened (`group.field`): read off `every_field`,
/// so that a field added to the record is a column without being listed, then `TABULATED`.
/// The case's columns (`case.<field>`) vary with the case and are not listed. Figures and
/// tables are checked against these before anything runs; a test of nlsolve checks that every
/// record it writes keeps to them.
pub fn columns() -> &'static [String] {
    static COLUMNS: OnceLock<Vec<String>> = OnceLock::new();
    COLUMNS.get_or_init(|| {
        let mut columns = flattened_names(&every_field().to_value());
        columns.retain(|c| !c.starts_with("case."));
        columns.extend(TABULATED.iter().map(|c| c.to_string()));
        columns
    })
}

/// Whether `name` is a column of records: one of `columns`, or a field of the case
/// (`case.<field>`, nested ones included).
pub fn is_column(name: &str) -> bool {
    name.strip_prefix("case.").is_some_and(|f| !f.is_empty()) || columns().iter().any(|c| c == name)
}

/// The names the tables give `record`'s fields, flattened (`group.field`), in its order.
pub fn flattened_names(record: &Value) -> Vec<String> {
    let mut names = Vec::new();
    flatten("", record.clone(), &mut |name, _| {
        names.push(name.to_string())
    });
    names
}

/// Each leaf of `value` with its column's name, `prefix.group.field` (`prefix` alone for a leaf,
/// none for an empty object): how a table holds a record. It takes the value apart and spells
/// the names in one buffer, so that nothing is copied (a collect flattens every record of a
/// study).
pub fn flatten(prefix: &str, value: Value, each: &mut impl FnMut(&str, Value)) {
    fn under(name: &mut String, value: Value, each: &mut impl FnMut(&str, Value)) {
        match value {
            Value::Object(fields) => {
                for (field, inner) in fields {
                    let length = name.len();
                    if length > 0 {
                        name.push('.');
                    }
                    name.push_str(&field);
                    under(name, inner, each);
                    name.truncate(length);
                }
            }
            _ => each(name, value),
        }
    }
    under(&mut prefix.to_string(), value, each)
}

/// The object a table's cells were flattened from (`flatten`'s inverse): `case.n` back under
/// `case`. A null cell is a field the record did not have.
pub fn unflatten<'a>(cells: impl IntoIterator<Item = (&'a str, &'a Value)>) -> Value {
    let mut object = serde_json::Map::new();
    for (name, value) in cells.into_iter().filter(|(_, value)| !value.is_null()) {
        let mut path = name.split('.').peekable();
        let mut fields = &mut object;
        while let Some(field) = path.next() {
            if path.peek().is_none() {
                fields.insert(field.to_string(), value.clone());
            } else {
                let group = fields
                    .entry(field)
                    .or_insert_with(|| Value::Object(serde_json::Map::new()));
                match group {
                    Value::Object(inner) => fields = inner,
                    // A leaf and a group of one name: no flattened record has both.
                    _ => break,
                }
            }
        }
    }
    Value::Object(object)
}

/// How a table holds a record's column where it does not hold it as the record does.
#[derive(Clone, Copy, PartialEq)]
enum Held {
    /// As the text of its JSON: a list of text (`hosts`, `cpus`).
    Json,
    /// As a list of floats: a list of counts (`histogram.counts`).
    Counts,
}

/// The record's columns a table holds otherwise than the record (`Held`), read off the leaves
/// of `every_field`.
fn held_otherwise() -> &'static [(String, Held)] {
    static HELD: OnceLock<Vec<(String, Held)>> = OnceLock::new();
    HELD.get_or_init(|| {
        let mut held = Vec::new();
        flatten("", every_field().to_value(), &mut |name, value| {
            let items = value.as_array().map(Vec::as_slice).unwrap_or_default();
            let kind = if value.is_object() || items.iter().any(|v| !v.is_number()) {
                Some(Held::Json)
            } else if items.iter().any(|v| v.is_u64() || v.is_i64()) {
                Some(Held::Counts)
            } else {
                None
            };
            if let Some(kind) = kind {
                held.push((name.to_string(), kind));
            }
        });
        held
    })
}

/// `unflatten` of a row read back from a table, each column as the record holds it: text of
/// JSON parsed again, and counts held as floats whole again, so that every record a table holds
/// reads back as the record.
pub fn unflatten_row<'a>(cells: impl IntoIterator<Item = (&'a str, &'a Value)>) -> Value {
    let held = |name: &str| {
        held_otherwise()
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, h)| *h)
    };
    let as_held: Vec<(&str, Value)> = cells
        .into_iter()
        .map(|(name, value)| {
            let read = match (held(name), value) {
                (Some(Held::Json), Value::String(text)) => serde_json::from_str(text).ok(),
                (Some(Held::Counts), Value::Array(items)) => items
                    .iter()
                    .map(|v| match v.as_f64() {
                        Some(x) if x.fract() == 0.0 && x >= 0.0 && x < 2f64.powi(53) => {
                            Some(Value::from(x as u64))
                        }
                        _ => None,
                    })
                    .collect::<Option<Vec<_>>>()
                    .map(Value::Array),
                _ => None,
            };
            (name, read.unwrap_or_else(|| value.clone()))
        })
        .collect();
    unflatten(as_held.iter().map(|(name, value)| (*name, value)))
}

/// A stored record with every field given (each optional one, each group, each list not
/// empty): what `columns` is read off. A field added to the record fails to compile here until
/// it has a value.
///
/// Long because it is one literal setting every field of a record: a field added to the record must
/// be added here (the compiler asks), and the columns are read off it.
pub fn every_field() -> Stored {
    let record = Record {
        case: json!({"method": "nonlocal", "dim": 1, "n": 16}),
        status: Status::Ok,
        message: String::new(),
        resolved: Resolved {
            h: 1.0 / 16.0,
            eps: Some(0.25),
            m: Some(4),
            c: Some(1.0),
            dt: 1e-3,
            dt_stable: 2e-3,
            dt_positive: Some(1e-3),
            dt_stable_spectrum: Some(2e-3),
            steps: 10,
            nodes: 16,
            bonds: 128,
            pair_visits: Some(128),
            quadrature: Some(Quadrature::default()),
            collar: Some(Collar::default()),
            patch_error: Some(0.0),
            backend: Some(Backend::Stencil),
            integrator: Some(Integrator::default()),
        },
        steps_done: 10,
        operator_applications: Some(40),
        setup_s: 1e-3,
        solve_s: 1e-2,
        step_s: 1e-3,
        wall_s: Some(2e-2),
        setup_cpu_s: Some(1e-3),
        solve_cpu_s: Some(2e-2),
        solve_wait_s: Some(1e-4),
        instructions: Some(123_456_789),
        instructions_by: Some("cachegrind".into()),
        resumed_from_step: Some(4),
        solve_s_segments: Some(vec![4e-3, 6e-3]),
        error_l2: Some(1e-8),
        error_l2_norm: Some(1e-4),
        error_max: Some(2e-4),
        error_total: Some(1e-7),
        mass: Some(1.0),
        mass_drift: Some(0.0),
        max_abs: Some(1.0),
        growth: Some(0.0),
        amplification: Some(1.0),
        amplification_low: Some(0.999),
        amplification_high: Some(1.001),
        amplification_applications: Some(96),
        positivity: Some(0.0),
        diverged_step: Some(10),
        diverged_time: Some(1e-2),
        c_tot: Some(MassSeries {
            time: vec![0.0],
            c_tot: vec![1.0],
        }),
        histogram: Some(Histogram {
            lo: 0.0,
            hi: 1.0,
            counts: vec![16],
        }),
        field: Some(FieldSnapshot {
            nx: 1,
            ny: 1,
            lower: 0.0,
            upper: 1.0,
            values: vec![0.5],
            error: Some(vec![0.0]),
        }),
        distribution: Distribution {
            ranks: 2,
            partition: Partition::Block,
            px: Some(2),
            py: Some(1),
            halo_nodes: 8,
            halo_bytes: 64,
            imbalance: 1.0,
            comm_s: 1e-5,
            hosts: vec!["host".into(), "host".into()],
            cpus: vec!["0".into(), "1".into()],
            solve_cpu_s_ranks: vec![1e-2, 1e-2],
            oversubscribed: Some(false),
            traffic: Some(Traffic::default()),
        },
        steady: SteadySolve {
            iterations: Some(10),
            relative_residual: Some(1e-10),
            dual_residual: Some(1e-10),
            subdomains: Some(4),
            floating_subdomains: Some(1),
            multipliers: Some(8),
            factor_nonzeros_max: Some(64),
            feti_phases: Some(FetiPhases::default()),
        },
        implicit: ImplicitSolves {
            solve_iterations_mean: Some(5.0),
            solve_iterations_max: Some(6),
            solves_unconverged: Some(0),
            solve_rtol: Some(1e-10),
        },
        patch: Some(PatchTest {
            ghost_force: 0.0,
            ghost_force_all: 0.0,
            expected: 0.0,
            eps_min: 0.25,
            x: vec![0.5],
            l_u: vec![0.0],
            eps_x: vec![0.25],
            spectrum: Some(Spectrum {
                max_real: -1.0,
                max_imaginary: 0.0,
                max_abs: 1.0,
                dt_forward_euler: Some(2.0),
                computed: Some(1),
            }),
        }),
        coupling: Some(Coupling {
            error_nonlocal: 1e-4,
            error_local: 1e-4,
            mismatch: Some(1e-5),
            gradient: Some(1e-8),
            hessian_condition: Some(10.0),
            controls_resolved: Some(2),
            control_nodes: vec![1.0],
            controls_nonlocal: vec![0.0],
            control_local: Some(0.0),
            control_error: Some(1e-5),
            nonlocal_nodes: 16,
            local_nodes: 16,
            local_domain: [0.5, 1.0],
        }),
        peak_memory_bytes: Some(1 << 20),
        memory_estimate_bytes: Some(1 << 20),
        provenance: Provenance {
            solver_version: "0.1.0".into(),
            fingerprint: "0".repeat(64),
            git_revision: Some("0000000".into()),
            host: "host".into(),
            cpu: "cpu".into(),
            threads: 1,
            ranks: 2,
            timestamp: "2026-01-01T00:00:00Z".into(),
            instruction_set: "avx2".into(),
            dirty_tree: false,
            cores_online: 2,
            load_start: Some(Load {
                average_1min: 0.0,
                other_runnable: 0,
            }),
            load_end: Some(Load {
                average_1min: 0.0,
                other_runnable: 0,
            }),
            noisy: false,
        },
        unknown: Map::new(),
    };
    Stored {
        key: "0".repeat(32),
        case_id: Some("0".repeat(32)),
        repeat: 0,
        solver_version: "0.1.0".into(),
        run_id: Some("host-0-1".into()),
        attempt: Some(1),
        outcome: Outcome::Ran(Box::new(record)),
    }
}

/// The value of the column `name` of `record`, as its run table holds it (`None` when absent).
pub fn column(record: &Stored, name: &str) -> Option<Value> {
    let mut value = record.to_value();
    for part in name.split('.') {
        value = value.as_object_mut()?.remove(part)?;
    }
    Some(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_column_is_a_field_a_member_of_a_group_or_of_the_case() {
        assert!(is_column("error_l2_norm") && is_column("c_tot.time"));
        assert!(is_column("feti_phases.coarse_s") && is_column("case.n"));
        assert!(is_column("provenance.load_start.average_1min") && is_column("threads"));
        assert!(!is_column("c_tot.") && !is_column("error_l2norm") && !is_column("c_tot"));
        assert!(!is_column("case.") && !is_column("unknown"));
        for name in TIMINGS.iter().chain(&RESULTS).chain(NAMED) {
            assert!(is_column(name), "{name}");
        }
    }

    /// The example reads back as itself: every field it gives survives the store's round trip.
    #[test]
    fn every_field_reads_back_whole() {
        let stored = every_field();
        let again: Stored = serde_json::from_value(stored.to_value()).unwrap();
        assert_eq!(again, stored);
        assert_eq!(column(&stored, "provenance.cores_online"), Some(json!(2)));
        assert_eq!(column(&stored, "traffic.halo_bytes"), Some(json!(0)));
        assert_eq!(column(&stored, "nothing"), None);
    }

    /// A table's row of every field, its cells read back, is the stored record again.
    #[test]
    fn unflatten_undoes_flatten() {
        let value = every_field().to_value();
        let mut cells = Vec::new();
        flatten("", value.clone(), &mut |name, value| {
            cells.push((name.to_string(), value))
        });
        assert!(cells.iter().any(|(name, _)| name == "feti_phases.coarse_s"));
        cells.push(("never_recorded".into(), Value::Null));
        let back = unflatten(cells.iter().map(|(name, value)| (name.as_str(), value)));
        assert_eq!(back, value);
        let stored: Stored = serde_json::from_value(back).unwrap();
        assert_eq!(stored, every_field());
    }
}
