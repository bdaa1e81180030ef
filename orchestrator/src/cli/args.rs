//! The `nlstudy` command line as one table: every command and flag with its help text. What
//! the commands do with them is in `commands`, one module each.

use crate::model::launcher::{Launcher, DEFAULT_LAUNCHER};
use crate::model::resources::Resources;
use crate::run::cluster::scheduler::Scheduler;
use crate::run::plan::Options;
use clap::{Args, Parser, Subcommand};
use std::num::NonZeroUsize;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "nlstudy",
    version,
    about = "Runs studies of nonlocal diffusion solvers."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Say only results and warnings: no progress, no notes of what was made.
    #[arg(long, short, global = true)]
    pub quiet: bool,
}

#[derive(Subcommand)]
pub enum Command {
    /// Print every point of the study, whether it will run and why; run nothing. With
    /// --simulate, predict what the study's latest run would take on other allocations.
    Plan(PlanCommandArgs),
    /// Run the points not yet stored (make-style) and store their records.
    Run(RunArgs),
    /// Gather the stored records into <results>/<study>/<study>.parquet (one row per run) and
    /// <study>-summary.parquet (one row per point, with speedups and convergence orders).
    Collect(CollectArgs),
    /// Draw the study's figures from its summary table into <results>/<study>/figures/, each
    /// only when its table or its spec changed.
    Plot(CommonArgs),
    /// Count the stored records by status and list the failures; with --timeline, where each
    /// worker's time went in the latest runs.
    Status(StatusArgs),
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
    /// Print stored records as JSON, one line each in key order: every point's latest record,
    /// or those of --key; with --from-table, the records the run table holds (what a results
    /// folder copied without its runs keeps), their cases resolved as the table has them.
    Show(ShowArgs),
    /// Draw each point's metric against the date each solver build (fingerprint) first ran it,
    /// from the current records and the superseded ones in history/, into
    /// <results>/<study>/history.svg.
    History(HistoryArgs),
}

#[derive(Args)]
pub struct StatusArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Print the timeline of the study's latest runs instead (one per `nlstudy run`, so one per
    /// job of a cluster's round): each worker's wall time as starting, set-up, solve, spectrum
    /// and errors, hand-off and store, idle and between rounds; and draw the latest into
    /// <results>/<study>/timeline.svg.
    #[arg(long)]
    pub timeline: bool,
}

#[derive(Args)]
pub struct ShowArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Only the records of these keys (comma-separated, as `plan` and `status` print them).
    #[arg(long, value_delimiter = ',')]
    pub key: Option<Vec<String>>,
    /// Read the records from the run table, <results>/<study>/<study>.parquet, not the store.
    #[arg(long)]
    pub from_table: bool,
}

#[derive(Args)]
pub struct HistoryArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// A record field, or `<field>_median` for the median over the repeats, e.g. `step_s_median`.
    #[arg(long, default_value = "step_s_median")]
    pub metric: String,
}

