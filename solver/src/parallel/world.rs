//! MPI's ranks as the `Exchange` every distributed solver uses (built with the `mpi` feature):
//! partner swaps with computation overlapped, sums and maxima, the partition agreed by all
//! ranks, and how a run was spread over them.

use crate::case::{Case, CaseError, Partition};
use crate::discretization::grid::Window;
use crate::discretization::stencil::Stencil;
use crate::output::record::{Distribution, Traffic};
use crate::parallel::exchange::{offsets, Exchange, Ranks};
use crate::parallel::partition::{self, Ownership, PartitionSummary};
use crate::parallel::share::RankShare;
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition as Pieces, PartitionMut as PiecesMut};
use mpi::point_to_point::Source as _;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use rayon::ThreadPool;
use std::cell::Cell;
use std::time::Instant;

/// The ranks of an MPI communicator, called from the main thread only.
pub struct Mpi<'a> {
    pub world: &'a SimpleCommunicator,
    seconds: Cell<f64>,
    traffic: Cell<Traffic>,
}

impl<'a> Mpi<'a> {
    pub fn new(world: &'a SimpleCommunicator) -> Self {
        Mpi {
            world,
            seconds: Cell::new(0.0),
            traffic: Cell::new(Traffic::default()),
        }
    }

    /// Adds one call to the counts.
    fn count(&self, add: impl FnOnce(&mut Traffic)) {
        let mut traffic = self.traffic.get();
        add(&mut traffic);
        self.traffic.set(traffic);
    }

    fn reduce(&self, local: f64, operation: SystemOperation) -> f64 {
        self.count(|t| {
            t.reductions += 1;
            t.reduction_bytes += 8;
        });
        let mut global = 0.0;
        self.world.all_reduce_into(&local, &mut global, operation);
        global
    }

    fn timed<T>(&self, work: impl FnOnce() -> T) -> T {
        let started = Instant::now();
        let result = work();
        self.seconds
            .set(self.seconds.get() + started.elapsed().as_secs_f64());
        result
    }
}

impl Exchange for Mpi<'_> {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }
    fn ranks(&self) -> usize {
        self.world.size() as usize
    }
    fn all_sum(&self, values: &mut [f64]) {
        self.count(|t| {
            t.reductions += 1;
            t.reduction_bytes += 8 * values.len() as u64;
        });
        self.timed(|| {
            let local = values.to_vec();
            self.world
                .all_reduce_into(&local[..], values, SystemOperation::sum());
        })
    }
    fn sum(&self, local: f64) -> f64 {
        self.timed(|| self.reduce(local, SystemOperation::sum()))
    }
    fn max(&self, local: f64) -> f64 {
        self.timed(|| self.reduce(local, SystemOperation::max()))
    }
    fn swap_overlapped(
        &self,
        peers: &[usize],
        send: &[Vec<f64>],
        receive: &mut [Vec<f64>],
        overlap: &mut dyn FnMut(),
    ) {
        self.count(|t| {
            t.halo_exchanges += 1;
            t.halo_bytes += 8 * send.iter().map(|s| s.len() as u64).sum::<u64>();
        });
        let mut overlap_s = 0.0;
        self.timed(|| {
            mpi::request::scope(|scope| {
                let mut requests = Vec::with_capacity(2 * peers.len());
                for (&peer, buffer) in peers.iter().zip(receive.iter_mut()) {
                    let from = self.world.process_at_rank(peer as i32);
                    requests.push(from.immediate_receive_into(scope, &mut buffer[..]));
                }
                for (&peer, buffer) in peers.iter().zip(send) {
                    let to = self.world.process_at_rank(peer as i32);
                    requests.push(to.immediate_send(scope, &buffer[..]));
                }
                let overlap_started = Instant::now();
                overlap();
                overlap_s = overlap_started.elapsed().as_secs_f64();
                for request in requests {
                    request.wait();
                }
            })
        });
        self.seconds.set(self.seconds.get() - overlap_s);
    }
    fn all_to_all(
        &self,
        send: &[f64],
        send_counts: &[usize],
        receive: &mut [f64],
        receive_counts: &[usize],
    ) {
        let others: usize = send_counts.iter().sum::<usize>() - send_counts[self.rank()];
        self.count(|t| {
            t.all_to_alls += 1;
            t.all_to_all_bytes += 8 * others as u64;
        });
        let counts = |c: &[usize]| -> Vec<Count> { c.iter().map(|&k| k as Count).collect() };
        let (sc, rc) = (counts(send_counts), counts(receive_counts));
        let (sd, rd) = (
            counts(&offsets(send_counts)),
            counts(&offsets(receive_counts)),
        );
        self.timed(|| {
            let send = Pieces::new(send, &sc[..], &sd[..]);
            let mut receive = PiecesMut::new(receive, &rc[..], &rd[..]);
            self.world.all_to_all_varcount_into(&send, &mut receive);
        })
    }
    fn seconds(&self) -> f64 {
        self.seconds.get()
    }
    fn traffic(&self) -> Traffic {
        self.traffic.get()
    }
    fn count_earlier(&self, earlier: Traffic) {
        self.count(|t| {
            t.halo_exchanges += earlier.halo_exchanges;
            t.halo_bytes += earlier.halo_bytes;
            t.reductions += earlier.reductions;
            t.reduction_bytes += earlier.reduction_bytes;
            t.all_to_alls += earlier.all_to_alls;
            t.all_to_all_bytes += earlier.all_to_all_bytes;
        });
    }
    fn bookkeeping_max(&self, local: f64) -> f64 {
        let mut global = 0.0;
        self.world
            .all_reduce_into(&local, &mut global, SystemOperation::max());
        global
    }
}

