//! Particle strength exchange (\[HPCSE], question 2) for ∂c/∂t = D∇²c on (−L/2, L/2)^d with
//! c = 0 on the boundary.
//!
//! N = n^d particles sit at the cell centres x_i = −L/2 + (i + ½)h, h = L/n, each of volume
//! V = L^d/N = h^d, and carry φ_i. Forward Euler integrates
//!     dφ_i/dt = D/ε² Σ_j V (φ_j − φ_i) η_ε(x_j − x_i),   η_ε(r) = 4/(π^{d/2} ε^d) exp(−|r|²/ε²),
//! which is the seed's eq. (3) in 2D; in 1D the same normalisation (∫ η z² dz = 2ε²) makes the
//! sum approximate D c''. The error is O(ε²) once h/ε is below about 1, where the lattice sum of
//! the Gaussian is exact to rounding.
//!
//! **Boundary.** c = 0 on ∂D is imposed by images: beyond each face the field continues oddly
//! (φ of the mirrored particle with its sign flipped; across two faces the sign flips twice), as
//! far as the kernel reaches. The Dirichlet eigenmodes are then exact eigenvectors of the sum,
//! and mass leaves through the boundary as it should. Without images the sum would be cut at
//! the boundary, which conserves mass (a no-flux condition) instead.
//!
//! **Cost.** exp(−r²/ε²) is dropped below 1e-16, i.e. beyond r_c = ε √(16 ln 10) ≈ 6.07 ε.
//! Particles and images are binned in cells of side ≥ r_c, so partners lie in the 3^d cells
//! around a particle, and each pair is visited once: a cell with itself and with its forward
//! half of neighbours. Pairs of two images are never visited. The record counts the pairs
//! visited and those within r_c: O(N) at fixed ε/h.
//!
//! **Threads.** Cells are grouped in strips (rows of cells in 2D, single cells in 1D). The pairs
//! a strip starts reach only that strip and the next, so even strips run in parallel, then odd
//! ones, each on its own slice of the rates: no two tasks write the same rate, and every rate
//! is summed in the same order whatever the number of threads.
//!
//! **Stability.** The sum acts on the Fourier mode e^{ik·x} as the symbol
//! −K Σ_o e^{−|o|²h²/ε²} (1 − cos(k·o h)) over lattice offsets o ≠ 0, with K = D V η_ε(0)/ε².
//! The Gaussian's lattice sum Σ_o e^{−|o|²h²/ε²} cos(k·o h) is a product of wrapped Gaussians,
//! positive and smallest at k_a h = π, so the symbol lies in [−λ_max, 0] with
//! λ_max = 2K Σ_{|o|₁ odd} e^{−|o|²h²/ε²}, and forward Euler is stable for dt ≤ 2/λ_max. The odd
//! extension keeps the Dirichlet modes among these Fourier modes.

use crate::case::ValidCase;
use crate::case::{readable, Case, CaseError};
use crate::integrate::amplification::{amplification, middle_node, positivity};
use crate::integrate::euler::ForwardEuler;
use crate::integrate::stepper::integrate;
use crate::integrate::time_step::{divergence_bound, requested, time_step};
use crate::integrate::timed::Stepping;
use crate::methods::local::{self, initial_value};
use crate::operator::LinearOperator;
use crate::output::diagnostics;
use crate::output::outcome::Outcome;
use crate::output::record::Resolved;
use crate::parallel::exchange::Ranks;
use rayon::prelude::*;
use std::f64::consts::{LN_10, PI};
use std::ops::Range;
use std::time::Instant;

/// PSE's rules: a kernel width of `m` particle spacings or a length `eps`, at most L/2, and
/// those of every local method.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    // L first: the kernel width is judged against it.
    local::validate_domain(case)?;
    let spacing = case.length() / case.n as f64;
    let (field, eps) = match (case.m, case.eps) {
        (Some(_), Some(_)) => return Err(CaseError::new(
            "eps",
            "give the kernel width once, as `m` (particle spacings) or `eps` (length), not both",
        )),
        (None, None) => {
            return Err(CaseError::new(
                "eps",
                "the kernel width is missing; give `eps` or `m` (ε = m·h, e.g. 2 for h/ε = 0.5)",
            ))
        }
        (Some(m), None) => ("m", m as f64 * spacing),
        (None, Some(eps)) => ("eps", eps),
    };
    let half = case.length() / 2.0;
    if !(eps > 0.0 && eps <= half) {
        return Err(CaseError::new(
            field,
            format!(
                "gives ε = {}, outside (0, L/2 = {}]; the kernel must be narrower than D",
                readable(eps),
                readable(half)
            ),
        ));
    }
    // Checked here as well as in `run`, before `Particles::new` bins the lattice in cells of
    // side r_c: a cutoff below h would ask for more cells than particles (at ε = 1e-9, 10¹⁷).
    if spacing * spacing >= eps * eps * CUTOFF_LOG {
        return Err(too_narrow(field, eps, spacing));
    }
    Ok(())
}

