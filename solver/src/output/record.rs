//! The record: one JSON object per run, what the orchestrator stores and tabulates.

use crate::case::{Backend, Case, Collar, Integrator, Partition, Quadrature};
use crate::discretization::stencil::Stencil;
use crate::output::diagnostics::{Histogram, MassSeries};
use crate::output::field::FieldSnapshot;
use serde::{Deserialize, Serialize};

pub use schema::record::Status;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Record {
    pub case: Case,
    pub status: Status,
    pub message: String,
    #[serde(flatten)]
    pub resolved: Resolved,
    /// Steps completed (fewer than `steps` when diverged).
    pub steps_done: usize,
    // Timings in seconds: setup (operator plan, sources, dt_stable), the time loop, its median step.
    pub setup_s: f64,
    pub solve_s: f64,
    pub step_s: f64,
    /// eᵏ = h^d Σᵢ |w(tᵏ, xᵢ) − ûᵢᵏ|² at the final time (\[JD], eq. A.3): the *squared*
    /// discrete L² error, as the contract names it.
    pub error_l2: Option<f64>,
    /// √(eᵏ), the discrete L² norm of the error, whose orders are the usual ones.
    pub error_l2_norm: Option<f64>,
    pub error_max: Option<f64>,
    /// e = Σₖ eᵏ (only when the case sets `error_total`).
    pub error_total: Option<f64>,
    /// h^d Σᵢ ûᵢ at the end.
    pub mass: Option<f64>,
    /// (mass at the end − mass at the start) / mass at the start, for a varying horizon's run
    /// of the bump (whether its form conserves Σ u).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_drift: Option<f64>,
    pub max_abs: Option<f64>,
    /// log₁₀ of the largest max |u| of any step over the problem's scale (max(1, max |u₀|,
    /// t_end × the source's scale)): ≤ 0 when the run never outgrew it; a run `ok` by its
    /// divergence bound (six decades up) with a growth of 1 or more is said to grow in its
    /// message (time-dependent runs only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub growth: Option<f64>,
    pub diverged_step: Option<usize>,
    pub diverged_time: Option<f64>,
    /// c_tot(t) samples (when the case sets `diagnostics_every`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c_tot: Option<MassSeries>,
    /// The final field's histogram (when the case sets `histogram_bins`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub histogram: Option<Histogram>,
    /// A coarse copy of the final field and its error (when the case sets `field_snapshot`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<FieldSnapshot>,
    #[serde(flatten)]
    pub distribution: Distribution,
    /// The steady methods' iteration: counts, residual and FETI's sizes (absent otherwise).
    #[serde(flatten)]
    pub steady: SteadySolve,
    #[serde(flatten)]
    pub implicit: ImplicitSolves,
    /// `patch_test`: L_h u along the bar and the ghost force.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch: Option<PatchTest>,
    /// `coupled_1d`: both models' errors, the controls and the optimality system.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling: Option<Coupling>,
    /// The solver process's peak resident memory (VmHWM), setup included; distributed, the
    /// largest rank's, before a field gather; absent where /proc does not tell.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_memory_bytes: Option<u64>,
    /// What `nlsolve run` estimated the run would hold at its peak, per rank, before it
    /// allocated (the estimate that refuses runs too large for the machine), beside the
    /// measured peak.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_estimate_bytes: Option<u64>,
    pub provenance: Provenance,
}

impl Record {
    /// The record of a coupled solve (either coupling): its timings (set-up, solve) and its
    /// errors, e(u_n) standing as the record's L² error.
    pub fn coupled(
        case: &Case,
        resolved: Resolved,
        (setup_s, solve_s): (f64, f64),
        coupling: Coupling,
    ) -> Record {
        Record {
            setup_s,
            solve_s,
            step_s: solve_s,
            error_l2_norm: Some(coupling.error_nonlocal),
            error_l2: Some(coupling.error_nonlocal.powi(2)),
            coupling: Some(coupling),
            ..Record::new(case, resolved, Distribution::serial(case))
        }
    }

