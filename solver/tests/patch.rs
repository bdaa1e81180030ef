//! Patch tests (\[LSSM]'s idea, for diffusion): L_h of a linear field vanishes and L_h of |x|²
//! is 2dk, checked on the operators themselves (both backends) at the nodes whose ball lies in D,
//! for every quadrature, kernel and m from 1 to 10.

use solver::case::{Backend, Kernel, Quadrature};
use solver::discretization::grid::{Grid, Horizon};
use solver::discretization::influence::Influence;
use solver::discretization::stencil::Stencil;
use solver::operator::{plan, LinearOperator};

const DIFFUSIVITY: f64 = 0.7;

/// The stencils of every dimension, kernel, quadrature and m = 1..=10 (on n = 2m + 5 nodes per
/// side, so that 5 nodes per side see no collar), leaving out those that vanish (J = 1 − r, m = 1).
fn patches() -> Vec<Stencil> {
    let mut stencils = Vec::new();
    for dim in [1, 2] {
        for kernel in Kernel::ALL {
            for quadrature in Quadrature::ALL {
                for m in 1..=10 {
                    let grid = Grid::new(dim, 2 * m + 5);
                    let horizon = Horizon::from_m(&grid, m);
                    let stencil = Stencil::new(grid, horizon, kernel, quadrature, DIFFUSIVITY);
                    if stencil.total_weight > 0.0 {
                        stencils.push(stencil);
                    }
                }
            }
        }
    }
    stencils
}

/// L_h u at the nodes whose ball lies in D, by each backend.
fn interior_values(stencil: &Stencil, u: &[f64]) -> Vec<Vec<f64>> {
    let (grid, m) = (stencil.grid, stencil.horizon.m);
    let interior = |i: usize| {
        let (ix, iy) = (i % grid.n, i / grid.n);
        let inside = |k: usize| k >= m && k + m < grid.n;
        inside(ix) && (grid.dim == 1 || inside(iy))
    };
    [Backend::Stencil, Backend::NeighbourList]
        .iter()
        .map(|&backend| {
            let mut out = vec![0.0; u.len()];
            plan(backend, stencil).apply_once(u, &mut out);
            (0..u.len())
                .filter(|&i| interior(i))
                .map(|i| out[i])
                .collect()
        })
        .collect()
}

fn label(s: &Stencil) -> String {
    format!(
        "{}D {:?} {:?} m={}",
        s.grid.dim, s.kernel, s.quadrature, s.horizon.m
    )
}

#[test]
fn linear_fields_give_zero_to_round_off() {
    for stencil in patches() {
        let grid = stencil.grid;
        let u: Vec<f64> = (0..grid.nodes())
            .map(|i| {
                let x = grid.position(i);
                0.3 + 1.7 * x[0] - 0.9 * x[1]
            })
            .collect();
        // Each term w_o (u_{i+o} − u_i) is at most w_o · 2.6 ε; their sum cancels exactly.
        let scale = stencil.total_weight * 2.6 * stencil.horizon.eps;
        for values in interior_values(&stencil, &u) {
            assert!(!values.is_empty());
            let worst = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(
                worst <= 1e-14 * scale,
                "{}: L_h(linear) = {worst:e}, scale {scale:e}",
                label(&stencil)
            );
        }
    }
}

#[test]
fn quadratic_fields_give_2dk_times_one_plus_the_patch_error() {
    for stencil in patches() {
        let grid = stencil.grid;
        // Centred in D so that |x − x_c|² stays O(ε²) where it is evaluated (no cancellation).
        let centre = grid.position(grid.nodes() / 2);
        let u: Vec<f64> = (0..grid.nodes())
            .map(|i| {
                let x = grid.position(i);
                (0..grid.dim).map(|a| (x[a] - centre[a]).powi(2)).sum()
            })
            .collect();
        let exact = 2.0 * grid.dim as f64 * DIFFUSIVITY;
        let expected = exact * (1.0 + stencil.patch_error());
        for values in interior_values(&stencil, &u) {
            for value in values {
                assert!(
                    (value - expected).abs() <= 1e-12 * exact,
                    "{}: L_h|x|² = {value}, the record's patch error says {expected}",
                    label(&stencil)
                );
                if stencil.quadrature == Quadrature::Ac {
                    assert!(
                        (value / exact - 1.0).abs() <= 1e-12,
                        "{}: `ac` gives L_h|x|² = {value}, not 2dk = {exact}",
                        label(&stencil)
                    );
                }
            }
        }
    }
}