/// The refusal of a kernel so narrow that no other particle lies within its cutoff.
/// 2/λ_max of the particles of spacing h in `dim` dimensions (module comment), or None when no
/// other particle lies within r_c: from the lattice of offsets alone, nothing allocated.
fn dt_stable(dim: usize, h: f64, eps: f64, diffusivity: f64) -> Option<f64> {
    let cutoff_squared = eps * eps * CUTOFF_LOG;
    let reach = (cutoff_squared.sqrt() / h).ceil() as i64;
    let offsets = -reach..=reach;
    let rows = if dim == 2 { offsets.clone() } else { 0..=0 };
    let mut odd_sum = 0.0;
    for oy in rows {
        for ox in offsets.clone() {
            let r2 = ((ox * ox + oy * oy) as f64) * h * h;
            if (ox + oy) % 2 != 0 && r2 < cutoff_squared {
                odd_sum += (-r2 / (eps * eps)).exp();
            }
        }
    }
    // K = D V η_ε(0) / ε², as `Particles::rate_factor`.
    let eta0 = 4.0 / (PI.powf(dim as f64 / 2.0) * eps.powi(dim as i32));
    let rate_factor = diffusivity * h.powi(dim as i32) * eta0 / (eps * eps);
    let lambda_max = 2.0 * rate_factor * odd_sum;
    (lambda_max > 0.0).then(|| 2.0 / lambda_max)
}

/// The time step of a `pse` case, checked as `run` checks it, without its particles: what
/// `nlsolve check` refuses before anything runs. `memo` keeps each particle lattice's stable
/// step (O(reach^d) to compute) between cases.
pub fn preflight(
    case: &ValidCase,
    memo: &mut std::collections::HashMap<String, Result<f64, CaseError>>,
) -> Result<(), CaseError> {
    let (field, eps) = match (case.m, case.eps) {
        (Some(m), _) => ("m", m as f64 * case.length() / case.n as f64),
        (None, eps) => ("eps", eps.expect("validated: m or eps")),
    };
    let h = case.length() / case.n as f64;
    let key = format!("pse {} {h} {field} {eps} {}", case.dim, case.diffusivity);
    let dt_stable = memo
        .entry(key)
        .or_insert_with(|| {
            dt_stable(case.dim, h, eps, case.diffusivity).ok_or_else(|| too_narrow(field, eps, h))
        })
        .clone()?;
    time_step(case, dt_stable, false).map(drop)
}

fn too_narrow(field: &str, eps: f64, h: f64) -> CaseError {
    CaseError::new(
        field,
        format!(
            "ε = {} is so small next to h = {} that no particle lies within the kernel's cutoff {:.2}ε; use ε ≥ h/6",
            readable(eps),
            readable(h),
            CUTOFF_LOG.sqrt()
        ),
    )
}

/// Bytes a `pse` run holds at its peak, from the case alone (nothing allocated): while
/// `Particles::new` builds the slots, its P lattice points of 48 bytes each (P: particles and
/// images, the span (n + 2R)^d of the cutoff's reach R in spacings, less the corners beyond
/// r_c), with beside them either the sort's buffer (24 P) or the slots' positions (16 P), image
/// sources (16 per image) and slot numbers (8 N), and four arrays of 8 bytes per cell. The time
/// loop holds less: the positions, the field in slot order and a few N-vectors.
pub(crate) fn memory_bytes(case: &Case) -> f64 {
    let (n, dim) = (case.n as f64, case.dim as i32);
    let h = case.length() / n;
    let eps = case.m.map_or(case.eps.unwrap_or(h), |m| m as f64 * h);
    let cutoff = eps * CUTOFF_LOG.sqrt();
    let reach = (cutoff / h).ceil();
    let side = case.length() + 2.0 * reach * h;
    let cells = (side / cutoff).floor().max(1.0).powi(dim);
    let corners = if dim == 2 {
        (4.0 - PI) * reach * reach
    } else {
        0.0
    };
    let points = (n + 2.0 * reach).powi(dim) - corners;
    let particles = n.powi(dim);
    48.0 * points + (24.0 * points).max(32.0 * points - 8.0 * particles) + 32.0 * cells
}

