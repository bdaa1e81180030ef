//! \[LSSM]'s optimization-based local–nonlocal coupling in 1D (D'Elia, Perego and Bochev).
//!
//! **Layout** (the seed's slides fix the local problem's far end at x = 1.75 and an overlap;
//! the rest is our choice, and consistent with the seed's tables: its finest errors are those of
//! P1 interpolation on Ω_n and Ω_l of unit length):
//! - nonlocal: −L u_n = f_n on Ω_n = (0, 1); u_n = the data on the outer collar Ω̃_i = [−ε, 0]
//!   and u_n = θ_n, the nonlocal control, on the inner collar Ω̃_c = [1, 1 + ε];
//! - local: −k u_l'' = f_l on Ω_l = (a, b) = `local_domain` (default (0.75, 1.75)); u_l = θ_l,
//!   the local control, at Γ_c = {a}, and u_l = the data at Γ_i = {b};
//! - overlap Ω_b = Ω_n ∩ Ω_l = (a, 1), where J(θ) = ½ ‖u_n(θ_n) − u_l(θ_l)‖²_{L²(Ω_b)} is
//!   minimised over the controls. Ω̃_c must lie inside Ω_l (b ≥ 1 + ε).
//!
//! **Discretization.** Piecewise-linear finite elements for both (`finite_element`), valid for
//! h ≥ ε: the nonlocal mesh is (0, 1) in n elements continued into the collars; the local mesh
//! divides (a, b) into elements of about the same h. θ_n is the vector of nodal values on Ω̃_c,
//! θ_l one number.
//!
//! **The optimality system.** Both states are affine in the controls: u_n = u_n⁰ + Σⱼ θ_n,ⱼ r_j
//! (r_j: the discrete nonlocal solution with zero data and source and a unit value at control
//! node j) and u_l = u_l⁰ + θ_l r_l. So the mismatch d = u_n − u_l on Ω_b is d⁰ + Ψ θ, and with
//! the Gauss points xₚ, weights wₚ of Ω_b (exact for the piecewise quadratic d²), J(θ) =
//! ½ ‖W^{½}(d⁰ + Ψ θ)‖². Its first-order condition Ψᵀ W (d⁰ + Ψ θ) = 0 is the normal equation of
//! a linear least-squares problem with a handful of unknowns (ε/h + 2), solved by a
//! column-pivoted QR (faer) rather than through the normal equations, whose matrix would square
//! the condition number. The directions J cannot resolve in double precision are decided by a
//! tiny smoothness term that is exact on linear data (see `least_squares`).
//! The record carries ‖∇J(θ)‖/‖∇J(0)‖, the first-order condition's residual.

use crate::case::{
    horizon_length, readable, Case, CaseError, CouplingKind, Method, Rules, ValidCase, MAX_EPS,
};
use crate::discretization::finite_element::{
    laplace_stiffness, nonlocal_stiffness, BandMatrix, Mesh,
};
use crate::discretization::grid::Lattice;
use crate::discretization::influence::{scaling_constant, Influence};
use crate::linalg::cholesky::{sparse_matrix, Cholesky};
use crate::output::outcome::Outcome;
use crate::output::record::{self, Coupling, Resolved};
use crate::problem::polynomial::PolynomialField;
use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use std::time::Instant;

/// Most elements of the local mesh (a few GB of vectors), so that a runaway `local_domain` is
/// refused rather than allocated.
const MAX_LOCAL_ELEMENTS: f64 = 1e8;

/// Longest set-up accepted, in seconds of `SETUP_RATE` operations (`Sizes::setup_operations`):
/// ten minutes, beyond any case of the seed (n ≤ 2⁷ takes milliseconds), and a guard against an
/// `n` or an ε that would run for days.
const MAX_SETUP_S: f64 = 600.0;

