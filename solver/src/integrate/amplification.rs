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
//!
//! Where L_h is symmetric (the constant horizon; checked by ⟨v, Lw⟩ = ⟨Lv, w⟩), `spectral`
//! measures the step exactly instead: max |R(dt·λ)| over the ends of L_h's spectrum (Lanczos,
//! `linalg::lanczos`), R the integrator's stability function, with an interval that holds it.
//! The rough field stays for the rest (the local methods, PSE, a varying horizon). `positivity`
//! takes one step of a unit spike; every time-dependent method measures both.

use super::integrator::{applications_per_step, stability_function};
use super::spectra;
use super::stepper::{Rhs, Stepper};
use crate::case::Integrator;
use crate::discretization::stencil::Stencil;
use crate::linalg::lanczos::{self, Ends};
use crate::operator::LinearOperator;
use crate::output::diagnostics::Amplification;
use crate::parallel::exchange::Ranks;
use std::hash::{Hash, Hasher};

/// The ends of L_h's spectrum are sought to this relative tolerance (of its largest |λ|),
/// whatever the step: a boundary then lies within about this of the exact one, far below any
/// search's rtol, and the ends serve every step and integrator of the operator.
pub const SPECTRAL_RTOL: f64 = 1e-10;

/// The applications of L_h a measurement may spend: those of the rough field's `steps` steps
/// of `integrator` (`applications_per_step`), so that the case's `amplification_steps` bounds
/// the effort either way; the interval then says what it reached.
pub fn spectral_budget(integrator: Integrator, steps: usize) -> usize {
    steps.saturating_mul(applications_per_step(integrator))
}

/// What tells one operator from another for the spectra a study shares (`spectra`): the
/// operator's implementation, grid and weights (bit for bit). A served worker runs a search's
/// probes one after another, and they differ in the step alone; the ends do not depend on the
/// step or the integrator, so a remembered operator gives the record a measured one would, bit
/// for bit.
pub fn spectrum_key<Op>(stencil: &Stencil) -> String {
    let mut weights = std::hash::DefaultHasher::new();
    for row in &stencil.rows {
        (row.dy, row.dx_min).hash(&mut weights);
        row.weights
            .iter()
            .for_each(|w| w.to_bits().hash(&mut weights));
    }
    format!(
        "{} {:?} {:x}",
        std::any::type_name::<Op>(),
        stencil.grid,
        weights.finish()
    )
}

/// The step's amplification from the spectrum of a symmetric `operator` (checked: else None,
/// and the rough field measures it): the step of `integrator` multiplies an eigenvector with
/// eigenvalue λ by R(dt·λ) (`stability_function`), whose largest |R| over the spectrum is at
/// one of its ends, so the spectral radius of the step is max |R(dt·λ)| over λ_min and λ_max,
/// their intervals found by Lanczos from the rough field to `SPECTRAL_RTOL` in at most `budget`
/// applications (`spectral_budget`), or taken under `key` from an earlier measurement of this
/// process or of the study (`spectra`). Where the radius's interval holds 1 the value is its
/// top: never called stable on a guess. None when a value is not finite.
pub fn spectral<Op: LinearOperator>(
    operator: &Op,
    ranks: Ranks,
    nodes: Option<&[usize]>,
    len: usize,
    (integrator, dt): (Integrator, f64),
    budget: usize,
    key: Option<&str>,
) -> Option<Amplification> {
    let measure = || spectrum_ends(operator, ranks, (nodes, len), budget);
    let (ends, applications) = match key {
        Some(key) => spectra::measured_once(key, iterations(budget), &settled, measure)?,
        None => measure()?,
    };
    radius((integrator, dt), &ends, applications)
}

/// The step's spectral radius, max |R(dt·λ)| over the ends' intervals: the Ritz values' when
/// the interval of |R| lies on one side of 1, else its top (never called stable on a guess).
fn radius(
    (integrator, dt): (Integrator, f64),
    ends: &Ends,
    applications: usize,
) -> Option<Amplification> {
    let [lowest, highest] = ends.intervals();
    let growth = |l: f64| stability_function(integrator, dt * l).abs();
    // Over each (narrow) interval |R| lies between its values at the ends: it turns only where
    // |R| is far from 1 (Heun's ½ at z = −1, forward Euler's 0).
    let (a, b) = (growth(lowest.0), growth(lowest.1));
    let (c, d) = (growth(highest.0), growth(highest.1));
    let (low, high) = (a.min(b).max(c.min(d)), a.max(b).max(c.max(d)));
    let value = match low <= 1.0 && 1.0 < high {
        true => high,
        false => growth(ends.lowest.ritz).max(growth(ends.highest.ritz)),
    };
    (value.is_finite() && low.is_finite() && high.is_finite()).then_some(Amplification {
        value,
        bounds: Some((low, high)),
        applications: Some(applications),
    })
}

