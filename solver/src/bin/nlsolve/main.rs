//! `nlsolve`: runs one case and prints its record as one JSON line on stdout, with a short human
//! summary on stderr.
//!
//! Exit statuses (`schema::exit`, also in `--help`): 0 when the record (the report, the
//! verdicts) was written; 1 when MPI could not start; 2 for bad input, with one sentence naming
//! the field; 3 when the record, the verdicts or a `--write-*` file could not be written, with
//! one line saying what and why. A failed write to stderr (the summary, a message) is ignored:
//! there is nowhere left to report it, and it says nothing about the result.

mod connect;
mod files;
mod flags;
mod stdout;
mod summary;

use clap::error::ErrorKind;
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use connect::ServeArgs;
use files::{write_atomically, write_vtk};
use flags::CaseArgs;
use schema::exit;
use schema::protocol::{self, Verdict};
use serde_json::Value;
use solver::case::Case;
use solver::ValidCase;
use std::io::{BufRead, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use stdout::{note, print_line, standard_output};
use summary::summary;

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
    /// method uses filled in; `needs` its threads and the memory it needs available, and `machine` why
    /// this machine could not run it, where it could not) or `{"error": "…"}` naming the field
    /// at fault.
    Check,
    /// Serve cases, one process for many: reads one JSON case per line on standard input and
    /// prints one line for each, as soon as it has run: the record `run` prints for it (its
    /// timings, load and peak memory its own), or `{"error": "…"}` naming the field at fault.
    /// What a study's worker pool keeps up, so that a point costs no process start. One
    /// process: a case on more than one rank is refused (start it with a launcher).
    Serve(ServeArgs),
    /// Print what this machine offers a run, as `{"cores", "most_threads", "available_bytes"}`
    /// (`available_bytes` null where it cannot be read): a case whose `threads` and whose
    /// `needs.bytes` (from `check`) are within them fits here. (Both lines are the types of
    /// `schema::protocol`.)
    Machine,
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
    /// Checkpoint the time loop into FILE (written beside it, then renamed over it) at the
    /// periods below and on SIGTERM, SIGINT or SIGHUP, which then end the run with 128 + the
    /// signal's number (143 for SIGTERM) and no record; a run started where FILE holds a checkpoint of the same case, build and rank
    /// count resumes from it, with the record of a run never stopped (`resumed_from_step`).
    /// FILE is removed once the record is written. Over MPI ranks each rank writes its own
    /// share, rank r > 0 into FILE.rank<r>, all at the same step; a run resumes when every rank
    /// finds its file at one step. A steady solve (steady_cg, feti) checkpoints CG's state
    /// between iterations: its steps are CG iterations.
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<PathBuf>,
    /// With --checkpoint: also every N steps.
    #[arg(long, value_name = "N", requires = "checkpoint")]
    checkpoint_every_steps: Option<usize>,
    /// With --checkpoint: also once SECONDS of wall time have passed since the last one.
    #[arg(long, value_name = "SECONDS", requires = "checkpoint")]
    checkpoint_every_seconds: Option<f64>,
    /// Keep FILE up to date with how far the time loop is (`{"step", "steps", "elapsed_s",
    /// "left_s"}`, at most once a second); removed when the loop ends.
    #[arg(long, value_name = "FILE")]
    progress: Option<PathBuf>,
    /// With --checkpoint: keep FILE after the record is written.
    #[arg(long, requires = "checkpoint")]
    keep_checkpoint: bool,
    /// Take the ends of L_h's spectrum from DIR, where the study's other runs left them, and
    /// leave them there when measured (one checksummed entry per operator; a damaged or
    /// foreign entry is measured again and replaced).
    #[arg(long, value_name = "DIR")]
    spectra: Option<PathBuf>,
}

/// Bad input: a message for the user, exit code 2.
struct BadInput(String);

/// Why nlsolve stops without success; each kind has its exit status.
enum ErrorExit {
    /// Bad input: one sentence naming the field, `exit::BAD_INPUT`.
    BadInput(String),
    /// An output could not be written (the message names it and the error): `exit::IO`.
    Output(String),
}

impl From<BadInput> for ErrorExit {
    fn from(BadInput(message): BadInput) -> Self {
        ErrorExit::BadInput(message)
    }
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
        "{}\n`nlsolve run` takes these flags:\n\n{run_help}",
        exit::nlsolve_help()
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

