//! Solver workers: `nlsolve serve` processes kept up from case to case, so that a tiny case
//! costs its solve and a line each way instead of a process start (~6 ms of a 25 µs case).
//!
//! A worker is one process answering the canonical cases written to its standard input, one
//! JSON line each, with the record `nlsolve run` would print (or `{"error": …}`). A thread per
//! worker reads its answers into one channel, which the pool waits on: an answer wakes it at
//! once. What a worker writes to standard error is kept, its last lines, for a failed record.

use crate::run::allocation::Node;
use crate::run::dial_back::{Dial, Heard, Listener};
use crate::run::nlsolve::Nlsolve;
use crate::store::FileError;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Write};
use std::net::IpAddr;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Lines of a worker's standard error kept for a failed record.
const STDERR_LINES: usize = 20;
/// The resident memory, in MiB, past which a worker that answered is replaced by default (a
/// fresh one holds about 8 MiB): memory a case freed but the allocator kept would count in the
/// next cases' `peak_memory_bytes`, which a process of its own would not, and a leak would grow
/// without bound.
pub const MEMORY_BOUND_MIB: u64 = 64;

/// The pool's workers: the idle ones and the channel every worker's answers come through.
pub struct Workers {
    said: Sender<Heard>,
    heard: Receiver<Heard>,
    idle: Vec<Worker>,
    /// This node's address, where workers on the allocation's other nodes connect
    /// (`dial_back`); `None`: they answer through their job step's standard streams.
    dial_back: Option<IpAddr>,
    listener: Option<Listener>,
    started: u64,
    /// Where workers run: the store's work directory, which tells whose workers they are
    /// (`/proc/<pid>/cwd`); a worker reads and writes no file.
    dir: PathBuf,
    /// Resident bytes past which a worker that answered is replaced.
    memory_bound: u64,
    /// The solver turned out not to serve (one from before `serve`, or a wrapper script that
    /// knows only `run`): every case runs as a process of its own from then on.
    pub unsupported: bool,
    /// What each worker did when, kept over the batches (rounds) as the workers are.
    pub timeline: crate::run::timeline::Timeline,
}

/// How long an ended worker's last words on standard error are waited for.
const HEARING: std::time::Duration = std::time::Duration::from_secs(1);

pub struct Worker {
    id: u64,
    /// Where it runs: the pool's node and the cores its step holds there.
    place: Place,
    child: Child,
    input: Input,
    /// When it was started: with its connection's time, its start.
    started_at: std::time::Instant,
    stderr: Arc<Mutex<VecDeque<String>>>,
    /// The thread that keeps `stderr`: done once the worker's standard error closed.
    stderr_reader: std::thread::JoinHandle<()>,
    /// Cases it has answered.
    pub answered: usize,
}

/// Where a worker reads its cases: its standard input, or its connection to the pool.
enum Input {
    Pipe(ChildStdin),
    Dialed {
        dial: Arc<Mutex<Dial>>,
        /// Held open and unused: a scheduler may end a step whose input closes.
        _stdin: ChildStdin,
    },
}

/// A worker's node (an index into the pool's nodes) and the cores its job step holds there (0
/// on this machine, where a worker serves cases of any thread count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Place {
    pub node: usize,
    pub cores: usize,
}

/// How a case sent to a worker ended.
pub enum Served {
    /// The worker printed this line.
    Answer(String),
    /// It ended (or closed its output) without answering: crashed, killed, or no `serve`.
    Died(ExitStatus),
}

impl Workers {
    /// Workers running in `dir`, replaced once they hold more than `memory_bound_mib` MiB.
    pub fn new(dir: PathBuf, memory_bound_mib: u64) -> Workers {
        let (said, heard) = channel();
        Workers {
            said,
            heard,
            idle: Vec::new(),
            dial_back: None,
            listener: None,
            started: 0,
            dir,
            memory_bound: memory_bound_mib << 20,
            unsupported: false,
            timeline: Default::default(),
        }
    }

    /// Workers started as job steps connect to `address`, this node's, to take their cases and
    /// give their answers.
    pub fn dial_back_to(&mut self, address: Option<IpAddr>) {
        self.dial_back = address;
    }

    /// Workers answer through their job steps' standard streams from now on: one could not
    /// connect (`why`).
    pub fn stop_dialing_back(&mut self, why: &str) {
        if let Some(address) = self.dial_back.take() {
            log::info!(
                "a worker could not answer over a connection to {address} ({why}): cases and answers go through the job steps' standard streams"
            );
        }
    }