/// Operations per second the set-up's loops run at on one core (each "operation" is a few
/// instructions: a binary search step, a band addition): measured set-up times at ε = 0.065 and
/// n = 1024, 2048, 4096, 8192 (0.42, 1.58, 6.82, 33.0 s here) are 3.0–3.5 × 10⁹ operations
/// per second of `Sizes::setup_operations`; the lower end, so that the limit errs long.
const SETUP_RATE: f64 = 3e9;

/// The smallest horizon the optimization-based coupling resolves. Its finite elements take
/// ε < h in their stride (the collar [1, 1 + ε] is one element, and the errors of Example 2
/// approach the local limit as ε → 0), but the kernel's 1/ε³ scale against the local 1/h makes
/// round-off grow like 4e-18/ε² on the patch test u = x (measured at n = 32 … 1024: 3.9e-8 at
/// ε = 1e-5, 4.3e-6 at 1e-6, 0.034 at 1e-8, 1.09 at 1e-9), whatever h.
const MIN_EPS: f64 = 1e-5;

/// The rules of a coupled case.
///
/// Long because it is the coupled problem's rules in a row, each a refusal naming its field, read
/// top to bottom as the guide lists them.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    if case.dim != 1 {
        return Err(CaseError::new(
            "dim",
            format!("the coupled problem is 1D (got {}); use dim = 1", case.dim),
        ));
    }
    if case.n < 2 {
        return Err(CaseError::new(
            "n",
            format!(
                "Ω_n = (0, 1) needs at least 2 elements for an unknown (got n = {}); use n ≥ 2",
                case.n
            ),
        ));
    }
    if case.m.is_some() == case.eps.is_some() {
        return Err(CaseError::new(
            "eps",
            "give the horizon as `eps` or `m` (one of them)",
        ));
    }
    let eps = horizon_length(case);
    if !(eps > 0.0 && eps <= MAX_EPS) {
        return Err(CaseError::new(
            if case.m.is_some() { "m" } else { "eps" },
            format!(
                "ε = {} must lie in (0, {MAX_EPS}]: the collars must stay narrower than Ω_n = (0, 1)",
                readable(eps)
            ),
        ));
    }
    if eps < MIN_EPS && case.coupling() == CouplingKind::Optimization {
        return Err(CaseError::new(
            if case.m.is_some() { "m" } else { "eps" },
            format!(
                "ε = {} is below {}, where the collar's one element of width ε loses the solution to round-off (the error on u = x, which the scheme reproduces, grows like 4e-18/ε²: 4e-8 at ε = 1e-5, 0.03 at 1e-8); use ε ≥ {}",
                readable(eps),
                readable(MIN_EPS),
                readable(MIN_EPS)
            ),
        ));
    }
    let [a, b] = local_domain(case);
    let message = if !(a.is_finite() && b.is_finite()) {
        Some("must be two finite numbers [a, b]".to_string())
    } else if a >= 1.0 {
        Some(format!(
            "the overlap Ω_b = (a, 1) with Ω_n = (0, 1) is empty (a = {}); put a inside (0, 1), e.g. 0.75",
            readable(a)
        ))
    } else if a <= 0.0 {
        Some(format!(
            "the interface Γ_c = {{a}} must lie inside Ω_n = (0, 1) (a = {}); e.g. 0.75",
            readable(a)
        ))
    } else if b < 1.0 + eps {
        Some(format!(
            "the nonlocal control collar [1, 1 + ε] = [1, {}] must lie inside the local domain (b = {}); use b ≥ 1 + ε, e.g. 1.75",
            readable(1.0 + eps),
            readable(b)
        ))
    } else if (b - a) * case.n as f64 > MAX_LOCAL_ELEMENTS {
        Some(format!(
            "meshing [a, b] = [{}, {}] at h = 1/{} takes {} elements, above {}; shorten the local domain",
            readable(a),
            readable(b),
            case.n,
            readable((b - a) * case.n as f64),
            readable(MAX_LOCAL_ELEMENTS)
        ))
    } else {
        None
    };
    if let Some(message) = message {
        return Err(CaseError::new("local_domain", message));
    }
    if case.coupling() == CouplingKind::Seamless {
        crate::methods::seamless::cells(case.n, b)?;
        if case.kernel.influence(1.0) <= 0.0 {
            return Err(CaseError::new(
                "kernel",
                "the seamless coupling's horizon is one cell h on the local part, whose only bond sits at r = 1, where this kernel's J vanishes; use constant, gaussian or inverse_distance",
            ));
        }
        crate::case::validate_diffusivity(case.diffusivity)?;
        case.refuse_steady_fields()?;
        return case.refuse_time_loop_fields(
            "the seamless coupling is steady, on one rank, solved directly by a sparse LU",
        );
    }
    let sizes = Sizes::of_case(case);
    // J must determine every control: faer's least squares asserts as many rows as columns.
    let (rows, columns) = sizes.least_squares_shape(sizes.overlap_breaks.0);
    if rows < columns {
        return Err(CaseError::new(
            "local_domain",
            format!(
                "the overlap Ω_b = (a, 1) = ({}, 1) holds no node of either mesh (h = 1/{}), so J has {rows} Gauss points and smoothing rows for {columns} controls and cannot determine them; put a below the last node 1 − h = {}",
                readable(a),
                case.n,
                readable(1.0 - 1.0 / case.n as f64)
            ),
        ));
    }
    crate::case::validate_diffusivity(case.diffusivity)?;
    if case.length.is_some() {
        return Err(CaseError::new(
            "length",
            "the coupled problem's domains are Ω_n = (0, 1) and `local_domain`; leave `length` out",
        ));
    }
    case.refuse_steady_fields()?;
    case.refuse_time_loop_fields(
        "the coupled problem is steady, on one rank, solved directly by finite elements",
    )?;
    let (nonlocal, local) = sizes.setup_operations();
    let seconds = sizes.setup_seconds();
    if seconds > MAX_SETUP_S {
        let (field, fix) = if local > nonlocal {
            ("local_domain", "shorten the local domain")
        } else {
            ("n", "use a smaller n or ε")
        };
        return Err(CaseError::new(
            field,
            format!(
                "the set-up would take about {} s ({} operations at {} per second: the nonlocal assembly grows as ε n², its factor and control responses as ε² n³, the local model as its length × n), more than the {MAX_SETUP_S} s accepted; {fix}",
                readable(seconds.round()),
                readable(nonlocal + local),
                readable(SETUP_RATE)
            ),
        ));
    }
    Ok(())
}

