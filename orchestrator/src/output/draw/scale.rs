//! An axis's coordinates and ticks: linear or log₁₀, the ticks round, one notation per axis.

use super::chart::*;
use crate::console::numbers_alike;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;
use std::ops::Range;

impl Axis {
    pub fn linear(label: impl Into<String>) -> Axis {
        Axis {
            label: label.into(),
            log: false,
            include: Vec::new(),
            whole: false,
            around: None,
        }
    }

    /// Linear, or zoomed in around `centre` (`Axis::around`) when most values crowd within 5 %
    /// of it: the resolution is their smallest distance from it.
    pub fn zooming(label: impl Into<String>, centre: f64, values: &[f64]) -> Axis {
        let distances: Vec<f64> = values
            .iter()
            .map(|v| (v - centre).abs())
            .filter(|d| d.is_finite() && *d > 0.0)
            .collect();
        let near = values
            .iter()
            .filter(|v| (*v - centre).abs() <= 0.05 * centre.abs())
            .count();
        let crowded = near * 2 > values.len() && distances.len() >= 2;
        let resolution = distances
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
            .max(1e-9);
        Axis {
            around: crowded.then_some((centre, resolution)),
            ..Axis::linear(label)
        }
    }

    /// The same axis, ticked on whole numbers.
    pub fn counting(self) -> Axis {
        Axis {
            whole: true,
            ..self
        }
    }

    /// Log when the values are positive and span a decade or more.
    pub fn fitting(label: impl Into<String>, values: impl IntoIterator<Item = f64>) -> Axis {
        let (lo, hi) = span(values.into_iter().filter(|v| v.is_finite()));
        Axis {
            log: lo > 0.0 && hi / lo >= 10.0,
            ..Axis::linear(label)
        }
    }

    /// Log when no value is negative and some are positive, however narrow their span: orders
    /// are read as slopes. A zero (an error exact to the last bit) has no place on it.
    pub fn log_if_positive(
        label: impl Into<String>,
        values: impl IntoIterator<Item = f64>,
    ) -> Axis {
        let (lo, hi) = span(values.into_iter().filter(|v| v.is_finite()));
        Axis {
            log: lo >= 0.0 && hi > 0.0,
            ..Axis::linear(label)
        }
    }

    pub(super) fn to(&self, v: f64) -> f64 {
        match (self.log, self.around) {
            (_, Some((c, delta))) => (v - c).signum() * (1.0 + (v - c).abs() / delta).log10(),
            (true, None) => v.log10(),
            (false, None) => v,
        }
    }

    pub(super) fn from(&self, t: f64) -> f64 {
        match (self.log, self.around) {
            (_, Some((c, delta))) => c + t.signum() * delta * (10f64.powf(t.abs()) - 1.0),
            (true, None) => 10f64.powf(t),
            (false, None) => t,
        }
    }

    /// The values it shows in drawing coordinates: finite, and positive on a log axis.
    pub(super) fn shown(&self, values: impl Iterator<Item = f64>) -> Vec<f64> {
        values
            .chain(self.include.iter().copied())
            .filter(|v| v.is_finite() && (!self.log || *v > 0.0))
            .map(|v| self.to(v))
            .collect()
    }

    /// The axis's range in drawing coordinates, from the values it shows, padded.
    pub(super) fn range(shown: &[f64]) -> (f64, f64) {
        let (lo, hi) = span(shown.iter().copied());
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
        (lo - pad, hi + pad)
    }

