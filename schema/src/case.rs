//! The case: every field that determines a run's result, its defaults, and the error that names a
//! bad field.
//!
//! A case is read from JSON with unknown fields refused, so a misspelt field is an error rather
//! than a silently ignored setting. What values a field may take is the solver's business (its
//! `methods::validate`); this module only says what the fields are, so that `nlsolve` and
//! `nlstudy` read the same case.

use crate::choices::*;
#[cfg(feature = "cli")]
use crate::cli::{finite_number, pair};
use crate::error::{field_names, FieldError, Subject};
use serde::{Deserialize, Serialize};

/// \[XGDF]'s relative tolerance for the steady solvers.
pub const DEFAULT_RTOL: f64 = 1e-5;

/// Default iteration limit of a steady solve: far beyond the L/m that CG needs.
pub const MAX_ITERATIONS: usize = 100_000;

/// Default side L of the local methods' domain (\[HPCSE]'s).
pub const DEFAULT_LENGTH: f64 = 2.0;

/// `coupled_1d`'s default local interval [Γ_c, Γ_i]: it overlaps Ω_n = (0, 1) on (0.75, 1).
pub const DEFAULT_LOCAL_DOMAIN: [f64; 2] = [0.75, 1.75];

/// How a case field takes a number (`Case::numeric`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Numeric {
    /// Any number: `cfl`, `dt`, `eps`.
    Real,
    /// A whole number only: `n`, `m`, `threads`.
    Whole,
    /// No number: a choice, a flag, an object, or no field of the case.
    No,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
