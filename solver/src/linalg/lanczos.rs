//! The two ends of a symmetric operator's spectrum by Lanczos, on one process or over ranks:
//! the three-term recurrence (three vectors of a rank's share, no basis kept), the extreme Ritz
//! values of the tridiagonal T_j (`tridiagonal`: bisection and inverse iteration, O(j)), and
//! for each end a bound on how far the operator's extreme eigenvalue lies beyond its Ritz value.
//!
//! A Ritz value never lies outside the spectrum (Cauchy interlacing), so the lowest Ritz value
//! bounds λ_min from above and the highest bounds λ_max from below. The other side: some
//! eigenvalue lies within the residual r = |β_j s_j| of each Ritz value, and within r²/δ when
//! the rest of the spectrum is δ away (Kato–Temple; δ is estimated by the next Ritz value). That
//! the eigenvalue near the extreme Ritz value is the extreme one rests on the start vector: the
//! rough field holds every mode of the grid. Without a kept basis the recurrence loses
//! orthogonality once a Ritz value converges, which copies converged values (Paige) but does not
//! move the extreme ones.

use super::tridiagonal::Tridiagonal;

/// One end of the spectrum: its Ritz value and how far beyond it the eigenvalue may lie.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct End {
    pub ritz: f64,
    pub bound: f64,
}

/// The spectrum's ends as far as the recurrence has gone: λ_min ∈ [lowest.ritz − lowest.bound,
/// lowest.ritz], λ_max ∈ [highest.ritz, highest.ritz + highest.bound].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ends {
    pub lowest: End,
    pub highest: End,
    /// Applications of the operator spent.
    pub applications: usize,
}

impl Ends {
    /// The intervals that hold λ_min and λ_max.
    pub fn intervals(&self) -> [(f64, f64); 2] {
        [
            (self.lowest.ritz - self.lowest.bound, self.lowest.ritz),
            (self.highest.ritz, self.highest.ritz + self.highest.bound),
        ]
    }
}

/// Ritz values are looked at every this many iterations: the extreme ones of T_j cost O(j),
/// far less than the operator's applications between two looks.
pub const CHECK_EVERY: usize = 8;

/// The ends of the spectrum of the symmetric operator `apply` (out = L u), from `start`, with
/// `dot` the inner product over every rank. Iterates until `settled` says the ends are known
/// well enough, or an invariant subspace is found (the ends are then exact), or
/// `max_iterations`; returns the last ends. None when the start is zero or a value is not
/// finite.
pub fn ends(
    apply: &mut dyn FnMut(&[f64], &mut [f64]),
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
    mut q: Vec<f64>,
    settled: &mut dyn FnMut(&Ends) -> bool,
    max_iterations: usize,
) -> Option<Ends> {
    let norm = dot(&q, &q).sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    q.iter_mut().for_each(|x| *x /= norm);
    let mut previous = vec![0.0; q.len()];
    let mut w = vec![0.0; q.len()];
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    let mut beta_previous = 0.0;
    for j in 1..=max_iterations.max(1) {
        apply(&q, &mut w);
        let alpha = dot(&w, &q);
        for ((w, q), p) in w.iter_mut().zip(&q).zip(&previous) {
            *w -= alpha * q + beta_previous * p;
        }
        let beta = dot(&w, &w).sqrt();
        if !(alpha.is_finite() && beta.is_finite()) {
            return None;
        }
        alphas.push(alpha);
        betas.push(beta);
        let scale = alphas.iter().fold(0.0_f64, |m, a| m.max(a.abs())).max(beta);
        // β ≈ 0: the Krylov space is invariant and its Ritz values are eigenvalues.
        let invariant = beta <= 1e-14 * scale;
        if invariant || j % CHECK_EVERY == 0 || j == max_iterations {
            let ends = ritz_ends(&alphas, &betas, invariant, j)?;
            if invariant || settled(&ends) || j >= max_iterations {
                return Some(ends);
            }
        }
        std::mem::swap(&mut previous, &mut q);
        for (q, w) in q.iter_mut().zip(&w) {
            *q = w / beta;
        }
        beta_previous = beta;
    }
    None
}

