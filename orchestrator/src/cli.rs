//! The `nlstudy` command line: its commands and flags, and what each command does with the
//! library's parts (study → plan → pool → store → collect → plot).

use crate::model::launcher::{Launcher, DEFAULT_LAUNCHER};
use crate::model::resources::Resources;
use crate::model::site::{Site, SITE_VARIABLE};
use crate::model::study::{fields_telling_apart, Study};
use crate::output::status;
use crate::run::cluster::scheduler::Scheduler;
use crate::run::cluster::submit;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{Decision, Options, Planned};
use crate::run::pool::PoolOptions;
use crate::run::progress::{Mode, Progress};
use crate::store::owner::Refusal;
use crate::store::{FileError, Index, Store};
use clap::{Args, Parser, Subcommand};
use std::fmt::Write as _;
use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "nlstudy",
    version,
    about = "Runs studies of nonlocal diffusion solvers."
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Print every point of the study, whether it will run and why; run nothing.
    Plan(PlanArgs),
    /// Run the points not yet stored (make-style) and store their records.
    Run(RunArgs),
    /// Gather the stored records into <results>/<study>/<study>.parquet (one row per run) and
    /// <study>-summary.parquet (one row per point, with speedups and convergence orders).
    Collect(CollectArgs),
    /// Draw the study's figures from its summary table into <results>/<study>/figures/, each
    /// only when its table or its spec changed.
    Plot(CommonArgs),
    /// Count the stored records by status and list the failures.
    Status(CommonArgs),
    /// Write <results>/<study>/report.html: one self-contained page with the study's description,
    /// its figures, the summary table, the runs by status, the failures and the provenance.
    Report(CommonArgs),
    /// Print values of the summary table as a Markdown table: rows by some fields, columns by
    /// another (e.g. `--rows branch,quadrature --column n --value order_l2`), or one column per
    /// value (e.g. `--rows n --value error_l2_norm,order_l2`).
    Table(TableArgs),
    /// Write Slurm or LSF job scripts for the points not yet stored, and submit them.
    Submit(SubmitArgs),
    /// Remove the figures no spec of the study draws any more, and list the stored records no
    /// point of the study has (deleted only with --yes).
    Clean(CleanArgs),
    /// Compare the study's stored runs (B, the new) with a baseline set of them (A), point by
    /// point: the ratio B/A of each metric's median over the repeats with a bootstrap 95 %
    /// interval, and a verdict; exits 1 when something got worse (for CI jobs).
    Compare(CompareArgs),
    /// Draw each point's metric against the date each solver build (fingerprint) first ran it,
    /// from the current records and the superseded ones in history/, into
    /// <results>/<study>/history.svg.
    History(HistoryArgs),
}

#[derive(Args)]
pub struct HistoryArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// A record field, or `<field>_median` for the median over the repeats, e.g. `step_s_median`.
    #[arg(long, default_value = "step_s_median")]
    metric: String,
}

#[derive(Args)]
pub struct CompareArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// The baseline A: `history` (the records that the current ones superseded, of the most
    /// recent other solver fingerprint), `fingerprint:PREFIX` (the stored or superseded records
    /// of the build whose fingerprint starts with PREFIX), or another results directory holding
    /// the same study.
    #[arg(long)]
    against: String,
    /// The smallest change of a timing that counts, as a fraction: with 0.1, B/A's interval
    /// must lie above 1.1 or below 1/1.1.
    #[arg(long, default_value_t = 0.1)]
    threshold: f64,
    /// Compare timings measured on unlike machines (another CPU model or instruction set).
    #[arg(long)]
    allow_unlike: bool,
    /// Compare a side whose runs come from several builds, hosts or instruction sets.
    #[arg(long)]
    allow_mixed: bool,
    /// B: the records of the build whose fingerprint starts with PREFIX (`fingerprint:PREFIX`,
    /// stored or superseded) instead of the study's current records: two past builds compared.
    #[arg(long)]
    of: Option<String>,
}

#[derive(Args)]
pub struct CleanArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Delete the records no point of the study has (without it they are only listed).
    #[arg(long)]
    yes: bool,
}