    /// An `ok` record with nothing measured yet: each method fills in what it measured.
    pub fn new(case: &Case, resolved: Resolved, distribution: Distribution) -> Self {
        Record {
            case: case.clone(),
            status: Status::Ok,
            message: String::new(),
            resolved,
            steps_done: 0,
            setup_s: 0.0,
            solve_s: 0.0,
            step_s: 0.0,
            error_l2: None,
            error_l2_norm: None,
            error_max: None,
            error_total: None,
            mass: None,
            mass_drift: None,
            max_abs: None,
            growth: None,
            diverged_step: None,
            diverged_time: None,
            c_tot: None,
            histogram: None,
            field: None,
            provenance: Provenance::of_this_run(case.threads, distribution.ranks),
            distribution,
            steady: SteadySolve::default(),
            implicit: ImplicitSolves::default(),
            patch: None,
            coupling: None,
            peak_memory_bytes: peak_memory_bytes(),
            memory_estimate_bytes: None,
        }
    }

    /// The first result that should be a finite number and is not, by its name in the record
    /// (the conditioning diagnostics `coupling.gradient` and `hessian_condition` may be
    /// infinite by right and are left out).
    pub fn non_finite_result(&self) -> Option<(&'static str, f64)> {
        let mut results = vec![
            ("error_l2", self.error_l2),
            ("error_l2_norm", self.error_l2_norm),
            ("error_max", self.error_max),
            ("error_total", self.error_total),
            ("mass", self.mass),
            ("mass_drift", self.mass_drift),
            ("max_abs", self.max_abs),
            ("relative_residual", self.steady.relative_residual),
            ("dual_residual", self.steady.dual_residual),
        ];
        if let Some(patch) = &self.patch {
            results.push(("patch.ghost_force", Some(patch.ghost_force)));
            results.push(("patch.ghost_force_all", Some(patch.ghost_force_all)));
        }
        if let Some(coupling) = &self.coupling {
            results.extend([
                ("coupling.error_nonlocal", Some(coupling.error_nonlocal)),
                ("coupling.error_local", Some(coupling.error_local)),
                ("coupling.mismatch", coupling.mismatch),
                ("coupling.control_error", coupling.control_error),
            ]);
        }
        first_non_finite(results)
    }

    /// An `ok` record holding a result that is not finite becomes `diverged`, saying which:
    /// such a number was never measured (JSON writes it as null), whatever a method's own
    /// checks let through. `methods::run` applies this to every record it returns.
    pub fn diverge_if_not_finite(&mut self) {
        if self.status != Status::Ok {
            return;
        }
        if let Some((name, value)) = self.non_finite_result() {
            self.status = Status::Diverged;
            self.message = format!(
                "`{name}` is {value}, not a finite number: the run produced no usable result"
            );
        }
    }
}

/// The first of named results that is given and not a finite number.
pub(crate) fn first_non_finite(
    results: impl IntoIterator<Item = (&'static str, Option<f64>)>,
) -> Option<(&'static str, f64)> {
    results
        .into_iter()
        .find_map(|(name, value)| value.filter(|v| !v.is_finite()).map(|v| (name, v)))
}

/// VmHWM of /proc/self/status: the most resident memory this process has held.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|line| line.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// What the case resolved to.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Resolved {
    pub h: f64,
    /// The horizon and the constant c of eq. 1.5 (nonlocal method only).
    pub eps: Option<f64>,
    pub m: Option<usize>,
    pub c: Option<f64>,
    pub dt: f64,
    pub dt_stable: f64,
    /// Steps planned to reach t_end.
    pub steps: usize,
    pub nodes: usize,
    /// Σᵢ |neighbourList[i]|: bonds of nodes in D to nodes of D ∪ D_c (2d per node for the
    /// grid methods' stencil; for `pse`, the particle pairs within the kernel's cutoff, each
    /// counted once, pairs with boundary images included).
    pub bonds: usize,
    /// `pse`: the pairs whose distance is checked per step (the cost, O(N) by the cell lists).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pair_visits: Option<usize>,
    /// Nonlocal method: the quadrature and the collar's values, also when the case left them at
    /// their defaults (and so out of its JSON), so that tables can select on them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quadrature: Option<Quadrature>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collar: Option<Collar>,
    /// Nonlocal method: L_h|x|²/(2dk) − 1, the relative error of the quadratic patch test of the
    /// case's quadrature (0 up to round-off for `ac`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch_error: Option<f64>,
    /// Nonlocal method: the operator backend that ran (`auto` resolved by the cost model).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backend: Option<Backend>,
    /// Nonlocal method: the time integrator that ran (the case leaves out the default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrator: Option<Integrator>,
}