    /// A worker to run a case at `place` (on `node`): an idle one there still alive, or a new
    /// one (a job step on an allocation's node).
    pub fn take(
        &mut self,
        solver: &Nlsolve,
        place: Place,
        node: &Node,
    ) -> Result<Worker, FileError> {
        while let Some(at) = self.idle.iter().rposition(|w| w.place == place) {
            let mut worker = self.idle.swap_remove(at);
            if matches!(worker.child.try_wait(), Ok(None)) {
                return Ok(worker);
            }
            worker.end();
        }
        if node.name.is_some() {
            // Idle steps on the node hold cores the scheduler would wait for.
            self.close_on(place.node);
        }
        self.started += 1;
        let command = node.command(place.cores, &solver.binary);
        if let (Some(_), Some(ip)) = (&node.name, self.dial_back) {
            self.bind_listener(ip);
        }
        let listener = match node.name {
            Some(_) => self.listener.as_ref().filter(|_| self.dial_back.is_some()),
            None => None,
        };
        Worker::start(
            self.started,
            place,
            command,
            &self.dir,
            self.said.clone(),
            listener,
        )
    }

    /// Binds the listener workers connect to, on first use; where it cannot be bound, workers
    /// answer through their standard streams.
    fn bind_listener(&mut self, ip: IpAddr) {
        if self.listener.is_none() {
            match Listener::bind(ip) {
                Ok(listener) => {
                    log::info!(
                        "workers on other nodes take their cases and give their answers over connections to {}",
                        listener.address
                    );
                    self.listener = Some(listener);
                }
                Err(e) => self.stop_dialing_back(&format!("cannot listen on {ip}: {e}")),
            }
        }
    }

    /// Ends the idle workers on `node`, whose job steps hold cores a new step there needs.
    pub fn close_on(&mut self, node: usize) {
        let (there, elsewhere) = std::mem::take(&mut self.idle)
            .into_iter()
            .partition(|w| w.place.node == node);
        self.idle = elsewhere;
        for worker in there {
            worker.close();
        }
    }

    /// Takes back a worker that answered: kept for the next case unless it holds too much (on
    /// this machine; a job step's process here is the scheduler's launcher, not the worker).
    pub fn give_back(&mut self, mut worker: Worker) {
        let local = worker.place.cores == 0;
        if local
            && resident_memory(worker.child.id()).is_some_and(|bytes| bytes > self.memory_bound)
        {
            worker.end();
        } else {
            self.idle.push(worker);
        }
    }

    /// Waits up to `limit` for a worker's line; `Some` with the worker's id and the line.
    pub fn listen(&self, limit: Duration) -> Option<(u64, Option<String>)> {
        self.heard.recv_timeout(limit).ok()
    }

    /// Ends the idle workers (their input closes; each exits after its last answer).
    pub fn close(&mut self) {
        for worker in self.idle.drain(..) {
            worker.close();
        }
    }
}

impl Drop for Workers {
    fn drop(&mut self) {
        self.close();
    }
}

