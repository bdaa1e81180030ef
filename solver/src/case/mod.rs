//! The case as the solver takes it: the fields (defined in the `schema` crate, shared with
//! `nlstudy`), the rules every method's case obeys, and the validated case only those rules make.
//!
//! This is the bottom layer of the crate: plain data every other layer reads. The rules of one
//! method live with that method (`methods::*::validate`); `methods::validate` applies the rules
//! below and then the method's. Every rule names the field and the fix in one sentence.

pub use schema::case::*;
pub use schema::choices::*;

use std::ops::Deref;

/// Most memory the frames kept for VTK output may take: they are written when the run ends.
const MAX_FRAME_BYTES: f64 = (4u64 << 30) as f64;

/// Largest horizon accepted: beyond it the collar is wider than half of D.
pub const MAX_EPS: f64 = 0.5;

/// Most points per side of a record's field snapshot: 256² values keep a record near 10 MB.
pub const MAX_SNAPSHOT_SIDE: usize = 256;

/// Most threads a case may ask for, on any machine (`nlsolve run` also refuses more than
/// `methods::resources::OVERSUBSCRIPTION` × this machine's cores).
pub const MAX_THREADS: usize = 1024;

/// Most bins of a histogram: as many values as the largest field snapshot (256²), so that a
/// record stays a few MB; each block of the field is also counted into its own copy of the bins.
pub const MAX_HISTOGRAM_BINS: usize = MAX_SNAPSHOT_SIDE * MAX_SNAPSHOT_SIDE;

/// Most samples of c_tot(t) a case may ask for (t_end / `diagnostics_every`): 10⁵ pairs of
/// numbers are a few MB of record, far more than a plot resolves; an interval below dt would
/// otherwise sample every step, up to 10⁸.
pub const MAX_SERIES_SAMPLES: f64 = 1e5;

/// The diffusivities accepted. k enters the weights (∝ k/ε^(d+2)), the sources (∝ k) and
/// dt_stable (∝ h²/k); within 10^±100 none of them overflows or sinks towards the subnormal
/// numbers on any grid a machine holds (h ≥ 10⁻⁹), beyond it they do (k = 1e308 gave fields of
/// NaN). The problems are scaled for k of order 1.
pub const DIFFUSIVITY_RANGE: std::ops::RangeInclusive<f64> = 1e-100..=1e100;

/// Most steps a measurement of the step's amplification may take (`amplification_steps`).
pub const MAX_AMPLIFICATION_STEPS: usize = 1_000_000;

/// Smallest relative tolerance `rtol` accepted: about 45 ε_mach. A residual computed in double
/// precision carries rounding of a few ε_mach per term summed (each product A p sums up to
/// hundreds of bonds, each norm all nodes), so below this a solve meets its tolerance by
/// chance or not at all and runs to `max_iterations`, to be recorded `diverged`. The implicit
/// integrators' own default stops at 1e-13 (`integrate::theta`).
pub const MIN_RTOL: f64 = 1e-14;

/// The horizon as a length: `eps`, or m·h with h = 1/n; 0 when the case gives neither (a
/// varying `horizon_profile`, or a case validation refuses).
pub fn horizon_length(case: &Case) -> f64 {
    case.eps
        .or(case.m.map(|m| m as f64 / case.n as f64))
        .unwrap_or(0.0)
}