/// 1D patch errors in closed form, from the sums Σⱼ jᵖ over the bonds j = 1..m (ε = m h):
/// `midpoint`, J = 1: Σ 2j² h³ / (2ε³/3) − 1 = (m + 1)(2m + 1)/(2m²) − 1;
/// `partial_volume`, J = 1 (the trapezoid rule: the end bond has half a cell): 1/(2m²);
/// J = 1 − r, either rule (the end bond has J = 0): Σ 2(1 − j/m) j² h³ / (ε³/6) − 1 = −1/m²;
/// J = 1/r, `partial_volume`: J s² = ε s is linear, which the trapezoid rule integrates exactly.
fn closed_form_1d(kernel: Kernel, quadrature: Quadrature, m: f64) -> Option<f64> {
    match (kernel, quadrature) {
        (_, Quadrature::Ac) => Some(0.0),
        (Kernel::Constant, Quadrature::Midpoint) => {
            Some((m + 1.0) * (2.0 * m + 1.0) / (2.0 * m * m) - 1.0)
        }
        (Kernel::Constant, Quadrature::PartialVolume) => Some(0.5 / (m * m)),
        (Kernel::Linear, _) => Some(-1.0 / (m * m)),
        (Kernel::InverseDistance, Quadrature::PartialVolume) => Some(0.0),
        _ => None,
    }
}

#[test]
fn patch_errors_match_their_closed_forms_and_only_ac_is_exact_in_2d() {
    for stencil in patches() {
        let error = stencil.patch_error();
        // Printed for the docs' table (`cargo test --test patch -- --nocapture`).
        println!("{}: {error:+.3e}", label(&stencil));
        let (kernel, quadrature) = (stencil.kernel, stencil.quadrature);
        if stencil.grid.dim == 1 {
            if let Some(exact) = closed_form_1d(kernel, quadrature, stencil.horizon.m as f64) {
                assert!(
                    (error - exact).abs() < 1e-13,
                    "{}: {error} vs {exact}",
                    label(&stencil)
                );
            }
        } else if quadrature != Quadrature::Ac {
            // The lattice's discs and cells never give the second moment exactly (the closest
            // is J = 1, midpoint, m = 6: +1.2e-4).
            assert!(error.abs() > 1e-5, "{}: {error:e}", label(&stencil));
        }
    }
    for quadrature in [Quadrature::Midpoint, Quadrature::PartialVolume] {
        let error = |m: usize| {
            let grid = Grid::new(2, 64);
            let horizon = Horizon::from_m(&grid, m);
            Stencil::new(grid, horizon, Kernel::Gaussian, quadrature, 1.0).patch_error()
        };
        assert!(
            error(20).abs() < 0.2 * error(2).abs(),
            "2D {quadrature:?}: the patch error does not shrink with m: {} at m = 2, {} at m = 20",
            error(2),
            error(20)
        );
    }
}

// ---- A horizon that varies along the bar ([LSSM]): standard and partial-stress forms ----

use solver::case::{Formulation, HorizonProfile};
use solver::discretization::variable_horizon::{horizon_at, VariableHorizonOperator};

const TRANSITION: HorizonProfile = HorizonProfile::Transition {
    left: 0.1,
    right: 0.025,
    start: 0.4,
    end: 0.6,
};
const RAMP: HorizonProfile = HorizonProfile::Linear {
    left: 0.1,
    right: 0.05,
};

