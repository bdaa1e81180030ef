//! The models an error-target search in space and time predicts from: its runs' error as
//! e ≈ C·h^p + D·dt^q + F (a spatial part, a temporal part, and a floor neither refines: the
//! round-off, or a modelling error such as a non-convergent quadrature's) or, where the parts
//! have opposite signs and cancel, e ≈ |C·h^p − D·dt^q|; their cost as K·h^−a·dt^−b; and an
//! explicit integrator's stable step as dt_stable(h) ∝ h^k. Fitted to the levels run so far by
//! least squares of relative residuals; the orders p and q over a grid (with few levels, q is
//! the integrator's and the floor none), C, D and F by non-negative least squares for each, or
//! with each run's sign for parts that cancel. Each order's interval is the spread of its
//! leave-one-out fits.
//!
//! Either way the search plans with C·h^p + D·dt^q + F, each part at its worst: a
//! configuration that meets the target only by its parts cancelling is a coincidence of the
//! problem that a finer grid or a smaller step does not keep.

use std::collections::BTreeMap;
use std::sync::Mutex;

/// A run as the models read it: its grid spacing and time step (from its record), its error and
/// its cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub h: f64,
    pub dt: f64,
    pub error: f64,
    pub cost: f64,
}

/// The error model e ≈ C·h^p + D·dt^q + F, or |C·h^p − D·dt^q| where the parts cancel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorModel {
    pub c: f64,
    pub p: f64,
    pub d: f64,
    pub q: f64,
    pub floor: f64,
    /// Whether the parts have opposite signs (the runs' errors fitted as |C·h^p − D·dt^q|).
    pub cancel: bool,
    /// The spread of p and q over the leave-one-out fits (with four levels or more).
    pub p_interval: Option<(f64, f64)>,
    pub q_interval: Option<(f64, f64)>,
    /// How far the fit's predictions miss runs it was not fitted to: the root mean square of
    /// ln(predicted/measured) over the leave-one-out fits, each run predicted by the others
    /// (with four levels or more). The search's margin is made of it.
    pub spread: Option<f64>,
}

impl ErrorModel {
    /// The error with each part at its worst, C·h^p + D·dt^q + F: what the search plans with.
    pub fn error(&self, h: f64, dt: f64) -> f64 {
        self.c * h.powf(self.p) + self.d * dt.powf(self.q) + self.floor
    }

    /// The error as fitted: the parts' difference where they cancel, else their sum.
    pub fn fitted(&self, h: f64, dt: f64) -> f64 {
        match self.cancel {
            true => (self.c * h.powf(self.p) - self.d * dt.powf(self.q)).abs(),
            false => self.error(h, dt),
        }
    }
}

/// The cost model K·h^−a·dt^−b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostModel {
    pub k: f64,
    pub a: f64,
    pub b: f64,
}

impl CostModel {
    pub fn cost(&self, h: f64, dt: f64) -> f64 {
        self.k * h.powf(-self.a) * dt.powf(-self.b)
    }
}

/// The levels an order is fitted from with the other held at its prior, and the fewest with
/// which both orders and the floor are fitted.
const ORDERS_FREE: usize = 5;

/// The grid of orders tried: 0.25 to 5, what a discretization's error shows. An error that
/// falls faster between two runs is no order but its parts cancelling (`ErrorModel::trusts`).
fn orders() -> impl Iterator<Item = f64> + Clone {
    (5..=100).map(|k| k as f64 * 0.05)
}

/// The highest order of the grid.
const MOST_ORDER: f64 = 5.0;

/// The error model of `points` (at least two). `q_prior`: the integrator's order, which `q`
/// keeps until `ORDERS_FREE` levels; the floor is fitted from `ORDERS_FREE` levels on.
pub fn error_model(points: &[Point], q_prior: f64) -> Option<ErrorModel> {
    // A search is replayed from its first run every round, and each replay fits every prefix of
    // its runs again (with its leave-one-out fits, a few hundred milliseconds with fifteen runs):
    // the same points give the same model, kept for the process.
    static FITTED: Mutex<BTreeMap<Vec<u64>, Option<ErrorModel>>> = Mutex::new(BTreeMap::new());
    let key: Vec<u64> = (points.iter())
        .flat_map(|x| [x.h, x.dt, x.error, x.cost])
        .chain([q_prior])
        .map(f64::to_bits)
        .collect();
    if let Some(model) = FITTED.lock().ok().and_then(|f| f.get(&key).copied()) {
        return model;
    }
    let model = error_model_of(points, q_prior);
    if let Ok(mut fitted) = FITTED.lock() {
        fitted.insert(key, model);
    }
    model
}

