//! The continuum nonlocal operator L φ(x) = c ∫_{H_ε(x)} J(|y−x|/ε)(φ(y) − φ(x)) dy of eq. 1.1,
//! evaluated at the nodes by accurate quadrature, for the manufactured profile φ of Appendix A
//! (zero outside D). With it the source b = ∂ₜw − L w makes the error measure the spatial
//! discretization alone.
//!
//! φ is smooth inside D and only continuous across ∂D, so the integral is split where its
//! integrand loses smoothness and each smooth piece gets Gauss–Legendre:
//! - 1D: at s = 0 (J(|s|/ε) has a kink) and where x + s crosses 0 or 1.
//! - 2D, in polar coordinates y = x + ρ(cos θ, sin θ): in ρ at the crossings of the ray with the
//!   four sides of D; in θ at the corners of D (the first side hit changes) and where the circle
//!   of radius ε meets a side (a crossing enters or leaves (0, ε)). The factor ρ of dy cancels the
//!   1/ρ of the inverse-distance kernel, so every piece is smooth.
//!
//! Where the ball lies inside D, φ = sin(a x₁) sin(a x₂) is an eigenfunction of the
//! translation-invariant operator: averaging over ±z leaves φ(x + z) → φ(x) cos(a z₁) cos(a z₂),
//! so L φ = λ φ with λ = c ∫_{|z|≤ε} J(|z|/ε)(cos(a z₁) cos(a z₂) − 1) dz (cos(a z) − 1 in 1D),
//! computed once.
//!
//! Along an edge of the square, where the ball crosses one side only, the same averaging over
//! ±z along that side (the cut ball is symmetric in it) gives L φ(x) = sin(a x_∥) G(x_⊥): G
//! depends on the distance to the side alone. `for_grid` computes G once per grid line near a
//! side, by the quadrature at x_∥ = 1/4 (where sin(a x_∥) = 1), so only the corner squares need
//! the quadrature node by node: at n = 2048, m = 32, 4096 nodes instead of 262 144.

use crate::case::Kernel;
use crate::discretization::grid::{Grid, Horizon};
use crate::discretization::influence::Influence;
use crate::problem::{profile, WAVENUMBER};
use gauss_quad::legendre::GaussLegendre;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::num::NonZeroUsize;

/// Gauss–Legendre points per piece; the refinement test shows 24 resolves L φ to ~1e-13.
pub const DEFAULT_ORDER: usize = 24;
/// Widest θ panel: the integrand's angular variation is at most that of sin over one period.
const MAX_ANGLE_PANEL: f64 = PI / 8.0;

pub struct ContinuumOperator {
    dim: usize,
    eps: f64,
    kernel: Kernel,
    c: f64,
    rule: GaussLegendre,
    /// L φ = (this) · φ wherever the ball lies inside D.
    interior_multiplier: f64,
    /// 2D, from `for_grid`: G at each grid line's coordinate (NaN away from the sides).
    edge_profile: Option<Vec<f64>>,
}

impl ContinuumOperator {
    pub fn new(dim: usize, horizon: &Horizon, kernel: Kernel, c: f64, order: usize) -> Self {
        let order = NonZeroUsize::new(order).expect("quadrature order is at least 1");
        let mut operator = ContinuumOperator {
            dim,
            eps: horizon.eps,
            kernel,
            c,
            rule: GaussLegendre::new(order),
            interior_multiplier: 0.0,
            edge_profile: None,
        };
        operator.interior_multiplier = operator.compute_interior_multiplier();
        operator
    }

    /// λ with L φ̃ = λ φ̃ for the continued profile φ̃ (see the module comment).
    pub fn eigenvalue(&self) -> f64 {
        self.interior_multiplier
    }

    /// L φ at every node of the grid.
    pub fn apply_to_profile(&self, grid: &Grid) -> Vec<f64> {
        (0..grid.nodes())
            .into_par_iter()
            .map(|i| self.at_node(grid, i))
            .collect()
    }

    /// The operator with G of the edge strips tabulated for `grid`'s lines (2D, ε ≤ 1/4, so
    /// that x_∥ = 1/4 is clear of the other sides); `at_node` then uses it on this grid.
    pub fn for_grid(mut self, grid: &Grid) -> Self {
        if self.dim != 2 || self.eps > 0.25 {
            return self;
        }
        let table = (0..grid.n)
            .into_par_iter()
            .map(|k| {
                let x = grid.coord(k as i64);
                match x.min(1.0 - x) < self.eps {
                    true => self.at([0.25, x]),
                    false => f64::NAN,
                }
            })
            .collect();
        self.edge_profile = Some(table);
        self
    }

    /// L φ at node i of the grid: the closed form where the ball lies inside D, the edge
    /// profile where it crosses one side (after `for_grid`), else quadrature.
    pub fn at_node(&self, grid: &Grid, i: usize) -> f64 {
        let x = grid.position(i);
        let clear = |a: usize| x[a].min(1.0 - x[a]) >= self.eps;
        if (0..self.dim).all(clear) {
            return self.interior_multiplier * profile(self.dim, x);
        }
        if let Some(edge) = self.edge_profile.as_ref().filter(|e| e.len() == grid.n) {
            let (ix, iy) = (i % grid.n, i / grid.n);
            match (clear(0), clear(1)) {
                (true, false) => return (WAVENUMBER * x[0]).sin() * edge[iy],
                (false, true) => return (WAVENUMBER * x[1]).sin() * edge[ix],
                _ => {}
            }
        }
        self.at(x)
    }

