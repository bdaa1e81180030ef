//! A horizon that varies along the bar, ε = ε(x) on D = [0, 1], and the two ways of building
//! the nonlocal diffusion operator from it that \[LSSM] compares: the standard (pairwise)
//! formulation, whose patch tests fail where ε varies ("ghost forces"), and the partial-stress
//! formulation, which passes them whatever ε(x).
//!
//! The scalar analogue of the seed's peridynamic forms. Let node x own the bonds ξ = y − x with
//! |ξ| ≤ ε(x), weighted w_x(ξ) = 2k J(|ξ|/ε(x)) / Σ_ξ' J(|ξ'|/ε(x)) ξ'² (so Σ_ξ w_x(ξ) ξ² = 2k: the
//! discrete form of the constant c of eq. 1.5, which makes a constant horizon pass both patch tests
//! to round-off, as the seed's constant-horizon bars do). Its "force state" is
//! T[x]⟨ξ⟩ = ½ w_x(ξ) (u(x + ξ) − u(x)).
//!
//! - **Standard**: L u(x) = Σ_y (T[x]⟨y − x⟩ − T[y]⟨x − y⟩) = Σ_y ½ (w_x(y − x) + w_y(x − y)) (u(y) − u(x)),
//!   the seed's L^pd with the pairwise bond term. It conserves Σ u (the weights are symmetric) but
//!   for u = x it leaves ½ Σ_y (w_y(x − y) − w_x(y − x)) (y − x), which vanishes only where ε is
//!   locally constant: the ghost force, proportional to ε'' for a smooth ε (the seed: "ghost
//!   forces are proportional to the second derivative of the horizon").
//! - **Partial stress** (Silling, Seleson; Lehoucq & Silling 2008): the flux ν(x) = Σ_ξ T[x]⟨ξ⟩ ξ,
//!   the seed's ν₀ = ∫ T[x]⟨ξ⟩ ⊗ ξ dV, equals k u' exactly for a linear u and 2k x for u = x²
//!   (the odd moments of a full ball vanish), whatever ε(x); then L u = ∇·ν by the nonlocal
//!   gradient of the seed's meshless form, ∇ν(x) = Σ_ξ ω(ξ) (ν(x + ξ) − ν(x)) ξ / Σ_ξ ω(ξ) ξ²
//!   with ω(ξ) = J(|ξ|/ε(x)), exact for a linear ν. So L u = 0 for u linear and L u = 2k for
//!   u = x², at every node, to round-off. It does not conserve Σ u exactly.
//! - **x-centred** (the non-divergence form): L u(x) = Σ_ξ w_x(ξ) (u(x + ξ) − u(x)), each node on
//!   its own horizon, unsymmetrised. Its ball is symmetric about x, so it gives 0 for a linear u
//!   and 2k for u = x² at every node whatever ε(x); its rows sum to zero and its off-diagonal
//!   entries are ≥ 0, so by Gershgorin every eigenvalue has Re λ ≤ 0, and forward Euler with
//!   dt ≤ 2 / max_i Σ_l |a_il| keeps 0 ≤ u ≤ max u₀. It is not symmetric and does not conserve
//!   Σ u.
//!
//! Nodes sit at x = (i + ½) h as in `grid`; the bar holds D and a collar of 2R nodes on each side
//! (R the largest reach in cells), where u is prescribed: ν at D's neighbours needs their own
//! neighbours. The horizon outside D is ε at the nearer end.
//!
//! **2D.** D = [0, 1]² with ε = ε(x), the profile along x: the same forms with the bonds of a
//! disc, w_x(ξ) = 2k J(|ξ|/ε(x)) / Σ_ξ' J ξ'₁² (so L x² = 2k), the flux ν a vector and the
//! gradient's divergence Σ_ξ ω (ν(x + ξ) − ν(x))·ξ / Σ_ξ ω ξ₁² (exact for a linear ν: a disc's
//! moments Σ ω ξ₁² and Σ ω ξ₂² agree and Σ ω ξ₁ξ₂ = 0). The bar is the square D and its collar;
//! each row is built on its own (rows are independent, so the thread count does not change the
//! bits), and bonds are kept per column of the bar, since ε depends on x alone.

use crate::case::{Formulation, HorizonProfile, Kernel};
use crate::discretization::influence::Influence;
use rayon::prelude::*;

/// Relative slack of the ball test |ξ| ≤ ε, as in `grid`.
const BALL_SLACK: f64 = 1e-12;