/// The sizes a coupled case's set-up works with, from its fields alone (nothing allocated):
/// what `validate` checks the least-squares problem and the set-up time against, and what the
/// memory estimate counts. Counts are f64: a case's fields may make them huge.
pub(crate) struct Sizes {
    /// Nodes of the nonlocal mesh (Ω_n and both collars) and of the local mesh.
    nonlocal_nodes: f64,
    local_nodes: f64,
    /// Nodes of each collar of the nonlocal mesh beyond D's end node; the controls are those of
    /// [1, 1 + ε], node 1 included.
    collar: f64,
    /// Half-bandwidth of the nonlocal stiffness matrix: the nodes within ε, and the element's.
    band: f64,
    /// Mesh nodes strictly inside the overlap (a, 1), the breaks of its quadrature: at least
    /// those of the denser mesh, at most those of both.
    overlap_breaks: (f64, f64),
}

impl Sizes {
    pub(crate) fn of_case(case: &Case) -> Sizes {
        let n = case.n as f64;
        let h = 1.0 / n;
        let eps = horizon_length(case);
        let [a, b] = local_domain(case);
        // As `Mesh::with_collars`: k h for k ≥ 1 below ε − h/4, then ε itself.
        let collar = ((eps / h - 0.25).ceil() - 1.0).max(0.0) + 1.0;
        // As `Coupled::new`: elements of about h on [a, b].
        let local_elements = ((b - a) / h).round().max(1.0);
        let local_spacing = (b - a) / local_elements;
        // Inside (a, 1): the nonlocal nodes k/n for k = ⌊a n⌋ + 1 … n − 1, and the local
        // nodes a + j h_l below 1.
        let nonlocal_inside = (n - 1.0 - (a * n).floor()).max(0.0);
        let local_inside = (((1.0 - a) / local_spacing).ceil() - 1.0).max(0.0);
        Sizes {
            nonlocal_nodes: n + 1.0 + 2.0 * collar,
            local_nodes: local_elements + 1.0,
            collar,
            band: collar + 2.0,
            overlap_breaks: (
                nonlocal_inside.max(local_inside),
                nonlocal_inside + local_inside,
            ),
        }
    }

