//! What a run asks of the machine it starts on, checked before it allocates: threads against
//! the cores, memory against what the machine, and the cgroups this process runs in, have
//! available.
//!
//! `nlsolve check` does not apply these (a study is planned on one machine and may run on
//! another); `nlsolve run` does, on the machine that would run it. The memory estimate counts
//! what each method holds at its peak, per rank: the fields of n^d values every method keeps
//! (u, its update, the source, stages and solver vectors), and the arrays that grow faster than
//! the nodes: the operator's padded copy, FFT buffers and stability search (`nonlocal`), the
//! particles and images with their cell lists (`pse::memory_bytes`), the subdomain matrices and
//! Cholesky factors (`feti::memory_bytes`), the variable horizon's bonds and rows
//! (`patch_test::operator_bytes`), the coupled problem's band, control responses and dense least
//! squares (`coupled::Sizes::peak_bytes`). Each says which arrays it counts; they aim within a
//! factor 2 of the record's measured `peak_memory_bytes`.

use super::{coupled, patch_test, pse, steady::feti};
use crate::case::{readable, Backend, CaseError, Integrator, Method, ValidCase};
use std::path::Path;

/// Most threads per core `nlsolve run` starts: beyond a few per core a timing measures the
/// scheduler, and thousands of spinning threads stall the machine.
pub const OVERSUBSCRIPTION: usize = 4;

const GIB: f64 = (1u64 << 30) as f64;

/// Where the cgroup file system is mounted: v2's unified hierarchy, v1's controllers below it.
const CGROUP_MOUNT: &str = "/sys/fs/cgroup";

/// A cgroup v1 limit at or above this is "no limit": v1 writes its unlimited value as the
/// largest page-aligned i64, 0x7FFFFFFFFFFFF000.
const CGROUP_V1_UNLIMITED: u64 = 1 << 62;

/// What this machine offers a case: its cores and the memory available (`None` where /proc does
/// not tell), read once by whoever checks many cases (`nlsolve check`).
#[derive(Clone, Copy)]
pub struct Machine {
    pub cores: usize,
    pub available: Option<f64>,
}

impl Machine {
    pub fn now() -> Machine {
        Machine {
            cores: crate::threads::cores(),
            available: available_memory(),
        }
    }

    /// The most threads a run may start here.
    pub fn most_threads(&self) -> usize {
        OVERSUBSCRIPTION * self.cores
    }
}

/// Refuses a case this machine cannot run: too many threads for its cores, or more memory than
/// it has available.
pub fn fit_machine(case: &ValidCase) -> Result<(), CaseError> {
    fit(case, Machine::now()).1
}

/// `fit_machine` against a machine read before, with the bytes of available memory the case
/// needs, of one estimate. With its threads that is all `fit` asks of a machine: a case fits
/// one that offers both (`Machine::most_threads`, `Machine::available`), which lets a plan that
/// keeps the solver's verdicts (`nlsolve check`'s `needs`) tell that a case still fits
/// without asking again.
pub fn fit(case: &ValidCase, machine: Machine) -> (f64, Result<(), CaseError>) {
    let (needed, estimate) = needed_on_this_node(case);
    (needed, refusal(case, machine, needed, &estimate))
}

/// Why `machine` cannot run the case, which `needed` bytes of it by `estimate`.
fn refusal(
    case: &ValidCase,
    machine: Machine,
    needed: f64,
    estimate: &Estimate,
) -> Result<(), CaseError> {
    let cores = machine.cores;
    let most = machine.most_threads();
    if case.threads > most {
        return Err(CaseError::new(
            "threads",
            format!(
                "{} threads on a machine with {cores} cores; at most {OVERSUBSCRIPTION} per core ({most}) run, and more than {cores} are marked oversubscribed",
                case.threads
            ),
        ));
    }
    let Some(available) = machine.available else {
        return Ok(());
    };
    if needed > available {
        return Err(CaseError::new(
            "n",
            format!(
                "the run needs at least {:.1} GiB ({}{}), more than the {:.1} GiB this machine has available; use a smaller n{}",
                needed / GIB,
                estimate.counted,
                if case.ranks > 1 { ", shared by the ranks" } else { "" },
                available / GIB,
                if case.method.is_local() || case.method == Method::Pse { "" } else { " or more ranks on more machines" },
            ),
        ));
    }
    Ok(())
}

