//! The signals that stop `nlstudy run`: Ctrl-C (SIGINT), a scheduler's warning before the time
//! limit, `scancel` or preemption (SIGTERM), and a closed terminal or session (SIGHUP). While
//! the pool runs cases, each only sets a flag: the pool sees it between polls, starts no more
//! cases, asks the running solvers to write their checkpoints and stores nothing for them, so
//! every record on disk is whole. Anywhere else (the plan, an adaptive study's rounds, the
//! tables, figures and report, which a later run makes again) the signal ends the process at
//! once with the shell's status for it: every file there is written whole or not at all.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// The signals caught.
pub const CAUGHT: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// Whether a stopping signal ends the process at once (outside the pool).
static AT_ONCE: AtomicBool = AtomicBool::new(true);

/// The stopping signal this process received last, if any.
#[derive(Clone, Default)]
pub struct Stop(Arc<AtomicUsize>);

impl Stop {
    /// A flag set by each of the `CAUGHT` signals to the signal's number; outside `asking`,
    /// the signal then ends the process (exit 128 + its number, after one line on stderr).
    pub fn on_signals() -> Result<Stop, String> {
        let stop = Stop::default();
        for signal in CAUGHT {
            let flag = Arc::clone(&stop.0);
            let action = move || {
                flag.store(signal as usize, Ordering::SeqCst);
                if AT_ONCE.load(Ordering::SeqCst) {
                    let said = stopped_line(signal);
                    // SAFETY: write(2) and _exit(2) are async-signal-safe; `said` is static.
                    unsafe {
                        libc::write(2, said.as_ptr().cast(), said.len());
                        libc::_exit(128 + signal);
                    }
                }
            };
            // SAFETY: the action only stores an atomic, writes a static line and exits, all
            // async-signal-safe.
            unsafe { signal_hook::low_level::register(signal, action) }
                .map_err(|e| format!("cannot catch signal {signal}: {e}"))?;
        }
        Ok(stop)
    }

    /// Runs `work` (the pool) with stopping signals only asking to stop, which `work` answers
    /// by ending its cases cleanly; after it, a signal ends the process at once again.
    pub fn asking<T>(&self, work: impl FnOnce() -> T) -> T {
        AT_ONCE.store(false, Ordering::SeqCst);
        let done = work();
        AT_ONCE.store(true, Ordering::SeqCst);
        done
    }

    /// Whether a stop was asked for.
    pub fn requested(&self) -> bool {
        self.signal().is_some()
    }

    /// The signal that asked for the stop.
    pub fn signal(&self) -> Option<i32> {
        match self.0.load(Ordering::SeqCst) {
            0 => None,
            n => Some(n as i32),
        }
    }

    /// The shell's status for a process the signal ended: 128 + its number (130 for Ctrl-C, 143
    /// for SIGTERM, 129 for SIGHUP).
    pub fn exit_code(&self) -> Option<u8> {
        self.signal().map(|s| 128 + s as u8)
    }
}

/// The line a signal that ends the process at once leaves on stderr.
fn stopped_line(signal: i32) -> &'static str {
    match signal {
        libc::SIGINT => {
            "nlstudy: stopped by SIGINT (Ctrl-C); what finished is stored, run again to resume\n"
        }
        libc::SIGTERM => {
            "nlstudy: stopped by SIGTERM; what finished is stored, run again to resume\n"
        }
        _ => "nlstudy: stopped by SIGHUP; what finished is stored, run again to resume\n",
    }
}

/// A test's hook: with `NLSTUDY_PAUSE_IN` set to `phase`, `nlstudy` says `nlstudy: paused in
/// <phase>` on stderr and waits there a minute, so that a test can send a signal in that phase.
pub fn phase(phase: &str) {
    if std::env::var("NLSTUDY_PAUSE_IN").is_ok_and(|p| p == phase) {
        log::info!("paused in {phase}");
        std::thread::sleep(std::time::Duration::from_secs(60));
    }
}

/// The signal's name, for the sentence `nlstudy` ends with.
pub fn name(signal: i32) -> &'static str {
    match signal {
        libc::SIGINT => "SIGINT (Ctrl-C)",
        libc::SIGTERM => "SIGTERM",
        libc::SIGHUP => "SIGHUP",
        _ => "a signal",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_caught_signal_sets_the_stop_to_its_own_exit_status() {
        let stop = Stop::on_signals().unwrap();
        // In the pool, where a signal only asks (outside it, it would end the test's process).
        AT_ONCE.store(false, Ordering::SeqCst);
        assert!(!stop.requested());
        for (signal, status) in [
            (libc::SIGHUP, 129),
            (libc::SIGTERM, 143),
            (libc::SIGINT, 130),
        ] {
            // SAFETY: raise sends the signal to this thread; the handler only stores a number.
            assert_eq!(unsafe { libc::raise(signal) }, 0);
            assert_eq!(stop.signal(), Some(signal));
            assert_eq!(stop.exit_code(), Some(status), "{}", name(signal));
        }
    }
}
