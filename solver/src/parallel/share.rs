//! One rank's share of the grid, planned once before time stepping (\[JD], Algorithm 3): the
//! nodes it owns, the ghosts it needs (nodes of other ranks within ε of its own), and per other
//! rank the ghosts it receives and the nodes it sends (`neighborsOutside`).
//!
//! A rank stores its values on a `Window`: the bounding box of its nodes grown by the stencil's
//! reach and clipped to D. The window holds every ghost, so the stencil kernel of the serial
//! operator runs on it unchanged. Owned nodes are kept as runs (pieces of rows), split in two
//! classes: *interior* nodes, whose ball holds no ghost and can be computed while the exchange is
//! in flight, and *boundary* nodes, which wait for it. Ghosts are found from the full ownership
//! map, so a rank whose ball reaches past its neighbours (ε wider than a share) simply
//! exchanges with the ranks beyond: no assumption that halos come from adjacent shares.

use crate::case::{Case, CaseError, Partition};
use crate::discretization::grid::{RowRun, Window};
use crate::discretization::stencil::Stencil;
use crate::parallel::partition::{self, Ownership};
use crate::threads::BLOCK;
use serde::Serialize;
use std::collections::BTreeMap;

/// What one rank exchanges with one other rank every step, as window indices in the order of
/// their node index in D (both sides list the same nodes in the same order).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Neighbour {
    pub rank: usize,
    /// Ghosts received from `rank`.
    pub receive: Vec<usize>,
    /// Owned nodes sent to `rank`.
    pub send: Vec<usize>,
}

#[derive(Clone, Debug)]
pub struct RankShare {
    pub rank: usize,
    pub window: Window,
    /// Owned nodes with no ghost within reach, at compact offsets 0 .. interior nodes.
    pub interior: Vec<RowRun>,
    /// Owned nodes with a ghost within reach, after the interior ones.
    pub boundary: Vec<RowRun>,
    pub neighbours: Vec<Neighbour>,
}

/// Class of a window cell while the share is planned.
const UNUSED: u8 = 0;
const OWNED: u8 = 1;
const GHOST: u8 = 2;
const BOUNDARY: u8 = 3;

impl RankShare {
    pub fn new(ownership: &Ownership, stencil: &Stencil, rank: usize) -> Self {
        let grid = ownership.grid;
        let n = grid.n;
        let mine = rank as u32;
        let owns = |x: usize, y: usize| ownership.owner(y * n + x) == mine;

        // The bounding box of the owned nodes, grown by the reach and clipped to D.
        let window = ownership
            .window_of(rank, stencil.reach())
            .unwrap_or_else(|| panic!("rank {rank} owns no node; partitions are checked for that"));

        let mut class = vec![UNUSED; window.len()];
        for y in window.y0..window.y0 + window.ny {
            for x in window.x0..window.x0 + window.nx {
                if owns(x, y) {
                    class[window.index(x, y)] = OWNED;
                }
            }
        }
        // Ghosts: non-owned nodes within reach of an owned one. Boundary: owned nodes within reach
        // of a ghost (the ball is symmetric, so these are exactly the nodes other ranks need).
        grow(&mut class, &window, stencil, OWNED, |c| {
            if *c != OWNED {
                *c = GHOST
            }
        });
        grow(&mut class, &window, stencil, GHOST, |c| {
            if *c == OWNED {
                *c = BOUNDARY
            }
        });

        let interior = runs_of(&class, &window, OWNED, 0);
        let interior_nodes = interior.iter().map(RowRun::len).sum();
        let boundary = runs_of(&class, &window, BOUNDARY, interior_nodes);
        let neighbours = neighbours(ownership, stencil, &class, &window, rank);
        RankShare {
            rank,
            window,
            interior,
            boundary,
            neighbours,
        }
    }

    pub fn owned(&self) -> usize {
        self.interior
            .iter()
            .chain(&self.boundary)
            .map(RowRun::len)
            .sum()
    }

    pub fn ghosts(&self) -> usize {
        self.neighbours.iter().map(|nb| nb.receive.len()).sum()
    }

    /// All runs, interior then boundary: the compact order of the rank's arrays.
    pub fn runs(&self) -> impl Iterator<Item = &RowRun> {
        self.interior.iter().chain(&self.boundary)
    }

    /// Node index in D of each compact position.
    pub fn node_indices(&self, n: usize) -> Vec<usize> {
        self.runs()
            .flat_map(|run| (run.x0..run.x1).map(move |x| run.y * n + x))
            .collect()
    }
}

