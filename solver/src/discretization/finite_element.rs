//! Piecewise-linear finite elements in 1D, for \[LSSM]'s local–nonlocal coupling: a mesh and its
//! hat functions, the stiffness matrices of −k u'' and of the nonlocal form, loads and L²
//! distances. Unlike the lattice schemes, they stay valid for h ≥ ε (the seed's coarse grids).
//!
//! **The nonlocal form.** With L u(x) = c ∫_{|y−x|<ε} J(|y−x|/ε)(u(y) − u(x)) dy (eq. 1.1's
//! operator, c of eq. 1.5), −∫ (L u) v = B(u, v) for every v that vanishes on the collars, where
//!
//! B(u, v) = (c/2) ∫∫_{D×D, |y−x|<ε} J(|y−x|/ε) (u(y) − u(x)) (v(y) − v(x)) dy dx
//!         = c ∫₀^ε J(s/ε) I(s) ds,  I(s) = ∫_{x, x+s ∈ D} (u(x+s) − u(x)) (v(x+s) − v(x)) dx
//!
//! (the half s < 0 equals the half s > 0 by x → x + s). Written so, \[LSSM]'s singular kernel
//! γ = 1/(ε²|x − y|) is harmless: for P1 functions I(s) = O(s²).
//!
//! **Quadrature.** For fixed s the x-integrand is a product of two linear functions between the
//! breakpoints {z_k} ∪ {z_k − s}, so two Gauss points per piece integrate it exactly. I(s) is a
//! cubic between consecutive node differences z_j − z_i; Gauss–Legendre on each such s-piece is
//! exact on the first (J(s/ε) I(s) is a polynomial there, also for J = 1/r) and converges
//! geometrically on the others, whose distance from the singularity s = 0 is at least their
//! width. Because every I(s) is exact, B(x, φᵢ) vanishes at each s-point for a test function
//! φᵢ inside D: the linear patch test holds to round-off, whatever the s-rule's error.

use crate::case::Kernel;
use crate::discretization::influence::Influence;
use gauss_quad::legendre::GaussLegendre;
use std::num::NonZeroUsize;

/// Gauss points per s-piece of the nonlocal form: the second piece, the worst, is resolved to
/// about 1e-15 relative (its Bernstein ellipse has ρ = 3 + √8).
const S_POINTS: usize = 12;

/// Sorted nodes z₀ < z₁ < … of a 1D mesh; element e is [z_e, z_{e+1}].
#[derive(Clone, Debug)]
pub struct Mesh {
    pub nodes: Vec<f64>,
}

impl Mesh {
    /// `elements` equal elements of [a, b].
    pub fn uniform(a: f64, b: f64, elements: usize) -> Self {
        let h = (b - a) / elements as f64;
        let mut nodes: Vec<f64> = (0..elements).map(|k| a + k as f64 * h).collect();
        nodes.push(b);
        Mesh { nodes }
    }

