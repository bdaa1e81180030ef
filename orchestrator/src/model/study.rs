//! Study files and their expansion into points: a `base` case, sweep groups (`product`, `zip`,
//! paths in the (ε, h) plane) whose points multiply, derived fields, a `where` filter, repeats.

use crate::model::adaptive::{Budget, Kind};
use crate::model::boundary::BoundarySpec;
use crate::model::expression::{self, Expression, Scope};
use crate::model::figure_spec::{FigureKind, FigureSpec};
use crate::model::resources::Resources;
use schema::error::{FieldError, Subject};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;

mod point;
mod sweep;

pub use point::{fields_telling_apart, label_parts, Point};
use point::{Moving, Names, BRANCH, REFINED, SCALED};

/// The most a study file may hold: far beyond any written by hand or generated (the shipped
/// ones are a few KB), so that a device given as one (/dev/zero) is not read until memory runs
/// out.
pub const TEXT_CAP: u64 = 16 << 20;

/// A study file, as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Study {
    /// Names the results directory `results/<name>/`.
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// The fields every point starts from.
    pub base: Map<String, Value>,
    /// Groups whose points multiply: a point takes one point of every group.
    #[serde(default)]
    pub sweep: Vec<SweepGroup>,
    /// Fields computed from the others once the sweep is applied, e.g. `"ranks": "px * py"`;
    /// `h` stands for the point's grid spacing. They may not refer to each other.
    #[serde(default)]
    pub derive: BTreeMap<String, String>,
    /// Conditions every kept point satisfies, e.g. `"threads * ranks <= 2"`.
    #[serde(default, rename = "where")]
    pub filter: Vec<String>,
    /// Runs of every point, for timing statistics.
    #[serde(default = "one")]
    pub repeat: usize,
    /// Let cases share the machine even though their timings are recorded (by default each
    /// case runs alone, so that no other run disturbs its timings).
    #[serde(default)]
    pub share_machine: bool,
    /// Seconds after which a case is stopped and stored as failed.
    #[serde(default)]
    pub timeout_s: Option<f64>,
    /// Each case checkpoints its time loop (or a steady solve its CG iterations) this often
    /// (wall seconds), and on a stopping signal, so that a run stopped midway resumes where it
    /// was.
    #[serde(default)]
    pub checkpoint_every_s: Option<f64>,
    /// What cluster jobs ask of the scheduler (`nlstudy submit`); flags override it.
    #[serde(default)]
    pub resources: Resources,
    /// The figures `nlstudy plot` draws from the study's summary table.
    #[serde(default)]
    pub figures: Vec<FigureSpec>,
    /// The study's adaptive question, if it asks one: read from its section (`boundary`,
    /// `refine`, `target`, or any kind `kinds` registers) by `Study::from_value`.
    #[serde(skip)]
    question: Option<Box<dyn Kind>>,
    /// What the adaptive question may spend over all the points: runs and core-seconds.
    #[serde(default)]
    pub budget: Option<Budget>,
    /// The study file's text as it was read (`Study::read`), once: what its owner file hashes,
    /// so that a FIFO or a file replaced meanwhile is never read a second time.
    #[serde(skip)]
    pub text: String,
}

/// The adaptive sections a study file may hold, each read into its question: the registry of
/// kinds (`kinds::SHIPPED`) as the study file's reader sees it.
pub trait Sections {
    /// The question of section `name` (its value as the file gives it), None for a name that
    /// is no kind's section.
    fn read(&self, name: &str, value: Value) -> Option<Result<Box<dyn Kind>, StudyError>>;

    /// The sections' names, for messages.
    fn names(&self) -> Vec<&'static str>;
}

/// Takes the top-level keys of `value` that are not the study's own fields out of it, by name:
/// each the section of an adaptive question, or an unknown field refused with the names a study
/// takes.
fn adaptive_sections(
    value: &mut Value,
    sections: &dyn Sections,
) -> Result<Vec<(String, Value)>, StudyError> {
    let Some(object) = value.as_object_mut() else {
        return Ok(Vec::new());
    };
    let own = serde_aux::serde_introspection::serde_introspect::<Study>();
    let others: Vec<String> = (object.keys())
        .filter(|k| !own.contains(&k.as_str()))
        .cloned()
        .collect();
    let names = sections.names();
    let mut asked = Vec::new();
    for key in others {
        if !names.contains(&key.as_str()) {
            let expected = own.iter().copied().chain(names.iter().copied());
            let expected: Vec<String> = expected.map(|n| format!("`{n}`")).collect();
            let message = format!(
                "unknown field `{key}`, expected one of {}",
                expected.join(", ")
            );
            return Err(StudyError::from_serde(String::new(), message));
        }
        let section = object.remove(&key).expect("a key of the object");
        asked.push((key, section));
    }
    Ok(asked)
}