/// Calls `mark` on every window cell within reach of a cell of class `from` (the cells themselves
/// included), a row run at a time: the ball's row dy around a run [a, b) spans [a − k, b + k).
fn grow(
    class: &mut [u8],
    window: &Window,
    stencil: &Stencil,
    from: u8,
    mut mark: impl FnMut(&mut u8),
) {
    let sources = runs_of(class, window, from, 0);
    let (wx0, wx1) = (window.x0 as i64, (window.x0 + window.nx) as i64);
    let (wy0, wy1) = (window.y0 as i64, (window.y0 + window.ny) as i64);
    for run in sources {
        for row in &stencil.rows {
            let y = run.y as i64 + row.dy;
            if y < wy0 || y >= wy1 {
                continue;
            }
            let k = -row.dx_min;
            let (a, b) = ((run.x0 as i64 - k).max(wx0), (run.x1 as i64 + k).min(wx1));
            let start = window.index(a as usize, y as usize);
            class[start..start + (b - a) as usize]
                .iter_mut()
                .for_each(&mut mark);
        }
    }
}

/// Maximal runs of cells of class `of`, row by row, cut into pieces of at most `BLOCK` (the
/// threads' work unit), with compact offsets counted from `first_offset`.
fn runs_of(class: &[u8], window: &Window, of: u8, first_offset: usize) -> Vec<RowRun> {
    let mut runs = Vec::new();
    let mut offset = first_offset;
    for (r, row) in class.chunks(window.nx).enumerate() {
        let mut x = 0;
        while x < row.len() {
            if row[x] != of {
                x += 1;
                continue;
            }
            let start = x;
            while x < row.len() && row[x] == of && x - start < BLOCK {
                x += 1;
            }
            runs.push(RowRun {
                y: window.y0 + r,
                x0: window.x0 + start,
                x1: window.x0 + x,
                offset,
            });
            offset += x - start;
        }
    }
    runs
}

/// Per other rank, the ghosts it owns and the boundary nodes it needs, both in node order.
fn neighbours(
    ownership: &Ownership,
    stencil: &Stencil,
    class: &[u8],
    window: &Window,
    rank: usize,
) -> Vec<Neighbour> {
    let n = ownership.grid.n;
    let rows = ownership.grid.rows() as i64;
    let mut by_rank = BTreeMap::new();
    let mut needs = Vec::new(); // ranks owning a neighbour of the current boundary node
    for (w, &c) in class.iter().enumerate() {
        let (x, y) = window.column_row(w);
        match c {
            GHOST => {
                let owner = ownership.owner(y * n + x) as usize;
                by_rank_entry(&mut by_rank, owner).receive.push(w);
            }
            BOUNDARY => {
                needs.clear();
                for row in &stencil.rows {
                    let jy = y as i64 + row.dy;
                    if jy < 0 || jy >= rows {
                        continue;
                    }
                    for (dx, _) in row.bonds() {
                        let jx = x as i64 + dx;
                        if jx < 0 || jx >= n as i64 {
                            continue;
                        }
                        let owner = ownership.owner(jy as usize * n + jx as usize) as usize;
                        if owner != rank && !needs.contains(&owner) {
                            needs.push(owner);
                        }
                    }
                }
                for &owner in &needs {
                    by_rank_entry(&mut by_rank, owner).send.push(w);
                }
            }
            _ => {}
        }
    }
    by_rank.into_values().collect()
}

fn by_rank_entry(by_rank: &mut BTreeMap<usize, Neighbour>, rank: usize) -> &mut Neighbour {
    by_rank.entry(rank).or_insert_with(|| Neighbour {
        rank,
        receive: Vec::new(),
        send: Vec::new(),
    })
}

/// What a distributed run of a case would exchange, found without running it (`nlsolve partition`).
#[derive(Clone, Debug, Serialize)]
pub struct HaloReport {
    pub ranks: usize,
    pub partition: Partition,
    pub px: Option<usize>,
    pub py: Option<usize>,
    pub nodes: usize,
    /// Ghost nodes over all ranks, and the bytes they make per step.
    pub halo_nodes: usize,
    pub halo_bytes: usize,
    /// The largest halo of one rank, and the most ranks one rank exchanges with.
    pub max_rank_halo_nodes: usize,
    pub max_rank_neighbours: usize,
    pub imbalance: f64,
    /// Seconds to partition and to plan every rank's share.
    pub partition_s: f64,
    pub plan_s: f64,
}