impl Resolved {
    /// What the weights `stencil` resolved to; no time step, collar, patch error or backend.
    pub fn of_stencil(stencil: &Stencil) -> Self {
        Resolved {
            h: stencil.grid.h,
            eps: Some(stencil.horizon.eps),
            m: Some(stencil.horizon.m),
            c: Some(stencil.c),
            nodes: stencil.grid.nodes(),
            bonds: stencil.bonds(),
            quadrature: Some(stencil.quadrature),
            ..Resolved::default()
        }
    }
}

/// The linear solves of an implicit integrator, one per step (absent for explicit ones).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ImplicitSolves {
    /// Preconditioned CG iterations per step: mean and maximum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_iterations_mean: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_iterations_max: Option<usize>,
    /// Steps whose solve stopped at `max_iterations` above its tolerance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solves_unconverged: Option<usize>,
    /// The solves' relative tolerance ‖r‖/‖b‖.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_rtol: Option<f64>,
}

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

/// What a steady solve (\[XGDF]) did; every field absent for the time-dependent methods.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SteadySolve {
    /// CG iterations (`steady_cg`) or projected-CG iterations on the multipliers (`feti`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// ‖f − A u‖/‖f‖ of the single-domain system (eq. 20) for the solution returned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relative_residual: Option<f64>,
    /// FETI: √(rᵀy / r₀ᵀy₀), the preconditioned projected residual its iteration stops on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dual_residual: Option<f64>,
    /// FETI: p², the subdomains, and how many of them float (Γ_n = ∅).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subdomains: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floating_subdomains: Option<usize>,
    /// FETI: q, the Lagrange multipliers (one per node shared by a pair of subdomains).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub multipliers: Option<usize>,
    /// FETI: the non-zeros of the largest subdomain's Cholesky factor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub factor_nonzeros_max: Option<usize>,
    /// FETI: where an iteration's time goes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feti_phases: Option<FetiPhases>,
}

/// Where one projected-CG iteration of FETI spends its time: wall seconds per iteration on a rank
/// (max over ranks), and the cost of one subdomain's products (mean over all subdomains), the
/// numbers a projection to one core per subdomain starts from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FetiPhases {
    /// K's local products: the subdomain solves A_n^† (two triangular solves each).
    pub subdomain_solves_s: f64,
    /// Q's local products (the Dirichlet preconditioner: S_n through A_II's solves).
    pub preconditioner_s: f64,
    /// The interface sums after each product: local pairs and the exchange with other ranks
    /// (waiting for a slower rank included).
    pub interface_sum_s: f64,
    /// The coarse projections P₀: Gᵀx summed over ranks, (GᵀG)⁻¹, G β.
    pub coarse_s: f64,
    /// The rest: inner products summed over ranks and the vector updates.
    pub other_s: f64,
    /// One subdomain's K_n product, on one thread.
    pub subdomain_k_s: f64,
    /// One subdomain's Q_n product, on one thread (0 without a preconditioner).
    pub subdomain_q_s: f64,
}

impl SteadySolve {
    /// The record of a CG solve on the single-domain system.
    pub fn cg(iterations: usize) -> Self {
        SteadySolve {
            iterations: Some(iterations),
            ..SteadySolve::default()
        }
    }
}