/// The ends of a symmetric `operator`'s spectrum to `SPECTRAL_RTOL` (or as far as `budget`
/// applications take them) and the applications spent (the symmetry check's two included);
/// None if it is not symmetric or a value is not finite.
fn spectrum_ends<Op: LinearOperator>(
    operator: &Op,
    ranks: Ranks,
    (nodes, len): (Option<&[usize]>, usize),
    budget: usize,
) -> Option<(Ends, usize)> {
    let mut rhs = Rhs::new(operator, None, ranks);
    let dot = |a: &[f64], b: &[f64]| ranks.sum(a.iter().zip(b).map(|(x, y)| x * y).sum());
    if !symmetric(&mut rhs, &dot, nodes, len) {
        return None;
    }
    let start = on_nodes(nodes, len, rough);
    let mut apply = |u: &[f64], out: &mut [f64]| rhs.apply(u, out);
    let ends = lanczos::ends(
        &mut apply,
        &dot,
        start,
        &mut |ends| settled(ends),
        iterations(budget),
    )?;
    Some((ends, ends.applications + 2))
}

/// Whether the ends are known to `SPECTRAL_RTOL` of the largest |λ|: Lanczos stops there.
fn settled(ends: &Ends) -> bool {
    let scale = ends.lowest.ritz.abs().max(ends.highest.ritz.abs());
    ends.lowest.bound.max(ends.highest.bound) <= SPECTRAL_RTOL * scale
}

/// The Lanczos iterations `budget` applications allow, the symmetry check's two spent.
fn iterations(budget: usize) -> usize {
    budget.saturating_sub(2).max(1)
}

/// Whether L_h is symmetric: ⟨v, L w⟩ = ⟨L v, w⟩ for two rough fields, to round-off (two
/// applications).
fn symmetric<Op: LinearOperator>(
    rhs: &mut Rhs<Op>,
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
    nodes: Option<&[usize]>,
    len: usize,
) -> bool {
    let v = on_nodes(nodes, len, rough);
    let w = on_nodes(nodes, len, |g| rough(g + 0x5bd1_e995));
    let (mut lv, mut lw) = (vec![0.0; len], vec![0.0; len]);
    rhs.apply(&v, &mut lv);
    rhs.apply(&w, &mut lw);
    let (a, b) = (dot(&v, &lw), dot(&lv, &w));
    let scale = dot(&lv, &lv).sqrt() * dot(&w, &w).sqrt();
    (a - b).abs() <= 1e-12 * scale
}

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
) -> Option<Amplification> {
    let applied = stepper.applications();
    let mut u = on_nodes(nodes, len, rough);
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
    growth.is_finite().then_some(Amplification {
        value: growth,
        bounds: None,
        applications: stepper.applications().zip(applied).map(|(a, b)| a - b),
    })
}

/// The solves' relative tolerance in the measurement of positivity: far tighter than any
/// run's, so that a negative value is the step's and not the solve's.
pub const POSITIVITY_RTOL: f64 = 1e-13;

/// Values within this of the spike's largest count as 0: what a solve to `POSITIVITY_RTOL` of
/// a system of condition ≲ 10³ leaves.
const ROUND_OFF: f64 = 1e-10;

/// The middle node of a grid of n nodes per side in `dim` dimensions, stored row by row.
pub fn middle_node(dim: usize, n: usize) -> usize {
    match dim {
        2 => (n / 2) * n + n / 2,
        _ => n / 2,
    }
}

