//! A seamless local–nonlocal coupling in the sense of Tao, Tian and Du (nonlocal models with
//! heterogeneous localization): one model on the whole body Ω = (0, b), whose horizon shrinks
//! from ε on the nonlocal part to one cell over the overlap (a, 1), so that it becomes local
//! without an interface, controls or an optimization. It solves \[LSSM]'s Examples 1 and 2 on
//! the layout of `coupled_1d` (Ω_n = (0, 1), Ω_l = `local_domain` = (a, b)), for comparison with
//! the optimization-based coupling.
//!
//! **The model.** δ(x) = max(ε, h) on (0, a), a C¹ step (`horizon_profile`'s transition) down
//! to h over (a, 1), and h on (1, b). The operator is the x-centred form of a varying horizon
//! (`discretization::variable_horizon`) on cell-centred nodes (i + ½) h: its weights are
//! normalised on the lattice (Σ w ξ² = 2k), so where δ = h it is exactly the local three-point
//! Laplacian k (u_{i−1} − 2u_i + u_{i+1}) / h², and it passes the patch tests for any δ(x), so
//! the transition adds no ghost force. Its continuum operator at horizon δ(x) gives the source
//! in closed form, f(x) = −L_{δ(x)} u(x) (for u = x² − x⁴: −(2k − 12k x² − 2k δ² M₄/M₂)), so
//! u is the exact solution of the model and what remains is the discretization's error.
//! u is the data on both collars. The system is not symmetric: a sparse LU (faer) solves it.
//!
//! Like every lattice scheme the horizon must hold a node: where ε < h (the seed's coarsest
//! grids) the whole body is local.
//!
//! **Errors** are the seed's: ‖u_h − u‖ in L²(Ω_n) and in L²(Ω_l), u_h the piecewise-linear
//! interpolant of the nodal values (the collars' nodes close it at both ends).

use crate::case::{horizon_length, readable, CaseError, Formulation, HorizonProfile, ValidCase};
use crate::discretization::finite_element::Mesh;
use crate::discretization::grid::Lattice;
use crate::discretization::variable_horizon::{horizon_at, VariableHorizonOperator};
use crate::output::outcome::Outcome;
use crate::output::record::{self, Coupling, Resolved};
use crate::problem::polynomial::PolynomialField;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use std::time::Instant;

/// The length b of Ω = (0, b) must be a whole number of cells h = 1/n: how far from one counts
/// as one.
const WHOLE_CELLS: f64 = 1e-9;

/// The cells of Ω = (0, b), b·n, when it is a whole number.
pub fn cells(n: usize, b: f64) -> Result<usize, CaseError> {
    let cells = b * n as f64;
    if (cells - cells.round()).abs() > WHOLE_CELLS * cells.max(1.0) {
        return Err(CaseError::new(
            "local_domain",
            format!(
                "the seamless coupling puts one lattice of h = 1/n on (0, b): b = {} holds {} cells of h = 1/{n}, not a whole number; choose b or n so that b·n is whole (the default b = 1.75 with n a multiple of 4)",
                readable(b),
                readable(cells)
            ),
        ));
    }
    Ok(cells.round() as usize)
}

/// The horizon δ(x) on Ω = (0, b), as a profile over the unit interval x/b.
fn profile(eps: f64, h: f64, a: f64, b: f64) -> HorizonProfile {
    HorizonProfile::Transition {
        left: eps.max(h) / b,
        right: h / b,
        start: a / b,
        end: 1.0 / b,
    }
}

/// Solves the seamless model and measures it against the exact solution.
///
/// Long because it is the model's one sequence (mesh, assembly, solve, measurement against the
/// exact solution), each step using the ones before.
pub fn run(case: &ValidCase) -> Result<Outcome, CaseError> {
    let started = Instant::now();
    let field = case.patch();
    let (diffusivity, kernel, eps) = (case.diffusivity, case.kernel, horizon_length(case));
    let [a, b] = case.local_domain();
    let h = 1.0 / case.n as f64;
    let cells = cells(case.n, b)?;
    let profile = profile(eps, h, a, b);
    // Built on the unit interval x/b: there d²/dx² = b⁻² d²/dξ², so k/b² gives L in x.
    let operator = VariableHorizonOperator::new(
        1,
        cells,
        profile,
        eps,
        kernel,
        diffusivity / (b * b),
        Formulation::XCentred,
    );
    let x_of = |k: usize| operator.x(k) * b;
    let delta = |x: f64| horizon_at(profile, eps, x / b) * b;
    let bar = operator.bar_nodes();
    let inside = operator.collar..operator.collar + cells;
    // L u = L_δ u on D: the collar's data moved to the right-hand side.
    let data: Vec<f64> = (0..bar)
        .map(|l| match inside.contains(&l) {
            true => 0.0,
            false => field.value(x_of(l)),
        })
        .collect();
    let from_data = operator.apply(&data);
    let rhs: Vec<f64> = inside
        .clone()
        .zip(&from_data)
        .map(|(l, g)| {
            let x = x_of(l);
            field.nonlocal_operator(x, diffusivity, kernel, delta(x)) - g
        })
        .collect();
    let triplets: Vec<Triplet<usize, usize, f64>> = operator
        .rows_with_zero_collar()
        .enumerate()
        .flat_map(|(i, row)| row.into_iter().map(move |(j, a)| Triplet::new(i, j, a)))
        .collect();
    let matrix = SparseColMat::try_new_from_triplets(cells, cells, &triplets)
        .expect("the rows' indices lie in D");
    let lu = matrix.sp_lu().map_err(|e| {
        CaseError::new(
            "n",
            format!("the seamless model's matrix could not be factored ({e:?})"),
        )
    })?;
    let setup_s = started.elapsed().as_secs_f64();
    let solving = crate::output::usage::Solving::starts();
    let solution = lu.solve(faer::Col::from_fn(cells, |i| rhs[i]));
    let solve_s = solving.ends();

    // Nodal values on the bar, the collars' data included, as a P1 function.
    let mesh = Mesh {
        nodes: (0..bar).map(x_of).collect(),
    };
    let u_h: Vec<f64> = (0..bar)
        .map(|k| match inside.contains(&k) {
            true => solution[k - operator.collar],
            false => data[k],
        })
        .collect();
    let exact = |x: f64| field.value(x);
    let count = |lo: f64, hi: f64| (0..bar).filter(|&k| (lo..=hi).contains(&x_of(k))).count();
    let coupling = Coupling {
        error_nonlocal: mesh.l2_distance(&u_h, 0.0, 1.0, exact),
        error_local: mesh.l2_distance(&u_h, a, b, exact),
        mismatch: None,
        gradient: None,
        hessian_condition: None,
        controls_resolved: None,
        control_nodes: Vec::new(),
        controls_nonlocal: Vec::new(),
        control_local: None,
        control_error: None,
        nonlocal_nodes: count(0.0, 1.0),
        local_nodes: count(a, b),
        local_domain: [a, b],
    };
    let resolved = Resolved {
        h,
        eps: Some(eps.max(h)),
        nodes: cells,
        bonds: operator.bonds,
        ..Resolved::default()
    };
    let record = record::coupled(case, resolved, (setup_s, solve_s), coupling);
    Ok(Outcome {
        record,
        field: solution.iter().copied().collect(),
        lattice: Lattice {
            dim: 1,
            n: cells,
            origin: 0.5 * h,
            spacing: h,
        },
        frames: Vec::new(),
    })
}