impl Worker {
    /// Starts `command` (the solver, or a job step of it) as a worker: over its standard
    /// streams, or connecting to `listener`.
    fn start(
        id: u64,
        place: Place,
        mut command: Command,
        dir: &Path,
        said: Sender<Heard>,
        listener: Option<&Listener>,
    ) -> Result<Worker, FileError> {
        command
            .arg("serve")
            .current_dir(dir)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let dialed = listener.map(|listener| {
            let (token, dial) = listener.expect(id, said.clone());
            command
                .arg("--connect")
                .arg(listener.address.to_string())
                .env(schema::protocol::SERVE_TOKEN_ENV, token);
            dial
        });
        die_with_parent(&mut command);
        let program = PathBuf::from(command.get_program());
        let started_at = std::time::Instant::now();
        let mut child = command.spawn().map_err(FileError::on("start", &program))?;
        let stdin = child.stdin.take().expect("piped");
        let stdout = child.stdout.take().expect("piped");
        let stderr_pipe = child.stderr.take().expect("piped");
        let dial = dialed.as_ref().map(Arc::clone);
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                // A worker that connected answers over its connection.
                if dial.is_none() && said.send((id, Some(line))).is_err() {
                    return;
                }
            }
            // Its standard output closed: the end of its answers, unless they come over its
            // connection (which says when they end).
            let ended = match &dial {
                None => true,
                Some(dial) => dial
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .ended_unconnected(),
            };
            if ended {
                let _ = said.send((id, None));
            }
        });
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let kept = Arc::clone(&stderr);
        let stderr_reader = std::thread::spawn(move || {
            for line in BufReader::new(stderr_pipe).lines() {
                let Ok(line) = line else { break };
                let mut kept = kept.lock().unwrap_or_else(|e| e.into_inner());
                if kept.len() == STDERR_LINES {
                    kept.pop_front();
                }
                kept.push_back(line);
            }
        });
        let input = match dialed {
            None => Input::Pipe(stdin),
            Some(dial) => Input::Dialed {
                dial,
                _stdin: stdin,
            },
        };
        Ok(Worker {
            id,
            place,
            child,
            input,
            started_at,
            stderr,
            stderr_reader,
            answered: 0,
        })
    }

    /// Whether it answers over a connection, and if so whether it has connected.
    pub fn dialed(&self) -> Option<bool> {
        match &self.input {
            Input::Pipe(_) => None,
            Input::Dialed { dial, .. } => Some(lock(dial).connected_at.is_some()),
        }
    }

    /// Seconds from its start to its connection: a job step's start, the solver's and its
    /// dial (`None` where it answers through its standard streams or has not connected).
    pub fn start_s(&self) -> Option<f64> {
        let connected = match &self.input {
            Input::Pipe(_) => None,
            Input::Dialed { dial, .. } => lock(dial).connected_at,
        };
        Some(connected?.duration_since(self.started_at).as_secs_f64())
    }

    pub fn id(&self) -> u64 {
        self.id
    }

    /// Sends a canonical case (one line of compact JSON); false when the worker is gone.
    pub fn send(&mut self, case: &str) -> bool {
        // What it said about the case before goes; what it said starting up (before any
        // answer) stays: a solver that cannot serve says why as it starts.
        if self.answered > 0 {
            self.stderr
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .clear();
        }
        let mut line = String::with_capacity(case.len() + 1);
        line.push_str(case);
        line.push('\n');
        match &mut self.input {
            Input::Pipe(stdin) => stdin.write_all(line.as_bytes()).is_ok() && stdin.flush().is_ok(),
            Input::Dialed { dial, .. } => lock(dial).send(line.as_bytes()),
        }
    }

    /// How the case in hand ended, given the worker's line (`None`: its output closed).
    pub fn ended(&mut self, line: Option<String>) -> Served {
        match line {
            Some(line) => {
                self.answered += 1;
                Served::Answer(line)
            }
            None => {
                let exit = self.child.wait().unwrap_or_else(|_| died());
                self.heard_all();
                Served::Died(exit)
            }
        }
    }

    /// Asks the worker to stop (SIGTERM: a case in its time loop writes its checkpoint first),
    /// kills it once `grace` has passed, and reaps it.
    pub fn stop(&mut self, grace: Duration) {
        if matches!(self.child.try_wait(), Ok(None)) {
            // SAFETY: kill(2) on our own child, not reaped yet (`try_wait` caches an exit).
            unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
            let asked = std::time::Instant::now();
            while asked.elapsed() < grace && matches!(self.child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        self.kill();
    }

    /// Kills the worker (past its timeout, or with the run stopping) and reaps it.
    pub fn kill(&mut self) -> ExitStatus {
        let _ = self.child.kill();
        let exit = self.child.wait().unwrap_or_else(|_| died());
        self.heard_all();
        exit
    }

    /// Waits, a second at most, until the ended worker's standard error is read to its end
    /// (the reader thread may lag the exit), so that `stderr_tail` has its last words; a
    /// process the worker started may hold the pipe open longer.
    fn heard_all(&self) {
        let since = std::time::Instant::now();
        while !self.stderr_reader.is_finished() && since.elapsed() < HEARING {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    }

    /// The last lines it wrote to standard error since its case was sent.
    /// (Escaped as the stderr of a process is: `schema::text::printable`.)
    pub fn stderr_tail(&self) -> String {
        let kept = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
        let tail = kept
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>()
            .join("\n");
        schema::text::printable(&tail).into_owned()
    }

    /// Lets an idle worker finish: its input closes and it exits.
    fn close(mut self) {
        match self.input {
            Input::Pipe(stdin) => drop(stdin),
            Input::Dialed { ref dial, .. } => lock(dial).close(),
        }
        let _ = self.child.wait();
    }

    fn end(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}

/// The status of a process whose end could not be waited for: killed.
fn died() -> ExitStatus {
    use std::os::unix::process::ExitStatusExt;
    ExitStatus::from_raw(libc::SIGKILL)
}

/// Makes the process `command` starts die with this one (SIGKILL included), so that a killed
/// `nlstudy` leaves no case running unowned.
pub fn die_with_parent(command: &mut Command) {
    // SAFETY: prctl is async-signal-safe and touches no memory of the parent.
    unsafe {
        command.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// The resident memory of process `pid` in bytes (VmRSS), when /proc tells.
fn resident_memory(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
