//! The record of a run of this build (its data is `schema::record`, the contract with the
//! orchestrator): the constructors that know this process — its build, host, load and memory.

use crate::case::Case;
use crate::discretization::stencil::Stencil;

pub use schema::record::*;

/// An `ok` record of this run with nothing measured yet: each method fills in what it measured.
pub fn fresh(case: &Case, resolved: Resolved, distribution: Distribution) -> Record {
    let provenance = provenance_of_this_run(case.threads, distribution.ranks);
    Record {
        peak_memory_bytes: peak_memory_bytes(),
        ..Record::new(case, resolved, distribution, provenance)
    }
}

/// The record of a coupled solve (either coupling): its timings (set-up, solve) and its
/// errors, e(u_n) standing as the record's L² error.
pub fn coupled(
    case: &Case,
    resolved: Resolved,
    (setup_s, solve_s): (f64, f64),
    coupling: Coupling,
) -> Record {
    Record {
        setup_s,
        solve_s,
        step_s: solve_s,
        error_l2_norm: Some(coupling.error_nonlocal),
        error_l2: Some(coupling.error_nonlocal.powi(2)),
        coupling: Some(coupling),
        ..fresh(case, resolved, Distribution::serial(case))
    }
}

/// VmHWM of /proc/self/status: the most resident memory this process has held.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|line| line.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// What the weights `stencil` resolved to; no time step, collar, patch error or backend.
pub fn resolved_of(stencil: &Stencil) -> Resolved {
    Resolved {
        h: stencil.grid.h,
        eps: Some(stencil.horizon.eps),
        m: Some(stencil.horizon.m),
        c: Some(stencil.c),
        nodes: stencil.grid.nodes(),
        bonds: stencil.bonds(),
        quadrature: Some(stencil.quadrature),
        ..Resolved::default()
    }
}

/// Now, with `own` of the runnable tasks being this run's; `None` where /proc does not tell.
pub fn load_now(own: usize) -> Option<Load> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    let mut fields = text.split_whitespace();
    let average_1min = fields.next()?.parse().ok()?;
    let runnable: usize = fields.nth(2)?.split('/').next()?.parse().ok()?;
    Some(Load {
        average_1min,
        other_runnable: runnable.saturating_sub(own),
    })
}

/// The load when the run started, taken by `note_start` before any work.
static START: std::sync::Mutex<Option<Load>> = std::sync::Mutex::new(None);

/// Takes the load at the start of a run (nlsolve calls it first thing, and `serve` before each
/// case; only this thread runs then).
pub fn note_start() {
    *START.lock().unwrap_or_else(|e| e.into_inner()) = load_now(1);
    super::usage::run_starts();
}

/// Starts the count of the most resident memory afresh (Linux's `clear_refs`, value 5), so
/// that a worker serving case after case records each case's own peak rather than the
/// largest so far; where the kernel refuses, the peak stays the process's.
pub fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// This build's fingerprint (see build/fingerprint.rs).
pub const FINGERPRINT: &str = env!("NLSOLVE_FINGERPRINT");

/// The provenance of a run of this build on this host, with the load at its start and now.
pub fn provenance_of_this_run(threads: usize, ranks: usize) -> Provenance {
    Provenance {
        solver_version: env!("CARGO_PKG_VERSION").to_string(),
        fingerprint: FINGERPRINT.to_string(),
        git_revision: option_env!("NLSOLVE_GIT_REVISION").map(str::to_string),
        host: this_machine().host.clone(),
        cpu: this_machine().cpu.clone(),
        threads,
        ranks,
        timestamp: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        instruction_set: crate::operator::InstructionSet::detected()
            .name()
            .to_string(),
        dirty_tree: option_env!("NLSOLVE_GIT_REVISION").is_some_and(|r| r.ends_with("-dirty")),
        cores_online: crate::threads::cores(),
        load_start: None,
        load_end: None,
        noisy: false,
    }
    .with_load(
        *START.lock().unwrap_or_else(|e| e.into_inner()),
        load_now(threads * ranks),
    )
}

/// What a process reads of its machine once: its host name and CPU model (/proc/cpuinfo is
/// long, and a worker writes a record per case).
struct ThisMachine {
    host: String,
    cpu: String,
}

