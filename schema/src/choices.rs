//! The choices a case makes: one enum per field with named values, serialised in snake_case.
//!
//! They are plain data here, shared by the solver and the orchestrator; what a choice means
//! numerically lives with the solver's numerics (`impl Kernel` in `discretization::influence`,
//! `impl Backend` in `operator`, …).

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The nonlocal heat equation of \[JD], in time by the case's `integrator` (forward Euler,
    /// eq. 2.1, by default).
    #[default]
    Nonlocal,
    /// Local diffusion (\[HPCSE]): central differences, forward Euler.
    FdExplicit,
    /// Local diffusion (\[HPCSE]): Peaceman–Rachford ADI with the Thomas algorithm.
    Adi,
    /// Local diffusion (\[HPCSE]): particle strength exchange, forward Euler.
    Pse,
    /// Steady nonlocal diffusion (\[XGDF]): unpreconditioned conjugate gradients on A u = f.
    SteadyCg,
    /// Steady nonlocal diffusion (\[XGDF]): FETI with p × p subdomains, projected CG on the
    /// Lagrange multipliers.
    Feti,
    /// \[LSSM]'s patch tests: L_h of a variable horizon (`horizon_profile`, `formulation`)
    /// applied to a prescribed linear or quadratic field (`patch`), 1D; no time.
    PatchTest,
    /// \[LSSM]'s optimization-based local–nonlocal coupling in 1D (D'Elia, Perego, Bochev): a
    /// steady nonlocal problem on Ω_n = (0, 1) and a Poisson problem on `local_domain`, their
    /// mismatch on the overlap minimised over the interface controls; exact field `patch`.
    #[serde(rename = "coupled_1d")]
    Coupled1d,
}

impl Method {
    /// h, the spacing of the method's nodes: 1/n on D = [0, 1]^d (the nonlocal and steady
    /// methods, nodes at cell centres), L/(n + 1) for the grid methods' interior nodes of
    /// (−L/2, L/2)^d, L/n for PSE's particles. Study files' `h` is this value.
    pub fn grid_spacing(self, n: usize, length: f64) -> f64 {
        match self {
            Method::FdExplicit | Method::Adi => length / (n + 1) as f64,
            Method::Pse => length / n as f64,
            Method::Nonlocal
            | Method::SteadyCg
            | Method::Feti
            | Method::PatchTest
            | Method::Coupled1d => 1.0 / n as f64,
        }
    }

    /// Does the method solve the local equation ∂c/∂t = D∇²c on (−L/2, L/2)^d?
    pub fn is_local(self) -> bool {
        matches!(self, Method::FdExplicit | Method::Adi | Method::Pse)
    }

    /// Does the method solve the steady problem −L u = f of \[XGDF] (no time)?
    pub fn is_steady(self) -> bool {
        matches!(self, Method::SteadyCg | Method::Feti)
    }
}

/// The time integrator of the nonlocal method, for u' = L_h u + b(t).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// \[JD]'s eq. 2.1: order 1, stable for dt ≤ 2/λ_max.
    #[default]
    ForwardEuler,
    /// Heun's method (explicit trapezoidal RK2): order 2, stable for dt ≤ 2/λ_max.
    Heun,
    /// The classical Runge–Kutta method: order 4, stable for dt ≤ 2.785/λ_max.
    Rk4,
    /// The θ-scheme with θ = 1: order 1, unconditionally stable (L-stable).
    BackwardEuler,
    /// The θ-scheme with θ = ½: order 2, unconditionally stable (A-stable).
    CrankNicolson,
}

impl Integrator {
    pub fn is_forward_euler(&self) -> bool {
        *self == Integrator::ForwardEuler
    }

    /// Does a step solve a linear system?
    pub fn is_implicit(self) -> bool {
        matches!(self, Integrator::BackwardEuler | Integrator::CrankNicolson)
    }

    /// The order of accuracy in dt.
    pub fn order(self) -> u32 {
        match self {
            Integrator::ForwardEuler | Integrator::BackwardEuler => 1,
            Integrator::Heun | Integrator::CrankNicolson => 2,
            Integrator::Rk4 => 4,
        }
    }
}

/// The preconditioner of FETI's projected CG (\[XGDF], section 3.1.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FetiPreconditioner {
    /// None: Q = I.
    None,
    /// The Dirichlet preconditioner of eq. 33, interior solves by sparse Cholesky.
    #[default]
    Dirichlet,
    /// The Dirichlet preconditioner with 5 CG iterations for the interior solves.
    DirichletCg,
    /// The Dirichlet preconditioner with multiplicity scaling (Rixen & Farhat, IJNME 44, 1999):
    /// each interface value weighted by 1/(subdomains sharing its node) on the way in and out.
    /// Not in \[XGDF]; about half the iterations of `dirichlet`.
    DirichletScaled,
}

/// The influence function J of eq. 1.1, as a function of r = |y − x| / ε.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kernel {
    /// J = 1.
    Constant,
    /// J = 1 − r.
    Linear,
    /// J = exp(−r²), cut at r = 1.
    Gaussian,
    /// J = 1/r: singular at the origin, integrable in the moments used by c (\[XGDF]'s kernel).
    InverseDistance,
}

impl Kernel {
    pub const ALL: [Kernel; 4] = [
        Kernel::Constant,
        Kernel::Linear,
        Kernel::Gaussian,
        Kernel::InverseDistance,
    ];
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quadrature {
    /// Full cell volume for every node in the closed ball (\[JD]).
    #[default]
    Midpoint,
    /// The part of each cell inside the ball.
    PartialVolume,
    /// Partial volumes rescaled to be exact on quadratics (asymptotically compatible).
    Ac,
}

impl Quadrature {
    pub const ALL: [Quadrature; 3] = [
        Quadrature::Midpoint,
        Quadrature::PartialVolume,
        Quadrature::Ac,
    ];

