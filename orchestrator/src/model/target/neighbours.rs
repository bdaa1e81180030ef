//! Once a run has met the target, the cheaper runs beside it. The model's cheapest lies where
//! the model says; the cheapest run is found where the runs say: from the cheapest run that met
//! the target, one field at a time, a coarser grid at its step and a larger step on its grid (up
//! to the largest stable step and t_end), each run where the model, scaled to that run's
//! measured error, says it may meet, and narrowed between a neighbour that met and one that
//! missed to a quarter of `rtol` in each field: the cost grows faster than either field (an
//! explicit step ∝ h² makes a 2D run's cost grow as n⁴), and the answer's cost is to be within
//! `rtol` of the cheapest. A cheaper neighbour that meets becomes the run the walk starts from.

use super::{Aimed, Axes, ErrorModel, Level, Probe, TargetSpec};

/// The field a neighbour differs in.
#[derive(Clone, Copy, PartialEq)]
enum Along {
    Space,
    Time,
}

impl TargetSpec {
    /// The next neighbour of the cheapest run that met the target worth running, or none: along
    /// each field the coarser side is known (a run within `rtol`/4 missed, or was unstable), is the
    /// coarsest there is, or is predicted to miss by more than `margin`.
    pub(super) fn cheaper_neighbour(
        &self,
        aimed: &Aimed,
        model: &ErrorModel,
        axes: &Axes,
        margin: f64,
    ) -> Option<Probe> {
        let best = aimed.answer(self)?;
        [Along::Space, Along::Time]
            .into_iter()
            .filter_map(|along| self.neighbour(along, &best, aimed, model, axes, margin))
            .find(|probe| !aimed.has_run(probe))
    }

    /// The neighbour of `best` along one field, where one is worth running.
    fn neighbour(
        &self,
        along: Along,
        best: &Level,
        aimed: &Aimed,
        model: &ErrorModel,
        axes: &Axes,
        margin: f64,
    ) -> Option<Probe> {
        let time = best.time?;
        // How coarse a run is along the field: its spacing, or its step.
        let coarseness = |value: f64, t: f64| match along {
            Along::Space => axes.h(value),
            Along::Time => axes.step(t, axes.h(value)),
        };
        let on_line = |value: f64, t: f64| match along {
            Along::Space => t == time,
            Along::Time => value == best.value,
        };
        let here = coarseness(best.value, time);
        // The nearest run on the line coarser than `best`, and its level (none: unstable).
        let runs = (aimed
            .levels
            .iter()
            .map(|l| (l.value, l.time.unwrap_or(time), Some(l))))
        .chain(aimed.unstable.iter().map(|p| (p[0], p[1], None)));
        let nearest = (runs.clone())
            .filter(|&(v, t, _)| on_line(v, t) && coarseness(v, t) > here * (1.0 + 1e-12))
            .min_by(|a, b| coarseness(a.0, a.1).total_cmp(&coarseness(b.0, b.1)));
        // The nearest finer run on the line that met the target: the walk's last step.
        let finer_met = runs
            .filter(|&(v, t, level)| {
                on_line(v, t)
                    && coarseness(v, t) < here * (1.0 - 1e-12)
                    && level.is_some_and(|l| self.meets(l, Some(model)))
            })
            .map(|(v, t, _)| (v, t))
            .max_by(|a, b| coarseness(a.0, a.1).total_cmp(&coarseness(b.0, b.1)));
        let aim = match nearest {
            // A cheaper run met but was measured costlier (a timing's noise): none cheaper here.
            Some((_, _, Some(level))) if self.meets(level, Some(model)) => return None,
            Some((v, t, level)) => {
                let far = coarseness(v, t);
                if far / here <= 1.0 + self.walk_tolerance() {
                    return None;
                }
                // The crossing the two predict (log–log; the middle where it was unstable), kept
                // in the middle half of the interval so that a poor prediction still narrows it.
                let guess = match level {
                    Some(l) => {
                        let slope = (l.error / best.error).ln() / (far / here).ln();
                        here * (self.below / best.error).powf(1.0 / slope.max(1e-3))
                    }
                    None => (here * far).sqrt(),
                };
                let span = (far / here).ln();
                guess.clamp(here * (0.25 * span).exp(), here * (0.75 * span).exp())
            }
            // A walk whose last step along the line met goes on at up to the square of that
            // step (at most twice as coarse): there the runs have told more than the model.
            None => match finer_met {
                Some((v, t)) => {
                    here * (here / coarseness(v, t))
                        .powi(2)
                        .clamp(1.0 + self.walk_tolerance(), 2.0)
                }
                None => self.predicted_neighbour(along, best, model, axes, margin)?,
            },
        };
        self.probe_at(along, best, aim, axes)
    }