/// The bytes the run needs of the memory of the node it starts on (its ranks there share it),
/// and the estimate they come from.
fn needed_on_this_node(case: &ValidCase) -> (f64, Estimate) {
    // The ranks Open MPI started on this node share its memory.
    let local_ranks = std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(1.0);
    let estimate = memory_estimate(case);
    (estimate.bytes / case.ranks as f64 * local_ranks, estimate)
}

/// What a run holds at its peak over all ranks: bytes, and which arrays they are.
struct Estimate {
    bytes: f64,
    counted: String,
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
        // Positions, strength and rate of each particle (`pse::memory_bytes` counts them all).
        Method::Pse => case.dim + 2,
        Method::SteadyCg => 5,
        Method::Feti => 6,
        // u on the bar and L_h u.
        Method::PatchTest => 2,
        // The nonlocal mesh's nodes, loads and states (`coupled::Sizes` counts them all).
        Method::Coupled1d => 0,
    }
}

/// The horizon in cells, ⌈ε/h⌉.
fn reach(case: &ValidCase) -> f64 {
    case.m.map_or_else(
        || (case.eps.unwrap_or(0.0) * case.n as f64).ceil(),
        |m| m as f64,
    )
}

/// The bytes one rank of the run holds at its peak, by the estimate.
pub fn estimated_bytes_per_rank(case: &ValidCase) -> u64 {
    (memory_estimate(case).bytes / case.ranks as f64) as u64
}

/// What one nlsolve process holds before any array (its code, libraries, thread stacks and, over
/// ranks, Open MPI's buffers): the peak of a 1D run on 8 nodes, 6.9 MiB, and of a 2D run on
/// 16² nodes over 2 ranks, 14.9 MiB per rank (measured here, Open MPI 4.1).
const PROCESS_BASE_BYTES: f64 = 7.0 * 1024.0 * 1024.0;
const RANK_BASE_BYTES: f64 = 15.0 * 1024.0 * 1024.0;

/// The bytes the run holds at its peak, over all ranks, and what they are.
fn memory_estimate(case: &ValidCase) -> Estimate {
    let nodes = (case.n as f64).powi(case.dim as i32);
    let fields = fields_kept(case);
    let base = match case.ranks {
        1 => PROCESS_BASE_BYTES,
        _ => RANK_BASE_BYTES,
    };
    let mut bytes = fields as f64 * nodes * 8.0 + base * case.ranks as f64;
    let mut counted = match fields {
        0 => format!("{} nodes", readable(nodes)),
        _ => format!("{} nodes, {fields} fields of them", readable(nodes)),
    };
    counted.push_str(&format!(", {} MiB per process", base / 1048576.0));
    let mut add = |more: f64, what: &str| {
        bytes += more;
        counted.push_str(", ");
        counted.push_str(what);
    };
    match case.method {
        Method::Nonlocal if case.horizon_profile.is_some() => add(
            patch_test::operator_bytes(case),
            "the variable horizon's bonds and rows",
        ),
        Method::Nonlocal => {
            let (reach, dim) = (reach(case), case.dim as i32);
            // The operator's copy of u with its collar (the stencil's padded window; the FFT's
            // real input and its half spectrum of complex values).
            let padded = (case.n as f64 + 2.0 * reach).powi(dim);
            let window = match case.backend {
                Backend::Fft => padded * 8.0 * 2.0,
                _ => padded * 8.0,
            };
            // The stable step's search (`stability::Symbol::maximum`): (4R + 9)^d samples of 24
            // bytes and a table of (4R + 9)(R + 1) cosines; the weights and bond volumes.
            let samples = 4.0 * reach + 9.0;
            let search = 24.0 * samples.powi(dim) + 8.0 * samples * (reach + 1.0);
            let weights = 16.0 * (2.0 * reach + 1.0).powi(dim);
            add(
                window + search + weights,
                "the operator's padded window and the stability search",
            );
        }
        Method::Pse => add(
            pse::memory_bytes(case),
            "the particles, their images and cell lists",
        ),
        Method::Feti => add(
            feti::memory_bytes(case),
            "the subdomain matrices with their Cholesky factors",
        ),
        Method::PatchTest => add(
            patch_test::operator_bytes(case),
            "the variable horizon's bonds and rows",
        ),
        Method::Coupled1d => add(
            coupled::Sizes::of_case(case).peak_bytes(),
            "the stiffness band, control responses and dense least squares",
        ),
        Method::FdExplicit | Method::Adi | Method::SteadyCg => {}
    }
    Estimate { bytes, counted }
}

