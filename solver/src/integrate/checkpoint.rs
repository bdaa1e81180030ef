//! Checkpoints of a time-dependent run, and its restart with the same bits.
//!
//! A checkpoint holds what the run carries from one step to the next (`Carried`): the field,
//! the step, the timed loop's timings so far, the observers' series (c_tot, frames), the total
//! error, the implicit solves' counts. Each layer of the loop (`timed::timed_steps`, its
//! observers, `stepper::integrate`, a θ-stepper) adds its own parts and takes them back. A run
//! resumed from a checkpoint continues from its step with those parts, so its record is the
//! record of a run that was never stopped, but for its timings (`timings_resumed`).
//!
//! Checkpointing belongs to the process, not to the case (`nlsolve run --checkpoint FILE`):
//! the case, and the key the orchestrator files it under, are the same with or without it. The
//! process sets it up once (`configure`) and the run's timed loop takes it (`take`). The file
//! is written beside its place and renamed over it, so the previous checkpoint stays whole
//! until the new one is; it names the solver build (fingerprint), the case (its canonical JSON)
//! and the rank count, and a checksum of its values: one that does not match is refused with
//! its reason and the run starts at step 0.
//!
//! Over MPI ranks each rank writes its own file (`rank_path`: the given path for rank 0,
//! `<path>.rank<r>` for the others) holding its share of the field, at a step all ranks agree on
//! (the timed loop takes the decision over ranks: a period due on any rank, or a stop asked of
//! any, is due on all), and no rank exits before every rank's file is written. A run resumes
//! only when every rank finds its file at the same step; otherwise all start at step 0.

use crate::output::record::Traffic;
use crate::parallel::exchange::Exchange;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// What a run carries from step to step, by name: values saved bit for bit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Carried {
    /// The steps done when it was taken.
    pub step: usize,
    parts: BTreeMap<String, Vec<f64>>,
}

impl Carried {
    /// Nothing yet, at `step` steps done.
    pub fn at(step: usize) -> Carried {
        Carried {
            step,
            parts: BTreeMap::new(),
        }
    }

    pub fn put(&mut self, name: &str, values: Vec<f64>) {
        self.parts.insert(name.to_string(), values);
    }

    pub fn put_number(&mut self, name: &str, value: f64) {
        self.put(name, vec![value]);
    }

    /// A count, exact as an f64 below 2⁵³.
    pub fn put_count(&mut self, name: &str, count: usize) {
        self.put_number(name, count as f64);
    }

    pub fn values(&self, name: &str) -> Option<&[f64]> {
        self.parts.get(name).map(Vec::as_slice)
    }

    pub fn number(&self, name: &str) -> Option<f64> {
        self.values(name).and_then(|v| v.first().copied())
    }

    pub fn count(&self, name: &str) -> Option<usize> {
        self.number(name).map(|v| v as usize)
    }

    /// The traffic sent between `start` and `now`, as the part "traffic" (counts below 2⁵³ are
    /// exact as f64): a resumed run counts it as sent before (`Exchange::count_earlier`).
    pub fn put_traffic_since(&mut self, now: Traffic, start: Traffic) {
        let sent = [
            now.halo_exchanges - start.halo_exchanges,
            now.halo_bytes - start.halo_bytes,
            now.reductions - start.reductions,
            now.reduction_bytes - start.reduction_bytes,
            now.all_to_alls - start.all_to_alls,
            now.all_to_all_bytes - start.all_to_all_bytes,
        ];
        self.put("traffic", sent.map(|count| count as f64).to_vec());
    }

    /// The traffic `put_traffic_since` saved.
    pub fn traffic(&self) -> Option<Traffic> {
        let values = self.values("traffic")?;
        let count = |k: usize| values.get(k).map_or(0, |&v| v as u64);
        Some(Traffic {
            halo_exchanges: count(0),
            halo_bytes: count(1),
            reductions: count(2),
            reduction_bytes: count(3),
            all_to_alls: count(4),
            all_to_all_bytes: count(5),
        })
    }
}

use schema::checkpoint::Header;
pub use schema::checkpoint::Identity;
use schema::regular::FileId;

/// The checkpoint file of `rank`: `path` itself for rank 0 (so a run of one process and the
/// first rank of many read the same name), `<path>.rank<r>` for the others.
pub fn rank_path(path: &Path, rank: usize) -> PathBuf {
    match rank {
        0 => path.to_path_buf(),
        r => {
            let mut name = path.as_os_str().to_os_string();
            name.push(format!(".rank{r}"));
            PathBuf::from(name)
        }
    }
}