#[derive(Args)]
pub struct SubmitArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// The scheduler (default: the site profile's).
    #[arg(long, value_enum)]
    scheduler: Option<Scheduler>,
    /// The site profile: a name (NAME.toml in $NLSTUDY_SITES, ~/.config/nlstudy/sites or the
    /// project's sites/) or a path; default: $NLSTUDY_SITE. It sets the scheduler, partition,
    /// account, QoS, constraint, memory, exclusive nodes, modules, prologue, launcher, cores
    /// per node and default time of every job; the study and the flags override it.
    #[arg(long)]
    site: Option<String>,
    /// One job array per allocation shape (one scheduler call each), each element running a
    /// bundle of `--cases-per-job` points (default 1) with the in-job worker pool.
    #[arg(long)]
    array: bool,
    /// With --array: how many elements run at once (`%T`).
    #[arg(long, requires = "array")]
    throttle: Option<NonZeroUsize>,
    /// Write the scripts into results/<study>/jobs/ without submitting them.
    #[arg(long)]
    dry_run: bool,
    /// Each flag overrides the study's `resources` field of the same name.
    #[command(flatten)]
    resources: Resources,
    /// Each job's `nlstudy run --retries N`: a case that failed for a reason outside it runs again.
    #[arg(long, default_value_t = 0)]
    retries: usize,
    /// Submit the other points when the solver refuses some (see `plan --allow-refused`).
    #[arg(long)]
    allow_refused: bool,
    /// The MPI launcher inside each job, `{ranks}` where the rank count goes (default: the
    /// site's, else `srun --mpi=pmix -n {ranks}` under Slurm, `mpirun -n {ranks}` under LSF),
    /// e.g. for a site whose Slurm speaks PMI-2: `srun --mpi=pmi2 -n {ranks}`.
    #[arg(long)]
    launcher: Option<Launcher>,
}

#[derive(Args)]
pub struct CollectArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Tabulate runs of several solver builds (fingerprints), hosts or instruction sets
    /// together; by default such a mix is refused.
    #[arg(long)]
    allow_mixed: bool,
}

#[derive(Args)]
pub struct TableArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// The fields that name a line (comma-separated), e.g. `dim,quadrature`.
    #[arg(long, value_delimiter = ',')]
    rows: Vec<String>,
    /// The field whose values head the columns, e.g. `n`; without it, one column per value.
    #[arg(long)]
    column: Option<String>,
    /// The columns of the summary table in the cells (comma-separated, side by side), e.g.
    /// `error_l2_norm,order_l2`.
    #[arg(long, value_delimiter = ',', required = true)]
    value: Vec<String>,
    /// Conditions a point must meet, in the study language (repeatable).
    #[arg(long = "where")]
    filter: Vec<String>,
}

#[derive(Args)]
pub struct CommonArgs {
    /// The study file (JSON).
    study: PathBuf,
    /// Where results go: <results>/<study name>/runs/<key>.json.
    #[arg(long, default_value = "results")]
    results: PathBuf,
    /// The nlsolve binary (default: $NLSOLVE, else the one beside nlstudy).
    #[arg(long)]
    solver: Option<PathBuf>,
    /// Make this study file the owner of <results>/<study name>/ when another file of the same
    /// name owns it (its stored runs stay; points that are the same cases reuse them).
    #[arg(long)]
    adopt: bool,
}

#[derive(Args)]
pub struct PlanArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Run every point again, stored or not.
    #[arg(long)]
    force: bool,
    /// Run the points whose stored record failed.
    #[arg(long)]
    rerun_failed: bool,
    /// Only the points with these keys (comma-separated), as cluster jobs do.
    #[arg(long, value_delimiter = ',')]
    only: Option<Vec<String>>,
    /// Reuse stored records that a solver of another fingerprint made (by default they are
    /// stale and run again; the old record moves to <results>/<study>/history/).
    #[arg(long)]
    keep_stale: bool,
    /// Go on when the solver refuses some points (they are stored as failed); by default a
    /// refused point stops `plan`, `run` and `submit` before anything runs.
    #[arg(long)]
    allow_refused: bool,
}