fn this_machine() -> &'static ThisMachine {
    static MACHINE: std::sync::OnceLock<ThisMachine> = std::sync::OnceLock::new();
    MACHINE.get_or_init(|| ThisMachine {
        host: read_trimmed("/proc/sys/kernel/hostname").unwrap_or_else(|| "unknown".into()),
        cpu: cpu_model().unwrap_or_else(|| "unknown".into()),
    })
}

/// This machine's host name, as every record of this process names it.
pub fn host() -> &'static str {
    &this_machine().host
}

fn read_trimmed(path: &str) -> Option<String> {
    Some(std::fs::read_to_string(path).ok()?.trim().to_string())
}

fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("model name"))?;
    Some(line.split_once(':')?.1.trim().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_is_noisy_when_others_wanted_the_cores_it_left_free() {
        // 4 cores, a 2-thread run: 2 free.
        let mut provenance = provenance_of_this_run(2, 1);
        provenance.cores_online = 4;
        let load = |others: usize| {
            Some(Load {
                average_1min: 1.0,
                other_runnable: others,
            })
        };
        assert!(!provenance.clone().with_load(load(2), load(0)).noisy);
        assert!(provenance.clone().with_load(load(0), load(3)).noisy);
        assert!(provenance.clone().with_load(load(3), None).noisy);
        assert!(
            !provenance.with_load(None, None).noisy,
            "unmeasured is not noisy"
        );
        let now = load_now(0).expect("/proc/loadavg on Linux");
        assert!(
            now.average_1min >= 0.0 && now.other_runnable >= 1,
            "this test runs: {now:?}"
        );
    }

    /// A solve on no core for most of its wall time (stopped by SIGSTOP, say) is noisy, with
    /// one thread or several, on one rank or several; one that computed its wall time is not.
    #[test]
    fn a_run_on_no_core_for_half_its_solve_is_noisy() {
        let judged = |threads: usize, ranks: usize, wall: f64, cpu: f64, wait: Option<f64>| {
            let mut provenance = provenance_of_this_run(threads, ranks);
            provenance.noisy = false;
            provenance.with_time_off_cpu(wall, cpu, wait).noisy
        };
        assert!(judged(1, 1, 1.0, 0.1, Some(0.0)), "stopped for 9/10 of it");
        assert!(judged(4, 1, 1.0, 0.3, None), "four threads, stopped");
        assert!(
            judged(1, 2, 1.0, 0.9, Some(0.0)),
            "two ranks computed one rank's time"
        );
        assert!(!judged(1, 1, 1.0, 0.97, Some(0.0)));
        assert!(
            !judged(1, 1, 1.0, 0.4, Some(0.5)),
            "waited for a core: with_wait's to judge"
        );
        assert!(!judged(4, 1, 1.0, 3.8, None));
        assert!(!judged(1, 1, 0.01, 0.0, Some(0.0)), "too short to judge");
    }

    fn record() -> Record {
        let case =
            Case::parse(serde_json::json!({"method": "steady_cg", "dim": 2, "n": 8, "m": 2}))
                .unwrap();
        fresh(&case, Resolved::default(), Distribution::serial(&case))
    }

    #[test]
    fn an_ok_record_holding_a_non_finite_result_is_diverged() {
        let mut finite = record();
        finite.error_max = Some(1e-3);
        finite.diverge_if_not_finite();
        assert_eq!(finite.status, Status::Ok);
        for value in [f64::NAN, f64::INFINITY] {
            let mut bad = record();
            bad.error_max = Some(0.0);
            bad.steady.relative_residual = Some(value);
            bad.diverge_if_not_finite();
            assert_eq!(bad.status, Status::Diverged);
            assert!(bad.message.contains("relative_residual"), "{}", bad.message);
        }
        // A record already diverged keeps its own message.
        let mut diverged = record();
        diverged.status = Status::Diverged;
        diverged.message = "stopped".into();
        diverged.mass = Some(f64::NAN);
        diverged.diverge_if_not_finite();
        assert_eq!(diverged.message, "stopped");
    }
}
