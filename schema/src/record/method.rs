//! The outcome groups of two methods of \[LSSM]: a variable horizon's patch test (with the
//! spectrum of its operator) and a coupled local–nonlocal solve.

use serde::{Deserialize, Serialize};

/// A patch test (\[LSSM]): L_h of a variable horizon applied to a prescribed field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatchTest {
    /// max |L_h u − k u''| over D's nodes farther than the largest ε from both ends (the seed
    /// leaves the nodes near the ends out): zero to round-off when the formulation passes.
    pub ghost_force: f64,
    /// The same over every node of D.
    pub ghost_force_all: f64,
    /// k u'', what L_h u should be (0 for a linear field, 2k for u = x²).
    pub expected: f64,
    /// The smallest ε over D (`eps` of the record is the largest).
    pub eps_min: f64,
    /// D's nodes along x (in 2D, the middle row's), L_h u at them, and ε(x) on D's columns.
    pub x: Vec<f64>,
    pub l_u: Vec<f64>,
    pub eps_x: Vec<f64>,
    /// The spectrum of L_h on D with u = 0 on the collar, the operator a time-dependent run
    /// steps: every eigenvalue (dense) up to `SPECTRUM_MAX_NODES` nodes, the ends of the
    /// spectrum (sparse) up to `SPARSE_SPECTRUM_MAX_NODES`, absent beyond or when the sparse
    /// eigensolver converged none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectrum: Option<Spectrum>,
}

/// Where the eigenvalues λ of a (possibly non-symmetric) L_h lie, and what that means for time
/// stepping: with some Re λ > 0, u' = L_h u grows like e^{t·max Re λ} and no step is stable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Spectrum {
    pub max_real: f64,
    pub max_imaginary: f64,
    pub max_abs: f64,
    /// The largest stable forward-Euler step, min over λ of −2 Re λ/|λ|² (|1 + dt λ| ≤ 1 for every
    /// λ); absent when some Re λ > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt_forward_euler: Option<f64>,
    /// How many eigenvalues the sparse eigensolver converged (near its shifts and the largest;
    /// one may be counted twice); absent when every eigenvalue was computed (dense). Then `max_imaginary` and `dt_forward_euler`
    /// are over the computed ones.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub computed: Option<usize>,
}

/// A coupled local–nonlocal solve (\[LSSM]): the errors of both models against the exact
/// solution; for the optimization-based coupling also the optimal controls and the optimality
/// system's residual and conditioning (absent for the seamless one, which has none).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Coupling {
    /// e(u_n) = ‖u_n − u‖ in L²(Ω_n) and e(u_l) = ‖u_l − u‖ in L²(Ω_l), the seed's columns.
    pub error_nonlocal: f64,
    pub error_local: f64,
    /// ‖u_n − u_l‖ in L²(Ω_b) at the optimum, √(2J).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mismatch: Option<f64>,
    /// ‖∇J(θ)‖/‖∇J(0)‖: the first-order condition's residual at the controls returned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gradient: Option<f64>,
    /// cond₂ of the reduced Hessian solved, ΨᵀWΨ plus the smoothness term that decides the
    /// directions J cannot resolve (see `methods::coupled`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hessian_condition: Option<f64>,
    /// The directions of the controls J resolves (σᵢ > ε_mach^¼ σ₁), of `control_nodes` + 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controls_resolved: Option<usize>,
    /// The nodes of the nonlocal control collar [1, 1 + ε], and θ_n there.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub control_nodes: Vec<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub controls_nonlocal: Vec<f64>,
    /// θ_l, u_l at Γ_c.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control_local: Option<f64>,
    /// max |θ − u| over every control: how far the controls are from the exact solution's values.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub control_error: Option<f64>,
    /// Nodes of each model's mesh; for the seamless coupling, those of its one lattice in
    /// Ω_n and in Ω_l (the overlap's in both).
    pub nonlocal_nodes: usize,
    pub local_nodes: usize,
    /// Ω_l = (Γ_c, Γ_i).
    pub local_domain: [f64; 2],
}
