//! A record's leaves straight from its typed fields: what `flatten` of its JSON tree gives,
//! without building the tree (a collect flattens every record of a study, and making the tree
//! again from the typed record and walking it was a sixth of its CPU). Serde writes the leaves
//! in the order of the record's fields; `tree_order` gives the tree's.

use serde::ser::{self, Impossible, Serialize, Serializer};
use serde_json::Value;
use std::fmt;

/// Gives `each` the leaves of `value` that `flatten("", to_value(value))` gives, in the order
/// serde writes them, each name's parts joined by `\0`. A top-level field named in `whole` is
/// one leaf, null in place of its value: the caller has it typed (a record's case), and copying
/// it here would cost what the tree did. `None` where a leaf might differ, for the caller to
/// flatten the tree instead: a value that is not an object of named fields, a name that is
/// empty or holds a `\0`, a top-level name that holds a `.` (its leaves could not be told from
/// a group's), an enum variant that carries data. (A name given twice is found by
/// `tree_order`.)
pub fn each_leaf<T: Serialize + ?Sized>(
    value: &T,
    whole: &[&str],
    each: &mut dyn FnMut(&str, Value),
) -> Option<()> {
    let mut collector = Collector {
        name: String::new(),
        depth: 0,
        whole,
        each,
    };
    value.serialize(&mut collector).ok()
}

/// The order of the leaves named `names` (as `each_leaf` spells them) in the tree: its sorted
/// names, a group's fields together, part by part. `None` where two names clash: one given
/// twice, or a leaf of a name another's group has.
pub fn tree_order(names: &[&str]) -> Option<Vec<usize>> {
    // `\0` sorts below every byte a name holds: sorting the texts sorts the tree's way.
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_unstable_by(|&a, &b| names[a].cmp(names[b]));
    let clash = |(&a, &b): (&usize, &usize)| {
        (names[b].strip_prefix(names[a]))
            .is_some_and(|rest| rest.is_empty() || rest.starts_with('\0'))
    };
    match order.iter().zip(order.iter().skip(1)).any(clash) {
        true => None,
        false => Some(order),
    }
}

/// A leaf's name as the tables spell it (`group.field`) from `each_leaf`'s.
pub fn dotted(name: &str) -> String {
    name.replace('\0', ".")
}

/// Where the two readings might differ: `each_leaf` gives up.
#[derive(Debug)]
struct GiveUp;

impl fmt::Display for GiveUp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("not flattened field by field")
    }
}

impl std::error::Error for GiveUp {}

impl ser::Error for GiveUp {
    fn custom<M: fmt::Display>(_: M) -> Self {
        GiveUp
    }
}

struct Collector<'w> {
    /// The name of the field being written, its parts joined by `\0`.
    name: String,
    /// How many parts `name` has.
    depth: usize,
    whole: &'w [&'w str],
    each: &'w mut dyn FnMut(&str, Value),
}

impl Collector<'_> {
    fn leaf(&mut self, value: Value) -> Result<(), GiveUp> {
        match self.depth {
            0 => Err(GiveUp),
            _ => {
                (self.each)(&self.name, value);
                Ok(())
            }
        }
    }

    /// Writes `value` as the field `part` of the group being written.
    fn field<T: Serialize + ?Sized>(&mut self, part: &str, value: &T) -> Result<(), GiveUp> {
        let dotted = self.depth == 0 && part.contains('.');
        if part.is_empty() || part.contains('\0') || dotted {
            return Err(GiveUp);
        }
        let length = self.name.len();
        if self.depth > 0 {
            self.name.push('\0');
        }
        self.name.push_str(part);
        self.depth += 1;
        let written = match self.depth == 1 && self.whole.contains(&part) {
            true => self.leaf(Value::Null),
            false => value.serialize(&mut *self),
        };
        self.depth -= 1;
        self.name.truncate(length);
        written
    }
}

/// A leaf's value as `to_value` makes it.
fn json<T: Serialize>(value: T) -> Result<Value, GiveUp> {
    serde_json::to_value(value).map_err(|_| GiveUp)
}

