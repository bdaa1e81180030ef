//! The p × p subdomains of \[XGDF] (section 2.1) on the particle lattice, and what they share.
//!
//! Along each axis the L particles are cut into p blocks Ω̃_k = [a_k, b_k) (boundaries ⌊k L/p⌋).
//! - Ω_n (eq. 8) keeps the particles of Ω̃_n farther than δ/2 from every other block: ⌊m/2⌋
//!   particles come off each side that faces another block.
//! - Ω_n ∪ Γ̂_n ∪ Γ_n (eqs. 9–10) is every particle of Ω ∪ Γ within δ of Ω_n: Ω_n grown by m,
//!   clipped to the lattice of Ω ∪ Γ. We call it E_n. Λ_n = E_n ∩ Ω (the subdomain's unknowns)
//!   and Γ_n = E_n ∖ Ω (its Dirichlet data). All three are boxes, products of one interval per axis.
//! - ζ_A(x, y) of eq. 12 counts the n with x, y ∈ E_n, and ζ_F(x) the n with x ∈ Λ_n. Box membership
//!   is per axis, so ζ_A = c_x(x₁, y₁) c_y(x₂, y₂) with c(a, b) = #{k : a, b ∈ E_k on that axis}.
//!   Every bond (|x − y|∞ ≤ δ) lies in some E_n: consecutive E intervals overlap by 2m − 2⌊m/2⌋ ≥ m.
//! - Subdomain n floats when Γ_n = ∅ (E_n inside Ω): its matrix A_n has the constants as nullspace.
//!
//! **Constraints.** The continuity of eq. 22 is imposed on every node of Λ_n ∩ Λ_n', for every
//! pair n < n' (diagonal neighbours included), one multiplier per shared node and pair, with
//! M row +1 on u_n and −1 on u_n'. Then equal copies make Σ_n E_n of eq. 21 the single-domain
//! energy bond by bond, so the FETI solution is the single-domain one exactly. For even m the
//! shared nodes are exactly Γ̂_n ∩ Γ̂_n'; for odd m the strips between the Ω_n are m − 1 wide and
//! Λ_n ∩ Λ_n' also holds a line of Ω_n, which we constrain too.

use faer::linalg::cholesky::llt::factor::LltError;
use faer::linalg::solvers::Llt;
use faer::{Mat, Side};
use std::ops::Range;

/// One axis: the blocks, their Ω and E intervals, and the counts c(a, b).
#[derive(Clone, Debug)]
pub struct Axis {
    pub n: usize,
    pub m: usize,
    /// Ω_k's interval of lattice indices.
    pub omega: Vec<Range<i64>>,
    /// E_k = Ω_k grown by m, clipped to [−m, n + m).
    pub extended: Vec<Range<i64>>,
    /// c(a, a + d) at counts[(a + m)(2m + 1) + d + m], for a in [−m, n + m) and |d| ≤ m.
    counts: Vec<u16>,
}

impl Axis {
    pub fn new(n: usize, p: usize, m: usize) -> Self {
        let (ni, mi) = (n as i64, m as i64);
        let cut = (m / 2) as i64;
        let omega: Vec<Range<i64>> = (0..p)
            .map(|k| {
                let (a, b) = ((k * n / p) as i64, ((k + 1) * n / p) as i64);
                let lo = if k > 0 { a + cut } else { a };
                let hi = if k + 1 < p { b - cut } else { b };
                lo..hi
            })
            .collect();
        let extended: Vec<Range<i64>> = omega
            .iter()
            .map(|r| (r.start - mi).max(-mi)..(r.end + mi).min(ni + mi))
            .collect();
        let side = 2 * m + 1;
        let mut counts = vec![0u16; (n + 2 * m) * side];
        for e in &extended {
            for a in e.clone() {
                for d in -mi..=mi {
                    if e.contains(&(a + d)) {
                        counts[(a + mi) as usize * side + (d + mi) as usize] += 1;
                    }
                }
            }
        }
        Axis {
            n,
            m,
            omega,
            extended,
            counts,
        }
    }

