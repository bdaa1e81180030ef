//! The worker pool: `nlsolve` processes within a core budget, MPI cases through a launcher, a
//! timeout per case, failures stored with the tail of stderr, and a clean stop on Ctrl-C.
//!
//! Each case runs under its key's lock in the store, so processes sharing a store never run a
//! point at the same time; a point another process holds, or has stored meanwhile, is passed.
//! A solver process dies with this one (its parent-death signal), so a killed `nlstudy` leaves
//! no case running unowned.

use crate::model::launcher::Launcher;
use crate::run::nlsolve::Nlsolve;
use crate::run::plan::{Decision, Planned, Reason};
use crate::run::progress::Progress;
use crate::run::signals::Stop;
use crate::store::fs::{create_dir, create_fresh, open_regular, read_regular, RECORD_CAP};
use crate::store::{FileError, Store};
use schema::exit;
use schema::record::{Failure, Outcome, Record, Status, Stored};
use serde_json::Value;
use std::fs::File;
use std::os::unix::process::{CommandExt, ExitStatusExt};
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
    if !exit
        .signal()
        .is_some_and(|s| crate::run::signals::CAUGHT.contains(&s))
    {
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
    /// One case at a time, so that timings are not disturbed.
    pub exclusive: bool,
    pub timeout: Option<Duration>,
    /// Command prefix of MPI cases, e.g. `srun --mpi=pmix -n {ranks}`.
    pub launcher: Launcher,
    /// Further attempts at a case that failed for a reason outside it: past its timeout, killed
    /// by a signal, or its MPI launcher hung. A case that diverges or is refused is a result and
    /// never runs again.
    pub retries: usize,
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
    child: Child,
    started: Instant,
    cores: usize,
    stdout: PathBuf,
    stderr: PathBuf,
    case_file: PathBuf,
    /// The key's lock in the store, held until the record is stored.
    _lock: File,
    /// MPI jobs: when a rank was first seen exited and not reaped by the launcher.
    launcher_watch: Option<LauncherWatch>,
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
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return false;
    };
    entries.flatten().any(|entry| {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            return false;
        };
        // After the command name's closing parenthesis: state, then the parent's pid.
        let Some((_, rest)) = stat.rsplit_once(')') else {
            return false;
        };
        let mut fields = rest.split_whitespace();
        let state = fields.next();
        let ppid = fields.next().and_then(|p| p.parse::<u32>().ok());
        state == Some("Z") && ppid == Some(parent)
    })
}

/// Runs the planned points that run; stores each record as it finishes. A failure of the file
/// system (the store, the scratch files, a record nlsolve could not write) is not a property of
/// a case: it stops the run, the running cases are ended and nothing is stored for them, so
/// the next run takes them up again.
pub fn run(
    planned: &[Planned],
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    stop: &Stop,
    progress: &mut Progress,
) -> Result<Tally, FileError> {
    let mut running: Vec<Running> = Vec::new();
    let outcome = run_cases(
        planned,
        solver,
        store,
        options,
        stop,
        progress,
        &mut running,
    );
    for mut job in running {
        let _ = job.child.kill();
        let _ = job.child.wait();
        job.remove_files();
    }
    outcome
}

