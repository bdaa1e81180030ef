//! Expressions of study files (`derive` and `where`): arithmetic, comparisons and logic over a
//! point's fields, every number an f64.
//!
//! Hand-written rather than evalexpr: evalexpr divides integers as integers and holds 64 and
//! 64.0 unequal, so `1/n` or `n == 64` would silently give wrong points; here `1/n` is a
//! fraction and `n == 64` holds for n = 64 however the file wrote it.
//!
//! A name the point lacks (a field another branch sweeps) is an error where its value is
//! needed, but `||` and `&&` read left to right and stop once decided, so
//! `branch != 'threads' || threads <= 2` holds on every branch.

use schema::case::DEFAULT_LENGTH;
use schema::choices::Method;
use serde_json::{Map, Value};
use std::collections::BTreeMap;

#[derive(Clone, Debug, PartialEq)]
enum Val {
    Num(f64),
    Str(String),
    Bool(bool),
    /// A name the point lacks: the error to give if its value is needed.
    Missing(String),
}

/// The names an expression may use: the point's fields, and `h`, its grid spacing.
pub struct Scope {
    names: BTreeMap<String, Val>,
}

impl Scope {
    pub fn from_fields(fields: &Map<String, Value>) -> Scope {
        let mut names: BTreeMap<String, Val> = fields
            .iter()
            .filter_map(|(name, value)| Some((name.clone(), val_of(value)?)))
            .collect();
        if let Some(h) = grid_spacing(|field| fields.get(field)) {
            names.insert("h".into(), Val::Num(h));
        }
        Scope { names }
    }

    /// The scope of just `names`, their values from `get`: all an expression reading only
    /// them needs, without copying every field (a plan evaluates `where` at each of 10⁶ points).
    pub fn of_names<'v>(names: &[String], get: impl Fn(&str) -> Option<&'v Value>) -> Scope {
        let mut scope = BTreeMap::new();
        for name in names {
            let value = match name.as_str() {
                // (As `from_fields`: the grid's spacing, else a field of that name.)
                "h" => (grid_spacing(&get).map(Val::Num)).or_else(|| get(name).and_then(val_of)),
                _ => get(name).and_then(val_of),
            };
            if let Some(value) = value {
                scope.insert(name.clone(), value);
            }
        }
        Scope { names: scope }
    }
}

/// A field's value as an expression sees it; none for arrays, objects and null.
fn val_of(value: &Value) -> Option<Val> {
    Some(match value {
        Value::Number(x) => Val::Num(x.as_f64()?),
        Value::String(s) => Val::Str(s.clone()),
        Value::Bool(b) => Val::Bool(*b),
        _ => return None,
    })
}

/// A run's columns (a table row, or a record flattened as one) as expression names, as a
/// study's own `where` reads them: the case's fields by their own names, then the other
/// columns. A case field wins over a record column of the same name (the record's `subdomains`
/// is p², the case's p; its `backend` is the one `auto` chose), so a figure's `where` means what
/// the study's does; the record's value is the column when the case leaves the field out.
pub fn fields_of_columns<N: AsRef<str>>(cells: &[(N, Value)]) -> Map<String, Value> {
    let mut fields = Map::new();
    for (name, value) in cells {
        if let Some(field) = name.as_ref().strip_prefix("case.") {
            if !value.is_null() {
                fields.insert(field.to_string(), value.clone());
            }
        }
    }
    for (name, value) in cells {
        fields.entry(name.as_ref()).or_insert_with(|| value.clone());
    }
    fields
}

/// The fields `h` is computed from (`grid_spacing`).
pub const GRID_SPACING_READS: [&str; 3] = ["n", "method", "length"];

/// h as the solver defines it (`schema`'s `Method::grid_spacing`); none while the method is
/// not one the solver knows (its check will say so).
fn grid_spacing<'v>(get: impl Fn(&str) -> Option<&'v Value>) -> Option<f64> {
    let n = get("n")?
        .as_f64()
        .filter(|n| n.fract() == 0.0 && *n >= 1.0)?;
    let method: Method = match get("method") {
        Some(name) => serde_json::from_value(name.clone()).ok()?,
        None => Method::default(),
    };
    let length = get("length")
        .and_then(Value::as_f64)
        .unwrap_or(DEFAULT_LENGTH);
    Some(method.grid_spacing(n as usize, length))
}

