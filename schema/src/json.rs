//! JSON as people write it, read strictly: a key given twice in one object is an error naming
//! the key, where serde_json keeps the last silently (`{"dim": 2, …, "dim": 1}` would run 1D).
//! The same reader takes TOML (through `from_deserializer`), whose `nan` and `inf` would become
//! `null`, "not given", in a `Value`: a number that is not finite is refused where it stands,
//! and so is a TOML date or time, which has no place in a case or a study.

use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};

use serde_json::{Map, Value};
use std::fmt;

/// Parses `text` as one JSON value, refusing duplicate keys. A byte-order mark at the start is
/// refused by name (serde_json would say only "expected value at line 1 column 1").
pub fn parse(text: &str) -> Result<Value, serde_json::Error> {
    if text.starts_with('\u{feff}') {
        return Err(de::Error::custom(
            "the file starts with a byte-order mark (U+FEFF); save it as UTF-8 without BOM",
        ));
    }
    serde_json::from_str::<Strict>(text).map(|strict| strict.0)
}

/// Whether `c` may not stand in a name or value that reaches a file name, a job script or a
/// terminal: a control character (a newline, an escape, a NUL) or a bidirectional control
/// (U+202A–U+202E, U+2066–U+2069, U+200E, U+200F, U+061C), which reorders what a terminal or a
/// browser shows (`\u{202e}gnp.exe` displays as "exe.png").
pub fn is_unsafe_char(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
        || matches!(c, '\u{200E}' | '\u{200F}' | '\u{061C}')
}

/// A character `is_unsafe_char` refuses, named for a message: `'\n'`, or `U+202E (a
/// bidirectional control)`.
pub fn describe_char(c: char) -> String {
    match c.is_control() {
        true => format!("the control character {c:?}"),
        false => format!("the bidirectional control U+{:04X}", u32::from(c)),
    }
}

/// The first character `is_unsafe_char` refuses in a key or a string of `value` (a newline, an
/// escape, a NUL, a bidirectional control),
/// with the path of where it stands (`resources.queue`, `sweep[1].zip.kernel[0]`), leaving out
/// the strings under the paths `prose` allows (free text may hold newlines and tabs). Names and
/// fields reach file names, job scripts and terminals, where such characters do harm.
pub fn control_character(value: &Value, prose: &[&str]) -> Option<(String, char)> {
    fn walk(value: &Value, path: &str, prose: &[&str]) -> Option<(String, char)> {
        let bad = |text: &str| {
            let layout = prose.contains(&path);
            text.chars()
                .find(|&c| is_unsafe_char(c) && !(layout && matches!(c, '\n' | '\t')))
        };
        match value {
            Value::String(text) => bad(text).map(|c| (path.to_string(), c)),
            Value::Array(items) => items
                .iter()
                .enumerate()
                .find_map(|(k, item)| walk(item, &format!("{path}[{k}]"), prose)),
            Value::Object(object) => object.iter().find_map(|(key, item)| {
                // The path is printed: a key's own control characters appear escaped in it.
                let printed = key.escape_debug();
                let inner = match path {
                    "" => printed.to_string(),
                    _ => format!("{path}.{printed}"),
                };
                match key.chars().find(|&c| is_unsafe_char(c)) {
                    Some(c) => Some((inner, c)),
                    None => walk(item, &inner, prose),
                }
            }),
            _ => None,
        }
    }
    walk(value, "", prose)
}

/// A value read as `parse` reads JSON, from any self-describing deserializer (the study files'
/// TOML: `serde_path_to_error::deserialize::<_, Strict>`): a key given twice, a number that is
/// not finite (TOML's `nan`, `inf`, which a `Value` would hold as `null`, "not given") and a
/// TOML date or time are refused.
pub struct Strict(pub Value);

impl<'de> Deserialize<'de> for Strict {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_any(StrictVisitor).map(Strict)
    }
}

struct StrictVisitor;

impl<'de> Visitor<'de> for StrictVisitor {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E>(self, b: bool) -> Result<Value, E> {
        Ok(Value::Bool(b))
    }

    fn visit_i64<E>(self, x: i64) -> Result<Value, E> {
        Ok(Value::from(x))
    }

    fn visit_u64<E>(self, x: u64) -> Result<Value, E> {
        Ok(Value::from(x))
    }