#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    plan: PlanArgs,
    /// Cores the running cases may use together (threads × ranks each); default: all.
    #[arg(short = 'j', long)]
    jobs: Option<usize>,
    /// Seconds after which a case is stopped and stored as failed (overrides the study's).
    #[arg(long)]
    timeout: Option<f64>,
    /// Command prefix of MPI cases; `{ranks}` becomes the case's rank count.
    #[arg(long, default_value = DEFAULT_LAUNCHER)]
    launcher: Launcher,
    /// Run a case again, up to N more times, when it failed for a reason outside it (past its
    /// timeout, killed by a signal, its MPI launcher hung); the record keeps its `attempt`.
    /// Divergence and refused input are results and never run again.
    #[arg(long, default_value_t = 0)]
    retries: usize,
    /// No progress output.
    #[arg(long, short)]
    quiet: bool,
    /// Do not gather the records into the study's tables, nor draw its figures, at the end.
    #[arg(long)]
    no_collect: bool,
    /// At the end, tabulate runs of several solver builds, hosts or instruction sets together
    /// (see `collect --allow-mixed`).
    #[arg(long)]
    allow_mixed: bool,
}

mod builds;
#[cfg(test)]
mod fuzz;

/// nlstudy's exit statuses.
pub mod exit {
    /// Every case ran and stored `ok` or `diverged`, or the command did what it was asked.
    pub const OK: u8 = 0;
    /// A case failed (its record is stored `failed`), or a table or figure could not be made.
    pub const CASE_FAILED: u8 = 1;
    /// A bad study file, flag or value: nothing ran.
    pub const BAD_INPUT: u8 = 2;
    /// The results could not be read or written (a full disk, a path that is not a
    /// directory), or a program could not be started: nothing is stored for the cases that
    /// were running, and the next run takes them up again.
    pub const IO: u8 = 3;
    /// Stopped by Ctrl-C (SIGINT); what finished is stored. SIGTERM (a scheduler's warning,
    /// `scancel`, preemption) exits 143 and SIGHUP 129: 128 + the signal, as the shell's.
    pub const INTERRUPTED: u8 = 130;
}

/// Why a command stopped: the sentence for the user and the exit status that tells its kind.
#[derive(Debug)]
pub struct Failure {
    pub message: String,
    pub code: u8,
}

impl From<String> for Failure {
    fn from(message: String) -> Failure {
        Failure {
            message,
            code: exit::BAD_INPUT,
        }
    }
}

impl From<&str> for Failure {
    fn from(message: &str) -> Failure {
        Failure::from(message.to_string())
    }
}

impl From<crate::store::Fault> for Failure {
    fn from(fault: crate::store::Fault) -> Failure {
        use crate::store::Fault;
        let code = match &fault {
            Fault::Input(_) => exit::BAD_INPUT,
            Fault::Io(_) => exit::IO,
        };
        Failure {
            message: fault.to_string(),
            code,
        }
    }
}

impl From<FileError> for Failure {
    fn from(e: FileError) -> Failure {
        Failure {
            message: e.to_string(),
            code: exit::IO,
        }
    }
}

/// Runs one `nlstudy` command and says how it ended.
pub fn main(cli: Cli) -> ExitCode {
    let code = match execute(cli) {
        Ok(code) => code,
        Err(failure) => {
            say!("nlstudy: {}", failure.message);
            ExitCode::from(failure.code)
        }
    };
    match crate::console::stdout_failure() {
        Some(why) => {
            say!("nlstudy: cannot write to standard output: {why}");
            ExitCode::from(exit::IO)
        }
        None => code,
    }
}

/// Runs one `nlstudy` command.
pub fn execute(cli: Cli) -> Result<ExitCode, Failure> {
    match cli.command {
        Command::Plan(args) => plan_command(&args),
        Command::Run(args) => run_command(&args),
        Command::Collect(args) => collect_command(&args),
        Command::Plot(args) => plot_command(&args),
        Command::Status(args) => status_command(&args),
        Command::Report(args) => report_command(&args),
        Command::Table(args) => table_command(&args),
        Command::Submit(args) => submit_command(&args),
        Command::Clean(args) => clean_command(&args),
        Command::Compare(args) => builds::compare_command(&args),
        Command::History(args) => builds::history_command(&args),
    }
}

impl PlanArgs {
    fn options(&self) -> Options {
        Options {
            force: self.force,
            rerun_failed: self.rerun_failed,
            only: self
                .only
                .as_ref()
                .map(|keys| keys.iter().cloned().collect()),
            keep_stale: self.keep_stale,
        }
    }
}