/// Names as a sentence lists them: `a`, `b` and `c` (with `and`; or `or`).
fn listed(names: &[&str], and: &str) -> String {
    let quoted: Vec<String> = names.iter().map(|n| format!("`{n}`")).collect();
    match quoted.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} {and} {last}", rest.join(", ")),
        None => String::new(),
    }
}

fn one() -> usize {
    1
}

/// One sweep group.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum SweepGroup {
    /// Every combination of the axes' values.
    Product(BTreeMap<String, Vec<Value>>),
    /// The axes' values in lock-step: the k-th point takes the k-th value of every axis.
    Zip(BTreeMap<String, Vec<Value>>),
    /// A path in the (ε, h) plane over grid sizes n.
    Path(PathSpec),
    /// Named alternatives, each a list of groups that multiply: a point lies on one branch, whose
    /// name the tables keep in the column `branch` (e.g. the paths of an ε/h study, each with its
    /// own source and time step). The solver never sees it.
    Branches(BTreeMap<String, Branch>),
}

/// One alternative of `branches`: its groups, written as a list (`"a": [{"product": …}]`), or
/// as an object that also gives the branch's own `where` (conditions on its points only, after
/// the study's) and `repeat` (instead of the study's): `"a": {"sweep": […], "repeat": 5}`.
#[derive(Debug, Default)]
pub struct Branch {
    pub sweep: Vec<SweepGroup>,
    pub filter: Vec<String>,
    pub repeat: Option<usize>,
}

/// A branch written as an object.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BranchFields {
    #[serde(default)]
    sweep: Vec<SweepGroup>,
    #[serde(default, rename = "where")]
    filter: Vec<String>,
    #[serde(default)]
    repeat: Option<usize>,
}

impl<'de> Deserialize<'de> for Branch {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Branch, D::Error> {
        use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
        struct Either;
        impl<'de> serde::de::Visitor<'de> for Either {
            type Value = Branch;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str(
                    "a list of sweep groups, or {\"sweep\": […], \"where\": […], \"repeat\": n}",
                )
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, seq: A) -> Result<Branch, A::Error> {
                Ok(Branch {
                    sweep: Deserialize::deserialize(SeqAccessDeserializer::new(seq))?,
                    ..Branch::default()
                })
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<Branch, A::Error> {
                let fields = BranchFields::deserialize(MapAccessDeserializer::new(map))?;
                Ok(Branch {
                    sweep: fields.sweep,
                    filter: fields.filter,
                    repeat: fields.repeat,
                })
            }
        }
        deserializer.deserialize_any(Either)
    }
}

/// Paths in the (ε, h) plane: how the horizon follows the grid as h → 0.
#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PathSpec {
    /// ε = m·h with m fixed: the ratio stays, both shrink.
    FixedM { m: u64, n: Vec<u64> },
    /// ε fixed while h → 0: convergence to the nonlocal solution.
    FixedEps { eps: f64, n: Vec<u64> },
    /// ε = c·h^alpha (alpha < 1: ε/h grows as h → 0, the asymptotically compatible regime).
    Power { c: f64, alpha: f64, n: Vec<u64> },
}

/// An assignment as its sweep group writes it: fields and values, `branch` among them.
type Pairs = Vec<(String, Value)>;

/// One choice of a sweep group: the fields it sets and their values, and the branch it names.
struct Assignment {
    fields: Vec<String>,
    values: Vec<Value>,
    branch: Option<Arc<str>>,
}

impl From<Pairs> for Assignment {
    fn from(pairs: Pairs) -> Assignment {
        let mut assignment = Assignment {
            fields: Vec::new(),
            values: Vec::new(),
            branch: None,
        };
        for (field, value) in pairs {
            if field == BRANCH {
                assignment.branch = value.as_str().map(Arc::from);
            } else {
                assignment.fields.push(field);
                assignment.values.push(value);
            }
        }
        assignment
    }
}

