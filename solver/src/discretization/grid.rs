//! The discretization of D = [0,1]^d: n cell-centred nodes per side and the horizon ε in cells.
//!
//! Node i sits at x_i = (i + ½) h with h = 1/n, so the cells of volume V_j = h^d tile D exactly and
//! the collar D_c of width ε holds only nodes outside D, where u = 0 (eq. 2.2). In 2D the node
//! (ix, iy) is stored at iy·n + ix.

/// Relative slack of the closed-ball test |x_j − x_i| ≤ ε, so that a node at distance exactly ε
/// (in exact arithmetic) is inside whatever the rounding of ε/h.
const BALL_SLACK: f64 = 1e-12;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub dim: usize,
    pub n: usize,
    pub h: f64,
}

impl Grid {
    pub fn new(dim: usize, n: usize) -> Self {
        Grid {
            dim,
            n,
            h: 1.0 / n as f64,
        }
    }

    /// Number of nodes in D.
    pub fn nodes(&self) -> usize {
        self.n.pow(self.dim as u32)
    }

    /// Rows of nodes: n in 2D, 1 in 1D.
    pub fn rows(&self) -> usize {
        if self.dim == 2 {
            self.n
        } else {
            1
        }
    }

    /// V_j = h^d.
    pub fn volume(&self) -> f64 {
        self.h.powi(self.dim as i32)
    }

    /// Coordinate of grid index i along one axis (i may lie in the collar: negative or ≥ n).
    #[inline]
    pub fn coord(&self, i: i64) -> f64 {
        (i as f64 + 0.5) * self.h
    }

    /// Where the field's values sit, for output.
    pub fn lattice(&self) -> Lattice {
        Lattice {
            dim: self.dim,
            n: self.n,
            origin: self.coord(0),
            spacing: self.h,
        }
    }

    /// Position of node `index` of D (the second coordinate is 0 in 1D).
    pub fn position(&self, index: usize) -> [f64; 2] {
        let (ix, iy) = (index % self.n, index / self.n);
        let y = if self.dim == 2 {
            self.coord(iy as i64)
        } else {
            0.0
        };
        [self.coord(ix as i64), y]
    }
}

/// The horizon ε and its extent m = ⌈ε/h⌉ in cells.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Horizon {
    pub eps: f64,
    pub m: usize,
    /// ε/h, exactly m when the case gave m.
    pub radius_cells: f64,
}

impl Horizon {
    /// ε = m·h.
    pub fn from_m(grid: &Grid, m: usize) -> Self {
        Horizon {
            eps: m as f64 * grid.h,
            m,
            radius_cells: m as f64,
        }
    }

    /// ε given directly; m = ⌈ε/h⌉ (a node at distance ε/h ≈ integer is not pushed one cell out).
    pub fn from_eps(grid: &Grid, eps: f64) -> Self {
        let radius_cells = eps / grid.h;
        Horizon {
            eps,
            m: (radius_cells * (1.0 - BALL_SLACK)).ceil() as usize,
            radius_cells,
        }
    }

    /// Does the lattice offset (dx, dy), in cells, lie in the closed ball of radius ε?
    #[inline]
    pub fn contains_offset(&self, dx: i64, dy: i64) -> bool {
        let r2 = (dx * dx + dy * dy) as f64;
        r2 <= self.radius_cells * self.radius_cells * (1.0 + BALL_SLACK)
    }

    /// Does a point at Euclidean distance `dist` lie in the closed ball of radius ε?
    #[inline]
    pub fn contains_distance(&self, dist: f64) -> bool {
        dist <= self.eps * (1.0 + BALL_SLACK)
    }
}

/// A rectangle of D's lattice, [x0, x0 + nx) × [y0, y0 + ny), stored row-major: the part of the
/// grid a rank keeps (its nodes and their ghosts), or all of D. In 1D, y0 = 0 and ny = 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x0: usize,
    pub y0: usize,
    pub nx: usize,
    pub ny: usize,
}

impl Window {
    /// All of D.
    pub fn whole(grid: &Grid) -> Self {
        Window {
            x0: 0,
            y0: 0,
            nx: grid.n,
            ny: grid.rows(),
        }
    }

    /// The box of nodes [lo, hi) grown by `reach` sideways (and by rows too in 2D), clipped to
    /// D: every node a stencil at a node of the box reads.
    pub fn around(grid: &Grid, lo: [usize; 2], hi: [usize; 2], reach: usize) -> Self {
        let reach_y = if grid.dim == 2 { reach } else { 0 };
        let (x0, y0) = (lo[0].saturating_sub(reach), lo[1].saturating_sub(reach_y));
        Window {
            x0,
            y0,
            nx: (hi[0] + reach).min(grid.n) - x0,
            ny: (hi[1] + reach_y).min(grid.rows()) - y0,
        }
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Storage index of the node in column x, row y of D (which must lie in the window).
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        (y - self.y0) * self.nx + (x - self.x0)
    }

    /// Column and row in D of storage index w: the inverse of `index`.
    pub fn column_row(&self, w: usize) -> (usize, usize) {
        (self.x0 + w % self.nx, self.y0 + w / self.nx)
    }
}

/// A window stored with `pad` zero cells before and after each of its rows: a stencil whose bonds
/// reach at most `pad` columns reads every bond of a window node without a bounds check (bonds
/// that leave D along x land on the zeros of the collar; rows outside D are skipped).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PaddedWindow {
    pub window: Window,
    pub pad: usize,
}

impl PaddedWindow {
    /// Distance between the starts of consecutive rows.
    pub fn stride(&self) -> usize {
        self.window.nx + 2 * self.pad
    }

    pub fn len(&self) -> usize {
        self.stride() * self.window.ny
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Storage index of the node in column x, row y of D (which must lie in the window).
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        (y - self.window.y0) * self.stride() + (x - self.window.x0) + self.pad
    }
}

/// A run of consecutive nodes in one row: columns x0..x1 of row y of D, stored from `offset` on
/// in compact (run-ordered) arrays, such as a rank's owned nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RowRun {
    pub y: usize,
    pub x0: usize,
    pub x1: usize,
    pub offset: usize,
}

impl RowRun {
    pub fn len(&self) -> usize {
        self.x1 - self.x0
    }

    pub fn is_empty(&self) -> bool {
        self.x1 == self.x0
    }
}

/// Where a field's values sit: n nodes per side in `dim` dimensions, node (ix, iy) at
/// (origin + ix·spacing, origin + iy·spacing), stored at iy·n + ix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    pub dim: usize,
    pub n: usize,
    pub origin: f64,
    pub spacing: f64,
}

impl Lattice {
    pub fn nodes(&self) -> usize {
        self.n.pow(self.dim as u32)
    }
}