/// The partition of the case, the same on every rank.
pub(crate) fn ownership(
    world: &SimpleCommunicator,
    case: &Case,
    stencil: &Stencil,
) -> Result<Ownership, CaseError> {
    let grid = stencil.grid;
    if case.partition == Partition::Block {
        return partition::ownership(case, stencil); // cheap and the same everywhere
    }
    // METIS on rank 0, one partition however METIS would behave on other hosts. Each rank then
    // gets the owners of its window only (its nodes' box grown by the reach: every node its share
    // looks up) and every rank's count, so that no rank but 0 holds the whole map.
    let root = world.process_at_rank(0);
    let computed = (world.rank() == 0).then(|| partition::ownership(case, stencil));
    let mut failed = i32::from(matches!(computed, Some(Err(_))));
    root.broadcast_into(&mut failed);
    if failed == 1 {
        return Err(match computed {
            Some(Err(e)) => e,
            _ => CaseError::new("partition", "the graph partition failed on rank 0"),
        });
    }
    let reach = stencil.reach();
    let header = |w: Window| [w.x0, w.y0, w.nx, w.ny].map(|v| v as u64);
    let (window, owners, mut counts) = match computed {
        Some(Ok(map)) => {
            let window_of = |rank| {
                map.window_of(rank, reach)
                    .expect("METIS leaves no rank empty")
            };
            for rank in 1..case.ranks {
                let to = world.process_at_rank(rank as i32);
                let window = window_of(rank);
                to.send(&header(window)[..]);
                to.send(&map.owners_in(window)[..]);
            }
            let counts: Vec<u64> = map.owned_counts().iter().map(|&c| c as u64).collect();
            let window = window_of(0);
            (window, map.owners_in(window), counts)
        }
        _ => {
            let (w, _) = root.receive_vec::<u64>();
            let window = Window {
                x0: w[0] as usize,
                y0: w[1] as usize,
                nx: w[2] as usize,
                ny: w[3] as usize,
            };
            (window, root.receive_vec::<u32>().0, vec![0; case.ranks])
        }
    };
    root.broadcast_into(&mut counts[..]);
    let counts = counts.iter().map(|&c| c as usize).collect();
    Ok(Ownership::of_window(
        grid, case.ranks, window, owners, counts,
    ))
}

/// How a run was spread over the ranks of `world`: the partition, the ghosts summed over ranks
/// and the communication seconds `comm_s` (this rank's) maximised over them.
pub(crate) fn distribution(
    mpi: &Mpi,
    case: &Case,
    partition: &PartitionSummary,
    share: &RankShare,
    comm_s: f64,
) -> Distribution {
    // Counted before the reductions below, which only report.
    let mine = mpi.traffic();
    let total = |bytes: u64| mpi.sum(bytes as f64) as u64;
    let traffic = Traffic {
        halo_bytes: total(mine.halo_bytes),
        reduction_bytes: total(mine.reduction_bytes),
        all_to_all_bytes: total(mine.all_to_all_bytes),
        ..mine
    };
    let ghosts = mpi.sum(share.ghosts() as f64) as usize;
    let hosts = all_gathered(mpi.world, &hostname());
    let cpus = all_gathered(mpi.world, &allowed_cpus());
    Distribution {
        ranks: partition.ranks,
        partition: case.partition,
        px: partition.blocks.map(|(px, _)| px),
        py: partition.blocks.map(|(_, py)| py),
        halo_nodes: ghosts,
        halo_bytes: ghosts * std::mem::size_of::<f64>(),
        imbalance: partition.imbalance,
        comm_s: mpi.max(comm_s),
        hosts: hosts.clone(),
        oversubscribed: oversubscribed(&hosts, &cpus, case.threads),
        cpus,
        solve_cpu_s_ranks: Vec::new(), // known once the run is over (`methods::finished`)
        traffic: Some(traffic),
    }
}