    /// The nonlocal controls: the nodes of [1, 1 + ε].
    fn controls(&self) -> f64 {
        self.collar + 1.0
    }

    /// The nonlocal unknowns (the nodes inside (0, 1)), and the non-zeros of their block of the
    /// stiffness matrix: the pairs of them within the band, i = j included.
    fn free_block(&self) -> (f64, f64) {
        let free = (self.nonlocal_nodes - 2.0 * self.controls()).max(1.0);
        let k = self.band.min(free - 1.0);
        (free, free + 2.0 * (k * free - k * (k + 1.0) / 2.0))
    }

    /// Rows and columns of the stacked least-squares matrix [Ψ; δ D₂] (`least_squares`) with
    /// `breaks` quadrature breaks inside the overlap: two Gauss points per piece between them,
    /// a smoothing row per interior nonlocal control; a column per control, θ_l's included.
    fn least_squares_shape(&self, breaks: f64) -> (f64, f64) {
        let rows = 2.0 * (breaks + 1.0) + (self.controls() - 2.0).max(0.0);
        (rows, self.controls() + 1.0)
    }

    /// Operations of the set-up, (nonlocal model and least squares, local model), as the code
    /// runs them: a model for refusing cases that would run for days, not a benchmark.
    fn setup_operations(&self) -> (f64, f64) {
        let (nodes, collar, band) = (self.nonlocal_nodes, self.collar, self.band);
        // `nonlocal_stiffness`: about 2·collar s-pieces (the node differences below ε) of 12
        // points, each over the 2·nodes x-pieces of `shifted_pieces` with 2 Gauss points, each
        // about 150 operations (two element searches, 16 band additions).
        let assembly = 2.0 * collar * 12.0 * 4.0 * nodes * 150.0;
        // `s_pieces`: the nodes·collar differences below ε, sorted.
        let differences = nodes * collar * (nodes * collar).max(2.0).log2();
        // The Cholesky factor of the free block (a band: its non-zeros times the band's width)
        // and a response per control (two triangular solves, four sweeps of the factor's half
        // of the block); the base state sums a band row per data node.
        let (free, block) = self.free_block();
        let factor = block * band.min(free) + 2.0 * self.controls() * block + nodes * collar;
        // Two singular value decompositions and a column-pivoted QR of the stacked matrix.
        let (rows, columns) = self.least_squares_shape(self.overlap_breaks.1);
        let least_squares = 10.0 * rows * columns * columns;
        // The local model is linear in its nodes: loads, assembly, factor, solves, L² errors.
        let local = 1000.0 * self.local_nodes;
        (assembly + differences + factor + least_squares, local)
    }

    /// The set-up's predicted seconds on one core, at `SETUP_RATE`.
    fn setup_seconds(&self) -> f64 {
        let (nonlocal, local) = self.setup_operations();
        (nonlocal + local) / SETUP_RATE
    }