/// MemAvailable of /proc/meminfo, lowered to the tightest memory limit of the cgroups this
/// process runs in.
fn available_memory() -> Option<f64> {
    let mut available = meminfo_available(&std::fs::read_to_string("/proc/meminfo").ok()?)?;
    if let Ok(membership) = std::fs::read_to_string("/proc/self/cgroup") {
        let read =
            |relative: &str| std::fs::read_to_string(Path::new(CGROUP_MOUNT).join(relative)).ok();
        if let Some(limit) = cgroup_memory_limit(&membership, read) {
            available = available.min(limit);
        }
    }
    Some(available)
}

/// Bytes available from the text of /proc/meminfo: MemAvailable, or MemTotal on kernels
/// before 3.14 that lack it.
fn meminfo_available(meminfo: &str) -> Option<f64> {
    let kib = |key: &str| -> Option<f64> {
        let line = meminfo.lines().find(|l| l.starts_with(key))?;
        line.split_whitespace().nth(1)?.parse().ok()
    };
    Some(kib("MemAvailable:").or_else(|| kib("MemTotal:"))? * 1024.0)
}

/// The tightest memory limit, in bytes, of the cgroups a process is in, from its
/// /proc/self/cgroup (`membership`) and `read`, which returns the text of a file given its path
/// relative to the cgroup mount, or None. cgroup v2 (the line `0::/path`): `memory.max` of the
/// process's cgroup and of every ancestor up to the mount's root, since a parent's limit binds
/// its children (a Slurm job's limit sits on the job, its steps and tasks below it). cgroup v1
/// (a line `N:…memory…:/path`): `memory/<path>/memory.limit_in_bytes`, likewise up to the root.
/// `max` and v1's near-2⁶³ values mean no limit; None when no level sets one.
fn cgroup_memory_limit(membership: &str, read: impl Fn(&str) -> Option<String>) -> Option<f64> {
    let mut tightest: Option<f64> = None;
    for line in membership.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let (hierarchy, file) = if controllers.is_empty() {
            ("", "memory.max")
        } else if controllers.split(',').any(|c| c == "memory") {
            ("memory", "memory.limit_in_bytes")
        } else {
            continue;
        };
        // The cgroup and its ancestors: /a/b, /a, then the root (the mount itself).
        let mut cgroup = path.trim().trim_end_matches('/');
        loop {
            let relative: Vec<&str> = [hierarchy, cgroup.trim_start_matches('/'), file]
                .into_iter()
                .filter(|part| !part.is_empty())
                .collect();
            if let Some(limit) = read(&relative.join("/")).and_then(|text| limit_bytes(&text)) {
                tightest = Some(tightest.map_or(limit, |t| t.min(limit)));
            }
            match cgroup.rfind('/') {
                Some(parent) => cgroup = &cgroup[..parent],
                None => break,
            }
        }
    }
    tightest
}

