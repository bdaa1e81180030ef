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

mod options;
mod process;
mod record;

pub use options::{machine_cores, PoolOptions};
use process::{children_of, start, Process, UNREAPED_RANK_GRACE};
use record::answer_record;
pub(crate) use record::failed_record;
pub(crate) use record::run_id;

use crate::run::allocation::Node;
use crate::run::nlsolve::{Checked, Nlsolve};
use crate::run::plan::{Decision, Planned, Reason};
use crate::run::progress::Progress;
use crate::run::signals::Stop;
use crate::run::timeline::{now_s, OnLane};
use crate::run::worker::{Place, Served, Worker, Workers};
use crate::store::fs::create_dir;
use crate::store::timeline::Phases;
use crate::store::{FileError, Store, CHECKPOINT, PROGRESS};
use schema::exit;
use schema::record::{Status, Stored};
use std::fs::File;
use std::os::unix::process::ExitStatusExt;
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
    /// Its row and start on the run's timeline.
    on: OnLane,
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

/// Runs the planned points that run, the costliest first where `costs` predicts theirs and
/// cases run side by side (so that no long case starts last while the other workers idle),
/// else in plan order; stores
/// each record as it finishes. A failure of the file system (the store, the scratch files, a
/// record nlsolve could not write) is not a property of a case: it stops the run, the running cases are ended and nothing is stored for them, so
/// the next run takes them up again. `workers` stay up for the next call (a search's rounds).
pub fn run(
    (planned, costs): (&[Planned], Option<&[f64]>),
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    workers: &mut Workers,
    stop: &Stop,
    progress: &mut Progress,
) -> Result<Tally, FileError> {
    let costs = costs.filter(|c| options.side_by_side() && c.len() == planned.len());
    let order = queue_order(planned, costs);
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
        // Popped from the back.
        queue: order
            .into_iter()
            .rev()
            .map(|index| Queued {
                index,
                attempt: 1,
                alone: false,
            })
            .collect(),
    };
    let names = options
        .nodes
        .iter()
        .map(|node| node.name.clone().unwrap_or_else(|| "this machine".into()));
    pool.workers.timeline.begin_batch(names.collect());
    let outcome = pool.run_cases(&mut running);
    for job in running {
        let (on, key) = (job.on, &planned[job.index].key);
        job.abandon();
        pool.workers.timeline.give_back(on, key, now_s(), None);
    }
    pool.workers.timeline.end_batch();
    outcome.map(|()| pool.tally)
}