fn error_model_of(points: &[Point], q_prior: f64) -> Option<ErrorModel> {
    let best = fit(points, q_prior)?;
    // Each run left out in turn (with four levels or more): the fit of the others.
    let others: Vec<(Point, ErrorModel)> = (0..points.len())
        .filter(|_| points.len() >= 4)
        .filter_map(|k| {
            let mut rest = points.to_vec();
            let left = rest.remove(k);
            Some((left, fit(&rest, q_prior)?))
        })
        .collect();
    let spread = |pick: fn(&ErrorModel) -> f64| -> Option<(f64, f64)> {
        (points.len() >= 4).then(|| {
            let orders = (others.iter().map(|(_, m)| pick(m))).chain([pick(&best)]);
            let low = orders.clone().fold(f64::INFINITY, f64::min);
            let high = orders.fold(f64::NEG_INFINITY, f64::max);
            (low, high)
        })
    };
    // What a prediction of an unrun configuration may miss by: each run predicted by the others.
    let missed: Vec<f64> = (others.iter())
        .map(|(left, m)| (m.fitted(left.h, left.dt) / left.error).ln())
        .filter(|x| x.is_finite())
        .collect();
    let rms = (missed.iter().map(|x| x * x).sum::<f64>() / missed.len() as f64).sqrt();
    Some(ErrorModel {
        spread: (!missed.is_empty()).then_some(rms),
        p_interval: spread(|m| m.p),
        q_interval: (points.len() >= ORDERS_FREE)
            .then(|| spread(|m| m.q))
            .flatten(),
        ..best
    })
}

/// The least-squares model of `points` over the grid of orders: first every quarter order, then
/// the grid's own steps within a quarter of the best (a fit is replayed for every prefix of a
/// search's runs and left out of for each; the full grid of 96² orders took 70 ms).
fn fit(points: &[Point], q_prior: f64) -> Option<ErrorModel> {
    if points.len() < 2 {
        return None;
    }
    let free = points.len() >= ORDERS_FREE;
    // Points of one spacing (or one step) cannot tell its order: the highest is taken, the
    // most a run of another spacing may be explained by (and the most hopeful prediction).
    let one = |of: fn(&Point) -> f64| points.iter().all(|x| of(x) == of(&points[0]));
    let coarse = |order: &f64| (order / 0.25 - (order / 0.25).round()).abs() < 1e-9;
    let ps: Vec<f64> = match one(|x| x.h) {
        true => vec![MOST_ORDER],
        false => orders().filter(coarse).collect(),
    };
    let qs: Vec<f64> = match free && !one(|x| x.dt) {
        true => orders().filter(coarse).collect(),
        false => vec![q_prior],
    };
    let (_, rough) = best_over(points, &ps, &qs, q_prior)?;
    let near = |of: f64, grid: &[f64]| -> Vec<f64> {
        match grid.len() {
            1 => grid.to_vec(),
            _ => orders().filter(|o| (o - of).abs() <= 0.25 + 1e-9).collect(),
        }
    };
    let (_, model) = best_over(points, &near(rough.p, &ps), &near(rough.q, &qs), q_prior)?;
    Some(model)
}

/// The best model over the orders `ps` × `qs`, and its residual.
fn best_over(points: &[Point], ps: &[f64], qs: &[f64], q_prior: f64) -> Option<(f64, ErrorModel)> {
    let free = points.len() >= ORDERS_FREE;
    let mut best: Option<(f64, ErrorModel)> = None;
    for &p in ps {
        for &q in qs {
            let columns: Vec<[f64; 3]> = points
                .iter()
                .map(|x| [x.h.powf(p), x.dt.powf(q), 1.0])
                .collect();
            let used = if free { 3 } else { 2 };
            let adding = nonnegative_least_squares(&columns, points, used);
            // Parts that cancel are fitted with q the integrator's: its sign is the integrator's
            // own (backward Euler damps too little, forward Euler too much).
            let cancel = (q == q_prior)
                .then(|| cancelling(&columns, points))
                .flatten();
            let fits = [Some((adding, false)), cancel.map(|f| (f, true))];
            for ((coefficients, residual), cancel) in fits.into_iter().flatten() {
                if best.as_ref().is_none_or(|(r, _)| residual < *r) {
                    let [c, d, floor] = coefficients;
                    let model = ErrorModel {
                        c,
                        p,
                        d,
                        q,
                        floor,
                        cancel,
                        p_interval: None,
                        q_interval: None,
                        spread: None,
                    };
                    best = Some((residual, model));
                }
            }
        }
    }
    best
}