/// max |L_h u − k u''| over D's nodes farther than the largest ε from the ends (along x), for
/// u = x^power.
fn ghost_force(op: &VariableHorizonOperator, power: i32) -> f64 {
    let u: Vec<f64> = (0..op.bar_nodes()).map(|k| op.x(k).powi(power)).collect();
    let expected = if power == 2 { 2.0 * DIFFUSIVITY } else { 0.0 };
    let eps_max = op.eps.iter().copied().fold(0.0, f64::max);
    op.apply(&u)
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let x = op.x(op.bar_index(*i));
            x > eps_max && x < 1.0 - eps_max
        })
        .map(|(_, v)| (v - expected).abs())
        .fold(0.0, f64::max)
}

fn operator(
    n: usize,
    profile: HorizonProfile,
    kernel: Kernel,
    formulation: Formulation,
) -> VariableHorizonOperator {
    VariableHorizonOperator::new(1, n, profile, 0.08, kernel, DIFFUSIVITY, formulation)
}

/// L_h 1 = 0, L_h x = 0 and L_h x² = 2k to 1e-10 away from the ends.
fn assert_exact_on_the_patch_tests(op: &VariableHorizonOperator, what: impl std::fmt::Debug) {
    for power in [0, 1, 2] {
        let ghost = ghost_force(op, power);
        assert!(ghost < 1e-10, "{what:?} u = x^{power}: {ghost:e}");
    }
}

#[test]
fn both_formulations_pass_the_patch_tests_with_a_constant_horizon() {
    for kernel in [Kernel::Constant, Kernel::Linear, Kernel::Gaussian] {
        for formulation in [Formulation::Standard, Formulation::PartialStress] {
            let op = operator(200, HorizonProfile::Constant, kernel, formulation);
            assert_exact_on_the_patch_tests(&op, (kernel, formulation));
        }
    }
}

#[test]
fn only_the_partial_stress_passes_them_where_the_horizon_varies() {
    for kernel in [Kernel::Constant, Kernel::Linear] {
        for profile in [RAMP, TRANSITION] {
            let partial = operator(400, profile, kernel, Formulation::PartialStress);
            assert_exact_on_the_patch_tests(&partial, (kernel, profile));
            let standard = operator(400, profile, kernel, Formulation::Standard);
            assert!(ghost_force(&standard, 0) < 1e-10, "L_h 1 = 0 in any form");
            assert!(
                ghost_force(&standard, 1) > 1e-3,
                "{kernel:?} {profile:?}: no ghost force?"
            );
        }
    }
}

/// The ghost force of the standard form: where ε'' ≠ 0 (the transition) it stays as h → 0 (the
/// seed: proportional to ε''); on a linear ramp (ε'' = 0) only the discrete ball's steps leave
/// one, and it shrinks with h.
#[test]
fn the_standard_forms_ghost_force_follows_the_second_derivative_of_the_horizon() {
    let ghost = |n, profile| {
        ghost_force(
            &operator(n, profile, Kernel::Linear, Formulation::Standard),
            1,
        )
    };
    let (ramp_coarse, ramp_fine) = (ghost(200, RAMP), ghost(800, RAMP));
    assert!(
        ramp_fine < 0.5 * ramp_coarse,
        "ramp: {ramp_coarse:e} → {ramp_fine:e}"
    );
    let (step_coarse, step_fine) = (ghost(200, TRANSITION), ghost(800, TRANSITION));
    assert!(
        step_fine > 0.5 * step_coarse && step_fine > 10.0 * ramp_fine,
        "transition: {step_coarse:e} → {step_fine:e}"
    );
}