/// When a run writes its checkpoint, and where.
#[derive(Clone, Debug)]
pub struct Policy {
    pub path: PathBuf,
    /// Every this many steps.
    pub every_steps: Option<usize>,
    /// Once this much wall time has passed since the last one (or the start).
    pub every: Option<Duration>,
}

/// A run's checkpointing: its policy, its identity and what it resumes from.
pub struct Checkpointer {
    policy: Policy,
    identity: Identity,
    /// What the run resumes from, taken by the loop's layers as they start.
    pub resume: Option<Carried>,
    last: Instant,
    /// Checkpoints written by this process.
    pub written: usize,
}

/// The run's checkpointer, set by `configure` and taken by the run's timed loop.
static CONFIGURED: Mutex<Option<Checkpointer>> = Mutex::new(None);
/// The stopping signal received (0: none): the loop writes a checkpoint and the process stops
/// with the shell's status for it, 128 + its number (143 for SIGTERM).
static STOP: AtomicI32 = AtomicI32::new(0);

/// The checkpoint file this process may remove once its record is out: the one it wrote last or
/// resumed from, by its path and identity. Whatever else stands at that path by then (a file
/// put there since, a link, a device) is left as it is.
static OWN: Mutex<Option<(PathBuf, FileId)>> = Mutex::new(None);

fn own(path: &Path, id: FileId) {
    *OWN.lock().unwrap_or_else(|e| e.into_inner()) = Some((path.to_path_buf(), id));
}

/// Removes the checkpoint this process wrote or resumed from, if the same regular file still
/// stands at its path; anything else is left in place. Nothing is removed twice.
pub fn remove_own() {
    if let Some((path, id)) = OWN.lock().unwrap_or_else(|e| e.into_inner()).take() {
        remove_if_still(&path, id);
    }
}

/// Removes `path` if the regular file `id` stands there (not a link to it, nor another file).
fn remove_if_still(path: &Path, id: FileId) {
    use std::os::unix::fs::MetadataExt;
    let still = std::fs::symlink_metadata(path)
        .is_ok_and(|meta| meta.file_type().is_file() && (meta.dev(), meta.ino()) == id);
    if still {
        let _ = std::fs::remove_file(path);
    }
}

/// Sets up this process's run to checkpoint by `policy`, resuming from the file there when it
/// holds a whole checkpoint of the same `identity` no larger than `cap` bytes
/// (`schema::checkpoint::most_bytes` of the case). Returns why a checkpoint that is there was
/// refused (the run then starts at step 0, and writes over it). A path that holds something
/// that is no checkpoint of nlsolve (`schema::checkpoint::foreign`: a file of the user's, a
/// link, a FIFO, a device) is an error: nlsolve never writes over it or removes it. A process
/// that runs case after case (`serve`) configures each.
pub fn configure(policy: Policy, identity: Identity, cap: u64) -> Result<Option<String>, String> {
    *OWN.lock().unwrap_or_else(|e| e.into_inner()) = None;
    if let Some(why) = schema::checkpoint::foreign(&policy.path) {
        return Err(format!(
            "checkpoint {}: {why}; nlsolve writes no checkpoint over it: give a new path, or one where nlsolve wrote a checkpoint",
            policy.path.display()
        ));
    }
    let (resume, refused) = match read(&policy.path, &identity, cap) {
        Ok(resume) => (resume, None),
        Err(why) => (None, Some(why)),
    };
    OVER.store(false, Ordering::SeqCst);
    *CONFIGURED.lock().unwrap_or_else(|e| e.into_inner()) = Some(Checkpointer {
        policy,
        identity,
        resume,
        last: Instant::now(),
        written: 0,
    });
    Ok(refused)
}

/// `configure` for the run of `case` on `rank`: its identity (this build, the case without its
/// thread count, which changes no bit of a run, so a run may resume on another) and the most a
/// checkpoint of it can hold.
pub fn configure_for(
    case: &crate::ValidCase,
    policy: Policy,
    rank: usize,
) -> Result<Option<String>, String> {
    let canonical = serde_json::to_value(&**case).expect("a case serializes");
    let identity = Identity {
        fingerprint: crate::output::record::FINGERPRINT.to_string(),
        case: Identity::case_text(&canonical),
        ranks: case.ranks,
        rank,
    };
    configure(policy, identity, schema::checkpoint::most_bytes(case))
}