/// The least squares of e ≈ |C·x₀ − D·x₁| (columns 0 and 1, C, D > 0) in relative residuals,
/// and its sum. The sum is not smooth where a run's parts change places, so the ratio D/C is
/// searched over a log grid spanning the runs' own x₀/x₁ (C in closed form for each), and the
/// best refined as least squares with each run's sign (whether its spatial part is the larger)
/// held. None where no such fit has both parts positive.
fn cancelling(columns: &[[f64; 3]], points: &[Point]) -> Option<([f64; 3], f64)> {
    let residual = |c: f64, d: f64| -> f64 {
        (columns.iter().zip(points))
            .map(|(row, x)| (((c * row[0] - d * row[1]).abs() - x.error) / x.error).powi(2))
            .sum()
    };
    let ratios = columns.iter().map(|row| row[0] / row[1]);
    let low = ratios.clone().fold(f64::INFINITY, f64::min) / 4.0;
    let high = ratios.fold(0.0, f64::max) * 4.0;
    if !(low > 0.0 && high.is_finite()) {
        return None;
    }
    let mut best: Option<(f64, f64, f64)> = None;
    for k in 0..=RATIOS {
        let r = low * (high / low).powf(k as f64 / RATIOS as f64);
        // e ≈ C·g, g = |x₀ − r·x₁|: C = Σ(g/e) / Σ(g/e)².
        let (mut s1, mut s2) = (0.0, 0.0);
        for (row, x) in columns.iter().zip(points) {
            let g = (row[0] - r * row[1]).abs() / x.error;
            (s1, s2) = (s1 + g, s2 + g * g);
        }
        if s2 > 0.0 {
            let c = s1 / s2;
            let sum = residual(c, r * c);
            if best.is_none_or(|(_, _, b)| sum < b) {
                best = Some((c, r * c, sum));
            }
        }
    }
    let (mut c, mut d, mut sum) = best?;
    // With the signs held, s·(C·x₀ − D·x₁) = e is linear: solved by weighted least squares.
    let signs: Vec<f64> = (columns.iter())
        .map(|row| (c * row[0] - d * row[1]).signum())
        .collect();
    // Each row weighted by 1/e: the relative residual.
    let rows: Vec<Vec<f64>> = (columns.iter().zip(points).zip(&signs))
        .map(|((row, x), s)| vec![s * row[0] / x.error, -s * row[1] / x.error])
        .collect();
    let ones = vec![1.0; rows.len()];
    if let Some([c1, d1]) = least_squares(&rows, &ones).map(|x| [x[0], x[1]]) {
        if c1 > 0.0 && d1 > 0.0 && residual(c1, d1) < sum {
            (c, d, sum) = (c1, d1, residual(c1, d1));
        }
    }
    Some(([c, d, 0.0], sum))
}

/// The ratios D/C a cancelling fit tries.
const RATIOS: usize = 120;

/// The coefficients ≥ 0 of the first `used` columns minimizing Σ ((Σ_j c_j·x_j − e)/e)², and
/// that sum: every subset of the columns solved as least squares, the best whose coefficients
/// are all non-negative kept (three columns: seven subsets).
fn nonnegative_least_squares(
    columns: &[[f64; 3]],
    points: &[Point],
    used: usize,
) -> ([f64; 3], f64) {
    let mut best = ([0.0; 3], f64::INFINITY);
    for subset in 1u32..(1 << used) {
        let chosen: Vec<usize> = (0..used).filter(|j| subset & (1 << j) != 0).collect();
        // Each row weighted by 1/e: the relative residual.
        let rows: Vec<Vec<f64>> = (columns.iter().zip(points))
            .map(|(row, x)| chosen.iter().map(|&j| row[j] / x.error).collect())
            .collect();
        let ones = vec![1.0; rows.len()];
        let Some(solved) = least_squares(&rows, &ones) else {
            continue;
        };
        if solved.iter().any(|&c| !(c >= 0.0 && c.is_finite())) {
            continue;
        }
        let mut coefficients = [0.0; 3];
        for (&j, &c) in chosen.iter().zip(&solved) {
            coefficients[j] = c;
        }
        let residual: f64 = (columns.iter().zip(points))
            .map(|(row, x)| {
                let model: f64 = (0..3).map(|j| coefficients[j] * row[j]).sum();
                ((model - x.error) / x.error).powi(2)
            })
            .sum();
        if residual < best.1 {
            best = (coefficients, residual);
        }
    }
    best
}