/// ln(1e16): exp(−r²/ε²) is dropped beyond r² = ε² · CUTOFF_LOG.
const CUTOFF_LOG: f64 = 16.0 * LN_10;

/// Which rates a visited pair (i, j) changes: i's and j's (two particles), only i's (j is an
/// image) or only j's (i is an image).
#[derive(Clone, Copy, PartialEq)]
enum Writes {
    Both,
    First,
    Second,
}

/// The particles of D and their boundary images, in cell order: real particles occupy slots
/// 0..N, images N..N + G, each group sorted by cell.
pub struct Particles {
    dim: usize,
    length: f64,
    /// Particle spacing h = L/n.
    pub h: f64,
    pub eps: f64,
    /// r_c².
    cutoff_squared: f64,
    /// Positions of the slots (the second coordinate is 0 in 1D).
    position: Vec<[f64; 2]>,
    /// The slot of real particle i, for i in lattice order (i = iy·n + ix).
    slot_of: Vec<usize>,
    /// For image slot N + g: the real slot it mirrors and the mirror's sign.
    image_source: Vec<(usize, f64)>,
    cells: Cells,
}

/// Cells of side ≥ r_c, numbered strip by strip; in 2D a strip is a row of cells, in 1D a
/// single cell.
struct Cells {
    /// Cells per strip (1 in 1D) and strips.
    across: usize,
    strips: usize,
    /// Real slots of cell c: real[c] .. real[c + 1]; image slots image[c] .. image[c + 1].
    real: Vec<usize>,
    image: Vec<usize>,
}

impl Cells {
    fn id(&self, strip: usize, across: usize) -> usize {
        strip * self.across + across
    }

    fn reals(&self, c: usize) -> Range<usize> {
        self.real[c]..self.real[c + 1]
    }

    fn images(&self, c: usize) -> Range<usize> {
        self.image[c]..self.image[c + 1]
    }

    /// The first real slot of strip s (N for s = strips).
    fn strip_start(&self, s: usize) -> usize {
        self.real[self.id(s, 0)]
    }

    /// Cell x of strip s and the cells it shares pairs with: itself, its right neighbour and
    /// the three cells of the next strip next to it. Every adjacent pair of cells appears once.
    fn forward_partners(&self, s: usize, x: usize) -> impl Iterator<Item = usize> + '_ {
        let right = (x + 1 < self.across).then(|| self.id(s, x + 1));
        let next_strip = (s + 1 < self.strips)
            .then(|| {
                (x.saturating_sub(1)..(x + 2).min(self.across)).map(move |b| self.id(s + 1, b))
            })
            .into_iter()
            .flatten();
        std::iter::once(self.id(s, x))
            .chain(right)
            .chain(next_strip)
    }
}

