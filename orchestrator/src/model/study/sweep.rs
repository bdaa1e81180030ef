//! How a sweep group expands: the assignments of a `product`, a `zip` and a path in the
//! (ε, h) plane, each checked where it is written.

use super::*;

impl SweepGroup {
    /// The number of points the group gives, counted without making them.
    pub(super) fn size(&self) -> u128 {
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
    pub(super) fn moving_with(&self, triggers: &[&str], branch: Option<&str>) -> Vec<String> {
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
    pub(super) fn stages(&self, g: usize) -> Result<Vec<Vec<Pairs>>, StudyError> {
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

    pub(super) fn assignments(&self, g: usize) -> Result<Vec<Pairs>, StudyError> {
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
    pub(super) fn assignments(&self, place: &str) -> Result<Vec<Pairs>, StudyError> {
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