/// The checkpointer `configure` set, for the run's timed loop of `steps` steps (or a steady
/// solve of at most `steps` iterations; once: the untimed runs after it, such as the
/// amplification's, find none), its field `field_len` values long where the loop carries one.
/// A checkpoint that does not fit that loop (another step count, a step past it, a field
/// of another length: a file that is whole and of this case, but of a writer at fault) is
/// refused on stderr and the run starts at step 0.
pub fn take(steps: usize, field_len: Option<usize>) -> Option<Checkpointer> {
    let mut taken = CONFIGURED.lock().unwrap_or_else(|e| e.into_inner()).take();
    if let Some(checkpointer) = taken.as_mut() {
        if let Err(why) = checkpointer.fits(steps, field_len) {
            eprintln!(
                "nlsolve: checkpoint {} refused: {why}; the run starts at step 0",
                checkpointer.policy.path.display()
            );
            checkpointer.resume = None;
        }
    }
    IN_LOOP.store(taken.is_some(), Ordering::SeqCst);
    taken
}

/// Set while a timed loop holds the checkpointer: the warning signal then asks it to write a
/// checkpoint and stop; outside it (the set-up) the process just ends.
static IN_LOOP: AtomicBool = AtomicBool::new(false);

/// Asks the running loop to write its checkpoint and stop, as `signal` does.
pub fn request_stop(signal: i32) {
    STOP.store(signal, Ordering::SeqCst);
}

/// The status a run stopped by `signal` exits with: the shell's, 128 + its number.
fn stopped_status() -> i32 {
    128 + STOP.load(Ordering::SeqCst)
}

/// Makes SIGTERM (Slurm's and LSF's warning signal, `scancel`, a local stop), SIGINT (Ctrl-C)
/// and SIGHUP the request to checkpoint and stop: in the time loop the run writes its
/// checkpoint at the end of the step it is in and exits with 128 + the signal's number; before
/// the loop (nothing to save yet) it exits at once, and once the loop is over it goes on to its
/// record.
pub fn stop_on_signals() {
    extern "C" fn on_signal(signal: libc::c_int) {
        request_stop(signal);
        if !IN_LOOP.load(Ordering::SeqCst) && !OVER.load(Ordering::SeqCst) {
            // SAFETY: _exit is async-signal-safe.
            unsafe { libc::_exit(128 + signal) };
        }
    }
    for signal in [libc::SIGTERM, libc::SIGINT, libc::SIGHUP] {
        // SAFETY: the handler only touches atomics and calls _exit, both async-signal-safe.
        unsafe {
            libc::signal(signal, on_signal as *const () as libc::sighandler_t);
        }
    }
}

/// Set once the timed loop is over: the run goes on to its record.
static OVER: AtomicBool = AtomicBool::new(false);

impl Drop for Checkpointer {
    fn drop(&mut self) {
        IN_LOOP.store(false, Ordering::SeqCst);
        OVER.store(true, Ordering::SeqCst);
    }
}

/// Between the cases of a process that runs many (`serve`), once the last one's answer is out:
/// a stop asked during it ends the process now (with 128 + the signal's number), and until the
/// next case's loop takes its checkpointer a stopping signal ends the process at once.
pub fn between_cases() {
    CONFIGURED.lock().unwrap_or_else(|e| e.into_inner()).take();
    IN_LOOP.store(false, Ordering::SeqCst);
    OVER.store(false, Ordering::SeqCst);
    if stop_requested() {
        std::process::exit(stopped_status());
    }
}

pub fn stop_requested() -> bool {
    STOP.load(Ordering::SeqCst) != 0
}

impl Checkpointer {
    /// Is a periodic checkpoint due after `steps_done` steps?
    pub fn due(&self, steps_done: usize) -> bool {
        self.policy
            .every_steps
            .is_some_and(|every| every > 0 && steps_done.is_multiple_of(every))
            || self
                .policy
                .every
                .is_some_and(|every| self.last.elapsed() >= every)
    }