impl Particles {
    /// n^d particles of width-ε kernels on (−L/2, L/2)^d, with the images the kernel reaches.
    pub fn new(dim: usize, n: usize, length: f64, eps: f64) -> Self {
        let h = length / n as f64;
        let cutoff_squared = eps * eps * CUTOFF_LOG;
        let cutoff = cutoff_squared.sqrt();
        let reach = (cutoff / h).ceil() as isize;
        let half = length / 2.0;
        let coordinate = |i: isize| -half + (i as f64 + 0.5) * h;
        let side = length + 2.0 * reach as f64 * h;
        let cells_per_axis = ((side / cutoff).floor() as usize).max(1);
        let cell_of = |x: f64| {
            let c = ((x + half + reach as f64 * h) / side * cells_per_axis as f64) as usize;
            c.min(cells_per_axis - 1)
        };
        let (across, strips) = if dim == 2 {
            (cells_per_axis, cells_per_axis)
        } else {
            (1, cells_per_axis)
        };

        // Every lattice point within reach: (cell, is image, lattice index, source, sign).
        let span = -reach..n as isize + reach;
        let rows: Vec<isize> = if dim == 2 {
            span.clone().collect()
        } else {
            vec![0]
        };
        let mut points = Vec::new();
        for &iy in &rows {
            for ix in span.clone() {
                let x = [coordinate(ix), if dim == 2 { coordinate(iy) } else { 0.0 }];
                let (sx, fx) = fold(ix, n);
                let (sy, fy) = if dim == 2 { fold(iy, n) } else { (0, 1.0) };
                let source = sy * n + sx;
                let is_image = (ix, iy) != (sx as isize, sy as isize);
                // An image farther than r_c from D meets no particle.
                let outside: f64 = x[..dim]
                    .iter()
                    .map(|&c| (c.abs() - half).max(0.0).powi(2))
                    .sum();
                if is_image && outside >= cutoff_squared {
                    continue;
                }
                let (cx, cy) = (cell_of(x[0]), cell_of(x[1]));
                let cell = if dim == 2 { cy * across + cx } else { cx };
                points.push((is_image, cell, source, fx * fy, x));
            }
        }
        // Reals before images, each by cell; ties keep lattice order.
        points.sort_by_key(|&(is_image, cell, ..)| (is_image, cell));

        let reals = n.pow(dim as u32);
        let cells_total = across * strips;
        let mut slot_of = vec![0; reals];
        let mut image_source = Vec::with_capacity(points.len() - reals);
        let mut real_count = vec![0; cells_total];
        let mut image_count = vec![0; cells_total];
        for (slot, &(is_image, cell, source, sign, _)) in points.iter().enumerate() {
            if is_image {
                image_count[cell] += 1;
                image_source.push((source, sign));
            } else {
                real_count[cell] += 1;
                slot_of[source] = slot;
            }
        }
        for entry in &mut image_source {
            entry.0 = slot_of[entry.0];
        }
        Particles {
            dim,
            length,
            h,
            eps,
            cutoff_squared,
            position: points.iter().map(|p| p.4).collect(),
            slot_of,
            image_source,
            cells: Cells {
                across,
                strips,
                real: prefix_sums(&real_count, 0),
                image: prefix_sums(&image_count, reals),
            },
        }
    }

    /// N, the number of real particles.
    pub fn count(&self) -> usize {
        self.slot_of.len()
    }

    /// The position of particle i in lattice order.
    pub fn lattice_position(&self, i: usize) -> [f64; 2] {
        self.position[self.slot_of[i]]
    }

    /// V = h^d.
    pub fn volume(&self) -> f64 {
        self.h.powi(self.dim as i32)
    }

    /// K = D V η_ε(0) / ε²: the factor of every pair's exp(−r²/ε²)(φ_j − φ_i).
    /// dt times this is the factor of a step.
    pub fn rate_factor(&self, diffusivity: f64) -> f64 {
        let eta0 = 4.0 / (PI.powf(self.dim as f64 / 2.0) * self.eps.powi(self.dim as i32));
        diffusivity * self.volume() * eta0 / (self.eps * self.eps)
    }

    /// 2/λ_max (module comment), or None when no other particle lies within r_c.
    pub fn dt_stable(&self, diffusivity: f64) -> Option<f64> {
        dt_stable(self.dim, self.h, self.eps, diffusivity)
    }

    /// Particles and their images.
    pub fn slots(&self) -> usize {
        self.position.len()
    }

    /// The pairs started in strip s: `visit_cell_pair` for each of its cells and their forward
    /// partners.
    fn visit_strip(&self, s: usize, mut visit: impl FnMut(usize, Range<usize>, Writes)) {
        for x in 0..self.cells.across {
            let a = self.cells.id(s, x);
            for b in self.cells.forward_partners(s, x) {
                self.visit_cell_pair(a, b, &mut visit);
            }
        }
    }

    /// Calls `visit(i, partners, writes)` for every slot i of cell a that has partners in cell b
    /// (a forward partner of a), so that each pair with a real particle is visited once.
    fn visit_cell_pair(
        &self,
        a: usize,
        b: usize,
        mut visit: impl FnMut(usize, Range<usize>, Writes),
    ) {
        let cells = &self.cells;
        for i in cells.reals(a) {
            let reals = if a == b {
                i + 1..cells.real[b + 1]
            } else {
                cells.reals(b)
            };
            visit(i, reals, Writes::Both);
            visit(i, cells.images(b), Writes::First);
        }
        if a != b {
            for i in cells.images(a) {
                visit(i, cells.reals(b), Writes::Second);
            }
        }
    }

