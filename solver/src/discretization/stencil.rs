//! The weights of the discrete nonlocal operator on a uniform grid, computed once per case.
//!
//! Eq. 2.1 on the lattice hℤ^d is translation invariant: bond offset o ≠ 0 carries
//! w_o = c J(|o|h/ε) V_o, with V_o the volume the case's quadrature gives it (h^d inside the ball
//! for \[JD]'s midpoint rule; see `quadrature`). Since the collar nodes count (with u = 0), every node of D sees the same
//! total weight W = Σ_o w_o, and
//!     L_h u_i = Σ_o w_o u_{i+o} − W u_i   (u = 0 outside D).
//! The stencil backend applies this form, the stability bound reads its symbol, and later backends
//! (FFT, distributed) reuse the same weights.

use super::grid::{Grid, Horizon};
use super::influence::scaling_constant;
use super::quadrature::{bond_influence, kernel_second_moment, BondVolumes};
use crate::case::{Case, Kernel, Quadrature};

/// The bonds of one lattice row dy: offsets dx_min ..= −dx_min, contiguous because the ball is convex.
#[derive(Clone, Debug)]
pub struct StencilRow {
    pub dy: i64,
    pub dx_min: i64,
    /// weights[k] belongs to dx = dx_min + k; the self-bond (0, 0) has weight 0.
    pub weights: Vec<f64>,
}

impl StencilRow {
    /// (dx, w) for every bond of the row, the self-bond excluded.
    pub fn bonds(&self) -> impl Iterator<Item = (i64, f64)> + '_ {
        let dy = self.dy;
        self.weights
            .iter()
            .enumerate()
            .map(move |(k, &w)| (self.dx_min + k as i64, w))
            .filter(move |&(dx, _)| dx != 0 || dy != 0)
    }
}

#[derive(Clone, Debug)]
pub struct Stencil {
    pub grid: Grid,
    pub horizon: Horizon,
    pub kernel: Kernel,
    pub quadrature: Quadrature,
    /// The constant c of eq. 1.5.
    pub c: f64,
    /// V_o per offset, shared with the neighbour-list backend.
    pub volumes: BondVolumes,
    pub rows: Vec<StencilRow>,
    /// W = Σ_o w_o over every bond, collar included.
    pub total_weight: f64,
    /// Number of bond offsets, i.e. neighbours of each node in D ∪ D_c.
    pub offsets: usize,
}

impl Stencil {
    /// The weights of the case's L_h (its horizon given as `m` or `eps`).
    pub fn of_case(case: &Case) -> Stencil {
        let grid = Grid::new(case.dim, case.n);
        let horizon = match case.m {
            Some(m) => Horizon::from_m(&grid, m),
            None => Horizon::from_eps(&grid, case.eps.expect("validated: m or eps")),
        };
        Stencil::new(
            grid,
            horizon,
            case.kernel,
            case.quadrature,
            case.diffusivity,
        )
    }

    /// The weights of eq. 2.1 for `kernel` with horizon `horizon`, diffusivity k and the
    /// bond volumes of `quadrature`.
    pub fn new(
        grid: Grid,
        horizon: Horizon,
        kernel: Kernel,
        quadrature: Quadrature,
        diffusivity: f64,
    ) -> Self {
        let c = scaling_constant(grid.dim, kernel, horizon.eps, diffusivity);
        let volumes = BondVolumes::new(&grid, &horizon, kernel, quadrature);
        let m = horizon.m as i64;
        let dy_range = if grid.dim == 2 { -m..=m } else { 0..=0 };
        let mut rows = Vec::new();
        for dy in dy_range {
            let reach = (0..=m).rev().find(|&dx| volumes.get(dx, dy) > 0.0);
            let Some(reach) = reach else { continue };
            let weights = (-reach..=reach)
                .map(|dx| {
                    if dx == 0 && dy == 0 {
                        return 0.0;
                    }
                    let r = ((dx * dx + dy * dy) as f64).sqrt() * grid.h / horizon.eps;
                    c * bond_influence(kernel, r) * volumes.get(dx, dy)
                })
                .collect();
            rows.push(StencilRow {
                dy,
                dx_min: -reach,
                weights,
            });
        }
        Stencil::from_rows(grid, horizon, kernel, quadrature, c, volumes, rows)
    }

