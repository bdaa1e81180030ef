//! The case a command line gives: a case file's fields with the flags on top. The flags are
//! `schema::Case`'s fields (it derives clap's `Args`), declared and documented there.

use crate::BadInput;
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, FromArgMatches};
use serde_json::{Map, Value};
use solver::case::Case;
use solver::ValidCase;
use std::io::Read;
use std::path::PathBuf;

/// Each flag sets the case field of the same name (dashes become underscores); see docs/guide/solver.md.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub(crate) struct CaseArgs {
    /// Case file in JSON (`-` for standard input); flags given too override its fields.
    #[arg(long, value_name = "FILE")]
    case: Option<PathBuf>,
    #[command(flatten)]
    flags: CaseFlags,
}

/// The case fields the command line sets, as JSON: only the flags given. A field given at its
/// default and left out of the case's JSON by serde (`--quadrature midpoint`) is `null`: it
/// takes the default, whatever a case file says.
pub(crate) struct CaseFlags(Map<String, Value>);

impl Args for CaseFlags {
    fn augment_args(command: clap::Command) -> clap::Command {
        Case::augment_args(command)
    }

    fn augment_args_for_update(command: clap::Command) -> clap::Command {
        Case::augment_args_for_update(command)
    }
}

impl FromArgMatches for CaseFlags {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        // Clap sets the fields given on a case whose other fields are anything valid.
        let mut case = Case::parse(serde_json::json!({"dim": 1, "n": 1}))
            .expect("a case of two fields parses");
        case.update_from_arg_matches(matches)?;
        let Ok(Value::Object(mut set)) = serde_json::to_value(&case) else {
            unreachable!("a case serializes to an object")
        };
        let given = Case::field_names()
            .iter()
            .filter(|field| matches.value_source(field) == Some(ValueSource::CommandLine))
            .map(|field| (field.to_string(), set.remove(*field).unwrap_or(Value::Null)));
        Ok(CaseFlags(given.collect()))
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = CaseFlags::from_arg_matches(matches)?;
        Ok(())
    }
}

impl CaseArgs {
    /// The case: the file's fields (if any) with the flags' fields set on top.
    pub(crate) fn case(&self) -> Result<ValidCase, BadInput> {
        ValidCase::from_json(Value::Object(self.fields()?)).map_err(|e| BadInput(e.to_string()))
    }

    /// The case's fields as JSON, before they are checked.
    pub(crate) fn fields(&self) -> Result<Map<String, Value>, BadInput> {
        let mut fields = match &self.case {
            Some(path) => read_case_file(path)?,
            None => Map::new(),
        };
        for (field, value) in &self.flags.0 {
            match value {
                Value::Null => fields.remove(field),
                value => fields.insert(field.clone(), value.clone()),
            };
        }
        Ok(fields)
    }
}