// The fields' docs are `nlsolve run --help`'s too, so they cite papers as [KEY], unlinked.
#[allow(rustdoc::broken_intra_doc_links)]
pub struct Case {
    /// Method: `nonlocal` (eq. 2.1, stepped by `integrator`); `fd_explicit`, `adi` or `pse`
    /// (local diffusion, [HPCSE]); `steady_cg` or `feti` (the steady problem of [XGDF]);
    /// `patch_test` (a variable horizon's patch tests, [LSSM]); `coupled_1d` ([LSSM]'s
    /// optimization-based local–nonlocal coupling).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub method: Method,
    /// Dimension d of D = [0,1]^d: 1 or 2.
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub dim: usize,
    /// Nodes per side; h = 1/n.
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub n: usize,
    /// Horizon in cells, ε = m·h; give `m` or `eps`. For `pse`, the kernel width in spacings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub m: Option<usize>,
    /// Horizon as a length in (0, 0.5]; m = ⌈ε/h⌉. For `pse`, the kernel width ε ≤ L/2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub eps: Option<f64>,
    /// Influence function J of the nonlocal operator.
    #[serde(default = "default_kernel")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub kernel: Kernel,
    /// Quadrature of the nonlocal operator: `midpoint` ([JD]), `partial_volume` or `ac` (exact
    /// on quadratics, [RKAC]).
    // Left out of the case's JSON when `midpoint`, so keys of earlier runs stay valid.
    #[serde(default, skip_serializing_if = "Quadrature::is_midpoint")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub quadrature: Quadrature,
    /// Operator backend: `auto` (stencil or fft by the cost model), `stencil` (precomputed
    /// weights), `fft` (convolution by FFT) or `neighbour_list` (Algorithm 1, the oracle).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub backend: Backend,
    /// Diffusivity k of the local limit kΔ (eq. 1.4; default 1).
    #[serde(default = "one")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number, required = false))]
    pub diffusivity: f64,
    /// Problem: `manufactured` or `bump` (nonlocal); `eigenmode` or `square` (`fd_explicit`,
    /// `adi`, `pse`).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub problem: Problem,
    /// Collar values: `zero` (eq. 2.2) or `exact` (the manufactured solution continued, a
    /// nonhomogeneous volume constraint).
    // Left out of the case's JSON when `zero`.
    #[serde(default, skip_serializing_if = "Collar::is_zero")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub collar: Collar,
    /// Source of the problem (default: `continuum` for `manufactured`, `none` for `bump`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub source: Option<SourceMode>,
    /// Side L of the local methods' domain (−L/2, L/2)^d (default 2, as in [HPCSE]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub length: Option<f64>,
    /// Final time T of the time-dependent methods.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub t_end: Option<f64>,
    /// Time step, lowered so that whole steps reach T; give `dt` or `cfl`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub dt: Option<f64>,
    /// Time step as a fraction of the stable step dt_stable (for the implicit integrators, of
    /// forward Euler's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub cfl: Option<f64>,
    /// Time integrator of `nonlocal`: explicit (`forward_euler`, eq. 2.1, is the default) or
    /// implicit (`backward_euler`, `crank_nicolson`: a preconditioned Krylov solve per step).
    // Left out of the case's JSON when `forward_euler`, so keys of earlier runs stay valid.
    #[serde(default, skip_serializing_if = "Integrator::is_forward_euler")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub integrator: Integrator,
    /// Accept a dt above dt_stable (stability studies); the run may end `diverged`.
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub allow_unstable: bool,
    /// Compute e = Σₖ eᵏ over every step (one extra pass per step, outside the timings).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub error_total: bool,
    /// Time between samples of c_tot(t) = h^d Σ c ([HPCSE]'s diagnostics.dat), rounded to whole
    /// steps; the series goes into the record. Absent: no series.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub diagnostics_every: Option<f64>,
    /// Bins of a histogram of the final field's values over [min, max] ([HPCSE]'s
    /// compute_histogram). Absent: no histogram.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub histogram_bins: Option<usize>,
    /// Blocks per side of a coarse copy of the final field (and of its error, when the problem
    /// has an exact solution) put into the record for heat maps: block means, at most 256.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub field_snapshot: Option<usize>,
    /// Time between frames of the field kept for `nlsolve run --write-vtk DIR` (t = 0, each
    /// output time, the end). Absent: --write-vtk writes the final field only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub vtk_every: Option<f64>,
    /// `nonlocal`, `fd_explicit`, `adi` and `pse`: also measure the step's
    /// amplification (untimed), at the step asked for (`dt`, or `cfl` times dt_stable, before it
    /// is lowered to land on `t_end`), into the record's `amplification`: above 1 it is unstable.
    /// For a constant horizon the step's spectral radius from L_h's spectrum (Lanczos on its
    /// ends, with the interval that holds it, in at most the applications of this many steps);
    /// otherwise the growth per step of a rough field under the homogeneous problem over this
    /// many steps (a few hundred). Its `positivity` is measured with it: one step of a unit spike,
    /// below 0 where the step makes negative values of non-negative data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub amplification_steps: Option<usize>,
    /// Threads (rayon) on each rank; results are bitwise the same for any count.
    #[serde(default = "one_thread")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub threads: usize,
    /// MPI ranks; must match `mpirun -n`. Results are bitwise the same for any count.
    #[serde(default = "one_thread")]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub ranks: usize,
    /// How the grid is divided among ranks: `block` (px × py rectangles) or `graph` (METIS).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, required = false))]
    pub partition: Partition,
    /// Blocks along x of a `block` partition; chosen to minimise the halo when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub px: Option<usize>,
    /// Blocks along y of a `block` partition (2D).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub py: Option<usize>,
    /// Relative tolerance of the iteration: steady methods (default 1e-5, [XGDF]'s) and the
    /// implicit integrators' solves (default: tied to the time error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_parser = finite_number))]
    pub rtol: Option<f64>,
    /// Iteration limit: steady methods (default 100000; a solve stopped by it is `diverged`) and
    /// the implicit integrators (default 1000 per step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub max_iterations: Option<usize>,
    /// `feti`: subdomains per side, p (p × p in all; p² may exceed the ranks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub subdomains: Option<usize>,
    /// `feti`'s preconditioner: `dirichlet` (default; Cholesky interior solves), `dirichlet_cg`
    /// (5 CG iterations for them), `dirichlet_scaled` (multiplicity scaling) or `none`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub preconditioner: Option<FetiPreconditioner>,
    /// The implicit integrators' Krylov method: `cg` or `bicgstab` (default: CG for a symmetric
    /// L_h, BiCGStab for the non-symmetric forms of a varying horizon).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub krylov: Option<Krylov>,
    /// `patch_test` and `nonlocal`: how ε varies along x, as JSON: `{"kind": "constant"}` (the
    /// default, from `eps` or `m`), `{"kind": "linear", "left": a, "right": b}` or
    /// `{"kind": "transition", "left": a, "right": b, "start": s, "end": e}`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "JSON"))]
    pub horizon_profile: Option<HorizonProfile>,
    /// `patch_test` and a varying-horizon `nonlocal`: `standard` (default: pairwise bonds, ghost
    /// forces where ε varies), `x_centred` (each node on its own horizon: exact on the patch
    /// tests and stable, not symmetric) or `partial_stress`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub formulation: Option<Formulation>,
    /// `patch_test`: the prescribed field, `linear` (default) or `quadratic`; `coupled_1d`: the
    /// exact solution, also `quartic` (u = x² − x⁴).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub patch: Option<PatchField>,
    /// `coupled_1d`: `optimization` (default: [LSSM]'s optimization-based coupling) or
    /// `seamless` (one model whose horizon shrinks to one cell over the overlap).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub coupling: Option<CouplingKind>,
    /// `coupled_1d`: the local problem's interval [Γ_c, Γ_i] (default [0.75, 1.75]); it overlaps
    /// Ω_n = (0, 1) on Ω_b = (Γ_c, 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "A,B", allow_hyphen_values = true, value_parser = pair))]
    pub local_domain: Option<[f64; 2]>,
}

