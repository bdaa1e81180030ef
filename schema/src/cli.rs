//! The case's fields as command-line flags (feature `cli`): `Case` derives clap's `Args`, so a
//! field is declared and documented once, in `case.rs`, and `nlsolve --help` shows that text.
//! Here is how a flag's text becomes a field's value: a choice takes the names serde gives its
//! variants (clap lists them and suggests the nearest), a number must be finite, the horizon
//! profile is JSON.

use crate::choices::*;
use crate::error::variant_names;
use clap::builder::{MapValueParser, PossibleValuesParser, TypedValueParser, ValueParserFactory};
use serde::de::{value::StrDeserializer, DeserializeOwned};

/// One of enum `T`'s variants by its serde name (`forward_euler`).
pub type Choice<T> = MapValueParser<PossibleValuesParser, fn(String) -> T>;

pub fn choice<T: DeserializeOwned + Clone + Send + Sync + 'static>() -> Choice<T> {
    PossibleValuesParser::new(variant_names::<T>()).map(|name: String| {
        T::deserialize(StrDeserializer::<serde::de::value::Error>::new(&name))
            .expect("a variant's own name names it")
    })
}

/// The choices' flags parse by their serde names (clap's derive finds the parser here).
macro_rules! choices {
    ($($choice:ty),*) => {$(
        impl ValueParserFactory for $choice {
            type Parser = Choice<$choice>;
            fn value_parser() -> Self::Parser {
                choice()
            }
        }
    )*};
}

choices!(
    Method,
    Kernel,
    Quadrature,
    Backend,
    Problem,
    Collar,
    SourceMode,
    Integrator,
    Partition,
    FetiPreconditioner,
    Krylov,
    Formulation,
    PatchField,
    CouplingKind
);

impl ValueParserFactory for HorizonProfile {
    type Parser = fn(&str) -> Result<HorizonProfile, String>;
    fn value_parser() -> Self::Parser {
        json::<HorizonProfile>
    }
}

/// A number flag's value: a finite f64. JSON has no NaN or infinity: serde_json would write one
/// as `null`, which the case reads as a field not given (`--diffusivity nan` would run with
/// the default), so it is refused here, by clap, naming the flag.
pub fn finite_number(text: &str) -> Result<f64, String> {
    let x: f64 = text.trim().parse().map_err(|e| format!("{e}"))?;
    match x.is_finite() {
        true => Ok(x),
        false => Err("not a finite number".into()),
    }
}

/// Two finite numbers `a,b` (an interval).
pub fn pair(text: &str) -> Result<[f64; 2], String> {
    match text
        .split(',')
        .map(finite_number)
        .collect::<Result<Vec<_>, _>>()?[..]
    {
        [a, b] => Ok([a, b]),
        _ => Err("two numbers are wanted, as a,b".into()),
    }
}

/// A value given as JSON text (`--horizon-profile '{"kind": "constant"}'`).
pub fn json<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    let value = crate::json::parse(text).map_err(|e| format!("not valid JSON: {e}"))?;
    serde_json::from_value(value).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_choice_is_a_variant_by_its_serde_name() {
        let command = clap::Command::new("t").arg(
            clap::Arg::new("kernel")
                .long("kernel")
                .value_parser(clap::value_parser!(Kernel)),
        );
        let given = |value: &str| {
            command
                .clone()
                .try_get_matches_from(["t", "--kernel", value])
        };
        let matches = given("inverse_distance").unwrap();
        assert_eq!(
            matches.get_one::<Kernel>("kernel"),
            Some(&Kernel::InverseDistance)
        );
        let refusal = given("gausian").unwrap_err().to_string();
        assert!(
            refusal.contains("possible values") && refusal.contains("'gaussian'"),
            "{refusal}"
        );
    }

    #[test]
    fn numbers_are_finite_and_a_pair_is_two() {
        assert_eq!(finite_number(" 0.25"), Ok(0.25));
        for bad in ["nan", "inf", "-inf", "1e400", "x"] {
            assert!(finite_number(bad).is_err(), "{bad}");
        }
        assert_eq!(pair("-0.5,1"), Ok([-0.5, 1.0]));
        for bad in ["1", "1,2,3", "1,nan"] {
            assert!(pair(bad).is_err(), "{bad}");
        }
        assert_eq!(
            json::<HorizonProfile>(r#"{"kind": "constant"}"#),
            Ok(HorizonProfile::Constant)
        );
        assert!(json::<HorizonProfile>("{")
            .unwrap_err()
            .contains("not valid JSON"));
    }
}