#[derive(Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// The baseline A: `history` (the records that the current ones superseded, of the most
    /// recent other solver fingerprint), `fingerprint:PREFIX` (the stored or superseded records
    /// of the build whose fingerprint starts with PREFIX), another results directory holding
    /// the same study, or `solver:PATH`: that nlsolve binary, run now in turns with this one
    /// (interleaved: A B, B A, … for --rounds rounds, one case at a time), each pair's ratio
    /// judged, so that a busy machine's drift hits both sides alike.
    #[arg(long)]
    pub against: String,
    /// With `--against solver:PATH`: rounds of interleaved runs (each point runs this many times
    /// with each build); at least 2, for an interval. 11 calls a 1.25× slower solve's CPU time
    /// worse 20 times in 20 on this 2-core machine under a load of two busy processes
    /// (docs/performance.md); an odd count keeps the median a run's own.
    #[arg(long, default_value_t = 11)]
    pub rounds: usize,
    /// With `--against solver:PATH`: the most rounds a point runs when its CPU time is still
    /// undecided after --rounds (its interval holds 1 + threshold or 1/(1 + threshold)): such
    /// points run --rounds more at a time, up to this many; default 3 × --rounds.
    #[arg(long, value_name = "N")]
    pub max_rounds: Option<usize>,
    /// With `--against solver:PATH`: also count each point's instructions under Valgrind (one
    /// run per build, 20–50× slower, the same count on any machine), judged to 0.5 %.
    #[arg(long)]
    pub instructions: bool,
    /// With `--against solver:PATH`: seconds after which a run is stopped and counted failed
    /// (overrides the study's `timeout_s`); a failed run on either side fails the comparison.
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
    /// With `--against solver:PATH`: only the points with these keys (comma-separated, as
    /// `plan` prints them); default: every point of the study.
    #[arg(long, value_delimiter = ',')]
    pub only: Option<Vec<String>>,
    /// The smallest change of a timing that counts, as a fraction: with 0.1, B/A's interval
    /// must lie above 1.1 or below 1/1.1.
    #[arg(long, default_value_t = 0.1)]
    pub threshold: f64,
    /// Compare timings measured on unlike machines (another CPU model or instruction set).
    #[arg(long)]
    pub allow_unlike: bool,
    /// Compare a side whose runs come from several builds, hosts or instruction sets.
    #[arg(long)]
    pub allow_mixed: bool,
    /// B: the records of the build whose fingerprint starts with PREFIX (`fingerprint:PREFIX`,
    /// stored or superseded) instead of the study's current records: two past builds compared.
    #[arg(long)]
    pub of: Option<String>,
}

#[derive(Args)]
pub struct CleanArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Delete the records no point of the study has (without it they are only listed).
    #[arg(long)]
    pub yes: bool,
}

#[derive(Args)]
pub struct SubmitArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// The scheduler (default: the site profile's).
    #[arg(long, value_enum)]
    pub scheduler: Option<Scheduler>,
    /// The site profile: a name (NAME.toml in $NLSTUDY_SITES, ~/.config/nlstudy/sites or the
    /// project's sites/) or a path; default: $NLSTUDY_SITE. It sets the scheduler, partition,
    /// account, QoS, constraint, memory, exclusive nodes, modules, prologue, launcher, cores
    /// per node and default time of every job; the study and the flags override it.
    #[arg(long)]
    pub site: Option<String>,
    /// One job array per allocation shape (one scheduler call each), each element running a
    /// bundle of `--cases-per-job` points (default 1) with the in-job worker pool.
    #[arg(long)]
    pub array: bool,
    /// With --array: how many elements run at once (`%T`).
    #[arg(long, requires = "array")]
    pub throttle: Option<NonZeroUsize>,
    /// Write the scripts into results/<study>/jobs/ without submitting them.
    #[arg(long)]
    pub dry_run: bool,
    /// One job that runs the whole study inside its allocation, every round of an adaptive one
    /// (the worker pool on the job's cores: one node's with a site's `cores_per_node`, else
    /// `--tasks`), and writes its tables, figures and report; a requeued job resumes from the
    /// store. Its time limit: `--time`, else the stored timings of a fixed study, else the
    /// site's default.
    #[arg(long, conflicts_with = "array")]
    pub whole: bool,
    /// With --follow or --whole: tabulate the runs of several hosts (the nodes of the cluster
    /// that ran them) or solver builds together at the end (see `collect --allow-mixed`). A
    /// whole study on more than one node (`--whole --nodes N`) tabulates its nodes' runs
    /// together without it.
    #[arg(long)]
    pub allow_mixed: bool,
    /// Stay until the study is answered: submit what is ready (the missing points, or an
    /// adaptive study's next round), wait while the scheduler holds the jobs, then submit the
    /// next round, and at the end write the tables, figures and report as `run` does. Stopped
    /// (Ctrl-C, a lost terminal: run it under nohup or tmux) and started again, it waits for
    /// the jobs already queued instead of submitting them twice.
    #[arg(long, conflicts_with = "dry_run")]
    pub follow: bool,
    /// With --follow: the longest pause, in seconds, between two questions to the scheduler
    /// (the first is 1 s, each later one half as long again).
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 60.0,
        requires = "follow"
    )]
    pub poll: f64,
    /// With --follow: how many times a point is submitted again after its job ended without
    /// its record (cancelled, timed out, its node lost); then it is stored failed with what the
    /// scheduler says of its jobs.
    #[arg(long, value_name = "N", default_value_t = 1, requires = "follow")]
    pub resubmit: usize,
    /// Each flag overrides the study's `resources` field of the same name.
    #[command(flatten)]
    pub resources: Resources,
    /// Each job's `nlstudy run --retries N`: a case that failed for a reason outside it runs again.
    #[arg(long, default_value_t = 0)]
    pub retries: usize,
    /// Submit the other points when the solver refuses some (see `plan --allow-refused`).
    #[arg(long)]
    pub allow_refused: bool,
    /// The MPI launcher inside each job, `{ranks}` where the rank count goes (default: the
    /// site's, else `srun --mpi=pmix -n {ranks}` under Slurm, `mpirun -n {ranks}` under LSF),
    /// e.g. for a site whose Slurm speaks PMI-2: `srun --mpi=pmi2 -n {ranks}`.
    #[arg(long)]
    pub launcher: Option<Launcher>,
}

