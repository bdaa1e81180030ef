//! Percentile bootstrap intervals over the repeats, seeded by point and metric so that a
//! comparison gives the same intervals every time.

use crate::statistics::median;
use fastrand::Rng;

/// Bootstrap resamples per interval, and the interval's coverage.
pub(super) const RESAMPLES: usize = 2000;

pub(super) const COVERAGE: f64 = 0.95;

/// The median of a resample (with replacement) of `values`.
pub(super) fn resampled(random: &mut Rng, values: &[f64]) -> f64 {
    let drawn: Vec<f64> = (0..values.len())
        .map(|_| values[random.usize(..values.len())])
        .collect();
    median(&drawn)
}

/// The percentile interval of `statistic` over `RESAMPLES` resamples.
pub(super) fn bootstrap(
    random: &mut Rng,
    mut statistic: impl FnMut(&mut Rng) -> f64,
) -> (f64, f64) {
    let mut ratios: Vec<f64> = (0..RESAMPLES).map(|_| statistic(random)).collect();
    ratios.sort_by(f64::total_cmp);
    let tail = (1.0 - COVERAGE) / 2.0;
    let at = |q: f64| ratios[((q * (RESAMPLES - 1) as f64).round() as usize).min(RESAMPLES - 1)];
    (at(tail), at(1.0 - tail))
}

/// A seed from the point and metric (FNV-1a), so that intervals do not depend on the order.
pub(super) fn seed_of(point: &str, metric: &str) -> u64 {
    let mut hash = fnv::FnvHasher::default();
    for bytes in [point.as_bytes(), &[0], metric.as_bytes()] {
        std::hash::Hasher::write(&mut hash, bytes);
    }
    std::hash::Hasher::finish(&hash)
}