    /// This process's rank and the ranks in all (0 of 1 without MPI).
    pub fn rank_of(world: Option<&World>) -> (usize, usize) {
        world.map_or((0, 1), |w| (w.rank() as usize, w.size() as usize))
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

    pub fn rank_of(_: Option<&World>) -> (usize, usize) {
        (0, 1)
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
        return ExitCode::from(exit::CASE_FAILED);
    };
    let world = ranks::world(&universe);
    let rank0 = ranks::is_rank0(world.as_ref());
    let result = parse_command_line()
        .map_err(ErrorExit::from)
        .and_then(|cli| match cli.command {
            Command::Run(args) => run(&args, world.as_ref()),
            Command::Partition(args) => partition_report(&args),
            Command::Check => check_cases(),
            Command::Serve(args) => serve_cases(&args),
            Command::Machine => print_machine(),
            Command::Fingerprint => {
                print_line(solver::output::record::FINGERPRINT, "the fingerprint")
            }
        });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            let (status, message) = match failure {
                ErrorExit::BadInput(message) => (exit::BAD_INPUT, message),
                ErrorExit::Output(message) => (exit::IO, message),
            };
            if rank0 {
                note(&format!("nlsolve: {message}"));
            }
            ExitCode::from(status)
        }
    }
}

/// Runs the case (on every rank of `world` when started by MPI); rank 0 prints the record.
fn run(args: &RunArgs, world: Option<&ranks::World>) -> Result<(), ErrorExit> {
    let case = args.case.case()?;
    if args.write_diagnostics.is_some() && case.diagnostics_every.is_none() {
        return Err(ErrorExit::BadInput(
            "--write-diagnostics needs the series: set case field `diagnostics_every` (e.g. --diagnostics-every 0.01)".into(),
        ));
    }
    let (rank, _) = ranks::rank_of(world);
    if let Some(path) = &args.checkpoint {
        start_checkpoints(args, path, &case, rank)?;
    }
    if ranks::is_rank0(world) {
        solver::integrate::progress::configure(args.progress.clone());
    }
    solver::integrate::spectra::configure(args.spectra.clone());
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
        // Not rank 0: its share of the run is over.
        if !args.keep_checkpoint {
            solver::integrate::checkpoint::remove_own();
        }
        return Ok(());
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
    let mut record = outcome.record;
    record.wall_s = solver::output::usage::run_wall_s();
    let line = serde_json::to_string(&record)
        .map_err(|e| ErrorExit::Output(format!("cannot write the record: {e}")))?;
    print_line(&line, "the record")?;
    if !args.keep_checkpoint {
        solver::integrate::checkpoint::remove_own();
    }
    note(&summary(&record));
    Ok(())
}

/// Sets up the run's checkpoints (`--checkpoint`): what to resume from, when to write, and
/// SIGTERM as the request to write one and stop. A checkpoint file of another run is refused
/// on stderr and the run starts at step 0. Over ranks, `rank` writes its own file
/// (`checkpoint::rank_path`).
fn start_checkpoints(
    args: &RunArgs,
    path: &std::path::Path,
    case: &ValidCase,
    rank: usize,
) -> Result<(), ErrorExit> {
    use solver::integrate::checkpoint::{self, Policy};
    let path = &checkpoint::rank_path(path, rank);
    let every = match args.checkpoint_every_seconds {
        Some(s) if !(s.is_finite() && s > 0.0) => {
            return Err(ErrorExit::BadInput(format!(
                "--checkpoint-every-seconds: must be a positive number of seconds (got {s})"
            )))
        }
        seconds => seconds.map(std::time::Duration::from_secs_f64),
    };
    let policy = Policy {
        path: path.to_path_buf(),
        every_steps: args.checkpoint_every_steps.filter(|&n| n > 0),
        every,
    };
    let refused = checkpoint::configure_for(case, policy, rank).map_err(BadInput)?;
    if let Some(why) = refused {
        note(&format!(
            "nlsolve: checkpoint {} refused: {why}; the run starts at step 0",
            path.display()
        ));
    }
    checkpoint::stop_on_signals();
    Ok(())
}

