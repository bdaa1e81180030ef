//! The case a command line gives: a case file's fields with the flags on top, one flag per
//! field of `schema::Case` (a test holds the two lists equal), every number flag finite.

use crate::BadInput;
use clap::Args;
use serde::Serialize;
use serde_json::{Map, Value};
use solver::ValidCase;
use std::io::Read;
use std::path::PathBuf;

/// Each flag sets the case field of the same name (dashes become underscores); see README.md.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub(crate) struct CaseArgs {
    /// Case file in JSON (`-` for standard input); flags given too override its fields.
    #[arg(long, value_name = "FILE")]
    case: Option<PathBuf>,
    #[command(flatten)]
    flags: CaseFlags,
}

/// The case's fields as flags, one for each field of `schema::Case` (a test checks that the two
/// lists agree): serialized, the flags given are the case fields they set (`CaseArgs::fields`).
#[derive(Args, Serialize)]
pub(crate) struct CaseFlags {
    /// Method: nonlocal (eq. 2.1, stepped by --integrator); fd_explicit, adi or pse (local diffusion,
    /// [HPCSE]); steady_cg or feti (the steady problem of [XGDF]); patch_test (a variable
    /// horizon's patch tests, [LSSM]); coupled_1d ([LSSM]'s optimization-based local–nonlocal
    /// coupling).
    #[arg(long)]
    method: Option<String>,
    /// Dimension of D = [0,1]^d: 1 or 2.
    #[arg(long)]
    dim: Option<usize>,
    /// Nodes per side; h = 1/n, nodes at cell centres.
    #[arg(long)]
    n: Option<usize>,
    /// Horizon in cells, ε = m·h (give --m or --eps); for pse, the kernel width in spacings.
    #[arg(long)]
    m: Option<usize>,
    /// Horizon as a length in (0, 0.5]; m = ceil(ε/h). For pse, the kernel width ε ≤ L/2.
    #[arg(long, value_parser = finite_number)]
    eps: Option<f64>,
    /// Influence function J: constant, linear, gaussian, inverse_distance.
    #[arg(long)]
    kernel: Option<String>,
    /// Quadrature of the nonlocal operator: midpoint ([JD]), partial_volume, ac (exact on quadratics).
    #[arg(long)]
    quadrature: Option<String>,
    /// Operator backend: auto (default: stencil or fft by the cost model), stencil (precomputed
    /// weights), fft (convolution by FFT) or neighbour_list (Algorithm 1, the oracle).
    #[arg(long)]
    backend: Option<String>,
    /// Diffusivity k of the local limit kΔ (default 1).
    #[arg(long, value_parser = finite_number)]
    diffusivity: Option<f64>,
    /// Problem: manufactured or bump (nonlocal); eigenmode or square (fd_explicit, adi, pse).
    #[arg(long)]
    problem: Option<String>,
    /// Collar values: zero (eq. 2.2) or exact (the manufactured solution continued).
    #[arg(long)]
    collar: Option<String>,
    /// Source mode of the manufactured problem: discrete, continuum (default) or local.
    #[arg(long)]
    source: Option<String>,
    /// Side L of the local methods' domain (−L/2, L/2)^d (default 2).
    #[arg(long, value_parser = finite_number)]
    length: Option<f64>,
    /// Final time.
    #[arg(long, value_parser = finite_number)]
    t_end: Option<f64>,
    /// Time step (lowered to land on t_end); give --dt or --cfl.
    #[arg(long, value_parser = finite_number)]
    dt: Option<f64>,
    /// Time step as a fraction of the stable step dt_stable (implicit integrators: of forward
    /// Euler's).
    #[arg(long, value_parser = finite_number)]
    cfl: Option<f64>,
    /// nonlocal: time integrator forward_euler (default, eq. 2.1), heun, rk4, backward_euler or
    /// crank_nicolson (the last two solve by sine-preconditioned CG each step).
    #[arg(long)]
    integrator: Option<String>,
    /// Accept a time step above dt_stable (stability studies); the run may end `diverged`.
    #[arg(long)]
    allow_unstable: bool,
    /// Also compute the total error e = Σ_k e^k (one extra pass per step, untimed).
    #[arg(long)]
    error_total: bool,
    /// Time between samples of c_tot(t) (into the record; see --write-diagnostics).
    #[arg(long, value_parser = finite_number)]
    diagnostics_every: Option<f64>,
    /// Bins of a histogram of the final field's values (into the record).
    #[arg(long)]
    histogram_bins: Option<usize>,
    /// Blocks per side of a coarse copy of the final field and its error (into the record).
    #[arg(long)]
    field_snapshot: Option<usize>,
    /// Time between the field's frames written by --write-vtk.
    #[arg(long, value_parser = finite_number)]
    vtk_every: Option<f64>,
    /// Threads (rayon) on each rank; results are bitwise the same for any count.
    #[arg(long)]
    threads: Option<usize>,
    /// MPI ranks; must match `mpirun -n`. Results are bitwise the same for any count.
    #[arg(long)]
    ranks: Option<usize>,
    /// How the grid is divided among ranks: block (px × py rectangles) or graph (METIS).
    #[arg(long)]
    partition: Option<String>,
    /// Blocks along x of a block partition (chosen to minimise the halo when left out).
    #[arg(long)]
    px: Option<usize>,
    /// Blocks along y of a block partition.
    #[arg(long)]
    py: Option<usize>,
    /// Relative tolerance of the iteration: steady methods (default 1e-5) and the implicit
    /// integrators' solves (default tied to the time error).
    #[arg(long, value_parser = finite_number)]
    rtol: Option<f64>,
    /// Iteration limit: steady methods (default 100000; a solve stopped by it is `diverged`) and
    /// the implicit integrators (default 1000 per step).
    #[arg(long)]
    max_iterations: Option<usize>,
    /// feti: subdomains per side, p (p × p in all).
    #[arg(long)]
    subdomains: Option<usize>,
    /// feti: preconditioner none, dirichlet (default; Cholesky interior solves), dirichlet_cg
    /// (5 CG iterations for the interior solves) or dirichlet_scaled (multiplicity scaling).
    #[arg(long)]
    preconditioner: Option<String>,
    /// implicit integrators: the Krylov method of each step's solve, cg or bicgstab (default:
    /// cg for a symmetric L_h, bicgstab for the x_centred and partial_stress forms).
    #[arg(long)]
    krylov: Option<String>,
    /// patch_test and nonlocal: how ε varies along x, as JSON: {"kind": "constant"} (from --eps or --m),
    /// {"kind": "linear", "left": a, "right": b} or {"kind": "transition", "left": a, "right":
    /// b, "start": s, "end": e}.
    #[arg(long, value_name = "JSON")]
    #[serde(serialize_with = "json_text")]
    horizon_profile: Option<String>,
    /// patch_test and a varying-horizon nonlocal: standard (pairwise bonds, the symmetrised
    /// dual-horizon kernel; ghost forces where ε varies), x_centred (each node on its own
    /// horizon: exact on the patch tests and stable, not symmetric) or partial_stress.
    #[arg(long)]
    formulation: Option<String>,
    /// patch_test: the prescribed field, linear (u = x) or quadratic (u = x²); coupled_1d: the
    /// exact solution, also quartic (u = x² − x⁴).
    #[arg(long)]
    patch: Option<String>,
    /// coupled_1d: optimization (default: [LSSM]'s optimization-based coupling) or seamless
    /// (one x-centred model whose horizon shrinks to h over the overlap).
    #[arg(long)]
    coupling: Option<String>,
    /// coupled_1d: the local problem's interval a,b (default 0.75,1.75): Γ_c = a inside (0, 1),
    /// Γ_i = b ≥ 1 + ε.
    #[arg(
        long,
        value_name = "A,B",
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_parser = finite_number
    )]
    local_domain: Option<Vec<f64>>,
}

