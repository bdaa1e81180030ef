//! `nlsolve`: runs one case and prints its record as one JSON line on stdout, with a short human
//! summary on stderr.
//!
//! Exit statuses (also in `--help`): 0 when the record (the report, the verdicts) was written; 1
//! when MPI could not start; 2 for bad input, with one sentence naming the field; 74
//! (`EXIT_IO`) when the record, the verdicts or a `--write-*` file could not be written, with
//! one line saying what and why. A failed write to stderr (the summary, a message) is ignored:
//! there is nowhere left to report it, and it says nothing about the result.

use clap::error::ErrorKind;
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use serde::Serialize;
use serde_json::{Map, Value};
use solver::case::{Case, Method};
use solver::output::record::Record;
use solver::output::vtk;
use solver::{Outcome, ValidCase};
use std::io::{BufRead, Read, Write};
use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Exit status of bad input (a case, a flag, a case file that cannot be read).
const EXIT_BAD_INPUT: u8 = 2;

/// Exit status when what nlsolve was asked to write could not be written (standard output
/// closed, a broken pipe, a full disk, a `--write-*` path that cannot be written), so that a
/// caller tells a lost record from a bad case and from a run that finished.
const EXIT_IO: u8 = schema::record::NLSOLVE_EXIT_IO;

/// The exit statuses, as `--help` lists them.
const EXIT_STATUSES: &str =
    "Exit status: 0 when the record (the report, the verdicts) was written; \
1 when MPI could not start; 2 for bad input (one line on stderr naming the field); 74 (EX_IOERR) \
when the record, the verdicts or a --write-* file could not be written (standard output closed \
or full, a broken pipe, a path that cannot be written), with one line on stderr saying which.";

#[derive(Parser)]
#[command(
    name = "nlsolve",
    version,
    about = "Runs one nonlocal diffusion case and prints its JSON record."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run one case, given as a JSON file, as flags, or as a file with flags overriding its fields.
    /// With ranks > 1, start it as `mpirun -n <ranks> nlsolve run … --ranks <ranks>`.
    Run(RunArgs),
    /// Report the partition and halo a distributed run of the case would use (ghost nodes, bytes
    /// per step, imbalance) without running it or starting MPI; the time fields may be left out.
    Partition(CaseArgs),
    /// Check cases without running them: reads one JSON case per line on standard input and
    /// prints one line for each: `{"case": …, "resolved": …}` (`case` in canonical form, keys
    /// sorted, what a run's key is taken from; `resolved` the same case with every default the
    /// method uses filled in) or `{"error": "…"}` naming the field at fault.
    Check,
    /// Print the build's fingerprint: the hash of everything that decides a record's numbers
    /// (the solver's and schema's sources, Cargo.lock, the compiler, target, flags, profile and
    /// features), which every record carries in its provenance.
    Fingerprint,
}

#[derive(Args)]
struct RunArgs {
    #[command(flatten)]
    case: CaseArgs,
    /// Also write the final field to FILE: little-endian f64 values in node order (iy·n + ix).
    #[arg(long, value_name = "FILE")]
    write_field: Option<PathBuf>,
    /// Also write the c_tot(t) series to FILE as CSV (`t,c_tot`, [HPCSE]'s diagnostics.dat);
    /// needs --diagnostics-every.
    #[arg(long, value_name = "FILE")]
    write_diagnostics: Option<PathBuf>,
    /// Also write the field for ParaView into DIR: u_<k>.vti (VTK image data) at each time the
    /// case's `vtk_every` asks for, else the final field only, and u.pvd listing them by time.
    #[arg(long, value_name = "DIR")]
    write_vtk: Option<PathBuf>,
}

/// Each flag sets the case field of the same name (dashes become underscores); see README.md.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
struct CaseArgs {
    /// Case file in JSON (`-` for standard input); flags given too override its fields.
    #[arg(long, value_name = "FILE")]
    case: Option<PathBuf>,
    #[command(flatten)]
    flags: CaseFlags,
}