    /// Tick positions in drawing coordinates over the range, given the values measured.
    pub(super) fn ticks(&self, (lo, hi): (f64, f64), shown: &[f64]) -> Vec<f64> {
        if self.around.is_some() {
            // The values measured, at most ten of them: on a zoomed scale round numbers are
            // sparse exactly where the data is dense.
            let mut own = shown.to_vec();
            own.sort_by(f64::total_cmp);
            own.dedup_by(|a, b| (*a - *b).abs() < 0.05);
            let every = own.len().div_ceil(10).max(1);
            return own
                .into_iter()
                .step_by(every)
                .filter(|t| (lo..=hi).contains(t))
                .collect();
        }
        if !self.log {
            let mut ticks = linear_ticks(lo, hi);
            if self.whole {
                ticks.retain(|t| t.fract() == 0.0);
            }
            return ticks;
        }
        let decades = (lo.floor() as i32)..=(hi.ceil() as i32);
        let mut ticks: Vec<f64> = if hi - lo <= 2.5 {
            decades
                .flat_map(|k| [1.0f64, 2.0, 5.0].map(|m| f64::from(k) + m.log10()))
                .collect()
        } else {
            let step = ((hi - lo) / 8.0).ceil() as i32;
            decades.filter(|k| k % step == 0).map(f64::from).collect()
        };
        ticks.retain(|t| (lo..=hi).contains(t));
        if ticks.len() < 3 {
            // Less than a factor 2.5 (h from 1/32 to 1/64): the values themselves, at most eight.
            let mut own = shown.to_vec();
            own.sort_by(f64::total_cmp);
            own.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            let every = own.len().div_ceil(8).max(1);
            let own: Vec<f64> = own.into_iter().step_by(every).collect();
            if own.len() > ticks.len() {
                return own;
            }
        }
        ticks
    }

    /// The ticks with their labels, in one notation. Ticks from 1 to 10⁵ and more, which
    /// `console::number` writes in full, are written in thousands, millions, …, the power
    /// going into the axis's label.
    pub(super) fn ticked(&self, range: (f64, f64), shown: &[f64]) -> Ticked {
        let ticks = self.ticks(range, shown);
        let values: Vec<f64> = ticks.iter().map(|&t| self.from(t)).collect();
        let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let counts = values.iter().all(|v| *v == 0.0 || v.abs() >= 1.0);
        let in_full = largest >= 1e5 && counts;
        let power = match in_full {
            true => 3 * (largest.log10() / 3.0).floor() as i32,
            false => 0,
        };
        let scaled: Vec<f64> = values.iter().map(|v| v / 10f64.powi(power)).collect();
        Ticked {
            lo: range.0,
            hi: range.1,
            labels: numbers_alike(&scaled),
            ticks,
            power,
        }
    }
}

/// A linear coordinate with the ticks we choose (plotters' own f64 axis picks its ticks itself)
/// and their labels.
#[derive(Clone)]
pub(super) struct Ticked {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) ticks: Vec<f64>,
    pub(super) labels: Vec<String>,
    /// The labels are the values over 10^power.
    pub(super) power: i32,
}

impl Ticked {
    /// Ticks on a linear scale over [lo, hi] (a heat map's sides, a colour bar).
    pub(super) fn linear(lo: f64, hi: f64) -> Ticked {
        Axis::linear("").ticked((lo, hi), &[])
    }

    /// The axis's description, with the power its labels leave out.
    pub(super) fn describe(&self, label: &str) -> String {
        match self.power {
            0 => label.to_string(),
            power => format!("{label} (×1e{power})"),
        }
    }

    pub(super) fn label(&self, t: f64) -> String {
        let at = self.ticks.iter().position(|&k| k == t);
        at.map(|k| self.labels[k].clone()).unwrap_or_default()
    }
}

impl Ranged for Ticked {
    type ValueType = f64;
    type FormatOption = DefaultFormatting;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let fraction = (value - self.lo) / (self.hi - self.lo);
        limit.0 + (f64::from(limit.1 - limit.0) * fraction + 1e-3).floor() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, _hint: Hint) -> Vec<f64> {
        self.ticks.clone()
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

/// (min, max) of the values; (∞, −∞) when there are none.
pub fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    })
}

/// About six ticks at 1, 2 or 5 times a power of ten.
pub(super) fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}
