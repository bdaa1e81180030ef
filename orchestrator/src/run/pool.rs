//! The worker pool: cases within a core budget, those of one process on `nlsolve serve`
//! workers that stay up (`worker`), MPI cases and those writing files through a process of
//! their own, a timeout per case, failures stored with the tail of stderr, and a clean stop on
//! Ctrl-C. A worker that dies or hangs on a case is replaced and the case runs again alone, in
//! a process of its own, so that a case that kills its worker fails by itself.
//!
//! Each case runs under its key's lock in the store, so processes sharing a store never run a
//! point at the same time; a point another process holds, or has stored meanwhile, is passed.
//! A solver process or worker dies with this one (its parent-death signal), so a killed `nlstudy` leaves
//! no case running unowned.

use crate::model::launcher::Launcher;
use crate::run::allocation::Node;
use crate::run::nlsolve::{Checked, Nlsolve};
use crate::run::plan::{Decision, Planned, Reason};
use crate::run::progress::Progress;
use crate::run::signals::Stop;
use crate::run::worker::{die_with_parent, Place, Served, Worker, Workers};
use crate::store::fs::{create_dir, create_fresh, open_regular, read_regular, RECORD_CAP};
use crate::store::{FileError, Store, CHECKPOINT, PROGRESS, SCRATCH};
use schema::exit;
use schema::record::{Failure, Outcome, Record, Status, Stored};
use serde_json::Value;
use std::fs::File;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// How long a solver ended by a stopping signal waits for that signal to reach nlstudy too: a
/// signal sent to the process group or the job (Ctrl-C, `scancel`) may end the child first.
const STOP_SIGNAL_SKEW: Duration = Duration::from_millis(200);

/// Whether a solver that exited unsuccessfully was ended by the stop `stop` asks for, rather
/// than failing on its own.
fn stopped_with_it(stop: &Stop, exit: std::process::ExitStatus) -> bool {
    if stop.requested() {
        return true;
    }
    // Ended by the signal, or by its own handler with the shell's status for it (a
    // checkpointing solver writes its checkpoint first).
    let by_signal = exit.signal().or(exit.code().map(|code| code - 128));
    if !by_signal.is_some_and(|s| crate::run::signals::CAUGHT.contains(&s)) {
        return false;
    }
    let since = Instant::now();
    while since.elapsed() < STOP_SIGNAL_SKEW {
        std::thread::sleep(Duration::from_millis(5));
        if stop.requested() {
            return true;
        }
    }
    false
}

/// The command that starts a case of `ranks` ranks of `threads` threads through `launcher`.
fn launcher_command(launcher: &Launcher, ranks: u64, threads: u64) -> Command {
    let mut words = launcher.argv(ranks, threads).into_iter();
    let mut command = Command::new(words.next().expect("a launcher has a program"));
    command.args(words);
    command
}

/// Lines of stderr kept in a failed record.
const STDERR_TAIL: usize = 20;
/// How long an MPI launcher may leave an exited rank unreaped before its job is ended: Open MPI
/// 4.1's `mpirun` can hang for good, ignoring SIGTERM, when a rank dies early (the dead rank
/// stays a zombie, the launcher waits on a futex), which would stall the study.
const UNREAPED_RANK_GRACE: Duration = Duration::from_secs(10);
/// How often a running MPI job's ranks are looked at.
const RANK_CHECK_EVERY: Duration = Duration::from_secs(1);

pub struct PoolOptions {
    /// Cores the running cases may use together (threads × ranks each).
    pub cores: usize,
    /// Where cases run, each within its cores: this machine, or the nodes of the allocation
    /// this process runs in (`allocation::nodes`).
    pub nodes: Vec<Node>,
    /// One case at a time on a node, so that timings are not disturbed.
    pub exclusive: bool,
    pub timeout: Option<Duration>,
    /// Command prefix of MPI cases, e.g. `srun --mpi=pmix -n {ranks}`.
    pub launcher: Launcher,
    /// Further attempts at a case that failed for a reason outside it: past its timeout, killed
    /// by a signal, or its MPI launcher hung or failed after the record was printed. A case
    /// that diverges or is refused is a result and never runs again.
    pub retries: usize,
    /// A process per case (`--isolate`), never a worker.
    pub isolate: bool,
    /// Cases checkpoint this often (a time loop, or a steady solve's CG), besides on a stopping
    /// signal, in `runs/.work/<key>.checkpoint` (and `.rank<r>` beside it over ranks), and
    /// resume from it.
    pub checkpoint_every: Option<Duration>,
    /// Keep each checkpoint after its record is stored.
    pub keep_checkpoints: bool,
}