/// The step's positivity: one step of `stepper` (no source) from a unit spike at global node
/// `spike`, its smallest value over its largest across the ranks, with values within
/// `ROUND_OFF` of the largest counted as 0. Below 0 the step makes negative values of
/// non-negative data. None if the step produced a value that is not finite.
pub fn positivity(
    stepper: &mut dyn Stepper,
    ranks: Ranks,
    nodes: Option<&[usize]>,
    len: usize,
    dt: f64,
    spike: usize,
) -> Option<f64> {
    let mut u = on_nodes(nodes, len, |g| if g == spike { 1.0 } else { 0.0 });
    stepper.step(&mut u, 0.0, dt);
    let (lowest, highest) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
    let (lowest, highest) = (-ranks.max(-lowest), ranks.max(highest));
    let ratio = match lowest.abs() <= ROUND_OFF * highest.abs() {
        true => 0.0,
        false => lowest / highest,
    };
    ratio.is_finite().then_some(ratio)
}

/// `value` of each global node of this rank's `nodes` (all `len` nodes when None), in order.
fn on_nodes(nodes: Option<&[usize]>, len: usize, value: impl Fn(usize) -> f64) -> Vec<f64> {
    match nodes {
        Some(nodes) => nodes.iter().map(|&g| value(g)).collect(),
        None => (0..len).map(value).collect(),
    }
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

    /// A spectrum whose lowest end is known only to within a bound that holds forward Euler's
    /// limit z = −2: the radius is the top of its interval (above 1), not the Ritz value's
    /// |R| (below 1); an interval wholly inside the stable side gives the Ritz value's.
    #[test]
    fn a_radius_whose_interval_holds_one_is_its_top() {
        let end = |ritz, bound| lanczos::End { ritz, bound };
        let ends = |lowest| Ends {
            lowest,
            highest: end(-0.5, 0.0),
            applications: 0,
        };
        let straddling = radius(
            (Integrator::ForwardEuler, 1.0),
            &ends(end(-1.9999995, 1e-6)),
            7,
        )
        .unwrap();
        assert_eq!(straddling.value, straddling.bounds.unwrap().1);
        assert!(straddling.value > 1.0 && (straddling.value - 1.0000005).abs() < 1e-12);
        let inside = radius((Integrator::ForwardEuler, 1.0), &ends(end(-1.9, 1e-6)), 7).unwrap();
        assert!((inside.value - 0.9).abs() < 1e-12, "{inside:?}");
        assert!(inside.bounds.unwrap().1 < 1.0);
        assert_eq!(inside.applications, Some(7));
    }

    #[test]
    fn a_pure_growth_is_measured_whatever_its_size() {
        for g in [0.5, 0.999, 1.0, 1.001, 3.0, 1e3] {
            let measured = amplification(&mut Scale(g), Ranks::single(), None, 50, 0.1, 400);
            let measured = measured.unwrap().value;
            assert!((measured / g - 1.0).abs() < 1e-12, "{g}: {measured}");
        }
        assert_eq!(
            amplification(&mut Scale(f64::NAN), Ranks::single(), None, 50, 0.1, 4),
            None
        );
    }

    /// u ← u + a·(shifted u − 2u) in 1D, a discrete Laplacian step with ratio `a`.
    struct Heat(f64);
    impl Stepper for Heat {
        fn step(&mut self, u: &mut [f64], _: f64, _: f64) -> f64 {
            let old = u.to_vec();
            for (i, x) in u.iter_mut().enumerate() {
                let left = if i > 0 { old[i - 1] } else { 0.0 };
                let right = old.get(i + 1).copied().unwrap_or(0.0);
                *x = old[i] + self.0 * (left + right - 2.0 * old[i]);
            }
            u.iter().fold(0.0, |m, x| m.max(x.abs()))
        }
    }

    #[test]
    fn positivity_is_lost_exactly_where_the_diagonal_of_the_step_turns_negative() {
        let measured = |a: f64| {
            positivity(
                &mut Heat(a),
                Ranks::single(),
                None,
                9,
                0.1,
                middle_node(1, 9),
            )
            .unwrap()
        };
        // The spike becomes (a, 1 − 2a, a): non-negative up to a = 1/2.
        assert_eq!(measured(0.25), 0.0);
        assert_eq!(measured(0.5), 0.0);
        assert!(
            (measured(0.6) - (-0.2 / 0.6)).abs() < 1e-15,
            "{}",
            measured(0.6)
        );
        assert_eq!((middle_node(1, 9), middle_node(2, 4)), (4, 10));
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
