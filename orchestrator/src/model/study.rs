//! Study files and their expansion into points: a `base` case, sweep groups (`product`, `zip`,
//! paths in the (ε, h) plane) whose points multiply, derived fields, a `where` filter, repeats.

use crate::model::expression::{self, Scope};
use crate::model::figure_spec::FigureSpec;
use crate::model::resources::Resources;
use schema::error::{FieldError, Subject};
use serde::Deserialize;
use serde_json::{Map, Value};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::Arc;

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
    /// What cluster jobs ask of the scheduler (`nlstudy submit`); flags override it.
    #[serde(default)]
    pub resources: Resources,
    /// The figures `nlstudy plot` draws from the study's summary table.
    #[serde(default)]
    pub figures: Vec<FigureSpec>,
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

/// The pseudo-field through which a branch's name travels with its points' assignments.
const BRANCH: &str = "branch";

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

/// One point of a study: the case fields before the solver checks them, which of them the
/// sweep set (for messages and tables), and the series the point belongs to.
///
/// A point holds only what sets it apart: the study's `base` and the list of swept names are
/// shared by every point that has them, so 10⁶ points cost a few hundred bytes each, not the
/// kilobyte and more of a full map.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    base: Arc<Map<String, Value>>,
    /// The fields the sweep set and `derive` computed, in that order; `values` holds theirs.
    swept: Names,
    values: Vec<Value>,
    /// The `branches` alternative the point lies on, if any.
    pub branch: Option<Arc<str>>,
    pub repeat: usize,
    /// The fields that move along its series, shared by its branch's points.
    moving: Arc<Moving>,
}

/// The fields a refinement moves, and those a scaling moves.
#[derive(Debug, Default, PartialEq)]
struct Moving {
    refined: Vec<String>,
    scaled: Vec<String>,
}

/// The lines of a study's tables a point lies on, named by the swept fields held fixed along
/// them: the points of one refinement series differ only in the grid (and what the sweep moves
/// with it: the horizon of a path, the partners of `n` in a zip); those of one scaling series
/// only in the workers (threads, ranks, px, py and their zip partners). Derived fields follow
/// the swept ones, so they are left out of the names.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointSeries {
    pub refinement: String,
    pub scaling: String,
}

/// The fields whose change makes a refinement, and a scaling.
const REFINED: &[&str] = &["n"];
const SCALED: &[&str] = &["threads", "ranks", "px", "py"];

impl Point {
    /// A point of `fields` alone, none of them swept.
    pub fn of(fields: Map<String, Value>) -> Point {
        Point {
            base: Arc::new(fields),
            swept: Arc::from([]),
            values: Vec::new(),
            branch: None,
            repeat: 0,
            moving: Arc::default(),
        }
    }

    /// The series the point lies on, named by the fields that stay along them.
    pub fn series(&self) -> PointSeries {
        PointSeries {
            refinement: self.label_without(&self.moving.refined),
            scaling: self.label_without(&self.moving.scaled),
        }
    }

    /// The field's value, swept or from `base`.
    pub fn get(&self, field: &str) -> Option<&Value> {
        match self.swept.iter().position(|f| f == field) {
            Some(k) => Some(&self.values[k]),
            None => self.base.get(field),
        }
    }

    /// Every field, keys sorted: the case as written.
    pub fn fields(&self) -> Map<String, Value> {
        let mut fields = (*self.base).clone();
        for (field, value) in self.swept.iter().zip(&self.values) {
            fields.insert(field.clone(), value.clone());
        }
        fields
    }

    /// `fields()` as compact JSON, written without building the map: what `nlsolve check`
    /// reads, and what keys a case the solver refused.
    pub fn write_fields(&self, out: impl std::io::Write) -> serde_json::Result<()> {
        let mut entries: Vec<(&str, &Value)> = self
            .base
            .iter()
            .filter(|(field, _)| !self.swept.contains(field))
            .map(|(field, value)| (field.as_str(), value))
            .chain(self.swept.iter().map(String::as_str).zip(&self.values))
            .collect();
        // The order of a `Map`, so the text is that of `fields()`.
        entries.sort_unstable_by_key(|(field, _)| *field);
        let mut serializer = serde_json::Serializer::new(out);
        serde::Serializer::collect_map(&mut serializer, entries)
    }

    /// `n=64 threads=2` – the swept fields, for messages.
    pub fn label(&self) -> String {
        let mut label = self.label_without_repeat();
        if self.repeat > 0 {
            label.push_str(&format!(" repeat={}", self.repeat));
        }
        label
    }

    /// The label shared by the point's repeats.
    pub fn label_without_repeat(&self) -> String {
        self.label_without(&[])
    }