    /// c(a, b): the blocks whose E interval holds both a and b (|a − b| ≤ m).
    #[inline]
    pub fn count(&self, a: i64, b: i64) -> u16 {
        let (m, side) = (self.m as i64, 2 * self.m as i64 + 1);
        self.counts[((a + m) * side + (b - a + m)) as usize]
    }

    /// Λ_k's interval: E_k ∩ [0, n).
    pub fn lambda(&self, k: usize) -> Range<i64> {
        let e = &self.extended[k];
        e.start.max(0)..e.end.min(self.n as i64)
    }

    /// Does E_k stay inside Ω on this axis?
    pub fn inside(&self, k: usize) -> bool {
        let e = &self.extended[k];
        e.start >= 0 && e.end <= self.n as i64
    }
}

/// Per block k of one axis: the width of Λ_k and of its interior (the nodes of Λ_k in no other
/// block's Λ), as `Axis::new` and `Decomposition::new` make them, from the cuts alone (the
/// memory estimate's sizes, without building the decomposition). A subdomain's unknowns and
/// interior are the products of its blocks' widths: a node lies on an interface exactly when
/// one of its coordinates lies in another block's Λ on that axis.
pub fn widths(n: usize, p: usize, m: usize) -> Vec<(usize, usize)> {
    let (ni, mi, cut) = (n as i64, m as i64, (m / 2) as i64);
    let lambda = |k: usize| {
        let (a, b) = ((k * n / p) as i64, ((k + 1) * n / p) as i64);
        let lo = if k > 0 { a + cut } else { a };
        let hi = if k + 1 < p { b - cut } else { b };
        (lo - mi).max(0)..(hi + mi).min(ni)
    };
    (0..p)
        .map(|k| {
            let own = lambda(k);
            // Λ's ends grow with k, so only the neighbours' Λ can reach into block k's.
            let start = if k > 0 {
                own.start.max(lambda(k - 1).end)
            } else {
                own.start
            };
            let end = if k + 1 < p {
                own.end.min(lambda(k + 1).start)
            } else {
                own.end
            };
            (
                (own.end - own.start).max(0) as usize,
                (end - start).max(0) as usize,
            )
        })
        .collect()
}

/// The nodes subdomain n shares with another one.
#[derive(Clone, Debug)]
pub struct Interface {
    pub other: usize,
    /// +1 when n < other (M's row reads u_n − u_other), −1 otherwise.
    pub sign: f64,
    /// Local indices in Λ_n of the shared nodes, in the order of their index in Ω (both sides
    /// list the same nodes in the same order).
    pub nodes: Vec<usize>,
    /// Where the interface's multipliers start in n's multiplier vector.
    pub offset: usize,
}

/// One subdomain's place in the decomposition.
#[derive(Clone, Debug)]
pub struct Subdomain {
    pub index: usize,
    /// Block coordinates (kx, ky).
    pub block: [usize; 2],
    /// Λ_n's interval per axis.
    pub lambda: [Range<i64>; 2],
    pub floating: bool,
    /// The coarse index of a floating subdomain (its column of G).
    pub coarse: Option<usize>,
    pub interfaces: Vec<Interface>,
}

impl Subdomain {
    /// Unknowns s_n = |Λ_n|.
    pub fn unknowns(&self) -> usize {
        self.width() * (self.lambda[1].end - self.lambda[1].start) as usize
    }

    pub fn width(&self) -> usize {
        (self.lambda[0].end - self.lambda[0].start) as usize
    }

    /// q_n, the multipliers of the subdomain.
    pub fn multipliers(&self) -> usize {
        self.interfaces.iter().map(|i| i.nodes.len()).sum()
    }

    /// Local index of node (x, y) of Λ_n.
    #[inline]
    pub fn local(&self, x: i64, y: i64) -> usize {
        (y - self.lambda[1].start) as usize * self.width() + (x - self.lambda[0].start) as usize
    }
}

/// The whole decomposition, the same on every rank.
#[derive(Clone, Debug)]
pub struct Decomposition {
    pub p: usize,
    pub axis: Axis,
    pub subdomains: Vec<Subdomain>,
    /// Floating subdomains, in coarse order.
    pub floating: Vec<usize>,
}