/// A cgroup memory limit's value in bytes; None for no limit (`max`, or v1's unlimited).
fn limit_bytes(text: &str) -> Option<f64> {
    let value: u64 = text.trim().parse().ok()?;
    (value < CGROUP_V1_UNLIMITED).then_some(value as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// `cgroup_memory_limit` over a file system given as (path relative to the mount, text).
    fn limit(membership: &str, files: &[(&str, &str)]) -> Option<f64> {
        let files: HashMap<&str, &str> = files.iter().copied().collect();
        cgroup_memory_limit(membership, |path| files.get(path).map(|t| t.to_string()))
    }

    #[test]
    fn cgroup_v2_reads_the_processs_own_memory_max() {
        let membership = "0::/system.slice/slurmstepd.scope/job_42/step_0\n";
        let files = [
            (
                "system.slice/slurmstepd.scope/job_42/step_0/memory.max",
                "max\n",
            ),
            (
                "system.slice/slurmstepd.scope/job_42/memory.max",
                "4294967296\n",
            ),
            ("system.slice/slurmstepd.scope/memory.max", "max\n"),
            ("system.slice/memory.max", "max\n"),
        ];
        assert_eq!(limit(membership, &files), Some(4294967296.0));
    }

    #[test]
    fn nested_cgroup_v2_limits_the_smallest_wins() {
        let membership = "0::/a/b/c\n";
        let files = [
            ("a/b/c/memory.max", "8000000000"),
            ("a/b/memory.max", "2000000000"),
            ("a/memory.max", "5000000000"),
            ("memory.max", "max"),
        ];
        assert_eq!(limit(membership, &files), Some(2e9));
        // The root of a cgroup namespace (a container): the mount's own memory.max.
        assert_eq!(
            limit("0::/\n", &[("memory.max", "1073741824")]),
            Some(1073741824.0)
        );
    }

    #[test]
    fn max_everywhere_is_no_limit() {
        let files = [("user.slice/memory.max", "max"), ("memory.max", "max")];
        assert_eq!(limit("0::/user.slice\n", &files), None);
        assert_eq!(limit("0::/user.slice\n", &[]), None);
        assert_eq!(limit("", &[]), None);
    }

    #[test]
    fn cgroup_v1_reads_the_memory_controllers_limit() {
        let membership = "12:pids:/slurm/uid_1000/job_7\n\
                          4:memory:/slurm/uid_1000/job_7/step_batch\n\
                          1:name=systemd:/user.slice\n";
        let files = [
            (
                "memory/slurm/uid_1000/job_7/step_batch/memory.limit_in_bytes",
                "9223372036854771712\n",
            ),
            (
                "memory/slurm/uid_1000/job_7/memory.limit_in_bytes",
                "3221225472\n",
            ),
            (
                "memory/slurm/memory.limit_in_bytes",
                "9223372036854771712\n",
            ),
            ("memory/memory.limit_in_bytes", "9223372036854771712\n"),
            // Another controller's or the v2 file: not read for a v1 memory line.
            ("memory.max", "1"),
        ];
        assert_eq!(limit(membership, &files), Some(3221225472.0));
        // v1's unlimited value alone is no limit; a controller listed with others counts.
        let unlimited = [("memory/memory.limit_in_bytes", "9223372036854771712")];
        assert_eq!(limit("3:memory:/\n", &unlimited), None);
        let combined = [("memory/x/memory.limit_in_bytes", "1000")];
        assert_eq!(limit("5:cpu,memory:/x\n", &combined), Some(1000.0));
    }

    #[test]
    fn a_hybrid_system_takes_the_tighter_of_v1_and_v2() {
        let membership = "4:memory:/job\n0::/job\n";
        let files = [
            ("memory/job/memory.limit_in_bytes", "6000"),
            ("job/memory.max", "5000"),
        ];
        assert_eq!(limit(membership, &files), Some(5000.0));
    }

    #[test]
    fn meminfo_gives_mem_available_or_else_mem_total() {
        let modern = "MemTotal:       16000000 kB\nMemFree:  100 kB\nMemAvailable:   8000000 kB\n";
        assert_eq!(meminfo_available(modern), Some(8000000.0 * 1024.0));
        assert_eq!(
            meminfo_available("MemTotal:  2000 kB\nMemFree:  100 kB\n"),
            Some(2000.0 * 1024.0)
        );
        assert_eq!(meminfo_available(""), None);
    }

    /// The estimate of the FETI case (n = 512, m = 4, p = 2: 1974 MiB measured) is
    /// within a factor 2, where the fields alone are 12 MiB; those of PSE with a wide kernel and
    /// of the coupled problem count what grows faster than the nodes.
    #[test]
    fn the_estimate_counts_what_grows_faster_than_the_nodes() {
        let estimate = |fields: serde_json::Value| {
            memory_estimate(&ValidCase::from_json(fields).unwrap()).bytes
        };
        let mib = (1u64 << 20) as f64;
        let feti = estimate(serde_json::json!({
            "method": "feti", "dim": 2, "n": 512, "m": 4, "kernel": "inverse_distance",
            "subdomains": 2,
        }));
        assert!(
            (987.0 * mib..3948.0 * mib).contains(&feti),
            "{} MiB",
            feti / mib
        );
        // ε = L/2: the images of a 6ε cutoff span (n + 2R)² ≈ 50 n² lattice points, where the
        // previous count was 4 fields of n² values.
        let pse = estimate(serde_json::json!({
            "method": "pse", "problem": "eigenmode", "dim": 2, "n": 256, "eps": 1.0,
            "t_end": 0.01, "cfl": 0.5,
        }));
        assert!(pse > 50.0 * 4.0 * 8.0 * 256.0 * 256.0, "{pse:e}");
        // ε = 1/2 at n = 2048: a band of 2053 per node, 3.1 M non-zeros in the free block,
        // each 72 bytes while it becomes a sparse matrix (the previous count, 2(2ε/h + 3) values
        // per node, was 64 MiB).
        let coupled = estimate(serde_json::json!({
            "method": "coupled_1d", "dim": 1, "n": 2048, "eps": 0.5, "local_domain": [0.75, 1.75],
        }));
        assert!(coupled > 200.0 * mib, "{} MiB", coupled / mib);
    }
}