impl HaloReport {
    /// The report of a validated case whose weights `stencil` holds.
    pub fn measure(case: &Case, stencil: &Stencil) -> Result<HaloReport, CaseError> {
        let started = std::time::Instant::now();
        let ownership = partition::ownership(case, stencil)?;
        let partition_s = started.elapsed().as_secs_f64();
        let started = std::time::Instant::now();
        let shares: Vec<RankShare> = (0..ownership.ranks)
            .map(|rank| RankShare::new(&ownership, stencil, rank))
            .collect();
        let plan_s = started.elapsed().as_secs_f64();
        let halo_nodes = shares.iter().map(RankShare::ghosts).sum();
        Ok(HaloReport {
            ranks: ownership.ranks,
            partition: case.partition,
            px: ownership.blocks.map(|(px, _)| px),
            py: ownership.blocks.map(|(_, py)| py),
            nodes: stencil.grid.nodes(),
            halo_nodes,
            halo_bytes: halo_nodes * std::mem::size_of::<f64>(),
            max_rank_halo_nodes: shares.iter().map(RankShare::ghosts).max().unwrap_or(0),
            max_rank_neighbours: shares.iter().map(|s| s.neighbours.len()).max().unwrap_or(0),
            imbalance: ownership.imbalance(),
            partition_s,
            plan_s,
        })
    }
}

#[cfg(test)]
mod tests {
    //! The plan of every rank checked against brute force on whole grids, and the operator on a
    //! rank's window checked bit for bit against the serial one, with every cell the plan does
    //! not fill poisoned by NaN.

    use super::*;
    use crate::case::Case;
    use crate::operator::stencil::WindowKernel;
    use crate::operator::{LinearOperator, StencilOperator};
    use crate::parallel::partition::block_halo;
    use std::collections::BTreeSet;

    fn case(dim: usize, n: usize, m: usize, ranks: usize, partition: Partition) -> Case {
        Case::parse(serde_json::json!({
            "dim": dim, "n": n, "m": m, "kernel": "linear", "t_end": 0.1, "cfl": 0.5,
            "ranks": ranks, "partition": partition,
        }))
        .expect("valid test case")
    }

    /// Nodes of D within the ball of node i, i excluded.
    fn ball(stencil: &Stencil, i: usize) -> Vec<usize> {
        let (n, rows) = (stencil.grid.n as i64, stencil.grid.rows() as i64);
        let (x, y) = ((i % n as usize) as i64, (i / n as usize) as i64);
        let mut nodes = Vec::new();
        for row in &stencil.rows {
            for (dx, _) in row.bonds() {
                let (jx, jy) = (x + dx, y + row.dy);
                if (0..n).contains(&jx) && (0..rows).contains(&jy) {
                    nodes.push((jy * n + jx) as usize);
                }
            }
        }
        nodes
    }

