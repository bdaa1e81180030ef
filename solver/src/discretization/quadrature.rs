//! Quadrature rules of the discrete nonlocal operator: the volume V_o each lattice bond offset o
//! carries in L_h u_i = Σ_o c J(|o|h/ε) V_o (u_{i+o} − u_i).
//!
//! - `midpoint` (\[JD], eq. 2.1): V_o = h^d when |o|h ≤ ε, else 0.
//! - `partial_volume`: V_o = |cell_o ∩ B_ε|, the part of node o's cell inside the ball, computed
//!   exactly (1D: an interval overlap; 2D: a square ∩ disc area in closed form). Cells cut by the
//!   sphere count even when their node lies outside; their J is taken at r = 1 (J(min(r, 1))),
//!   since J is only defined on the ball. In 1D with ε = m h this is the trapezoid rule.
//! - `ac`: the partial volumes rescaled so that L_h is exact on quadratics. Derivation: the
//!   weights w_o are even in each axis and (in 2D) symmetric under swapping the axes, so for a
//!   polynomial p of degree ≤ 3 the Taylor expansion of Σ_o w_o (p(x + oh) − p(x)) keeps only
//!   ½ Σ_o w_o (o h)ᵀ ∇²p (o h) = (Δp / 2d) Σ_o w_o |o h|²: the odd terms and the mixed second
//!   derivatives cancel. Hence L_h is exact on every polynomial of degree ≤ 3 (L_h p = kΔp, as the
//!   continuum operator of eq. 1.1 with c of eq. 1.5 is) if and only if the one moment condition
//!   Σ_o w_o |o h|² = 2 d k,   i.e.   Σ_o J_o V_o |o h|² = ∫_{B_ε} J(|z|/ε) |z|² dz
//!   holds (the right side is 2ε³M₂ in 1D and 2πε⁴M₃ in 2D). This is the quadratic exactness of
//!   \[RKAC] (Lemma 5), whose quasi-discrete operator gets it from reproducing-kernel quadrature
//!   weights; on our symmetric lattice the generalized-moving-least-squares weight fit of Trask,
//!   You, Yu & Parks (CMAME 343, 2019) reduces to the same single condition, since the linear and
//!   mixed quadratic constraints hold by symmetry. Of the weights that meet it we take the
//!   rescaling V_o = s V_o^partial, which keeps the kernel's shape (Tian & Du, SINUM 51, 2013, show
//!   that quadratic exactness is what makes a quadrature-based scheme AC). Consistency:
//!   L_h u − kΔu = O(Σ_o w_o |o h|⁴) = O(ε²) for fixed m (convergence to the local limit), and
//!   s − 1 → 0 with the partial volumes' quadrature error for fixed ε (convergence to the
//!   nonlocal operator).

use crate::case::{Kernel, Quadrature};
use crate::discretization::grid::{Grid, Horizon};
use crate::discretization::influence::Influence;
use std::f64::consts::PI;

/// J of a bond at distance r·ε: cells cut by the sphere may have their node just outside the
/// ball (r > 1), where J is taken at the sphere.
#[inline]
pub fn bond_influence(kernel: Kernel, r: f64) -> f64 {
    kernel.influence(r.min(1.0))
}

/// V_o for every offset o with |o_a| ≤ m, computed once per case.
#[derive(Clone, Debug, PartialEq)]
pub struct BondVolumes {
    dim: usize,
    m: usize,
    /// volumes[(dy + m)(2m + 1) + (dx + m)]; one row in 1D.
    volumes: Vec<f64>,
}

impl BondVolumes {
    pub fn new(grid: &Grid, horizon: &Horizon, kernel: Kernel, quadrature: Quadrature) -> Self {
        let m = horizon.m as i64;
        let side = 2 * horizon.m + 1;
        let dy_range = if grid.dim == 2 { -m..=m } else { 0..=0 };
        let mut volumes = Vec::with_capacity(side * dy_range.clone().count());
        for dy in dy_range {
            for dx in -m..=m {
                let volume = if dx == 0 && dy == 0 {
                    0.0
                } else {
                    match quadrature {
                        Quadrature::Midpoint => {
                            if horizon.contains_offset(dx, dy) {
                                grid.volume()
                            } else {
                                0.0
                            }
                        }
                        Quadrature::PartialVolume | Quadrature::Ac => {
                            cell_in_ball(grid.dim, horizon.radius_cells, dx, dy) * grid.volume()
                        }
                    }
                };
                volumes.push(volume);
            }
        }
        let mut bond_volumes = BondVolumes {
            dim: grid.dim,
            m: horizon.m,
            volumes,
        };
        if quadrature == Quadrature::Ac {
            let discrete = bond_volumes.second_moment(grid.h, horizon.radius_cells, kernel);
            let exact = kernel_second_moment(grid.dim, kernel, horizon.eps);
            // discrete = 0 only when every bond has J = 0; the case is refused for that later.
            if discrete > 0.0 {
                let scale = exact / discrete;
                bond_volumes.volumes.iter_mut().for_each(|v| *v *= scale);
            }
        }
        bond_volumes
    }

