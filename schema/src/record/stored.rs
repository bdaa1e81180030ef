//! A record as `nlstudy` stores it: what the solver wrote, or the failure nlstudy recorded in
//! its place, with the fields nlstudy adds to tell runs apart. The store reads every record
//! through this struct, so a field renamed here fails to compile wherever the orchestrator
//! reads it, and the tables take their columns from what it serializes.

use super::provenance::Provenance;
use super::run::Record;
use super::status::Status;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::{Map, Value};

/// Read by `Stored::from_value` (see its `Deserialize`), which gives the defaults of the fields
/// a record may leave out.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stored {
    /// The hash of the case, the solver version and the repeat: the record's file name.
    pub key: String,
    /// The hash of the case alone: the repeats of a point share it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub case_id: Option<String>,
    pub repeat: usize,
    pub solver_version: String,
    /// The `nlstudy` process that ran it: the runs of one invocation share the machine's state.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run_id: Option<String>,
    /// Which attempt at the point made it (a failure outside the case is retried).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub attempt: Option<usize>,
    #[serde(flatten)]
    pub outcome: Outcome,
}

/// What became of a run.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// The solver ran the case (`ok` or `diverged`): its whole record, the case as the JSON the
    /// key was hashed from.
    Ran(Box<Record<Value>>),
    /// It did not: the solver refused the case, or crashed, or timed out (`failed`).
    Failed(Failure),
}

/// A run that produced no record: the case (as planned, when the solver refused it) and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Failure {
    pub case: Value,
    pub message: String,
}

impl Stored {
    pub fn status(&self) -> Status {
        match &self.outcome {
            Outcome::Ran(record) => record.status,
            Outcome::Failed(_) => Status::Failed,
        }
    }

    pub fn message(&self) -> &str {
        match &self.outcome {
            Outcome::Ran(record) => &record.message,
            Outcome::Failed(failure) => &failure.message,
        }
    }

    pub fn case(&self) -> &Value {
        match &self.outcome {
            Outcome::Ran(record) => &record.case,
            Outcome::Failed(failure) => &failure.case,
        }
    }

    /// The solver's record; `None` for a failed run.
    pub fn record(&self) -> Option<&Record<Value>> {
        match &self.outcome {
            Outcome::Ran(record) => Some(record),
            Outcome::Failed(_) => None,
        }
    }

    pub fn record_mut(&mut self) -> Option<&mut Record<Value>> {
        match &mut self.outcome {
            Outcome::Ran(record) => Some(record),
            Outcome::Failed(_) => None,
        }
    }

    pub fn provenance(&self) -> Option<&Provenance> {
        self.record().map(|record| &record.provenance)
    }

    /// Whether its provenance says it was timed on a busy machine.
    pub fn noisy(&self) -> bool {
        self.provenance().is_some_and(|p| p.noisy)
    }

    /// The record as JSON: what the store writes, and what the tables flatten into columns.
    pub fn to_value(&self) -> Value {
        serde_json::to_value(self).expect("a record is plain data")
    }
}

impl Serialize for Outcome {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Failed<'a> {
            case: &'a Value,
            status: Status,
            message: &'a str,
        }
        match self {
            Outcome::Ran(record) => record.serialize(serializer),
            Outcome::Failed(failure) => Failed {
                case: &failure.case,
                status: Status::Failed,
                message: &failure.message,
            }
            .serialize(serializer),
        }
    }
}

/// One reader of records: serde's reads through `Stored::from_value`.
impl<'de> Deserialize<'de> for Stored {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Stored::from_value(Value::deserialize(deserializer)?).map_err(D::Error::custom)
    }
}