/// The study file, its figures checked against the columns its tables will have.
fn read_study(path: &std::path::Path) -> Result<Study, String> {
    let study = Study::read(path).map_err(|e| e.to_string())?;
    crate::analysis::figure_columns::check(&study).map_err(|e| e.to_string())?;
    Ok(study)
}

/// The study's store, once the study file is known to own it (see `store::owner`); a command
/// that `writes` records the file as its owner.
fn open_store(args: &CommonArgs, study: &Study, writes: bool) -> Result<Store, Failure> {
    let store = Store::open(&args.results, &study.name);
    claim(args, study, &store, writes)?;
    Ok(store)
}

/// Checks that the study file owns `store`, and with `writes` records it as the owner.
fn claim(args: &CommonArgs, study: &Study, store: &Store, writes: bool) -> Result<(), Failure> {
    let text = std::fs::read_to_string(&args.study).unwrap_or_default();
    match store.claim(&args.study, &text, args.adopt, writes) {
        Ok(()) => Ok(()),
        Err(Refusal::Io(e)) => Err(e.into()),
        Err(Refusal::OwnedBy(owner)) => Err(format!(
            "{} holds the results of another study file of the same name `{}`: {}; give this study its own `name`, or --adopt to make {} the owner (the stored runs stay, and its points that are the same cases reuse them)",
            store.table("").display(),
            study.name,
            owner.display(),
            args.study.display()
        )
        .into()),
    }
}

/// The study, its solver and store, and the plan of its points; see `open_store` for `writes`.
fn planned(
    args: &CommonArgs,
    options: &Options,
    writes: bool,
) -> Result<(Study, Nlsolve, Store, Vec<Planned>), Failure> {
    let (study, solver, store, _, planned) = planned_and_index(args, options, writes)?;
    Ok((study, solver, store, planned))
}

/// `planned`, with the store's index it planned against.
fn planned_and_index(
    args: &CommonArgs,
    options: &Options,
    writes: bool,
) -> Result<(Study, Nlsolve, Store, Index, Vec<Planned>), Failure> {
    let study = read_study(&args.study)?;
    let solver = Nlsolve::locate(args.solver.as_deref())?;
    let store = open_store(args, &study, writes)?;
    let index = store.index();
    for unreadable in &index.unreadable {
        say!("nlstudy: warning: {unreadable}");
    }
    let planned = crate::run::plan::plan(&study, &solver, &index, options)?;
    Ok((study, solver, store, index, planned))
}

fn plan_command(args: &PlanArgs) -> Result<ExitCode, Failure> {
    let (study, solver, _, planned) = planned(&args.common, &args.options(), false)?;
    tell!(
        "study {}: {} points, solver {}",
        study.name,
        planned.len(),
        solver.version
    );
    if !study.description.is_empty() {
        tell!("{}", study.description);
    }
    // Written 64 kB at a time: a line at a time is a system call each at 10⁵ points, and all
    // at once a hundred megabytes at 10⁶.
    let mut listing = String::new();
    for p in &planned {
        if listing.len() >= 1 << 16 {
            tell_raw!("{listing}");
            listing.clear();
        }
        let what = match &p.decision {
            Decision::Run(reason) => format!("run   ({reason})"),
            Decision::Skip(status) => format!("skip  ({status})"),
            Decision::Duplicate => "skip  (the same case as an earlier point)".into(),
        };
        // Said once per distinct sentence below.
        let refused = match &p.case {
            Err(_) => "  refused",
            Ok(_) => "",
        };
        let _ = writeln!(
            listing,
            "{}  {what:<40} {}{refused}",
            p.key,
            p.point.label()
        );
    }
    tell_raw!("{listing}");
    let runs = planned.iter().filter(|p| p.runs()).count();
    let duplicates = planned
        .iter()
        .filter(|p| p.decision == Decision::Duplicate)
        .count();
    let shared = match duplicates {
        0 => String::new(),
        n => format!(", {n} the same case as an earlier point"),
    };
    tell!(
        "{runs} to run, {} stored{shared}",
        planned.len() - runs - duplicates
    );
    say_what_does_not_fit(&planned);
    no_refusals(&planned, args.allow_refused)?;
    Ok(ExitCode::SUCCESS)
}