    /// [0, 1] in n elements of h = 1/n, continued by h into the collars [−ε, 0] and [1, 1 + ε],
    /// which end at a node: a lattice node closer than h/4 to ±ε is dropped, so that no collar
    /// element is a sliver. For h ≥ ε each collar is one element of width ε.
    pub fn with_collars(n: usize, eps: f64) -> Self {
        let h = 1.0 / n as f64;
        let mut collar: Vec<f64> = (1..)
            .map(|k| k as f64 * h)
            .take_while(|&d| d < eps - 0.25 * h)
            .collect();
        collar.push(eps);
        let mut nodes: Vec<f64> = collar.iter().rev().map(|d| -d).collect();
        nodes.extend((0..=n).map(|k| k as f64 / n as f64)); // 1 exactly at k = n
        nodes.extend(collar.iter().map(|d| 1.0 + d));
        Mesh { nodes }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The element holding x (the nearer end element outside the mesh).
    fn element_of(&self, x: f64) -> usize {
        let after = self.nodes.partition_point(|&z| z <= x);
        after.clamp(1, self.len() - 1) - 1
    }

    /// φ_e(x) and φ_{e+1}(x), the two hat functions of element e.
    fn hats(&self, e: usize, x: f64) -> (f64, f64) {
        let t = (x - self.nodes[e]) / (self.nodes[e + 1] - self.nodes[e]);
        (1.0 - t, t)
    }

    /// The P1 function with nodal values u, at x.
    pub fn value(&self, u: &[f64], x: f64) -> f64 {
        let e = self.element_of(x);
        let (left, right) = self.hats(e, x);
        left * u[e] + right * u[e + 1]
    }

    /// Gauss points and weights of ∫_a^b with `per_piece` points between consecutive breaks: the
    /// mesh's nodes inside (a, b) and the `extra` ones (another mesh's nodes).
    pub fn quadrature(&self, a: f64, b: f64, per_piece: usize, extra: &[f64]) -> Vec<(f64, f64)> {
        let mut breaks: Vec<f64> = self
            .nodes
            .iter()
            .chain(extra)
            .copied()
            .filter(|&z| z > a && z < b)
            .chain([a, b])
            .collect();
        breaks.sort_by(f64::total_cmp);
        breaks.dedup_by(|z, previous| *z - *previous <= 1e-14 * (b - a));
        let rule = gauss_legendre(per_piece);
        breaks
            .windows(2)
            .flat_map(|piece| on_interval(&rule, piece[0], piece[1]))
            .collect()
    }

    /// ∫_a^b f φᵢ for every node i, exact for f of degree up to 2·4 − 2 = 6.
    pub fn load(&self, a: f64, b: f64, f: impl Fn(f64) -> f64) -> Vec<f64> {
        let mut load = vec![0.0; self.len()];
        for (x, w) in self.quadrature(a, b, 4, &[]) {
            let e = self.element_of(x);
            let (left, right) = self.hats(e, x);
            load[e] += w * f(x) * left;
            load[e + 1] += w * f(x) * right;
        }
        load
    }

    /// ‖u_h − u‖ in L²(a, b), exact for u of degree up to 4.
    pub fn l2_distance(&self, u_h: &[f64], a: f64, b: f64, u: impl Fn(f64) -> f64) -> f64 {
        self.quadrature(a, b, 5, &[])
            .into_iter()
            .map(|(x, w)| w * (self.value(u_h, x) - u(x)).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// A symmetric matrix stored by rows over its band [i − w, i + w].
#[derive(Clone, Debug)]
pub struct BandMatrix {
    n: usize,
    w: usize,
    values: Vec<f64>,
}

impl BandMatrix {
    pub fn zeros(n: usize, w: usize) -> Self {
        BandMatrix {
            n,
            w,
            values: vec![0.0; n * (2 * w + 1)],
        }
    }

    fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let offset = j as isize - i as isize + self.w as isize;
        (0..=2 * self.w as isize)
            .contains(&offset)
            .then(|| i * (2 * self.w + 1) + offset as usize)
    }

    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let slot = self.slot(i, j).expect("entry inside the band");
        self.values[slot] += v;
    }

    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.slot(i, j).map_or(0.0, |s| self.values[s])
    }

    /// The non-zero entries (row, column, value) of the block rows × columns, renumbered; `rows`
    /// distinct and ascending. Each column visits only its band, through each row's place in
    /// `rows`: O(len · w) rather than O(|rows| · |columns|), which made a long local domain's
    /// set-up quadratic in its length.
    pub fn block(&self, rows: &[usize], columns: &[usize]) -> Vec<(usize, usize, f64)> {
        let mut place = vec![usize::MAX; self.n];
        for (r, &i) in rows.iter().enumerate() {
            place[i] = r;
        }
        let mut entries = Vec::new();
        for (c, &j) in columns.iter().enumerate() {
            let band = j.saturating_sub(self.w)..(j + self.w + 1).min(self.n);
            for (i, &row) in place.iter().enumerate().take(band.end).skip(band.start) {
                let v = self.get(i, j);
                if row != usize::MAX && v != 0.0 {
                    entries.push((row, c, v));
                }
            }
        }
        entries
    }

    /// Off-diagonal non-zeros: the bonds the form couples.
    pub fn off_diagonal_nonzeros(&self) -> usize {
        (0..self.n)
            .flat_map(|i| {
                (i.saturating_sub(self.w)..(i + self.w + 1).min(self.n)).map(move |j| (i, j))
            })
            .filter(|&(i, j)| i != j && self.get(i, j) != 0.0)
            .count()
    }
}

/// The stiffness matrix of ∫ k u' v' on the mesh.
pub fn laplace_stiffness(mesh: &Mesh, k: f64) -> BandMatrix {
    let mut a = BandMatrix::zeros(mesh.len(), 1);
    for e in 0..mesh.len() - 1 {
        let g = k / (mesh.nodes[e + 1] - mesh.nodes[e]);
        a.add(e, e, g);
        a.add(e + 1, e + 1, g);
        a.add(e, e + 1, -g);
        a.add(e + 1, e, -g);
    }
    a
}

/// The matrix of the nonlocal form B(φⱼ, φᵢ) over D = the mesh's span (see the module comment):
/// kernel J(s/ε) scaled by c.
pub fn nonlocal_stiffness(mesh: &Mesh, kernel: Kernel, eps: f64, c: f64) -> BandMatrix {
    let z = &mesh.nodes;
    let n = z.len();
    let band = (0..n - 1)
        .map(|e| mesh.element_of(z[e + 1] + eps) + 1 - e)
        .max()
        .unwrap_or(1);
    let mut a = BandMatrix::zeros(n, band);
    let rule = gauss_legendre(S_POINTS);
    let pair = gauss_legendre(2);
    for piece in s_pieces(z, eps).windows(2) {
        for (s, ws) in on_interval(&rule, piece[0], piece[1]) {
            let weight = ws * c * kernel.influence(s / eps);
            for (x, wx) in shifted_pieces(z, s)
                .windows(2)
                .flat_map(|p| on_interval(&pair, p[0], p[1]))
            {
                let (e, f) = (mesh.element_of(x), mesh.element_of(x + s));
                let (he, he1) = mesh.hats(e, x);
                let (hf, hf1) = mesh.hats(f, x + s);
                // u(x + s) − u(x) for the hats that are non-zero at x or x + s.
                let differences = [(e, -he), (e + 1, -he1), (f, hf), (f + 1, hf1)];
                for &(i, di) in &differences {
                    for &(j, dj) in &differences {
                        a.add(i, j, weight * wx * di * dj);
                    }
                }
            }
        }
    }
    a
}

/// The s-pieces of (0, ε): split at every node difference below ε, where I(s) changes form.
fn s_pieces(z: &[f64], eps: f64) -> Vec<f64> {
    let mut breaks = vec![0.0, eps];
    for (i, &zi) in z.iter().enumerate() {
        breaks.extend(
            z[i + 1..]
                .iter()
                .map(|&zj| zj - zi)
                .take_while(|&d| d < eps),
        );
    }
    breaks.sort_by(f64::total_cmp);
    breaks.dedup_by(|d, previous| *d - *previous <= 1e-13 * eps);
    breaks
}

/// The x-pieces for shift s: {z_k} ∪ {z_k − s} inside [z₀, z_last − s], merged in order.
fn shifted_pieces(z: &[f64], s: f64) -> Vec<f64> {
    let (first, last) = (z[0], z[z.len() - 1] - s);
    let mut breaks = Vec::with_capacity(2 * z.len());
    let (mut i, mut j) = (0, 0);
    while i < z.len() || j < z.len() {
        let take_unshifted = j == z.len() || (i < z.len() && z[i] <= z[j] - s);
        let next = if take_unshifted {
            i += 1;
            z[i - 1]
        } else {
            j += 1;
            z[j - 1] - s
        };
        if next >= first && next <= last && breaks.last().is_none_or(|&b| next > b) {
            breaks.push(next);
        }
    }
    breaks
}

fn gauss_legendre(points: usize) -> GaussLegendre {
    GaussLegendre::new(NonZeroUsize::new(points).expect("at least one point"))
}

/// The rule's points and weights mapped to [a, b].
fn on_interval(rule: &GaussLegendre, a: f64, b: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
    let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
    rule.as_node_weight_pairs()
        .iter()
        .map(move |&(t, w)| (mid + half * t, half * w))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_collars_end_at_eps_without_slivers() {
        let coarse = Mesh::with_collars(8, 0.065);
        assert_eq!(coarse.nodes.first(), Some(&-0.065));
        assert_eq!(coarse.nodes.last(), Some(&1.065));
        assert_eq!(coarse.len(), 9 + 2);
        let fine = Mesh::with_collars(128, 0.065);
        let widths: Vec<f64> = fine.nodes.windows(2).map(|p| p[1] - p[0]).collect();
        let h = 1.0 / 128.0;
        assert!(widths.iter().all(|&w| w > 0.25 * h && w < 1.25 * h + 1e-15));
        assert!((fine.nodes[0] + 0.065).abs() < 1e-15);
    }

    /// The band-limited block is the block read entry by entry, in the same order.
    #[test]
    fn a_block_is_every_non_zero_of_its_rows_and_columns() {
        let mesh = Mesh::with_collars(16, 0.2);
        let a = nonlocal_stiffness(&mesh, Kernel::Constant, 0.2, 1.0);
        let rows: Vec<usize> = (0..mesh.len()).filter(|i| i % 5 != 2).collect();
        let columns: Vec<usize> = (0..mesh.len()).filter(|i| i % 3 != 0).collect();
        let mut brute = Vec::new();
        for (c, &j) in columns.iter().enumerate() {
            for (r, &i) in rows.iter().enumerate() {
                if a.get(i, j) != 0.0 {
                    brute.push((r, c, a.get(i, j)));
                }
            }
        }
        assert!(!brute.is_empty());
        assert_eq!(a.block(&rows, &columns), brute);
    }

    #[test]
    fn the_laplace_stiffness_is_exact_on_quadratics() {
        // For −u'' = −2 with u = x², the P1 solution is nodally exact in 1D.
        let mesh = Mesh::uniform(0.25, 1.5, 5);
        let a = laplace_stiffness(&mesh, 1.0);
        let load = mesh.load(0.25, 1.5, |_| -2.0);
        let u: Vec<f64> = mesh.nodes.iter().map(|x| x * x).collect();
        for (i, &l) in load.iter().enumerate().take(mesh.len() - 1).skip(1) {
            let au: f64 = (0..mesh.len()).map(|j| a.get(i, j) * u[j]).sum();
            assert!((au - l).abs() < 1e-13, "row {i}: {au} vs {l}");
        }
    }

    /// B(u, v) for P1 nodal vectors by brute force: the double integral on a fine midpoint grid
    /// in (x, s).
    fn brute_force_form(mesh: &Mesh, eps: f64, u: &[f64], v: &[f64]) -> f64 {
        let (a, b) = (mesh.nodes[0], mesh.nodes[mesh.len() - 1]);
        let ns = 4000;
        let ds = eps / ns as f64;
        let mut total = 0.0;
        for k in 0..ns {
            let s = (k as f64 + 0.5) * ds;
            let nx = 4000;
            let dx = (b - s - a) / nx as f64;
            let inner: f64 = (0..nx)
                .map(|i| {
                    let x = a + (i as f64 + 0.5) * dx;
                    (mesh.value(u, x + s) - mesh.value(u, x))
                        * (mesh.value(v, x + s) - mesh.value(v, x))
                })
                .sum::<f64>()
                * dx;
            total += inner * Kernel::InverseDistance.influence(s / eps) * ds;
        }
        total
    }

    #[test]
    fn the_nonlocal_stiffness_is_the_double_integral() {
        let eps = 0.3;
        let mesh = Mesh::with_collars(5, eps);
        let a = nonlocal_stiffness(&mesh, Kernel::InverseDistance, eps, 1.0);
        let u: Vec<f64> = mesh.nodes.iter().map(|x| (3.0 * x).sin()).collect();
        let v: Vec<f64> = mesh.nodes.iter().map(|x| x * x - 0.5 * x).collect();
        let form: f64 = (0..mesh.len())
            .flat_map(|i| (0..mesh.len()).map(move |j| (i, j)))
            .map(|(i, j)| v[i] * a.get(i, j) * u[j])
            .sum();
        let brute = brute_force_form(&mesh, eps, &u, &v);
        assert!(
            (form - brute).abs() < 1e-5 * brute.abs(),
            "{form} vs {brute}"
        );
        // Symmetric, and constants are in its kernel.
        for i in 0..mesh.len() {
            let row: f64 = (0..mesh.len()).map(|j| a.get(i, j)).sum();
            assert!(row.abs() < 1e-13, "row {i} sums to {row}");
            for j in 0..mesh.len() {
                assert!((a.get(i, j) - a.get(j, i)).abs() < 1e-14);
            }
        }
    }
}