impl Outcome {
    /// The outcome a record's fields (but those `Stored` reads itself) say, by its `status`: a
    /// failed run's case and message, or the solver's whole record, whose every field must be
    /// there with its type (the error names the first that is not).
    fn of_fields(mut fields: Map<String, Value>) -> Result<Outcome, String> {
        let status = fields.get("status").and_then(Value::as_str);
        match status.and_then(Status::parse) {
            None => Err("it has no known `status`".into()),
            Some(Status::Failed) => Ok(Outcome::Failed(Failure {
                case: fields.remove("case").unwrap_or(Value::Null),
                message: match fields.remove("message") {
                    Some(Value::String(message)) => message,
                    _ => String::new(),
                },
            })),
            Some(_) => {
                let fields = Value::Object(fields);
                // Read as borrowed (its texts copied once, not buffered as owned), and read
                // again to find the field that failed only when it did fail: the path kept at
                // every field was a tenth of a collect's CPU.
                let record = Record::deserialize(&fields).or_else(|_| {
                    serde_path_to_error::deserialize(fields)
                        .map_err(|e| format!("field `{}`: {}", e.path(), e.inner()))
                })?;
                Ok(Outcome::Ran(Box::new(record)))
            }
        }
    }
}

/// The fields `Stored` adds to the solver's record (which `Record` would keep among its unknown
/// ones), as `from_value` takes them.
const STORED_FIELDS: [&str; 6] = [
    "key",
    "case_id",
    "repeat",
    "solver_version",
    "run_id",
    "attempt",
];

impl Stored {
    /// A ran (`ok` or `diverged`) record from its text, read straight into the typed structs:
    /// the same `Stored` as `from_value` of the parsed text, without a tree of the whole record
    /// first (the tree and its reading were a quarter of a collect's CPU). `None` wherever it
    /// reads nothing (a failed run, a field missing or of another type, a name written twice):
    /// `from_value` then reads the record and names what is wrong.
    pub fn from_ran_text(text: &str) -> Option<Stored> {
        #[derive(Deserialize)]
        struct Added {
            key: String,
            #[serde(default)]
            case_id: Option<String>,
            #[serde(default)]
            repeat: usize,
            solver_version: String,
            #[serde(default)]
            run_id: Option<String>,
            #[serde(default)]
            attempt: Option<usize>,
        }
        let added: Added = serde_json::from_str(text).ok()?;
        let mut record: Record<Value> = serde_json::from_str(text).ok()?;
        if record.status == Status::Failed {
            return None;
        }
        for name in STORED_FIELDS {
            record.unknown.remove(name);
        }
        Some(Stored {
            key: added.key,
            case_id: added.case_id,
            repeat: added.repeat,
            solver_version: added.solver_version,
            run_id: added.run_id,
            attempt: added.attempt,
            outcome: Outcome::Ran(Box::new(record)),
        })
    }

    /// A record from its parsed JSON (what `Deserialize` does too): by hand rather than through
    /// serde's `flatten`, whose buffering made reading a record four times the cost of parsing
    /// it (a collect reads every record of a study). The error names the field.
    pub fn from_value(value: Value) -> Result<Stored, String> {
        let Value::Object(mut fields) = value else {
            return Err("not a JSON object".into());
        };
        fn take<T: serde::de::DeserializeOwned>(
            fields: &mut Map<String, Value>,
            name: &str,
            missing: Option<T>,
        ) -> Result<T, String> {
            match (fields.remove(name), missing) {
                (Some(value), _) => {
                    serde_json::from_value(value).map_err(|e| format!("field `{name}`: {e}"))
                }
                (None, Some(default)) => Ok(default),
                (None, None) => Err(format!("missing field `{name}`")),
            }
        }
        Ok(Stored {
            key: take(&mut fields, "key", None)?,
            case_id: take(&mut fields, "case_id", Some(None))?,
            repeat: take(&mut fields, "repeat", Some(0))?,
            solver_version: take(&mut fields, "solver_version", None)?,
            run_id: take(&mut fields, "run_id", Some(None))?,
            attempt: take(&mut fields, "attempt", Some(None))?,
            outcome: Outcome::of_fields(fields)?,
        })
    }
}
