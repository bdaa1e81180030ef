//! What this process's threads spent on a run's phases, beside their wall time: CPU time (user
//! and system, every thread, `CLOCK_PROCESS_CPUTIME_ID`) and the time they waited, ready to run,
//! for a core another task held (the kernel's run-queue delay, per thread in
//! `/proc/self/task/*/schedstat`). The CPU time measures the work whatever the neighbours do;
//! the wait says how much of the wall time they took, which a run's wall time alone cannot tell
//! apart from its own slowness.
//!
//! A run has two phases: its set-up, from its start (`run_starts`) to its solve, and its solve
//! (`Solving`), the time loop with its bookkeeping or a steady solve. Each read costs about a
//! microsecond (a system call, a small file per thread), so phases are read at their ends only,
//! never per step.

use std::sync::Mutex;
use std::time::Instant;

/// A process's usage so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Usage {
    /// CPU seconds of every thread, exited ones included.
    pub cpu_s: f64,
    /// Run-queue seconds of the threads alive now; `None` where the kernel does not keep them
    /// (no `schedstat`).
    pub wait_s: Option<f64>,
}

impl Usage {
    pub fn now() -> Usage {
        Usage {
            cpu_s: process_cpu_s(),
            wait_s: threads_wait_s(),
        }
    }

    /// What was spent between `earlier` and `self`.
    pub fn since(self, earlier: Usage) -> Usage {
        Usage {
            cpu_s: (self.cpu_s - earlier.cpu_s).max(0.0),
            wait_s: self
                .wait_s
                .zip(earlier.wait_s)
                .map(|(now, then)| (now - then).max(0.0)),
        }
    }
}

/// CPU seconds of this process, every thread (user and system).
fn process_cpu_s() -> f64 {
    let mut time = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes the timespec it is given, which lives on this stack.
    let read = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut time) };
    match read {
        0 => time.tv_sec as f64 + time.tv_nsec as f64 * 1e-9,
        _ => 0.0,
    }
}

/// Seconds this process's threads have waited on a run queue, summed over the threads alive now
/// (the second field of each `/proc/self/task/<tid>/schedstat`, in nanoseconds).
fn threads_wait_s() -> Option<f64> {
    let tasks = std::fs::read_dir("/proc/self/task").ok()?;
    let mut waited_ns = 0u64;
    let mut read_any = false;
    for task in tasks.flatten() {
        let Ok(text) = std::fs::read_to_string(task.path().join("schedstat")) else {
            continue; // a thread that ended meanwhile
        };
        let ns = text.split_whitespace().nth(1)?.parse::<u64>().ok()?;
        waited_ns += ns;
        read_any = true;
    }
    read_any.then_some(waited_ns as f64 * 1e-9)
}

/// A run's phases as this process saw them.
#[derive(Clone, Copy, Debug, Default)]
struct Phases {
    /// When the run started, for its whole wall time (`run_wall_s`).
    began: Option<Instant>,
    started: Option<Usage>,
    solve_started: Option<Usage>,
    setup: Option<Usage>,
    solve: Option<Usage>,
}

static PHASES: Mutex<Phases> = Mutex::new(Phases {
    began: None,
    started: None,
    solve_started: None,
    setup: None,
    solve: None,
});

fn phases() -> std::sync::MutexGuard<'static, Phases> {
    PHASES.lock().unwrap_or_else(|e| e.into_inner())
}

/// A run starts now (nlsolve's first step, and each case of `serve`): its set-up is counted from
/// here.
pub fn run_starts() {
    *phases() = Phases {
        began: Some(Instant::now()),
        started: Some(Usage::now()),
        ..Phases::default()
    };
}

/// Seconds since the run started (`run_starts`): its set-up, its solve and what it measured
/// after the solve (a step's amplification, errors), up to its record.
pub fn run_wall_s() -> Option<f64> {
    Some(phases().began?.elapsed().as_secs_f64())
}

/// A solve being timed: its wall time, and its usage once it ends.
pub struct Solving {
    started: Instant,
}

impl Solving {
    /// The set-up ends and the solve starts now.
    pub fn starts() -> Solving {
        let now = Usage::now();
        let mut phases = phases();
        if phases.solve_started.is_none() {
            phases.setup = phases.started.map(|started| now.since(started));
            phases.solve_started = Some(now);
        }
        Solving {
            started: Instant::now(),
        }
    }

    /// The solve ends now: its wall seconds.
    pub fn ends(self) -> f64 {
        let wall = self.started.elapsed().as_secs_f64();
        let now = Usage::now();
        let mut phases = phases();
        if let (Some(started), None) = (phases.solve_started, phases.solve) {
            phases.solve = Some(now.since(started));
        }
        wall
    }
}

/// The set-up's usage and the solve's, as far as they were seen (a run with no solve of its own
/// has neither).
pub fn taken() -> (Option<Usage>, Option<Usage>) {
    let phases = phases();
    (phases.setup, phases.solve)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A busy thread's CPU time grows with its work, and what it spent between two readings is
    /// never negative. (The test harness runs other tests in this process at the same time, so
    /// the wall time is checked against a process of its own: `tests/timing.rs`.)
    #[test]
    fn cpu_time_grows_with_work() {
        let before = Usage::now();
        let started = Instant::now();
        let mut x = 0u64;
        while started.elapsed().as_secs_f64() < 0.05 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let spent = Usage::now().since(before);
        assert!(spent.cpu_s > 0.0, "{spent:?}");
        assert!(spent.wait_s.is_none_or(|w| w >= 0.0), "{spent:?}");
        assert!(before.wait_s.is_some(), "Linux keeps schedstat");
    }
}