impl Decomposition {
    /// p × p subdomains of the L × L lattice (n = L) for horizon m.
    pub fn new(n: usize, p: usize, m: usize) -> Self {
        let axis = Axis::new(n, p, m);
        // Along one axis, the blocks whose Λ intervals overlap block k's.
        let overlapping: Vec<Vec<usize>> = (0..p)
            .map(|k| {
                let own = axis.lambda(k);
                (0..p)
                    .filter(|&j| {
                        let other = axis.lambda(j);
                        other.start < own.end && own.start < other.end
                    })
                    .collect()
            })
            .collect();
        let mut floating = Vec::new();
        let mut subdomains: Vec<Subdomain> = (0..p * p)
            .map(|index| {
                let block = [index % p, index / p];
                let is_floating = axis.inside(block[0]) && axis.inside(block[1]);
                let coarse = is_floating.then(|| {
                    floating.push(index);
                    floating.len() - 1
                });
                Subdomain {
                    index,
                    block,
                    lambda: [axis.lambda(block[0]), axis.lambda(block[1])],
                    floating: is_floating,
                    coarse,
                    interfaces: Vec::new(),
                }
            })
            .collect();
        for index in 0..p * p {
            let [kx, ky] = subdomains[index].block;
            let mut offset = 0;
            let mut interfaces = Vec::new();
            for &jy in &overlapping[ky] {
                for &jx in &overlapping[kx] {
                    let other = jy * p + jx;
                    if other == index {
                        continue;
                    }
                    let (own, theirs) = (&subdomains[index], &subdomains[other]);
                    let xs = own.lambda[0].start.max(theirs.lambda[0].start)
                        ..own.lambda[0].end.min(theirs.lambda[0].end);
                    let ys = own.lambda[1].start.max(theirs.lambda[1].start)
                        ..own.lambda[1].end.min(theirs.lambda[1].end);
                    let nodes: Vec<usize> = ys
                        .flat_map(|y| xs.clone().map(move |x| (x, y)))
                        .map(|(x, y)| own.local(x, y))
                        .collect();
                    let len = nodes.len();
                    interfaces.push(Interface {
                        other,
                        sign: if index < other { 1.0 } else { -1.0 },
                        nodes,
                        offset,
                    });
                    offset += len;
                }
            }
            subdomains[index].interfaces = interfaces;
        }
        Decomposition {
            p,
            axis,
            subdomains,
            floating,
        }
    }

    /// q: every multiplier once.
    pub fn multipliers(&self) -> usize {
        self.subdomains
            .iter()
            .map(Subdomain::multipliers)
            .sum::<usize>()
            / 2
    }

    /// ζ_A for the bond between lattice nodes a and b (each (x, y), possibly in Γ).
    #[inline]
    pub fn zeta_a(&self, a: [i64; 2], b: [i64; 2]) -> u16 {
        self.axis.count(a[0], b[0]) * self.axis.count(a[1], b[1])
    }

    /// The rank that owns subdomain n: contiguous runs of subdomains per rank.
    /// The block k along an axis that holds coordinate x: ⌊k n/p⌋ ≤ x < ⌊(k+1) n/p⌋.
    pub fn block_of(&self, x: usize) -> usize {
        ((x + 1) * self.p - 1) / self.axis.n
    }

    pub fn owner(&self, index: usize, ranks: usize) -> usize {
        index * ranks / self.subdomains.len()
    }

    /// GᵀG (floating × floating, column-major): G = M Z has, in the column of floating
    /// subdomain a, the sign of a's M row on each of a's multipliers; so (GᵀG)_aa = q_a and
    /// (GᵀG)_ab = −|Λ_a ∩ Λ_b|.
    fn coarse_matrix(&self) -> Vec<f64> {
        let nf = self.floating.len();
        let mut gtg = vec![0.0; nf * nf];
        for (a, &index) in self.floating.iter().enumerate() {
            let subdomain = &self.subdomains[index];
            gtg[a * nf + a] = subdomain.multipliers() as f64;
            for interface in &subdomain.interfaces {
                if let Some(b) = self.subdomains[interface.other].coarse {
                    gtg[b * nf + a] -= interface.nodes.len() as f64;
                }
            }
        }
        gtg
    }