/// Evaluates a condition.
pub fn condition(text: &str, scope: &Scope) -> Result<bool, String> {
    Expression::parse(text)?.condition(scope)
}

/// The names an expression reads (its fields), without evaluating it.
pub fn names(text: &str) -> Result<Vec<String>, String> {
    Ok(Expression::parse(text)?
        .names()
        .into_iter()
        .map(str::to_string)
        .collect())
}

/// The conditions of a figure's or a table's `where`, read once to keep the rows of a table by:
/// a row's scope holds just the names they read (a table of 10⁵ rows would otherwise copy every
/// cell of each). Like `&&`, they are read in order and stop at the first that does not hold.
pub struct Filter {
    conditions: Vec<Expression>,
    names: Vec<String>,
}

impl Filter {
    /// The conditions read; one that cannot be says which (its index) and why.
    pub fn parse(conditions: &[String]) -> Result<Filter, (usize, String)> {
        let conditions = (conditions.iter().enumerate())
            .map(|(k, text)| Expression::parse(text).map_err(|e| (k, e)))
            .collect::<Result<Vec<_>, _>>()?;
        let names = names_read(&conditions);
        Ok(Filter { conditions, names })
    }

    /// The names the conditions read, each once.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether a row, its fields by `get`, meets every condition; the first condition that
    /// cannot be evaluated there says which and why, naming all the row's fields (`all`).
    pub fn keeps<'v>(
        &self,
        get: impl Fn(&str) -> Option<&'v Value>,
        all: impl Fn() -> Map<String, Value>,
    ) -> Result<bool, (usize, String)> {
        let scope = Scope::of_names(&self.names, get);
        for (k, condition) in self.conditions.iter().enumerate() {
            let holds = (condition.condition(&scope))
                .or_else(|_| condition.condition(&Scope::from_fields(&all())))
                .map_err(|e| (k, e))?;
            if !holds {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// The names `expressions` read, each once, in the order first read: all a scope for them needs.
pub fn names_read<'a>(expressions: impl IntoIterator<Item = &'a Expression>) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for name in expressions.into_iter().flat_map(Expression::names) {
        if !names.iter().any(|n| n == name) {
            names.push(name.to_string());
        }
    }
    names
}

/// An expression read once, to be evaluated at many points.
pub struct Expression {
    text: Box<str>,
    tokens: Vec<Token>,
}

impl Expression {
    /// The expression's words; its syntax shows when it is evaluated.
    pub fn parse(text: &str) -> Result<Expression, String> {
        Ok(Expression {
            text: text.into(),
            tokens: tokenize(text)?,
        })
    }

    /// The names it reads, each once, in the order first read.
    pub fn names(&self) -> Vec<&str> {
        let mut names: Vec<&str> = Vec::new();
        for token in &self.tokens {
            if let Token::Name(name) = token {
                if name != "true" && name != "false" && !names.contains(&name.as_str()) {
                    names.push(name);
                }
            }
        }
        names
    }

    /// Its value as a number; an integral result becomes a JSON integer.
    pub fn number(&self, scope: &Scope) -> Result<Value, String> {
        let text = &self.text;
        match self.evaluate(scope)? {
            Val::Num(x) if x.fract() == 0.0 && x.abs() < 9.0e15 => Ok(Value::from(x as i64)),
            Val::Num(x) if x.is_finite() => Ok(Value::from(x)),
            Val::Num(x) => Err(format!("`{text}` evaluates to {x}, not a finite number")),
            other => Err(format!("`{text}` must give a number, not {other:?}")),
        }
    }

    /// Whether it holds.
    pub fn condition(&self, scope: &Scope) -> Result<bool, String> {
        match self.evaluate(scope)? {
            Val::Bool(b) => Ok(b),
            other => Err(format!(
                "`{}` must be true or false, not {other:?}",
                self.text
            )),
        }
    }

    fn evaluate(&self, scope: &Scope) -> Result<Val, String> {
        match self.evaluate_as_far_as_known(scope)? {
            Val::Missing(why) => Err(why),
            value => Ok(value),
        }
    }

    /// Its value, `Missing` when a name it needs is not in `scope`.
    fn evaluate_as_far_as_known(&self, scope: &Scope) -> Result<Val, String> {
        let mut parser = Parser {
            tokens: &self.tokens,
            at: 0,
            scope,
            depth: 0,
        };
        let value = parser.or()?;
        match parser.tokens.get(parser.at) {
            None => Ok(value),
            Some(token) => Err(format!("`{}`: unexpected {token:?}", self.text)),
        }
    }
}

/// Whether `text` is an expression (a record's condition, before any record gives its names
/// values): its syntax is checked, the names it reads are not.
pub fn check_syntax(text: &str) -> Result<(), String> {
    let nothing = Scope {
        names: BTreeMap::new(),
    };
    Expression::parse(text)?
        .evaluate_as_far_as_known(&nothing)
        .map(drop)
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Str(String),
    Name(String),
    Op(&'static str),
}

const OPERATORS: [&str; 16] = [
    "==", "!=", "<=", ">=", "&&", "||", "<", ">", "+", "-", "*", "/", "^", "(", ")", "!",
];

fn tokenize(text: &str) -> Result<Vec<Token>, String> {
    let mut tokens = Vec::new();
    let mut rest = text.trim_start();
    while !rest.is_empty() {
        let c = rest.chars().next().expect("not empty");
        let taken = if c.is_ascii_digit() || c == '.' {
            let end = number_end(rest);
            let x = rest[..end]
                .parse()
                .map_err(|_| format!("`{text}`: `{}` is not a number", &rest[..end]))?;
            tokens.push(Token::Num(x));
            end
        } else if c.is_alphabetic() || c == '_' {
            // A dotted name is a nested field as the tables flatten it (`horizon_profile.kind`).
            let end = rest
                .find(|ch: char| !(ch.is_alphanumeric() || ch == '_' || ch == '.'))
                .unwrap_or(rest.len());
            tokens.push(Token::Name(rest[..end].to_string()));
            end
        } else if c == '"' || c == '\'' {
            let close = rest[1..]
                .find(c)
                .ok_or_else(|| format!("`{text}`: a string is not closed"))?;
            tokens.push(Token::Str(rest[1..1 + close].to_string()));
            close + 2
        } else if let Some(op) = OPERATORS.iter().find(|op| rest.starts_with(**op)) {
            tokens.push(Token::Op(op));
            op.len()
        } else {
            return Err(format!("`{text}`: unexpected `{c}`"));
        };
        rest = rest[taken..].trim_start();
    }
    Ok(tokens)
}

/// The end of a number literal starting `text`: digits, a point, and an exponent `e±d`.
fn number_end(text: &str) -> usize {
    let bytes = text.as_bytes();
    let mut end = 0;
    while end < bytes.len() && (bytes[end].is_ascii_digit() || bytes[end] == b'.') {
        end += 1;
    }
    if end < bytes.len() && (bytes[end] == b'e' || bytes[end] == b'E') {
        let mut exp = end + 1;
        if exp < bytes.len() && (bytes[exp] == b'+' || bytes[exp] == b'-') {
            exp += 1;
        }
        if exp < bytes.len() && bytes[exp].is_ascii_digit() {
            end = exp;
            while end < bytes.len() && bytes[end].is_ascii_digit() {
                end += 1;
            }
        }
    }
    end
}

/// How deeply parentheses, signs and `!` may nest: far beyond what a study writes, and far
/// below what would overflow the parser's stack.
const DEEPEST: usize = 64;

struct Parser<'a> {
    tokens: &'a [Token],
    at: usize,
    scope: &'a Scope,
    /// Nesting of the expression being parsed now.
    depth: usize,
}

impl Parser<'_> {
    /// Parses one nested level with `parse`, refusing nesting deeper than `DEEPEST`.
    fn nested(&mut self, parse: fn(&mut Self) -> Result<Val, String>) -> Result<Val, String> {
        if self.depth == DEEPEST {
            return Err(format!(
                "nested deeper than {DEEPEST} levels of parentheses, signs or `!`; write it more simply"
            ));
        }
        self.depth += 1;
        let value = parse(self);
        self.depth -= 1;
        value
    }

    fn eat(&mut self, op: &str) -> bool {
        let found = matches!(self.tokens.get(self.at), Some(Token::Op(o)) if *o == op);
        if found {
            self.at += 1;
        }
        found
    }

    fn or(&mut self) -> Result<Val, String> {
        let mut left = self.and()?;
        while self.eat("||") {
            let right = self.and()?;
            left = match left {
                Val::Bool(true) => left,
                Val::Missing(_) => left,
                _ if matches!(right, Val::Missing(_)) => right,
                _ => Val::Bool(truth(&left)? || truth(&right)?),
            };
        }
        Ok(left)
    }

    fn and(&mut self) -> Result<Val, String> {
        let mut left = self.comparison()?;
        while self.eat("&&") {
            let right = self.comparison()?;
            left = match left {
                Val::Bool(false) => left,
                Val::Missing(_) => left,
                _ if matches!(right, Val::Missing(_)) => right,
                _ => Val::Bool(truth(&left)? && truth(&right)?),
            };
        }
        Ok(left)
    }

    fn comparison(&mut self) -> Result<Val, String> {
        let left = self.sum()?;
        for op in ["==", "!=", "<=", ">=", "<", ">"] {
            if self.eat(op) {
                let right = self.sum()?;
                let holds = match (&left, &right, op) {
                    (Val::Missing(_), _, _) => return Ok(left),
                    (_, Val::Missing(_), _) => return Ok(right),
                    (_, _, "==") => left == right,
                    (_, _, "!=") => left != right,
                    (Val::Num(a), Val::Num(b), _) => match op {
                        "<=" => a <= b,
                        ">=" => a >= b,
                        "<" => a < b,
                        _ => a > b,
                    },
                    _ => return Err(format!("cannot order {left:?} and {right:?}")),
                };
                return Ok(Val::Bool(holds));
            }
        }
        Ok(left)
    }

    fn sum(&mut self) -> Result<Val, String> {
        let mut left = self.product()?;
        loop {
            if self.eat("+") {
                left = arithmetic(left, self.product()?, |a, b| a + b)?;
            } else if self.eat("-") {
                left = arithmetic(left, self.product()?, |a, b| a - b)?;
            } else {
                return Ok(left);
            }
        }
    }

    fn product(&mut self) -> Result<Val, String> {
        let mut left = self.unary()?;
        loop {
            if self.eat("*") {
                left = arithmetic(left, self.unary()?, |a, b| a * b)?;
            } else if self.eat("/") {
                left = arithmetic(left, self.unary()?, |a, b| a / b)?;
            } else {
                return Ok(left);
            }
        }
    }

    fn unary(&mut self) -> Result<Val, String> {
        if self.eat("-") {
            return arithmetic(Val::Num(0.0), self.nested(Self::unary)?, |_, b| -b);
        }
        if self.eat("!") {
            return match self.nested(Self::unary)? {
                Val::Missing(why) => Ok(Val::Missing(why)),
                value => Ok(Val::Bool(!truth(&value)?)),
            };
        }
        let base = self.atom()?;
        if self.eat("^") {
            return arithmetic(base, self.nested(Self::unary)?, f64::powf);
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Val, String> {
        let tokens = self.tokens;
        let token = tokens.get(self.at).ok_or("the expression ends too early")?;
        self.at += 1;
        match token {
            Token::Num(x) => Ok(Val::Num(*x)),
            Token::Str(s) => Ok(Val::Str(s.clone())),
            Token::Name(name) if name == "true" => Ok(Val::Bool(true)),
            Token::Name(name) if name == "false" => Ok(Val::Bool(false)),
            Token::Name(name) => Ok(self.scope.names.get(name).cloned().unwrap_or_else(|| {
                let known = self.scope.names.keys().map(String::as_str);
                let guess = schema::error::nearest(name, known.clone())
                    .map_or(String::new(), |g| format!("did you mean `{g}`? "));
                let known: Vec<&str> = known.collect();
                Val::Missing(format!(
                    "unknown name `{name}`; {guess}the point has {}",
                    known.join(", ")
                ))
            })),
            Token::Op("(") => {
                let inner = self.nested(Self::or)?;
                if !self.eat(")") {
                    return Err("a `(` is not closed".into());
                }
                Ok(inner)
            }
            Token::Op(op) => Err(format!("unexpected `{op}`")),
        }
    }
}

/// `f` of two numbers; a missing name stays missing (an error only where its value is needed).
fn arithmetic(left: Val, right: Val, f: impl Fn(f64, f64) -> f64) -> Result<Val, String> {
    match (&left, &right) {
        (Val::Missing(_), _) => Ok(left),
        (_, Val::Missing(_)) => Ok(right),
        _ => Ok(Val::Num(f(num(&left)?, num(&right)?))),
    }
}

fn num(value: &Val) -> Result<f64, String> {
    match value {
        Val::Num(x) => Ok(*x),
        other => Err(format!("{other:?} is not a number")),
    }
}

fn truth(value: &Val) -> Result<bool, String> {
    match value {
        Val::Bool(b) => Ok(*b),
        other => Err(format!("{other:?} is not true or false")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn scope(fields: Value) -> Scope {
        Scope::from_fields(fields.as_object().expect("an object"))
    }

    fn evaluate_number(text: &str, scope: &Scope) -> Result<Value, String> {
        Expression::parse(text)?.number(scope)
    }

    #[test]
    fn arithmetic_is_in_f64_and_integral_results_are_integers() {
        let s = scope(json!({"n": 64, "m": 4, "px": 2, "py": 3}));
        assert_eq!(evaluate_number("px * py", &s), Ok(json!(6)));
        assert_eq!(evaluate_number("m * h", &s), Ok(json!(0.0625)));
        assert_eq!(evaluate_number("1/n", &s), Ok(json!(0.015625)));
        assert_eq!(evaluate_number("2^-3 + 1e-1 * 10", &s), Ok(json!(1.125)));
        assert_eq!(evaluate_number("-(m - 6) * 2", &s), Ok(json!(4)));
    }

    #[test]
    fn conditions_compare_numbers_however_written_and_strings() {
        let s = scope(json!({"n": 64.0, "threads": 2, "ranks": 1, "method": "adi"}));
        assert_eq!(condition("n == 64", &s), Ok(true));
        assert_eq!(
            condition("threads * ranks <= 2 && method == \"adi\"", &s),
            Ok(true)
        );
        assert_eq!(condition("!(n > 32) || method != 'adi'", &s), Ok(false));
        let nested = scope(json!({"horizon_profile.kind": "linear", "patch.ghost_force": 1e-13}));
        assert_eq!(
            condition("horizon_profile.kind == 'linear'", &nested),
            Ok(true)
        );
        assert_eq!(condition("patch.ghost_force < 1e-12", &nested), Ok(true));
        // h of a grid method: L/(n + 1) with L = 2.
        assert_eq!(evaluate_number("h", &s), Ok(json!(2.0 / 65.0)));
    }

    #[test]
    fn a_name_the_point_lacks_is_skipped_once_the_logic_is_decided() {
        let on_threads = scope(json!({"branch": "threads", "threads": 4}));
        let on_steps = scope(json!({"branch": "steps", "cfl": 0.5}));
        let spanning = "branch != 'threads' || threads <= 2";
        assert_eq!(condition(spanning, &on_threads), Ok(false));
        assert_eq!(condition(spanning, &on_steps), Ok(true));
        assert_eq!(
            condition("branch == 'threads' && threads > 2", &on_steps),
            Ok(false)
        );
        // Needed, it is an error, with a guess when one is near.
        for needed in [
            "threads <= 2 || branch == 'steps'",
            "threads == 1",
            "-threads < 0",
        ] {
            let error = condition(needed, &on_steps).unwrap_err();
            assert!(
                error.contains("unknown name `threads`"),
                "{needed}: {error}"
            );
        }
        let error = condition("thread == 1", &on_threads).unwrap_err();
        assert!(error.contains("did you mean `threads`?"), "{error}");
    }

    #[test]
    fn errors_say_what_is_wrong() {
        let s = scope(json!({"n": 64}));
        assert!(evaluate_number("n * q", &s)
            .unwrap_err()
            .contains("unknown name `q`"));
        assert!(evaluate_number("(n + 1", &s)
            .unwrap_err()
            .contains("not closed"));
        assert!(condition("n + 1", &s)
            .unwrap_err()
            .contains("true or false"));
        assert!(evaluate_number("n $ 2", &s)
            .unwrap_err()
            .contains("unexpected `$`"));
    }

    #[test]
    fn nesting_is_refused_past_a_depth_not_overflowing_the_stack() {
        let s = Scope::from_fields(&serde_json::Map::new());
        let deep =
            |open: &str, n: usize, close: &str| format!("{}1{}", open.repeat(n), close.repeat(n));
        assert_eq!(evaluate_number(&deep("(", DEEPEST, ")"), &s), Ok(json!(1)));
        assert_eq!(evaluate_number(&deep("-", DEEPEST, ""), &s), Ok(json!(1)));
        for text in [
            deep("(", 10_000, ")"),
            deep("-", 100_000, ""),
            deep("!", 100_000, ""),
            deep("2^", 100_000, ""),
        ] {
            let e = evaluate_number(&text, &s).unwrap_err();
            assert!(e.contains("nested deeper than"), "{e}");
        }
    }
}