/// Names the points to run that this machine could not (memory, cores): `run` would store them
/// failed here, a cluster may run them (`submit`), so they are said, not refused.
fn say_what_does_not_fit(planned: &[Planned]) {
    let crowded: Vec<(&Planned, &str)> = planned
        .iter()
        .filter(|p| p.runs())
        .filter_map(|p| Some((p, p.case.as_ref().ok()?.machine.as_deref()?)))
        .collect();
    if let Some((first, why)) = crowded.first() {
        say!(
            "nlstudy: {} points to run do not fit this machine, and would fail if run here (the first, {}: {why}); `nlstudy submit` them to a cluster, or make them smaller",
            crowded.len(),
            first.point.label()
        );
    }
}

/// Stops a command when the solver refused points (unless `allowed`): each distinct refusal
/// once, with the number of points it refused.
fn no_refusals(planned: &[Planned], allowed: bool) -> Result<(), Failure> {
    let refusals = crate::run::plan::refusals(planned);
    if refusals.is_empty() {
        return Ok(());
    }
    let points: usize = refusals.iter().map(|r| r.points).sum();
    let text = crate::run::plan::describe_refusals(&refusals);
    if allowed {
        say!("nlstudy: warning: the solver refuses {points} points; they are stored as failed:\n{text}");
        return Ok(());
    }
    Err(format!(
        "the solver refuses {points} of the study's points, so nothing runs:\n{text}\nfix the study file, or give --allow-refused to run the other points and store these as failed"
    )
    .into())
}

fn run_command(args: &RunArgs) -> Result<ExitCode, Failure> {
    let (study, solver, store, planned) = planned(&args.plan.common, &args.plan.options(), true)?;
    no_refusals(&planned, args.plan.allow_refused)?;
    say_what_does_not_fit(&planned);
    let cores = crate::run::pool::machine_cores();
    let timeout = match args.timeout {
        Some(seconds) => Some(timeout(seconds, "--timeout")?),
        None => study
            .timeout_s
            .map(|s| timeout(s, "timeout_s"))
            .transpose()?,
    };
    let options = PoolOptions {
        cores: args.jobs.unwrap_or(cores).max(1),
        exclusive: !study.share_machine,
        timeout,
        launcher: args.launcher.clone(),
        retries: args.retries,
    };
    store.clear_abandoned_outputs()?;
    let stop = crate::run::signals::Stop::on_signals()?;
    let to_run = planned.iter().filter(|p| p.runs()).count();
    let duplicates = planned
        .iter()
        .filter(|p| p.decision == Decision::Duplicate)
        .count();
    let skipped = planned.len() - to_run - duplicates;
    let mut progress = Progress::new(Mode::detect(args.quiet), to_run, skipped);
    let tally = crate::run::pool::run(&planned, &solver, &store, &options, &stop, &mut progress);
    progress.close();
    let tally = tally.map_err(|e| Failure {
        message: format!("{e}; the cases that were running are not stored and run again next time"),
        code: exit::IO,
    })?;
    if !args.quiet {
        let passed = match tally.passed {
            0 => String::new(),
            n => format!(", {n} run by another nlstudy"),
        } + &match duplicates {
            0 => String::new(),
            n => format!(", {n} the same case as an earlier point"),
        };
        say!(
            "study {}: {} ran ({} ok, {} diverged, {} failed), {skipped} already stored{passed}",
            study.name,
            tally.ok + tally.diverged + tally.failed,
            tally.ok,
            tally.diverged,
            tally.failed,
        );
        if tally.noisy > 0 {
            say!(
                "  {} of them noisy: timed while other tasks wanted the cores they left free; their timings measure contention too (`nlstudy run --force` them on a quiet machine)",
                tally.noisy
            );
        }
    }
    if let Some(signal) = stop.signal().filter(|_| tally.interrupted) {
        say!(
            "nlstudy: stopped by {}; what finished is stored, run again to resume",
            crate::run::signals::name(signal)
        );
        return Ok(ExitCode::from(
            stop.exit_code().unwrap_or(exit::INTERRUPTED),
        ));
    }
    if !args.no_collect {
        let tables = crate::analysis::collect::collect(&planned, &store, &study, args.allow_mixed)
            .and_then(|collected| match collected {
                Some(collected) => {
                    let figures = crate::output::plot::plot(&study.figures, &store)?;
                    let swept = fields_telling_apart(planned.iter().map(|p| &p.point));
                    let page = crate::output::report::write(&study, &store, &swept)?;
                    if !args.quiet {
                        print_tables_written(&collected);
                        print_figures_drawn(&figures);
                        say!("report: {}", page.display());
                    }
                    Ok(crate::output::plot::all_drawn(&figures).err())
                }
                None => Ok(None),
            });
        // A table or figure that cannot be made of these runs exits 1; a file that cannot be
        // read or written, 3.
        let (message, code) = match tables {
            Ok(None) => (None, exit::OK),
            Ok(Some(figures)) => (Some(figures), exit::CASE_FAILED),
            Err(crate::store::Fault::Input(m)) => (Some(m), exit::CASE_FAILED),
            Err(crate::store::Fault::Io(m)) => (Some(m), exit::IO),
        };
        if let Some(message) = message {
            say!("nlstudy: {message}; the runs are stored");
            return Ok(ExitCode::from(code));
        }
    }
    Ok(match tally.failed {
        0 => ExitCode::SUCCESS,
        _ => ExitCode::from(exit::CASE_FAILED),
    })
}