/// Counts of a pool's work.
#[derive(Debug, Default, PartialEq)]
pub struct Tally {
    pub ok: usize,
    pub diverged: usize,
    pub failed: usize,
    /// Planned cases another process ran, or was running, meanwhile.
    pub passed: usize,
    /// Runs timed while other tasks wanted the cores they left free (`provenance.noisy`).
    pub noisy: usize,
    pub interrupted: bool,
}

impl Tally {
    /// Counts `other`'s work too (a search's rounds).
    pub fn add(&mut self, other: &Tally) {
        self.ok += other.ok;
        self.diverged += other.diverged;
        self.failed += other.failed;
        self.passed += other.passed;
        self.noisy += other.noisy;
        self.interrupted |= other.interrupted;
    }
}

struct Running {
    index: usize,
    /// 1 for the first run of the point, 2 for its first retry, …
    attempt: usize,
    started: Instant,
    cores: usize,
    /// Its node, an index into the pool's nodes.
    node: usize,
    /// The key's lock in the store, held until the record is stored.
    _lock: File,
    how: How,
}

/// Where a running case runs.
enum How {
    /// A process of its own (`nlsolve run`, or its MPI launcher).
    Process(Process),
    /// A worker, and its line once heard (`Some(None)`: its output closed).
    Served {
        worker: Worker,
        heard: Option<Option<String>>,
    },
}

struct Process {
    child: Child,
    stdout: PathBuf,
    stderr: PathBuf,
    case_file: PathBuf,
    progress: PathBuf,
    /// MPI jobs: when a rank was first seen exited and not reaped by the launcher.
    launcher_watch: Option<LauncherWatch>,
}

/// A point waiting to run.
#[derive(Clone, Copy)]
struct Queued {
    index: usize,
    attempt: usize,
    /// In a process of its own even where a worker could run it: its worker died on it.
    alone: bool,
}

/// How a running case ended.
enum Ended {
    /// A process exited (`None`: it was killed past the timeout).
    Exited(Option<std::process::ExitStatus>),
    /// An MPI launcher left a dead rank unreaped and was killed.
    LauncherHung,
    /// A worker answered.
    Answered(String),
    /// A worker died (or was killed past the timeout) before it answered.
    WorkerLost {
        exit: std::process::ExitStatus,
        timed_out: bool,
    },
}

/// What is known of an MPI launcher's ranks.
struct LauncherWatch {
    checked: Instant,
    unreaped_since: Option<Instant>,
}

impl LauncherWatch {
    /// Has a rank of `launcher` been dead and unreaped for longer than the grace period?
    fn hung(&mut self, launcher: u32) -> bool {
        if self.checked.elapsed() < RANK_CHECK_EVERY {
            return false;
        }
        self.checked = Instant::now();
        if !has_zombie_child(launcher) {
            self.unreaped_since = None;
            return false;
        }
        let since = *self.unreaped_since.get_or_insert_with(Instant::now);
        since.elapsed() > UNREAPED_RANK_GRACE
    }
}

/// Does process `parent` have a child that has exited and not been reaped (state Z)?
fn has_zombie_child(parent: u32) -> bool {
    processes().any(|(_, ppid, state)| state == 'Z' && ppid == parent)
}

/// The running children of process `parent` (an MPI launcher's ranks on this machine).
fn children_of(parent: u32) -> Vec<u32> {
    processes()
        .filter(|&(_, ppid, state)| ppid == parent && state != 'Z')
        .map(|(pid, _, _)| pid)
        .collect()
}

/// Every process's pid, parent's pid and state, from /proc.
fn processes() -> impl Iterator<Item = (u32, u32, char)> {
    std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let pid = entry.file_name().to_str()?.parse::<u32>().ok()?;
            let stat = std::fs::read_to_string(entry.path().join("stat")).ok()?;
            // After the command name's closing parenthesis: state, then the parent's pid.
            let (_, rest) = stat.rsplit_once(')')?;
            let mut fields = rest.split_whitespace();
            let state = fields.next()?.chars().next()?;
            let ppid = fields.next()?.parse::<u32>().ok()?;
            Some((pid, ppid, state))
        })
}

/// Runs the planned points that run; stores each record as it finishes. A failure of the file
/// system (the store, the scratch files, a record nlsolve could not write) is not a property of
/// a case: it stops the run, the running cases are ended and nothing is stored for them, so
/// the next run takes them up again. `workers` stay up for the next call (a search's rounds).
pub fn run(
    planned: &[Planned],
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    workers: &mut Workers,
    stop: &Stop,
    progress: &mut Progress,
) -> Result<Tally, FileError> {
    let mut running: Vec<Running> = Vec::new();
    let mut pool = Pool {
        planned,
        solver,
        store,
        options,
        workers,
        stop,
        progress,
        tally: Tally::default(),
        // Popped from the back in plan order.
        queue: (0..planned.len())
            .rev()
            .filter(|&i| planned[i].runs())
            .map(|index| Queued {
                index,
                attempt: 1,
                alone: false,
            })
            .collect(),
    };
    let outcome = pool.run_cases(&mut running);
    for job in running {
        job.abandon();
    }
    outcome.map(|()| pool.tally)
}