    /// Whether what it resumes from fits a loop of `steps` steps over a field of `field_len`.
    fn fits(&self, steps: usize, field_len: Option<usize>) -> Result<(), String> {
        let Some(resume) = &self.resume else {
            return Ok(());
        };
        if resume.step > steps {
            return Err(format!("it is at step {} of a run of {steps}", resume.step));
        }
        if resume.count("steps").is_some_and(|theirs| theirs != steps) {
            return Err(format!(
                "it is of a run of {} steps, this one has {steps}",
                resume.count("steps").unwrap_or(0)
            ));
        }
        let Some(field_len) = field_len else {
            return Ok(());
        };
        match resume.values("field").map(<[f64]>::len) {
            Some(len) if len == field_len => Ok(()),
            Some(len) => Err(format!(
                "its field has {len} values, this run's {field_len}"
            )),
            None => Err("it holds no field".into()),
        }
    }

    /// Over ranks, a run resumes only if every rank resumes from the same step: otherwise
    /// every rank forgets its checkpoint and starts afresh (said once, by rank 0).
    pub fn agree_over_ranks(&mut self, exchange: &dyn Exchange) {
        let step = self.resume.as_ref().map_or(-1.0, |c| c.step as f64);
        if exchange.bookkeeping_max(step) != -exchange.bookkeeping_max(-step) {
            if exchange.rank() == 0 {
                eprintln!(
                    "nlsolve: the ranks' checkpoints are not of one step; the run starts at step 0"
                );
            }
            self.resume = None;
        }
    }

    /// Writes `carried`, and the parts `borrowed` from the run as they are, whole. A checkpoint
    /// that cannot be written is said on stderr and the run goes on (the previous one stays
    /// valid).
    pub fn save(&mut self, carried: &Carried, borrowed: &[(&str, &[f64])]) {
        match write(&self.policy.path, &self.identity, carried, borrowed) {
            Ok(id) => {
                own(&self.policy.path, id);
                self.written += 1
            }
            Err(e) => eprintln!(
                "nlsolve: cannot write the checkpoint {}: {e}; the run goes on",
                self.policy.path.display()
            ),
        }
        self.last = Instant::now();
    }

    /// Ends the process after the checkpoint of `step` (a time step, or a steady solve's
    /// `iteration`, as `unit` says), as the stop asked: with 128 + the signal's number (143 for
    /// SIGTERM), and no record, since the run is not over. Over ranks a rank the signal did not
    /// reach exits as SIGTERM would have ended it.
    pub fn stop(&self, unit: &str, step: usize) -> ! {
        if self.identity.rank == 0 {
            eprintln!(
                "nlsolve: stopped at {unit} {step} by a signal; checkpoint {}",
                self.policy.path.display()
            );
        }
        let status = match STOP.load(Ordering::SeqCst) {
            0 => 128 + libc::SIGTERM,
            _ => stopped_status(),
        };
        std::process::exit(status);
    }

    /// The step the run resumed from (0 when it started afresh).
    pub fn resumed_from(&self) -> usize {
        self.resume.as_ref().map_or(0, |c| c.step)
    }
}