/// The longest timeout taken: about 31 years, past any allocation.
const LONGEST_TIMEOUT_S: f64 = 1e9;

/// A case's timeout from `field`: a positive, finite number of seconds.
fn timeout(seconds: f64, field: &str) -> Result<Duration, Failure> {
    if !seconds.is_finite() {
        return Err(format!(
            "{field}: {seconds} is not a finite number; give a number of seconds, or none for no limit"
        )
        .into());
    }
    if !(seconds > 0.0 && seconds <= LONGEST_TIMEOUT_S) {
        return Err(format!(
            "{field}: {seconds} is not a timeout; give a number of seconds above 0 and at most {LONGEST_TIMEOUT_S:e}, or none for no limit"
        )
        .into());
    }
    Ok(Duration::from_secs_f64(seconds))
}

fn collect_command(args: &CollectArgs) -> Result<ExitCode, Failure> {
    let allow_mixed = args.allow_mixed;
    let args = &args.common;
    let (study, _, store, planned) = planned(args, &Options::default(), true)?;
    let collected = crate::analysis::collect::collect(&planned, &store, &study, allow_mixed)?
        .ok_or_else(|| {
            format!(
                "nothing to collect: no run of study {} is stored yet; `nlstudy run` it first",
                store.study
            )
        })?;
    print_tables_written(&collected);
    let swept = fields_telling_apart(planned.iter().map(|p| &p.point));
    tell_raw!(
        "{}",
        crate::analysis::collect::overview(&collected.table, &swept)
    );
    Ok(ExitCode::SUCCESS)
}

fn plot_command(args: &CommonArgs) -> Result<ExitCode, Failure> {
    let study = read_study(&args.study)?;
    if study.figures.is_empty() {
        return Err(format!(
            "study {} lists no figures; add a `figures` list to {}",
            study.name,
            args.study.display()
        )
        .into());
    }
    let store = open_store(args, &study, true)?;
    let figures = crate::output::plot::plot(&study.figures, &store)?;
    print_figures_drawn(&figures);
    crate::output::plot::all_drawn(&figures).map_err(|message| Failure {
        message,
        code: exit::CASE_FAILED,
    })?;
    Ok(ExitCode::SUCCESS)
}

fn table_command(args: &TableArgs) -> Result<ExitCode, Failure> {
    let study = read_study(&args.common.study)?;
    let store = open_store(&args.common, &study, false)?;
    let path = store.table(&format!("{}-summary.parquet", study.name));
    if !path.exists() {
        return Err(format!(
            "{} does not exist; `nlstudy collect {}` writes it",
            path.display(),
            args.common.study.display()
        )
        .into());
    }
    // A table and its sum are read as one collect wrote them (on a read-only copy, unlocked).
    let _outputs = store.lock_outputs().ok();
    let spec = crate::analysis::pivot::PivotSpec {
        rows: args.rows.clone(),
        column: args.column.clone(),
        values: args.value.clone(),
        filter: args.filter.clone(),
    };
    tell_raw!(
        "{}",
        crate::analysis::pivot::markdown(&spec, &crate::store::table::read_parquet(&path)?)?
    );
    Ok(ExitCode::SUCCESS)
}