/// A pool's state while it runs one batch of points.
struct Pool<'a> {
    planned: &'a [Planned],
    solver: &'a Nlsolve,
    store: &'a Store,
    options: &'a PoolOptions,
    workers: &'a mut Workers,
    stop: &'a Stop,
    progress: &'a mut Progress,
    tally: Tally,
    queue: Vec<Queued>,
}

/// How long a solver asked to stop may take to write its checkpoint before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(30);

/// How often the bar shows how far the running cases are (from their progress files).
const SHOW_PROGRESS_EVERY: Duration = Duration::from_secs(1);

/// `step k of N, about S s left` from a running case's progress file (`nlsolve --progress`),
/// once its time loop (or steady solve) has written one (a second into it: short cases never
/// show).
fn how_far(progress: &std::path::Path) -> Option<String> {
    let progress = crate::store::progress_of(progress)?;
    Some(format!("{}, {}", progress.steps_done(), progress.left()))
}

/// How long the pool waits for a worker's answer before it looks at its processes again.
const POLL_EVERY: Duration = Duration::from_millis(10);

impl Pool<'_> {
    fn run_cases(&mut self, running: &mut Vec<Running>) -> Result<(), FileError> {
        create_dir(&self.store.work_dir())?;
        let mut shown = Instant::now();
        loop {
            if self.stop.requested() {
                self.tally.interrupted = true;
                return Ok(());
            }
            self.start_what_fits(running)?;
            if running.is_empty() && self.queue.is_empty() {
                return Ok(());
            }
            // An answer wakes the pool at once; processes are looked at every POLL_EVERY.
            let mut wait = POLL_EVERY;
            while let Some((worker, line)) = self.workers.listen(wait) {
                let busy = running.iter_mut().find_map(|job| match &mut job.how {
                    How::Served { worker: w, heard } if w.id() == worker => Some(heard),
                    _ => None,
                });
                if let Some(heard) = busy {
                    *heard = Some(line);
                }
                wait = Duration::ZERO;
            }
            if shown.elapsed() >= SHOW_PROGRESS_EVERY {
                shown = Instant::now();
                let how_far: Vec<String> = running
                    .iter()
                    .filter_map(|job| {
                        let planned = &self.planned[job.index];
                        let progress = self.store.scratch(&planned.key, PROGRESS);
                        Some(format!(
                            "{}: {}",
                            planned.point.shown(),
                            how_far(&progress)?
                        ))
                    })
                    .collect();
                self.progress.running(&how_far);
            }
            let mut k = 0;
            while k < running.len() {
                let Some(ended) = running[k].poll(self.options.timeout, self.solver)? else {
                    k += 1;
                    continue;
                };
                let job = running.swap_remove(k);
                self.ended(job, ended)?;
            }
        }
    }

    /// Starts what fits in the core budget; a case larger than the budget runs alone.
    fn start_what_fits(&mut self, running: &mut Vec<Running>) -> Result<(), FileError> {
        while let Some(&next) = self.queue.last() {
            let planned = &self.planned[next.index];
            let cores = cores_of(planned);
            let busy: Vec<(usize, usize)> = running.iter().map(|r| (r.node, r.cores)).collect();
            // Over the nodes of an allocation, an MPI case's launcher spreads its ranks over
            // the allocation as it does for a job of its own: such a case runs alone.
            let spread = self.options.nodes.len() > 1
                && planned.case.as_ref().is_ok_and(|case| case.ranks() > 1);
            let node = match spread {
                true => busy.is_empty().then_some(0),
                false => place(&self.options.nodes, self.options, &busy, cores),
            };
            let Some(node) = node else {
                return Ok(());
            };
            self.queue.pop();
            let Some(lock) = self.store.lock(&planned.key)? else {
                self.progress
                    .passed(&planned.point.shown(), "another nlstudy is running it");
                self.tally.passed += 1;
                continue;
            };
            // A forced or stale point runs whatever is stored; others may have been stored by
            // another nlstudy since the plan. A point run again alone is this run's own.
            let forced = next.alone
                || matches!(
                    planned.decision,
                    Decision::Run(Reason::Forced | Reason::Stale { .. })
                );
            let stored = self
                .store
                .status(&planned.key)
                .filter(|s| *s != Status::Failed);
            if let Some(status) = stored.filter(|_| !forced) {
                let why = format!("another nlstudy has stored it meanwhile ({status})");
                self.progress.passed(&planned.point.shown(), &why);
                self.tally.passed += 1;
                continue;
            }
            let case = match &planned.case {
                Err(message) => {
                    let record = failed_record(planned, self.solver, message.clone());
                    self.finish(planned, record)?;
                    continue;
                }
                Ok(case) => case,
            };
            let on = &self.options.nodes[node];
            let how = if self.serves(case, next.alone) {
                // A worker on this machine serves any thread count; a step keeps the cores it
                // was started with.
                let held = if on.name.is_some() { cores } else { 0 };
                let place = Place { node, cores: held };
                let mut worker = self.workers.take(self.solver, place, on)?;
                let line = served_line(case, &planned.key, self.store, self.options);
                // A worker that is gone already says so when its output closes.
                worker.send(&line);
                How::Served {
                    worker,
                    heard: None,
                }
            } else {
                if on.name.is_some() {
                    // Idle steps on the node hold cores the scheduler would wait for.
                    self.workers.close_on(node);
                }
                How::Process(start(
                    case,
                    planned,
                    self.solver,
                    self.store,
                    self.options,
                    on,
                )?)
            };
            running.push(Running {
                index: next.index,
                attempt: next.attempt,
                started: Instant::now(),
                cores,
                node,
                _lock: lock,
                how,
            });
        }
        Ok(())
    }

    /// Does a worker run this case? Cases of one process that write no VTK files.
    fn serves(&self, case: &Checked, alone: bool) -> bool {
        let writes_vtk = case.case().is_some_and(|case| case.vtk_every.is_some());
        !(alone
            || self.options.isolate
            || self.workers.unsupported
            || case.ranks() > 1
            || writes_vtk)
    }

    /// Stores the record of a case that ended, or queues it again.
    fn ended(&mut self, job: Running, ended: Ended) -> Result<(), FileError> {
        let planned = &self.planned[job.index];
        let label = planned.point.shown();
        let again = |alone| Queued {
            index: job.index,
            attempt: job.attempt,
            alone,
        };
        let (record, outside_the_case) = match ended {
            Ended::Exited(exit) => {
                let How::Process(process) = &job.how else {
                    unreachable!("only processes exit")
                };
                let record = match exit {
                    None => failed_record(
                        planned,
                        self.solver,
                        format!(
                            "timed out after {:.0} s; {}",
                            job.started.elapsed().as_secs_f64(),
                            process.stderr_tail()
                        ),
                    ),
                    Some(exit) if !exit.success() && stopped_with_it(self.stop, exit) => {
                        // Ctrl-C reaches the whole process group, scancel the whole job: a
                        // case the stopping signal ended is not a failure.
                        job.abandon();
                        return Ok(());
                    }
                    Some(exit) => process.record(planned, self.solver, job.cores, exit)?,
                };
                let killed = exit.is_none_or(|e| e.signal().is_some() && !e.success());
                // A launcher that failed after its ranks printed the record: the case ran to its
                // end, the MPI runtime did not (Open MPI 4.1 now and then reports a finished
                // rank "exiting improperly" at the job's teardown).
                let launcher_failed = process.launcher_watch.is_some()
                    && exit.is_some_and(|e| !e.success())
                    && process.printed_a_record();
                (record, killed || launcher_failed)
            }
            Ended::LauncherHung => {
                let How::Process(process) = &job.how else {
                    unreachable!("only launchers hang")
                };
                let message = format!(
                    "a rank exited and the MPI launcher had not ended {} s later, so it was killed; {}",
                    UNREAPED_RANK_GRACE.as_secs(),
                    process.stderr_tail()
                );
                (failed_record(planned, self.solver, message), true)
            }
            Ended::Answered(line) => {
                let How::Served { worker, .. } = job.how else {
                    unreachable!("only workers answer")
                };
                self.workers.give_back(worker);
                let record = answer_record(planned, self.solver, job.cores, &line);
                self.finish_attempt(planned, record, job.attempt)?;
                return Ok(());
            }
            Ended::WorkerLost { exit, timed_out } => {
                let How::Served { worker, .. } = &job.how else {
                    unreachable!("only workers are lost")
                };
                if !timed_out && stopped_with_it(self.stop, exit) {
                    job.abandon();
                    return Ok(());
                }
                if worker.answered == 0 && exit.code() == Some(i32::from(exit::BAD_INPUT)) {
                    // It does not know `serve`: from now on, a process per case.
                    self.workers.unsupported = true;
                    self.queue.push(again(true));
                    return Ok(());
                }
                if exit.code() == Some(i32::from(exit::IO)) {
                    let said = std::io::Error::other(worker.stderr_tail());
                    return Err(FileError::new(
                        "get the records of",
                        &self.solver.binary,
                        said,
                    ));
                }
                // The case may have been the worker's undoing or its victim: run alone, it
                // fails alone if it is the case's fault.
                let why = if timed_out {
                    format!(
                        "its worker was still at it after {:.0} s and was replaced",
                        job.started.elapsed().as_secs_f64()
                    )
                } else {
                    format!(
                        "its worker ended with {exit} and was replaced: {}",
                        worker.stderr_tail()
                    )
                };
                self.progress.alone(&label, &why);
                self.queue.push(again(true));
                return Ok(());
            }
        };
        if let How::Process(process) = &job.how {
            process.remove_files();
        }
        let failed = record.status() == Status::Failed;
        if failed && outside_the_case && job.attempt <= self.options.retries {
            self.progress
                .retrying(&label, job.attempt + 1, record.message());
            self.queue.push(Queued {
                index: job.index,
                attempt: job.attempt + 1,
                alone: false,
            });
            return Ok(());
        }
        self.finish_attempt(planned, record, job.attempt)
    }

    fn finish_attempt(
        &mut self,
        planned: &Planned,
        mut record: Stored,
        attempt: usize,
    ) -> Result<(), FileError> {
        record.attempt = Some(attempt);
        self.finish(planned, record)
    }

    fn finish(&mut self, planned: &Planned, record: Stored) -> Result<(), FileError> {
        let status = record.status();
        let mut message = record.message().to_string();
        if !self.store.save(&planned.key, &record)? {
            message.push_str("; the stored result of an earlier run is kept");
        }
        // A whole record makes the point's checkpoint useless. The solver removes it after its
        // answer, but a worker's removal can come after this process has ended: a checkpoint
        // would then outlive its record.
        if status != Status::Failed && !self.options.keep_checkpoints {
            self.store.remove_checkpoint(&planned.key);
        }
        match status {
            Status::Ok => self.tally.ok += 1,
            Status::Diverged => self.tally.diverged += 1,
            Status::Failed => self.tally.failed += 1,
        }
        self.tally.noisy += usize::from(record.noisy());
        self.progress
            .finished(&planned.point.shown(), status, &message);
        Ok(())
    }
}

