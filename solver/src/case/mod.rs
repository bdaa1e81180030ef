//! The case: everything that determines a run's result, the rules its fields obey whatever the
//! method, and the error that names a bad field.
//!
//! This is the bottom layer of the crate: plain data every other layer reads. A case is read from
//! JSON with unknown fields refused, so a misspelt field is an error rather than a silently
//! ignored setting. The rules of one method live with that method (`methods::*::validate`);
//! `methods::validate` applies the rules below and then the method's. Every rule names the field
//! and the fix in one sentence.

mod choices;

pub use choices::*;

use serde::{Deserialize, Serialize};
use std::fmt;
use std::ops::Deref;

/// Most memory the frames kept for VTK output may take: they are written when the run ends.
const MAX_FRAME_BYTES: f64 = (4u64 << 30) as f64;

/// Largest horizon accepted: beyond it the collar is wider than half of D.
pub const MAX_EPS: f64 = 0.5;

/// Seed 001's relative tolerance for the steady solvers.
pub const DEFAULT_RTOL: f64 = 1e-5;

/// Default iteration limit of a steady solve: far beyond the L/m that CG needs.
pub const MAX_ITERATIONS: usize = 100_000;

/// Default side L of the local methods' domain (seed 004's).
pub const DEFAULT_LENGTH: f64 = 2.0;

/// Most points per side of a record's field snapshot: 256² values keep a record near 10 MB.
pub const MAX_SNAPSHOT_SIDE: usize = 256;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    #[serde(default)]
    pub method: Method,
    /// Dimension d of D = [0,1]^d: 1 or 2.
    pub dim: usize,
    /// Nodes per side; h = 1/n.
    pub n: usize,
    /// Horizon in cells, ε = m·h (for `pse`, the kernel width in particle spacings). Give `m`
    /// or `eps`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub m: Option<usize>,
    /// Horizon as a length; then m = ⌈ε/h⌉ (for `pse`, ε itself).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eps: Option<f64>,
    #[serde(default = "default_kernel")]
    pub kernel: Kernel,
    /// The nonlocal operator's quadrature: `midpoint` (seed 000), `partial_volume` or `ac`.
    /// Left out of the case's JSON when `midpoint`, so keys of earlier runs stay valid.
    #[serde(default, skip_serializing_if = "Quadrature::is_midpoint")]
    pub quadrature: Quadrature,
    #[serde(default)]
    pub backend: Backend,
    /// k of the local limit kΔ (eq. 1.4).
    #[serde(default = "one")]
    pub diffusivity: f64,
    #[serde(default)]
    pub problem: Problem,
    /// The collar's values: `zero` (eq. 2.2) or `exact` (the manufactured solution continued,
    /// a nonhomogeneous volume constraint). Left out of the case's JSON when `zero`.
    #[serde(default, skip_serializing_if = "Collar::is_zero")]
    pub collar: Collar,
    /// Source mode; `continuum` for `manufactured` and `none` for `bump` when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceMode>,
    /// Side L of the local methods' domain (−L/2, L/2)^d (default 2, as in seed 004).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// Final time T (time-dependent methods).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_end: Option<f64>,
    /// Time step, lowered so that an integer number of steps reaches T. Give `dt` or `cfl`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dt: Option<f64>,
    /// Time step as a fraction of dt_stable (for the implicit integrators, of forward Euler's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cfl: Option<f64>,
    /// The nonlocal method's time integrator. Left out of the case's JSON when `forward_euler`,
    /// so keys of earlier runs stay valid.
    #[serde(default, skip_serializing_if = "Integrator::is_forward_euler")]
    pub integrator: Integrator,
    /// Accept a dt above dt_stable (stability studies); the run may end `diverged`.
    #[serde(default)]
    pub allow_unstable: bool,
    /// Compute e = Σₖ eᵏ over every step (one extra pass per step, outside the timings).
    #[serde(default)]
    pub error_total: bool,
    /// Time between samples of c_tot(t) = h^d Σ c (seed 004's diagnostics.dat), rounded to whole
    /// steps; the series goes into the record. Absent: no series.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnostics_every: Option<f64>,
    /// Bins of a histogram of the final field's values over [min, max] (seed 004's
    /// compute_histogram). Absent: no histogram.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub histogram_bins: Option<usize>,
    /// Blocks per side of a coarse copy of the final field (and of its error, when the problem
    /// has an exact solution) put into the record for heat maps: block means, at most 256.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field_snapshot: Option<usize>,
    /// Time between frames of the field kept for `nlsolve run --write-vtk DIR` (t = 0, each
    /// output time, the end). Absent: --write-vtk writes the final field only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vtk_every: Option<f64>,
    /// Threads of the rayon pool that runs the case (on each rank).
    #[serde(default = "one_thread")]
    pub threads: usize,
    /// MPI ranks: the run must be started by `mpirun -n ranks`.
    #[serde(default = "one_thread")]
    pub ranks: usize,
    /// How the grid is divided among ranks.
    #[serde(default)]
    pub partition: Partition,
    /// Blocks along x of a `block` partition; chosen to minimise the halo when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub px: Option<usize>,
    /// Blocks along y of a `block` partition (2D).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub py: Option<usize>,
    /// Relative tolerance of the iteration: steady methods (default 1e-5, seed 001's) and the
    /// implicit integrators' solves (default: tied to the time error, see `integrate::theta`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rtol: Option<f64>,
    /// Most iterations before a solve stops as not converged (steady default 100000; implicit
    /// integrators 1000 per step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<usize>,
    /// `feti`: subdomains per side, p (p × p in all; p² may exceed the ranks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subdomains: Option<usize>,
    /// `feti`: the preconditioner (default `dirichlet`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preconditioner: Option<FetiPreconditioner>,
}