#[derive(Args)]
pub struct CollectArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Tabulate runs of several solver builds (fingerprints), hosts or instruction sets
    /// together; by default such a mix is refused.
    #[arg(long)]
    pub allow_mixed: bool,
}

#[derive(Args)]
pub struct TableArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// The fields that name a line (comma-separated), e.g. `dim,quadrature`.
    #[arg(long, value_delimiter = ',')]
    pub rows: Vec<String>,
    /// The field whose values head the columns, e.g. `n`; without it, one column per value.
    #[arg(long)]
    pub column: Option<String>,
    /// The columns of the summary table in the cells (comma-separated, side by side), e.g.
    /// `error_l2_norm,order_l2`.
    #[arg(long, value_delimiter = ',', required = true)]
    pub value: Vec<String>,
    /// Conditions a point must meet, in the study language (repeatable).
    #[arg(long = "where")]
    pub filter: Vec<String>,
}

#[derive(Args)]
pub struct CommonArgs {
    /// The study file (JSON).
    pub study: PathBuf,
    /// Where results go: <results>/<study name>/ (records in runs/segments/, tables, figures).
    #[arg(long, default_value = "results")]
    pub results: PathBuf,
    /// The nlsolve binary (default: $NLSOLVE, else the one beside nlstudy).
    #[arg(long)]
    pub solver: Option<PathBuf>,
    /// Make this study file the owner of <results>/<study name>/ when another file of the same
    /// name owns it (its stored runs stay; points that are the same cases reuse them).
    #[arg(long)]
    pub adopt: bool,
}

#[derive(Args)]
pub struct PlanArgs {
    #[command(flatten)]
    pub common: CommonArgs,
    /// Run every point again, stored or not.
    #[arg(long)]
    pub force: bool,
    /// Run the points whose stored record failed.
    #[arg(long)]
    pub rerun_failed: bool,
    /// Only the points with these keys (comma-separated), as cluster jobs do.
    #[arg(long, value_delimiter = ',')]
    pub only: Option<Vec<String>>,
    /// With --only, the file of those keys' probes that `submit` wrote beside the job's
    /// script: an adaptive study's job plans them at once, rather than replaying every search
    /// from the store to find them (it does when the file no longer gives them all).
    #[arg(long, requires = "only", value_name = "FILE")]
    pub probes: Option<PathBuf>,
    /// Reuse stored records that a solver of another fingerprint made (by default they are
    /// stale and run again; the old record moves to <results>/<study>/history/).
    #[arg(long)]
    pub keep_stale: bool,
    /// Go on when the solver refuses some points (they are stored as failed); by default a
    /// refused point stops `plan`, `run` and `submit` before anything runs.
    #[arg(long)]
    pub allow_refused: bool,
}