/// The case's fields as flags, one for each field of `schema::Case` (a test checks that the two
/// lists agree): serialized, the flags given are the case fields they set (`CaseArgs::fields`).
#[derive(Args, Serialize)]
struct CaseFlags {
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
fn finite_number(text: &str) -> Result<f64, String> {
    let x: f64 = text.trim().parse().map_err(|e| format!("{e}"))?;
    match x.is_finite() {
        true => Ok(x),
        false => Err("not a finite number".into()),
    }
}

/// Bad input: a message for the user, exit code 2.
struct BadInput(String);

/// Why nlsolve stops without success; each kind has its exit status.
enum Failure {
    /// Bad input: one sentence naming the field, `EXIT_BAD_INPUT`.
    BadInput(String),
    /// An output could not be written (the message names it and the error): `EXIT_IO`.
    Output(String),
}

impl From<BadInput> for Failure {
    fn from(BadInput(message): BadInput) -> Self {
        Failure::BadInput(message)
    }
}

/// Writes one line to standard error, ignoring a failure: a closed or full stderr must not turn
/// a finished run into a crash (`eprintln!` panics), and there is nowhere left to report it.
fn note(line: &str) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

/// Standard output as a file of its own (a duplicate of descriptor 1). `std::io::stdout`
/// reports a write to a closed descriptor as a success, so a record written there would be lost
/// with exit status 0; through this file every failure (EBADF, EPIPE, ENOSPC) is an error, and
/// so is a standard output that was closed when nlsolve started.
fn standard_output() -> std::io::Result<std::fs::File> {
    if standard_output_was_closed() {
        return Err(std::io::Error::other("it was closed when nlsolve started"));
    }
    let descriptor = std::io::stdout().as_fd().try_clone_to_owned()?;
    Ok(std::fs::File::from(descriptor))
}

/// Was standard output closed when nlsolve started (`nlsolve run … >&-`)? Rust's runtime opens
/// /dev/null in its place before `main` (so that no later file takes descriptor 1), after which a
/// closed descriptor and a /dev/null a caller chose (`>/dev/null`, Python's
/// `subprocess.DEVNULL`, opened for reading and writing) look alike. So the descriptor is looked
/// at before the runtime starts, by a function the loader runs first (`.init_array`).
fn standard_output_was_closed() -> bool {
    CLOSED_AT_START.load(std::sync::atomic::Ordering::Relaxed)
}

static CLOSED_AT_START: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Run by the loader before `main` and before Rust's runtime reopens a closed descriptor:
/// /proc/self/fd/1 names no file when descriptor 1 is closed. (Where /proc does not tell, every
/// descriptor counts as open.)
extern "C" fn note_a_closed_standard_output() {
    let closed = std::fs::symlink_metadata("/proc/self/fd")
        .is_ok_and(|_| std::fs::read_link("/proc/self/fd/1").is_err());
    CLOSED_AT_START.store(closed, std::sync::atomic::Ordering::Relaxed);
}

#[used]
#[link_section = ".init_array"]
static NOTE_A_CLOSED_STANDARD_OUTPUT: extern "C" fn() = note_a_closed_standard_output;

/// Writes `line` and a newline to standard output; `what` names it in the error (`the record`).
fn print_line(line: &str, what: &str) -> Result<(), Failure> {
    let failed =
        |e: std::io::Error| Failure::Output(format!("cannot write {what} to standard output: {e}"));
    let mut out = standard_output().map_err(failed)?;
    out.write_all(format!("{line}\n").as_bytes())
        .map_err(failed)
}

impl CaseArgs {
    /// The case: the file's fields (if any) with the flags' fields set on top.
    fn case(&self) -> Result<ValidCase, BadInput> {
        ValidCase::from_json(Value::Object(self.fields()?)).map_err(|e| BadInput(e.to_string()))
    }

