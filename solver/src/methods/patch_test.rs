//! Seed 003's patch tests of a variable horizon: the operator L_h of a formulation (`standard` or
//! `partial_stress`, `discretization::variable_horizon`) applied to a prescribed linear or
//! quadratic field on D = [0, 1] with its collars, in 1D. A linear field must give L_h u = 0 and
//! u = x² the constant 2k; what is left is the ghost force.
//!
//! The record carries L_h u along the bar (the seed's "acceleration over the length of the bar"),
//! its largest deviation (`ghost_force`), the bonds and the forward-Euler stable step of the
//! operator (the seed's performance slide compares both for a constant and a varying horizon).

use crate::case::{
    horizon_length, readable, Case, CaseError, HorizonProfile, Method, PatchField, Rules,
    ValidCase, MAX_EPS,
};
use crate::discretization::variable_horizon::{horizon_at, VariableHorizonOperator};
use crate::output::outcome::Outcome;
use crate::output::record::{Distribution, PatchTest, Record, Resolved, Spectrum};
use crate::problem::polynomial::PolynomialField;
use faer::Mat;
use std::time::Instant;

/// Above this many nodes the dense eigenvalues (O(n³)) are left out of the record.
pub const SPECTRUM_MAX_NODES: usize = 2000;

/// The rules of a patch-test case.
pub fn validate(case: &Case) -> Result<(), CaseError> {
    if case.dim != 1 {
        return Err(CaseError::new(
            "dim",
            format!(
                "the variable-horizon patch test is 1D (got {}); use dim = 1",
                case.dim
            ),
        ));
    }
    if case.patch == Some(PatchField::Quartic) {
        return Err(CaseError::new(
            "patch",
            "a patch test prescribes `linear` or `quadratic`; `quartic` is coupled_1d's Example 2",
        ));
    }
    validate_horizon(case)?;
    case.refuse_steady_fields()?;
    case.refuse_time_loop_fields(
        "a patch test evaluates L_h once, on one rank, with its own weights",
    )
}

/// A variable horizon's rules, for the patch test and the time-dependent nonlocal method: ε(x)
/// from a varying `horizon_profile` (then no `m` or `eps`) or a constant one (then one of
/// them), a transition inside D, and ε within [h, 1/2] along the bar.
pub(crate) fn validate_horizon(case: &Case) -> Result<(), CaseError> {
    let profile = case.horizon_profile.unwrap_or(HorizonProfile::Constant);
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
        if !(0.0..=1.0).contains(&start) || !(start < end && end <= 1.0) {
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
    for x in [0.0, 0.5, 1.0] {
        let eps = horizon_at(profile, constant, x);
        if !(eps >= h && eps <= MAX_EPS) {
            return Err(CaseError::new(
                if profile == HorizonProfile::Constant { "eps" } else { "horizon_profile" },
                format!(
                    "ε = {} at x = {x} lies outside [h, {MAX_EPS}] = [{}, {MAX_EPS}]; every node needs a neighbour and the collar must stay narrower than D",
                    readable(eps),
                    readable(h)
                ),
            ));
        }
    }
    Ok(())
}

/// Evaluates L_h on the prescribed field and measures the ghost force.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    debug_assert_eq!(case.method, Method::PatchTest);
    let started = Instant::now();
    let profile = case.horizon_profile.unwrap_or(HorizonProfile::Constant);
    let constant = horizon_length(case);
    let field = case.patch.unwrap_or_default();
    let formulation = case.formulation.unwrap_or_default();
    let operator = VariableHorizonOperator::new(
        case.n,
        profile,
        constant,
        case.kernel,
        case.diffusivity,
        formulation,
    );
    let setup_s = started.elapsed().as_secs_f64();
    let applied = Instant::now();
    let u: Vec<f64> = (0..operator.bar_nodes())
        .map(|k| field.value(operator.x(k)))
        .collect();
    let l_u = operator.apply(&u);
    let solve_s = applied.elapsed().as_secs_f64();
    let expected = field.local_operator(0.0, case.diffusivity);
    let x: Vec<f64> = (0..case.n)
        .map(|i| operator.x(operator.collar + i))
        .collect();
    let eps_d = &operator.eps[operator.collar..operator.collar + case.n];
    let eps_max = eps_d.iter().copied().fold(0.0, f64::max);
    // As the seed plots it: the nodes within the largest horizon of an end left out (there ε
    // meets its constant continuation into the collar).
    let ghost_force = x
        .iter()
        .zip(&l_u)
        .filter(|(x, _)| **x > eps_max && **x < 1.0 - eps_max)
        .map(|(_, v)| (v - expected).abs())
        .fold(0.0, f64::max);
    let ghost_force_all = l_u.iter().map(|v| (v - expected).abs()).fold(0.0, f64::max);
    let lambda = operator.lambda_bound();
    let resolved = Resolved {
        h: operator.h,
        eps: Some(eps_max),
        dt_stable: 2.0 / lambda,
        nodes: case.n,
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
            l_u: l_u.clone(),
            eps_x: eps_d.to_vec(),
            spectrum: (case.n <= SPECTRUM_MAX_NODES).then(|| spectrum(&operator)),
        }),
        ..Record::new(case, resolved, Distribution::serial(case))
    };
    let lattice = crate::discretization::grid::Grid::new(1, case.n).lattice();
    Ok(Outcome {
        record,
        field: l_u,
        lattice,
        frames: Vec::new(),
    })
}

/// The eigenvalues of L_h on D with a zero collar, dense: the partial-stress form is not
/// symmetric, and with a varying horizon some of its eigenvalues have Re λ > 0.
pub fn spectrum(operator: &VariableHorizonOperator) -> Spectrum {
    let n = operator.n;
    let mut a = Mat::<f64>::zeros(n, n);
    for (i, row) in operator.rows_with_zero_collar().enumerate() {
        for (j, value) in row {
            a[(i, j)] += value;
        }
    }
    let eigenvalues = a
        .eigenvalues()
        .expect("the eigenvalues of a finite dense matrix");
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
    Spectrum {
        max_real,
        max_imaginary: fold(|z| z.im.abs(), 0.0),
        max_abs: fold(|z| (z.re * z.re + z.im * z.im).sqrt(), 0.0),
        dt_forward_euler,
    }
}