/// The standard form's rows against its definition, node by node:
/// Σ_y ½ (w_x(y − x) + w_y(x − y)) (u_y − u_x) with w_x(ξ) = 2k J(|ξ|/ε(x)) / Σ_ξ' J ξ'².
#[test]
fn the_standard_form_is_the_pairwise_sum_of_its_definition() {
    let n = 60;
    let op = operator(n, TRANSITION, Kernel::Linear, Formulation::Standard);
    let h = 1.0 / n as f64;
    let weight = |k: usize, offset: i64| -> f64 {
        let eps = op.eps[k];
        let reach = (eps / h * (1.0 + 1e-12)).floor() as i64;
        if offset == 0 || offset.abs() > reach {
            return 0.0;
        }
        let j = |o: i64| Kernel::Linear.influence(((o.abs() as f64) * h / eps).min(1.0));
        let moment: f64 = (-reach..=reach)
            .map(|o| j(o) * (o as f64 * h).powi(2))
            .sum();
        2.0 * DIFFUSIVITY * j(offset) / moment
    };
    let u: Vec<f64> = (0..op.bar_nodes()).map(|k| (3.0 * op.x(k)).sin()).collect();
    let applied = op.apply(&u);
    for (i, &got) in applied.iter().enumerate().take(n) {
        let k = op.collar + i;
        let mut expected = 0.0;
        for l in 0..op.bar_nodes() {
            let offset = l as i64 - k as i64;
            let w = 0.5 * (weight(k, offset) + weight(l, -offset));
            expected += w * (u[l] - u[k]);
        }
        assert!(
            (got - expected).abs() <= 1e-12 * expected.abs().max(1.0),
            "node {i}: {got} vs {expected}"
        );
    }
    assert_eq!(
        horizon_at(TRANSITION, 0.0, -1.0),
        0.1,
        "the collar keeps the end's ε"
    );
}

/// A horizon that shrinks where nonlocality is not needed cuts the bonds, and its smallest ε
/// sets a smaller stable step (the seed's performance slide).
#[test]
fn a_varying_horizon_has_fewer_bonds_and_a_smaller_stable_step() {
    let constant = VariableHorizonOperator::new(
        1,
        400,
        HorizonProfile::Constant,
        0.1,
        Kernel::Constant,
        DIFFUSIVITY,
        Formulation::Standard,
    );
    let varying = operator(400, TRANSITION, Kernel::Constant, Formulation::Standard);
    assert!(varying.bonds < constant.bonds);
    assert!(varying.lambda_bound() > 4.0 * constant.lambda_bound());
}

/// The spectrum of the operator a time-dependent run would step (zero collar). The standard form
/// is symmetric: real, negative eigenvalues for every profile, and Gershgorin's step is safe. The
/// partial stress is not: with a constant horizon its eigenvalues are still real and ≤ 0, but
/// where the horizon varies some have Re λ > 0 at every n, so u' = L_h u grows and no
/// forward-Euler step is stable (measured max Re λ: +0.006 on the ramp, +8.6 on the transition).
#[test]
fn only_the_standard_form_gives_a_stable_heat_equation_where_the_horizon_varies() {
    for n in [100, 200] {
        for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
            let standard = operator(n, profile, Kernel::Linear, Formulation::Standard);
            let s = spectrum_of(&standard);
            let safe = 2.0 / standard.lambda_bound();
            assert!(s.max_real < 0.0, "{profile:?}: {s:?}");
            assert!(s.max_imaginary < 1e-8 * s.max_abs, "{profile:?}: {s:?}");
            assert!(s.dt_forward_euler.unwrap() >= safe, "{profile:?}: {s:?}");

            let partial = spectrum_of(&operator(
                n,
                profile,
                Kernel::Linear,
                Formulation::PartialStress,
            ));
            if profile == HorizonProfile::Constant {
                assert!(partial.max_real <= 1e-8 * partial.max_abs, "{partial:?}");
                assert!(
                    partial.max_imaginary < 1e-8 * partial.max_abs,
                    "{partial:?}"
                );
            } else {
                assert!(partial.max_real > 1e-3, "{profile:?}: {partial:?}");
                assert_eq!(partial.dt_forward_euler, None);
            }
        }
    }
}

/// The x-centred form: each node on its own (symmetric) ball, so the patch tests pass to
/// round-off on every profile, and its eigenvalues keep Re λ ≤ 0 (Gershgorin: rows summing to
/// zero, off-diagonal entries ≥ 0) where the partial stress's do not.
#[test]
fn the_x_centred_form_passes_the_patch_tests_and_keeps_its_spectrum_in_the_left_half_plane() {
    for kernel in [Kernel::Constant, Kernel::Linear, Kernel::Gaussian] {
        for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
            let op = operator(400, profile, kernel, Formulation::XCentred);
            assert_exact_on_the_patch_tests(&op, (kernel, profile));
        }
    }
    for n in [100, 200] {
        for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
            let op = operator(n, profile, Kernel::Linear, Formulation::XCentred);
            let s = spectrum_of(&op);
            assert!(s.max_real <= 1e-12 * s.max_abs, "{profile:?}: {s:?}");
            // Gershgorin's forward-Euler step is safe for it.
            assert!(
                s.dt_forward_euler.unwrap() >= 2.0 / op.lambda_bound() * (1.0 - 1e-12),
                "{profile:?}: {s:?}"
            );
        }
    }
}