    fn visit_f64<E: de::Error>(self, x: f64) -> Result<Value, E> {
        match x.is_finite() {
            true => Ok(Value::from(x)),
            false => Err(E::custom(format!(
                "{x} is not a finite number; write a number"
            ))),
        }
    }

    fn visit_str<E>(self, s: &str) -> Result<Value, E> {
        Ok(Value::from(s))
    }

    fn visit_string<E>(self, s: String) -> Result<Value, E> {
        Ok(Value::String(s))
    }

    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut items = Vec::new();
        while let Some(Strict(item)) = seq.next_element()? {
            items.push(item);
        }
        Ok(Value::Array(items))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut object = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            // How the toml crate hands over a date or a time.
            if key == "$__toml_private_datetime" {
                let Strict(value) = map.next_value()?;
                return Err(de::Error::custom(format!(
                    "{value} is a TOML date or time; quote it if it is text, or write a number"
                )));
            }
            if object.contains_key(&key) {
                return Err(de::Error::custom(format!(
                    "the key `{key}` is given twice in one object; keep one"
                )));
            }
            let Strict(value) = map.next_value()?;
            object.insert(key, value);
        }
        Ok(Value::Object(object))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_given_twice_is_named_and_values_read_as_serde_json_reads_them() {
        let error = parse(r#"{"dim": 2, "n": 8, "dim": 1}"#)
            .unwrap_err()
            .to_string();
        assert!(error.contains("the key `dim` is given twice"), "{error}");
        let nested = parse(r#"{"base": {"m": 1, "m": 2}}"#)
            .unwrap_err()
            .to_string();
        assert!(nested.contains("`m`"), "{nested}");
        let text =
            r#"{"a": [1, -2, 0.1, 1e-300, "s", null, true, {"b": {}}], "c": 18446744073709551615}"#;
        assert_eq!(
            parse(text).unwrap(),
            serde_json::from_str::<Value>(text).unwrap()
        );
        assert!(parse("{\"a\": 1} trailing").is_err());
    }

    #[test]
    fn a_control_character_is_found_with_its_path_wherever_it_stands() {
        let value = serde_json::json!({
            "description": "two\nlines\tand a tab",
            "sweep": [{"zip": {"kernel": ["constant", "linear\u{1b}[2J"]}}],
        });
        assert_eq!(
            control_character(&value, &["description"]),
            Some(("sweep[0].zip.kernel[1]".to_string(), '\u{1b}'))
        );
        assert_eq!(
            control_character(&value, &[]),
            Some(("description".to_string(), '\n'))
        );
        let key = serde_json::json!({"base": {"n\r": 1}});
        assert_eq!(
            control_character(&key, &[]),
            Some(("base.n\\r".to_string(), '\r'))
        );
        assert_eq!(
            control_character(&serde_json::json!({"a": ["b", 1]}), &[]),
            None
        );
        // A bidirectional control shows "exe.png" for "\u{202e}gnp.exe": refused, even in prose.
        for c in [
            '\u{202a}', '\u{202e}', '\u{2066}', '\u{2069}', '\u{200f}', '\u{061c}',
        ] {
            let value = serde_json::json!({"figures": [{"title": format!("{c}gnp.exe")}]});
            assert_eq!(
                control_character(&value, &["figures[0].title"]),
                Some(("figures[0].title".to_string(), c))
            );
            assert!(describe_char(c).contains("bidirectional control U+"));
        }
        assert!(!is_unsafe_char('é') && !is_unsafe_char('ε'));
    }

    #[test]
    fn a_number_that_is_not_finite_a_date_and_a_bom_are_refused() {
        let error = parse("\u{feff}{}").unwrap_err().to_string();
        assert!(error.contains("byte-order mark"), "{error}");
        // JSON itself has no NaN: serde_json refuses it before the visitor sees a number.
        assert!(parse(r#"{"dt": NaN}"#).is_err());
        assert!(parse("[1e400]").is_err(), "an overflow is no number");
        let visit = |x: f64| StrictVisitor.visit_f64::<serde_json::Error>(x);
        assert!(visit(f64::NAN)
            .unwrap_err()
            .to_string()
            .contains("not a finite number"));
        assert!(visit(f64::NEG_INFINITY).is_err());
        assert_eq!(visit(0.5).unwrap(), serde_json::json!(0.5));
    }
}
