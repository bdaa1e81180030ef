//! How a search in space and time maps a probe's values to its run's grid spacing and time step,
//! as the runs so far tell: the spacing from the first run's (h ∝ 1/fineness), the step from the
//! temporal value (`dt` itself, or `cfl` times the stable step), and an explicit integrator's
//! stable step fitted from the runs' own (`fit::stable_step`).

use super::{fit, Aimed, TargetSpec};

pub(super) struct Axes<'a> {
    spec: &'a TargetSpec,
    /// The first run's spacing and its spatial value's fineness.
    h0: f64,
    fineness0: f64,
    /// The first run's step and the study's first temporal value: a `cfl` with no stable step
    /// known is a step in proportion to them.
    dt0: f64,
    time0: f64,
    /// The time the runs reach.
    pub t_end: f64,
    /// The stable step at a spacing (explicit integrators), fitted from the runs' and lowered
    /// 2 % below each step the solver refused or that diverged.
    stable: Option<Box<dyn Fn(f64) -> f64 + 'a>>,
}

impl<'a> Axes<'a> {
    /// The axes of `aimed`'s runs; none before a run gave a level.
    pub fn of(spec: &'a TargetSpec, aimed: &Aimed) -> Option<Self> {
        let time = spec.time.as_ref()?;
        let first = aimed.levels.first()?;
        let fitted = fit::stable_step(
            &(aimed.levels.iter())
                .filter_map(|l| Some((l.h, l.stable?)))
                .collect::<Vec<_>>(),
        );
        let mut axes = Axes {
            spec,
            h0: first.h,
            fineness0: spec.fineness(spec.start),
            dt0: first.dt,
            time0: time.start.max(f64::MIN_POSITIVE),
            t_end: first.t_end,
            stable: None,
        };
        // A step the solver refused (or that diverged) lies above the stable one, whatever the
        // fit says.
        let lowered = match (&fitted, time.field.as_str()) {
            (Some(fitted), "dt") => (aimed.unstable.iter())
                .map(|p| p[1] / fitted(axes.h(p[0])) * 0.98)
                .fold(1.0, f64::min),
            _ => 1.0,
        };
        axes.stable = fitted.map(|fitted| Box::new(move |h: f64| fitted(h) * lowered) as Box<_>);
        Some(axes)
    }

    /// The grid spacing of a spatial value.
    pub fn h(&self, value: f64) -> f64 {
        self.h0 * self.fineness0 / self.spec.fineness(value)
    }

    /// The stable step at spacing h, where an explicit integrator has one.
    pub fn stable(&self, h: f64) -> Option<f64> {
        self.stable.as_ref().map(|stable| stable(h))
    }

    fn is_cfl(&self) -> bool {
        self.spec.time.as_ref().is_some_and(|t| t.field == "cfl")
    }

    /// The step of a temporal value at spacing h.
    pub fn step(&self, value: f64, h: f64) -> f64 {
        match (self.is_cfl(), self.stable(h)) {
            (true, Some(stable)) => value * stable,
            (true, None) => value * self.dt0 / self.time0,
            (false, _) => value,
        }
    }

    /// The temporal value of a step dt at spacing h.
    pub fn value_of_step(&self, dt: f64, h: f64) -> f64 {
        match (self.is_cfl(), self.stable(h)) {
            (true, Some(stable)) => dt / stable,
            (true, None) => dt / self.dt0 * self.time0,
            (false, _) => dt,
        }
    }
}