/// How the run was spread over ranks, and what that cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Distribution {
    pub ranks: usize,
    pub partition: Partition,
    /// The block partition's shape (py = 1 in 1D); absent for `graph`.
    pub px: Option<usize>,
    pub py: Option<usize>,
    /// Ghost nodes summed over ranks: values received per step (`feti`: multiplier values
    /// received per interface exchange; `steady_cg`: ghosts per matrix–vector product).
    pub halo_nodes: usize,
    /// Bytes received per step, all ranks together (8 per ghost).
    pub halo_bytes: usize,
    /// max owned / mean owned nodes per rank.
    pub imbalance: f64,
    /// Median per step of the time spent communicating (halo exchange and the divergence check's
    /// reduction), max over ranks; 0 on one rank.
    pub comm_s: f64,
    /// The host of each rank, in rank order (absent on one rank): where a multi-node run ran.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hosts: Vec<String>,
    /// The CPUs each rank may run on (its affinity, as /proc's `Cpus_allowed_list`: `0-1`), in
    /// rank order (absent on one rank): how a scheduler placed the ranks' threads.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cpus: Vec<String>,
    /// Whether some rank ran more threads than its CPUs, or the ranks of one host more threads
    /// than their CPUs together (absent on one rank, where `nlstudy` judges it): its timings
    /// measure contention, not scaling.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub oversubscribed: Option<bool>,
    /// What the ranks sent each other over the whole run, set-up included (absent on one rank):
    /// the inputs of the scaling model (docs/scaling.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traffic: Option<Traffic>,
}

/// Communication counted by kind: calls as one rank made them (every rank makes the same), bytes
/// sent to other ranks summed over all of them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Traffic {
    /// Halo exchanges (partner swaps) and their bytes.
    pub halo_exchanges: u64,
    pub halo_bytes: u64,
    /// All-reduces (sums and maxima, of one value or a vector) and the bytes put in.
    pub reductions: u64,
    pub reduction_bytes: u64,
    /// All-to-alls (the 2D sine transform's transposes and redistributions) and their bytes.
    pub all_to_alls: u64,
    pub all_to_all_bytes: u64,
}