    /// h² for every offset of the square |o|∞ ≤ m but the origin (2D): \[XGDF]'s ω_j.
    pub fn square(grid: &Grid, m: usize) -> Self {
        let side = 2 * m + 1;
        let mut volumes = vec![grid.volume(); side * side];
        volumes[m * side + m] = 0.0;
        BondVolumes { dim: 2, m, volumes }
    }

    /// V_o, 0 outside the ball (and for |o_a| > m).
    #[inline]
    pub fn get(&self, dx: i64, dy: i64) -> f64 {
        let m = self.m as i64;
        if dx.abs() > m || dy.abs() > m || (self.dim == 1 && dy != 0) {
            return 0.0;
        }
        let side = 2 * m + 1;
        let row = if self.dim == 2 { dy + m } else { 0 };
        self.volumes[(row * side + dx + m) as usize]
    }

    /// Σ_o J_o V_o |o h|² (the left side of the moment condition).
    fn second_moment(&self, h: f64, radius_cells: f64, kernel: Kernel) -> f64 {
        let m = self.m as i64;
        let dy_reach = if self.dim == 2 { m } else { 0 };
        let mut sum = 0.0;
        for dy in -dy_reach..=dy_reach {
            for dx in -m..=m {
                let r2 = (dx * dx + dy * dy) as f64;
                let volume = self.get(dx, dy);
                if volume > 0.0 {
                    sum += bond_influence(kernel, r2.sqrt() / radius_cells) * volume * r2 * h * h;
                }
            }
        }
        sum
    }
}

/// ∫_{B_ε} J(|z|/ε) |z|² dz: 2ε³M₂ in 1D, 2πε⁴M₃ in 2D.
pub fn kernel_second_moment(dim: usize, kernel: Kernel, eps: f64) -> f64 {
    match dim {
        1 => 2.0 * eps.powi(3) * kernel.moment(2),
        _ => 2.0 * PI * eps.powi(4) * kernel.moment(3),
    }
}

/// The fraction of the cell of offset (dx, dy) inside the ball of radius R (in cells) centred at 0.
fn cell_in_ball(dim: usize, radius: f64, dx: i64, dy: i64) -> f64 {
    let (x0, x1) = (dx as f64 - 0.5, dx as f64 + 0.5);
    if dim == 1 {
        return (x1.min(radius) - x0.max(-radius)).max(0.0);
    }
    rectangle_in_disc(radius, [x0, x1], [dy as f64 - 0.5, dy as f64 + 0.5])
}