impl Running {
    /// How the case ended, if it has: a process exited or was killed past the timeout, a
    /// launcher hung, a worker answered or died.
    fn poll(
        &mut self,
        timeout: Option<Duration>,
        solver: &Nlsolve,
    ) -> Result<Option<Ended>, FileError> {
        let timed_out = timeout.is_some_and(|limit| self.started.elapsed() > limit);
        match &mut self.how {
            How::Served { worker, heard } => Ok(match heard.take() {
                Some(line) => Some(match worker.ended(line) {
                    Served::Answer(line) => Ended::Answered(line),
                    Served::Died(exit) => Ended::WorkerLost {
                        exit,
                        timed_out: false,
                    },
                }),
                None if timed_out => Some(Ended::WorkerLost {
                    exit: worker.kill(),
                    timed_out: true,
                }),
                None => None,
            }),
            How::Process(process) => {
                let child = &mut process.child;
                if timed_out {
                    let _ = child.kill();
                    child
                        .wait()
                        .map_err(FileError::on("wait for", &solver.binary))?;
                    return Ok(Some(Ended::Exited(None)));
                }
                let pid = child.id();
                if process
                    .launcher_watch
                    .as_mut()
                    .is_some_and(|watch| watch.hung(pid))
                {
                    let _ = child.kill();
                    child
                        .wait()
                        .map_err(FileError::on("wait for", &solver.binary))?;
                    return Ok(Some(Ended::LauncherHung));
                }
                let exit = child
                    .try_wait()
                    .map_err(FileError::on("wait for", &solver.binary))?;
                Ok(exit.map(|exit| Ended::Exited(Some(exit))))
            }
        }
    }