fn run_cases(
    planned: &[Planned],
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    stop: &Stop,
    progress: &mut Progress,
    running: &mut Vec<Running>,
) -> Result<Tally, FileError> {
    let mut tally = Tally::default();
    // (point, attempt), popped from the back in plan order.
    let mut queue: Vec<(usize, usize)> = (0..planned.len())
        .filter(|&i| planned[i].runs())
        .map(|i| (i, 1))
        .collect();
    queue.reverse();
    create_dir(&store.work_dir())?;
    loop {
        if stop.requested() {
            tally.interrupted = true;
            return Ok(tally);
        }
        // Start what fits; a case larger than the budget runs alone.
        while let Some(&(next, attempt)) = queue.last() {
            let planned = &planned[next];
            let cores = cores_of(planned);
            let used: usize = running.iter().map(|r| r.cores).sum();
            let fits = if options.exclusive {
                running.is_empty()
            } else {
                running.is_empty() || used + cores <= options.cores
            };
            if !fits {
                break;
            }
            queue.pop();
            let Some(lock) = store.lock(&planned.key)? else {
                progress.passed(&planned.point.label(), "another nlstudy is running it");
                tally.passed += 1;
                continue;
            };
            // A forced or stale point runs whatever is stored; others may have been stored by
            // another nlstudy since the plan.
            let forced = matches!(
                planned.decision,
                Decision::Run(Reason::Forced | Reason::Stale { .. })
            );
            let stored = store.status(&planned.key).filter(|s| *s != Status::Failed);
            if let Some(status) = stored.filter(|_| !forced) {
                let why = format!("another nlstudy has stored it meanwhile ({status})");
                progress.passed(&planned.point.label(), &why);
                tally.passed += 1;
                continue;
            }
            match &planned.case {
                Err(message) => {
                    let record = failed_record(planned, solver, message.clone());
                    finish(store, planned, record, &mut tally, progress)?;
                }
                Ok(case) => {
                    let mut job = start(
                        next,
                        &case.canonical(),
                        planned,
                        solver,
                        store,
                        options,
                        lock,
                    )?;
                    job.attempt = attempt;
                    running.push(job);
                }
            }
        }
        if running.is_empty() && queue.is_empty() {
            return Ok(tally);
        }
        std::thread::sleep(Duration::from_millis(10));
        let mut k = 0;
        while k < running.len() {
            let job = &mut running[k];
            let timed_out = options
                .timeout
                .is_some_and(|limit| job.started.elapsed() > limit);
            let launcher_hung = !timed_out
                && job.launcher_watch.as_mut().is_some_and(|watch| {
                    let pid = job.child.id();
                    watch.hung(pid)
                });
            let exit = if timed_out || launcher_hung {
                let _ = job.child.kill();
                Some(job.child.wait())
            } else {
                job.child.try_wait().transpose()
            };
            let exit = exit
                .transpose()
                .map_err(FileError::on("wait for", &solver.binary))?;
            let Some(exit) = exit else {
                k += 1;
                continue;
            };
            let job = running.swap_remove(k);
            if !exit.success() && stopped_with_it(stop, exit) {
                // Ctrl-C reaches the whole process group, scancel the whole job: a case the
                // stopping signal ended is not a failure.
                job.remove_files();
                continue;
            }
            let planned = &planned[job.index];
            let killed = exit.signal().is_some() && !exit.success();
            let outside_the_case = timed_out || launcher_hung || killed;
            let record = if timed_out {
                failed_record(
                    planned,
                    solver,
                    format!(
                        "timed out after {:.0} s; {}",
                        job.started.elapsed().as_secs_f64(),
                        job.stderr_tail()
                    ),
                )
            } else if launcher_hung {
                failed_record(
                    planned,
                    solver,
                    format!(
                        "a rank exited and the MPI launcher had not ended {} s later, so it was killed; {}",
                        UNREAPED_RANK_GRACE.as_secs(),
                        job.stderr_tail()
                    ),
                )
            } else {
                job.record(planned, solver, exit)?
            };
            job.remove_files();
            let failed = record.status() == Status::Failed;
            if failed && outside_the_case && job.attempt <= options.retries {
                progress.retrying(&planned.point.label(), job.attempt + 1, record.message());
                queue.push((job.index, job.attempt + 1));
                continue;
            }
            let mut record = record;
            record.attempt = Some(job.attempt);
            finish(store, planned, record, &mut tally, progress)?;
        }
    }
}

/// The cores this process may use (its affinity mask and cgroup quota respected).
pub fn machine_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// threads × ranks of a case (1 for a refused one).
fn cores_of(planned: &Planned) -> usize {
    let field = |name: &str| {
        planned
            .case
            .as_ref()
            .ok()
            .and_then(|c| c.resolved_count(name))
            .unwrap_or(1) as usize
    };
    field("threads").max(1) * field("ranks").max(1)
}