/// Whether the ranks ran more threads than they had CPUs: a rank's `threads` beyond its own
/// affinity, or a host's ranks' threads beyond the CPUs they may use together (ranks left
/// unbound share them all). `None` when an affinity does not read.
fn oversubscribed(hosts: &[String], cpus: &[String], threads: usize) -> Option<bool> {
    let sets: Option<Vec<std::collections::BTreeSet<usize>>> =
        cpus.iter().map(|list| cpu_list(list)).collect();
    let sets = sets?;
    let mut by_host: std::collections::BTreeMap<&str, (usize, std::collections::BTreeSet<usize>)> =
        std::collections::BTreeMap::new();
    for (host, set) in hosts.iter().zip(&sets) {
        let (ranks, union) = by_host.entry(host).or_default();
        *ranks += 1;
        union.extend(set);
    }
    let rank_over = sets.iter().any(|set| threads > set.len());
    let host_over = by_host
        .values()
        .any(|(ranks, union)| threads * ranks > union.len());
    Some(rank_over || host_over)
}

/// The CPUs of a list such as `0-3,8,10-11`; `None` when it does not read.
fn cpu_list(list: &str) -> Option<std::collections::BTreeSet<usize>> {
    let mut cpus = std::collections::BTreeSet::new();
    for part in list.trim().split(',') {
        let (first, last): (usize, usize) = match part.split_once('-') {
            Some((a, b)) => (a.parse().ok()?, b.parse().ok()?),
            None => {
                let cpu = part.parse().ok()?;
                (cpu, cpu)
            }
        };
        if last < first || last - first > 1 << 16 {
            return None;
        }
        cpus.extend(first..=last);
    }
    (!cpus.is_empty()).then_some(cpus)
}

/// The whole field of `len` nodes on rank 0 (None elsewhere), from every rank's values at its
/// `nodes`.
pub(crate) fn gather(
    world: &SimpleCommunicator,
    nodes: &[usize],
    values: &[f64],
    len: usize,
) -> Option<Vec<f64>> {
    let nodes: Vec<u64> = nodes.iter().map(|&i| i as u64).collect();
    if world.rank() != 0 {
        let root = world.process_at_rank(0);
        root.send(&nodes[..]);
        root.send(values);
        return None;
    }
    let mut field = vec![0.0; len];
    let mut place = |nodes: &[u64], values: &[f64]| {
        for (&i, &v) in nodes.iter().zip(values) {
            field[i as usize] = v;
        }
    };
    place(&nodes, values);
    for r in 1..world.size() {
        let source = world.process_at_rank(r);
        let (nodes, _) = source.receive_vec::<u64>();
        let (values, _) = source.receive_vec::<f64>();
        place(&nodes, &values);
    }
    Some(field)
}

fn hostname() -> String {
    let name = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    name.trim().to_string()
}

/// The CPUs this process may run on, from /proc (`Cpus_allowed_list`); "" where it does not say.
fn allowed_cpus() -> String {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let list = status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"));
    list.unwrap_or("").trim().to_string()
}

/// Each rank's `mine`, in rank order, on every rank: a short text (a host name, a CPU list), cut
/// at `LONGEST` bytes (a cut CPU list does not read, and its rank's affinity is unknown).
fn all_gathered(world: &SimpleCommunicator, mine: &str) -> Vec<String> {
    const LONGEST: usize = 256;
    let mut own = [0u8; LONGEST];
    let kept = mine.len().min(LONGEST);
    own[..kept].copy_from_slice(&mine.as_bytes()[..kept]);
    let mut all = vec![0u8; LONGEST * world.size() as usize];
    world.all_gather_into(&own[..], &mut all[..]);
    all.chunks(LONGEST)
        .map(|c| String::from_utf8_lossy(c.split(|b| *b == 0).next().unwrap_or_default()).into())
        .collect()
}

impl<'a> Ranks<'a> {
    /// The ranks of `mpi`, each computing on `pool`.
    pub fn mpi(mpi: &'a Mpi<'a>, pool: &'a ThreadPool) -> Self {
        Ranks {
            exchange: mpi,
            pool: Some(pool),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_are_oversubscribed_when_their_threads_outnumber_their_cpus() {
        let hosts = |names: &[&str]| names.iter().map(|h| h.to_string()).collect::<Vec<_>>();
        let cpus = hosts;
        // One rank per node, each bound to two CPUs: two threads each fit.
        let two_nodes = oversubscribed(&hosts(&["a", "b"]), &cpus(&["0-1", "0-1"]), 2);
        assert_eq!(two_nodes, Some(false));
        // Two unbound ranks on one node of two CPUs: four threads do not.
        let one_node = oversubscribed(&hosts(&["a", "a"]), &cpus(&["0-1", "0-1"]), 2);
        assert_eq!(one_node, Some(true));
        // Bound to disjoint CPUs of a four-CPU node, they do.
        let bound = oversubscribed(&hosts(&["a", "a"]), &cpus(&["0-1", "2,3"]), 2);
        assert_eq!(bound, Some(false));
        // A rank bound to one CPU runs two threads on it.
        let narrow = oversubscribed(&hosts(&["a", "b"]), &cpus(&["0", "0-1"]), 2);
        assert_eq!(narrow, Some(true));
        assert_eq!(oversubscribed(&hosts(&["a"]), &cpus(&["0-"]), 1), None);
        assert_eq!(cpu_list("0-3,8,10-11").unwrap().len(), 7);
    }
}
