//! An error that is not monotone in a field: where ε/h crosses whole numbers at a fixed horizon,
//! the error of neighbouring grids can differ thirtyfold. No fit of C·h^p explains a rise towards
//! finer resolution, and an answer there is a coincidence a neighbouring grid does not keep: the
//! candidate says so, and along one field answers only with a run whose finer runs all meet the
//! target, one of them at least.

use super::{Aimed, Level, Probe, Reached, TargetSpec};
use schema::text::number;

/// A rise of the error towards finer resolution by more than this factor is no discretization's
/// (whose error falls, or stalls at a floor within `PLATEAU`'s 10 %).
const RISE: f64 = 1.5;

impl Aimed {
    /// The first place its runs show the error rising towards finer resolution along a field
    /// (its other field held), beyond `RISE`: `error not monotone in n: 2.3e-6 at 128, 2.9e-5
    /// at 144`.
    pub fn erratic(&self, spec: &TargetSpec) -> Option<String> {
        // Along the first field: runs of one temporal value (all, along one field); along the
        // step: runs of one spatial value.
        let mut fields: Vec<(&str, Vec<&Level>)> =
            lines(&self.levels, |l| l.time.map(f64::to_bits))
                .into_iter()
                .map(|line| (spec.field.as_str(), line))
                .collect();
        if let Some(time) = &spec.time {
            let by_value = lines(&self.levels, |l| l.value.to_bits());
            fields.extend(by_value.into_iter().map(|line| (time.field.as_str(), line)));
        }
        fields.into_iter().find_map(|(field, mut line)| {
            // Coarse to fine: the first field by its fineness, a step by its size (larger first).
            match field == spec.field {
                true => {
                    line.sort_by(|a, b| spec.fineness(a.value).total_cmp(&spec.fineness(b.value)))
                }
                false => line.sort_by(|a, b| b.dt.total_cmp(&a.dt)),
            }
            let at = |l: &Level| match field == spec.field {
                true => number(l.value),
                false => number(l.time.unwrap_or(l.dt)),
            };
            line.windows(2)
                .find(|pair| pair[1].error > RISE * pair[0].error)
                .map(|pair| {
                    format!(
                        "error not monotone in {field}: {} at {}, {} at {}",
                        number(pair[0].error),
                        at(pair[0]),
                        number(pair[1].error),
                        at(pair[1])
                    )
                })
        })
    }

    /// Along one field where the error is erratic: the coarsest run that meets the target whose
    /// finer runs all meet it too, one at least; none while there is no such run.
    pub(super) fn robust(&self, spec: &TargetSpec) -> Option<&Level> {
        let mut line: Vec<&Level> = self.levels.iter().collect();
        line.sort_by(|a, b| spec.fineness(a.value).total_cmp(&spec.fineness(b.value)));
        let meets = |l: &&Level| l.error <= spec.below;
        (0..line.len().saturating_sub(1))
            .find(|&k| line[k..].iter().all(meets))
            .map(|k| line[k])
    }
}

impl TargetSpec {
    /// A search along one field that ended (`reached`) where its runs show an erratic error:
    /// ended still where a run has finer runs that all meet the target, else one run finer than
    /// the finest (by `rtol`, or one node), until one has.
    pub(super) fn robust_along_one(
        &self,
        aimed: &Aimed,
        reached: Reached,
    ) -> Result<Probe, Reached> {
        let ended = matches!(reached, Reached::Found | Reached::AtCoarsest);
        if !ended || aimed.erratic(self).is_none() || aimed.robust(self).is_some() {
            return Err(reached);
        }
        if aimed.levels.len() + aimed.unstable.len() >= self.most_probes() {
            return Err(Reached::Budget);
        }
        let finest = (aimed.levels.iter())
            .map(|l| self.fineness(l.value))
            .fold(0.0, f64::max);
        let mut value = self.value_of(finest * (1.0 + self.rtol));
        if self.is_grid() {
            value = value.max(finest + 1.0);
        }
        Ok(vec![value])
    }
}

/// The levels grouped by `key` (the field held along a line), in the order first met.
fn lines<K: PartialEq>(levels: &[Level], key: impl Fn(&Level) -> K) -> Vec<Vec<&Level>> {
    let mut lines: Vec<(K, Vec<&Level>)> = Vec::new();
    for l in levels {
        let k = key(l);
        match lines.iter_mut().find(|(held, _)| *held == k) {
            Some((_, line)) => line.push(l),
            None => lines.push((k, vec![l])),
        }
    }
    lines.into_iter().map(|(_, line)| line).collect()
}