/// A case whose fields passed the rules of every case and of its method. Only
/// `methods::validate` makes one (`ValidCase::new` and `ValidCase::from_json`, defined there,
/// call it); it reads as a `Case`.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidCase(Case);

impl ValidCase {
    /// The case `methods::validate` has just checked.
    pub(crate) fn validated(case: Case) -> ValidCase {
        ValidCase(case)
    }

    pub fn into_case(self) -> Case {
        self.0
    }
}

impl Deref for ValidCase {
    type Target = Case;
    fn deref(&self) -> &Case {
        &self.0
    }
}

fn default_kernel() -> Kernel {
    Kernel::Constant
}
fn one() -> f64 {
    1.0
}
fn one_thread() -> usize {
    1
}

/// Bad input: the field at fault and one sentence saying what is wrong and how to fix it.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseError {
    pub field: String,
    pub message: String,
}

impl CaseError {
    pub fn new(field: &str, message: impl Into<String>) -> Self {
        CaseError {
            field: field.to_string(),
            message: message.into(),
        }
    }
}

impl fmt::Display for CaseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "case field `{}`: {}", self.field, self.message)
    }
}

impl std::error::Error for CaseError {}

impl Case {
    /// Parses a case from JSON, naming the offending field on any error. The fields' values are
    /// not checked yet: `ValidCase::from_json` (defined in `methods`) parses and validates.
    pub fn parse(value: serde_json::Value) -> Result<Case, CaseError> {
        let case: Case = serde_path_to_error::deserialize(value).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner().to_string();
            // serde reports an unknown or missing field at the parent; name the field itself.
            let field = field_named_in(&inner).unwrap_or(path);
            CaseError::new(
                &field,
                format!("{inner}; see `nlsolve run --help` for the fields"),
            )
        })?;
        Ok(case)
    }

    /// L of the local methods' domain.
    pub fn length(&self) -> f64 {
        self.length.unwrap_or(DEFAULT_LENGTH)
    }

    /// T, 0 for the steady methods.
    pub fn t_end(&self) -> f64 {
        self.t_end.unwrap_or(0.0)
    }

    /// The steady methods' relative tolerance.
    pub fn rtol(&self) -> f64 {
        self.rtol.unwrap_or(DEFAULT_RTOL)
    }

    /// The steady methods' iteration limit.
    pub fn max_iterations(&self) -> usize {
        self.max_iterations.unwrap_or(MAX_ITERATIONS)
    }

    pub fn preconditioner(&self) -> FetiPreconditioner {
        self.preconditioner.unwrap_or_default()
    }

    pub fn source(&self) -> SourceMode {
        self.source.unwrap_or(self.problem.default_source())
    }

    /// The rules every case obeys: a dimension the solver covers and at least one node.
    pub(crate) fn validate_grid(&self) -> Result<(), CaseError> {
        if !(1..=2).contains(&self.dim) {
            return Err(CaseError::new(
                "dim",
                format!(
                    "must be 1 or 2 (got {}); the solver covers D = [0,1] and [0,1]^2",
                    self.dim
                ),
            ));
        }
        if self.n < 1 {
            return Err(CaseError::new(
                "n",
                "must be at least 1 (got 0); give the number of nodes per side, h = 1/n",
            ));
        }
        Ok(())
    }

    /// The rules every time-dependent case obeys, checked after the method's own: k > 0, the
    /// diagnostics, the time step, threads and ranks, and a source that fits the problem.
    /// dt against dt_stable is checked when the stencil is known.
    pub(crate) fn validate_time_dependent(&self) -> Result<(), CaseError> {
        positive("diffusivity", self.diffusivity)?;
        self.validate_diagnostics()?;
        self.validate_time_and_threads()
    }

    fn validate_diagnostics(&self) -> Result<(), CaseError> {
        if let Some(every) = self.diagnostics_every {
            positive("diagnostics_every", every)?;
        }
        if self.histogram_bins == Some(0) {
            return Err(CaseError::new(
                "histogram_bins",
                "must be at least 1 (got 0); leave it out for no histogram",
            ));
        }
        if let Some(side) = self.field_snapshot {
            if !(1..=MAX_SNAPSHOT_SIDE).contains(&side) {
                return Err(CaseError::new(
                    "field_snapshot",
                    format!("must be 1 to {MAX_SNAPSHOT_SIDE} blocks per side (got {side}); a heat map needs no more"),
                ));
            }
        }
        if let Some(every) = self.vtk_every {
            positive("vtk_every", every)?;
            let frames = (self.t_end() / every).ceil() + 2.0;
            let bytes = frames * (self.n as f64).powi(self.dim as i32) * 8.0;
            if bytes > MAX_FRAME_BYTES {
                return Err(CaseError::new(
                    "vtk_every",
                    format!(
                        "keeps about {frames} frames of the field, {:.1} GiB, until the run ends (limit {} GiB); enlarge `vtk_every`",
                        bytes / (1u64 << 30) as f64,
                        MAX_FRAME_BYTES / (1u64 << 30) as f64
                    ),
                ));
            }
        }
        if self.ranks <= 1 {
            return Ok(());
        }
        refuse_given(
            &[
                ("diagnostics_every", self.diagnostics_every.is_some()),
                ("histogram_bins", self.histogram_bins.is_some()),
                ("field_snapshot", self.field_snapshot.is_some()),
                ("vtk_every", self.vtk_every.is_some()),
            ],
            |_| {
                "the distributed solver computes no diagnostics, snapshots or frames (its field equals the one-rank field bit for bit); leave it out or use ranks = 1".into()
            },
        )
    }

    fn validate_time_and_threads(&self) -> Result<(), CaseError> {
        let Some(t_end) = self.t_end else {
            return Err(CaseError::new(
                "t_end",
                "the final time is missing; give `t_end`",
            ));
        };
        positive("t_end", t_end)?;
        match (self.dt, self.cfl) {
            (Some(_), Some(_)) => return Err(CaseError::new(
                "cfl",
                "give the time step once, as `dt` or as `cfl` (a fraction of dt_stable), not both",
            )),
            (None, None) => return Err(CaseError::new(
                "dt",
                "the time step is missing; give `dt` or `cfl` (e.g. 0.5 for half the stable step)",
            )),
            (Some(dt), None) => positive("dt", dt)?,
            (None, Some(cfl)) => positive("cfl", cfl)?,
        }
        if self.threads < 1 {
            return Err(CaseError::new("threads", "must be at least 1 (got 0)"));
        }
        self.validate_distribution()?;
        match (self.problem, self.source()) {
            (Problem::Manufactured, SourceMode::None) => Err(CaseError::new(
                "source",
                "the manufactured problem needs a source: `discrete`, `continuum` or `local`",
            )),
            (Problem::Bump, s) if s != SourceMode::None => Err(CaseError::new(
                "source",
                "the bump problem has no source; leave `source` out or set it to `none`",
            )),
            _ => Ok(()),
        }
    }
}