    /// Bytes the set-up holds at its peak, the largest of its three stages:
    /// - the nonlocal model's `sparse_matrix`: the band matrix (8 bytes per entry of the
    ///   nodes × (2 band + 1) band), and per non-zero of the free block its entry (24 bytes),
    ///   faer's triplet (24) and the matrix built from them (its argsort, row indices and
    ///   values: 24), with the mesh, load and free list;
    /// - the local model's, the same on its tridiagonal band plus the load's Gauss points (4 per
    ///   element, 16 bytes each), beside the nonlocal control responses (a vector of the
    ///   nonlocal nodes per control) kept from then on;
    /// - the least squares: Ψ, the stacked matrix, and the copies its QR and singular value
    ///   decompositions take (8 bytes per entry, four matrices), beside the responses.
    pub(crate) fn peak_bytes(&self) -> f64 {
        let (nodes, local) = (self.nonlocal_nodes, self.local_nodes);
        let (_, block) = self.free_block();
        let nonlocal = 8.0 * nodes * (2.0 * self.band + 1.0) + 72.0 * block + 24.0 * nodes;
        let responses = 8.0 * nodes * (self.controls() + 3.0);
        let local_model = 80.0 * 3.0 * local + 88.0 * local;
        let (rows, columns) = self.least_squares_shape(self.overlap_breaks.1);
        let least_squares = 32.0 * rows * columns + 24.0 * local;
        nonlocal.max(responses + local_model.max(least_squares))
    }
}

fn local_domain(case: &Case) -> [f64; 2] {
    case.local_domain()
}

/// One model's discrete problem, reduced to its controls: the state with zero controls and
/// each control's response, as nodal values on its mesh.
struct Reduced {
    mesh: Mesh,
    base: Vec<f64>,
    responses: Vec<Vec<f64>>,
    /// Positions of the control nodes.
    control_nodes: Vec<f64>,
}

impl Reduced {
    fn state(&self, controls: &[f64]) -> Vec<f64> {
        let mut u = self.base.clone();
        for (response, theta) in self.responses.iter().zip(controls) {
            for (ui, ri) in u.iter_mut().zip(response) {
                *ui += theta * ri;
            }
        }
        u
    }
}

/// Solves A u = load on the free nodes, with u given on `data` nodes and each control node in
/// turn set to 1 (the rest 0): the base state and the control responses.
fn reduce(
    mesh: Mesh,
    a: &BandMatrix,
    load: &[f64],
    data: &[(usize, f64)],
    controls: &[usize],
) -> Result<Reduced, CaseError> {
    let fixed: Vec<usize> = data
        .iter()
        .map(|&(i, _)| i)
        .chain(controls.iter().copied())
        .collect();
    let free: Vec<usize> = (0..mesh.len()).filter(|i| !fixed.contains(i)).collect();
    let mut factor = Cholesky::new(sparse_matrix(free.len(), &a.block(&free, &free)).as_ref())
        .map_err(|e| {
            CaseError::new(
                "n",
                format!("the discrete problem could not be factored ({e})"),
            )
        })?;
    let solve = |factor: &mut Cholesky, given: &[(usize, f64)], with_load: bool| {
        let mut rhs: Vec<f64> = free
            .iter()
            .map(|&i| {
                let coupling: f64 = given.iter().map(|&(j, v)| a.get(i, j) * v).sum();
                let source = if with_load { load[i] } else { 0.0 };
                source - coupling
            })
            .collect();
        factor.solve_in_place(&mut rhs);
        let mut u = vec![0.0; mesh.len()];
        for &(j, v) in given {
            u[j] = v;
        }
        for (&i, v) in free.iter().zip(rhs) {
            u[i] = v;
        }
        u
    };
    let base = solve(&mut factor, data, true);
    let responses = controls
        .iter()
        .map(|&j| solve(&mut factor, &[(j, 1.0)], false))
        .collect();
    let control_nodes = controls.iter().map(|&j| mesh.nodes[j]).collect();
    Ok(Reduced {
        mesh,
        base,
        responses,
        control_nodes,
    })
}

