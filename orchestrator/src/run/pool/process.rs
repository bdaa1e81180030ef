//! A case in a process of its own: `nlsolve run` started (through the MPI launcher for a case
//! over ranks, as a job step on a node of an allocation), watched for a launcher that leaves a
//! dead rank unreaped, and read back from its files once it ends.

use super::options::PoolOptions;
use super::record::{failed_record, last_object, printed_record};
use crate::model::launcher::Launcher;
use crate::run::allocation::Node;
use crate::run::nlsolve::{Checked, Nlsolve};
use crate::run::plan::Planned;
use crate::run::worker::die_with_parent;
use crate::store::fs::{create_fresh, open_regular, read_regular, RECORD_CAP};
use crate::store::{FileError, Store, CHECKPOINT, SCRATCH};
use schema::exit;
use schema::record::Stored;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The command that starts a case of `ranks` ranks of `threads` threads through `launcher`.
pub(super) fn launcher_command(launcher: &Launcher, ranks: u64, threads: u64) -> Command {
    let mut words = launcher.argv(ranks, threads).into_iter();
    let mut command = Command::new(words.next().expect("a launcher has a program"));
    command.args(words);
    command
}

/// Lines of stderr kept in a failed record.
pub(super) const STDERR_TAIL: usize = 20;

/// How long an MPI launcher may leave an exited rank unreaped before its job is ended: Open MPI
/// 4.1's `mpirun` can hang for good, ignoring SIGTERM, when a rank dies early (the dead rank
/// stays a zombie, the launcher waits on a futex), which would stall the study.
pub(super) const UNREAPED_RANK_GRACE: Duration = Duration::from_secs(10);

/// How often a running MPI job's ranks are looked at.
pub(super) const RANK_CHECK_EVERY: Duration = Duration::from_secs(1);

pub(super) struct Process {
    pub(super) child: Child,
    pub(super) stdout: PathBuf,
    pub(super) stderr: PathBuf,
    pub(super) case_file: PathBuf,
    pub(super) progress: PathBuf,
    /// MPI jobs: when a rank was first seen exited and not reaped by the launcher.
    pub(super) launcher_watch: Option<LauncherWatch>,
}

/// What is known of an MPI launcher's ranks.
pub(super) struct LauncherWatch {
    pub(super) checked: Instant,
    pub(super) unreaped_since: Option<Instant>,
}

impl LauncherWatch {
    /// Has a rank of `launcher` been dead and unreaped for longer than the grace period?
    pub(super) fn hung(&mut self, launcher: u32) -> bool {
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
pub(super) fn has_zombie_child(parent: u32) -> bool {
    processes().any(|(_, ppid, state)| state == 'Z' && ppid == parent)
}

/// The running children of process `parent` (an MPI launcher's ranks on this machine).
pub(super) fn children_of(parent: u32) -> Vec<u32> {
    processes()
        .filter(|&(_, ppid, state)| ppid == parent && state != 'Z')
        .map(|(pid, _, _)| pid)
        .collect()
}

/// Every process's pid, parent's pid and state, from /proc.
pub(super) fn processes() -> impl Iterator<Item = (u32, u32, char)> {
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

/// Starts `case` as a process of its own: `nlsolve run`, through the launcher over ranks.
pub(super) fn start(
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
    let (threads, ranks) = case.threads_and_ranks();
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
    if solver.shares_spectra {
        command.arg("--spectra").arg(store.spectra());
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
    pub(super) fn record(
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
    pub(super) fn printed_a_record(&self) -> bool {
        read_regular(&self.stdout, RECORD_CAP).is_ok_and(|printed| last_object(&printed).is_some())
    }

    /// The last lines of its stderr, as stored in a failed record: what a terminal would act on
    /// (an escape sequence) escaped, since the record's message is printed.
    pub(super) fn stderr_tail(&self) -> String {
        let text = tail_of(&self.stderr);
        let lines: Vec<&str> = text.lines().collect();
        let tail = lines[lines.len().saturating_sub(STDERR_TAIL)..].join("\n");
        schema::text::printable(&tail).into_owned()
    }

    pub(super) fn remove_files(&self) {
        for path in [&self.stdout, &self.stderr, &self.case_file, &self.progress] {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The last 64 KiB of the regular file `path` as text ("" when it cannot be read).
pub(super) fn tail_of(path: &std::path::Path) -> String {
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

/// Is this process root (effective uid 0)?
pub(super) fn is_root() -> bool {
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
}