impl Case {
    /// The steady methods' fields, refused elsewhere.
    /// The steady methods' fields, refused for a time-dependent case; `rtol` and `max_iterations`
    /// are also the implicit integrators', whose steps solve linear systems.
    pub(crate) fn refuse_steady_fields(&self) -> Result<(), CaseError> {
        let solves = self.integrator.is_implicit();
        refuse_given(
            &[
                ("rtol", self.rtol.is_some() && !solves),
                ("max_iterations", self.max_iterations.is_some() && !solves),
                ("subdomains", self.subdomains.is_some()),
                ("preconditioner", self.preconditioner.is_some()),
            ],
            |field| {
                match field {
                "rtol" | "max_iterations" => format!(
                    "belongs to the steady methods and the implicit integrators (`backward_euler`, `crank_nicolson`); leave `{field}` out"
                ),
                _ => "belongs to the steady methods `steady_cg` and `feti`; leave it out".into(),
            }
            },
        )?;
        self.validate_iteration()
    }

    /// `rtol` in (0, 1) and at least one iteration, when given.
    pub(crate) fn validate_iteration(&self) -> Result<(), CaseError> {
        if self.max_iterations == Some(0) {
            return Err(CaseError::new(
                "max_iterations",
                "must be at least 1 (got 0); leave it out for the default",
            ));
        }
        match self.rtol {
            Some(rtol) if !(rtol > 0.0 && rtol < 1.0) => Err(CaseError::new(
                "rtol",
                format!("must lie in (0, 1) (got {rtol}); seed 001 uses 1e-5"),
            )),
            _ => Ok(()),
        }
    }

