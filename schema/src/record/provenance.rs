//! Where and by what a record was made: the build, the machine, and its load while the run was
//! timed.

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    pub solver_version: String,
    /// The build's fingerprint (`nlsolve fingerprint`): the hash of the solver's and schema's
    /// sources, Cargo.lock, the compiler, target, flags, profile and features (solver/build/
    /// fingerprint.rs says what is in it); absent from records made before it was kept.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub fingerprint: String,
    pub git_revision: Option<String>,
    pub host: String,
    pub cpu: String,
    pub threads: usize,
    pub ranks: usize,
    pub timestamp: String,
    /// The instruction set the stencil kernel ran (`portable`, `avx2`, `avx512f`), detected at
    /// start-up; absent from records made before the kernel dispatched.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub instruction_set: String,
    /// Whether the working tree had uncommitted changes when the solver was built (from
    /// `git_revision`'s `-dirty`); the fingerprint hashes the sources themselves either way.
    #[serde(default)]
    pub dirty_tree: bool,
    /// Cores this process may run on (affinity and cgroup limits included).
    #[serde(default)]
    pub cores_online: usize,
    /// The machine's load when the run started and ended: /proc/loadavg's one-minute average,
    /// and how many other tasks were runnable at that instant (the run's own left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_start: Option<Load>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_end: Option<Load>,
    /// Timed while other tasks wanted more cores than the run left free (cores online minus
    /// threads × ranks), at its start or its end, or while its solve waited for cores other
    /// tasks held more than `NOISY_WAIT_SHARE` of its time: its timings measure contention too.
    #[serde(default)]
    pub noisy: bool,
}

/// The machine's load at one instant (see `Provenance::load_start`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Load {
    pub average_1min: f64,
    pub other_runnable: usize,
}

/// The share of its time a solve may wait, ready to run, for cores other tasks hold before its
/// timings are noisy: its wait over its CPU and wait together.
pub const NOISY_WAIT_SHARE: f64 = 0.1;

/// The share of its wall time a solve may spend on no core before its timings are noisy.
pub const OFF_CPU_SHARE: f64 = 0.5;
/// The shortest solve judged by its time off the cores.
pub const OFF_CPU_SHORTEST_S: f64 = 0.02;

impl Provenance {
    /// Noisy too when a solve that computed `cpu_s` waited `wait_s` for cores other tasks held
    /// beyond `NOISY_WAIT_SHARE` of its time: it lost that share of its cores, whatever the
    /// load samples at its ends said.
    pub fn with_wait(mut self, cpu_s: f64, wait_s: f64) -> Self {
        let runnable = cpu_s + wait_s;
        self.noisy |= runnable > 0.0 && wait_s / runnable > NOISY_WAIT_SHARE;
        self
    }

    /// Noisy too when a solve of `wall_s` over `ranks` processes was on no core for more than
    /// `OFF_CPU_SHARE` of it: neither computing (`cpu_s`, every thread's) nor waiting for a core
    /// (`wait_s`), since at least each rank's main thread works the whole solve. A stopped
    /// process (SIGSTOP, a suspended job) or one swapped out is so; a run of any thread count is
    /// judged. Solves under `OFF_CPU_SHORTEST_S` are left alone (a clock's tick).
    pub fn with_time_off_cpu(mut self, wall_s: f64, cpu_s: f64, wait_s: Option<f64>) -> Self {
        let on = cpu_s + wait_s.filter(|w| w.is_finite()).unwrap_or(0.0);
        let budget = wall_s * self.ranks.max(1) as f64;
        self.noisy |=
            wall_s >= OFF_CPU_SHORTEST_S && on.is_finite() && on < (1.0 - OFF_CPU_SHARE) * budget;
        self
    }

    /// The load at the run's start and end, and whether it made the run noisy.
    pub fn with_load(mut self, start: Option<Load>, end: Option<Load>) -> Self {
        let free = self.cores_online.saturating_sub(self.threads * self.ranks);
        self.noisy = [start, end]
            .iter()
            .flatten()
            .any(|load| load.other_runnable > free);
        self.load_start = start;
        self.load_end = end;
        self
    }
}