/// A case field as JSON (every field serializes).
fn json(value: impl Serialize) -> serde_json::Value {
    serde_json::to_value(value).expect("case fields serialize")
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

/// What a `CaseError` is about: a field of the case.
pub struct CaseField;

impl Subject for CaseField {
    const NAME: &'static str = "case field";
}

/// Bad input: the case field at fault and one sentence saying what is wrong and how to fix it.
pub type CaseError = FieldError<CaseField>;

impl Case {
    /// Parses a case from JSON, naming the offending field on any error. The fields' values are
    /// not checked yet: the solver's `ValidCase::from_json` parses and validates.
    pub fn parse(value: serde_json::Value) -> Result<Case, CaseError> {
        // A case's strings reach messages, file names and terminals.
        if let Some((field, c)) = crate::json::control_character(&value, &[]) {
            return Err(CaseError::new(
                field,
                format!(
                    "holds {}; case values are printable text",
                    crate::json::describe_char(c)
                ),
            ));
        }
        let case: Case = serde_path_to_error::deserialize(value).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner().to_string();
            CaseError::from_serde(
                path,
                format!("{inner}; see `nlsolve run --help` for the fields"),
            )
        })?;
        Ok(case)
    }

    /// How `field` takes a number, read off the type itself (a case of that one field, parsed):
    /// what a study may search along.
    pub fn numeric(field: &str) -> Numeric {
        let takes = |value: serde_json::Value| {
            // The fields every case needs, then the one asked about.
            let mut case = serde_json::Map::new();
            case.insert("dim".into(), serde_json::json!(1));
            case.insert("n".into(), serde_json::json!(16));
            case.insert(field.to_string(), value);
            serde_json::from_value::<Case>(serde_json::Value::Object(case)).is_ok()
        };
        match (takes(serde_json::json!(0.5)), takes(serde_json::json!(1))) {
            (true, _) => Numeric::Real,
            (false, true) => Numeric::Whole,
            (false, false) => Numeric::No,
        }
    }

    /// The names of every field, in the order of the struct.
    pub fn field_names() -> &'static [&'static str] {
        field_names::<Case>()
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

    /// `patch_test`'s horizon profile.
    pub fn horizon_profile(&self) -> HorizonProfile {
        self.horizon_profile.unwrap_or(HorizonProfile::Constant)
    }

    /// Whether the case's L_h is symmetric: always with a constant horizon; with a varying one,
    /// as its formulation is.
    pub fn symmetric_operator(&self) -> bool {
        self.horizon_profile.is_none() || self.formulation().is_symmetric()
    }

    /// The implicit integrators' Krylov method, given or chosen by L_h's symmetry.
    pub fn krylov(&self) -> Krylov {
        self.krylov
            .unwrap_or_else(|| Krylov::for_symmetry(self.symmetric_operator()))
    }

    pub fn formulation(&self) -> Formulation {
        self.formulation.unwrap_or_default()
    }

    /// The prescribed (`patch_test`) or exact (`coupled_1d`) field.
    pub fn patch(&self) -> PatchField {
        self.patch.unwrap_or_default()
    }

    pub fn coupling(&self) -> CouplingKind {
        self.coupling.unwrap_or_default()
    }

    pub fn local_domain(&self) -> [f64; 2] {
        self.local_domain.unwrap_or(DEFAULT_LOCAL_DOMAIN)
    }

    /// The case as people and tables read it: every field the method uses, with the default it
    /// resolves to when the case leaves it out (`quadrature: midpoint`, `source: continuum`, …).
    /// Fields without a default (`t_end`, `dt`, `px`, …) stay absent when not given. A run's key
    /// is not taken from this form but from the case as serialized, which leaves some defaults
    /// out so that the keys of earlier runs stay valid.
    pub fn resolved(&self) -> serde_json::Value {
        let mut fields = match json(self) {
            serde_json::Value::Object(fields) => fields,
            _ => unreachable!("a case serializes as an object"),
        };
        let mut fill = |name: &str, v: serde_json::Value| {
            fields.entry(name).or_insert(v);
        };
        match self.method {
            Method::Nonlocal => {
                fill("quadrature", json(self.quadrature));
                fill("collar", json(self.collar));
                fill("integrator", json(self.integrator));
                fill("source", json(self.source()));
            }
            Method::FdExplicit | Method::Adi | Method::Pse => fill("length", json(self.length())),
            Method::SteadyCg | Method::Feti => {
                fill("quadrature", json(self.quadrature));
                fill("rtol", json(self.rtol()));
                fill("max_iterations", json(self.max_iterations()));
                if self.method == Method::Feti {
                    fill("preconditioner", json(self.preconditioner()));
                }
            }
            Method::PatchTest => {
                fill("horizon_profile", json(self.horizon_profile()));
                fill("formulation", json(self.formulation()));
                fill("patch", json(self.patch()));
            }
            Method::Coupled1d => {
                fill("patch", json(self.patch()));
                fill("local_domain", json(self.local_domain()));
            }
        }
        serde_json::Value::Object(fields)
    }

    /// The case's grid spacing h (see `Method::grid_spacing`).
    pub fn h(&self) -> f64 {
        self.method.grid_spacing(self.n, self.length())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_field_names_are_the_structs() {
        let names = Case::field_names();
        assert_eq!(names.first(), Some(&"method"));
        assert_eq!(names.last(), Some(&"local_domain"));
        for name in [
            "dim",
            "n",
            "eps",
            "integrator",
            "threads",
            "ranks",
            "subdomains",
        ] {
            assert!(names.contains(&name), "{name} missing from {names:?}");
        }
        // Every field a case serializes is among them (the list cannot miss a field).
        let full = Case::parse(serde_json::json!({"dim": 1, "n": 8, "m": 2, "eps": 0.1,
            "source": "discrete", "length": 2.0, "t_end": 1.0, "dt": 0.1, "cfl": 0.5,
            "diagnostics_every": 0.1, "histogram_bins": 4, "field_snapshot": 4, "vtk_every": 0.5,
            "px": 1, "py": 1, "rtol": 1e-6, "max_iterations": 9, "subdomains": 2,
            "preconditioner": "dirichlet", "formulation": "standard", "patch": "linear",
            "local_domain": [0.75, 1.75], "quadrature": "ac", "collar": "exact",
            "integrator": "rk4"}))
        .unwrap();
        let written = serde_json::to_value(&full).unwrap();
        for field in written.as_object().unwrap().keys() {
            assert!(
                names.contains(&field.as_str()),
                "{field} missing from {names:?}"
            );
        }
    }

    #[test]
    fn the_resolved_case_fills_every_default_the_method_uses() {
        let case = |fields: serde_json::Value| Case::parse(fields).unwrap().resolved();
        let nonlocal = case(serde_json::json!({"dim": 1, "n": 8, "m": 2}));
        for (field, default) in [
            ("quadrature", "midpoint"),
            ("collar", "zero"),
            ("integrator", "forward_euler"),
            ("source", "continuum"),
            ("kernel", "constant"),
            ("method", "nonlocal"),
        ] {
            assert_eq!(nonlocal[field], default, "{field}");
        }
        assert!(nonlocal.get("t_end").is_none() && nonlocal.get("rtol").is_none());
        let bump = case(serde_json::json!({"dim": 1, "n": 8, "m": 2, "problem": "bump"}));
        assert_eq!(bump["source"], "none");
        let adi = case(serde_json::json!({"method": "adi", "dim": 1, "n": 8}));
        assert_eq!(adi["length"], DEFAULT_LENGTH);
        assert!(
            adi.get("quadrature").is_none(),
            "adi has no quadrature: {adi}"
        );
        let feti = case(serde_json::json!({"method": "feti", "dim": 2, "n": 8, "m": 2}));
        assert_eq!(
            (
                &feti["rtol"],
                &feti["max_iterations"],
                &feti["preconditioner"]
            ),
            (
                &serde_json::json!(DEFAULT_RTOL),
                &serde_json::json!(MAX_ITERATIONS),
                &serde_json::json!("dirichlet")
            )
        );
        let coupled = case(serde_json::json!({"method": "coupled_1d", "dim": 1, "n": 8, "m": 2}));
        assert_eq!(
            coupled["local_domain"],
            serde_json::json!(DEFAULT_LOCAL_DOMAIN)
        );
        // A given value is kept, and the serialized case (the key's source) stays as it was.
        let given =
            Case::parse(serde_json::json!({"dim": 1, "n": 8, "m": 2, "quadrature": "ac"})).unwrap();
        assert_eq!(given.resolved()["quadrature"], "ac");
        let keyed = serde_json::to_value(
            Case::parse(serde_json::json!({"dim": 1, "n": 8, "m": 2})).unwrap(),
        )
        .unwrap();
        assert!(keyed.get("quadrature").is_none() && keyed.get("integrator").is_none());
    }

    #[test]
    fn a_control_character_in_any_value_is_refused_naming_the_field() {
        for (case, field) in [
            (
                serde_json::json!({"dim": 1, "n": 8, "kernel": "constant\u{1b}[2J"}),
                "kernel",
            ),
            (
                serde_json::json!({"dim": 1, "n": 8, "horizon_profile": {"kind": "x\ny"}}),
                "horizon_profile.kind",
            ),
        ] {
            let refusal = Case::parse(case).unwrap_err();
            assert_eq!(refusal.field, field);
            assert!(refusal.message.contains("control character"), "{refusal}");
        }
    }

    #[test]
    fn h_is_each_methods_node_spacing() {
        let case = |method: &str, length: f64| {
            Case::parse(serde_json::json!({"method": method, "dim": 1, "n": 7, "length": length}))
                .unwrap()
        };
        assert_eq!(case("nonlocal", 2.0).h(), 1.0 / 7.0);
        assert_eq!(case("feti", 2.0).h(), 1.0 / 7.0);
        assert_eq!(case("adi", 4.0).h(), 0.5);
        assert_eq!(case("pse", 3.5).h(), 0.5);
    }

    #[test]
    fn a_fields_numeric_kind_is_read_off_its_type() {
        for (field, kind) in [
            ("cfl", Numeric::Real),
            ("dt", Numeric::Real),
            ("eps", Numeric::Real),
            ("n", Numeric::Whole),
            ("m", Numeric::Whole),
            ("threads", Numeric::Whole),
            ("integrator", Numeric::No),
            ("allow_unstable", Numeric::No),
            ("horizon_profile", Numeric::No),
            ("no_such_field", Numeric::No),
        ] {
            assert_eq!(Case::numeric(field), kind, "{field}");
        }
    }
}