    pub(crate) fn validate_distribution(&self) -> Result<(), CaseError> {
        let nodes = self.n.saturating_pow(self.dim as u32);
        if self.ranks < 1 {
            return Err(CaseError::new("ranks", "must be at least 1 (got 0)"));
        }
        if self.ranks > nodes {
            return Err(CaseError::new(
                "ranks",
                format!(
                    "{} ranks cannot share {nodes} nodes (every rank must own one); use ranks ≤ {nodes} or a larger n",
                    self.ranks
                ),
            ));
        }
        if self.ranks > 1 && !matches!(self.backend, Backend::Stencil | Backend::Auto) {
            return Err(CaseError::new(
                "backend",
                "the distributed solver runs the `stencil` backend; use `stencil` or `auto` with ranks > 1",
            ));
        }
        for (field, value) in [("px", self.px), ("py", self.py)] {
            if value.is_some() && self.partition != Partition::Block {
                return Err(CaseError::new(
                    field,
                    format!("applies to `partition: block` only; leave `{field}` out"),
                ));
            }
            if value == Some(0) {
                return Err(CaseError::new(field, "must be at least 1 (got 0)"));
            }
        }
        Ok(())
    }
}

/// Refuses the first of `fields` that is given (true), with `message(field)`.
pub(crate) fn refuse_given(
    fields: &[(&str, bool)],
    message: impl Fn(&str) -> String,
) -> Result<(), CaseError> {
    match fields.iter().find(|(_, given)| *given) {
        Some((field, _)) => Err(CaseError::new(field, message(field))),
        None => Ok(()),
    }
}

pub(crate) fn positive(field: &str, value: f64) -> Result<(), CaseError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(CaseError::new(
            field,
            format!("must be a positive number (got {value})"),
        ))
    }
}

/// The field a serde message like "unknown field `x`, expected …" or "missing field `x`" names.
fn field_named_in(message: &str) -> Option<String> {
    ["unknown field `", "missing field `"]
        .iter()
        .find_map(|prefix| {
            let rest = message.strip_prefix(prefix)?;
            Some(rest[..rest.find('`')?].to_string())
        })
}