/// Area of [x0, x1] × [y0, y1] ∩ {|z| ≤ R}, exactly: ∫ |[y0, y1] ∩ [−s, s]| dx with
/// s(x) = √(R² − x²), split where s crosses |y0| or |y1| so that on each piece the chord's ends are
/// fixed (a side of the rectangle or the circle), each integrated with ∫ s = ½(x s + R² asin(x/R)).
fn rectangle_in_disc(radius: f64, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> f64 {
    let (a, b) = (x0.max(-radius), x1.min(radius));
    if a >= b {
        return 0.0;
    }
    let half_chord = |x: f64| (radius * radius - x * x).max(0.0).sqrt();
    let antiderivative = |x: f64| {
        let x = x.clamp(-radius, radius);
        0.5 * (x * half_chord(x) + radius * radius * (x / radius).asin())
    };
    let mut breaks = vec![a, b];
    for y in [y0, y1] {
        if y.abs() < radius {
            let x = half_chord(y);
            breaks.extend([-x, x].into_iter().filter(|&x| x > a && x < b));
        }
    }
    breaks.sort_by(f64::total_cmp);
    breaks
        .windows(2)
        .map(|piece| {
            let (p, q) = (piece[0], piece[1]);
            // Which end is which holds on the whole piece, except where the circle touches a
            // side (s = y1 at one point): the ties go to the circle, which is then the nearer.
            let s_mid = half_chord(0.5 * (p + q));
            let top_is_circle = s_mid <= y1;
            let bottom_is_circle = -s_mid >= y0;
            if s_mid.min(y1) <= (-s_mid).max(y0) {
                return 0.0;
            }
            let s_integral = antiderivative(q) - antiderivative(p);
            let width = q - p;
            let top = if top_is_circle {
                s_integral
            } else {
                y1 * width
            };
            let bottom = if bottom_is_circle {
                -s_integral
            } else {
                y0 * width
            };
            top - bottom
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The area by a fine midpoint rule in x over the chord lengths in y: slow, obviously right.
    fn sampled_area(radius: f64, x: [f64; 2], y: [f64; 2]) -> f64 {
        const K: usize = 200_000;
        let dx = (x[1] - x[0]) / K as f64;
        (0..K)
            .map(|i| {
                let px = x[0] + (i as f64 + 0.5) * dx;
                let s = (radius * radius - px * px).max(0.0).sqrt();
                (s.min(y[1]) - (-s).max(y[0])).max(0.0) * dx
            })
            .sum()
    }

    #[test]
    fn rectangle_in_disc_matches_a_fine_sampling() {
        let cases = [
            (3.0, [2.5, 3.5], [-0.5, 0.5]),
            (3.0, [1.5, 2.5], [1.5, 2.5]),
            (2.7, [-2.5, -1.5], [0.5, 1.5]),
            (1.0, [-0.5, 0.5], [0.5, 1.5]),
            (2.5, [-0.5, 0.5], [1.5, 2.5]), // the circle touches the top side at x = 0
            (5.3, [3.5, 4.5], [-3.5, -2.5]),
            (0.4, [-0.5, 0.5], [-0.5, 0.5]),
        ];
        for (radius, x, y) in cases {
            let exact = rectangle_in_disc(radius, x, y);
            let sampled = sampled_area(radius, x, y);
            // The chord has √ kinks where the circle meets a side: the midpoint rule errs by ~1e-9.
            assert!(
                (exact - sampled).abs() < 1e-8,
                "R = {radius}, {x:?} × {y:?}: exact {exact}, sampled {sampled}"
            );
        }
    }

    #[test]
    fn partial_volumes_tile_the_ball_exactly() {
        for radius_cells in [1.0, 2.0, 2.5, 3.0, 4.7, 10.0] {
            let n = 64;
            let grid = Grid::new(2, n);
            let horizon = Horizon::from_eps(&grid, radius_cells * grid.h);
            let volumes =
                BondVolumes::new(&grid, &horizon, Kernel::Constant, Quadrature::PartialVolume);
            let m = horizon.m as i64;
            let total: f64 = (-m..=m)
                .flat_map(|dy| (-m..=m).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| volumes.get(dx, dy))
                .sum();
            // The self-cell is left out: it lies inside the ball whole when R ≥ √2/2.
            let ball = PI * horizon.eps.powi(2) - grid.volume();
            assert!(
                (total - ball).abs() < 1e-13 * ball,
                "R = {radius_cells}: cells sum to {total}, ball less its centre cell {ball}"
            );
        }
    }

    #[test]
    fn midpoint_volumes_are_the_full_cells_of_the_closed_ball() {
        let grid = Grid::new(2, 40);
        let horizon = Horizon::from_m(&grid, 3);
        let volumes = BondVolumes::new(&grid, &horizon, Kernel::Constant, Quadrature::Midpoint);
        assert_eq!(volumes.get(3, 0), grid.volume());
        assert_eq!(volumes.get(2, 2), grid.volume()); // √8 < 3
        assert_eq!(volumes.get(3, 1), 0.0); // √10 > 3
        assert_eq!(volumes.get(0, 0), 0.0);
        assert_eq!(volumes.get(4, 0), 0.0);
    }

    #[test]
    fn one_dimensional_partial_volumes_are_the_trapezoid_rule() {
        let grid = Grid::new(1, 50);
        let horizon = Horizon::from_m(&grid, 4);
        let volumes = BondVolumes::new(&grid, &horizon, Kernel::Linear, Quadrature::PartialVolume);
        for dx in 1..4 {
            assert_eq!(volumes.get(dx, 0), grid.h);
            assert_eq!(volumes.get(-dx, 0), grid.h);
        }
        assert!((volumes.get(4, 0) - 0.5 * grid.h).abs() < 1e-16);
    }
}