/// The minimiser of J_δ(θ) = ½‖d⁰ + Ψ θ‖² + ½δ²‖D₂ θ_n‖², and what conditions it.
struct Optimum {
    /// (θ_n, θ_l).
    theta: Vec<f64>,
    /// ‖∇J(θ)‖/‖∇J(0)‖ = ‖ΨᵀW(d⁰ + Ψθ)‖/‖ΨᵀWd⁰‖, the first-order condition's residual.
    gradient: f64,
    /// Singular directions of Ψ that J resolves (σᵢ > δ).
    resolved: usize,
    /// cond₂ of the Hessian ΨᵀΨ + δ² D₂ᵀD₂ of the problem solved.
    condition: f64,
}

/// Minimises J_δ by a column-pivoted QR of the stacked matrix [Ψ; δ D₂] (faer).
///
/// The control-to-mismatch map Ψ is nearly singular on the collar's far nodes: a value near
/// 1 + ε reaches Ω_n only through the bonds of a sliver at x = 1, so its singular value falls
/// as h shrinks (8e-9 σ₁ at h = 2⁻⁷, ε = 0.065; exactly 0 where no bond reaches). J alone fits
/// the O(h²) mismatch of the two discretizations through those directions: controls of 1e12
/// at h = 2⁻⁷, with the same u_n and u_l. J is a square, so a direction with σᵢ < ε_mach^¼ σ₁
/// changes it by less than √ε_mach of the strongest direction's change for the same step, the
/// accuracy to which a minimum computed in double precision can be located at all. A
/// smoothness term with δ = ε_mach^¼ σ₁ decides those directions: D₂ takes h² times the second
/// divided differences of θ_n along the collar, which vanish on linear data, so the linear
/// patch test stays exact. Measured at ε = 0.065 (u = x² − x⁴): e(u_n) and e(u_l) move by less
/// than 0.3 %, ‖∇J‖/‖∇J(0)‖ ≤ 3e-9, and the controls converge to u's values at O(h²)
/// (max error 6e-4 at h = 2⁻⁷, against 2 with δ = √ε_mach σ₁).
fn least_squares(
    psi: &Mat<f64>,
    d0: &Mat<f64>,
    smoothing: &Mat<f64>,
) -> Result<Optimum, CaseError> {
    let failed = |e| CaseError::new("n", format!("the reduced problem's SVD failed ({e:?})"));
    // Fewer rows than controls cannot determine them (and faer's least squares asserts);
    // `validate` refuses such an overlap, this keeps any other way here a refusal too.
    let columns = psi.ncols();
    if psi.nrows() + smoothing.nrows() < columns {
        return Err(CaseError::new(
            "local_domain",
            format!(
                "the overlap Ω_b holds {} Gauss points and smoothing rows for {columns} controls, too few to determine them; put a further below 1",
                psi.nrows() + smoothing.nrows()
            ),
        ));
    }
    let sigma = psi.singular_values().map_err(failed)?;
    let largest = sigma.iter().copied().fold(0.0, f64::max);
    let delta = f64::EPSILON.sqrt().sqrt() * largest;
    let (rows, penalties) = (psi.nrows(), smoothing.nrows());
    let stacked = Mat::from_fn(rows + penalties, psi.ncols(), |i, j| {
        if i < rows {
            psi[(i, j)]
        } else {
            delta * smoothing[(i - rows, j)]
        }
    });
    let rhs = Mat::from_fn(rows + penalties, 1, |i, _| {
        if i < rows {
            -d0[(i, 0)]
        } else {
            0.0
        }
    });
    let theta = stacked.col_piv_qr().solve_lstsq(&rhs);
    let stacked_sigma = stacked.singular_values().map_err(failed)?;
    let (most, least) = stacked_sigma
        .iter()
        .fold((0.0f64, f64::INFINITY), |(hi, lo), &s| {
            (hi.max(s), lo.min(s))
        });
    let residual = d0 + psi * &theta;
    let gradient = (psi.transpose() * &residual).norm_l2() / (psi.transpose() * d0).norm_l2();
    Ok(Optimum {
        theta: (0..psi.ncols()).map(|j| theta[(j, 0)]).collect(),
        gradient,
        resolved: sigma.iter().filter(|&&s| s > delta).count(),
        condition: (most / least).powi(2),
    })
}

