//! A horizon that varies along the bar, ε = ε(x) on D = [0, 1], and the two ways of building
//! the nonlocal diffusion operator from it that seed 003 compares: the standard (pairwise)
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

use crate::case::{Formulation, HorizonProfile, Kernel};
use crate::discretization::influence::Influence;

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

/// The operator as explicit rows over the bar's nodes: row i of D holds (bar index, a_il).
pub struct VariableHorizonOperator {
    pub n: usize,
    pub h: f64,
    /// Collar nodes on each side of D in the bar.
    pub collar: usize,
    /// ε at each bar node.
    pub eps: Vec<f64>,
    rows: Vec<Vec<(usize, f64)>>,
    /// Σ over D's nodes of the bonds each owns (|ξ| ≤ ε(x), J > 0).
    pub bonds: usize,
}

/// One node's bonds: (offset in cells, weight w_x(ξ), influence ω(ξ) = J).
fn node_bonds(eps: f64, h: f64, kernel: Kernel, diffusivity: f64) -> Vec<(i64, f64, f64)> {
    let reach = (eps / h * (1.0 + BALL_SLACK)).floor() as i64;
    let mut bonds: Vec<(i64, f64, f64)> = (-reach..=reach)
        .filter(|&o| o != 0)
        .map(|o| (o, kernel.influence((o.abs() as f64 * h / eps).min(1.0))))
        .filter(|&(_, j)| j > 0.0)
        .map(|(o, j)| (o, j, j))
        .collect();
    let second_moment: f64 = bonds
        .iter()
        .map(|&(o, j, _)| j * (o as f64 * h).powi(2))
        .sum();
    for bond in &mut bonds {
        bond.1 *= 2.0 * diffusivity / second_moment;
    }
    bonds
}

impl VariableHorizonOperator {
    pub fn new(
        n: usize,
        profile: HorizonProfile,
        constant_eps: f64,
        kernel: Kernel,
        diffusivity: f64,
        formulation: Formulation,
    ) -> Self {
        let h = 1.0 / n as f64;
        let reach_of = |eps: f64| (eps / h * (1.0 + BALL_SLACK)).floor() as usize;
        let x_of = |k: usize, collar: usize| (k as f64 - collar as f64 + 0.5) * h;
        // The largest reach: ε over D and at its ends, which the collar repeats.
        let reach = (0..n)
            .map(|i| (i as f64 + 0.5) * h)
            .chain([0.0, 1.0])
            .map(|x| reach_of(horizon_at(profile, constant_eps, x)))
            .max()
            .unwrap_or(0);
        let collar = 2 * reach;
        let size = n + 2 * collar;
        let eps: Vec<f64> = (0..size)
            .map(|k| horizon_at(profile, constant_eps, x_of(k, collar)))
            .collect();
        let bonds_of: Vec<Vec<(i64, f64, f64)>> = eps
            .iter()
            .map(|&e| node_bonds(e, h, kernel, diffusivity))
            .collect();
        let own = (collar..collar + n).map(|k| bonds_of[k].len()).sum();
        let rows = (collar..collar + n)
            .map(|k| match formulation {
                Formulation::Standard => standard_row(k, reach, &bonds_of),
                Formulation::PartialStress => partial_stress_row(k, reach, &bonds_of, h),
                Formulation::XCentred => x_centred_row(k, reach, &bonds_of),
            })
            .collect();
        VariableHorizonOperator {
            n,
            h,
            collar,
            eps,
            rows,
            bonds: own,
        }
    }

    /// Nodes of the bar: D and its collars.
    pub fn bar_nodes(&self) -> usize {
        self.n + 2 * self.collar
    }

    /// x of bar node k.
    pub fn x(&self, k: usize) -> f64 {
        (k as f64 - self.collar as f64 + 0.5) * self.h
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
    /// the time-dependent problem: the collar's columns dropped, D's renumbered from 0.
    pub fn rows_with_zero_collar(&self) -> impl Iterator<Item = Vec<(usize, f64)>> + '_ {
        let d = self.collar..self.collar + self.n;
        self.rows.iter().map(move |row| {
            row.iter()
                .filter(|(l, _)| d.contains(l))
                .map(|&(l, a)| (l - self.collar, a))
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

/// Row k's coefficients on the window k − 2R ..= k + 2R of the bar, which holds every node a row
/// reaches (the partial-stress form reaches the neighbours of neighbours).
struct Window {
    first: i64,
    a: Vec<f64>,
}

impl Window {
    fn new(k: usize, reach: usize) -> Window {
        Window {
            first: k as i64 - 2 * reach as i64,
            a: vec![0.0; 4 * reach + 1],
        }
    }

    fn add(&mut self, l: i64, a: f64) {
        self.a[(l - self.first) as usize] += a;
    }

    fn into_row(self) -> Vec<(usize, f64)> {
        let first = self.first;
        self.a
            .into_iter()
            .enumerate()
            .filter(|&(_, a)| a != 0.0)
            .map(|(m, a)| ((first + m as i64) as usize, a))
            .collect()
    }
}

/// Row k of the standard form: Σ_y ½ (w_x(y − x) + w_y(x − y)) (u_y − u_x).
fn standard_row(k: usize, reach: usize, bonds_of: &[Vec<(i64, f64, f64)>]) -> Vec<(usize, f64)> {
    let mut row = Window::new(k, reach);
    let k = k as i64;
    for &(o, w, _) in &bonds_of[k as usize] {
        row.add(k + o, 0.5 * w);
        row.add(k, -0.5 * w);
    }
    // The bonds other nodes own towards k: node l = k − o owns offset o when it reaches k.
    for o in -(reach as i64)..=reach as i64 {
        let l = k - o;
        if o == 0 {
            continue;
        }
        if let Some(&(_, w, _)) = bonds_of[l as usize].iter().find(|b| b.0 == o) {
            row.add(l, 0.5 * w);
            row.add(k, -0.5 * w);
        }
    }
    row.into_row()
}

/// Row k of the x-centred form: Σ_ξ w_x(ξ) (u(x + ξ) − u(x)), node k's own bonds only.
fn x_centred_row(k: usize, reach: usize, bonds_of: &[Vec<(i64, f64, f64)>]) -> Vec<(usize, f64)> {
    let mut row = Window::new(k, reach);
    let k = k as i64;
    for &(o, w, _) in &bonds_of[k as usize] {
        row.add(k + o, w);
        row.add(k, -w);
    }
    row.into_row()
}

/// Row k of the partial-stress form: ∇·ν with ν(x) = ½ Σ_ξ w_x(ξ) (u(x + ξ) − u(x)) ξ.
fn partial_stress_row(
    k: usize,
    reach: usize,
    bonds_of: &[Vec<(i64, f64, f64)>],
    h: f64,
) -> Vec<(usize, f64)> {
    let mut row = Window::new(k, reach);
    // Adds c·ν(x_j), ν as coefficients of u.
    let add_flux = |row: &mut Window, j: i64, c: f64| {
        for &(o, w, _) in &bonds_of[j as usize] {
            let a = c * 0.5 * w * o as f64 * h;
            row.add(j + o, a);
            row.add(j, -a);
        }
    };
    let weight: f64 = bonds_of[k]
        .iter()
        .map(|&(o, _, omega)| omega * (o as f64 * h).powi(2))
        .sum();
    let k = k as i64;
    for &(o, _, omega) in &bonds_of[k as usize] {
        let c = omega * o as f64 * h / weight;
        add_flux(&mut row, k + o, c);
        add_flux(&mut row, k, -c);
    }
    row.into_row()
}
