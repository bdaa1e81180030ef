//! Errors against an exact solution and the conserved-quantity diagnostics, reduced in a fixed
//! order so that the numbers do not depend on the thread count.

use crate::threads::BLOCK;
use rayon::prelude::*;

/// The step's amplification as measured: from L_h's spectrum with an interval that holds it,
/// or from a rough field's growth (no interval).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Amplification {
    /// From the spectrum, the step's spectral radius: |R(dt·λ)| largest over L_h's extreme
    /// eigenvalues, the interval's top when the interval holds 1 (never called stable on a
    /// guess). From a rough field, its growth per step.
    pub value: f64,
    /// The interval that holds the spectral radius (from the spectrum only).
    pub bounds: Option<(f64, f64)>,
    /// Applications of L_h spent on it (where they are counted).
    pub applications: Option<usize>,
}

/// Σᵢ term(i) for i < len, with the same rounding whatever the number of threads.
pub(crate) fn fixed_order_sum(len: usize, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    let partials: Vec<f64> = (0..len.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| (b * BLOCK..len.min((b + 1) * BLOCK)).map(&term).sum())
        .collect();
    partials.iter().sum()
}

/// e^k = h^d Σᵢ |exact(i) − uᵢ|² (\[JD], eq. A.3): the square of the discrete L² error.
pub fn squared_l2_error(exact: impl Fn(usize) -> f64 + Sync, u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(u.len(), |i| (exact(i) - u[i]).powi(2))
}

/// maxᵢ |exact(i) − uᵢ|, with a NaN counted as +∞ (`f64::max` would skip it, and a field of
/// NaN would report an error of 0).
pub fn max_error(exact: impl Fn(usize) -> f64 + Sync, u: &[f64]) -> f64 {
    (0..u.len())
        .into_par_iter()
        .map(|i| magnitude(exact(i) - u[i]))
        .reduce(|| 0.0, f64::max)
}

/// h^d Σᵢ uᵢ.
pub fn total_mass(u: &[f64], volume: f64) -> f64 {
    volume * fixed_order_sum(u.len(), |i| u[i])
}

/// maxᵢ |uᵢ|, with a NaN counted as +∞ so that a blown-up field is never reported as small.
pub fn max_abs(u: &[f64]) -> f64 {
    u.par_chunks(BLOCK)
        .map(block_max_abs)
        .reduce(|| 0.0, f64::max)
}

/// maxᵢ |uᵢ| of a block, NaN counted as +∞, in one pass the compiler vectorises: eight running
/// maxima side by side, and NaNs tracked apart (a running `f64::max` is a serial chain). Inlined
/// always, so a caller compiled for a wider instruction set runs it at that width.
#[inline(always)]
pub fn block_max_abs(u: &[f64]) -> f64 {
    const LANES: usize = 8;
    let mut lanes = [0.0f64; LANES];
    let mut nan = false;
    let chunks = u.chunks_exact(LANES);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (m, &v) in lanes.iter_mut().zip(chunk) {
            let a = v.abs();
            *m = if a > *m { a } else { *m };
            nan |= v.is_nan();
        }
    }
    let rest_max = rest.iter().fold(0.0, |m: f64, &v| m.max(magnitude(v)));
    if nan {
        return f64::INFINITY;
    }
    lanes.into_iter().fold(rest_max, f64::max)
}

/// |v|, or +∞ for a NaN.
#[inline]
pub fn magnitude(v: f64) -> f64 {
    if v.is_nan() {
        f64::INFINITY
    } else {
        v.abs()
    }
}

/// Output times j·interval of a run of `steps` steps of dt: due at the first step at or past
/// each output time not yet reached, and at the last step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Schedule {
    interval: f64,
    dt: f64,
    steps: usize,
    reached: usize,
}

impl Schedule {
    pub fn new(interval: f64, dt: f64, steps: usize) -> Self {
        Schedule {
            interval,
            dt,
            steps,
            reached: 0,
        }
    }

