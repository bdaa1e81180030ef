//! \[LSSM]'s patch tests of a variable horizon: the operator L_h of a formulation (`standard`,
//! `x_centred` or `partial_stress`, `discretization::variable_horizon`) applied to a prescribed
//! linear or quadratic field on D = [0, 1]^d with its collars, in 1D or 2D (ε and the field
//! depending on x alone). A linear field must give L_h u = 0 and
//! u = x² the constant 2k; what is left is the ghost force.
//!
//! The record carries L_h u along the bar (the seed's "acceleration over the length of the bar"),
//! its largest deviation (`ghost_force`), the bonds and the forward-Euler stable step of the
//! operator (the seed's performance slide compares both for a constant and a varying horizon).

use crate::case::{
    horizon_length, readable, validate_diffusivity, Case, CaseError, HorizonProfile, Method,
    PatchField, Rules, ValidCase, MAX_EPS,
};
use crate::discretization::influence::Influence;
use crate::discretization::variable_horizon::{horizon_at, VariableHorizonOperator};
use crate::output::diagnostics::magnitude;
use crate::output::outcome::Outcome;
use crate::output::record::{self, Distribution, PatchTest, Record, Resolved, Spectrum};
use crate::problem::polynomial::PolynomialField;
use faer::Mat;
use std::time::Instant;

/// Above this many nodes the dense eigenvalues (O(n³)) give way to the sparse eigensolver's.
pub const SPECTRUM_MAX_NODES: usize = 2000;

/// Above this many nodes the spectrum is left out of the record: the sparse LU of a 2D L_h
/// fills in about nodes × (2R + 1) n entries (R the reach in cells), 1.3 GB at 200².
pub const SPARSE_SPECTRUM_MAX_NODES: usize = 20_000;

/// The rules of a patch-test case.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    if case.patch == Some(PatchField::Quartic) {
        return Err(CaseError::new(
            "patch",
            "a patch test prescribes `linear` or `quadratic`; `quartic` is coupled_1d's Example 2",
        ));
    }
    validate_horizon(case)?;
    validate_interior(case)?;
    validate_diffusivity(case.diffusivity)?;
    case.refuse_steady_fields()?;
    case.refuse_time_loop_fields(
        "a patch test evaluates L_h once, on one rank, with its own weights",
    )
}

/// The field that sets the horizon: `horizon_profile` when it varies, else `m` or `eps`.
fn horizon_field(case: &Case) -> &'static str {
    match case.horizon_profile {
        Some(profile) if profile != HorizonProfile::Constant => "horizon_profile",
        _ if case.m.is_some() => "m",
        _ => "eps",
    }
}

/// The refusal of a horizon whose largest value ε_max over D leaves no node of D farther than
/// ε_max from both ends: the ghost force is measured there, and over no node it would be 0.
fn empty_interior(case: &Case, eps_max: f64) -> CaseError {
    let h = 1.0 / case.n as f64;
    CaseError::new(
        horizon_field(case),
        format!(
            "ε reaches {} on D, so no node of D lies farther than that from both ends, where the ghost force is measured; keep ε below 1/2 − h/2 = {} (or refine n)",
            readable(eps_max),
            readable(0.5 - 0.5 * h)
        ),
    )
}

/// Some node of D must lie farther than the largest ε from both ends (`run` measures the ghost
/// force there). ε(x) is monotone for every profile, so its largest value on D's nodes is at the
/// first or the last node, and the nodes nearest the middle are the ones to test.
fn validate_interior(case: &Case) -> Result<(), CaseError> {
    let profile = case.horizon_profile();
    let (n, h) = (case.n, 1.0 / case.n as f64);
    let x = |i: usize| (i as f64 + 0.5) * h;
    let eps_max = horizon_at(profile, horizon_length(case), x(0)).max(horizon_at(
        profile,
        horizon_length(case),
        x(n - 1),
    ));
    let inside = |i: usize| x(i) > eps_max && x(i) < 1.0 - eps_max;
    if inside((n - 1) / 2) || inside(n / 2) {
        Ok(())
    } else {
        Err(empty_interior(case, eps_max))
    }
}