    /// Ends the case without a record: the run stops, or the stop ended it. The solver is
    /// first asked to stop (SIGTERM: a checkpointing solver writes its checkpoint; over ranks
    /// each rank, the launcher's children, is asked, so that every rank writes its share
    /// before the launcher ends the job) and given `STOP_GRACE`; then it is killed.
    fn abandon(self) {
        match self.how {
            How::Process(mut process) => {
                let running = matches!(process.child.try_wait(), Ok(None));
                if running {
                    let asked = Instant::now();
                    let id = process.child.id();
                    let asked_to_stop = match process.launcher_watch {
                        Some(_) => children_of(id),
                        None => vec![id],
                    };
                    for pid in asked_to_stop {
                        // SAFETY: kill(2) on our own child, not yet reaped (an exit is cached
                        // by `try_wait`, which would have said so), or on a child of it, which
                        // it has not reaped either (it is running).
                        unsafe { libc::kill(pid as libc::pid_t, libc::SIGTERM) };
                    }
                    while asked.elapsed() < STOP_GRACE
                        && matches!(process.child.try_wait(), Ok(None))
                    {
                        std::thread::sleep(Duration::from_millis(5));
                    }
                }
                let _ = process.child.kill();
                let _ = process.child.wait();
                process.remove_files();
            }
            How::Served { mut worker, .. } => {
                worker.stop(STOP_GRACE);
            }
        }
    }
}