fn spectrum_of(op: &VariableHorizonOperator) -> solver::output::record::Spectrum {
    solver::methods::patch_test::spectrum(op, DIFFUSIVITY).expect("a spectrum within the limits")
}

fn operator_2d(
    n: usize,
    profile: HorizonProfile,
    kernel: Kernel,
    formulation: Formulation,
) -> VariableHorizonOperator {
    VariableHorizonOperator::new(2, n, profile, 0.08, kernel, DIFFUSIVITY, formulation)
}

/// In 2D (ε = ε(x)), the x-centred and partial-stress forms pass the patch tests to round-off on
/// every profile; the standard form with a constant horizon too, and with a varying one it
/// shows a ghost force.
#[test]
fn every_formulation_meets_its_patch_tests_in_2d() {
    for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
        for formulation in [
            Formulation::XCentred,
            Formulation::PartialStress,
            Formulation::Standard,
        ] {
            let op = operator_2d(48, profile, Kernel::Linear, formulation);
            assert_eq!(op.apply(&vec![0.0; op.bar_nodes()]).len(), 48 * 48);
            for power in [0, 1, 2] {
                let ghost = ghost_force(&op, power);
                let exact = formulation != Formulation::Standard
                    || profile == HorizonProfile::Constant
                    || power == 0;
                match exact {
                    true => assert!(
                        ghost < 1e-10,
                        "{formulation:?} {profile:?} x^{power}: {ghost:e}"
                    ),
                    false if profile == TRANSITION => assert!(
                        ghost > 1e-3,
                        "{formulation:?} {profile:?} x^{power}: a ghost force of only {ghost:e}"
                    ),
                    false => {}
                }
            }
        }
    }
}

/// On a field constant in y, the 2D operator is a 1D one: each row equals a literal 1D sum
/// whose weights are the 2D ones summed over ξ₂, W_x(ξ₁) = Σ_ξ₂ w_x(ξ₁, ξ₂), computed here from
/// the definitions (x-centred: Σ W_x(ξ₁) (u(x + ξ₁) − u(x)); standard: the same with
/// ½ (W_x(ξ₁) + W_y(−ξ₁))), on every row of nodes alike.
#[test]
fn the_2d_operator_on_a_field_constant_in_y_is_the_1d_sum_of_its_projected_weights() {
    let (n, kernel) = (48usize, Kernel::Linear);
    let h = 1.0 / n as f64;
    // W_x(o₁) for the node at x: the 2D weights of the ball around x summed over o₂.
    let projected = |x: f64, o1: i64| -> f64 {
        let eps = horizon_at(TRANSITION, 0.08, x);
        let radius = eps / h * (1.0 + 1e-12);
        let reach = radius.floor() as i64;
        let ball = || {
            (-reach..=reach)
                .flat_map(move |a| (-reach..=reach).map(move |b| (a, b)))
                .filter(move |&(a, b)| {
                    (a, b) != (0, 0) && ((a * a + b * b) as f64) <= radius * radius
                })
                .map(move |(a, b)| {
                    (
                        a,
                        b,
                        kernel.influence((((a * a + b * b) as f64).sqrt() * h / eps).min(1.0)),
                    )
                })
        };
        let second: f64 = ball().map(|(a, _, j)| j * (a as f64 * h).powi(2)).sum();
        ball()
            .filter(|&(a, _, _)| a == o1)
            .map(|(_, _, j)| 2.0 * DIFFUSIVITY * j / second)
            .sum()
    };
    let u = |x: f64| (3.0 * x).sin() + x * x;
    for formulation in [Formulation::XCentred, Formulation::Standard] {
        let op = operator_2d(n, TRANSITION, kernel, formulation);
        let field: Vec<f64> = (0..op.bar_nodes()).map(|k| u(op.x(k))).collect();
        let l_u = op.apply(&field);
        let reach = (0.1 / h * (1.0 + 1e-12)).floor() as i64;
        for (i, value) in l_u.iter().enumerate() {
            let x = (((i % n) as f64) + 0.5) * h;
            let literal: f64 = (-reach..=reach)
                .filter(|&o| o != 0)
                .map(|o| {
                    let y = x + o as f64 * h;
                    let w = match formulation {
                        Formulation::XCentred => projected(x, o),
                        _ => 0.5 * (projected(x, o) + projected(y, -o)),
                    };
                    w * (u(y) - u(x))
                })
                .sum();
            assert!(
                (value - literal).abs() <= 1e-11 * literal.abs().max(1.0),
                "{formulation:?}, node {i}: {value} against the 1D sum {literal}"
            );
        }
    }
}

