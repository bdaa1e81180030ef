//! What a run asks of the machine it starts on, checked before it allocates: threads against
//! the cores, memory against what the machine has available.
//!
//! `nlsolve check` does not apply these (a study is planned on one machine and may run on
//! another); `nlsolve run` does, on the machine that would run it. The memory estimate is a lower
//! bound: the fields every method of the case keeps (u, its update, the source, stages and solver
//! vectors), the operator's padded copy and the FFT's buffers, per rank. A case above it cannot
//! fit; a case below it may still be large, and the record's `peak_memory_bytes` says what it took.

use crate::case::{readable, Backend, CaseError, Integrator, Method, ValidCase};

/// Most threads per core `nlsolve run` starts: beyond a few per core a timing measures the
/// scheduler, and thousands of spinning threads stall the machine.
pub const OVERSUBSCRIPTION: usize = 4;

const GIB: f64 = (1u64 << 30) as f64;

/// Refuses a case this machine cannot run: too many threads for its cores, or more memory than
/// it has available.
pub fn fit_machine(case: &ValidCase) -> Result<(), CaseError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let most = OVERSUBSCRIPTION * cores;
    if case.threads > most {
        return Err(CaseError::new(
            "threads",
            format!(
                "{} threads on a machine with {cores} cores; at most {OVERSUBSCRIPTION} per core ({most}) run, and more than {cores} are marked oversubscribed",
                case.threads
            ),
        ));
    }
    let Some(available) = available_memory() else {
        return Ok(());
    };
    // The ranks Open MPI started on this node share its memory.
    let local_ranks = std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(1.0);
    let needed = bytes_at_least(case) / case.ranks as f64 * local_ranks;
    if needed > available {
        return Err(CaseError::new(
            "n",
            format!(
                "the run needs at least {:.1} GiB ({} nodes, {} fields of them{}), more than the {:.1} GiB this machine has available; use a smaller n{}",
                needed / GIB,
                readable((case.n as f64).powi(case.dim as i32)),
                fields_kept(case),
                if case.ranks > 1 { ", shared by the ranks" } else { "" },
                available / GIB,
                if case.method.is_local() || case.method == Method::Pse { "" } else { " or more ranks on more machines" },
            ),
        ));
    }
    Ok(())
}

/// Fields of n^d values the case's method keeps at least.
fn fields_kept(case: &ValidCase) -> usize {
    match case.method {
        Method::Nonlocal => match case.integrator {
            Integrator::ForwardEuler => 3,
            Integrator::Heun => 5,
            Integrator::Rk4 => 7,
            Integrator::BackwardEuler | Integrator::CrankNicolson => 9,
        },
        Method::FdExplicit | Method::Adi => 2,
        // Positions, strength and rate of each particle.
        Method::Pse => case.dim + 2,
        Method::SteadyCg => 5,
        Method::Feti => 6,
        // u on the bar and L_h u.
        Method::PatchTest => 2,
        // The nonlocal stiffness matrix's band, 2ε/h + 3 values per node, and its factor.
        Method::Coupled1d => 2 * (2 * reach(case) as usize + 3),
    }
}

/// The horizon in cells, ⌈ε/h⌉.
fn reach(case: &ValidCase) -> f64 {
    case.m.map_or_else(
        || (case.eps.unwrap_or(0.0) * case.n as f64).ceil(),
        |m| m as f64,
    )
}

/// A lower bound of the bytes the run allocates over all ranks.
fn bytes_at_least(case: &ValidCase) -> f64 {
    let nodes = (case.n as f64).powi(case.dim as i32);
    let mut bytes = fields_kept(case) as f64 * nodes * 8.0;
    if case.method == Method::Nonlocal {
        // The operator's copy of u with its collar (the stencil's padded window; the FFT's real
        // input and its half spectrum of complex values).
        let padded = (case.n as f64 + 2.0 * reach(case)).powi(case.dim as i32);
        bytes += match case.backend {
            Backend::Fft => padded * 8.0 * 2.0,
            _ => padded * 8.0,
        };
    }
    bytes
}

/// MemAvailable of /proc/meminfo, lowered to the cgroup's limit when one is set.
fn available_memory() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    let mut available = kib * 1024.0;
    if let Ok(limit) = std::fs::read_to_string("/sys/fs/cgroup/memory.max") {
        if let Ok(limit) = limit.trim().parse::<f64>() {
            available = available.min(limit);
        }
    }
    Some(available)
}