/// The least-squares solution of rows·x = rhs by faer's column-pivoted QR, or none when the
/// columns are (numerically) dependent: then the fit cannot tell its terms apart.
fn least_squares(rows: &[Vec<f64>], rhs: &[f64]) -> Option<Vec<f64>> {
    use faer::linalg::solvers::SolveLstsq;
    let unknowns = rows.first()?.len();
    if rows.len() < unknowns {
        return None;
    }
    let a = faer::Mat::from_fn(rows.len(), unknowns, |i, j| rows[i][j]);
    let qr = a.col_piv_qr();
    let r = qr.R();
    let largest = r[(0, 0)].abs();
    if !(1..unknowns).all(|k| r[(k, k)].abs() > 1e-12 * largest) || largest == 0.0 {
        return None;
    }
    let x = qr.solve_lstsq(faer::Mat::from_fn(rhs.len(), 1, |i, _| rhs[i]));
    let x: Vec<f64> = (0..unknowns).map(|k| x[(k, 0)]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The cost model of `points`: least squares of log cost on log h and log dt where the points
/// tell them apart, else the prior exponents (`dim` for h: nodes; 1 for dt: steps) with K fitted.
pub fn cost_model(points: &[Point], dim: f64) -> Option<CostModel> {
    let first = points.first()?;
    let varies = |read: fn(&Point) -> f64| {
        points
            .iter()
            .any(|x| (read(x) / read(first) - 1.0).abs() > 1e-6)
    };
    let (mut a, mut b) = (dim, 1.0);
    if points.len() >= 3 && varies(|x| x.h) && varies(|x| x.dt) {
        // log c = log K − a log h − b log dt: three unknowns.
        let rows: Vec<Vec<f64>> = points
            .iter()
            .map(|x| vec![1.0, -x.h.ln(), -x.dt.ln()])
            .collect();
        let logs: Vec<f64> = points.iter().map(|x| x.cost.ln()).collect();
        // At least the nodes' count and half the steps' (an implicit step's solve takes more
        // iterations as dt grows): the costs of small runs are mostly noise, and a cost fitted
        // to grow slower than its nodes would send the search to grids it cannot afford.
        if let Some(solved) = least_squares(&rows, &logs) {
            (a, b) = (solved[1].max(dim), solved[2].max(0.5));
        }
    }
    // K through the points in the geometric mean.
    let log_k = points
        .iter()
        .map(|x| x.cost.ln() + a * x.h.ln() + b * x.dt.ln())
        .sum::<f64>()
        / points.len() as f64;
    Some(CostModel {
        k: log_k.exp(),
        a,
        b,
    })
}

/// An explicit integrator's stable step as a function of h, from the points' own (h, dt_stable):
/// dt_stable(h) = s·h^k, k fitted where two spacings are known, else 2 (a diffusion operator's).
pub fn stable_step(known: &[(f64, f64)]) -> Option<impl Fn(f64) -> f64> {
    let &(h0, s0) = known.first()?;
    let far = known
        .iter()
        .copied()
        .max_by(|x, y| (x.0 / h0).ln().abs().total_cmp(&(y.0 / h0).ln().abs()))?;
    let k = match (far.0 / h0 - 1.0).abs() > 1e-6 {
        true => (far.1 / s0).ln() / (far.0 / h0).ln(),
        false => 2.0,
    };
    Some(move |h: f64| s0 * (h / h0).powf(k))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(law: impl Fn(f64, f64) -> f64, grid: &[(f64, f64)]) -> Vec<Point> {
        grid.iter()
            .map(|&(h, dt)| Point {
                h,
                dt,
                error: law(h, dt),
                cost: 1e-6 / (h * h * dt),
            })
            .collect()
    }

    /// Six levels varying both fields, as a search in space and time probes them.
    const DESIGN: [(f64, f64); 6] = [
        (0.1, 1e-2),
        (0.05, 1e-2),
        (0.1, 5e-3),
        (0.05, 2.5e-3),
        (0.025, 5e-3),
        (0.0125, 1e-3),
    ];

    /// A law C·h² + D·dt is fitted back from five levels of a design varying both: the orders
    /// within 0.05, the coefficients within a few per cent.
    #[test]
    fn an_error_law_in_space_and_time_is_fitted_back() {
        let law = |h: f64, dt: f64| 3.0 * h * h + 0.5 * dt;
        let model = error_model(&points(law, &DESIGN), 1.0).unwrap();
        assert!((model.p - 2.0).abs() <= 0.05, "{model:?}");
        assert!((model.q - 1.0).abs() <= 0.05, "{model:?}");
        assert!(
            (model.c / 3.0 - 1.0).abs() < 0.05 && (model.d / 0.5 - 1.0).abs() < 0.05,
            "{model:?}"
        );
        assert!(model.floor < 1e-6, "{model:?}");
        let (low, high) = model.p_interval.unwrap();
        assert!(low <= 2.0 && high >= 2.0 && high - low < 0.2, "{model:?}");
    }

    /// The spread is what the fit of the others misses each run by: nothing for runs of an
    /// exact law, and for runs scattered ±20 % about it (each alternately above and below) the
    /// root mean square of the log ratios the leave-one-out fits give, recomputed here by hand.
    #[test]
    fn the_spread_is_what_each_left_out_run_is_missed_by() {
        let law = |h: f64, dt: f64| 3.0 * h * h + 0.5 * dt;
        let exact = error_model(&points(law, &DESIGN), 1.0).unwrap();
        assert!(exact.spread.unwrap() < 1e-3, "{exact:?}");
        let mut scattered = points(law, &DESIGN);
        for (k, x) in scattered.iter_mut().enumerate() {
            x.error *= if k % 2 == 0 { 1.2 } else { 1.0 / 1.2 };
        }
        let model = error_model(&scattered, 1.0).unwrap();
        let by_hand: Vec<f64> = (0..scattered.len())
            .map(|k| {
                let mut rest = scattered.clone();
                let left = rest.remove(k);
                (fit(&rest, 1.0).unwrap().fitted(left.h, left.dt) / left.error).ln()
            })
            .collect();
        let rms = (by_hand.iter().map(|x| x * x).sum::<f64>() / by_hand.len() as f64).sqrt();
        assert!(
            (model.spread.unwrap() - rms).abs() < 1e-12,
            "{model:?}, {rms}"
        );
        assert!(rms > 0.15 && rms < 1.0, "±20 % scatter: {rms}");
        assert_eq!(error_model(&scattered[..3], 1.0).unwrap().spread, None);
    }

    /// Parts of opposite signs, e = |C·h² − D·dt| (backward Euler's damping against a scheme's
    /// spatial error, on one mode): fitted back from the three runs of the exploration, the
    /// spatial order 2 with them, though one run's parts nearly cancel; the model plans with
    /// the parts at their worst, far above that run's error.
    #[test]
    fn parts_that_cancel_are_fitted_back_and_planned_at_their_worst() {
        let law = |h: f64, dt: f64| (0.66 * h * h - 0.08 * dt).abs();
        // The start, finer in space (where the parts nearly cancel), finer in time.
        let grid = [(1.0 / 32.0, 2e-3), (1.0 / 64.0, 2e-3), (1.0 / 32.0, 1e-3)];
        let runs = points(law, &grid);
        let model = error_model(&runs, 1.0).unwrap();
        assert!(model.cancel, "{model:?}");
        assert!((model.p - 2.0).abs() <= 0.05, "{model:?}");
        for x in &runs {
            let fitted = (model.c * x.h.powf(model.p) - model.d * x.dt.powf(model.q)).abs();
            assert!((fitted / x.error - 1.0).abs() < 0.1, "{x:?} {model:?}");
        }
        let cancelling = &runs[1];
        assert!(
            model.error(cancelling.h, cancelling.dt) > 30.0 * cancelling.error,
            "{model:?}"
        );
    }

    /// A floor neither field refines is found once there are levels enough.
    #[test]
    fn a_floor_is_fitted_where_the_error_stops_falling() {
        let law = |h: f64, dt: f64| 3.0 * h * h + 0.5 * dt + 1e-3;
        let model = error_model(&points(law, &DESIGN), 1.0).unwrap();
        assert!((model.floor / 1e-3 - 1.0).abs() < 0.1, "{model:?}");
    }

    #[test]
    fn costs_and_stable_steps_are_fitted_from_their_points() {
        let grid = [(0.1, 1e-2), (0.05, 1e-2), (0.1, 5e-3)];
        let cost = cost_model(&points(|_, _| 1.0, &grid), 2.0).unwrap();
        assert!(
            (cost.a - 2.0).abs() < 1e-9 && (cost.b - 1.0).abs() < 1e-9,
            "{cost:?}"
        );
        assert!((cost.cost(0.02, 1e-3) / (1e-6 / (0.02 * 0.02 * 1e-3)) - 1.0).abs() < 1e-9);
        let stable = stable_step(&[(0.1, 2e-3), (0.05, 5e-4)]).unwrap();
        assert!((stable(0.025) / 1.25e-4 - 1.0).abs() < 1e-9);
    }
}