pub(crate) fn read_case_file(path: &PathBuf) -> Result<Map<String, Value>, BadInput> {
    let name = path.display();
    let text = if path.as_os_str() == "-" {
        let mut text = String::new();
        std::io::stdin()
            .read_to_string(&mut text)
            .map_err(|e| BadInput(format!("cannot read the case from standard input: {e}")))?;
        text
    } else {
        std::fs::read_to_string(path).map_err(|e| {
            BadInput(format!(
                "cannot read case file {name}: {e}; check the path given to --case"
            ))
        })?
    };
    match schema::json::parse(&text) {
        Ok(Value::Object(fields)) => Ok(fields),
        Ok(_) => Err(BadInput(format!(
            "case file {name} must hold one JSON object of case fields"
        ))),
        Err(e) => Err(BadInput(format!("case file {name} is not valid JSON: {e}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{usage_error, Cli, Command};
    use clap::Parser;

    /// No flag takes a number that is not finite (or any value a case refuses): `nan`, `inf`
    /// and `-inf` are refused by every flag that takes a value, the number flags saying "not a
    /// finite number".
    #[test]
    fn no_flag_takes_a_number_that_is_not_finite() {
        let command = Case::augment_args(clap::Command::new("nlsolve"));
        let mut numbers = 0;
        for arg in command.get_arguments() {
            if !arg.get_action().takes_values() {
                continue;
            }
            let flag = format!("--{}", arg.get_long().expect("a long flag"));
            // `--flag=value`, so that `-inf` is a value, not a flag.
            let given = |value: &str| format!("{flag}={value}");
            let parses =
                |value: &str| Cli::try_parse_from(["nlsolve", "run", &given(value)]).is_ok();
            let takes_a_fraction = (parses("0.5") || parses("0.5,0.5")) && !parses("x");
            for value in ["nan", "NaN", "inf", "-inf", "infinity", "1e400"] {
                let refusal = match Cli::try_parse_from(["nlsolve", "run", &given(value)]) {
                    Err(e) => e.to_string(),
                    Ok(cli) => {
                        let Command::Run(args) = cli.command else {
                            panic!("a run")
                        };
                        match args.case.case() {
                            Err(BadInput(message)) => message,
                            Ok(_) => panic!("{flag} {value} was accepted"),
                        }
                    }
                };
                if takes_a_fraction {
                    assert!(
                        refusal.contains("not a finite number"),
                        "{flag} {value}: {refusal}"
                    );
                }
            }
            numbers += usize::from(takes_a_fraction);
        }
        assert!(numbers >= 10, "the f64 flags were found: {numbers}");
    }

    /// A misspelt flag is one line of bad input that still carries clap's suggestion.
    #[test]
    fn a_misspelt_flag_is_refused_with_the_flag_it_resembles() {
        let error = Cli::try_parse_from(["nlsolve", "run", "--integrater", "rk4"])
            .err()
            .expect("an unknown flag");
        let line = usage_error(&error.to_string());
        assert!(!line.contains('\n'), "{line}");
        assert!(
            line.starts_with("unexpected argument '--integrater' found")
                && line.contains("similar argument exists: '--integrator'"),
            "{line}"
        );
    }

    /// The flags given, and only those, become the case's fields, with their JSON types.
    #[test]
    fn the_flags_given_are_the_fields_they_set() {
        let demo = concat!(env!("CARGO_MANIFEST_DIR"), "/../cases/demo.json");
        let cli = Cli::try_parse_from([
            "nlsolve",
            "run",
            "--case",
            demo,
            "--n",
            "8",
            "--kernel",
            "constant",
            "--eps",
            "0.25",
            "--error-total",
            "--horizon-profile",
            r#"{"kind": "linear", "left": 0.1, "right": 0.2}"#,
            "--local-domain",
            "-0.5,1",
            "--integrator",
            "rk4",
            "--quadrature",
            "midpoint",
        ])
        .unwrap();
        let Command::Run(args) = cli.command else {
            panic!("a run")
        };
        // The quadrature given at its default is null: whatever a file says, it is the default.
        assert_eq!(
            Value::Object(args.case.flags.0.clone()),
            serde_json::json!({"n": 8, "eps": 0.25, "kernel": "constant", "error_total": true,
                "integrator": "rk4", "quadrature": null, "local_domain": [-0.5, 1.0],
                "horizon_profile": {"kind": "linear", "left": 0.1, "right": 0.2}})
        );
        let fields = args.case.fields().ok().unwrap();
        assert_eq!(
            Value::Object(fields),
            serde_json::json!({"dim": 2, "n": 8, "m": 4, "eps": 0.25, "kernel": "constant",
                "problem": "manufactured", "source": "continuum", "t_end": 0.1, "cfl": 0.5,
                "threads": 2, "error_total": true, "integrator": "rk4",
                "local_domain": [-0.5, 1.0],
                "horizon_profile": {"kind": "linear", "left": 0.1, "right": 0.2}})
        );
        let at_default = CaseArgs {
            case: Some(demo.into()),
            flags: CaseFlags(
                serde_json::json!({"kernel": null})
                    .as_object()
                    .unwrap()
                    .clone(),
            ),
        };
        assert!(!at_default.fields().ok().unwrap().contains_key("kernel"));
        let refusal = Cli::try_parse_from(["nlsolve", "run", "--horizon-profile", "{"])
            .err()
            .unwrap()
            .to_string();
        assert!(
            refusal.contains("--horizon-profile") && refusal.contains("not valid JSON"),
            "{refusal}"
        );
    }
}
