//! The step's amplification as a run measures it: how much a rough field grows per step under
//! the homogeneous problem (no source, a zero collar). A stability search bisects on it: above
//! 1 the step amplifies some mode of the grid, at or below 1 it amplifies none.
//!
//! A blow-up waits for the unstable modes to grow out of the round-off of a smooth field, so
//! near the boundary (growth 1.001 per step) a run of a few hundred steps ends `ok`. Here the
//! field holds every mode from the start: its values are pseudo-random per global node (the same
//! on any number of ranks), and the growth of its max norm per step over the second half of the
//! steps is that of the step's most amplified modes. It approaches the step's spectral radius
//! from below, by O(1/steps) through the modes beside the top one; the field is rescaled as it
//! grows or decays, so no step overflows.

use super::stepper::Stepper;
use crate::parallel::exchange::Ranks;

/// The growth per step of a rough field over the second half of `steps` steps of `stepper`
/// (which must have no source), on this rank's `nodes` (all `len` nodes when None). None if
/// the step produced a value that is not finite.
pub fn amplification(
    stepper: &mut dyn Stepper,
    ranks: Ranks,
    nodes: Option<&[usize]>,
    len: usize,
    dt: f64,
    steps: usize,
) -> Option<f64> {
    let mut u: Vec<f64> = match nodes {
        Some(nodes) => nodes.iter().map(|&g| rough(g)).collect(),
        None => (0..len).map(rough).collect(),
    };
    let half = steps / 2;
    // ln of the factor the field was divided by, and ln max |u| after step `half`.
    let (mut rescaled, mut at_half) = (0.0, 0.0);
    let mut max_abs = ranks.max_abs(&u);
    for k in 1..=steps {
        max_abs = stepper.step(&mut u, 0.0, dt);
        if !(max_abs.is_finite() && max_abs > 0.0) {
            return None;
        }
        if k == half {
            at_half = rescaled + max_abs.ln();
        }
        if !(1e-100..=1e100).contains(&max_abs) {
            ranks.on(|| u.iter_mut().for_each(|x| *x /= max_abs));
            rescaled += max_abs.ln();
            max_abs = 1.0;
        }
    }
    let growth = ((rescaled + max_abs.ln() - at_half) / (steps - half) as f64).exp();
    growth.is_finite().then_some(growth)
}

/// A value in [−1, 1) for global node `g`: SplitMix64's finalizer of g, so that neighbouring
/// nodes are uncorrelated and every mode of the grid is present.
fn rough(g: usize) -> f64 {
    let mut z = (g as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// u ← g·u with max |u| returned: the growth per step measured is g.
    struct Scale(f64);
    impl Stepper for Scale {
        fn step(&mut self, u: &mut [f64], _: f64, _: f64) -> f64 {
            u.iter_mut().for_each(|x| *x *= self.0);
            u.iter().fold(0.0, |m, x| m.max(x.abs()))
        }
    }

    #[test]
    fn a_pure_growth_is_measured_whatever_its_size() {
        for g in [0.5, 0.999, 1.0, 1.001, 3.0, 1e3] {
            let measured = amplification(&mut Scale(g), Ranks::single(), None, 50, 0.1, 400);
            let measured = measured.unwrap();
            assert!((measured / g - 1.0).abs() < 1e-12, "{g}: {measured}");
        }
        assert_eq!(
            amplification(&mut Scale(f64::NAN), Ranks::single(), None, 50, 0.1, 4),
            None
        );
    }

    #[test]
    fn the_rough_field_is_rough_and_bounded() {
        let values: Vec<f64> = (0..10_000).map(rough).collect();
        assert!(values.iter().all(|x| (-1.0..1.0).contains(x)));
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let lag_one = values.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / values.len() as f64;
        assert!(
            mean.abs() < 0.03 && lag_one.abs() < 0.03,
            "{mean} {lag_one}"
        );
    }
}