impl Point {
    /// The point with `assignment` applied, whose names (the point's swept ones and the
    /// assignment's) are `swept`.
    fn assigned(&self, assignment: &Assignment, swept: Names) -> Point {
        let mut values = Vec::with_capacity(swept.len());
        values.extend_from_slice(&self.values);
        values.extend_from_slice(&assignment.values);
        Point {
            base: self.base.clone(),
            swept,
            values,
            branch: assignment.branch.clone().or_else(|| self.branch.clone()),
            repeat: 0,
            moving: Arc::default(),
        }
    }
}

/// Lists of swept names, one per distinct list: the points that extend the same list the same
/// way share the result. Keyed by the address of the list extended, which the map keeps alive
/// so that no other list can take that address while it is a key.
#[derive(Default)]
struct SharedNames(HashMap<(usize, usize), (Names, Names)>);

impl SharedNames {
    /// `names` extended in the way numbered `how`, made by `extend` the first time.
    fn extended(
        &mut self,
        names: &Names,
        how: usize,
        extend: impl FnOnce(&[String]) -> Result<Vec<String>, StudyError>,
    ) -> Result<Names, StudyError> {
        let key = (Arc::as_ptr(names) as *const String as usize, how);
        if let Some((_, extended)) = self.0.get(&key) {
            return Ok(extended.clone());
        }
        let extended: Names = extend(names)?.into();
        self.0.insert(key, (names.clone(), extended.clone()));
        Ok(extended)
    }
}

/// Every point of `points` with every one of `assignments` (of sweep group `g`), in that order.
fn assign(
    points: &[Point],
    assignments: &[Assignment],
    g: usize,
) -> Result<Vec<Point>, StudyError> {
    let mut names = SharedNames::default();
    let mut next = Vec::with_capacity(points.len() * assignments.len());
    for point in points {
        for (a, assignment) in assignments.iter().enumerate() {
            let swept = names.extended(&point.swept, a, |earlier| {
                let mut swept = earlier.to_vec();
                for field in &assignment.fields {
                    if swept.contains(field) {
                        return Err(StudyError::new(
                            format!("sweep[{g}].{field}"),
                            "is swept by an earlier group too; sweep each field in one group",
                        ));
                    }
                    swept.push(field.clone());
                }
                Ok(swept)
            })?;
            next.push(point.assigned(assignment, swept));
        }
    }
    Ok(next)
}

/// What a `StudyError` is about: a place in a study file (`sweep[1].zip.n`, `resources.time`).
pub struct StudyPlace;

impl Subject for StudyPlace {
    const NAME: &'static str = "study";
}

/// Bad study file: where and what, in one sentence.
pub type StudyError = FieldError<StudyPlace>;

impl Study {
    /// The adaptive question the study asks (it asks at most one), or None for a fixed sweep.
    pub fn question(&self) -> Option<&dyn Kind> {
        self.question.as_deref()
    }