    /// GᵀG's Cholesky factor (dense, on every rank); None when no subdomain floats.
    pub fn coarse_factor(&self) -> Option<Result<Llt<f64>, LltError>> {
        let nf = self.floating.len();
        (nf > 0).then(|| {
            let gtg = self.coarse_matrix();
            Mat::from_fn(nf, nf, |i, j| gtg[j * nf + i]).llt(Side::Lower)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_coordinate_lies_in_the_block_block_of_names() {
        for (n, p) in [(32, 4), (33, 5), (64, 3), (7, 7)] {
            let decomposition = Decomposition::new(n, p, 2);
            for x in 0..n {
                let k = decomposition.block_of(x);
                assert!(
                    k * n / p <= x && x < (k + 1) * n / p,
                    "n {n} p {p} x {x}: block {k}"
                );
            }
        }
    }

    #[test]
    fn even_m_leaves_strips_of_width_m_between_the_omegas() {
        let axis = Axis::new(32, 4, 4);
        assert_eq!(axis.omega, vec![0..6, 10..14, 18..22, 26..32]);
        assert_eq!(axis.extended[0], -4..10);
        assert_eq!(axis.lambda(1), 6..18);
        assert!(!axis.inside(0) && axis.inside(1));
    }

    #[test]
    fn every_bond_of_omega_lies_in_some_subdomain() {
        for (n, p, m) in [(24, 3, 4), (25, 4, 3), (30, 5, 2), (24, 2, 5)] {
            let axis = Axis::new(n, p, m);
            let (ni, mi) = (n as i64, m as i64);
            for a in 0..ni {
                for b in a - mi..=a + mi {
                    assert!(axis.count(a, b) >= 1, "n {n} p {p} m {m}: bond {a}–{b}");
                }
            }
        }
    }

    /// `widths` gives every subdomain's unknowns and interior (the nodes on no interface, as
    /// the Dirichlet preconditioner finds them) without building the decomposition.
    #[test]
    fn widths_are_the_decompositions_unknowns_and_interiors() {
        for (n, p, m) in [
            (30, 3, 4),
            (25, 4, 3),
            (32, 4, 4),
            (24, 2, 5),
            (40, 5, 1),
            (16, 1, 2),
        ] {
            let decomposition = Decomposition::new(n, p, m);
            let widths = widths(n, p, m);
            for subdomain in &decomposition.subdomains {
                let [kx, ky] = subdomain.block;
                let ((wx, ix), (wy, iy)) = (widths[kx], widths[ky]);
                assert_eq!(subdomain.unknowns(), wx * wy, "n {n} p {p} m {m}");
                let mut on_interface = vec![false; subdomain.unknowns()];
                for interface in &subdomain.interfaces {
                    for &i in &interface.nodes {
                        on_interface[i] = true;
                    }
                }
                let interior = on_interface.iter().filter(|&&shared| !shared).count();
                assert_eq!(interior, ix * iy, "n {n} p {p} m {m} block {kx},{ky}");
            }
        }
    }

    #[test]
    fn interfaces_pair_up_with_the_same_nodes_in_the_same_order() {
        let decomposition = Decomposition::new(30, 3, 4);
        assert_eq!(decomposition.floating, vec![4]);
        for subdomain in &decomposition.subdomains {
            for interface in &subdomain.interfaces {
                let other = &decomposition.subdomains[interface.other];
                let back = other
                    .interfaces
                    .iter()
                    .find(|i| i.other == subdomain.index)
                    .expect("the partner lists the interface too");
                assert_eq!(back.nodes.len(), interface.nodes.len());
                assert_eq!(back.sign, -interface.sign);
                let global = |s: &Subdomain, local: usize| {
                    let (x, y) = (local % s.width(), local / s.width());
                    (s.lambda[0].start + x as i64, s.lambda[1].start + y as i64)
                };
                for (&a, &b) in interface.nodes.iter().zip(&back.nodes) {
                    assert_eq!(global(subdomain, a), global(other, b));
                }
            }
        }
        // The centre subdomain shares nodes with all eight neighbours.
        assert_eq!(decomposition.subdomains[4].interfaces.len(), 8);
    }
}