/// The sparse eigensolver (shift-invert and plain Krylov–Schur) finds the dense spectrum's
/// rightmost real part and largest |λ| for every formulation and profile (1D, n = 300),
/// including the partial stress's complex pair with Re λ > 0.
#[test]
fn the_sparse_spectrum_finds_the_dense_ones_ends() {
    for formulation in [
        Formulation::Standard,
        Formulation::XCentred,
        Formulation::PartialStress,
    ] {
        for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
            let op = operator(300, profile, Kernel::Linear, formulation);
            let dense = spectrum_of(&op);
            let rows: Vec<_> = op.rows_with_zero_collar().collect();
            let sparse = solver::linalg::spectrum::ends(&rows, DIFFUSIVITY).unwrap();
            let max_real = sparse
                .iter()
                .map(|z| z.re)
                .fold(f64::NEG_INFINITY, f64::max);
            let max_abs = sparse
                .iter()
                .map(|z| (z.re * z.re + z.im * z.im).sqrt())
                .fold(0.0, f64::max);
            let scale = dense.max_abs;
            assert!(
                (max_real - dense.max_real).abs() <= 1e-8 * scale,
                "{formulation:?} {profile:?}: rightmost {max_real} sparse, {} dense",
                dense.max_real
            );
            assert!(
                (max_abs - dense.max_abs).abs() <= 1e-8 * scale,
                "{formulation:?} {profile:?}: largest {max_abs} sparse, {} dense",
                dense.max_abs
            );
        }
    }
}

/// In 2D (by the sparse eigensolver) as in 1D (dense), the x-centred and the standard (the
/// symmetrised, dual-horizon) forms keep every eigenvalue in the closed left half-plane on every
/// profile; the partial stress does not on the transition.
#[test]
fn the_x_centred_and_standard_forms_are_stable_on_every_profile_in_1d_and_2d() {
    for profile in [HorizonProfile::Constant, RAMP, TRANSITION] {
        for (dim, n) in [(1, 400), (2, 48)] {
            for formulation in [
                Formulation::XCentred,
                Formulation::Standard,
                Formulation::PartialStress,
            ] {
                // The partial stress is asserted on only where it is certainly unstable.
                if formulation == Formulation::PartialStress && profile != TRANSITION {
                    continue;
                }
                let op = VariableHorizonOperator::new(
                    dim,
                    n,
                    profile,
                    0.08,
                    Kernel::Linear,
                    DIFFUSIVITY,
                    formulation,
                );
                let s = spectrum_of(&op);
                assert_eq!(s.computed.is_some(), dim == 2, "dense in 1D, sparse in 2D");
                match formulation {
                    Formulation::PartialStress => {
                        assert!(s.max_real > 1.0, "{dim}D {profile:?}: {s:?}")
                    }
                    _ => assert!(
                        s.max_real <= 1e-12 * s.max_abs,
                        "{dim}D {formulation:?} {profile:?}: {s:?}"
                    ),
                }
            }
        }
    }
}