/// The cores this process may use (its affinity mask and cgroup quota respected), read once: it
/// reads the cgroup's files, and every record asks.
pub fn machine_cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// The node a case of `cores` cores starts on now, if one has room (`busy`: the node and cores
/// of each running case): within the pool's budget and the node's cores, or alone on a node of
/// its own when the study times its runs (`exclusive`). A case larger than any room runs alone,
/// on the first node, once nothing runs.
fn place(
    nodes: &[Node],
    options: &PoolOptions,
    busy: &[(usize, usize)],
    cores: usize,
) -> Option<usize> {
    if busy.is_empty() {
        return Some(0);
    }
    let used = |node: usize| -> usize { busy.iter().filter(|b| b.0 == node).map(|b| b.1).sum() };
    let total: usize = busy.iter().map(|b| b.1).sum();
    if !options.exclusive && total + cores > options.cores {
        return None;
    }
    (0..nodes.len()).find(|&node| {
        let used = used(node);
        (!options.exclusive || used == 0) && used + cores <= nodes[node].cores
    })
}

/// threads × ranks of a case (1 for a refused one).
fn cores_of(planned: &Planned) -> usize {
    let case = planned.case.as_ref().ok();
    case.map_or(1, |case| case.threads() * case.ranks())
}

/// The line a worker reads for `case` (`schema::protocol::ServeLine`): the case, the file its
/// time loop says how far it is in, and its checkpoint, written on a stopping signal (and
/// every `checkpoint_every`) and resumed from. Paths are absolute (a worker runs in the work
/// directory), and given only when they are text, as JSON needs.
fn served_line(case: &Checked, key: &str, store: &Store, options: &PoolOptions) -> String {
    let text = |name: &str| {
        let path = std::path::absolute(store.scratch(key, name)).ok()?;
        path.to_str().filter(|p| !p.is_empty()).map(str::to_string)
    };
    let line = schema::protocol::ServeLine {
        case: case.canonical(),
        progress: text(PROGRESS),
        checkpoint: text(CHECKPOINT),
        checkpoint_every_s: options.checkpoint_every.map(|every| every.as_secs_f64()),
        keep_checkpoint: options.keep_checkpoints,
    };
    serde_json::to_string(&line).expect("a line serializes")
}

/// Starts `case` as a process of its own: `nlsolve run`, through the launcher over ranks.
fn start(
    case: &Checked,
    planned: &Planned,
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    node: &Node,
) -> Result<Process, FileError> {
    let [case_file, stdout, stderr, progress] =
        SCRATCH.map(|name| store.scratch(&planned.key, name));
    create_fresh(&case_file)
        .and_then(|mut file| std::io::Write::write_all(&mut file, case.canonical_text().as_bytes()))
        .map_err(FileError::on("write", &case_file))?;
    let (ranks, threads) = (case.ranks(), case.threads());
    let mut command = if ranks > 1 {
        let mut command = launcher_command(&options.launcher, ranks as u64, threads as u64);
        if is_root() {
            // Open MPI refuses root (containers, CI) unless told.
            command.env("OMPI_ALLOW_RUN_AS_ROOT", "1");
            command.env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
        }
        command.arg(&solver.binary);
        command
    } else {
        node.command(threads, &solver.binary)
    };
    command
        .arg("run")
        .arg("--case")
        .arg(&case_file)
        .arg("--progress")
        .arg(&progress);
    if case.case().is_some_and(|case| case.vtk_every.is_some()) {
        command.arg("--write-vtk").arg(store.fields(&planned.key));
    }
    // Every case may be stopped (Ctrl-C, a scheduler's warning): its time loop then writes a
    // checkpoint, which the next run resumes from.
    command
        .arg("--checkpoint")
        .arg(store.scratch(&planned.key, CHECKPOINT));
    if let Some(every) = options.checkpoint_every {
        command
            .arg("--checkpoint-every-seconds")
            .arg(every.as_secs_f64().to_string());
    }
    if options.keep_checkpoints {
        command.arg("--keep-checkpoint");
    }
    command
        .stdin(Stdio::null())
        .stdout(create_fresh(&stdout).map_err(FileError::on("create", &stdout))?)
        .stderr(create_fresh(&stderr).map_err(FileError::on("create", &stderr))?);
    die_with_parent(&mut command);
    let program = PathBuf::from(command.get_program());
    let child = command.spawn().map_err(FileError::on("start", &program))?;
    Ok(Process {
        child,
        stdout,
        stderr,
        case_file,
        progress,
        launcher_watch: (ranks > 1).then(|| LauncherWatch {
            checked: Instant::now(),
            unreaped_since: None,
        }),
    })
}

