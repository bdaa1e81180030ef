//! The neighbour-list backend: Algorithm 1 of \[JD], literally.
//!
//! The list of node i holds every node j of D ∪ D_c that the quadrature gives a volume V_ij > 0
//! (for \[JD]'s midpoint rule: 0 < |x_j − x_i| ≤ ε), by its index on the grid extended by the
//! collar. Each application recomputes |x_j − x_i| and J for every bond and sums
//! c J (U[j] − U[i]) V_ij, with U = 0 on the collar. This is the slow, obviously right oracle.

use super::linear::LinearOperator;
use crate::case::{Kernel, Quadrature};
use crate::discretization::grid::{Grid, Horizon};
use crate::discretization::quadrature::{bond_influence, BondVolumes};
use crate::discretization::stencil::Stencil;
use rayon::prelude::*;

pub struct NeighbourList {
    grid: Grid,
    horizon: Horizon,
    kernel: Kernel,
    c: f64,
    volumes: BondVolumes,
    /// Side of the extended grid, n + 2m (1 in the second direction in 1D).
    extended_side: usize,
    /// neighbours[start[i]..start[i + 1]] is the list of node i (compressed rows).
    start: Vec<usize>,
    neighbours: Vec<u32>,
}

impl NeighbourList {
    /// Builds the lists for the grid, horizon, kernel, c and bond volumes of `stencil` (not its
    /// weights).
    pub fn new(stencil: &Stencil) -> Self {
        let (grid, horizon) = (stencil.grid, stencil.horizon);
        let m = horizon.m as i64;
        let extended_side = grid.n + 2 * horizon.m;
        let mut start = Vec::with_capacity(grid.nodes() + 1);
        let mut neighbours = Vec::new();
        let dy_reach = if grid.dim == 2 { m } else { 0 };
        for i in 0..grid.nodes() {
            start.push(neighbours.len());
            let xi = grid.position(i);
            let (ix, iy) = ((i % grid.n) as i64, (i / grid.n) as i64);
            for jy in iy - dy_reach..=iy + dy_reach {
                for jx in ix - m..=ix + m {
                    if jx == ix && jy == iy {
                        continue;
                    }
                    let xj = position_of(&grid, jx, jy);
                    let member = match stencil.quadrature {
                        Quadrature::Midpoint => horizon.contains_distance(distance(xi, xj)),
                        _ => stencil.volumes.get(jx - ix, jy - iy) > 0.0,
                    };
                    if member {
                        let ex = (jx + m) as usize;
                        let ey = if grid.dim == 2 { (jy + m) as usize } else { 0 };
                        neighbours.push((ey * extended_side + ex) as u32);
                    }
                }
            }
        }
        start.push(neighbours.len());
        NeighbourList {
            grid,
            horizon,
            kernel: stencil.kernel,
            c: stencil.c,
            volumes: stencil.volumes.clone(),
            extended_side,
            start,
            neighbours,
        }
    }

    /// Grid indices (jx, jy) of extended index j; they are negative or ≥ n on the collar.
    fn grid_indices(&self, j: u32) -> (i64, i64) {
        let m = self.horizon.m as i64;
        let j = j as usize;
        let jx = (j % self.extended_side) as i64 - m;
        let jy = if self.grid.dim == 2 {
            (j / self.extended_side) as i64 - m
        } else {
            0
        };
        (jx, jy)
    }
}

fn position_of(grid: &Grid, jx: i64, jy: i64) -> [f64; 2] {
    let y = if grid.dim == 2 { grid.coord(jy) } else { 0.0 };
    [grid.coord(jx), y]
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

impl LinearOperator for NeighbourList {
    /// The oracle recomputes everything from the lists: no scratch.
    type Workspace = ();

    fn workspace(&self) {}

    fn apply(&self, u: &[f64], out: &mut [f64], _: &mut ()) {
        let grid = &self.grid;
        let n = grid.n as i64;
        out.par_iter_mut().enumerate().for_each(|(i, out_i)| {
            let xi = grid.position(i);
            let (ix, iy) = ((i % grid.n) as i64, (i / grid.n) as i64);
            let ui = u[i];
            let mut val_i = 0.0;
            for &j in &self.neighbours[self.start[i]..self.start[i + 1]] {
                let (jx, jy) = self.grid_indices(j);
                let inside = (0..n).contains(&jx) && (0..n).contains(&jy);
                let uj = if inside {
                    u[(jy * n + jx) as usize]
                } else {
                    0.0
                };
                let r = distance(xi, position_of(grid, jx, jy)) / self.horizon.eps;
                let volume = self.volumes.get(jx - ix, jy - iy);
                val_i += self.c * bond_influence(self.kernel, r) * (uj - ui) * volume;
            }
            *out_i = val_i;
        });
    }
}