/// The extreme Ritz values of T_j (diagonal `alphas`, off-diagonal `betas[..j−1]`) and their
/// bounds min(r, r²/δ), r = |β_j s_j| the residual, δ the gap to the next Ritz value, and at
/// least the round-off of the values.
fn ritz_ends(alphas: &[f64], betas: &[f64], invariant: bool, applications: usize) -> Option<Ends> {
    let j = alphas.len();
    let t = Tridiagonal {
        diagonal: alphas,
        off: &betas[..j - 1],
    };
    let value = |k: usize| t.eigenvalue(k);
    let beta = if invariant { 0.0 } else { betas[j - 1] };
    let (lowest, highest) = (value(0), value(j - 1));
    // The Ritz values themselves are known to a few ulps of T's norm, whatever the residual.
    let round_off = 16.0 * f64::EPSILON * lowest.abs().max(highest.abs());
    let end = |ritz: f64, next: Option<f64>| {
        let residual = (beta * t.last_component(ritz)).abs();
        let gap = next.map_or(f64::INFINITY, |next| (next - ritz).abs());
        End {
            ritz,
            bound: residual.min(residual * residual / gap).max(round_off),
        }
    };
    let second = |k: usize| (j > 1).then(|| value(k));
    let ends = Ends {
        lowest: end(lowest, second(1)),
        highest: end(highest, second(j.saturating_sub(2))),
        applications,
    };
    let finite = [ends.lowest, ends.highest]
        .iter()
        .all(|e| e.ritz.is_finite() && e.bound.is_finite());
    finite.then_some(ends)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diagonal operator with eigenvalues −k (k = 1..=n) and a cluster at its bottom.
    fn diagonal(n: usize) -> Vec<f64> {
        (1..=n)
            .map(|k| -(k as f64) - if k > n - 5 { 0.3 } else { 0.0 })
            .collect()
    }

    #[test]
    fn the_ends_of_a_known_spectrum_lie_in_their_intervals_and_tighten() {
        let d = diagonal(400);
        let mut apply = |u: &[f64], out: &mut [f64]| {
            for ((o, u), d) in out.iter_mut().zip(u).zip(&d) {
                *o = d * u;
            }
        };
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum();
        let start: Vec<f64> = (0..400)
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let (lowest, highest) = (-400.3, -1.0);
        for tolerance in [1e-3, 1e-8, 1e-11] {
            let mut settled = |e: &Ends| e.lowest.bound.max(e.highest.bound) <= tolerance * 400.0;
            let ends = ends(&mut apply, &dot, start.clone(), &mut settled, 1000).unwrap();
            let [(low, top), (bottom, high)] = ends.intervals();
            assert!(low <= lowest && lowest <= top, "{ends:?}");
            assert!(bottom <= highest && highest <= high, "{ends:?}");
            assert!(top - low <= tolerance * 400.0 && high - bottom <= tolerance * 400.0);
        }
    }

    #[test]
    fn an_invariant_start_gives_exact_ends_and_a_zero_start_none() {
        let mut apply = |u: &[f64], out: &mut [f64]| {
            out.iter_mut().zip(u).for_each(|(o, u)| *o = -2.0 * u);
        };
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum();
        let ends = ends(&mut apply, &dot, vec![1.0; 10], &mut |_| false, 100).unwrap();
        assert!((ends.lowest.ritz + 2.0).abs() <= 1e-15, "{ends:?}");
        assert!(ends.lowest.bound <= 1e-14, "{ends:?}");
        assert_eq!(ends.applications, 1);
        assert!(super::ends(&mut apply, &dot, vec![0.0; 10], &mut |_| true, 100).is_none());
    }
}