    /// (pairs visited, pairs within r_c) per step.
    pub fn count_pairs(&self) -> (usize, usize) {
        let cells = &self.cells;
        (0..cells.strips)
            .into_par_iter()
            .map(|s| {
                let (mut visited, mut within) = (0, 0);
                self.visit_strip(s, |i, partners, _| {
                    visited += partners.len();
                    within += partners
                        .filter(|&j| self.distance_squared(i, j) < self.cutoff_squared)
                        .count();
                });
                (visited, within)
            })
            .reduce(|| (0, 0), |p, q| (p.0 + q.0, p.1 + q.1))
    }

    #[inline]
    fn distance_squared(&self, i: usize, j: usize) -> f64 {
        let (p, q) = (self.position[i], self.position[j]);
        (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)
    }

    /// Sets every image to its mirrored particle's value times the mirror's sign.
    fn fill_images(&self, phi: &mut [f64]) {
        let (reals, images) = phi.split_at_mut(self.count());
        images
            .par_iter_mut()
            .zip(&self.image_source)
            .for_each(|(value, &(source, sign))| *value = sign * reals[source]);
    }

    /// rate_i = Σ_j exp(−r_ij²/ε²)(φ_j − φ_i) over the real slots, with images already in φ.
    fn exchange(&self, phi: &[f64], rate: &mut [f64]) {
        let cells = &self.cells;
        rate.par_iter_mut().for_each(|r| *r = 0.0);
        for parity in 0..2 {
            let tasks = cells.strips.saturating_sub(parity).div_ceil(2);
            if tasks > 0 {
                let start = cells.strip_start(parity);
                self.exchange_strips(parity, tasks, phi, &mut rate[start..]);
            }
        }
    }

    /// The pairs started in strips first, first + 2, … (`tasks` of them), in parallel: strips s
    /// and s + 1 hold the rates the pairs started in strip s change, so these tasks write
    /// disjoint slots. `rate` starts at strip `first`'s first slot.
    fn exchange_strips(&self, first: usize, tasks: usize, phi: &[f64], rate: &mut [f64]) {
        let cells = &self.cells;
        if tasks == 1 {
            self.exchange_strip(first, phi, cells.strip_start(first), rate);
            return;
        }
        let middle = first + 2 * (tasks / 2);
        let (left, right) = rate.split_at_mut(cells.strip_start(middle) - cells.strip_start(first));
        rayon::join(
            || self.exchange_strips(first, tasks / 2, phi, left),
            || self.exchange_strips(middle, tasks - tasks / 2, phi, right),
        );
    }

    /// The pairs started in strip s; `rate` holds the rates of slots base.. (strips s, s + 1).
    fn exchange_strip(&self, s: usize, phi: &[f64], base: usize, rate: &mut [f64]) {
        let inverse_eps_squared = 1.0 / (self.eps * self.eps);
        self.visit_strip(s, |i, partners, writes| {
            let (xi, phi_i) = (self.position[i], phi[i]);
            let mut gain = 0.0;
            for j in partners {
                let xj = self.position[j];
                let r2 = (xj[0] - xi[0]).powi(2) + (xj[1] - xi[1]).powi(2);
                if r2 < self.cutoff_squared {
                    let flux = (-r2 * inverse_eps_squared).exp() * (phi[j] - phi_i);
                    gain += flux;
                    if writes != Writes::First {
                        rate[j - base] -= flux;
                    }
                }
            }
            if writes != Writes::Second {
                rate[i - base] += gain;
            }
        });
    }

    /// The initial field of a local problem in lattice order.
    fn sample(&self, case: &Case) -> Vec<f64> {
        (0..self.count())
            .into_par_iter()
            .map(|i| {
                initial_value(
                    case.problem,
                    &self.lattice_position(i)[..self.dim],
                    self.length,
                )
            })
            .collect()
    }
}

/// PSE's sum as an operator on lattice-ordered fields: (L u)_i = K Σ_j exp(−r_ij²/ε²)(u_j − u_i)
/// over the particles and images within r_c (`rate_factor` gives K), D times PSE's Laplacian.
pub struct PseOperator<'a> {
    particles: &'a Particles,
    factor: f64,
    /// The lattice index of each real slot (the real particles fill slots 0 .. N): `slot_of`
    /// inverted, so the field is gathered into slot order in parallel.
    lattice_of: Vec<usize>,
}