/// ε(x) of a profile; `constant` is the case's ε.
pub fn horizon_at(profile: HorizonProfile, constant: f64, x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    match profile {
        HorizonProfile::Constant => constant,
        HorizonProfile::Linear { left, right } => left + (right - left) * x,
        HorizonProfile::Transition {
            left,
            right,
            start,
            end,
        } => {
            let s = ((x - start) / (end - start)).clamp(0.0, 1.0);
            // A C¹ step (smoothstep), so that ε'' is bounded.
            left + (right - left) * s * s * (3.0 - 2.0 * s)
        }
    }
}

/// An offset ξ in cells, (ξ₁, ξ₂); ξ₂ = 0 in 1D.
type Offset = [i64; 2];

/// One bond of a node: its offset, its weight w_x(ξ) and its influence ω(ξ) = J.
#[derive(Clone, Copy)]
struct Bond {
    offset: Offset,
    weight: f64,
    influence: f64,
}

/// The bonds of the nodes of one column of the bar (one x, so one ε).
struct Column {
    eps: f64,
    /// ε/h with the ball's slack: ξ is in the ball when |ξ| (in cells) is at most this.
    radius: f64,
    /// 2k / Σ_ξ J ξ₁², the factor from J to w.
    scale: f64,
    bonds: Vec<Bond>,
}

impl Column {
    fn new(dim: usize, eps: f64, h: f64, kernel: Kernel, diffusivity: f64) -> Column {
        let radius = eps / h * (1.0 + BALL_SLACK);
        let reach = radius.floor() as i64;
        let rows = if dim == 2 { -reach..=reach } else { 0..=0 };
        let mut column = Column {
            eps,
            radius,
            scale: 1.0,
            bonds: Vec::new(),
        };
        let bonds: Vec<Bond> = rows
            .flat_map(|oy| (-reach..=reach).map(move |ox| [ox, oy]))
            .filter_map(|offset| {
                column.influence(offset, h, kernel).map(|j| Bond {
                    offset,
                    weight: j,
                    influence: j,
                })
            })
            .collect();
        let second_moment: f64 = bonds
            .iter()
            .map(|b| b.weight * (b.offset[0] as f64 * h).powi(2))
            .sum();
        column.scale = 2.0 * diffusivity / second_moment;
        column.bonds = bonds
            .into_iter()
            .map(|b| Bond {
                weight: b.weight * column.scale,
                ..b
            })
            .collect();
        column
    }

    /// J(|ξ|/ε) when ξ is a bond of this column's nodes (in the closed ball, J > 0).
    fn influence(&self, offset: Offset, h: f64, kernel: Kernel) -> Option<f64> {
        let cells2 = (offset[0] * offset[0] + offset[1] * offset[1]) as f64;
        if cells2 == 0.0 || cells2 > self.radius * self.radius {
            return None;
        }
        let j = kernel.influence((cells2.sqrt() * h / self.eps).min(1.0));
        (j > 0.0).then_some(j)
    }
}

/// The operator as explicit rows over the bar's nodes: row i of D (in `grid`'s order) holds
/// (bar index, a_il).
pub struct VariableHorizonOperator {
    pub dim: usize,
    pub n: usize,
    pub h: f64,
    /// Collar nodes on each side of D in the bar.
    pub collar: usize,
    /// ε at each column of the bar.
    pub eps: Vec<f64>,
    rows: Vec<Vec<(usize, f64)>>,
    /// Σ over D's nodes of the bonds each owns (|ξ| ≤ ε(x), J > 0).
    pub bonds: usize,
}

/// Where the rows are built: the columns' bonds and the bar's shape.
struct Bar<'a> {
    dim: usize,
    h: f64,
    /// Nodes per side of the bar.
    side: usize,
    /// The largest reach in cells.
    reach: usize,
    kernel: Kernel,
    columns: &'a [Column],
}