impl Process {
    /// The record a finished process printed, or a failed record with its stderr; an error
    /// when nlsolve could not write the record it computed.
    fn record(
        &self,
        planned: &Planned,
        solver: &Nlsolve,
        cores: usize,
        ended: std::process::ExitStatus,
    ) -> Result<Stored, FileError> {
        if ended.code() == Some(i32::from(exit::IO)) {
            let said = std::io::Error::other(self.stderr_tail());
            return Err(FileError::new("write", &self.stdout, said));
        }
        // A record the store could not read back is not stored as a result.
        let printed = match read_regular(&self.stdout, RECORD_CAP) {
            Ok(printed) => printed,
            Err(why) if ended.success() => {
                let why = format!("its record cannot be stored: {why}");
                return Ok(failed_record(planned, solver, why));
            }
            Err(_) => String::new(),
        };
        if !ended.success() {
            let message = format!("nlsolve exited with {ended}: {}", self.stderr_tail());
            return Ok(failed_record(planned, solver, message));
        }
        Ok(match last_object(&printed) {
            Some(object) => printed_record(planned, solver, cores, object),
            None => failed_record(
                planned,
                solver,
                format!("nlsolve exited with {ended}: {}", self.stderr_tail()),
            ),
        })
    }

    /// Whether the solver printed its record before its process ended.
    fn printed_a_record(&self) -> bool {
        read_regular(&self.stdout, RECORD_CAP).is_ok_and(|printed| last_object(&printed).is_some())
    }

    /// The last lines of its stderr, as stored in a failed record: what a terminal would act on
    /// (an escape sequence) escaped, since the record's message is printed.
    fn stderr_tail(&self) -> String {
        let text = tail_of(&self.stderr);
        let lines: Vec<&str> = text.lines().collect();
        let tail = lines[lines.len().saturating_sub(STDERR_TAIL)..].join("\n");
        schema::text::printable(&tail).into_owned()
    }