/// h² times the second divided differences of θ_n at the interior collar nodes (a row each);
/// the last column, θ_l, takes no part.
fn second_differences(nodes: &[f64], h: f64, columns: usize) -> Mat<f64> {
    let mut d = Mat::zeros(nodes.len().saturating_sub(2), columns);
    for j in 1..nodes.len().saturating_sub(1) {
        let (left, right) = (nodes[j] - nodes[j - 1], nodes[j + 1] - nodes[j]);
        let scale = 2.0 * h * h / (left + right);
        d[(j - 1, j - 1)] = scale / left;
        d[(j - 1, j)] = -scale * (1.0 / left + 1.0 / right);
        d[(j - 1, j + 1)] = scale / right;
    }
    d
}

/// The discrete coupled problem, both models reduced to their controls, and where J is measured.
struct Coupled {
    nonlocal: Reduced,
    local: Reduced,
    /// Gauss points and weights of Ω_b, between the nodes of both meshes (exact for d²).
    overlap: Vec<(f64, f64)>,
    h: f64,
    eps: f64,
    c: f64,
    bonds: usize,
}

impl Coupled {
    /// Assembles and reduces both models (the factorisations and control responses included).
    fn new(case: &Case) -> Result<Coupled, CaseError> {
        let field = case.patch();
        let (k, kernel, eps) = (case.diffusivity, case.kernel, horizon_length(case));
        let [a, b] = local_domain(case);
        let h = 1.0 / case.n as f64;

        // The nonlocal model on [−ε, 1 + ε].
        let mesh = Mesh::with_collars(case.n, eps);
        let c = scaling_constant(1, kernel, eps, k);
        let stiffness = nonlocal_stiffness(&mesh, kernel, eps, c);
        let bonds = stiffness.off_diagonal_nonzeros();
        let load = mesh.load(0.0, 1.0, |x| -field.nonlocal_operator(x, k, kernel, eps));
        let data: Vec<(usize, f64)> = (0..mesh.len())
            .filter(|&i| mesh.nodes[i] <= 0.0)
            .map(|i| (i, field.value(mesh.nodes[i])))
            .collect();
        let collar: Vec<usize> = (0..mesh.len()).filter(|&i| mesh.nodes[i] >= 1.0).collect();
        let nonlocal = reduce(mesh, &stiffness, &load, &data, &collar)?;

        // The local model on [a, b].
        let mesh = Mesh::uniform(a, b, (((b - a) / h).round() as usize).max(1));
        let load = mesh.load(a, b, |x| -field.local_operator(x, k));
        let stiffness = laplace_stiffness(&mesh, k);
        let outer = [(mesh.len() - 1, field.value(b))];
        let local = reduce(mesh, &stiffness, &load, &outer, &[0])?;

        let overlap = nonlocal.mesh.quadrature(a, 1.0, 2, &local.mesh.nodes);
        Ok(Coupled {
            nonlocal,
            local,
            overlap,
            h,
            eps,
            c,
            bonds,
        })
    }

    /// Ψ and d⁰, both weighted by W^{½}: d = u_n − u_l at Ω_b's Gauss points, per control and
    /// at zero controls.
    fn reduced(&self) -> (Mat<f64>, Mat<f64>) {
        let (nonlocal, local) = (&self.nonlocal, &self.local);
        let columns = nonlocal.responses.len() + 1;
        let psi = Mat::from_fn(self.overlap.len(), columns, |p, j| {
            let (x, w) = self.overlap[p];
            w.sqrt()
                * match nonlocal.responses.get(j) {
                    Some(r) => nonlocal.mesh.value(r, x),
                    None => -local.mesh.value(&local.responses[0], x),
                }
        });
        let d0 = Mat::from_fn(self.overlap.len(), 1, |p, _| {
            let (x, w) = self.overlap[p];
            w.sqrt() * (nonlocal.mesh.value(&nonlocal.base, x) - local.mesh.value(&local.base, x))
        });
        (psi, d0)
    }