/// The serializer's methods for scalars, each one leaf, its value made by `$make`
/// (`Value::from` where that is what `to_value` gives, else `json`).
macro_rules! leaves {
    ($make:expr; $($method:ident: $kind:ty),*) => {$(
        fn $method(self, v: $kind) -> Result<(), GiveUp> {
            let value: Result<Value, GiveUp> = ($make)(v);
            self.leaf(value?)
        }
    )*};
}

impl<'a, 'w> Serializer for &'a mut Collector<'w> {
    type Ok = ();
    type Error = GiveUp;
    type SerializeSeq = Items<'a, 'w>;
    type SerializeTuple = Items<'a, 'w>;
    type SerializeTupleStruct = Items<'a, 'w>;
    type SerializeTupleVariant = Impossible<(), GiveUp>;
    type SerializeMap = Group<'a, 'w>;
    type SerializeStruct = Group<'a, 'w>;
    type SerializeStructVariant = Impossible<(), GiveUp>;

    leaves!(|v| Ok(Value::from(v));
        serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32,
        serialize_i64: i64, serialize_u8: u8, serialize_u16: u16, serialize_u32: u32,
        serialize_u64: u64, serialize_f64: f64);
    leaves!(json;
        serialize_i128: i128, serialize_u128: u128, serialize_f32: f32, serialize_char: char);
    fn serialize_str(self, v: &str) -> Result<(), GiveUp> {
        self.leaf(Value::String(v.to_string()))
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<(), GiveUp> {
        self.leaf(json(v)?)
    }
    fn serialize_none(self) -> Result<(), GiveUp> {
        self.leaf(Value::Null)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<(), GiveUp> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<(), GiveUp> {
        self.leaf(Value::Null)
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<(), GiveUp> {
        self.leaf(Value::Null)
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<(), GiveUp> {
        self.leaf(Value::String(variant.to_string()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        value: &T,
    ) -> Result<(), GiveUp> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<(), GiveUp> {
        Err(GiveUp)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Items<'a, 'w>, GiveUp> {
        Ok(Items {
            collector: self,
            items: Vec::with_capacity(len.unwrap_or(0)),
        })
    }
    fn serialize_tuple(self, len: usize) -> Result<Items<'a, 'w>, GiveUp> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(self, _: &'static str, len: usize) -> Result<Items<'a, 'w>, GiveUp> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, GiveUp> {
        Err(GiveUp)
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Group<'a, 'w>, GiveUp> {
        Ok(Group {
            collector: self,
            key: None,
        })
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Group<'a, 'w>, GiveUp> {
        self.serialize_map(None)
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, GiveUp> {
        Err(GiveUp)
    }
}

/// A list: one leaf, its items as `to_value` makes them.
struct Items<'a, 'w> {
    collector: &'a mut Collector<'w>,
    items: Vec<Value>,
}

impl Items<'_, '_> {
    fn push<T: Serialize + ?Sized>(&mut self, item: &T) -> Result<(), GiveUp> {
        self.items.push(json(item)?);
        Ok(())
    }

    fn done(self) -> Result<(), GiveUp> {
        self.collector.leaf(Value::Array(self.items))
    }
}

/// The three kinds of list serde writes, each one leaf.
macro_rules! items {
    ($($kind:ident :: $item:ident),*) => {$(
        impl ser::$kind for Items<'_, '_> {
            type Ok = ();
            type Error = GiveUp;
            fn $item<T: Serialize + ?Sized>(&mut self, item: &T) -> Result<(), GiveUp> {
                self.push(item)
            }
            fn end(self) -> Result<(), GiveUp> {
                self.done()
            }
        }
    )*};
}

items!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field
);

/// A group of named fields (a struct, or a map whose keys are texts): each field written under
/// its name; an empty group leaves no leaf, as `flatten` of an empty object.
struct Group<'a, 'w> {
    collector: &'a mut Collector<'w>,
    /// The key given, its value to come.
    key: Option<String>,
}

impl ser::SerializeMap for Group<'_, '_> {
    type Ok = ();
    type Error = GiveUp;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), GiveUp> {
        match json(key)? {
            Value::String(key) => {
                self.key = Some(key);
                Ok(())
            }
            _ => Err(GiveUp),
        }
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), GiveUp> {
        let key = self.key.take().ok_or(GiveUp)?;
        self.collector.field(&key, value)
    }
    fn end(self) -> Result<(), GiveUp> {
        Ok(())
    }
}

impl ser::SerializeStruct for Group<'_, '_> {
    type Ok = ();
    type Error = GiveUp;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        name: &'static str,
        value: &T,
    ) -> Result<(), GiveUp> {
        self.collector.field(name, value)
    }
    fn end(self) -> Result<(), GiveUp> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{every_field, flatten};
    use super::*;
    use serde_json::json;

    /// The leaves of `value` in the tree's order, dotted: as a reader of `each_leaf` puts them.
    fn leaves<T: Serialize + ?Sized>(value: &T, whole: &[&str]) -> Option<Vec<(String, Value)>> {
        let mut written = Vec::new();
        each_leaf(value, whole, &mut |name, value| {
            written.push((name.to_string(), value))
        })?;
        let names: Vec<&str> = written.iter().map(|(name, _)| name.as_str()).collect();
        let order = tree_order(&names)?;
        Some(
            (order.into_iter())
                .map(|k| (dotted(&written[k].0), written[k].1.clone()))
                .collect(),
        )
    }

    fn of_tree(value: &Value) -> Vec<(String, Value)> {
        let mut cells = Vec::new();
        flatten("", value.clone(), &mut |name, value| {
            cells.push((name.to_string(), value))
        });
        cells
    }

    /// A record's leaves are its tree's, flattened, in the same order, whatever groups and lists
    /// it holds; a field asked whole is one leaf; and where names could clash, or a variant
    /// carries data, it gives up rather than differ.
    #[test]
    fn leaves_are_the_flattened_tree_in_its_order() {
        let stored = every_field();
        let tree = stored.to_value();
        assert_eq!(leaves(&stored, &[]), Some(of_tree(&tree)));
        let with_case = leaves(&stored, &["case"]).unwrap();
        let case = with_case.iter().find(|(name, _)| name == "case").unwrap();
        assert_eq!(case.1, Value::Null);
        assert!(!with_case.iter().any(|(name, _)| name.starts_with("case.")));
        // Names that sort differently as parts and as texts (`-`, `.` and digits sort below
        // `_`), empty groups, nulls, lists of groups, non-finite numbers.
        let odd = json!({
            "a": {"b": 1, "b-c": {"x": null}, "b_c": 2, "b0": {}, "b.d": 3},
            "a-b": [{"z": 1}, 2],
            "a0": {},
        });
        assert_eq!(leaves(&odd, &[]), Some(of_tree(&odd)));
        #[derive(serde::Serialize)]
        struct Numbers {
            nan: f64,
            whole: u64,
            none: Option<f64>,
            pair: (u8, f32),
        }
        let numbers = Numbers {
            nan: f64::NAN,
            whole: u64::MAX,
            none: None,
            pair: (1, 0.5),
        };
        assert_eq!(
            leaves(&numbers, &[]),
            Some(of_tree(&serde_json::to_value(&numbers).unwrap()))
        );
        assert_eq!(leaves(&json!(1), &[]), None);
        assert_eq!(leaves(&json!([{"a": 1}]), &[]), None);
        assert_eq!(leaves(&json!({"": {"b": 1}}), &[]), None);
        assert_eq!(leaves(&json!({"a.b": 1}), &[]), None);
        assert_eq!(leaves(&json!({"a\u{0}b": 1}), &[]), None);
        let mut twice = serde_json::Map::new();
        twice.insert("a".into(), json!(1));
        #[derive(serde::Serialize)]
        struct Clash<'a> {
            a: u8,
            #[serde(flatten)]
            more: &'a serde_json::Map<String, Value>,
        }
        assert_eq!(leaves(&Clash { a: 2, more: &twice }, &[]), None);
        #[derive(serde::Serialize)]
        enum Carries {
            Data(u8),
        }
        #[derive(serde::Serialize)]
        struct WithVariant {
            v: Carries,
        }
        assert_eq!(
            leaves(
                &WithVariant {
                    v: Carries::Data(1)
                },
                &[]
            ),
            None
        );
    }
}