    /// Whether the study asks a question of kind `S` (its spec's type), which a figure that
    /// draws that kind's answers needs.
    pub fn asks<S: 'static>(&self) -> bool {
        self.question().is_some_and(|q| q.as_any().is::<S>())
    }

    /// Reads and parses a study file, naming the field at fault: TOML when its name ends in
    /// `.toml`, else JSON in which comments are allowed (JSONC).
    pub fn read(path: &Path, sections: &dyn Sections) -> Result<Study, StudyError> {
        let text = Study::text_of(path)?;
        let mut study = match path.extension().and_then(|x| x.to_str()) {
            Some("toml") => Study::parse_toml(&text, sections),
            _ => Study::parse(&text, sections),
        }?;
        study.text = text;
        Ok(study)
    }

    /// The text of the study file `path`: at most `TEXT_CAP` bytes of UTF-8.
    fn text_of(path: &Path) -> Result<String, StudyError> {
        let name = path.display().to_string();
        let bytes = schema::regular::read_at_most(path, TEXT_CAP, "a study file").map_err(|e| {
            StudyError::new(
                &name,
                format!("cannot read the study file: {e}; check the path"),
            )
        })?;
        String::from_utf8(bytes)
            .map_err(|_| StudyError::new(&name, "the study file is not UTF-8 text"))
    }

    /// A study from JSON with comments (`//`, `/* */`, `#`): they become spaces, so the lines
    /// and columns of errors stay those of the file.
    pub fn parse(text: &str, sections: &dyn Sections) -> Result<Study, StudyError> {
        let mut plain = String::with_capacity(text.len());
        std::io::Read::read_to_string(
            &mut json_comments::StripComments::new(text.as_bytes()),
            &mut plain,
        )
        .map_err(|e| StudyError::new("file", format!("{e}; close every /* comment with */")))?;
        // Typed fields refuse a repeated key themselves; maps such as `base` would keep the last.
        let value =
            schema::json::parse(&plain).map_err(|e| StudyError::new("file", e.to_string()))?;
        Study::from_value(value, sections)
    }

    /// A study from TOML (which refuses a key given twice itself).
    pub fn parse_toml(text: &str, sections: &dyn Sections) -> Result<Study, StudyError> {
        let value = super::toml_file::parse(text)
            .map_err(|e| StudyError::new("file", format!("not valid TOML: {e}")))?;
        Study::from_value(value, sections)
    }

    /// A study from its file's value: its own fields typed by serde, and each other top-level
    /// key the section of an adaptive question, which `sections` reads (a key that is neither is
    /// refused as an unknown field).
    fn from_value(mut value: Value, sections: &dyn Sections) -> Result<Study, StudyError> {
        if let Some((place, c)) = schema::json::control_character(&value, &["description"]) {
            return Err(StudyError::new(
                place,
                format!("holds {}; names and values are printable text (only `description` may hold newlines and tabs)", schema::json::describe_char(c)),
            ));
        }
        let asked = adaptive_sections(&mut value, sections)?;
        let mut study: Study = serde_path_to_error::deserialize(value).map_err(|e| {
            let path = e.path().to_string();
            StudyError::from_serde(path, e.into_inner().to_string())
        })?;
        if let [_, (second, _), ..] = &asked[..] {
            return Err(StudyError::new(
                second,
                format!("a study asks one adaptive question: give one of {}, and the others in studies of their own", listed(&sections.names(), "and")),
            ));
        }
        for (name, section) in asked {
            let read = sections.read(&name, section);
            study.question = Some(read.expect("a section adaptive_sections kept")?);
        }
        if !is_file_stem(&study.name) {
            return Err(StudyError::new(
                "name",
                format!(
                    "`{}` must be non-empty letters, digits, `_` or `-`: it names the results directory",
                    study.name
                ),
            ));
        }
        if study.name.len() > LONGEST_NAME {
            return Err(StudyError::new("name", too_long(study.name.len())));
        }
        for (k, figure) in study.figures.iter().enumerate() {
            if !is_file_stem(&figure.name) {
                return Err(StudyError::new(
                    format!("figures[{k}].name"),
                    format!(
                        "`{}` must be non-empty letters, digits, `_` or `-`: it names the SVG file",
                        figure.name
                    ),
                ));
            }
            if figure.name.len() > LONGEST_NAME {
                return Err(StudyError::new(
                    format!("figures[{k}].name"),
                    too_long(figure.name.len()),
                ));
            }
            if figure.kind == FigureKind::Boundaries && !study.asks::<BoundarySpec>() {
                return Err(StudyError::new(
                    format!("figures[{k}].kind"),
                    "`boundaries` draws the table of a boundary search; give the study a `boundary` question, or choose another kind",
                ));
            }
            if study.figures[..k].iter().any(|f| f.name == figure.name) {
                return Err(StudyError::new(
                    format!("figures[{k}].name"),
                    format!(
                        "`{}` names an earlier figure too; give each figure its own name",
                        figure.name
                    ),
                ));
            }
        }
        if study.repeat == 0 {
            return Err(StudyError::new("repeat", "must be at least 1 (got 0)"));
        }
        if let Some(budget) = &study.budget {
            budget
                .check()
                .map_err(|(field, why)| StudyError::new(field, why))?;
            if study.question().is_none() {
                return Err(StudyError::new(
                    "budget",
                    format!(
                        "bounds an adaptive question; give {}, or leave `budget` out",
                        listed(&sections.names(), "or")
                    ),
                ));
            }
        }
        Ok(study)
    }

    /// The points of the study, in sweep order, each repeated `repeat` times.
    pub fn expand(&self) -> Result<Vec<Point>, StudyError> {
        let size = self.sweep.iter().fold(self.repeat as u128, |total, g| {
            total.saturating_mul(g.size())
        });
        if size > MOST_POINTS as u128 {
            return Err(StudyError::new(
                "sweep",
                format!(
                    "expands to {size} points with their repeats, before `where`; at most {MOST_POINTS} are taken: split the study, or sweep fewer values"
                ),
            ));
        }
        let mut points = vec![Point::from_fields(self.base.clone())];
        for (g, group) in self.sweep.iter().enumerate() {
            for stage in group.stages(g)? {
                let assignments: Vec<Assignment> =
                    stage.into_iter().map(Assignment::from).collect();
                points = assign(&points, &assignments, g)?;
            }
        }
        let derived: Vec<String> = self.derive.keys().cloned().collect();
        let fields_moving = |triggers: &[&str], branch: Option<&str>| -> Vec<String> {
            let mut fields: Vec<String> = self
                .sweep
                .iter()
                .flat_map(|g| g.moving_with(triggers, branch))
                .collect();
            fields.extend(derived.iter().cloned());
            fields
        };
        let branches = self.branches()?;
        // The fields that move along each branch's series, worked out once per branch.
        let mut moving: HashMap<Option<Arc<str>>, Arc<Moving>> = HashMap::new();
        let mut names = SharedNames::default();
        let formulas = Expressions::parse_lists([("derive".to_string(), self.derive.values())]);
        for point in &mut points {
            self.derive_fields(point, &formulas, &mut names)?;
        }
        // Filtered in place: at 10⁶ points a second list is a hundred megabytes more.
        let mut failure = None;
        let (study_filter, branch_filters) = self.filters(&branches);
        let filter_of = |point: &Point| {
            let branch = point.branch.as_deref();
            branch
                .and_then(|b| branch_filters.get(b))
                .unwrap_or(&study_filter)
        };
        points.retain(|point| match filter_of(point).keeps(point) {
            Ok(keep) => keep && failure.is_none(),
            Err(e) => {
                failure.get_or_insert(e);
                false
            }
        });
        if let Some(e) = failure {
            return Err(e);
        }
        for point in &mut points {
            let branch = point.branch.as_deref();
            point.moving = moving
                .entry(point.branch.clone())
                .or_insert_with(|| {
                    Arc::new(Moving {
                        refined: fields_moving(REFINED, branch),
                        scaled: fields_moving(SCALED, branch),
                    })
                })
                .clone();
        }
        let repeats = |point: &Point| {
            let own = point.branch.as_deref().and_then(|b| branches.get(b));
            own.and_then(|(_, b)| b.repeat).unwrap_or(self.repeat)
        };
        if points.iter().all(|p| repeats(p) == 1) {
            return Ok(points);
        }
        // Each point once per repeat: moved, not copied, into its last repeat.
        let mut expanded = Vec::with_capacity(points.len() * self.repeat);
        for point in points {
            let repeats = repeats(&point);
            if repeats == 0 {
                continue;
            }
            for repeat in 0..repeats - 1 {
                expanded.push(Point {
                    repeat,
                    ..point.clone()
                });
            }
            expanded.push(Point {
                repeat: repeats - 1,
                ..point
            });
        }
        Ok(expanded)
    }

    /// Every branch of the sweep, nested ones too, by name, with its place in the file. Names
    /// are unique: a point's `branch` names one.
    fn branches(&self) -> Result<BTreeMap<String, (String, &Branch)>, StudyError> {
        fn walk<'a>(
            groups: &'a [SweepGroup],
            place: &str,
            found: &mut BTreeMap<String, (String, &'a Branch)>,
        ) -> Result<(), StudyError> {
            for (g, group) in groups.iter().enumerate() {
                let SweepGroup::Branches(branches) = group else {
                    continue;
                };
                for (name, branch) in branches {
                    let at = format!("{place}[{g}].branches.{name}");
                    if found.contains_key(name) {
                        return Err(StudyError::new(
                            at,
                            "names another branch too; give each branch its own name",
                        ));
                    }
                    found.insert(name.clone(), (at.clone(), branch));
                    walk(&branch.sweep, &at, found)?;
                }
            }
            Ok(())
        }
        let mut found = BTreeMap::new();
        walk(&self.sweep, "sweep", &mut found)?;
        Ok(found)
    }

    fn derive_fields(
        &self,
        point: &mut Point,
        formulas: &Expressions,
        names: &mut SharedNames,
    ) -> Result<(), StudyError> {
        if self.derive.is_empty() {
            return Ok(());
        }
        let mut derived = Vec::with_capacity(self.derive.len());
        for (field, (_, value)) in self
            .derive
            .keys()
            .zip(formulas.at(point, Expression::number))
        {
            derived.push(value.map_err(|e| StudyError::new(format!("derive.{field}"), e))?);
        }
        // A derived field the sweep set too keeps its place; the others follow the swept ones.
        point.swept = names.extended(&point.swept, 0, |swept| {
            let mut swept = swept.to_vec();
            swept.extend(
                self.derive
                    .keys()
                    .filter(|f| !swept.contains(f))
                    .cloned()
                    .collect::<Vec<_>>(),
            );
            Ok(swept)
        })?;
        for (field, value) in self.derive.keys().zip(derived) {
            match point.swept.iter().position(|f| f == field) {
                Some(k) if k < point.values.len() => point.values[k] = value,
                _ => point.values.push(value),
            }
        }
        Ok(())
    }

    /// The study's `where`, and each branch's after it, read once for all points.
    fn filters<'b>(
        &self,
        branches: &'b BTreeMap<String, (String, &Branch)>,
    ) -> (Expressions, HashMap<&'b str, Expressions>) {
        let study = || std::iter::once(("where".to_string(), self.filter.iter()));
        let of_branch = branches.iter().map(|(name, (place, branch))| {
            let own = (format!("{place}.where"), branch.filter.iter());
            (
                name.as_str(),
                Expressions::parse_lists(study().chain([own])),
            )
        });
        (Expressions::parse_lists(study()), of_branch.collect())
    }
}