/// The order the planned points that run start in: the costliest first where `costs` are
/// given (cases side by side), else plan order. Cases one after another gain nothing from it,
/// and in a job with a time limit the short ones would wait behind a long one that may not
/// finish.
fn queue_order(planned: &[Planned], costs: Option<&[f64]>) -> Vec<usize> {
    let mut order: Vec<usize> = (0..planned.len()).filter(|&i| planned[i].runs()).collect();
    if let Some(costs) = costs {
        // Equal costs in key order, which is no order of the study's: the probes of one
        // operator (a search's, its integrators') cost the same and stand together in the
        // plan, and side by side they would wait for one another's spectrum (the first round
        // of the stability map on two workers took as long as on one).
        order.sort_by(|&a, &b| {
            let by_key = || planned[a].key.cmp(&planned[b].key);
            costs[b].total_cmp(&costs[a]).then_with(by_key)
        });
    }
    order
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
                let (on, answered) = (job.on, now_s());
                let key = &self.planned[job.index].key;
                let phases = self.ended(job, ended)?;
                self.workers.timeline.give_back(on, key, answered, phases);
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
            let mut fresh = true;
            let how = if self.serves(case, next.alone) {
                // A worker on this machine serves any thread count; a step keeps the cores it
                // was started with.
                let held = if on.name.is_some() { cores } else { 0 };
                let place = Place { node, cores: held };
                let mut worker = self.workers.take(self.solver, place, on)?;
                fresh = worker.answered == 0;
                let line = served_line(case, &planned.key, self.solver, self.store, self.options);
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
                on: self.workers.timeline.take(node, fresh),
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
    ///
    /// Long because each way a case can end (an exit, with or without its record, a launcher that
    /// hung, serve's answer, a worker lost) is an arm of one match over the same running job and
    /// its attempts.
    fn ended(&mut self, job: Running, ended: Ended) -> Result<Option<Phases>, FileError> {
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
                        return Ok(None);
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
                if let (1, Some(start)) = (worker.answered, worker.start_s()) {
                    let node = self.options.nodes[job.node]
                        .name
                        .as_deref()
                        .unwrap_or("this node");
                    log::info!(
                        "a worker on {node} connected {:.0} ms after its job step was started",
                        start * 1e3
                    );
                }
                self.workers.give_back(worker);
                let record = answer_record(planned, self.solver, job.cores, &line);
                return self.finish_attempt(planned, record, job.attempt);
            }
            Ended::WorkerLost { exit, timed_out } => {
                let How::Served { worker, .. } = &job.how else {
                    unreachable!("only workers are lost")
                };
                if !timed_out && stopped_with_it(self.stop, exit) {
                    job.abandon();
                    return Ok(None);
                }
                if worker.dialed() == Some(false) {
                    // It never reached this node (an unreachable address, a solver without
                    // `serve --connect`): workers answer through their standard streams.
                    let why = format!("it ended with {exit}: {}", worker.stderr_tail());
                    self.workers.stop_dialing_back(&why);
                    self.queue.push(again(false));
                    return Ok(None);
                }
                if worker.answered == 0 && exit.code() == Some(i32::from(exit::BAD_INPUT)) {
                    // It does not know `serve`: from now on, a process per case.
                    self.workers.unsupported = true;
                    self.queue.push(again(true));
                    return Ok(None);
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
                return Ok(None);
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
            return Ok(None);
        }
        self.finish_attempt(planned, record, job.attempt)
    }

    /// Stores the record of an attempt and returns its solver's phases, for the timeline.
    fn finish_attempt(
        &mut self,
        planned: &Planned,
        mut record: Stored,
        attempt: usize,
    ) -> Result<Option<Phases>, FileError> {
        record.attempt = Some(attempt);
        let phases = record.record().map(|ran| Phases {
            setup_s: ran.setup_s,
            solve_s: ran.solve_s,
            wall_s: ran.wall_s.unwrap_or(ran.setup_s + ran.solve_s),
        });
        self.finish(planned, record)?;
        Ok(phases)
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
    case.map_or(1, |case| {
        let (threads, ranks) = case.threads_and_ranks();
        threads * ranks
    })
}

/// The line a worker reads for `case` (`schema::protocol::ServeLine`): the case, the file its
/// time loop says how far it is in, and its checkpoint, written on a stopping signal (and
/// every `checkpoint_every`) and resumed from, and the study's shared spectra where the solver
/// takes them. Paths are absolute (a worker runs in the work directory), and given only when
/// they are text, as JSON needs.
fn served_line(
    case: &Checked,
    key: &str,
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
) -> String {
    let absolute = |path: std::path::PathBuf| {
        let path = std::path::absolute(path).ok()?;
        path.to_str().filter(|p| !p.is_empty()).map(str::to_string)
    };
    let text = |name: &str| absolute(store.scratch(key, name));
    let line = schema::protocol::ServeLine {
        case: case.canonical(),
        progress: text(PROGRESS),
        checkpoint: text(CHECKPOINT),
        checkpoint_every_s: options.checkpoint_every.map(|every| every.as_secs_f64()),
        keep_checkpoint: options.keep_checkpoints,
        spectra: solver
            .shares_spectra
            .then(|| absolute(store.spectra()))
            .flatten(),
    };
    serde_json::to_string(&line).expect("a line serializes")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The costliest first where costs are given, equal costs by key (not in plan order, where
    /// one operator's probes stand together), points that do not run left out; plan order
    /// without costs.
    #[test]
    fn points_start_costliest_first_and_equal_costs_by_key() {
        let point = |n: u64, runs: bool| {
            let fields = serde_json::json!({"dim": 1, "n": n, "m": 2});
            Planned {
                point: crate::model::study::Point::from_fields(fields.as_object().unwrap().clone()),
                case: Err("not checked".into()),
                key: crate::store::case_id_and_key(&fields.to_string(), "", 0).1,
                case_id: Default::default(),
                decision: match runs {
                    true => Decision::Run(Reason::Missing),
                    false => Decision::Duplicate,
                },
                probe: None,
            }
        };
        let planned: Vec<Planned> = (0..6).map(|k| point(16 + k, k != 5)).collect();
        let costs = [1.0, 5.0, 5.0, 1.0, 5.0, 9.0];
        assert_eq!(queue_order(&planned, None), vec![0, 1, 2, 3, 4]);
        let order = queue_order(&planned, Some(&costs));
        let mut dear = [1, 2, 4];
        dear.sort_by_key(|&k| planned[k].key);
        let mut cheap = [0, 3];
        cheap.sort_by_key(|&k| planned[k].key);
        assert_eq!(order, [dear.to_vec(), cheap.to_vec()].concat());
        assert_ne!(
            dear,
            [1, 2, 4],
            "the keys are not in plan order: the test tells them apart"
        );
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