#[derive(Args)]
pub struct PlanCommandArgs {
    #[command(flatten)]
    pub plan: PlanArgs,
    /// Predict instead what the study's latest run (its timeline) would take in one allocation
    /// of each of these shapes (comma-separated NODES or NODESxCORES, cores by default this
    /// machine's), from its cases' measured times, the driver's time per case, a worker's start
    /// and the time between rounds; the assumptions are printed with it.
    #[arg(long, value_delimiter = ',', value_name = "NODES[xCORES]")]
    pub simulate: Option<Vec<String>>,
}

#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub plan: PlanArgs,
    /// Cores the running cases may use together (threads × ranks each), at least 1; default:
    /// all.
    #[arg(short = 'j', long, value_parser = cores)]
    pub jobs: Option<usize>,
    /// Seconds after which a case is stopped and stored as failed (overrides the study's).
    #[arg(long)]
    pub timeout: Option<f64>,
    /// Command prefix of MPI cases; `{ranks}` becomes the case's rank count.
    #[arg(long, default_value = DEFAULT_LAUNCHER)]
    pub launcher: Launcher,
    /// Run a case again, up to N more times, when it failed for a reason outside it (past its
    /// timeout, killed by a signal, its MPI launcher hung or failed after the solver printed
    /// the record); the record keeps its `attempt`.
    /// Divergence and refused input are results and never run again.
    #[arg(long, default_value_t = 0)]
    pub retries: usize,
    /// Run every case in a process of its own (`nlsolve run`), as MPI cases and those writing
    /// VTK files always do; by default the others run on `nlsolve serve` workers that stay up.
    #[arg(long)]
    pub isolate: bool,
    /// Checkpoint each case every SECONDS of wall time (its time loop, or a steady solve's CG
    /// iterations) and when a stopping signal arrives, so that `run` again resumes a stopped
    /// case where it was (overrides the study's `checkpoint_every_s`). Such cases run as
    /// processes of their own.
    #[arg(long, value_name = "SECONDS")]
    pub checkpoint_every: Option<f64>,
    /// Keep each case's checkpoint after its record is stored (in runs/.work/<key>.checkpoint).
    #[arg(long)]
    pub keep_checkpoints: bool,
    /// A worker holding more than this many MiB once it has answered a case is replaced, so
    /// that memory a case left behind neither counts in the next case's peak nor accumulates.
    #[arg(long, value_name = "MIB", default_value_t = crate::run::worker::MEMORY_BOUND_MIB)]
    pub worker_memory: u64,
    /// Do not gather the records into the study's tables, nor draw its figures, at the end.
    #[arg(long)]
    pub no_collect: bool,
    /// At the end, tabulate runs of several solver builds, hosts or instruction sets together
    /// (see `collect --allow-mixed`).
    #[arg(long)]
    pub allow_mixed: bool,
}

impl PlanArgs {
    /// What the plan is asked to do with the stored records.
    pub fn options(&self) -> Options {
        Options {
            force: self.force,
            rerun_failed: self.rerun_failed,
            only: self
                .only
                .as_ref()
                .map(|keys| keys.iter().cloned().collect()),
            probes: self.probes.clone(),
            keep_stale: self.keep_stale,
        }
    }
}

/// A count of cores: a whole number from 1.
fn cores(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("give at least 1 core (0 would run nothing)".into()),
        Ok(cores) => Ok(cores),
        Err(_) => Err("give a whole number of cores, at least 1".into()),
    }
}