    /// The partitions this build has: METIS's graph partition comes with the `mpi` feature.
    fn partitions() -> &'static [Partition] {
        match cfg!(feature = "mpi") {
            true => &[Partition::Block, Partition::Graph],
            false => &[Partition::Block],
        }
    }

    /// The grids, horizons and rank counts covered: uneven splits, ε wider than a share
    /// (1D n = 40 on 6 ranks with m = 8 reaches two ranks away), and both partitions.
    fn layouts() -> Vec<Case> {
        let mut cases = Vec::new();
        for &partition in partitions() {
            for (dim, n, m, ranks) in [
                (1, 40, 8, 6),
                (1, 101, 3, 4),
                (2, 20, 1, 3),
                (2, 24, 3, 6),
                (2, 17, 8, 4),
                (2, 101, 3, 4),
            ] {
                cases.push(case(dim, n, m, ranks, partition));
            }
        }
        cases
    }

    #[test]
    fn every_rank_plan_matches_brute_force() {
        for case in layouts() {
            let stencil = Stencil::of_case(&case);
            let ownership = partition::ownership(&case, &stencil).expect("partitionable");

            let shares: Vec<RankShare> = (0..case.ranks)
                .map(|r| RankShare::new(&ownership, &stencil, r))
                .collect();
            let mut owned_anywhere = vec![0; stencil.grid.nodes()];
            for sub in &shares {
                let rank = sub.rank;
                let nodes = sub.node_indices(case.n);
                let mut expected_ghosts = BTreeSet::new();
                for &i in &nodes {
                    owned_anywhere[i] += 1;
                    assert_eq!(ownership.owner(i) as usize, rank);
                    let foreign: Vec<usize> = ball(&stencil, i)
                        .into_iter()
                        .filter(|&j| ownership.owner(j) as usize != rank)
                        .collect();
                    let on_boundary = sub
                        .boundary
                        .iter()
                        .any(|run| run.y * case.n + run.x0 <= i && i < run.y * case.n + run.x1);
                    assert_eq!(on_boundary, !foreign.is_empty(), "{case:?}: node {i} class");
                    expected_ghosts.extend(foreign);
                }
                let window = &sub.window;
                let node_of = |w: usize| {
                    let (x, y) = window.column_row(w);
                    y * case.n + x
                };
                let ghosts: BTreeSet<usize> = sub
                    .neighbours
                    .iter()
                    .flat_map(|nb| nb.receive.iter().map(|&w| node_of(w)))
                    .collect();
                assert_eq!(ghosts, expected_ghosts, "{case:?}: ghosts of rank {rank}");
                assert_eq!(ghosts.len(), sub.ghosts(), "{case:?}: a ghost listed twice");
                // What r receives from q is what q sends to r, in the same order.
                for nb in &sub.neighbours {
                    let other = &shares[nb.rank];
                    let back = other
                        .neighbours
                        .iter()
                        .find(|o| o.rank == rank)
                        .expect("symmetric");
                    let other_node = |w: usize| {
                        let (x, y) = other.window.column_row(w);
                        y * case.n + x
                    };
                    let received: Vec<usize> = nb.receive.iter().map(|&w| node_of(w)).collect();
                    let sent: Vec<usize> = back.send.iter().map(|&w| other_node(w)).collect();
                    assert_eq!(received, sent, "{case:?}: {rank} ← {}", nb.rank);
                    assert!(received
                        .iter()
                        .all(|&i| ownership.owner(i) as usize == nb.rank));
                }
            }
            assert!(
                owned_anywhere.iter().all(|&c| c == 1),
                "{case:?}: every node owned once"
            );
            if case.partition == Partition::Block {
                let (px, py) = ownership.blocks.expect("block shape");
                let total: usize = shares.iter().map(RankShare::ghosts).sum();
                assert_eq!(
                    block_halo(&stencil, px, py),
                    total,
                    "{case:?}: analytic halo"
                );
            }
        }
    }

    #[test]
    fn operator_on_a_window_equals_the_serial_operator_bit_for_bit() {
        for case in layouts() {
            let stencil = Stencil::of_case(&case);
            let ownership = partition::ownership(&case, &stencil).expect("partitionable");
            let nodes = stencil.grid.nodes();
            let u: Vec<f64> = (0..nodes)
                .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.4)
                .collect();
            let mut serial = vec![0.0; nodes];
            StencilOperator::new(&stencil).apply_once(&u, &mut serial);
            for rank in 0..case.ranks {
                let sub = RankShare::new(&ownership, &stencil, rank);
                let window = &sub.window;
                let kernel = WindowKernel::new(&stencil, *window);
                let layout = kernel.layout();
                // Only owned values, received ghosts and the collar (zero) are filled; anything
                // else read is NaN.
                let mut local = vec![f64::NAN; layout.len()];
                for row in local.chunks_mut(layout.stride()) {
                    for (c, value) in row.iter_mut().enumerate() {
                        let x = (window.x0 + c) as i64 - layout.pad as i64;
                        if !(0..case.n as i64).contains(&x) {
                            *value = 0.0;
                        }
                    }
                }
                for run in sub.runs() {
                    for x in run.x0..run.x1 {
                        local[layout.index(x, run.y)] = u[run.y * case.n + x];
                    }
                }
                for nb in &sub.neighbours {
                    for &w in &nb.receive {
                        let (x, y) = window.column_row(w);
                        local[layout.index(x, y)] = u[y * case.n + x];
                    }
                }
                let mut out = vec![0.0; sub.owned()];
                let interior = sub.interior.iter().map(RowRun::len).sum::<usize>();
                let (inner, outer) = out.split_at_mut(interior);
                kernel.apply_on_runs(&sub.interior, &local, inner);
                kernel.apply_on_runs(&sub.boundary, &local, outer);
                for (k, i) in sub.node_indices(case.n).into_iter().enumerate() {
                    assert_eq!(
                        out[k].to_bits(),
                        serial[i].to_bits(),
                        "{case:?}: rank {rank} node {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn interior_nodes_never_read_a_ghost() {
        // The graph partition's jagged boundary where it exists, else blocks.
        let case = case(2, 30, 3, 4, *partitions().last().unwrap());
        let stencil = Stencil::of_case(&case);
        let ownership = partition::ownership(&case, &stencil).unwrap();
        for rank in 0..case.ranks {
            let sub = RankShare::new(&ownership, &stencil, rank);
            let kernel = WindowKernel::new(&stencil, sub.window);
            let layout = kernel.layout();
            let mut local = vec![1.0; layout.len()];
            for nb in &sub.neighbours {
                for &w in &nb.receive {
                    let (x, y) = sub.window.column_row(w);
                    local[layout.index(x, y)] = f64::NAN; // not yet arrived
                }
            }
            let mut out = vec![0.0; sub.interior.iter().map(RowRun::len).sum()];
            kernel.apply_on_runs(&sub.interior, &local, &mut out);
            assert!(out.iter().all(|v| v.is_finite()), "rank {rank}");
        }
    }
}