/// Expressions read once for all the points they are evaluated at (a plan evaluates `where`
/// at each of 10⁶ points): each with its place (`where[0]`), and the names they read, the only
/// fields a point's scope needs to hold for them.
struct Expressions {
    expressions: Vec<(String, Result<Expression, String>)>,
    names: Vec<String>,
}

impl Expressions {
    fn parse_lists<'a>(
        lists: impl IntoIterator<Item = (String, impl Iterator<Item = &'a String>)>,
    ) -> Self {
        let mut expressions: Vec<(String, Result<Expression, String>)> = Vec::new();
        for (place, list) in lists {
            for (k, text) in list.enumerate() {
                expressions.push((format!("{place}[{k}]"), Expression::parse(text)));
            }
        }
        let names = expression::names_read(expressions.iter().filter_map(|(_, e)| e.as_ref().ok()));
        Expressions { expressions, names }
    }

    /// `evaluate` of each expression at `point`, with its place, one at a time: over a scope of
    /// the names they read, and where that fails over all the point's fields, so that a name
    /// the point lacks is said with all the names it has.
    fn at<'s, T>(
        &'s self,
        point: &'s Point,
        evaluate: impl Fn(&Expression, &Scope) -> Result<T, String> + 's,
    ) -> impl Iterator<Item = (&'s str, Result<T, String>)> + 's {
        let scope = point.scope_of(&self.names);
        self.expressions.iter().map(move |(place, expression)| {
            let value = (expression.as_ref().map_err(Clone::clone))
                .and_then(|e| evaluate(e, &scope).or_else(|_| evaluate(e, &point.scope())));
            (place.as_str(), value)
        })
    }

    /// Whether the point meets every condition.
    fn keeps(&self, point: &Point) -> Result<bool, StudyError> {
        if self.expressions.is_empty() {
            return Ok(true);
        }
        for (place, holds) in self.at(point, Expression::condition) {
            let at = |e| StudyError::new(place, format!("{e} (at {})", point.label()));
            if !holds.map_err(at)? {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// The longest study or figure name: a file name holds at most 255 bytes, and the files named
/// after one add up to 40 (`.<name>-summary.parquet.<pid>.partial`).
const LONGEST_NAME: usize = 200;

fn too_long(length: usize) -> String {
    format!("is {length} characters long; names file names, so keep it to {LONGEST_NAME}")
}

/// Letters, digits, `_` and `-`: a name that is safe as a file or directory name.
fn is_file_stem(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// The most points a study may expand to (repeats included), counted before they are made: a
/// planned point costs 800 bytes or so and a line of `nlsolve check`, so 10⁶ is most of a
/// gigabyte.
pub const MOST_POINTS: usize = 1_000_000;

#[cfg(test)]
mod tests;