/// A variable horizon's rules, for the patch test and the time-dependent nonlocal method: ε(x)
/// from a varying `horizon_profile` (then no `m` or `eps`) or a constant one (then one of
/// them), a transition inside D, and ε within [h, 1/2] along the bar.
pub(crate) fn validate_horizon(case: &Case) -> Result<(), CaseError> {
    let profile = case.horizon_profile();
    match (profile, case.m, case.eps) {
        (HorizonProfile::Constant, Some(_), None) | (HorizonProfile::Constant, None, Some(_)) => {}
        (HorizonProfile::Constant, _, _) => {
            return Err(CaseError::new(
                "eps",
                "a constant horizon needs `eps` or `m` (one of them); or give a varying `horizon_profile`",
            ))
        }
        (_, None, None) => {}
        (_, _, _) => {
            return Err(CaseError::new(
                if case.m.is_some() { "m" } else { "eps" },
                "the horizon_profile gives ε(x); leave `m` and `eps` out",
            ))
        }
    }
    let constant = horizon_length(case);
    if let HorizonProfile::Transition { start, end, .. } = profile {
        if !((0.0..=1.0).contains(&start) && start < end && end <= 1.0) {
            return Err(CaseError::new(
                "horizon_profile",
                format!(
                    "the transition must lie in D = [0, 1] with start < end (got start = {}, end = {})",
                    readable(start),
                    readable(end)
                ),
            ));
        }
    }
    let h = 1.0 / case.n as f64;
    let field = match profile {
        HorizonProfile::Constant => "eps",
        _ => "horizon_profile",
    };
    for x in [0.0, 0.5, 1.0] {
        let eps = horizon_at(profile, constant, x);
        if !(eps >= h && eps <= MAX_EPS) {
            return Err(CaseError::new(
                field,
                format!(
                    "ε = {} at x = {x} lies outside [h, {MAX_EPS}] = [{}, {MAX_EPS}]; every node needs a neighbour and the collar must stay narrower than D",
                    readable(eps),
                    readable(h)
                ),
            ));
        }
        // The nearest neighbour sits at r = h/ε: a kernel that vanishes there (J = 1 − r at
        // ε = h) leaves the node without a bond.
        if case.kernel.influence((h / eps).min(1.0)) <= 0.0 {
            return Err(CaseError::new(
                field,
                format!(
                    "ε = {} at x = {x} reaches only the nearest neighbour, at r = h/ε = 1, where the kernel's J vanishes, so the node has no bond; keep ε above h = {} with this kernel",
                    readable(eps),
                    readable(h)
                ),
            ));
        }
    }
    Ok(())
}

/// Bytes the variable-horizon operator holds at its peak, from the case alone (nothing
/// allocated): D's rows (16 bytes per coefficient: a node's bonds, about 2ε/h in 1D and
/// π (ε/h)² in 2D, plus one for `standard` and `x_centred`; 2^d times that for
/// `partial_stress`, whose rows reach the neighbours' neighbours) and the bonds of the bar's
/// columns (24 bytes each); a patch test's spectrum (dense up to `SPECTRUM_MAX_NODES` nodes:
/// the matrix and the eigensolver's copies, 32 N² bytes; sparse up to
/// `SPARSE_SPECTRUM_MAX_NODES`: the LU's fill, about N (2r + 1) n entries of 16 bytes, twice, r
/// the rows' reach);
/// for a time-dependent run, the rows copied into its operator (growing vectors: up to twice
/// their length).
pub(crate) fn operator_bytes(case: &Case) -> f64 {
    let profile = case.horizon_profile();
    let constant = horizon_length(case);
    let n = case.n as f64;
    let dim = case.dim as i32;
    // ε(x) is monotone: its extremes are at the ends.
    let [left, right] = [0.0, 1.0].map(|x| horizon_at(profile, constant, x) * n);
    let (largest, mean) = (left.max(right).floor(), 0.5 * (left + right));
    let bonds_per_node = match dim {
        2 => std::f64::consts::PI * mean * mean,
        _ => 2.0 * mean,
    };
    let nodes = n.powi(dim);
    let columns = n + 4.0 * largest;
    let bonds = 24.0 * columns * bonds_per_node;
    let row = match case.formulation() {
        crate::case::Formulation::Standard | crate::case::Formulation::XCentred => {
            bonds_per_node + 1.0
        }
        crate::case::Formulation::PartialStress => 2f64.powi(dim) * bonds_per_node + 1.0,
    };
    let rows = 16.0 * nodes * row;
    let spectrum = match case.method == Method::PatchTest {
        true if nodes <= SPECTRUM_MAX_NODES as f64 => 32.0 * nodes * nodes,
        true if nodes <= SPARSE_SPECTRUM_MAX_NODES as f64 => {
            // The rows' reach: R, or 2R for the partial stress.
            let reach = match case.formulation() {
                crate::case::Formulation::PartialStress => 2.0 * largest,
                _ => largest,
            };
            2.0 * 16.0 * nodes * (2.0 * reach + 1.0) * n.powi(dim - 1) + 2.0 * rows
        }
        _ => 0.0,
    };
    let copied = match case.method == Method::Nonlocal {
        true => 2.0 * rows,
        false => 0.0,
    };
    bonds + rows + spectrum + copied
}

