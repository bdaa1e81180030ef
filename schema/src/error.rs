//! Bad input, in one shape for a case and a study file: the field (or place) at fault and one
//! sentence saying what is wrong and how to fix it; and what serde knows of a struct's fields.

use serde::de::{self, Deserialize, Deserializer, Visitor};
use std::fmt;
use std::marker::PhantomData;

/// What a `FieldError` is about, as its message begins: "case field `n`: …", "study `sweep`: …".
pub trait Subject {
    const NAME: &'static str;
}

/// The field or place at fault and one sentence.
pub struct FieldError<S: Subject> {
    pub field: String,
    pub message: String,
    subject: PhantomData<S>,
}

impl<S: Subject> FieldError<S> {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            message: message.into(),
            subject: PhantomData,
        }
    }

    /// A refusal by serde (through `serde_path_to_error`): at `path`, saying `message`. serde
    /// reports an unknown or missing field at its parent; the error names the field itself.
    /// A misspelt name gets the nearest of the names serde expected (`did you mean `kernel`?`).
    pub fn from_serde(path: String, message: String) -> Self {
        let field = match field_named_in(&message) {
            None => path,
            Some(field) if path == "." || path.is_empty() => field,
            Some(field) if path.ends_with(&field) => path,
            Some(field) => format!("{path}.{field}"),
        };
        let message = match suggestion(&message) {
            Some(name) => with_suggestion(&message, &name),
            None => message,
        };
        FieldError::new(field, message)
    }
}

impl<S: Subject> Clone for FieldError<S> {
    fn clone(&self) -> Self {
        FieldError::new(self.field.clone(), self.message.clone())
    }
}

impl<S: Subject> PartialEq for FieldError<S> {
    fn eq(&self, other: &Self) -> bool {
        (&self.field, &self.message) == (&other.field, &other.message)
    }
}

impl<S: Subject> fmt::Debug for FieldError<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct(S::NAME)
            .field("field", &self.field)
            .field("message", &self.message)
            .finish()
    }
}

impl<S: Subject> fmt::Display for FieldError<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} `{}`: {}", S::NAME, self.field, self.message)
    }
}

impl<S: Subject> std::error::Error for FieldError<S> {}

/// The field a serde message like "unknown field `x`, expected …" or "missing field `x`" names.
fn field_named_in(message: &str) -> Option<String> {
    ["unknown field `", "missing field `"]
        .iter()
        .find_map(|prefix| {
            let rest = message.strip_prefix(prefix)?;
            Some(rest[..rest.find('`')?].to_string())
        })
}

/// The name a serde refusal ("unknown field `kernal`, expected one of `dim`, `kernel`, …",
/// "unknown variant `rk5`, expected `a` or `b`") most likely meant: the expected name nearest to
/// the given one, if it is near enough to be a misspelling rather than another word.
pub fn suggestion(message: &str) -> Option<String> {
    let rest = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|prefix| message.strip_prefix(prefix))?;
    let given = &rest[..rest.find('`')?];
    let expected = &rest[rest.find("expected")?..];
    // A hint may follow the list (`; see `nlsolve run --help``).
    let expected = expected.split(';').next().unwrap_or_default();
    let candidates = expected.split('`').skip(1).step_by(2);
    nearest(given, candidates)
}

/// "unknown field `kernal`, expected one of … ; see …" as "unknown field `kernal`; did you mean
/// `kernel`?; see …": the guess replaces the list of every name, which it makes noise.
fn with_suggestion(message: &str, name: &str) -> String {
    let Some(list) = message.find(", expected") else {
        return format!("{message}; did you mean `{name}`?");
    };
    let hint = message[list..]
        .find(';')
        .map_or("", |k| &message[list + k..]);
    format!("{}; did you mean `{name}`?{hint}", &message[..list])
}

/// The candidate nearest to `given` by Jaro–Winkler similarity, if above 0.8 (a typo or two).
pub fn nearest<'a>(given: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    candidates
        .into_iter()
        .map(|c| (strsim::jaro_winkler(given, c), c))
        .filter(|(similarity, _)| *similarity > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c)| c.to_string())
}

/// The fields of struct `T` in declaration order, as its derived `Deserialize` hands them to the
/// deserializer: from the type itself, so the list cannot drift from the struct.
pub fn field_names<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    names_of::<T>()
}

/// The variants of enum `T` as serde names them (`forward_euler`): from the type itself.
pub fn variant_names<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    names_of::<T>()
}

fn names_of<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    let mut names = Names(&[]);
    let _ = T::deserialize(&mut names);
    names.0
}

/// A deserializer that only listens: it keeps the names `deserialize_struct` (the fields) or
/// `deserialize_enum` (the variants) is given.
struct Names(&'static [&'static str]);

impl<'de> Deserializer<'de> for &mut Names {
    type Error = de::value::Error;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Self::Error> {
        Err(de::Error::custom("not a struct or an enum"))
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Self::Error> {
        self.0 = fields;
        Err(de::Error::custom("only the field names were asked"))
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        variants: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, Self::Error> {
        self.0 = variants;
        Err(de::Error::custom("only the variant names were asked"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map identifier
        ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Thing;
    impl Subject for Thing {
        const NAME: &'static str = "thing";
    }

    #[test]
    fn serde_refusals_name_the_field_itself() {
        let at = |path: &str, message: &str| {
            FieldError::<Thing>::from_serde(path.into(), message.into()).field
        };
        assert_eq!(
            at(".", "unknown field `kernal`, expected one of …"),
            "kernal"
        );
        assert_eq!(at("resources", "missing field `x`"), "resources.x");
        assert_eq!(
            at("base.n", "invalid type: string, expected usize"),
            "base.n"
        );
        let e = FieldError::<Thing>::new("n", "must be at least 1");
        assert_eq!(e.to_string(), "thing `n`: must be at least 1");
    }

    #[test]
    fn a_misspelt_name_is_met_with_the_nearest_expected_one() {
        let e = FieldError::<Thing>::from_serde(
            ".".into(),
            "unknown field `kernal`, expected one of `method`, `dim`, `kernel`, `n`".into(),
        );
        assert_eq!(e.field, "kernal");
        assert_eq!(e.message, "unknown field `kernal`; did you mean `kernel`?");
        let hinted = FieldError::<Thing>::from_serde(
            ".".into(),
            "unknown field `kernal`, expected `kernel` or `n`; see `nlsolve run --help`".into(),
        );
        assert_eq!(
            hinted.message,
            "unknown field `kernal`; did you mean `kernel`?; see `nlsolve run --help`"
        );
        let variant = "unknown variant `forward_eulr`, expected one of `forward_euler`, `heun`";
        assert_eq!(suggestion(variant).as_deref(), Some("forward_euler"));
        assert_eq!(
            suggestion("unknown variant `rk5`, expected `rk4` or `heun`").as_deref(),
            Some("rk4")
        );
        // Another word altogether gets no guess.
        assert_eq!(
            suggestion("unknown field `colour`, expected `n` or `dim`"),
            None
        );
        assert_eq!(suggestion("invalid type: string, expected usize"), None);
    }

    #[test]
    fn field_names_come_from_the_type() {
        #[derive(serde::Deserialize)]
        #[allow(dead_code)]
        struct Two {
            first: u8,
            #[serde(rename = "second_renamed")]
            second: u8,
        }
        assert_eq!(field_names::<Two>(), ["first", "second_renamed"]);
        assert_eq!(
            variant_names::<crate::choices::Integrator>(),
            [
                "forward_euler",
                "heun",
                "rk4",
                "backward_euler",
                "crank_nicolson"
            ]
        );
    }
}