    /// The stencil of the square (ℓ∞) neighbourhood |o|∞ ≤ m of \[XGDF], bond o weighted
    /// `weight(dx, dy)`: every row spans −m ..= m.
    pub fn square(
        grid: Grid,
        horizon: Horizon,
        kernel: Kernel,
        quadrature: Quadrature,
        c: f64,
        weight: impl Fn(i64, i64) -> f64,
    ) -> Self {
        let m = horizon.m as i64;
        let volumes = BondVolumes::square(&grid, horizon.m);
        let rows = (-m..=m)
            .map(|dy| StencilRow {
                dy,
                dx_min: -m,
                weights: (-m..=m)
                    .map(|dx| {
                        if (dx, dy) == (0, 0) {
                            0.0
                        } else {
                            weight(dx, dy)
                        }
                    })
                    .collect(),
            })
            .collect();
        Stencil::from_rows(grid, horizon, kernel, quadrature, c, volumes, rows)
    }

    fn from_rows(
        grid: Grid,
        horizon: Horizon,
        kernel: Kernel,
        quadrature: Quadrature,
        c: f64,
        volumes: BondVolumes,
        rows: Vec<StencilRow>,
    ) -> Self {
        let total_weight = rows
            .iter()
            .flat_map(|row| row.bonds())
            .map(|(_, w)| w)
            .sum();
        let offsets = rows.iter().map(|row| row.bonds().count()).sum();
        Stencil {
            grid,
            horizon,
            kernel,
            quadrature,
            c,
            volumes,
            rows,
            total_weight,
            offsets,
        }
    }

    /// L_h|x|² / (2dk) − 1: the relative error of the quadratic patch test (\[LSSM]) on the
    /// lattice, where L_h|x|² = Σ_o w_o |o h|² at every node whose ball lies in D. Zero up to
    /// round-off for `ac`; 2dk = c ∫_{B_ε} J |z|² dz by eq. 1.5.
    pub fn patch_error(&self) -> f64 {
        let exact = self.c * kernel_second_moment(self.grid.dim, self.kernel, self.horizon.eps);
        self.second_moment() / exact - 1.0
    }

    /// Σ_o w_o |o h|²: L_h|x|² at a node whose neighbourhood lies in D.
    pub fn second_moment(&self) -> f64 {
        let h2 = self.grid.h * self.grid.h;
        self.rows
            .iter()
            .flat_map(|row| {
                row.bonds()
                    .map(move |(dx, w)| w * (dx * dx + row.dy * row.dy) as f64)
            })
            .sum::<f64>()
            * h2
    }

    /// Σ_o w_o f(x_{i+o}) over the bonds of node i that reach into the collar.
    pub fn collar_sum(&self, i: usize, f: impl Fn(usize, [f64; 2]) -> f64) -> f64 {
        let grid = &self.grid;
        let (n, rows) = (grid.n as i64, grid.rows() as i64);
        let (ix, iy) = ((i % grid.n) as i64, (i / grid.n) as i64);
        let mut sum = 0.0;
        for row in &self.rows {
            let jy = iy + row.dy;
            for (dx, w) in row.bonds() {
                let jx = ix + dx;
                if !(0..n).contains(&jx) || !(0..rows).contains(&jy) {
                    let y = if grid.dim == 2 { grid.coord(jy) } else { 0.0 };
                    sum += w * f(grid.dim, [grid.coord(jx), y]);
                }
            }
        }
        sum
    }

    /// Largest |dx| or |dy| of a bond, at most m.
    pub fn reach(&self) -> usize {
        self.rows
            .iter()
            .map(|row| row.dx_min.unsigned_abs() as usize)
            .max()
            .unwrap_or(0)
    }

    /// Σ_i |neighbourList[i]| of Algorithm 1: every node of D with each of its neighbours in D ∪ D_c.
    pub fn bonds(&self) -> usize {
        self.grid.nodes() * self.offsets
    }
}