/// Evaluates L_h on the prescribed field and measures the ghost force.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    debug_assert_eq!(case.method, Method::PatchTest);
    let started = Instant::now();
    let profile = case.horizon_profile();
    let constant = horizon_length(case);
    let field = case.patch();
    let formulation = case.formulation();
    let operator = VariableHorizonOperator::new(
        case.dim,
        case.n,
        profile,
        constant,
        case.kernel,
        case.diffusivity,
        formulation,
    );
    let setup_s = started.elapsed().as_secs_f64();
    let applied = crate::output::usage::Solving::starts();
    let u: Vec<f64> = (0..operator.bar_nodes())
        .map(|k| field.value(operator.x(k)))
        .collect();
    let l_u = operator.apply(&u);
    let solve_s = applied.ends();
    let expected = field.local_operator(0.0, case.diffusivity);
    let x_of = |i: usize| operator.x(operator.bar_index(i));
    let eps_d = operator.eps_on_d();
    let eps_max = eps_d.iter().copied().fold(0.0, f64::max);
    // As the seed plots it: the nodes within the largest horizon of an end left out (there ε
    // meets its constant continuation into the collar). A NaN counts as +∞ (`f64::max` would
    // skip it), and no node at all is a refusal, not a ghost force of 0. In 2D the field and
    // ε depend on x alone, and the collar holds the field, so every row of nodes counts.
    let deviation = |v: &f64| magnitude(v - expected);
    let ghost_force = l_u
        .iter()
        .enumerate()
        .filter(|&(i, _)| x_of(i) > eps_max && x_of(i) < 1.0 - eps_max)
        .map(|(_, v)| deviation(v))
        .reduce(f64::max)
        .ok_or_else(|| empty_interior(case, eps_max))?;
    // Along the bar: in 2D, the middle row of nodes.
    let first = if case.dim == 2 {
        case.n / 2 * case.n
    } else {
        0
    };
    let along = first..first + case.n;
    let x: Vec<f64> = along.clone().map(x_of).collect();
    let ghost_force_all = l_u.iter().map(deviation).fold(0.0, f64::max);
    let lambda = operator.lambda_bound();
    let resolved = Resolved {
        h: operator.h,
        eps: Some(eps_max),
        dt_stable: 2.0 / lambda,
        nodes: l_u.len(),
        bonds: operator.bonds,
        ..Resolved::default()
    };
    let record = Record {
        setup_s,
        solve_s,
        step_s: solve_s,
        patch: Some(PatchTest {
            ghost_force,
            ghost_force_all,
            expected,
            eps_min: eps_d.iter().copied().fold(f64::INFINITY, f64::min),
            x,
            l_u: l_u[along].to_vec(),
            eps_x: eps_d.to_vec(),
            spectrum: spectrum(&operator, case.diffusivity),
        }),
        ..record::fresh(case, resolved, Distribution::serial(case))
    };
    let lattice = crate::discretization::grid::Grid::new(case.dim, case.n).lattice();
    Ok(Outcome {
        record,
        field: l_u,
        lattice,
        frames: Vec::new(),
    })
}

/// The eigenvalues of L_h on D with a zero collar: every one, dense, up to
/// `SPECTRUM_MAX_NODES` nodes; beyond, up to `SPARSE_SPECTRUM_MAX_NODES`, the rightmost and the
/// largest by a sparse eigensolver (`linalg::spectrum`). The partial-stress form is not
/// symmetric, and with a varying horizon some of its eigenvalues have Re λ > 0.
pub fn spectrum(operator: &VariableHorizonOperator, diffusivity: f64) -> Option<Spectrum> {
    let rows: Vec<Vec<(usize, f64)>> = operator.rows_with_zero_collar().collect();
    let n = rows.len();
    let (eigenvalues, computed) = if n <= SPECTRUM_MAX_NODES {
        let mut a = Mat::<f64>::zeros(n, n);
        for (i, row) in rows.iter().enumerate() {
            for &(j, value) in row {
                a[(i, j)] += value;
            }
        }
        let all = a
            .eigenvalues()
            .expect("the eigenvalues of a finite dense matrix");
        (all, None)
    } else if n <= SPARSE_SPECTRUM_MAX_NODES {
        // Shifts from σ = k, right of the slowest decay −k π² d of the local limit. Without
        // converged eigenvalues the record has no spectrum rather than an invented one.
        let some = crate::linalg::spectrum::ends(&rows, diffusivity).ok()?;
        let count = some.len();
        (some, Some(count))
    } else {
        return None;
    };
    let fold =
        |f: fn(&faer::c64) -> f64, start: f64| eigenvalues.iter().map(f).fold(start, f64::max);
    let max_real = fold(|z| z.re, f64::NEG_INFINITY);
    let dt_forward_euler = (max_real <= 0.0).then(|| {
        eigenvalues
            .iter()
            .map(|z| z.re * z.re + z.im * z.im)
            .zip(&eigenvalues)
            .filter(|(modulus2, _)| *modulus2 > 0.0)
            .map(|(modulus2, z)| -2.0 * z.re / modulus2)
            .fold(f64::INFINITY, f64::min)
    });
    Some(Spectrum {
        max_real,
        max_imaginary: fold(|z| z.im.abs(), 0.0),
        max_abs: fold(|z| (z.re * z.re + z.im * z.im).sqrt(), 0.0),
        dt_forward_euler,
        computed,
    })
}