    fn remove_files(&self) {
        for path in [&self.stdout, &self.stderr, &self.case_file, &self.progress] {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The record in what nlsolve printed: its last line that is a JSON object.
fn last_object(printed: &str) -> Option<Value> {
    (printed.lines().rev()).find_map(|line| {
        serde_json::from_str::<Value>(line)
            .ok()
            .filter(Value::is_object)
    })
}

/// The stored record of a worker's answer: the record, or its error as the failed record of
/// the same case run as a process says it (`nlsolve run` exits 2 with the error on stderr).
fn answer_record(planned: &Planned, solver: &Nlsolve, cores: usize, line: &str) -> Stored {
    use std::os::unix::process::ExitStatusExt;
    let answer = serde_json::from_str::<Value>(line)
        .ok()
        .filter(Value::is_object);
    let Some(mut answer) = answer else {
        let message =
            format!("nlsolve serve answered with a line that is no JSON object: {line:.200}");
        return failed_record(planned, solver, message);
    };
    match answer.get_mut("error").map(Value::take) {
        Some(Value::String(error)) => {
            let as_a_process = std::process::ExitStatus::from_raw(i32::from(exit::BAD_INPUT) << 8);
            failed_record(
                planned,
                solver,
                format!("nlsolve exited with {as_a_process}: nlsolve: {error}"),
            )
        }
        _ => printed_record(planned, solver, cores, answer),
    }
}

/// The stored record of the JSON object nlsolve printed for `planned`; it must keep to the
/// schema.
fn printed_record(planned: &Planned, solver: &Nlsolve, cores: usize, object: Value) -> Stored {
    match serde_path_to_error::deserialize::<_, Record<Value>>(object) {
        Ok(mut record) => {
            // Its timings measure contention, not scaling; figures and tables say so. Over
            // ranks, the solver judges it from each rank's affinity; here, from the cores.
            let oversubscribed = cores > machine_cores();
            record
                .distribution
                .oversubscribed
                .get_or_insert(oversubscribed);
            stored(planned, solver, Outcome::Ran(Box::new(record)))
        }
        Err(e) => failed_record(
            planned,
            solver,
            format!(
                "nlsolve printed a record that does not keep to the schema (field `{}`: {}); is the solver of another version?",
                e.path(),
                e.inner()
            ),
        ),
    }
}

/// The last 64 KiB of the regular file `path` as text ("" when it cannot be read).
fn tail_of(path: &std::path::Path) -> String {
    use std::io::{Read, Seek, SeekFrom};
    const TAIL: u64 = 64 << 10;
    let Ok((mut file, len)) = open_regular(path) else {
        return String::new();
    };
    let mut bytes = Vec::new();
    let _ = file.seek(SeekFrom::Start(len.saturating_sub(TAIL)));
    let _ = file.take(TAIL).read_to_end(&mut bytes);
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The record of `outcome` with the fields the orchestrator adds: its key, case id, repeat and
/// version, and the `nlstudy` process that ran it (`run_id`: the runs of one invocation share
/// the machine's state, which is what `compare`'s noise model tells apart from each point's own
/// noise).
fn stored(planned: &Planned, solver: &Nlsolve, outcome: Outcome) -> Stored {
    Stored {
        key: planned.key.to_string(),
        case_id: Some(planned.case_id.to_string()),
        repeat: planned.point.repeat,
        solver_version: solver.version.clone(),
        run_id: Some(run_id().to_string()),
        attempt: None,
        outcome,
    }
}

/// This `nlstudy` process: its host, its start in nanoseconds since the epoch and its process
/// id (the jobs of a cluster start processes of the same id on many hosts, in namespaces).
fn run_id() -> &'static str {
    static ID: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ID.get_or_init(|| {
        let start = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        format!("{}-{start}-{}", host.trim(), std::process::id())
    })
}

/// The record of a point that ran to no record of its own (crashed, timed out, lost with its job).
pub(crate) fn failed_record(planned: &Planned, solver: &Nlsolve, message: String) -> Stored {
    let case = match &planned.case {
        Ok(case) => case.canonical(),
        Err(_) => Value::Object(planned.point.fields()),
    };
    stored(planned, solver, Outcome::Failed(Failure { case, message }))
}

/// Is this process root (effective uid 0)?
fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() == 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_launcher_starts_the_case_as_its_words_say() {
        let launcher: Launcher =
            r#"env "A=b c" mpirun -n {ranks} --bind-to 'core'"#.parse().unwrap();
        let command = launcher_command(&launcher, 3, 1);
        let args: Vec<_> = command.get_args().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(command.get_program(), "env");
        assert_eq!(args, ["A=b c", "mpirun", "-n", "3", "--bind-to", "core"]);
    }

    /// Cases go where their cores fit: several on a node within its cores and the budget, one
    /// a node when the study times its runs, and one larger than any room alone.
    #[test]
    fn a_case_is_placed_on_a_node_with_room_for_its_cores() {
        let node = |name: &str, cores| Node {
            name: Some(name.into()),
            cores,
            scheduler: crate::run::cluster::scheduler::Scheduler::Slurm,
        };
        let nodes = [node("a", 2), node("b", 1)];
        let options = |cores, exclusive| PoolOptions {
            cores,
            nodes: nodes.to_vec(),
            exclusive,
            timeout: None,
            launcher: crate::model::launcher::DEFAULT_LAUNCHER.parse().unwrap(),
            retries: 0,
            isolate: false,
            checkpoint_every: None,
            keep_checkpoints: false,
        };
        let shared = options(3, false);
        assert_eq!(place(&nodes, &shared, &[], 8), Some(0), "alone, too large");
        assert_eq!(place(&nodes, &shared, &[(0, 1)], 1), Some(0));
        assert_eq!(place(&nodes, &shared, &[(0, 2)], 1), Some(1));
        assert_eq!(
            place(&nodes, &shared, &[(0, 1), (1, 1)], 2),
            None,
            "over the budget"
        );
        assert_eq!(
            place(&nodes, &shared, &[(0, 1)], 2),
            None,
            "no node has 2 free"
        );
        assert_eq!(
            place(&nodes, &options(2, false), &[(0, 1), (0, 1)], 1),
            None
        );
        let timed = options(3, true);
        assert_eq!(
            place(&nodes, &timed, &[(0, 1)], 1),
            Some(1),
            "a node of its own"
        );
        assert_eq!(place(&nodes, &timed, &[(0, 1)], 2), None, "b has 1 core");
        assert_eq!(place(&nodes, &timed, &[(0, 1), (1, 1)], 1), None);
    }
}