/// Writes `carried` and the parts `borrowed` (large vectors of the run's own, not copied) as one
/// checkpoint (`schema::checkpoint`: the header and the values under one checksum), beside its
/// place, synced, then renamed over it. Returns the identity of the file written.
fn write(
    path: &Path,
    identity: &Identity,
    carried: &Carried,
    borrowed: &[(&str, &[f64])],
) -> std::io::Result<FileId> {
    let parts = || {
        let owned = carried
            .parts
            .iter()
            .map(|(n, v)| (n.as_str(), v.as_slice()));
        owned.chain(borrowed.iter().copied())
    };
    let header = Header {
        identity: identity.clone(),
        step: carried.step,
        steps: carried.count("steps"),
        parts: parts().map(|(n, v)| (n.to_string(), v.len())).collect(),
    };
    use std::os::unix::fs::MetadataExt;
    let partial = schema::atomic::partial_path(path);
    let written = (|| {
        // The values go out as they are, in large writes: no copy of the field is made.
        let mut out =
            std::io::BufWriter::with_capacity(1 << 20, schema::atomic::create_fresh(&partial)?);
        schema::checkpoint::write(&mut out, &header, parts().flat_map(|(_, v)| v).copied())?;
        let file = out.into_inner().map_err(|e| e.into_error())?;
        // Whole on disk before it replaces the previous one (a node may fail, not only a process).
        file.sync_data()?;
        let meta = file.metadata()?;
        std::fs::rename(&partial, path)?;
        Ok((meta.dev(), meta.ino()))
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    written
}

/// The checkpoint at `path` of the run `identity`, read no further than `cap` bytes: `None`
/// when there is none, an error saying why when the file is not a whole checkpoint of that run.
fn read(path: &Path, identity: &Identity, cap: u64) -> Result<Option<Carried>, String> {
    let Some((checkpoint, id)) = schema::checkpoint::read_identified(path, cap)? else {
        return Ok(None);
    };
    if let Some(why) = identity.refuses(&checkpoint.header.identity) {
        return Err(why);
    }
    let mut carried = Carried::at(checkpoint.header.step);
    for (name, values) in checkpoint.parts() {
        carried.put(name, values);
    }
    // What others read of it (`nlstudy status`) is what the run resumes from.
    if checkpoint.header.steps != carried.count("steps") {
        return Err(format!(
            "its header says {:?} steps, its values {:?}",
            checkpoint.header.steps,
            carried.count("steps")
        ));
    }
    own(path, id);
    Ok(Some(carried))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity() -> Identity {
        Identity {
            fingerprint: "ab".repeat(32),
            case: r#"{"dim":1,"n":16}"#.into(),
            ranks: 1,
            rank: 0,
        }
    }

    /// At its end a run removes the checkpoint it wrote only if that very file still stands at
    /// its path: not a file put there since, nor a link to it.
    #[test]
    fn only_the_file_written_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.checkpoint");
        let id = write(&path, &identity(), &Carried::at(1), &[]).unwrap();
        remove_if_still(&path, id);
        assert!(!path.exists(), "the file written is removed");

        let id = write(&path, &identity(), &Carried::at(1), &[]).unwrap();
        let moved = dir.path().join("moved");
        std::fs::rename(&path, &moved).unwrap();
        std::fs::write(&path, "the user's").unwrap();
        remove_if_still(&path, id);
        assert_eq!(std::fs::read(&path).unwrap(), b"the user's");

        std::fs::remove_file(&path).unwrap();
        std::os::unix::fs::symlink(&moved, &path).unwrap();
        remove_if_still(&path, id);
        assert!(
            path.is_symlink() && moved.exists(),
            "a link to it stays, and so does it"
        );
    }

    #[test]
    fn a_checkpoint_reads_back_bit_for_bit_and_a_damaged_or_foreign_one_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.checkpoint");
        assert_eq!(read(&path, &identity(), 1 << 20), Ok(None), "none yet");
        let mut carried = Carried::at(17);
        carried.put(
            "field",
            vec![0.1, -0.0, f64::MIN_POSITIVE, 1e300, 1.0 / 3.0],
        );
        carried.put_count("solves", 12);
        carried.put("empty", Vec::new());
        write(&path, &identity(), &carried, &[]).unwrap();
        assert_eq!(read(&path, &identity(), 1 << 20), Ok(Some(carried.clone())));
        // Parts lent by the run read back as parts of their own.
        let lent = [2.5, -1e-300, f64::MAX];
        write(&path, &identity(), &carried, &[("lent", &lent)]).unwrap();
        let mut with_lent = carried.clone();
        with_lent.put("lent", lent.to_vec());
        assert_eq!(read(&path, &identity(), 1 << 20), Ok(Some(with_lent)));
        write(&path, &identity(), &carried, &[]).unwrap();
        let bits = |c: &Carried| -> Vec<u64> {
            c.values("field")
                .unwrap()
                .iter()
                .map(|v| v.to_bits())
                .collect()
        };
        assert_eq!(
            bits(&read(&path, &identity(), 1 << 20).unwrap().unwrap()),
            bits(&carried)
        );

        let refused = |identity: Identity| read(&path, &identity, 1 << 20).unwrap_err();
        let other_build = Identity {
            fingerprint: "cd".repeat(32),
            ..identity()
        };
        assert!(refused(other_build).contains("another solver build"));
        let other_case = Identity {
            case: r#"{"dim":1,"n":32}"#.into(),
            ..identity()
        };
        assert!(refused(other_case).contains("another case"));
        let other_ranks = Identity {
            ranks: 2,
            ..identity()
        };
        assert!(refused(other_ranks).contains("written on 1 ranks, this run has 2"));

        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        assert!(refused(identity()).contains("cut short"));
        let mut flipped = bytes.clone();
        let last = flipped.len() - 1;
        flipped[last] ^= 1;
        std::fs::write(&path, &flipped).unwrap();
        assert!(refused(identity()).contains("checksum"));
        std::fs::write(&path, b"garbage").unwrap();
        assert!(refused(identity()).contains("not a checkpoint"));
    }
}
