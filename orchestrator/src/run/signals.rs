//! The signals that stop `nlstudy run`: Ctrl-C (SIGINT), a scheduler's warning before the time
//! limit, `scancel` or preemption (SIGTERM), and a closed terminal or session (SIGHUP). Each only
//! sets a flag: the pool sees it between polls, starts no more cases, ends the running solvers
//! and stores nothing for them, so every record on disk is whole.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// The signals caught.
pub const CAUGHT: [i32; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

/// The stopping signal this process received last, if any.
#[derive(Clone, Default)]
pub struct Stop(Arc<AtomicUsize>);

impl Stop {
    /// A flag set by each of the `CAUGHT` signals to the signal's number.
    pub fn on_signals() -> Result<Stop, String> {
        let stop = Stop::default();
        for signal in CAUGHT {
            signal_hook::flag::register_usize(signal, Arc::clone(&stop.0), signal as usize)
                .map_err(|e| format!("cannot catch signal {signal}: {e}"))?;
        }
        Ok(stop)
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