    /// The case's fields as JSON, before they are checked.
    fn fields(&self) -> Result<Map<String, Value>, BadInput> {
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
fn json_text<S: serde::Serializer>(text: &Option<String>, to: S) -> Result<S::Ok, S::Error> {
    let text = text.as_deref().unwrap_or("null");
    let value = schema::json::parse(text).map_err(|e| {
        serde::ser::Error::custom(format!("--horizon-profile is not valid JSON: {e}"))
    })?;
    value.serialize(to)
}

fn read_case_file(path: &PathBuf) -> Result<Map<String, Value>, BadInput> {
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

/// The name a value has in the JSON case and record (`linear`, `neighbour_list`, `ok`).
fn label<T: serde::Serialize>(value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(Value::String(name)) => name,
        _ => String::from("?"),
    }
}

fn summary(record: &Record) -> String {
    let case = &record.case;
    let errors = match (record.error_l2_norm, record.error_max) {
        (Some(l2), Some(max)) => format!("; error L2 norm {l2:.3e}, max {max:.3e}"),
        _ => String::new(),
    };
    let resolved = &record.resolved;
    let method = match (case.method, resolved.m, resolved.eps) {
        (Method::Pse, _, Some(eps)) => format!("pse ε={eps:.4} (ε/h {:.3})", eps / resolved.h),
        (_, Some(m), _) => format!(
            "m={m} {} {} {}",
            label(&case.kernel),
            label(&case.quadrature),
            resolved
                .backend
                .map_or_else(|| label(&case.backend), |b| label(&b))
        ),
        _ => label(&case.method),
    };
    if let Some(patch) = &record.patch {
        return format!(
            "nlsolve: patch test n={} {} {} field, {}, ε from {:.4} to {:.4}: max |L_h u − k u''| = {:.3e} over {} bonds; dt_stable {:.3e}; status {}",
            case.n,
            label(&case.kernel),
            label(&case.patch()),
            label(&case.formulation()),
            patch.eps_min,
            resolved.eps.unwrap_or(f64::NAN),
            patch.ghost_force,
            resolved.bonds,
            resolved.dt_stable,
            label(&record.status),
        );
    }
    if let Some(coupled) = &record.coupling {
        let optimum = match (coupled.mismatch, coupled.gradient) {
            (Some(mismatch), Some(gradient)) => format!(
                "overlap mismatch {mismatch:.3e}, ‖∇J‖/‖∇J(0)‖ {gradient:.1e} over {} controls",
                coupled.controls_nonlocal.len() + 1
            ),
            _ => "no interface: the horizon shrinks to h over the overlap".into(),
        };
        return format!(
            "nlsolve: coupled_1d ({}) n={} ε={} {} {} field, local domain [{}, {}]: e(u_n) {:.3e}, e(u_l) {:.3e}, {optimum}; status {}",
            label(&case.coupling()),
            case.n,
            resolved.eps.unwrap_or(f64::NAN),
            label(&case.kernel),
            label(&case.patch()),
            coupled.local_domain[0],
            coupled.local_domain[1],
            coupled.error_nonlocal,
            coupled.error_local,
            label(&record.status),
        );
    }
    if let Some(iterations) = record.steady.iterations {
        let solver = match case.subdomains {
            Some(p) => format!(
                "feti {p}×{p} ({}) with {} multipliers",
                label(&case.preconditioner()),
                record.steady.multipliers.unwrap_or(0)
            ),
            None => "cg".into(),
        };
        return format!(
            "nlsolve: steady n={} {method}, {solver}, {} rank(s) × {} thread(s): {iterations} iterations in {:.3e} s (setup {:.3e} s), relative residual {:.2e}{errors}; status {} {}",
            case.n,
            case.ranks,
            case.threads,
            record.solve_s,
            record.setup_s,
            record.steady.relative_residual.unwrap_or(f64::NAN),
            label(&record.status),
            record.message,
        );
    }
    let solves = match record.implicit.solve_iterations_mean {
        Some(mean) => format!(
            ", {mean:.1} CG iterations per step (max {})",
            record.implicit.solve_iterations_max.unwrap_or(0)
        ),
        None => String::new(),
    };
    format!(
        "nlsolve: {}D n={} {method} {}, {} rank(s) × {} thread(s): {} steps of dt={:.3e} (dt/dt_stable {:.3}){solves} in {:.3e} s, {:.3e} s/step{errors}; status {} {}",
        case.dim,
        case.n,
        label(&case.integrator),
        case.ranks,
        case.threads,
        record.steps_done,
        record.resolved.dt,
        record.resolved.dt / record.resolved.dt_stable,
        record.solve_s,
        record.step_s,
        label(&record.status),
        record.message,
    )
}

/// Parses the command line. `nlsolve --help` also lists the flags of `run`; a usage error is one
/// line and exit code 2, like every other kind of bad input.
fn parse_command_line() -> Result<Cli, BadInput> {
    let mut command = Cli::command();
    let run_help = command
        .find_subcommand_mut("run")
        .expect("the run subcommand exists")
        .render_help();
    let command = command.after_help(format!(
        "{EXIT_STATUSES}\n\n`nlsolve run` takes these flags:\n\n{run_help}"
    ));
    let matches = command.try_get_matches().map_err(|e| match e.kind() {
        ErrorKind::DisplayHelp
        | ErrorKind::DisplayVersion
        | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => e.exit(),
        _ => BadInput(usage_error(&e.to_string())),
    })?;
    Cli::from_arg_matches(&matches).map_err(|e| BadInput(e.to_string()))
}

/// clap's error as one line: its first line and its tips (`a similar argument exists:
/// '--integrator'`), without the usage block.
fn usage_error(text: &str) -> String {
    let first = text.lines().next().unwrap_or_default();
    let tips = text
        .lines()
        .filter_map(|line| line.trim().strip_prefix("tip: "))
        .map(|tip| format!("; {tip}"));
    std::iter::once(first.trim_start_matches("error: ").to_string())
        .chain(tips)
        .collect()
}

/// MPI, with the `mpi` feature: the ranks of the launcher that started this process.
#[cfg(feature = "mpi")]
mod ranks {
    use mpi::topology::Communicator;
    pub use mpi::topology::SimpleCommunicator as World;

    /// Was this process started by an MPI launcher (mpirun, mpiexec, srun)?
    fn launched_by_mpi() -> bool {
        ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"]
            .iter()
            .any(|name| std::env::var_os(name).is_some())
    }

    /// MPI initialised when a launcher started this process (None otherwise), or Err when it
    /// could not be.
    pub fn start() -> Result<Option<mpi::environment::Universe>, ()> {
        match launched_by_mpi() {
            true => mpi::initialize_with_threading(mpi::Threading::Funneled)
                .map(|(universe, _)| Some(universe))
                .ok_or(()),
            false => Ok(None),
        }
    }

    pub fn world(universe: &Option<mpi::environment::Universe>) -> Option<World> {
        universe.as_ref().map(|u| u.world())
    }

    pub fn is_rank0(world: Option<&World>) -> bool {
        world.is_none_or(|w| w.rank() == 0)
    }

    pub use solver::run_on_ranks as run;
}

/// No MPI without the `mpi` feature: one process, and no value of `World` exists.
#[cfg(not(feature = "mpi"))]
mod ranks {
    pub enum World {}

    pub fn start() -> Result<Option<()>, ()> {
        Ok(None)
    }

    pub fn world(_: &Option<()>) -> Option<World> {
        None
    }

    pub fn is_rank0(_: Option<&World>) -> bool {
        true
    }

    pub fn run(
        world: &World,
        _: &solver::Case,
        _: bool,
    ) -> Result<Option<solver::Outcome>, solver::CaseError> {
        match *world {}
    }
}

fn main() -> ExitCode {
    // The machine's load before this run adds to it, for the record's provenance.
    solver::output::record::note_start();
    // MPI starts before anything can fail, so that every rank of a bad run finalizes and exits
    // with the same code instead of leaving mpirun to report a crash.
    let Ok(universe) = ranks::start() else {
        note("nlsolve: MPI could not be initialised");
        return ExitCode::FAILURE;
    };
    let world = ranks::world(&universe);
    let rank0 = ranks::is_rank0(world.as_ref());
    let result = parse_command_line()
        .map_err(Failure::from)
        .and_then(|cli| match cli.command {
            Command::Run(args) => run(&args, world.as_ref()),
            Command::Partition(args) => partition_report(&args),
            Command::Check => check_cases(),
            Command::Fingerprint => {
                print_line(solver::output::record::FINGERPRINT, "the fingerprint")
            }
        });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            let (status, message) = match failure {
                Failure::BadInput(message) => (EXIT_BAD_INPUT, message),
                Failure::Output(message) => (EXIT_IO, message),
            };
            if rank0 {
                note(&format!("nlsolve: {message}"));
            }
            ExitCode::from(status)
        }
    }
}

/// Runs the case (on every rank of `world` when started by MPI); rank 0 prints the record.
fn run(args: &RunArgs, world: Option<&ranks::World>) -> Result<(), Failure> {
    let case = args.case.case()?;
    if args.write_diagnostics.is_some() && case.diagnostics_every.is_none() {
        return Err(Failure::BadInput(
            "--write-diagnostics needs the series: set case field `diagnostics_every` (e.g. --diagnostics-every 0.01)".into(),
        ));
    }
    let outcome = match world {
        Some(world) => ranks::run(
            world,
            &case,
            args.write_field.is_some() || args.write_vtk.is_some(),
        ),
        None => solver::run(&case).map(Some),
    }
    .map_err(|e| BadInput(e.to_string()))?;
    let Some(outcome) = outcome else {
        return Ok(()); // not rank 0
    };
    if let Some(path) = &args.write_field {
        let bytes: Vec<u8> = outcome.field.iter().flat_map(|v| v.to_le_bytes()).collect();
        write_atomically(path, &bytes, "--write-field")?;
    }
    if let (Some(path), Some(series)) = (&args.write_diagnostics, &outcome.record.c_tot) {
        write_atomically(path, series.to_csv().as_bytes(), "--write-diagnostics")?;
    }
    if let Some(dir) = &args.write_vtk {
        write_vtk(dir, &outcome)?;
    }
    let line = serde_json::to_string(&outcome.record)
        .map_err(|e| Failure::Output(format!("cannot write the record: {e}")))?;
    print_line(&line, "the record")?;
    note(&summary(&outcome.record));
    Ok(())
}

/// Writes the outcome's frames (or its final field) into `dir` as `.vti` files, then the `.pvd`
/// collection: a reader that finds the collection finds every frame it lists.
fn write_vtk(dir: &Path, outcome: &Outcome) -> Result<(), Failure> {
    let t_final = outcome.record.steps_done as f64 * outcome.record.resolved.dt;
    let frames: Vec<(f64, &[f64])> = match outcome.frames.is_empty() {
        true => vec![(t_final, &outcome.field)],
        false => outcome
            .frames
            .iter()
            .map(|f| (f.time, &f.values[..]))
            .collect(),
    };
    std::fs::create_dir_all(dir).map_err(|e| {
        Failure::Output(format!(
            "cannot create {}: {e}; check the path given to --write-vtk",
            dir.display()
        ))
    })?;
    let names = vtk::frame_names(frames.len());
    for ((_, values), name) in frames.iter().zip(&names) {
        let bytes = vtk::image_data(&outcome.lattice, "u", values);
        write_atomically(&dir.join(name), &bytes, "--write-vtk")?;
    }
    let entries: Vec<(f64, String)> = frames.iter().map(|f| f.0).zip(names).collect();
    let collection = vtk::collection(&entries);
    write_atomically(&dir.join("u.pvd"), collection.as_bytes(), "--write-vtk")
}

/// Writes `bytes` to `path` through a temporary file, so that no half-written file is left; a
/// failure names the path and exits with `EXIT_IO` (an output lost, not a bad case).
fn write_atomically(path: &Path, bytes: &[u8], flag: &str) -> Result<(), Failure> {
    let partial = path.with_extension("partial");
    std::fs::write(&partial, bytes)
        .and_then(|()| std::fs::rename(&partial, path))
        .map_err(|e| {
            // Leave no partial file behind (it may not exist: ignore that).
            let _ = std::fs::remove_file(&partial);
            Failure::Output(format!(
                "cannot write {}: {e}; check the path given to {flag}",
                path.display()
            ))
        })
}

/// Prints the halo report of the case as one JSON line.
fn partition_report(args: &CaseArgs) -> Result<(), Failure> {
    let mut fields = args.fields()?;
    // The time step does not shape the partition; fill it in when absent.
    fields.entry("t_end").or_insert(Value::from(1.0));
    if !fields.contains_key("dt") {
        fields.entry("cfl").or_insert(Value::from(1.0));
    }
    let case = Case::parse(Value::Object(fields)).map_err(|e| BadInput(e.to_string()))?;
    let report = solver::partition_report(&case).map_err(|e| BadInput(e.to_string()))?;
    print_line(
        &serde_json::to_string(&report).expect("the report serializes"),
        "the partition report",
    )
}

/// `nlsolve check`: validates each case of standard input and prints its canonical form.
/// `nlsolve check`'s answer on a case whose fields are valid: its time step checked as `run`
/// would check it (`methods::preflight`), then `case` (which keys the run), `resolved` (the same
/// case as people read it) and, when this machine could not run it, `machine`: why, which a plan
/// reports without refusing (the case may run elsewhere).
fn verdict(
    case: &ValidCase,
    memo: &mut std::collections::HashMap<String, Result<f64, solver::case::CaseError>>,
    machine: solver::methods::resources::Machine,
) -> Value {
    if let Err(e) = solver::methods::preflight(case, memo) {
        return serde_json::json!({ "error": e.to_string() });
    }
    let mut verdict = serde_json::json!({ "case": **case, "resolved": case.resolved() });
    if let Err(e) = solver::methods::resources::fit(case, machine) {
        verdict["machine"] = Value::from(e.to_string());
    }
    verdict
}

fn check_cases() -> Result<(), Failure> {
    let failed = |e: std::io::Error| {
        Failure::Output(format!("cannot write the verdicts to standard output: {e}"))
    };
    // Flushed whenever no more input is waiting, so that a reader sending one case at a time
    // sees each verdict as its case is read, and many cases go out in large writes; on
    // `standard_output()`, so that a closed descriptor is an error too.
    let mut out = std::io::BufWriter::with_capacity(1 << 16, standard_output().map_err(failed)?);
    let mut input = std::io::BufReader::with_capacity(1 << 16, std::io::stdin().lock());
    let mut line = String::new();
    let mut printed = Vec::new();
    let mut memo = std::collections::HashMap::new();
    let machine = solver::methods::resources::Machine::now();
    loop {
        line.clear();
        let read = input
            .read_line(&mut line)
            .map_err(|e| BadInput(format!("cannot read standard input: {e}")))?;
        if read == 0 {
            break;
        }
        if !line.trim().is_empty() {
            let verdict = match schema::json::parse(&line) {
                Ok(fields) => match ValidCase::from_json(fields) {
                    Ok(case) => verdict(&case, &mut memo, machine),
                    Err(e) => serde_json::json!({ "error": e.to_string() }),
                },
                Err(e) => serde_json::json!({ "error": format!("not valid JSON: {e}") }),
            };
            printed.clear();
            serde_json::to_writer(&mut printed, &verdict).expect("a Value prints");
            printed.push(b'\n');
            out.write_all(&printed).map_err(failed)?;
        }
        if input.buffer().is_empty() {
            out.flush().map_err(failed)?;
        }
    }
    out.flush().map_err(failed)
}

#[cfg(test)]
mod tests {
    use super::*;

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