/// Prints the halo report of the case as one JSON line.
fn partition_report(args: &CaseArgs) -> Result<(), ErrorExit> {
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
/// case as people read it), `needs` (its threads and the memory it needs, from `resources::fit`)
/// and, when this machine could not run it, `machine`: why, which a plan reports without
/// refusing (the case may run elsewhere).
fn verdict(
    case: &ValidCase,
    memo: &mut std::collections::HashMap<String, Result<f64, solver::case::CaseError>>,
    machine: solver::methods::resources::Machine,
) -> Verdict {
    if let Err(e) = solver::methods::preflight(case, memo) {
        return refused(e.to_string());
    }
    let object = |value: Value| match value {
        Value::Object(fields) => fields,
        _ => unreachable!("a case serializes as an object"),
    };
    let (needs_bytes, fits) = solver::methods::resources::fit(case, machine);
    Verdict::Checked(protocol::Checked {
        case: object(serde_json::to_value(&**case).expect("a case serializes")),
        resolved: object(case.resolved()),
        needs: protocol::Needs {
            threads: case.threads as u64,
            bytes: needs_bytes.ceil() as u64,
        },
        machine: fits.err().map(|e| e.to_string()),
    })
}

fn refused(error: String) -> Verdict {
    Verdict::Refused(protocol::Refusal { error })
}

fn print_machine() -> Result<(), ErrorExit> {
    let machine = solver::methods::resources::Machine::now();
    let line = protocol::Machine {
        cores: machine.cores as u64,
        most_threads: machine.most_threads() as u64,
        available_bytes: machine.available.map(|bytes| bytes.floor() as u64),
    };
    print_line(
        &serde_json::to_string(&line).expect("the machine serializes"),
        "the machine",
    )
}

fn check_cases() -> Result<(), ErrorExit> {
    let mut memo = std::collections::HashMap::new();
    let machine = solver::methods::resources::Machine::now();
    answer_each_line(
        "the verdicts",
        false,
        |line| {
            let verdict = match schema::json::parse(line) {
                Ok(fields) => match ValidCase::from_json(fields) {
                    Ok(case) => verdict(&case, &mut memo, machine),
                    Err(e) => refused(e.to_string()),
                },
                Err(e) => refused(format!("not valid JSON: {e}")),
            };
            serde_json::to_string(&verdict).expect("a verdict serializes")
        },
        || {},
    )
}

/// Answers each line of standard input that is not blank with one line on standard output
/// (`what` names them in an error): `check`'s verdicts and `serve`'s records. Flushed after
/// each answer with `flush_each` (then `answered` runs), else whenever no more input is
/// waiting, so that a reader sending one case at a time sees each answer as its case is read
/// and many cases go out in large writes; on `standard_output()`, so that a closed descriptor
/// is an error too.
fn answer_each_line(
    what: &str,
    flush_each: bool,
    answer: impl FnMut(&str) -> String,
    answered: impl FnMut(),
) -> Result<(), ErrorExit> {
    let out = standard_output()
        .map_err(|e| ErrorExit::Output(format!("cannot write {what} to standard output: {e}")))?;
    let lines = Lines {
        input: std::io::stdin().lock(),
        out,
        from: "standard input",
        to: "standard output",
    };
    answer_lines(lines, what, flush_each, answer, answered)
}

/// Where answers are read from and written to, named for errors.
struct Lines<R, W> {
    input: R,
    out: W,
    from: &'static str,
    to: &'static str,
}

/// `answer_each_line` over any `Lines`: standard input and output, or `serve --connect`'s
/// connection.
fn answer_lines(
    lines: Lines<impl std::io::Read, impl Write>,
    what: &str,
    flush_each: bool,
    mut answer: impl FnMut(&str) -> String,
    mut answered: impl FnMut(),
) -> Result<(), ErrorExit> {
    let failed =
        |e: std::io::Error| ErrorExit::Output(format!("cannot write {what} to {}: {e}", lines.to));
    let mut out = std::io::BufWriter::with_capacity(1 << 16, lines.out);
    let mut input = std::io::BufReader::with_capacity(1 << 16, lines.input);
    let mut line = String::new();
    loop {
        line.clear();
        let read = input
            .read_line(&mut line)
            .map_err(|e| BadInput(format!("cannot read {}: {e}", lines.from)))?;
        if read == 0 {
            break;
        }
        if !line.trim().is_empty() {
            let mut printed = answer(&line);
            printed.push('\n');
            out.write_all(printed.as_bytes()).map_err(failed)?;
        }
        if flush_each || input.buffer().is_empty() {
            out.flush().map_err(failed)?;
        }
        if flush_each {
            answered();
        }
    }
    out.flush().map_err(failed)
}

/// `nlsolve serve`'s answer to one line of input: the record's JSON, or `{"error": …}`. A line
/// is a case, or a `protocol::ServeLine`: the case with the file its time loop keeps
/// up to date with how far it is (as `run --progress`) and the checkpoint it writes on a
/// stopping signal and resumes from (as `run --checkpoint`).
/// Returns the answer and whether to remove the checkpoint it wrote or resumed from once the
/// answer is out.
fn served(line: &str) -> (String, bool) {
    let refusal = |message: String| {
        serde_json::to_string(&protocol::Refusal { error: message }).expect("a refusal serializes")
    };
    let error = |message: String| (refusal(message), false);
    let fields = match schema::json::parse(line) {
        Ok(fields @ Value::Object(_)) => fields,
        Ok(_) => return error("a case is one JSON object of case fields".into()),
        Err(e) => return error(format!("not valid JSON: {e}")),
    };
    let line = match fields.get("case") {
        Some(_) => match serde_json::from_value::<protocol::ServeLine>(fields) {
            Ok(line) => line,
            Err(e) => {
                return error(format!(
                    "{e}; a line is a case, or {{\"case\": …, \"progress\": FILE, \"checkpoint\": FILE}}"
                ))
            }
        },
        None => protocol::ServeLine {
            case: fields,
            progress: None,
            checkpoint: None,
            checkpoint_every_s: None,
            keep_checkpoint: false,
            spectra: None,
        },
    };
    solver::integrate::progress::configure(line.progress.as_ref().map(PathBuf::from));
    solver::integrate::spectra::configure(line.spectra.as_ref().map(PathBuf::from));
    let case = match ValidCase::from_json(line.case) {
        Ok(case) if case.ranks > 1 => {
            return error(format!(
                "case field `ranks`: {} ranks need a launcher; run the case as `mpirun -n {0} nlsolve run`",
                case.ranks
            ))
        }
        Ok(case) => case,
        Err(e) => return error(e.to_string()),
    };
    let checkpoint = line.checkpoint.as_ref().map(PathBuf::from);
    if let Some(path) = &checkpoint {
        let every = match line.checkpoint_every_s {
            Some(s) if !(s.is_finite() && s > 0.0) => {
                return error(format!(
                    "`checkpoint_every_s`: must be a positive number of seconds (got {s})"
                ))
            }
            seconds => seconds.map(std::time::Duration::from_secs_f64),
        };
        let policy = solver::integrate::checkpoint::Policy {
            path: path.clone(),
            every_steps: None,
            every,
        };
        match solver::integrate::checkpoint::configure_for(&case, policy, 0) {
            Err(why) => return error(why),
            Ok(Some(why)) => note(&format!(
                "nlsolve: checkpoint {} refused: {why}; the run starts at step 0",
                path.display()
            )),
            Ok(None) => {}
        }
    }
    // Each case's provenance and peak memory are its own, as if it ran in a process of its own.
    solver::output::record::note_start();
    solver::output::record::reset_peak_memory();
    let answer = match solver::run(&case) {
        Ok(outcome) => serde_json::to_string(&schema::record::Record {
            wall_s: solver::output::usage::run_wall_s(),
            ..outcome.record
        })
        .unwrap_or_else(|e| refusal(format!("cannot write the record: {e}"))),
        Err(e) => refusal(e.to_string()),
    };
    (answer, checkpoint.is_some() && !line.keep_checkpoint)
}

/// `nlsolve serve`: runs each case of standard input and prints its answer line at once; with
/// `--connect`, of a connection to the pool that started it instead.
/// A stopping signal (SIGTERM, SIGINT, SIGHUP) ends it: at once between cases and in a case's
/// set-up, with a checkpoint from a case's time loop when the case has one, and after its answer
/// when it came once the loop was over.
fn serve_cases(args: &ServeArgs) -> Result<(), ErrorExit> {
    solver::integrate::checkpoint::stop_on_signals();
    // Whether the checkpoint of the case answered last goes once its answer is out.
    let remove = std::cell::Cell::new(false);
    let answer = |line: &str| {
        let (answer, remove_checkpoint) = served(line);
        remove.set(remove_checkpoint);
        answer
    };
    let answered = || {
        if remove.take() {
            solver::integrate::checkpoint::remove_own();
        }
        solver::integrate::checkpoint::between_cases();
    };
    match &args.connect {
        None => answer_each_line("the records", true, answer, answered),
        Some(address) => {
            let stream = connect::dial(address)?;
            let input = stream
                .try_clone()
                .map_err(|e| ErrorExit::Output(format!("cannot read {address}: {e}")))?;
            let lines = Lines {
                input,
                out: stream,
                from: "the pool's connection",
                to: "the pool's connection",
            };
            answer_lines(lines, "the records", true, answer, answered)
        }
    }
}