    fn label_without(&self, left_out: &[String]) -> String {
        let branch = self.branch.iter().map(|b| format!("{BRANCH}={b}"));
        let parts: Vec<String> = branch
            .chain(
                self.swept
                    .iter()
                    .zip(&self.values)
                    .filter(|(f, _)| !left_out.contains(f))
                    .map(|(f, v)| match v {
                        Value::String(s) => format!("{f}={s}"),
                        v => format!("{f}={v}"),
                    }),
            )
            .collect();
        parts.join(" ")
    }

    /// The fields an expression sees: the case's, and the branch.
    fn scope(&self) -> Scope {
        let mut fields = self.fields();
        if let Some(branch) = &self.branch {
            fields.insert(BRANCH.into(), Value::from(branch.to_string()));
        }
        Scope::of(&fields)
    }

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

/// Lists of swept names, one per distinct list: the points that extend the same list the same
/// way share the result. Keyed by the address of the list extended, which the map keeps alive
/// so that no other list can take that address while it is a key.
#[derive(Default)]
struct SharedNames(HashMap<(usize, usize), (Names, Names)>);

/// A list of swept field names, shared.
type Names = Arc<[String]>;

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

/// The fields that tell a study's points apart, for the columns of its tables: `branch` when
/// there are branches, then every field swept or derived on any branch, in first-seen order (the
/// fields of one branch alone would leave another's rows looking alike).
pub fn fields_telling_apart<'a>(points: impl IntoIterator<Item = &'a Point>) -> Vec<String> {
    let mut fields: Vec<String> = Vec::new();
    for point in points {
        if point.branch.is_some() && !fields.iter().any(|f| f == BRANCH) {
            fields.insert(0, BRANCH.to_string());
        }
        for field in point.swept.iter() {
            if !fields.contains(field) {
                fields.push(field.clone());
            }
        }
    }
    fields
}

/// What a `StudyError` is about: a place in a study file (`sweep[1].zip.n`, `resources.time`).
pub struct StudyPlace;

impl Subject for StudyPlace {
    const NAME: &'static str = "study";
}

/// Bad study file: where and what, in one sentence.
pub type StudyError = FieldError<StudyPlace>;