fn start(
    index: usize,
    case: &Value,
    planned: &Planned,
    solver: &Nlsolve,
    store: &Store,
    options: &PoolOptions,
    lock: File,
) -> Result<Running, FileError> {
    let work = store.work_dir();
    let case_file = work.join(format!("{}.case.json", planned.key));
    let stdout = work.join(format!("{}.out", planned.key));
    let stderr = work.join(format!("{}.err", planned.key));
    create_fresh(&case_file)
        .and_then(|mut file| std::io::Write::write_all(&mut file, case.to_string().as_bytes()))
        .map_err(FileError::on("write", &case_file))?;
    let ranks = case.get("ranks").and_then(Value::as_u64).unwrap_or(1);
    let threads = case.get("threads").and_then(Value::as_u64).unwrap_or(1);
    let mut command = if ranks > 1 {
        let mut command = launcher_command(&options.launcher, ranks, threads);
        if is_root() {
            // Open MPI refuses root (containers, CI) unless told.
            command.env("OMPI_ALLOW_RUN_AS_ROOT", "1");
            command.env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
        }
        command.arg(&solver.binary);
        command
    } else {
        Command::new(&solver.binary)
    };
    command.arg("run").arg("--case").arg(&case_file);
    if case.get("vtk_every").is_some_and(|every| !every.is_null()) {
        command.arg("--write-vtk").arg(store.fields(&planned.key));
    }
    command
        .stdin(Stdio::null())
        .stdout(create_fresh(&stdout).map_err(FileError::on("create", &stdout))?)
        .stderr(create_fresh(&stderr).map_err(FileError::on("create", &stderr))?);
    // SAFETY: prctl is async-signal-safe and touches no memory of the parent.
    unsafe {
        command.pre_exec(|| {
            // The case dies with this process (SIGKILL included), not run on unowned.
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let program = PathBuf::from(command.get_program());
    let child = command.spawn().map_err(FileError::on("start", &program))?;
    Ok(Running {
        index,
        attempt: 1,
        child,
        started: Instant::now(),
        cores: cores_of(planned),
        stdout,
        stderr,
        case_file,
        _lock: lock,
        launcher_watch: (ranks > 1).then(|| LauncherWatch {
            checked: Instant::now(),
            unreaped_since: None,
        }),
    })
}

impl Running {
    /// The record a finished process printed, or a failed record with its stderr; an error
    /// when nlsolve could not write the record it computed.
    fn record(
        &self,
        planned: &Planned,
        solver: &Nlsolve,
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
        // The record is nlsolve's last line that is a JSON object; it must keep to the schema.
        let last_object = printed.lines().rev().find_map(|line| {
            serde_json::from_str::<Value>(line)
                .ok()
                .filter(Value::is_object)
        });
        let record = last_object.map(|object| {
            serde_path_to_error::deserialize::<_, Record<Value>>(object)
                .map_err(|e| format!("field `{}`: {}", e.path(), e.inner()))
        });
        Ok(match (ended.success(), record) {
            (true, Some(Ok(mut record))) => {
                // Its timings measure contention, not scaling; figures and tables say so. Over
                // ranks, the solver judges it from each rank's affinity; here, from the cores.
                let oversubscribed = self.cores > machine_cores();
                record
                    .distribution
                    .oversubscribed
                    .get_or_insert(oversubscribed);
                stored(planned, solver, Outcome::Ran(Box::new(record)))
            }
            (true, Some(Err(why))) => failed_record(
                planned,
                solver,
                format!("nlsolve printed a record that does not keep to the schema ({why}); is the solver of another version?"),
            ),
            _ => failed_record(
                planned,
                solver,
                format!("nlsolve exited with {ended}: {}", self.stderr_tail()),
            ),
        })
    }

    fn stderr_tail(&self) -> String {
        let text = tail_of(&self.stderr);
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(STDERR_TAIL)..].join("\n")
    }

    fn remove_files(&self) {
        for path in [&self.stdout, &self.stderr, &self.case_file] {
            let _ = std::fs::remove_file(path);
        }
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

fn failed_record(planned: &Planned, solver: &Nlsolve, message: String) -> Stored {
    let case = match &planned.case {
        Ok(case) => case.canonical(),
        Err(_) => Value::Object(planned.point.fields()),
    };
    stored(planned, solver, Outcome::Failed(Failure { case, message }))
}

fn finish(
    store: &Store,
    planned: &Planned,
    record: Stored,
    tally: &mut Tally,
    progress: &mut Progress,
) -> Result<(), FileError> {
    let status = record.status();
    let mut message = record.message().to_string();
    if !store.save(&planned.key, &record)? {
        message.push_str("; the stored result of an earlier run is kept");
    }
    store.release_lock_file(&planned.key);
    match status {
        Status::Ok => tally.ok += 1,
        Status::Diverged => tally.diverged += 1,
        Status::Failed => tally.failed += 1,
    }
    tally.noisy += usize::from(record.noisy());
    progress.finished(&planned.point.label(), status, &message);
    Ok(())
}

/// Is this process root (uid 0)? Read from /proc, to need no libc binding.
fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("Uid:"))?;
            Some(line.split_whitespace().nth(1)? == "0")
        })
        .unwrap_or(false)
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
}