    /// The controls minimising J_δ (see `least_squares`).
    fn optimum(&self) -> Result<Optimum, CaseError> {
        let (psi, d0) = self.reduced();
        let smoothing = second_differences(&self.nonlocal.control_nodes, self.h, psi.ncols());
        least_squares(&psi, &d0, &smoothing)
    }

    /// u_n and u_l for the controls θ = (θ_n, θ_l).
    fn states(&self, theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (theta_n, theta_l) = theta.split_at(theta.len() - 1);
        (self.nonlocal.state(theta_n), self.local.state(theta_l))
    }

    /// ‖u_n − u_l‖ in L²(Ω_b): √(2J).
    fn mismatch(&self, (u_n, u_l): &(Vec<f64>, Vec<f64>)) -> f64 {
        self.overlap
            .iter()
            .map(|&(x, w)| {
                w * (self.nonlocal.mesh.value(u_n, x) - self.local.mesh.value(u_l, x)).powi(2)
            })
            .sum::<f64>()
            .sqrt()
    }
}

/// Solves the coupled problem and measures both states against the exact solution.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    debug_assert_eq!(case.method, Method::Coupled1d);
    let started = Instant::now();
    let problem = Coupled::new(case)?;
    let setup_s = started.elapsed().as_secs_f64();
    let solving = crate::output::usage::Solving::starts();
    let optimum = problem.optimum()?;
    let (theta_n, theta_l) = optimum.theta.split_at(optimum.theta.len() - 1);
    let states = problem.states(&optimum.theta);
    let (nonlocal, local) = (&problem.nonlocal, &problem.local);
    let (u_n, u_l) = (&states.0, &states.1);
    let solve_s = solving.ends();

    let field = case.patch();
    let exact = |x: f64| field.value(x);
    let [a, b] = local_domain(case);
    let control_error = nonlocal
        .control_nodes
        .iter()
        .zip(theta_n)
        .map(|(&x, t)| (t - exact(x)).abs())
        .fold((theta_l[0] - exact(a)).abs(), f64::max);
    let coupling = Coupling {
        error_nonlocal: nonlocal.mesh.l2_distance(u_n, 0.0, 1.0, exact),
        error_local: local.mesh.l2_distance(u_l, a, b, exact),
        mismatch: Some(problem.mismatch(&states)),
        gradient: Some(optimum.gradient),
        hessian_condition: Some(optimum.condition),
        controls_resolved: Some(optimum.resolved),
        control_nodes: nonlocal.control_nodes.clone(),
        controls_nonlocal: theta_n.to_vec(),
        control_local: Some(theta_l[0]),
        control_error: Some(control_error),
        nonlocal_nodes: nonlocal.mesh.len(),
        local_nodes: local.mesh.len(),
        local_domain: [a, b],
    };
    let resolved = Resolved {
        h: problem.h,
        eps: Some(problem.eps),
        c: Some(problem.c),
        nodes: nonlocal.mesh.len() + local.mesh.len(),
        bonds: problem.bonds,
        ..Resolved::default()
    };
    let record = record::coupled(case, resolved, (setup_s, solve_s), coupling);
    // The field on Ω_n's lattice kh, k = 0 … n (the collars' nodes left out).
    let first = nonlocal.mesh.nodes.partition_point(|&z| z < 0.0);
    Ok(Outcome {
        record,
        field: u_n[first..=first + case.n].to_vec(),
        lattice: Lattice {
            dim: 1,
            n: case.n + 1,
            origin: 0.0,
            spacing: problem.h,
        },
        frames: Vec::new(),
    })
}

#[cfg(test)]
mod tests;