impl Distribution {
    /// One process owning all of D.
    pub fn serial(case: &Case) -> Self {
        Distribution {
            ranks: 1,
            partition: case.partition,
            px: Some(1),
            py: Some(1),
            halo_nodes: 0,
            halo_bytes: 0,
            imbalance: 1.0,
            comm_s: 0.0,
            hosts: Vec::new(),
            cpus: Vec::new(),
            oversubscribed: None,
            traffic: None,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Provenance {
    pub solver_version: String,
    /// The build's fingerprint (`nlsolve fingerprint`): the hash of the solver's and schema's
    /// sources, Cargo.lock, the compiler, target, flags, profile and features (solver/build/
    /// fingerprint.rs says what is in it); absent from records made before it was kept.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub fingerprint: String,
    pub git_revision: Option<String>,
    pub host: String,
    pub cpu: String,
    pub threads: usize,
    pub ranks: usize,
    pub timestamp: String,
    /// The instruction set the stencil kernel ran (`portable`, `avx2`, `avx512f`), detected at
    /// start-up; absent from records made before the kernel dispatched.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub instruction_set: String,
    /// Whether the working tree had uncommitted changes when the solver was built (from
    /// `git_revision`'s `-dirty`); the fingerprint hashes the sources themselves either way.
    #[serde(default)]
    pub dirty_tree: bool,
    /// Cores this process may run on (affinity and cgroup limits included).
    #[serde(default)]
    pub cores_online: usize,
    /// The machine's load when the run started and ended: /proc/loadavg's one-minute average,
    /// and how many other tasks were runnable at that instant (the run's own left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_start: Option<Load>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_end: Option<Load>,
    /// Timed while other tasks wanted more cores than the run left free (cores online minus
    /// threads × ranks), at its start or its end: its timings measure contention too.
    #[serde(default)]
    pub noisy: bool,
}

/// The machine's load at one instant (see `Provenance::load_start`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Load {
    pub average_1min: f64,
    pub other_runnable: usize,
}

impl Load {
    /// Now, with `own` of the runnable tasks being this run's; `None` where /proc does not tell.
    pub fn now(own: usize) -> Option<Load> {
        let text = std::fs::read_to_string("/proc/loadavg").ok()?;
        let mut fields = text.split_whitespace();
        let average_1min = fields.next()?.parse().ok()?;
        let runnable: usize = fields.nth(2)?.split('/').next()?.parse().ok()?;
        Some(Load {
            average_1min,
            other_runnable: runnable.saturating_sub(own),
        })
    }
}

/// The load when the run started, taken by `note_start` before any work.
static START: std::sync::OnceLock<Option<Load>> = std::sync::OnceLock::new();

/// Takes the load at the start of the run (nlsolve calls it first thing; only this thread runs).
pub fn note_start() {
    START.get_or_init(|| Load::now(1));
}

/// This build's fingerprint (see build/fingerprint.rs).
pub const FINGERPRINT: &str = env!("NLSOLVE_FINGERPRINT");

impl Provenance {
    pub fn of_this_run(threads: usize, ranks: usize) -> Self {
        Provenance {
            solver_version: env!("CARGO_PKG_VERSION").to_string(),
            fingerprint: FINGERPRINT.to_string(),
            git_revision: option_env!("NLSOLVE_GIT_REVISION").map(str::to_string),
            host: read_trimmed("/proc/sys/kernel/hostname").unwrap_or_else(|| "unknown".into()),
            cpu: cpu_model().unwrap_or_else(|| "unknown".into()),
            threads,
            ranks,
            timestamp: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            instruction_set: crate::operator::InstructionSet::detected()
                .name()
                .to_string(),
            dirty_tree: option_env!("NLSOLVE_GIT_REVISION").is_some_and(|r| r.ends_with("-dirty")),
            cores_online: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_start: None,
            load_end: None,
            noisy: false,
        }
        .with_load(START.get().copied().flatten(), Load::now(threads * ranks))
    }

    /// The load at the run's start and end, and whether it made the run noisy.
    fn with_load(mut self, start: Option<Load>, end: Option<Load>) -> Self {
        let free = self.cores_online.saturating_sub(self.threads * self.ranks);
        self.noisy = [start, end]
            .iter()
            .flatten()
            .any(|load| load.other_runnable > free);
        self.load_start = start;
        self.load_end = end;
        self
    }
}

fn read_trimmed(path: &str) -> Option<String> {
    Some(std::fs::read_to_string(path).ok()?.trim().to_string())
}

fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("model name"))?;
    Some(line.split_once(':')?.1.trim().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_is_noisy_when_others_wanted_the_cores_it_left_free() {
        // 4 cores, a 2-thread run: 2 free.
        let mut provenance = Provenance::of_this_run(2, 1);
        provenance.cores_online = 4;
        let load = |others: usize| {
            Some(Load {
                average_1min: 1.0,
                other_runnable: others,
            })
        };
        assert!(!provenance.clone().with_load(load(2), load(0)).noisy);
        assert!(provenance.clone().with_load(load(0), load(3)).noisy);
        assert!(provenance.clone().with_load(load(3), None).noisy);
        assert!(
            !provenance.with_load(None, None).noisy,
            "unmeasured is not noisy"
        );
        let now = Load::now(0).expect("/proc/loadavg on Linux");
        assert!(
            now.average_1min >= 0.0 && now.other_runnable >= 1,
            "this test runs: {now:?}"
        );
    }

    fn record() -> Record {
        let case =
            Case::parse(serde_json::json!({"method": "steady_cg", "dim": 2, "n": 8, "m": 2}))
                .unwrap();
        Record::new(&case, Resolved::default(), Distribution::serial(&case))
    }

    #[test]
    fn an_ok_record_holding_a_non_finite_result_is_diverged() {
        let mut finite = record();
        finite.error_max = Some(1e-3);
        finite.diverge_if_not_finite();
        assert_eq!(finite.status, Status::Ok);
        for value in [f64::NAN, f64::INFINITY] {
            let mut bad = record();
            bad.error_max = Some(0.0);
            bad.steady.relative_residual = Some(value);
            bad.diverge_if_not_finite();
            assert_eq!(bad.status, Status::Diverged);
            assert!(bad.message.contains("relative_residual"), "{}", bad.message);
        }
        // A record already diverged keeps its own message.
        let mut diverged = record();
        diverged.status = Status::Diverged;
        diverged.message = "stopped".into();
        diverged.mass = Some(f64::NAN);
        diverged.diverge_if_not_finite();
        assert_eq!(diverged.message, "stopped");
    }
}