    /// L φ(x) by the split quadrature, valid at any x in D.
    pub fn at(&self, x: [f64; 2]) -> f64 {
        match self.dim {
            1 => self.at_1d(x[0]),
            _ => self.at_2d(x),
        }
    }

    fn at_1d(&self, x: f64) -> f64 {
        let eps = self.eps;
        let phi_x = profile(1, [x, 0.0]);
        let mut breaks = vec![-eps, 0.0, eps, -x, 1.0 - x];
        breaks.retain(|s| s.abs() <= eps);
        sort_dedup(&mut breaks);
        let integrand =
            |s: f64| self.kernel.influence(s.abs() / eps) * (profile(1, [x + s, 0.0]) - phi_x);
        let integral: f64 = breaks
            .windows(2)
            .flat_map(|p| graded_panels(p[0], p[1]))
            .map(|(a, b)| self.rule.integrate(a, b, integrand))
            .sum();
        self.c * integral
    }

    fn at_2d(&self, x: [f64; 2]) -> f64 {
        let eps = self.eps;
        let phi_x = profile(2, x);
        let mut angles = vec![0.0, 2.0 * PI];
        for cx in [0.0, 1.0] {
            for cy in [0.0, 1.0] {
                angles.push((cy - x[1]).atan2(cx - x[0]));
            }
        }
        for side in [0.0, 1.0] {
            for (axis, coordinate) in x.iter().enumerate() {
                let offset = (side - coordinate) / eps;
                if offset.abs() < 1.0 {
                    let (a, b) = if axis == 0 {
                        (offset.acos(), -offset.acos())
                    } else {
                        (offset.asin(), PI - offset.asin())
                    };
                    angles.extend([a, b]);
                }
            }
        }
        for a in angles.iter_mut() {
            *a = a.rem_euclid(2.0 * PI);
        }
        angles.push(2.0 * PI);
        sort_dedup(&mut angles);

        let radial = |theta: f64| {
            let (sin, cos) = theta.sin_cos();
            let mut breaks = vec![0.0, eps];
            for side in [0.0, 1.0] {
                for (xa, da) in [(x[0], cos), (x[1], sin)] {
                    let rho = (side - xa) / da;
                    if rho > 0.0 && rho < eps {
                        breaks.push(rho);
                    }
                }
            }
            sort_dedup(&mut breaks);
            let integrand = |rho: f64| {
                let y = [x[0] + rho * cos, x[1] + rho * sin];
                self.kernel.influence(rho / eps) * (profile(2, y) - phi_x) * rho
            };
            breaks
                .windows(2)
                .map(|p| self.rule.integrate(p[0], p[1], integrand))
                .sum::<f64>()
        };
        let integral: f64 = angles
            .windows(2)
            .map(|p| {
                let panels = ((p[1] - p[0]) / MAX_ANGLE_PANEL).ceil().max(1.0) as usize;
                let width = (p[1] - p[0]) / panels as f64;
                (0..panels)
                    .map(|k| {
                        let a = p[0] + k as f64 * width;
                        self.rule.integrate(a, a + width, radial)
                    })
                    .sum::<f64>()
            })
            .sum();
        self.c * integral
    }

    /// λ with L φ = λ φ at nodes whose ball lies in D (see the module comment).
    fn compute_interior_multiplier(&self) -> f64 {
        let eps = self.eps;
        let a = WAVENUMBER;
        let integral = match self.dim {
            1 => {
                2.0 * self.rule.integrate(0.0, eps, |s| {
                    self.kernel.influence(s / eps) * ((a * s).cos() - 1.0)
                })
            }
            _ => self.rule.integrate(0.0, eps, |rho| {
                // The θ-integrand is periodic and analytic: the trapezoid rule converges
                // geometrically; 64 points reach round-off for aρ ≤ π.
                const POINTS: usize = 64;
                let ring: f64 = (0..POINTS)
                    .map(|k| {
                        let (sin, cos) = (2.0 * PI * k as f64 / POINTS as f64).sin_cos();
                        (a * rho * cos).cos() * (a * rho * sin).cos() - 1.0
                    })
                    .sum::<f64>()
                    * (2.0 * PI / POINTS as f64);
                self.kernel.influence(rho / eps) * ring * rho
            }),
        };
        self.c * integral
    }
}

/// Splits [a, b] (on one side of 0) into panels no wider than their distance from 0, so that
/// J = 1/|s| on the collar part of the ball, −ε φ(x)/|s| for s from −ε to −x, is resolved even
/// when its pole at s = 0 is close to the panel (x ≪ ε).
fn graded_panels(a: f64, b: f64) -> Vec<(f64, f64)> {
    let (near, far) = if a.abs() < b.abs() { (a, b) } else { (b, a) };
    if near == 0.0 || far.abs() <= 2.0 * near.abs() {
        return vec![(a, b)];
    }
    let mut cuts = vec![near];
    while cuts.last().unwrap().abs() * 2.0 < far.abs() {
        cuts.push(cuts.last().unwrap() * 2.0);
    }
    cuts.push(far);
    cuts.windows(2)
        .map(|w| (w[0].min(w[1]), w[0].max(w[1])))
        .collect()
}

fn sort_dedup(v: &mut Vec<f64>) {
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-14);
}