    /// The schedule of a run resumed after `reached` outputs (t = 0's not counted).
    pub fn resume(&mut self, reached: usize) {
        self.reached = reached;
    }

    /// Is step k due? It counts as reached when it is.
    pub fn due(&mut self, k: usize) -> bool {
        let next_output = (self.reached + 1) as f64 * self.interval;
        // Relative slack: an output time reached up to rounding counts as reached.
        let due = self.time(k) >= next_output * (1.0 - 1e-12) || k == self.steps;
        self.reached += usize::from(due);
        due
    }

    /// The time after step k.
    pub fn time(&self, k: usize) -> f64 {
        k as f64 * self.dt
    }
}

pub use schema::record::{Histogram, MassSeries};

/// c_tot(t) sampled as a run goes: the series (what the record carries) and the schedule that
/// says which steps are due.
#[derive(Clone, Debug, PartialEq)]
pub struct MassSampling {
    schedule: Schedule,
    pub series: MassSeries,
}

impl MassSampling {
    /// The sampling of a run of `steps` steps of `dt`, when an output `interval` is given,
    /// starting from c_tot(0) = `c_tot0`.
    pub fn start(interval: Option<f64>, dt: f64, steps: usize, c_tot0: f64) -> Option<Self> {
        interval.map(|interval| MassSampling {
            schedule: Schedule::new(interval, dt, steps),
            series: MassSeries {
                time: vec![0.0],
                c_tot: vec![c_tot0],
            },
        })
    }

    /// The sampling of a run resumed after `reached` samples (t = 0's not counted).
    pub fn resume(&mut self, reached: usize) {
        self.schedule.resume(reached);
    }

    /// Adds c_tot after step k if the sampling exists and step k is due; `c_tot` is evaluated
    /// only then.
    pub fn observe_if(sampling: &mut Option<Self>, k: usize, c_tot: impl FnOnce() -> f64) {
        let Some(sampling) = sampling else { return };
        if sampling.schedule.due(k) {
            sampling.series.time.push(sampling.schedule.time(k));
            sampling.series.c_tot.push(c_tot());
        }
    }
}

/// The histogram of u over [min u, max u] in `bins` bins (\[HPCSE]'s compute_histogram), counted
/// in parallel by blocks; integer counts make the result independent of the thread count. A
/// field that is not finite everywhere has no histogram.
pub fn histogram(u: &[f64], bins: usize) -> Option<Histogram> {
    let (lo, hi) = u.par_iter().map(|&v| (v, v)).reduce(
        || (f64::INFINITY, f64::NEG_INFINITY),
        |a, b| (a.0.min(b.0), a.1.max(b.1)),
    );
    if !(lo.is_finite() && hi.is_finite()) || u.par_iter().any(|v| v.is_nan()) {
        return None;
    }
    let width = (hi - lo) / bins as f64;
    let bin = |v: f64| {
        if width > 0.0 {
            (((v - lo) / width) as usize).min(bins - 1)
        } else {
            0
        }
    };
    let counts = u
        .par_chunks(BLOCK)
        .map(|block| {
            let mut counts = vec![0u64; bins];
            for &v in block {
                counts[bin(v)] += 1;
            }
            counts
        })
        .reduce(
            || vec![0u64; bins],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    Some(Histogram { lo, hi, counts })
}

/// The median of timing samples, 0 when there are none.
pub fn median(mut samples: Vec<f64>) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let mid = samples.len() / 2;
    *samples.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_of_nan_has_an_infinite_max_error_and_max_abs() {
        let u = [0.5, f64::NAN, 0.25];
        assert_eq!(max_error(|_| 0.0, &u), f64::INFINITY);
        assert_eq!(max_abs(&u), f64::INFINITY);
        let exact = [0.5, 0.0, 0.25];
        assert_eq!(max_error(|i| exact[i], &[0.5, 0.0, 0.5]), 0.25);
        assert!(squared_l2_error(|_| 0.0, &u, 1.0).is_nan());
    }
}
