//! The solver's record of one run: what the case resolved to, what was measured, how the run
//! was spread over ranks and what its linear solves did. `nlsolve` writes it; `nlstudy` reads it
//! back through the same struct (its case as plain JSON, see `Stored`).

use super::field::{FieldSnapshot, Histogram, MassSeries};
use super::method::{Coupling, PatchTest};
use super::provenance::Provenance;
use super::status::Status;
use crate::case::Case;
use crate::choices::{Backend, Collar, Integrator, Partition, Quadrature};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record<C = Case> {
    /// The case as the solver ran it (`nlstudy` keeps it as the JSON it hashed into the key).
    pub case: C,
    pub status: Status,
    pub message: String,
    #[serde(flatten)]
    pub resolved: Resolved,
    /// Steps completed (fewer than `steps` when diverged).
    pub steps_done: usize,
    /// The times the time loop applied the operator L_h (each stage of a step, each iteration
    /// of an implicit step's Krylov solve, over a resumed run's segments): the run's work the
    /// same on any machine, as the function evaluations of the ODE literature's work–precision
    /// diagrams. Absent for the methods that do not count it (the local methods, the steady
    /// solves) and in records of builds before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operator_applications: Option<u64>,
    // Timings in seconds: setup (operator plan, sources, dt_stable), the time loop, its median step.
    pub setup_s: f64,
    pub solve_s: f64,
    pub step_s: f64,
    /// The run's whole wall time, from its start to its record: the set-up, the solve and what
    /// was measured after it (a step's amplification from L_h's spectrum, errors). Rank 0's over
    /// ranks; absent in records of builds before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wall_s: Option<f64>,
    /// CPU seconds (user and system, every thread; over ranks, their sum) of the set-up, from
    /// the run's start to its solve, and of the solve (the time loop with its bookkeeping, or a
    /// steady solve): the work itself, whatever else the machine runs. Absent where the system
    /// does not tell, and in records of builds before them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub setup_cpu_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_cpu_s: Option<f64>,
    /// Seconds the solve's threads were ready to run but waited for a core (the kernel's
    /// run-queue delay, summed over threads and ranks): for a run of one thread, the part of its
    /// wall time that other tasks took, and over 10 % of the solve's CPU and wait together it is
    /// `noisy`; a pool of threads also waits each time a step wakes it, its own cost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_wait_s: Option<f64>,
    /// The instructions the run's process executed, counted by `instructions_by` (`cachegrind`:
    /// Valgrind's count, the same on any machine however busy; set by `nlstudy compare
    /// --instructions`, whose counted runs' timings are Valgrind's, not the solver's). Counts are
    /// compared only with counts of the same kind.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instructions: Option<u64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instructions_by: Option<String>,
    /// The step this run resumed from, from a checkpoint (`nlsolve run --checkpoint`); absent
    /// for a run that started at step 0. Its numbers are those of a run never stopped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resumed_from_step: Option<usize>,
    /// The time loop's seconds in each segment of a resumed run, the first up to its first
    /// checkpoint read back (`solve_s` is their sum).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solve_s_segments: Option<Vec<f64>>,
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
    /// The step's amplification, where the case asks (`amplification_steps`): above 1 the step
    /// amplifies some mode, so it is unstable. For a symmetric L_h the step's spectral radius
    /// from L_h's spectrum (`amplification_low`/`_high` hold it); otherwise the growth per step
    /// of a rough field under the homogeneous problem over `amplification_steps` steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplification: Option<f64>,
    /// The interval that holds `amplification` where it was measured from L_h's spectrum (a
    /// symmetric L_h: Lanczos on its ends, mapped by the integrator's stability function).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplification_low: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplification_high: Option<f64>,
    /// The applications of L_h the measurement of `amplification` spent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplification_applications: Option<u64>,
    /// The step's positivity, measured with `amplification`: one homogeneous step of a unit
    /// spike at the middle node, its smallest value over its largest. Below 0 the step makes a
    /// negative value of non-negative data; values within 1e-10 of the largest count as 0 (the
    /// implicit solves run to 1e-13).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub positivity: Option<f64>,
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
    /// Fields this struct does not name (a newer solver's), passed through to the tables as
    /// they were written.
    #[serde(flatten)]
    pub unknown: Map<String, Value>,
}

impl Record {
    /// An `ok` record with nothing measured yet, made by the build and run `provenance` says:
    /// each method fills in what it measured.
    pub fn new(
        case: &Case,
        resolved: Resolved,
        distribution: Distribution,
        provenance: Provenance,
    ) -> Self {
        Record {
            case: case.clone(),
            status: Status::Ok,
            message: String::new(),
            resolved,
            steps_done: 0,
            operator_applications: None,
            setup_s: 0.0,
            solve_s: 0.0,
            step_s: 0.0,
            wall_s: None,
            setup_cpu_s: None,
            solve_cpu_s: None,
            solve_wait_s: None,
            instructions: None,
            instructions_by: None,
            resumed_from_step: None,
            solve_s_segments: None,
            error_l2: None,
            error_l2_norm: None,
            error_max: None,
            error_total: None,
            mass: None,
            mass_drift: None,
            max_abs: None,
            growth: None,
            amplification: None,
            amplification_low: None,
            amplification_high: None,
            amplification_applications: None,
            positivity: None,
            diverged_step: None,
            diverged_time: None,
            c_tot: None,
            histogram: None,
            field: None,
            provenance,
            distribution,
            steady: SteadySolve::default(),
            implicit: ImplicitSolves::default(),
            patch: None,
            coupling: None,
            peak_memory_bytes: None,
            memory_estimate_bytes: None,
            unknown: Map::new(),
        }
    }
}

impl<C> Record<C> {
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
pub fn first_non_finite(
    results: impl IntoIterator<Item = (&'static str, Option<f64>)>,
) -> Option<(&'static str, f64)> {
    results
        .into_iter()
        .find_map(|(name, value)| value.filter(|v| !v.is_finite()).map(|v| (name, v)))
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
    /// A varying horizon's explicit stable step from L_h's computed eigenvalues (forward Euler's
    /// min over λ of −2 Re λ/|λ|², times the integrator's real stability interval over 2), where
    /// no symbol gives it: with `amplification_steps`, up to the nodes a spectrum is computed
    /// for; absent for the implicit integrators and where some Re λ > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt_stable_spectrum: Option<f64>,
    /// The largest step whose explicit part I + (1 − θ) dt L_h has no negative entry, where the
    /// theory has one: forward Euler 1/|L_ii| (then exactly the positivity limit), Crank–Nicolson
    /// 2/|L_ii| (a sufficient bound), explicit FD h²/(2dD) (exact), ADI h²/D (sufficient);
    /// absent for backward Euler (positive for every step), for Heun, RK4 and PSE (not derived),
    /// and for weights of either sign.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt_positive: Option<f64>,
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
    /// Each rank's `solve_cpu_s`, in rank order (absent on one rank).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub solve_cpu_s_ranks: Vec<f64>,
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
            solve_cpu_s_ranks: Vec::new(),
            oversubscribed: None,
            traffic: None,
        }
    }
}