impl Study {
    /// Reads and parses a study file, naming the field at fault: TOML when its name ends in
    /// `.toml`, else JSON in which comments are allowed (JSONC).
    pub fn read(path: &Path) -> Result<Study, StudyError> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| {
            StudyError::new(
                &name,
                format!("cannot read the study file: {e}; check the path"),
            )
        })?;
        match path.extension().and_then(|x| x.to_str()) {
            Some("toml") => Study::parse_toml(&text),
            _ => Study::parse(&text),
        }
    }

    /// A study from JSON with comments (`//`, `/* */`, `#`): they become spaces, so the lines
    /// and columns of errors stay those of the file.
    pub fn parse(text: &str) -> Result<Study, StudyError> {
        let mut plain = String::with_capacity(text.len());
        std::io::Read::read_to_string(
            &mut json_comments::StripComments::new(text.as_bytes()),
            &mut plain,
        )
        .map_err(|e| StudyError::new("file", format!("{e}; close every /* comment with */")))?;
        // Typed fields refuse a repeated key themselves; maps such as `base` would keep the last.
        let value =
            schema::json::parse(&plain).map_err(|e| StudyError::new("file", e.to_string()))?;
        Study::from_value(value)
    }

    /// A study from TOML (which refuses a key given twice itself).
    pub fn parse_toml(text: &str) -> Result<Study, StudyError> {
        let value = super::toml_file::parse(text)
            .map_err(|e| StudyError::new("file", format!("not valid TOML: {e}")))?;
        Study::from_value(value)
    }

    fn from_value(value: Value) -> Result<Study, StudyError> {
        if let Some((place, c)) = schema::json::control_character(&value, &["description"]) {
            return Err(StudyError::new(
                place,
                format!("holds {}; names and values are printable text (only `description` may hold newlines and tabs)", schema::json::describe_char(c)),
            ));
        }
        let study: Study = serde_path_to_error::deserialize(value).map_err(|e| {
            let path = e.path().to_string();
            StudyError::from_serde(path, e.into_inner().to_string())
        })?;
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
        let mut points = vec![Point::of(self.base.clone())];
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
        for point in &mut points {
            self.derive_fields(point, &mut names)?;
        }
        // Filtered in place: at 10⁶ points a second list is a hundred megabytes more.
        let mut failure = None;
        points.retain(|point| match self.keeps(point, &branches) {
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

    fn derive_fields(&self, point: &mut Point, names: &mut SharedNames) -> Result<(), StudyError> {
        if self.derive.is_empty() {
            return Ok(());
        }
        let scope = point.scope();
        let mut derived = Vec::with_capacity(self.derive.len());
        for (field, formula) in &self.derive {
            let value = expression::evaluate_number(formula, &scope)
                .map_err(|e| StudyError::new(format!("derive.{field}"), e))?;
            derived.push(value);
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

    /// Whether the point meets the study's `where`, then its branch's.
    fn keeps(
        &self,
        point: &Point,
        branches: &BTreeMap<String, (String, &Branch)>,
    ) -> Result<bool, StudyError> {
        let study = self.filter.iter().map(|c| ("where".to_string(), c));
        let own = point.branch.as_deref().and_then(|b| branches.get(b));
        let branch = own
            .into_iter()
            .flat_map(|(place, b)| b.filter.iter().map(move |c| (format!("{place}.where"), c)));
        let mut conditions = study.enumerate().chain(branch.enumerate()).peekable();
        if conditions.peek().is_none() {
            return Ok(true);
        }
        let scope = point.scope();
        for (k, (place, condition)) in conditions {
            let holds = expression::condition(condition, &scope).map_err(|e| {
                StudyError::new(
                    format!("{place}[{k}]"),
                    format!("{e} (at {})", point.label()),
                )
            })?;
            if !holds {
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

impl SweepGroup {
    /// The number of points the group gives, counted without making them.
    fn size(&self) -> u128 {
        let length = |values: &Vec<Value>| values.len() as u128;
        match self {
            SweepGroup::Product(axes) => axes
                .values()
                .fold(1, |total: u128, v| total.saturating_mul(length(v))),
            SweepGroup::Zip(axes) => axes.values().next().map_or(0, length),
            SweepGroup::Path(
                PathSpec::FixedM { n, .. }
                | PathSpec::FixedEps { n, .. }
                | PathSpec::Power { n, .. },
            ) => n.len() as u128,
            // A branch's own repeats are counted with it (the study's multiply the rest).
            SweepGroup::Branches(branches) => branches
                .values()
                .map(|branch| {
                    branch
                        .sweep
                        .iter()
                        .fold(branch.repeat.unwrap_or(1) as u128, |t: u128, g| {
                            t.saturating_mul(g.size())
                        })
                })
                .fold(0, u128::saturating_add),
        }
    }

    /// The group's fields that change when one of `triggers` does: the triggers themselves
    /// among a product's axes, every field of a zip or path that holds one; of `branches`,
    /// only those of the point's own branch.
    fn moving_with(&self, triggers: &[&str], branch: Option<&str>) -> Vec<String> {
        let fields: Vec<String> = match self {
            SweepGroup::Product(axes) | SweepGroup::Zip(axes) => axes.keys().cloned().collect(),
            SweepGroup::Path(_) => vec!["n".to_string(), "m".to_string(), "eps".to_string()],
            SweepGroup::Branches(branches) => {
                return branch
                    .and_then(|b| branches.get(b))
                    .into_iter()
                    .flat_map(|b| &b.sweep)
                    .flat_map(|g| g.moving_with(triggers, branch))
                    .collect()
            }
        };
        let triggered = |f: &String| triggers.contains(&f.as_str());
        match self {
            SweepGroup::Product(_) => fields.into_iter().filter(triggered).collect(),
            _ if fields.iter().any(triggered) => fields,
            _ => Vec::new(),
        }
    }

    /// The group's points, as field assignments; `g` is its index, for messages.
    /// The group's assignments as stages whose points multiply in order: a product's axes one
    /// stage each (the first outermost), so that a product of 10⁶ points is never 10⁶
    /// assignments at once; any other group one stage.
    fn stages(&self, g: usize) -> Result<Vec<Vec<Pairs>>, StudyError> {
        let SweepGroup::Product(axes) = self else {
            return Ok(vec![self.assignments(g)?]);
        };
        axes.iter()
            .map(|(field, values)| match values.is_empty() {
                true => Err(StudyError::new(
                    format!("sweep[{g}].product.{field}"),
                    "has no values; give at least one or remove the axis",
                )),
                false => Ok(values
                    .iter()
                    .map(|v| vec![(field.clone(), v.clone())])
                    .collect()),
            })
            .collect()
    }

    fn assignments(&self, g: usize) -> Result<Vec<Pairs>, StudyError> {
        let place = |what: &str| format!("sweep[{g}].{what}");
        match self {
            SweepGroup::Product(_) => {
                let mut assignments = vec![Vec::new()];
                for axis in self.stages(g)? {
                    assignments = assignments
                        .into_iter()
                        .flat_map(|a: Vec<(String, Value)>| {
                            axis.iter()
                                .map(move |b| a.iter().chain(b).cloned().collect())
                        })
                        .collect();
                }
                Ok(assignments)
            }
            SweepGroup::Zip(axes) => {
                let mut lengths = axes.iter().map(|(f, v)| (f, v.len()));
                let Some((first, length)) = lengths.next() else {
                    return Err(StudyError::new(place("zip"), "has no axes"));
                };
                if let Some((field, other)) = lengths.find(|&(_, l)| l != length) {
                    return Err(StudyError::new(
                        place(&format!("zip.{field}")),
                        format!(
                            "has {other} values but `{first}` has {length}; the axes of a zip step together, so give each the same number"
                        ),
                    ));
                }
                Ok((0..length)
                    .map(|k| {
                        axes.iter()
                            .map(|(f, v)| (f.clone(), v[k].clone()))
                            .collect()
                    })
                    .collect())
            }
            SweepGroup::Path(path) => path.assignments(&place("path")),
            SweepGroup::Branches(branches) => {
                if branches.is_empty() {
                    return Err(StudyError::new(place("branches"), "has no branches"));
                }
                let mut assignments = Vec::new();
                for (name, branch) in branches {
                    if branch.repeat == Some(0) {
                        return Err(StudyError::new(
                            format!("{}.{name}.repeat", place("branches")),
                            "must be at least 1 (got 0)",
                        ));
                    }
                    let mut own = vec![vec![(BRANCH.to_string(), Value::from(name.clone()))]];
                    for (k, group) in branch.sweep.iter().enumerate() {
                        let inner = group.assignments(k).map_err(|e| {
                            StudyError::new(
                                format!(
                                    "{}.{name}{}",
                                    place("branches"),
                                    e.field.trim_start_matches("sweep")
                                ),
                                e.message,
                            )
                        })?;
                        own = own
                            .iter()
                            .flat_map(|a| {
                                inner
                                    .iter()
                                    .map(move |b| a.iter().chain(b).cloned().collect())
                            })
                            .collect();
                    }
                    assignments.extend(own);
                }
                Ok(assignments)
            }
        }
    }
}

impl PathSpec {
    fn assignments(&self, place: &str) -> Result<Vec<Pairs>, StudyError> {
        let sizes = match self {
            PathSpec::FixedM { n, .. }
            | PathSpec::FixedEps { n, .. }
            | PathSpec::Power { n, .. } => n,
        };
        if let Some(bad) = sizes.iter().find(|&&n| n == 0) {
            return Err(StudyError::new(
                format!("{place}.n"),
                format!("holds {bad}; grid sizes are at least 1"),
            ));
        }
        if sizes.is_empty() {
            return Err(StudyError::new(format!("{place}.n"), "has no grid sizes"));
        }
        sizes
            .iter()
            .map(|&n| {
                let horizon = match self {
                    PathSpec::FixedM { m, .. } => ("m", Value::from(*m)),
                    PathSpec::FixedEps { eps, .. } => ("eps", finite(*eps, place, n)?),
                    // h = 1/n: paths are for the nonlocal method on D = [0, 1]^d.
                    PathSpec::Power { c, alpha, .. } => {
                        ("eps", finite(c * (1.0 / n as f64).powf(*alpha), place, n)?)
                    }
                };
                Ok(vec![
                    ("n".to_string(), Value::from(n)),
                    (horizon.0.to_string(), horizon.1),
                ])
            })
            .collect()
    }
}

/// The `field=value` parts of a label (`Point::label`, the tables' `point` and series columns),
/// split where a space is followed by a name and `=`: a value may hold spaces (a branch `a b`).
pub fn label_parts(label: &str) -> Vec<(String, String)> {
    let starts_part = |rest: &str| {
        let name_end = rest.find('=').unwrap_or(0);
        let name = &rest[..name_end];
        name_end > 0
            && name
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.')
    };
    let mut parts: Vec<(String, String)> = Vec::new();
    let mut rest = label;
    while !rest.is_empty() {
        // The next space that begins a part, or the end.
        let end = rest
            .match_indices(' ')
            .map(|(at, _)| at)
            .find(|&at| starts_part(&rest[at + 1..]))
            .unwrap_or(rest.len());
        let part = &rest[..end];
        if let Some((field, value)) = part.split_once('=') {
            parts.push((field.to_string(), value.to_string()));
        } else if let Some(last) = parts.last_mut() {
            last.1.push(' ');
            last.1.push_str(part);
        }
        rest = rest[end..].strip_prefix(' ').unwrap_or("");
    }
    parts
}

/// A path's ε at `n` as a value: a `Value` would hold a number that is not finite as `null`,
/// which leaves the field out of the case.
fn finite(eps: f64, place: &str, n: u64) -> Result<Value, StudyError> {
    match eps.is_finite() {
        true => Ok(Value::from(eps)),
        false => Err(StudyError::new(
            place,
            format!("gives ε = {eps} at n = {n}, not a finite number; choose c and alpha so that ε stays a number"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn points(study: Value) -> Result<Vec<Map<String, Value>>, StudyError> {
        let study = Study::parse(&study.to_string())?;
        Ok(study.expand()?.into_iter().map(|p| p.fields()).collect())
    }

    fn fields(value: Value) -> Map<String, Value> {
        value.as_object().expect("an object").clone()
    }

    #[test]
    fn a_point_writes_its_fields_as_their_map_prints_and_a_swept_value_beats_the_base() {
        let study = Study::parse(
            &json!({
                "name": "t",
                "base": {"z": null, "a": 1.5e-300, "n": 8, "s": "é \"q\"", "o": {"k": [1, 0.1]}},
                "sweep": [{"product": {"n": [16], "b": ["x"]}}, {"zip": {"m": [2], "a": [3]}}],
                "derive": {"eps": "m * h"},
            })
            .to_string(),
        )
        .unwrap();
        let points = study.expand().unwrap();
        let point = &points[0];
        let mut written = Vec::new();
        point.write_fields(&mut written).unwrap();
        let fields = point.fields();
        assert_eq!(
            String::from_utf8(written).unwrap(),
            Value::Object(fields.clone()).to_string()
        );
        assert_eq!(
            (fields["n"].clone(), fields["a"].clone()),
            (json!(16), json!(3))
        );
        assert_eq!(point.get("eps"), Some(&json!(2.0 / 16.0)));
        assert_eq!(point.get("z"), Some(&Value::Null));
        assert_eq!(point.label(), "b=x n=16 a=3 m=2 eps=0.125");
    }

    #[test]
    fn a_sweep_is_counted_before_it_is_made_and_refused_past_the_limit() {
        let values: Vec<u64> = (0..100).collect();
        let huge = json!({
            "name": "s", "base": {},
            "sweep": [{"product": {"a": values, "b": values, "c": values}},
                      {"branches": {"x": [{"zip": {"d": values}}], "y": [{"path": {"kind": "fixed_m", "m": 2, "n": values}}]}}],
            "repeat": 3
        });
        let e = points(huge).unwrap_err();
        assert_eq!(e.field, "sweep");
        // 100³ × (100 + 100) × 3, none of them made.
        assert!(
            e.message.contains("expands to 600000000 points"),
            "{}",
            e.message
        );
        let fits = json!({"name": "s", "base": {}, "sweep": [{"product": {"a": values, "b": values}}], "repeat": 3});
        assert_eq!(points(fits).unwrap().len(), 30_000);
    }

    #[test]
    fn a_control_character_anywhere_is_refused_naming_its_place() {
        let study = |extra: Value| {
            let mut s =
                json!({"name": "s", "base": {"dim": 1}, "description": "line one\nline two"});
            s.as_object_mut().unwrap().extend(fields(extra));
            Study::parse(&s.to_string())
        };
        assert!(study(json!({})).is_ok(), "prose may hold newlines");
        let cases = [
            (
                json!({"sweep": [{"branches": {"a\u{1b}[31m": []}}]}),
                "sweep[0].branches.a\\u{1b}[31m",
            ),
            (json!({"where": ["n > 1\n"]}), "where[0]"),
            (
                json!({"figures": [{"name": "f", "kind": "convergence", "title": "t\r"}]}),
                "figures[0].title",
            ),
            (
                json!({"resources": {"queue": "debug\ntouch /tmp/pwned"}}),
                "resources.queue",
            ),
        ];
        for (extra, place) in cases {
            let e = study(extra).unwrap_err();
            assert_eq!(e.field, place);
            assert!(e.message.contains("control character"), "{}", e.message);
        }
    }

    #[test]
    fn branches_are_alternatives_named_in_the_tables_but_not_the_case() {
        let study = Study::parse(
            &json!({
                "name": "s", "base": {"dim": 1},
                "sweep": [
                    {"branches": {
                        "fixed_m": [{"product": {"m": [2, 4], "source": ["local"]}},
                                    {"product": {"n": [8, 16]}}],
                        "fixed_eps": [{"path": {"kind": "fixed_eps", "eps": 0.25, "n": [8, 16]}}]
                    }},
                    {"product": {"kernel": ["constant", "linear"]}}
                ],
                "where": ["branch != 'fixed_eps' || kernel == 'linear'"]
            })
            .to_string(),
        )
        .unwrap();
        let points = study.expand().unwrap();
        let on = |b: &str| {
            points
                .iter()
                .filter(|p| p.branch.as_deref() == Some(b))
                .count()
        };
        assert_eq!((on("fixed_m"), on("fixed_eps"), points.len()), (8, 2, 10));
        for p in &points {
            assert!(
                !p.fields().contains_key("branch"),
                "the solver must not see it"
            );
            assert!(p
                .label()
                .starts_with(&format!("branch={}", p.branch.as_ref().unwrap())));
        }
        // The tables' columns: the branch, then what any branch sweeps.
        assert_eq!(
            fields_telling_apart(&points),
            ["branch", "n", "eps", "kernel", "m", "source"]
        );
        // A refinement series runs along n within one branch.
        let eps_series: Vec<String> = points
            .iter()
            .filter(|p| p.branch.as_deref() == Some("fixed_eps"))
            .map(|p| p.series().refinement)
            .collect();
        assert_eq!(eps_series, ["branch=fixed_eps kernel=linear"; 2]);
        // The other branch's path moves m with n; this one's m stays in its series.
        let m_series = points
            .iter()
            .find(|p| p.branch.as_deref() == Some("fixed_m"))
            .map(|p| p.series().refinement);
        assert_eq!(
            m_series.as_deref(),
            Some("branch=fixed_m m=2 source=local kernel=constant")
        );
        let bad = Study::parse(
            &json!({"name": "s", "base": {}, "sweep": [{"branches": {"a": [{"product": {"n": []}}]}}]})
                .to_string(),
        )
        .unwrap()
        .expand()
        .unwrap_err();
        assert_eq!(bad.field, "sweep[0].branches.a[0].product.n", "{bad}");
    }

    #[test]
    fn a_branch_may_have_its_own_where_and_repeat() {
        let study = Study::parse(
            &json!({
                "name": "s", "base": {"dim": 1, "n": 16},
                "sweep": [{"branches": {
                    "threads": {"sweep": [{"product": {"threads": [1, 2, 4]}}],
                                "where": ["threads <= 2"], "repeat": 3},
                    "steps": [{"zip": {"cfl": [0.25, 0.5], "dt": [null, 0.001]}}]
                }}],
                // Spans branches: `threads` is read only where the branch has it.
                "where": ["branch != 'threads' || threads >= 1"]
            })
            .to_string(),
        )
        .unwrap();
        let points = study.expand().unwrap();
        let on = |b: &str| {
            points
                .iter()
                .filter(|p| p.branch.as_deref() == Some(b))
                .map(|p| (p.get("threads").cloned(), p.repeat))
                .collect::<Vec<_>>()
        };
        let threads: Vec<_> = [1, 2]
            .iter()
            .flat_map(|&t| (0..3).map(move |r| (Some(json!(t)), r)))
            .collect();
        assert_eq!(on("threads"), threads);
        assert_eq!(on("steps"), [(None, 0), (None, 0)]);
        // `null` in a zip leaves the field out of the case (here: dt from cfl).
        assert_eq!(points[0].get("dt"), Some(&Value::Null));

        let refused = |branches: Value| {
            Study::parse(
                &json!({"name": "s", "base": {}, "sweep": [{"branches": branches}]}).to_string(),
            )
            .and_then(|s| s.expand())
            .unwrap_err()
        };
        let e = refused(json!({"a": {"sweep": [], "where": ["thread > 1"]}}));
        assert_eq!(e.field, "sweep[0].branches.a.where[0]", "{e}");
        assert!(e.message.contains("unknown name `thread`"), "{e}");
        let e = refused(json!({"a": {"repeat": 0}}));
        assert_eq!(e.field, "sweep[0].branches.a.repeat", "{e}");
        let e = refused(json!({"a": {"sweep": [{"branches": {"a": []}}]}}));
        assert!(e.message.contains("give each branch its own name"), "{e}");
        let e = refused(json!({"a": {"repeats": 2}}));
        assert!(e.message.contains("did you mean `repeat`?"), "{e}");
    }

    #[test]
    fn study_files_may_carry_comments_or_be_toml() {
        let commented = r#"
            // a first study
            {
              "name": "s", /* results/s/ */
              "base": {"dim": 1, "note": "a // in a string stays"},
              "sweep": [{"product": {"n": [8, 16]}}]  # shell style too
            }"#;
        let toml = r#"
            name = "s"
            [base]
            dim = 1
            note = "a // in a string stays"
            [[sweep]]
            product = { n = [8, 16] }
        "#;
        let json = Study::parse(commented).unwrap().expand().unwrap();
        let from_toml = Study::parse_toml(toml).unwrap().expand().unwrap();
        assert_eq!(json, from_toml);
        assert_eq!(json[1].fields()["note"], "a // in a string stays");
        // Comments become spaces: an error still names its line in the file.
        let error = Study::parse("// one\n// two\n{\"name\": }").unwrap_err();
        assert!(error.message.contains("line 3"), "{error}");
        let error = Study::parse_toml("name = \"s\"\nname = \"t\"").unwrap_err();
        assert!(error.message.contains("not valid TOML"), "{error}");
        // nan and inf are no values (a `Value` would hold them as null: "not given"), and a
        // date is no number.
        for (text, place) in [
            ("[base]\ndt = nan", "base.dt"),
            (
                "[[sweep]]\nproduct = { dt = [0.1, inf] }",
                "sweep[0].product.dt[1]",
            ),
            ("timeout_s = inf", "timeout_s"),
        ] {
            let error = Study::parse_toml(&format!("name = \"s\"\n{text}")).unwrap_err();
            assert!(
                error.message.contains(place) && error.message.contains("not a finite number"),
                "{text}: {error}"
            );
        }
        let error = Study::parse_toml("name = \"s\"\n[base]\nt_end = 1979-05-27").unwrap_err();
        assert!(error.message.contains("quote it"), "{error}");
        let error = Study::parse("\u{feff}{\"name\": \"s\", \"base\": {}}").unwrap_err();
        assert!(error.message.contains("byte-order mark"), "{error}");
        let error = Study::parse_toml("name = \"s\"\n[base]\n[[sweep]]\nproduct = { n = [] }")
            .unwrap()
            .expand()
            .unwrap_err();
        assert_eq!(error.field, "sweep[0].product.n");
    }

    #[test]
    fn product_and_zip_groups_multiply() {
        let got = points(json!({
            "name": "s", "base": {"dim": 1},
            "sweep": [
                {"product": {"n": [8, 16], "m": [2, 3]}},
                {"zip": {"threads": [1, 2], "ranks": [2, 1]}}
            ]
        }))
        .unwrap();
        let mut expected = Vec::new();
        for (m, n) in [(2, 8), (3, 8), (2, 16), (3, 16)] {
            for (threads, ranks) in [(1, 2), (2, 1)] {
                expected.push(fields(json!({
                    "dim": 1, "n": n, "m": m, "threads": threads, "ranks": ranks
                })));
            }
        }
        // Axes of a product vary in name order, the last fastest.
        expected.sort_by_key(|f| (f["m"].as_u64(), f["n"].as_u64()));
        let mut got_sorted = got.clone();
        got_sorted.sort_by_key(|f| (f["m"].as_u64(), f["n"].as_u64()));
        assert_eq!(got.len(), 8);
        assert_eq!(got_sorted, expected);
    }

    #[test]
    fn derived_fields_paths_filters_and_repeats() {
        let study = Study::parse(
            &json!({
                "name": "s", "base": {"dim": 2},
                "sweep": [
                    {"path": {"kind": "fixed_m", "m": 3, "n": [16, 32]}},
                    {"product": {"px": [1, 2], "py": [1, 2]}}
                ],
                "derive": {"ranks": "px * py", "eps_check": "m * h"},
                "where": ["ranks <= 2"],
                "repeat": 2
            })
            .to_string(),
        )
        .unwrap();
        let points = study.expand().unwrap();
        // 2 sizes × 3 shapes with px·py ≤ 2, twice each.
        assert_eq!(points.len(), 12);
        let first = points[0].fields();
        assert_eq!(first["n"], json!(16));
        assert_eq!(first["m"], json!(3));
        assert_eq!(first["ranks"], json!(1));
        assert_eq!(first["eps_check"], json!(3.0 / 16.0));
        assert_eq!((points[0].repeat, points[1].repeat), (0, 1));
        assert!(points
            .iter()
            .all(|p| p.fields()["ranks"].as_u64() <= Some(2)));

        let eps_paths = points_of_path(json!({"kind": "fixed_eps", "eps": 0.25, "n": [8, 16]}));
        assert_eq!(eps_paths, vec![(8, json!(0.25)), (16, json!(0.25))]);
        let power = points_of_path(json!({"kind": "power", "c": 2.0, "alpha": 0.5, "n": [4, 16]}));
        assert_eq!(power, vec![(4, json!(1.0)), (16, json!(0.5))]);
    }

    #[test]
    fn series_hold_all_but_the_grid_or_the_workers_fixed() {
        let series = |study: Value| -> Vec<(String, String)> {
            let study = Study::parse(&study.to_string()).unwrap();
            let points = study.expand().unwrap();
            points
                .into_iter()
                .map(|p| p.series())
                .map(|s| (s.refinement, s.scaling))
                .collect()
        };
        // A product moves only its `n`; a zip moves all its fields with its worker counts.
        let got = series(json!({
            "name": "s", "base": {},
            "sweep": [
                {"product": {"n": [8, 16], "m": [2]}},
                {"zip": {"threads": [1, 2], "ranks": [2, 1]}}
            ]
        }));
        let expected = [
            ("m=2 ranks=2 threads=1", "m=2 n=8"),
            ("m=2 ranks=1 threads=2", "m=2 n=8"),
            ("m=2 ranks=2 threads=1", "m=2 n=16"),
            ("m=2 ranks=1 threads=2", "m=2 n=16"),
        ];
        let expected: Vec<(String, String)> = expected
            .iter()
            .map(|(r, s)| (r.to_string(), s.to_string()))
            .collect();
        assert_eq!(got, expected);
        // A path moves its horizon with n; derived fields are left out of the names.
        let got = series(json!({
            "name": "s", "base": {},
            "sweep": [
                {"path": {"kind": "power", "c": 1.0, "alpha": 0.5, "n": [4, 16]}},
                {"product": {"px": [1, 2], "method": ["nonlocal"]}}
            ],
            "derive": {"ranks": "px"}
        }));
        assert_eq!(
            got[0],
            (
                "method=nonlocal px=1".into(),
                "n=4 eps=0.5 method=nonlocal".into()
            )
        );
        assert_eq!(
            got[3],
            (
                "method=nonlocal px=2".into(),
                "n=16 eps=0.25 method=nonlocal".into()
            )
        );
    }

    fn points_of_path(path: Value) -> Vec<(u64, Value)> {
        points(json!({"name": "s", "base": {}, "sweep": [{"path": path}]}))
            .unwrap()
            .into_iter()
            .map(|f| (f["n"].as_u64().unwrap(), f["eps"].clone()))
            .collect()
    }

    #[test]
    fn labels_split_into_their_parts_where_a_name_and_equals_follow() {
        assert_eq!(
            label_parts("branch=a b n=16 kernel=constant"),
            [
                ("branch".to_string(), "a b".to_string()),
                ("n".to_string(), "16".to_string()),
                ("kernel".to_string(), "constant".to_string())
            ]
        );
        assert!(label_parts("").is_empty());
        assert_eq!(label_parts("cfl=null dt=1e-8").len(), 2);
        assert_eq!(
            label_parts("branch=x=y z").len(),
            1,
            "a value may hold = and spaces"
        );
    }

    #[test]
    fn malformed_studies_name_the_place() {
        let place = |study: Value| points(study).unwrap_err().field;
        assert_eq!(place(json!({"name": "s"})), "base");
        assert_eq!(
            place(json!({"name": "s", "base": {}, "colour": 1})),
            "colour"
        );
        assert_eq!(place(json!({"name": "a b", "base": {}})), "name");
        assert_eq!(
            place(json!({"name": "s", "base": {}, "repeat": 0})),
            "repeat"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {}, "sweep": [{"zip": {"n": [1, 2], "m": [1]}}]})),
            "sweep[0].zip.n"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {}, "sweep": [{"product": {"n": []}}]})),
            "sweep[0].product.n"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {}, "sweep": [
                {"product": {"n": [1]}}, {"product": {"n": [2]}}
            ]})),
            "sweep[1].n"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {"n": 4}, "derive": {"ranks": "px * 2"}})),
            "derive.ranks"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {"n": 4}, "where": ["n + 1"]})),
            "where[0]"
        );
        assert_eq!(
            place(
                json!({"name": "s", "base": {}, "sweep": [{"path": {"kind": "fixed_m", "m": 2, "n": [0]}}]})
            ),
            "sweep[0].path.n"
        );
        assert_eq!(place(json!({"name": "a".repeat(256), "base": {}})), "name");
        assert_eq!(
            place(json!({"name": "s", "base": {},
                "figures": [{"name": "f".repeat(201), "kind": "convergence"}]})),
            "figures[0].name"
        );
        assert_eq!(
            place(json!({"name": "s", "base": {}, "sweep": [
                {"path": {"kind": "power", "c": 1e300, "alpha": -100.0, "n": [4]}}
            ]})),
            "sweep[0].path"
        );
        // JSON text, not a Value: a key given twice in a map (`base`) would keep the last.
        let twice = Study::parse(r#"{"name": "s", "base": {"dim": 2, "n": 8, "dim": 1}}"#);
        let error = twice.map(|_| ()).unwrap_err();
        assert_eq!(error.field, "file");
        assert!(
            error.message.contains("the key `dim` is given twice"),
            "{error}"
        );
    }
}