impl VariableHorizonOperator {
    pub fn new(
        dim: usize,
        n: usize,
        profile: HorizonProfile,
        constant_eps: f64,
        kernel: Kernel,
        diffusivity: f64,
        formulation: Formulation,
    ) -> Self {
        assert!(dim == 1 || dim == 2, "a bar of dimension {dim}");
        let h = 1.0 / n as f64;
        let reach_of = |eps: f64| (eps / h * (1.0 + BALL_SLACK)).floor() as usize;
        // The largest reach: ε over D and at its ends, which the collar repeats.
        let reach = (0..n)
            .map(|i| (i as f64 + 0.5) * h)
            .chain([0.0, 1.0])
            .map(|x| reach_of(horizon_at(profile, constant_eps, x)))
            .max()
            .unwrap_or(0);
        let collar = 2 * reach;
        let side = n + 2 * collar;
        let x_of = |k: usize| (k as f64 - collar as f64 + 0.5) * h;
        let columns: Vec<Column> = (0..side)
            .map(|k| {
                let eps = horizon_at(profile, constant_eps, x_of(k));
                Column::new(dim, eps, h, kernel, diffusivity)
            })
            .collect();
        let per_column: usize = columns[collar..collar + n]
            .iter()
            .map(|c| c.bonds.len())
            .sum();
        let bar = Bar {
            dim,
            h,
            side,
            reach,
            kernel,
            columns: &columns,
        };
        let nodes = n.pow(dim as u32);
        let rows = (0..nodes)
            .into_par_iter()
            .map(|i| {
                let node = [i % n + collar, i / n + if dim == 2 { collar } else { 0 }];
                match formulation {
                    Formulation::Standard => bar.standard_row(node),
                    Formulation::PartialStress => bar.partial_stress_row(node),
                    Formulation::XCentred => bar.x_centred_row(node),
                }
            })
            .collect();
        VariableHorizonOperator {
            dim,
            n,
            h,
            collar,
            eps: columns.iter().map(|c| c.eps).collect(),
            rows,
            bonds: per_column * if dim == 2 { n } else { 1 },
        }
    }

    /// Nodes per side of the bar: D and its collars.
    fn side(&self) -> usize {
        self.n + 2 * self.collar
    }

    /// Nodes of the bar: D and its collars.
    pub fn bar_nodes(&self) -> usize {
        self.side().pow(self.dim as u32)
    }

    /// The position of bar node k (stored row by row, as `grid` stores D).
    pub fn position(&self, k: usize) -> [f64; 2] {
        let coordinate = |i: usize| (i as f64 - self.collar as f64 + 0.5) * self.h;
        match self.dim {
            2 => [coordinate(k % self.side()), coordinate(k / self.side())],
            _ => [coordinate(k), 0.0],
        }
    }

    /// x of bar node k.
    pub fn x(&self, k: usize) -> f64 {
        self.position(k)[0]
    }

    /// ε on D's columns.
    pub fn eps_on_d(&self) -> &[f64] {
        &self.eps[self.collar..self.collar + self.n]
    }

    /// The bar index of node i of D.
    pub fn bar_index(&self, i: usize) -> usize {
        let c = self.collar;
        match self.dim {
            2 => (i / self.n + c) * self.side() + i % self.n + c,
            _ => i + c,
        }
    }

    /// (L_h u)_i at D's nodes, for u given at every bar node.
    pub fn apply(&self, u: &[f64]) -> Vec<f64> {
        assert_eq!(u.len(), self.bar_nodes());
        self.rows
            .iter()
            .map(|row| row.iter().map(|&(l, a)| a * u[l]).sum())
            .collect()
    }

