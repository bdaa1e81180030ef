//! The exact ends of L_h's spectrum and the explicit integrators' exact stability limits: the
//! independent reference of the stability measurements (shared with the end-to-end search test
//! of the workspace, which includes this file by path).

use solver::case::{Backend, Integrator};
use solver::discretization::stencil::Stencil;
use solver::operator::{plan, LinearOperator};

/// The exact ends (λ_min, λ_max) of L_h: the dense matrix of the literal Algorithm 1 (the
/// neighbour list, one application per unit vector), by faer's dense symmetric eigensolver.
pub fn dense_ends(stencil: &Stencil) -> (f64, f64) {
    let operator = plan(Backend::NeighbourList, stencil);
    let n = stencil.grid.nodes();
    let mut dense = faer::Mat::<f64>::zeros(n, n);
    let (mut unit, mut column) = (vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        unit[j] = 1.0;
        operator.apply_once(&unit, &mut column);
        unit[j] = 0.0;
        for (i, &value) in column.iter().enumerate() {
            dense[(i, j)] = value;
        }
    }
    for i in 0..n {
        for j in 0..i {
            let (a, b) = (dense[(i, j)], dense[(j, i)]);
            assert!(
                (a - b).abs() <= 1e-12 * a.abs().max(b.abs()),
                "L_h is not symmetric"
            );
        }
    }
    let eigen = dense.self_adjoint_eigen(faer::Side::Lower).unwrap();
    let values = eigen.S().column_vector();
    (values[0], values[n - 1])
}

/// |R(z)| of the explicit integrators, written out here (Taylor's sum to the order).
pub fn growth_of(integrator: Integrator, z: f64) -> f64 {
    let terms = match integrator {
        Integrator::ForwardEuler => 1,
        Integrator::Heun => 2,
        _ => 4,
    };
    let (mut sum, mut term) = (1.0, 1.0);
    for j in 1..=terms {
        term *= z / j as f64;
        sum += term;
    }
    sum.abs()
}

/// Where |R| = 1 on z < 0: x of the real stability interval [−x, 0], by bisection.
pub fn real_stability_limit(integrator: Integrator) -> f64 {
    let (mut stable, mut unstable) = (-1.5, -3.5);
    for _ in 0..200 {
        let middle = 0.5 * (stable + unstable);
        match growth_of(integrator, middle) > 1.0 {
            true => unstable = middle,
            false => stable = middle,
        }
    }
    -stable
}