/// A number flag's value: a finite f64. JSON has no NaN or infinity: serde_json would write one
/// as `null`, which the case reads as a field not given (`--diffusivity nan` would run with
/// the default), so it is refused here, by clap, naming the flag.
pub(crate) fn finite_number(text: &str) -> Result<f64, String> {
    let x: f64 = text.trim().parse().map_err(|e| format!("{e}"))?;
    match x.is_finite() {
        true => Ok(x),
        false => Err("not a finite number".into()),
    }
}

impl CaseArgs {
    /// The case: the file's fields (if any) with the flags' fields set on top.
    pub(crate) fn case(&self) -> Result<ValidCase, BadInput> {
        ValidCase::from_json(Value::Object(self.fields()?)).map_err(|e| BadInput(e.to_string()))
    }

    /// The case's fields as JSON, before they are checked.
    pub(crate) fn fields(&self) -> Result<Map<String, Value>, BadInput> {
        let mut fields = match &self.case {
            Some(path) => read_case_file(path)?,
            None => Map::new(),
        };
        match serde_json::to_value(&self.flags) {
            // A flag not given is null (a switch not given, false): it leaves its field alone.
            Ok(Value::Object(flags)) => fields.extend(
                flags
                    .into_iter()
                    .filter(|(_, v)| !v.is_null() && *v != Value::Bool(false)),
            ),
            Ok(_) => unreachable!("a struct serializes to an object"),
            Err(e) => return Err(BadInput(e.to_string())),
        }
        Ok(fields)
    }
}

/// `--horizon-profile`'s JSON text as the JSON value it is.
pub(crate) fn json_text<S: serde::Serializer>(
    text: &Option<String>,
    to: S,
) -> Result<S::Ok, S::Error> {
    let text = text.as_deref().unwrap_or("null");
    let value = schema::json::parse(text).map_err(|e| {
        serde::ser::Error::custom(format!("--horizon-profile is not valid JSON: {e}"))
    })?;
    value.serialize(to)
}