    /// The rows of L_h on D's nodes with u = 0 on the collar (eq. 2.2's volume constraint), for
    /// the time-dependent problem: the collar's columns dropped, D's renumbered in `grid`'s
    /// order.
    pub fn rows_with_zero_collar(&self) -> impl Iterator<Item = Vec<(usize, f64)>> + '_ {
        let (side, c, n) = (self.side(), self.collar, self.n);
        let in_d = move |l: usize| -> Option<usize> {
            let (lx, ly) = match self.dim {
                2 => (l % side, l / side),
                _ => (l, c),
            };
            let inside = (c..c + n).contains(&lx) && (c..c + n).contains(&ly);
            inside.then(|| (ly - c) * n * (self.dim - 1) + lx - c)
        };
        self.rows.iter().map(move |row| {
            row.iter()
                .filter_map(|&(l, a)| in_d(l).map(|j| (j, a)))
                .collect()
        })
    }

    /// Gershgorin's bound on the largest |eigenvalue| of L_h: max over rows of Σ_l |a_il|.
    pub fn lambda_bound(&self) -> f64 {
        self.rows
            .iter()
            .map(|row| row.iter().map(|&(_, a)| a.abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }
}

/// Row k's coefficients on the window of offsets within 2R of k (2R per axis), which holds
/// every node a row reaches (the partial-stress form reaches the neighbours of neighbours).
struct Window {
    dim: usize,
    node: [usize; 2],
    /// 2R.
    half: i64,
    a: Vec<f64>,
}

impl Window {
    fn new(dim: usize, node: [usize; 2], reach: usize) -> Window {
        let width = 4 * reach + 1;
        Window {
            dim,
            node,
            half: 2 * reach as i64,
            a: vec![0.0; if dim == 2 { width * width } else { width }],
        }
    }

    fn add(&mut self, offset: Offset, a: f64) {
        let width = 2 * self.half + 1;
        let index =
            (offset[0] + self.half) + (offset[1] + self.half) * width * (self.dim as i64 - 1);
        self.a[index as usize] += a;
    }

    /// The row in bar indices, ascending.
    fn into_row(self, side: usize) -> Vec<(usize, f64)> {
        let width = (2 * self.half + 1) as usize;
        let half = self.half as usize;
        let (node, dim) = (self.node, self.dim);
        self.a
            .into_iter()
            .enumerate()
            .filter(|&(_, a)| a != 0.0)
            .map(|(m, a)| {
                let x = node[0] + m % width - half;
                let index = match dim {
                    2 => (node[1] + m / width - half) * side + x,
                    _ => x,
                };
                (index, a)
            })
            .collect()
    }
}

impl Bar<'_> {
    fn window(&self, node: [usize; 2]) -> Window {
        Window::new(self.dim, node, self.reach)
    }

    /// The column (x index in the bar) at `offset` from `node`.
    fn column(&self, node: [usize; 2], offset: Offset) -> &Column {
        &self.columns[(node[0] as i64 + offset[0]) as usize]
    }

    /// Row of `node`, the standard form: Σ_y ½ (w_x(y − x) + w_y(x − y)) (u_y − u_x).
    fn standard_row(&self, node: [usize; 2]) -> Vec<(usize, f64)> {
        let mut row = self.window(node);
        for bond in &self.columns[node[0]].bonds {
            row.add(bond.offset, 0.5 * bond.weight);
            row.add([0, 0], -0.5 * bond.weight);
        }
        // The bonds other nodes own towards this one: node l = x − o owns the offset o when it
        // reaches x.
        let r = self.reach as i64;
        let rows = if self.dim == 2 { -r..=r } else { 0..=0 };
        for oy in rows {
            for ox in -r..=r {
                let back = [-ox, -oy];
                let owner = self.column(node, back);
                if let Some(j) = owner.influence([ox, oy], self.h, self.kernel) {
                    let w = j * owner.scale;
                    row.add(back, 0.5 * w);
                    row.add([0, 0], -0.5 * w);
                }
            }
        }
        row.into_row(self.side)
    }

    /// Row of `node`, the x-centred form: Σ_ξ w_x(ξ) (u(x + ξ) − u(x)), its own bonds only.
    fn x_centred_row(&self, node: [usize; 2]) -> Vec<(usize, f64)> {
        let mut row = self.window(node);
        for bond in &self.columns[node[0]].bonds {
            row.add(bond.offset, bond.weight);
            row.add([0, 0], -bond.weight);
        }
        row.into_row(self.side)
    }

    /// Row of `node`, the partial-stress form: ∇·ν with ν(x) = ½ Σ_ξ w_x(ξ) (u(x + ξ) − u(x)) ξ.
    fn partial_stress_row(&self, node: [usize; 2]) -> Vec<(usize, f64)> {
        let h = self.h;
        let mut row = self.window(node);
        // Adds c·ν(x + at), ν as coefficients of u.
        let add_flux = |row: &mut Window, at: Offset, c: [f64; 2]| {
            for bond in &self.column(node, at).bonds {
                let z = bond.offset;
                let a = (c[0] * z[0] as f64 + c[1] * z[1] as f64) * 0.5 * bond.weight * h;
                row.add([at[0] + z[0], at[1] + z[1]], a);
                row.add(at, -a);
            }
        };
        let own = &self.columns[node[0]].bonds;
        let weight: f64 = own
            .iter()
            .map(|b| b.influence * (b.offset[0] as f64 * h).powi(2))
            .sum();
        for bond in own {
            let o = bond.offset;
            let c = [o[0], o[1]].map(|o| bond.influence * o as f64 * h / weight);
            add_flux(&mut row, o, c);
            add_flux(&mut row, [0, 0], c.map(|c| -c));
        }
        row.into_row(self.side)
    }
}
