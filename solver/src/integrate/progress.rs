//! How far a running case is: the time loop writes its step, its steps in all and an estimate
//! of the time left into a small file, at most once a second, so that `nlstudy status` (another
//! process) and the pool's progress bar can show it. A steady solve writes its iteration and the
//! iterations its residual's decay so far says it needs. Like checkpointing it belongs to the
//! process, not to the case: `nlsolve run --progress FILE`, or the line `nlsolve serve` reads.

use schema::protocol::ProgressUnit;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// How often the file is rewritten at most.
const EVERY: Duration = Duration::from_secs(1);

/// The progress file of the run to come, set by `configure` and taken by its timed loop.
static CONFIGURED: Mutex<Option<PathBuf>> = Mutex::new(None);

/// The next run's time loop reports into `path` (`None`: it does not report).
pub fn configure(path: Option<PathBuf>) {
    *CONFIGURED.lock().unwrap_or_else(|e| e.into_inner()) = path;
}

/// The reporter of this run's timed loop, if one was asked for (once: later loops have none).
pub fn take() -> Option<Reporter> {
    let path = CONFIGURED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take()?;
    Some(Reporter {
        path,
        last: None,
        since: Instant::now(),
        first_step: None,
        unit: ProgressUnit::Step,
    })
}

pub struct Reporter {
    path: PathBuf,
    last: Option<Instant>,
    since: Instant,
    /// The step this segment of the run started from (a resumed run's rate is its own).
    first_step: Option<usize>,
    /// What a step is: a time step, or a steady solve's iteration.
    unit: ProgressUnit,
}

impl Reporter {
    /// A reporter whose steps are `unit`s (the file says so: iterations for a steady solve,
    /// whose iterations in all are an estimate).
    pub fn counting(mut self, unit: ProgressUnit) -> Reporter {
        self.unit = unit;
        self
    }

    /// After `steps_done` of `steps`: rewrites the file when a second has passed since the last
    /// time (and after the first step).
    pub fn note(&mut self, steps_done: usize, steps: usize) {
        let first = *self.first_step.get_or_insert(steps_done.saturating_sub(1));
        if self.last.is_some_and(|last| last.elapsed() < EVERY) {
            return;
        }
        self.last = Some(Instant::now());
        let elapsed = self.since.elapsed().as_secs_f64();
        let done_here = (steps_done - first).max(1) as f64;
        let left_s = elapsed / done_here * (steps - steps_done) as f64;
        let text = serde_json::to_string(&schema::protocol::Progress {
            step: steps_done as u64,
            steps: steps as u64,
            elapsed_s: elapsed,
            left_s,
            unit: self.unit,
        })
        .expect("progress serializes");
        // Whole or absent for a reader; a file that cannot be written is only not shown.
        let _ = write(&self.path, text.as_bytes());
    }
}

impl Drop for Reporter {
    /// The loop is over: nothing more to show.
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

fn write(path: &Path, text: &[u8]) -> std::io::Result<()> {
    schema::atomic::write_atomically(path, text).map_err(|(_, e)| e)
}