pub(crate) fn read_case_file(path: &PathBuf) -> Result<Map<String, Value>, BadInput> {
    let name = path.display();
    let text = if path.as_os_str() == "-" {
        let mut text = String::new();
        std::io::stdin()
            .read_to_string(&mut text)
            .map_err(|e| BadInput(format!("cannot read the case from standard input: {e}")))?;
        text
    } else {
        std::fs::read_to_string(path).map_err(|e| {
            BadInput(format!(
                "cannot read case file {name}: {e}; check the path given to --case"
            ))
        })?
    };
    match schema::json::parse(&text) {
        Ok(Value::Object(fields)) => Ok(fields),
        Ok(_) => Err(BadInput(format!(
            "case file {name} must hold one JSON object of case fields"
        ))),
        Err(e) => Err(BadInput(format!("case file {name} is not valid JSON: {e}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{usage_error, Cli, Command};
    use clap::Parser;
    use solver::case::Case;

    /// One flag per case field, named as the field: the flags and `schema::Case` cannot drift.
    #[test]
    fn the_flags_are_the_case_fields() {
        let command = CaseFlags::augment_args(clap::Command::new("nlsolve"));
        let flags: Vec<&str> = command
            .get_arguments()
            .map(|a| a.get_id().as_str())
            .collect();
        assert_eq!(flags, Case::field_names());
    }

    /// No flag takes a number that is not finite (or any value a case refuses): `nan`, `inf`
    /// and `-inf` are refused by every flag that takes a value, the number flags saying "not a
    /// finite number".
    #[test]
    fn no_flag_takes_a_number_that_is_not_finite() {
        let command = CaseFlags::augment_args(clap::Command::new("nlsolve"));
        let mut numbers = 0;
        for arg in command.get_arguments() {
            if !arg.get_action().takes_values() {
                continue;
            }
            let flag = format!("--{}", arg.get_long().expect("a long flag"));
            // `--flag=value`, so that `-inf` is a value, not a flag.
            let given = |value: &str| format!("{flag}={value}");
            let parses =
                |value: &str| Cli::try_parse_from(["nlsolve", "run", &given(value)]).is_ok();
            let takes_a_fraction = parses("0.5") && !parses("x");
            for value in ["nan", "NaN", "inf", "-inf", "infinity", "1e400"] {
                let refusal = match Cli::try_parse_from(["nlsolve", "run", &given(value)]) {
                    Err(e) => e.to_string(),
                    Ok(cli) => {
                        let Command::Run(args) = cli.command else {
                            panic!("a run")
                        };
                        match args.case.case() {
                            Err(BadInput(message)) => message,
                            Ok(_) => panic!("{flag} {value} was accepted"),
                        }
                    }
                };
                if takes_a_fraction {
                    assert!(
                        refusal.contains("not a finite number"),
                        "{flag} {value}: {refusal}"
                    );
                }
            }
            numbers += usize::from(takes_a_fraction);
        }
        assert!(numbers >= 10, "the f64 flags were found: {numbers}");
    }

    /// A misspelt flag is one line of bad input that still carries clap's suggestion.
    #[test]
    fn a_misspelt_flag_is_refused_with_the_flag_it_resembles() {
        let error = Cli::try_parse_from(["nlsolve", "run", "--integrater", "rk4"])
            .err()
            .expect("an unknown flag");
        let line = usage_error(&error.to_string());
        assert!(!line.contains('\n'), "{line}");
        assert!(
            line.starts_with("unexpected argument '--integrater' found")
                && line.contains("similar argument exists: '--integrator'"),
            "{line}"
        );
    }

    /// The flags given, and only those, become the case's fields, with their JSON types.
    #[test]
    fn the_flags_given_are_the_fields_they_set() {
        let cli = Cli::try_parse_from([
            "nlsolve",
            "run",
            "--dim",
            "1",
            "--n",
            "8",
            "--eps",
            "0.25",
            "--error-total",
            "--horizon-profile",
            r#"{"kind": "constant", "eps": 0.1}"#,
            "--local-domain",
            "-0.5,1",
        ])
        .unwrap();
        let Command::Run(args) = cli.command else {
            panic!("a run")
        };
        let fields = args.case.fields().ok().unwrap();
        assert_eq!(
            Value::Object(fields),
            serde_json::json!({"dim": 1, "n": 8, "eps": 0.25, "error_total": true,
                "horizon_profile": {"kind": "constant", "eps": 0.1}, "local_domain": [-0.5, 1.0]})
        );
        let bad = Cli::try_parse_from(["nlsolve", "run", "--horizon-profile", "{"]).unwrap();
        let Command::Run(args) = bad.command else {
            panic!("a run")
        };
        let refusal = args.case.fields().err().unwrap().0;
        assert!(
            refusal.contains("--horizon-profile is not valid JSON"),
            "{refusal}"
        );
    }
}