fn print_figures_drawn(figures: &[crate::output::plot::Figure]) {
    use crate::output::plot::Outcome;
    for figure in figures {
        let what = match figure.outcome {
            Outcome::Drawn => "drawn",
            Outcome::UpToDate => "up to date",
            Outcome::Failed(_) => "not drawn",
        };
        say!("figure {what}: {}", figure.path.display());
    }
}

fn print_tables_written(collected: &crate::analysis::collect::Collected) {
    say!(
        "tables: {} ({} runs), {} ({} points)",
        collected.runs.display(),
        collected.rows,
        collected.summary.display(),
        collected.points
    );
    if collected.missing > 0 {
        say!(
            "  {} runs of the study are not stored yet",
            collected.missing
        );
    }
    if collected.left_out > 0 {
        say!(
            "  {} stored records are left out: their points are no longer in the study or were run by another solver version",
            collected.left_out
        );
    }
}

/// Needs no solver: a report of a results folder copied to a laptop is made from its tables.
fn report_command(args: &CommonArgs) -> Result<ExitCode, Failure> {
    let study = read_study(&args.study)?;
    let store = open_store(args, &study, true)?;
    let points = study.expand().map_err(|e| e.to_string())?;
    let swept = fields_telling_apart(&points);
    let page = crate::output::report::write(&study, &store, &swept)?;
    tell!("report: {}", page.display());
    Ok(ExitCode::SUCCESS)
}

fn status_command(args: &CommonArgs) -> Result<ExitCode, Failure> {
    let (study, _, store, index, planned) = planned_and_index(args, &Options::default(), false)?;
    tell_raw!("{}", status::render(&study.name, &store, &index, &planned));
    Ok(ExitCode::SUCCESS)
}

fn submit_command(args: &SubmitArgs) -> Result<ExitCode, Failure> {
    let site = match args
        .site
        .clone()
        .or_else(|| std::env::var(SITE_VARIABLE).ok())
    {
        Some(name) => Site::find(&name)?,
        None => Site::default(),
    };
    let scheduler = match (args.scheduler, site.scheduler) {
        (Some(given), Some(site_s)) if given != site_s => {
            return Err(format!(
                "--scheduler {given} but the site profile {} is for {site_s}; drop one",
                site.file.display()
            )
            .into())
        }
        (Some(s), _) | (None, Some(s)) => s,
        (None, None) => {
            return Err(format!(
                "which scheduler? give --scheduler slurm|lsf, or a site profile (--site NAME or {SITE_VARIABLE})"
            )
            .into())
        }
    };
    site.check_for(scheduler)?;
    let (study, solver, store, index, planned) =
        planned_and_index(&args.common, &Options::default(), true)?;
    no_refusals(&planned, args.allow_refused)?;
    let explicit = study.resources.overridden_by(&args.resources);
    let target = submit::Target {
        scheduler,
        resources: site.defaults().overridden_by(&explicit),
        time: explicit.time,
        site,
        array: args.array,
        throttle: args.throttle,
        results: args.common.results.clone(),
        study_file: args.common.study.clone(),
        dry_run: args.dry_run,
        retries: args.retries,
        launcher: args.launcher.clone(),
    };
    submit::submit_study(&study, &solver, &planned, &store, &index, &target)?;
    Ok(ExitCode::SUCCESS)
}

fn clean_command(args: &CleanArgs) -> Result<ExitCode, Failure> {
    let (study, _, store, planned) = planned(&args.common, &Options::default(), true)?;
    let cleaned = crate::output::clean::clean(&study, &store, &planned, args.yes)?;
    for figure in &cleaned.figures {
        tell!("removed figures/{figure}: no figure of the study draws it");
    }
    if cleaned.orphans.is_empty() {
        tell!("every stored record is a point of study {}", study.name);
        return Ok(ExitCode::SUCCESS);
    }
    for (key, case) in &cleaned.orphans {
        // A record on disk may hold anything: escaped for the terminal.
        tell!("{key}  {}", case.escape_debug());
    }
    let count = cleaned.orphans.len();
    if cleaned.deleted {
        tell!(
            "deleted {count} records that are no point of study {}",
            study.name
        );
    } else {
        tell!(
            "{count} stored records are no point of study {} (removed from its sweep, or run by another solver version); `nlstudy clean --yes` deletes them",
            study.name
        );
    }
    Ok(ExitCode::SUCCESS)
}