/// The field in slot order, images included, and the rates of the real slots.
pub struct PseWorkspace {
    phi: Vec<f64>,
    rate: Vec<f64>,
}

impl<'a> PseOperator<'a> {
    pub fn new(particles: &'a Particles, diffusivity: f64) -> Self {
        let mut lattice_of = vec![0; particles.count()];
        for (i, &slot) in particles.slot_of.iter().enumerate() {
            lattice_of[slot] = i;
        }
        PseOperator {
            particles,
            factor: particles.rate_factor(diffusivity),
            lattice_of,
        }
    }
}

impl LinearOperator for PseOperator<'_> {
    type Workspace = PseWorkspace;

    fn workspace(&self) -> PseWorkspace {
        PseWorkspace {
            phi: vec![0.0; self.particles.slots()],
            rate: vec![0.0; self.particles.count()],
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], workspace: &mut PseWorkspace) {
        let (particles, PseWorkspace { phi, rate }) = (self.particles, workspace);
        phi[..particles.count()]
            .par_iter_mut()
            .zip(&self.lattice_of)
            .for_each(|(value, &i)| *value = u[i]);
        particles.fill_images(phi);
        particles.exchange(phi, rate);
        let rate = &rate[..];
        out.par_iter_mut()
            .zip(&particles.slot_of)
            .for_each(|(o, &slot)| *o = self.factor * rate[slot]);
    }
}

/// Index i of the odd 2n-periodic extension: the lattice index it mirrors and the sign.
fn fold(i: isize, n: usize) -> (usize, f64) {
    let k = i.rem_euclid(2 * n as isize) as usize;
    if k < n {
        (k, 1.0)
    } else {
        (2 * n - 1 - k, -1.0)
    }
}

/// [first, first + c₀, first + c₀ + c₁, …].
fn prefix_sums(counts: &[usize], first: usize) -> Vec<usize> {
    std::iter::once(first)
        .chain(counts.iter().scan(first, |total, &c| {
            *total += c;
            Some(*total)
        }))
        .collect()
}

/// Runs a `pse` case.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    let setup_started = Instant::now();
    let (field, eps) = match (case.m, case.eps) {
        (Some(m), _) => ("m", m as f64 * case.length() / case.n as f64),
        (None, eps) => ("eps", eps.expect("validated: m or eps")),
    };
    let particles = Particles::new(case.dim, case.n, case.length(), eps);
    let dt_stable = particles
        .dt_stable(case.diffusivity)
        .ok_or_else(|| too_narrow(field, eps, particles.h))?;
    let (dt, steps) = time_step(case, dt_stable, false)?;
    let u0 = particles.sample(case);
    let divergence_bound = divergence_bound(case, diagnostics::max_abs(&u0), None);
    let (pair_visits, bonds) = particles.count_pairs();
    let setup_s = setup_started.elapsed().as_secs_f64();
    let stepping = Stepping::of_case(case, dt, steps, divergence_bound, particles.volume());
    let operator = PseOperator::new(&particles, case.diffusivity);
    let ranks = Ranks::single();
    let mut euler = ForwardEuler::new(&operator, None, ranks, u0.len());
    let mut trajectory = integrate(&mut euler, ranks, u0, None, &stepping);
    // Untimed, after the run: at the step asked for, before it was lowered to land on t_end.
    if let Some(steps) = case.amplification_steps {
        let (asked, _) = requested(case, dt_stable);
        let count = particles.count();
        let mut euler = ForwardEuler::new(&operator, None, ranks, count);
        trajectory.amplification = amplification(&mut euler, ranks, None, count, asked, steps);
        let spike = middle_node(case.dim, case.n);
        trajectory.positivity = positivity(&mut euler, ranks, None, count, asked, spike);
    }
    let resolved = Resolved {
        h: particles.h,
        eps: Some(eps),
        m: case.m,
        c: None,
        dt,
        dt_stable,
        dt_positive: None,
        dt_stable_spectrum: None,
        steps,
        nodes: particles.count(),
        bonds,
        pair_visits: Some(pair_visits),
        quadrature: None,
        collar: None,
        patch_error: None,
        backend: None,
        integrator: None,
    };
    let position = |i: usize| particles.lattice_position(i);
    Ok(local::outcome(
        case, resolved, setup_s, &stepping, trajectory, position,
    ))
}

#[cfg(test)]
mod tests;