    pub fn is_midpoint(&self) -> bool {
        *self == Quadrature::Midpoint
    }
}

/// Which implementation of L_h a case runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// The stencil or the FFT, whichever the calibrated cost model (`cost`) says is faster.
    #[default]
    Auto,
    /// Precomputed weights per lattice offset, register-blocked (uniform grids): O(N m^d).
    Stencil,
    /// Zero-padded FFT convolution with the weights (uniform grids): O(N log N) for any m.
    Fft,
    /// Algorithm 1 of \[JD] literally: a neighbour list per node, distances and J recomputed
    /// for every bond at every application. The oracle the fast backends are tested against.
    NeighbourList,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Partition {
    /// px × py rectangles of the grid.
    #[default]
    Block,
    /// A METIS partition of the grid graph: irregular subdomains, like \[JD]'s Figure 3.
    Graph,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Problem {
    /// w = cos(2πt) sin(2πx₁)[sin(2πx₂)], exact solution known (Appendix A).
    #[default]
    Manufactured,
    /// u₀ = exp(−|x − ½|²/(2·0.1²)), no source, no exact solution: for demonstrations.
    Bump,
    /// Local methods: c = Π_a cos(π x_a / L) on (−L/2, L/2)^d, decaying as exp(−dπ²Dt/L²).
    Eigenmode,
    /// Local methods, \[HPCSE]'s setup: c = 1 where every |x_a| < L/4, else 0.
    Square,
}

/// What the collar D_c holds: the data of the volume constraint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Collar {
    /// u = 0 (eq. 2.2). Then even the continuum nonlocal solution differs from the local one by
    /// O(ε) in a layer of width ε along ∂D.
    #[default]
    Zero,
    /// The manufactured solution's smooth continuation cos(2πt) sin(2πx₁)[sin(2πx₂)], which is
    /// odd about ∂D: the local solution's own values, so that no boundary layer forms and the
    /// error against the local solution is the interior consistency error alone.
    Exact,
}

impl Collar {
    pub fn is_zero(&self) -> bool {
        *self == Collar::Zero
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceMode {
    Discrete,
    Continuum,
    Local,
    None,
}

impl Problem {
    /// Does the problem belong to the local methods' domain (−L/2, L/2)^d?
    pub fn is_local(self) -> bool {
        matches!(self, Problem::Eigenmode | Problem::Square)
    }

    pub fn default_source(self) -> SourceMode {
        match self {
            Problem::Manufactured => SourceMode::Continuum,
            Problem::Bump | Problem::Eigenmode | Problem::Square => SourceMode::None,
        }
    }
}

/// How the horizon varies along D = [0, 1] (\[LSSM]); outside D it keeps its value at the
/// nearer end.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum HorizonProfile {
    /// The case's `eps` (or m·h) everywhere.
    Constant,
    /// ε(x) = left + (right − left) x.
    Linear { left: f64, right: f64 },
    /// ε = left up to `start`, right from `end`, and a C¹ cubic step between.
    Transition {
        left: f64,
        right: f64,
        start: f64,
        end: f64,
    },
}

/// How `coupled_1d` couples its local and nonlocal models.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CouplingKind {
    /// D'Elia, Perego and Bochev's: two models on overlapping domains, their interface values
    /// the controls of a least-squares mismatch on the overlap (\[LSSM]).
    #[default]
    Optimization,
    /// Tao, Tian and Du's heterogeneous localization: one model whose horizon shrinks to one
    /// cell over the overlap, local beyond it.
    Seamless,
}

/// The Krylov method of the implicit integrators' solves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Krylov {
    /// Conjugate gradients: needs a symmetric L_h.
    Cg,
    /// BiCGStab: any L_h, at about twice CG's work per iteration.
    Bicgstab,
}

impl Krylov {
    /// The method L_h's symmetry allows when a case names none: CG needs a symmetric operator
    /// and is never handed another.
    pub fn for_symmetry(symmetric: bool) -> Krylov {
        match symmetric {
            true => Krylov::Cg,
            false => Krylov::Bicgstab,
        }
    }
}

/// How a variable horizon enters the nonlocal operator (\[LSSM]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Formulation {
    /// Pairwise bonds, each node's state on its own horizon: conservative, ghost forces where ε
    /// varies.
    #[default]
    Standard,
    /// The divergence of the peridynamic partial stress: passes the patch tests for any ε(x).
    PartialStress,
    /// Each node on its own horizon, unsymmetrised, L u(x) = Σ_ξ w_x(ξ) (u(x + ξ) − u(x)): passes
    /// the patch tests for any ε(x) and keeps Re λ ≤ 0 (its rows sum to zero, its off-diagonal
    /// entries are ≥ 0), but is not symmetric and does not conserve Σ u.
    XCentred,
}

impl Formulation {
    /// Whether L_h is symmetric (CG needs it; the implicit integrators solve the others by
    /// BiCGStab).
    pub fn is_symmetric(self) -> bool {
        self == Formulation::Standard
    }
}

/// The field a patch test prescribes, or the exact solution of a coupled problem.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PatchField {
    /// u = x: L u = 0.
    #[default]
    Linear,
    /// u = x²: L u = 2k.
    Quadratic,
    /// u = x² − x⁴ (`coupled_1d` only, \[LSSM]'s Example 2): L u = 2k − 12k x² − 2k ε² M₄/M₂.
    Quartic,
}