    /// With no run coarser on the line: the coarsest the model, scaled to `best`'s measured
    /// error, says meets the target, the walk's tolerance coarser at least and twice as coarse
    /// at most; none where even that step is predicted to miss by more than `margin`.
    fn predicted_neighbour(
        &self,
        along: Along,
        best: &Level,
        model: &ErrorModel,
        axes: &Axes,
        margin: f64,
    ) -> Option<f64> {
        let scale = best.error / model.error(best.h, best.dt);
        let time = best.time?;
        let predicted = |c: f64| {
            scale
                * match along {
                    Along::Space => model.error(c, axes.step(time, c)),
                    Along::Time => model.error(best.h, c),
                }
        };
        let here = match along {
            Along::Space => best.h,
            Along::Time => best.dt,
        };
        let least = here * (1.0 + self.walk_tolerance());
        let may_meet = predicted(least) <= self.below * margin;
        if !may_meet {
            return None;
        }
        let coarsest = (0..=40)
            .map(|k| here * 2f64.powf(k as f64 / 40.0))
            .filter(|&c| predicted(c) <= self.below)
            .fold(least, f64::max);
        Some(coarsest)
    }

    /// How close in each field the walk narrows: a quarter of `rtol`.
    fn walk_tolerance(&self) -> f64 {
        self.rtol / 4.0
    }

    /// What "cheapest" means, as the answers say it: in space and time `the cheapest run to
    /// within 2.5 % in each field` (the walk's tolerance); along one field `the coarsest n to
    /// within 10 % or one node`.
    pub fn cheapest_means(&self) -> String {
        let percent = |tolerance: f64| schema::text::number(100.0 * tolerance);
        match (&self.time, self.is_grid()) {
            (Some(_), _) => format!(
                "the cheapest run to within {} % in each field",
                percent(self.walk_tolerance())
            ),
            (None, true) => format!(
                "the coarsest {} to within {} % or one node",
                self.field,
                percent(self.rtol)
            ),
            (None, false) => format!(
                "the coarsest {} to within {} %",
                self.field,
                percent(self.rtol)
            ),
        }
    }

    /// The probe `best` moved along the field to coarseness `c` (a spacing or a step): a whole n
    /// at least one node coarser, or a whole number of steps at least one fewer, within the
    /// largest stable step and t_end; none where there is no coarser one.
    fn probe_at(&self, along: Along, best: &Level, c: f64, axes: &Axes) -> Option<Probe> {
        let time = best.time?;
        match along {
            Along::Space => {
                let value = self.value_of(self.fineness(best.value) * best.h / c);
                let value = match self.is_grid() {
                    true if best.value <= 1.0 => return None,
                    true => value.min(best.value - 1.0),
                    false => value,
                };
                (value != best.value).then(|| vec![value, time])
            }
            Along::Time => {
                let largest = match axes.stable(best.h) {
                    Some(stable) => axes.t_end.min(stable * (1.0 - 1e-9)),
                    None => axes.t_end,
                };
                let steps_here = (axes.t_end / best.dt).round();
                // The nearest whole number of steps, one more where that is above the largest.
                let mut steps = (axes.t_end / c.min(largest)).round().max(1.0);
                if axes.t_end / steps > largest * (1.0 + 1e-9) {
                    steps += 1.0;
                }
                let steps = steps.min(steps_here - 1.0);
                if steps < 1.0 || axes.t_end / steps > largest * (1.0 + 1e-9) {
                    return None;
                }
                let dt = axes.t_end / steps;
                Some(vec![best.value, axes.value_of_step(dt, best.h)])
            }
        }
    }
}