/// A number as a message shows it: four significant digits, in scientific notation far from 1
/// (so 1e-300 reads as `1e-300`, not as 300 digits; `schema::text::number`).
pub fn readable(x: f64) -> String {
    schema::text::number(x)
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

/// The rules of the fields shared by every method; `methods::validate` applies them and then the
/// method's own.
pub(crate) trait Rules {
    fn validate_grid(&self) -> Result<(), CaseError>;
    fn validate_time_dependent(&self) -> Result<(), CaseError>;
    fn refuse_steady_fields(&self) -> Result<(), CaseError>;
    fn validate_iteration(&self) -> Result<(), CaseError>;
    fn validate_distribution(&self) -> Result<(), CaseError>;
    fn refuse_time_loop_fields(&self, why: &str) -> Result<(), CaseError>;
}

impl Rules for Case {
    /// The rules every case obeys: a dimension the solver covers and at least one node.
    fn validate_grid(&self) -> Result<(), CaseError> {
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
        validate_amplification(self)
    }

    /// The rules every time-dependent case obeys, checked after the method's own: k > 0, the
    /// diagnostics, the time step, threads and ranks, and a source that fits the problem.
    /// dt against dt_stable is checked when the stencil is known.
    fn validate_time_dependent(&self) -> Result<(), CaseError> {
        validate_diffusivity(self.diffusivity)?;
        validate_diagnostics(self)?;
        validate_time_and_threads(self)
    }

    /// The steady methods' fields, refused for a time-dependent case; `rtol` and `max_iterations`
    /// are also the implicit integrators', whose steps solve linear systems.
    fn refuse_steady_fields(&self) -> Result<(), CaseError> {
        let solves = self.integrator.is_implicit();
        refuse_given(
            &[
                ("rtol", self.rtol.is_some() && !solves),
                ("max_iterations", self.max_iterations.is_some() && !solves),
                ("krylov", self.krylov.is_some() && !solves),
                ("subdomains", self.subdomains.is_some()),
                ("preconditioner", self.preconditioner.is_some()),
            ],
            |field| {
                match field {
                "rtol" | "max_iterations" | "krylov" => format!(
                    "belongs to the steady methods and the implicit integrators (`backward_euler`, `crank_nicolson`); leave `{field}` out"
                ),
                _ => "belongs to the steady methods `steady_cg` and `feti`; leave it out".into(),
            }
            },
        )?;
        self.validate_iteration()
    }

    /// `rtol` in [`MIN_RTOL`, 1) and at least one iteration, when given.
    fn validate_iteration(&self) -> Result<(), CaseError> {
        if self.max_iterations == Some(0) {
            return Err(CaseError::new(
                "max_iterations",
                "must be at least 1 (got 0); leave it out for the default",
            ));
        }
        match self.rtol {
            Some(rtol) if !(rtol > 0.0 && rtol < 1.0) => Err(CaseError::new(
                "rtol",
                format!(
                    "must lie in (0, 1) (got {}); [XGDF] uses 1e-5",
                    readable(rtol)
                ),
            )),
            Some(rtol) if rtol < MIN_RTOL => Err(CaseError::new(
                "rtol",
                format!(
                    "{} is below {}, what a residual computed in double precision can reach (rounding of a few ε_mach = 2.2e-16 per term), so the solve would run to `max_iterations` and end `diverged`; use rtol ≥ {}",
                    readable(rtol),
                    readable(MIN_RTOL),
                    readable(MIN_RTOL)
                ),
            )),
            _ => Ok(()),
        }
    }

    /// For a one-shot method on one rank (\[LSSM]'s): refuses the fields of a time loop, of the
    /// lattice operator's choices, of ranks and of the outputs a time loop makes; `why` says
    /// what the method does instead.
    fn refuse_time_loop_fields(&self, why: &str) -> Result<(), CaseError> {
        refuse_given(
            &[
                ("t_end", self.t_end.is_some()),
                ("dt", self.dt.is_some()),
                ("cfl", self.cfl.is_some()),
                ("ranks", self.ranks > 1),
                ("integrator", !self.integrator.is_forward_euler()),
                ("quadrature", !self.quadrature.is_midpoint()),
                ("collar", !self.collar.is_zero()),
                ("source", self.source.is_some()),
                ("diagnostics_every", self.diagnostics_every.is_some()),
                ("histogram_bins", self.histogram_bins.is_some()),
                ("field_snapshot", self.field_snapshot.is_some()),
                ("vtk_every", self.vtk_every.is_some()),
            ],
            |field| format!("{why}; leave `{field}` out"),
        )
    }

    fn validate_distribution(&self) -> Result<(), CaseError> {
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
        if self.ranks > 1 && self.backend == Backend::NeighbourList {
            return Err(CaseError::new(
                "backend",
                "`neighbour_list` is the one-process oracle; use `stencil`, `fft` or `auto` with ranks > 1",
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

/// The measurement of the step's amplification: of the nonlocal method and of the grid and
/// particle methods of \[HPCSE], over 2 to `MAX_AMPLIFICATION_STEPS` steps.
fn validate_amplification(case: &Case) -> Result<(), CaseError> {
    let Some(steps) = case.amplification_steps else {
        return Ok(());
    };
    let measured = matches!(
        case.method,
        Method::Nonlocal | Method::FdExplicit | Method::Adi | Method::Pse
    );
    if !measured {
        return Err(CaseError::new(
            "amplification_steps",
            "is measured for the time-dependent methods (`nonlocal`, `fd_explicit`, `adi`, `pse`); leave it out",
        ));
    }
    if !(2..=MAX_AMPLIFICATION_STEPS).contains(&steps) {
        return Err(CaseError::new(
            "amplification_steps",
            format!(
                "must be 2 to {} (got {steps}); a few hundred steps resolve a growth of 1.001 per step",
                MAX_AMPLIFICATION_STEPS
            ),
        ));
    }
    Ok(())
}

fn validate_diagnostics(case: &Case) -> Result<(), CaseError> {
    if let Some(every) = case.diagnostics_every {
        positive("diagnostics_every", every)?;
        let samples = case.t_end() / every;
        if samples > MAX_SERIES_SAMPLES {
            return Err(CaseError::new(
                "diagnostics_every",
                format!(
                    "asks for t_end / diagnostics_every = {} samples of c_tot(t), more than {}; enlarge `diagnostics_every` to at least {}",
                    readable(samples),
                    readable(MAX_SERIES_SAMPLES),
                    readable(case.t_end() / MAX_SERIES_SAMPLES)
                ),
            ));
        }
    }
    match case.histogram_bins {
        Some(0) => {
            return Err(CaseError::new(
                "histogram_bins",
                "must be at least 1 (got 0); leave it out for no histogram",
            ))
        }
        Some(bins) if bins > MAX_HISTOGRAM_BINS => {
            return Err(CaseError::new(
                "histogram_bins",
                format!(
                    "must be at most {MAX_HISTOGRAM_BINS} (got {bins}): every bin is a count in the record and in each block's copy; use fewer bins"
                ),
            ))
        }
        _ => {}
    }
    if let Some(side) = case.field_snapshot {
        if !(1..=MAX_SNAPSHOT_SIDE).contains(&side) {
            return Err(CaseError::new(
                    "field_snapshot",
                    format!("must be 1 to {MAX_SNAPSHOT_SIDE} blocks per side (got {side}); a heat map needs no more"),
                ));
        }
    }
    if let Some(every) = case.vtk_every {
        positive("vtk_every", every)?;
        let frames = (case.t_end() / every).ceil() + 2.0;
        let bytes = frames * (case.n as f64).powi(case.dim as i32) * 8.0;
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
    if case.ranks <= 1 {
        return Ok(());
    }
    refuse_given(
        &[
            ("diagnostics_every", case.diagnostics_every.is_some()),
            ("histogram_bins", case.histogram_bins.is_some()),
            ("field_snapshot", case.field_snapshot.is_some()),
            ("vtk_every", case.vtk_every.is_some()),
        ],
        |_| {
            "the distributed solver computes no diagnostics, snapshots or frames (its field equals the one-rank field bit for bit); leave it out or use ranks = 1".into()
        },
    )
}

fn validate_time_and_threads(case: &Case) -> Result<(), CaseError> {
    let Some(t_end) = case.t_end else {
        return Err(CaseError::new(
            "t_end",
            "the final time is missing; give `t_end`",
        ));
    };
    positive("t_end", t_end)?;
    match (case.dt, case.cfl) {
        (Some(_), Some(_)) => {
            return Err(CaseError::new(
                "cfl",
                "give the time step once, as `dt` or as `cfl` (a fraction of dt_stable), not both",
            ))
        }
        (None, None) => {
            return Err(CaseError::new(
                "dt",
                "the time step is missing; give `dt` or `cfl` (e.g. 0.5 for half the stable step)",
            ))
        }
        (Some(dt), None) => positive("dt", dt)?,
        (None, Some(cfl)) => positive("cfl", cfl)?,
    }
    if !(1..=MAX_THREADS).contains(&case.threads) {
        return Err(CaseError::new(
            "threads",
            format!(
                "must lie in 1 ..= {MAX_THREADS} (got {}); a thread per core is the usual choice",
                case.threads
            ),
        ));
    }
    case.validate_distribution()?;
    match (case.problem, case.source()) {
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

/// Refuses the first of `fields` that is given (true), with `message(field)`.
pub(crate) fn refuse_given(
    fields: &[(&str, bool)],
    message: impl Fn(&str) -> String,
) -> Result<(), CaseError> {
    match fields.iter().find(|(_, given)| *given) {
        Some((field, _)) => Err(CaseError::new(*field, message(field))),
        None => Ok(()),
    }
}

/// `diffusivity` positive and within [`DIFFUSIVITY_RANGE`].
pub(crate) fn validate_diffusivity(k: f64) -> Result<(), CaseError> {
    positive("diffusivity", k)?;
    if !DIFFUSIVITY_RANGE.contains(&k) {
        return Err(CaseError::new(
            "diffusivity",
            format!(
                "k = {} lies outside [{}, {}]: the weights (∝ k), the sources (∝ k) and dt_stable (∝ h²/k) overflow or vanish; the problems are scaled for k of order 1, use one",
                readable(k),
                readable(*DIFFUSIVITY_RANGE.start()),
                readable(*DIFFUSIVITY_RANGE.end())
            ),
        ));
    }
    Ok(())
}

pub(crate) fn positive(field: &str, value: f64) -> Result<(), CaseError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(CaseError::new(
            field,
            format!("must be a positive number (got {})", readable(value)),
        ))
    }
}
