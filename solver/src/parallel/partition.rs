//! How the nodes of D are divided among ranks (\[JD], section 3): which rank owns each node.
//!
//! - `block`: px × py rectangles, boundaries at ⌊i·n/p⌋ so uneven splits differ by at most one
//!   node; px·py = R is chosen to minimise the halo unless the case gives it, or, for the
//!   implicit integrators, 1 × R: the slabs of rows their sine transform runs on.
//! - `graph`: METIS k-way partition of the lattice's nearest-neighbour graph. Its edge cut is the
//!   subdomains' perimeter, and the ε-halo is that perimeter times the reach, so minimising one
//!   minimises the other while the graph stays 2d edges per node instead of the ~πm² bonds of the
//!   full interaction graph (which at n = 1024, m = 8 would be 2·10⁸ edges for METIS to hold).

use crate::case::{Case, CaseError, Partition};
use crate::discretization::grid::{Grid, Window};
use crate::discretization::stencil::Stencil;

/// The rank that owns each node of D.
#[derive(Clone, Debug, PartialEq)]
pub struct Ownership {
    pub grid: Grid,
    pub ranks: usize,
    owners: Owners,
    /// px × py of a block partition (py = 1 in 1D).
    pub blocks: Option<(usize, usize)>,
}

/// Who owns each node: for blocks a rule (the block of each column and of each row, O(n) to
/// hold, so that no rank of a block partition holds anything the size of the grid); for a graph
/// partition METIS's map of every node, or, on a rank over MPI, the part of it in one window
/// with every rank's count.
#[derive(Clone, Debug, PartialEq)]
enum Owners {
    Blocks {
        column: Vec<u32>,
        row: Vec<u32>,
    },
    Map(Vec<u32>),
    Window {
        window: Window,
        owner: Vec<u32>,
        counts: Vec<usize>,
    },
}

impl Ownership {
    /// A graph partition's map: `owner[i]` for node index i.
    pub fn of_map(grid: Grid, ranks: usize, owner: Vec<u32>) -> Self {
        Ownership {
            grid,
            ranks,
            owners: Owners::Map(owner),
            blocks: None,
        }
    }

    /// The part of a graph partition's map a rank needs, `owner` at the nodes of `window` row by
    /// row, with the nodes each rank owns.
    pub fn of_window(
        grid: Grid,
        ranks: usize,
        window: Window,
        owner: Vec<u32>,
        counts: Vec<usize>,
    ) -> Self {
        assert_eq!(
            owner.len(),
            window.nx * window.ny,
            "a value per node of the window"
        );
        Ownership {
            grid,
            ranks,
            owners: Owners::Window {
                window,
                owner,
                counts,
            },
            blocks: None,
        }
    }

    /// The rank that owns node i (within the window, for a rank's part of a map).
    pub fn owner(&self, i: usize) -> u32 {
        match &self.owners {
            Owners::Blocks { column, row } => {
                let px = self.blocks.map_or(1, |(px, _)| px) as u32;
                row[i / self.grid.n] * px + column[i % self.grid.n]
            }
            Owners::Map(owner) => owner[i],
            Owners::Window { window, owner, .. } => {
                let (x, y) = (i % self.grid.n, i / self.grid.n);
                assert!(
                    (window.x0..window.x0 + window.nx).contains(&x)
                        && (window.y0..window.y0 + window.ny).contains(&y),
                    "node {i} lies outside this rank's part of the partition"
                );
                owner[window.index(x, y)]
            }
        }
    }

    /// The nodes within `reach` (sideways; and rows too in 2D) of `rank`'s nodes' bounding box,
    /// clipped to D: every node a rank's share looks up (`RankShare`). None if it owns none.
    pub fn window_of(&self, rank: usize, reach: usize) -> Option<Window> {
        let (lo, hi) = self.bounding_box(rank)?;
        Some(Window::around(&self.grid, lo, hi, reach))
    }

    /// The owners of the nodes of `window`, row by row.
    pub fn owners_in(&self, window: Window) -> Vec<u32> {
        let n = self.grid.n;
        (window.y0..window.y0 + window.ny)
            .flat_map(|y| (window.x0..window.x0 + window.nx).map(move |x| y * n + x))
            .map(|i| self.owner(i))
            .collect()
    }

    /// The map of every node's owner, for a graph partition (None for blocks, which need none).
    pub fn into_map(self) -> Option<Vec<u32>> {
        match self.owners {
            Owners::Map(owner) => Some(owner),
            Owners::Blocks { .. } | Owners::Window { .. } => None,
        }
    }

    /// The smallest box [x₀, x₁) × [y₀, y₁) holding the nodes `rank` owns, as ([x₀, y₀], [x₁, y₁]);
    /// None if it owns none.
    pub fn bounding_box(&self, rank: usize) -> Option<([usize; 2], [usize; 2])> {
        let mine = rank as u32;
        match &self.owners {
            Owners::Blocks { column, row } => {
                let px = self.blocks.map_or(1, |(px, _)| px) as u32;
                let span = |of: &[u32], block: u32| {
                    let first = of.iter().position(|&b| b == block)?;
                    let last = of.iter().rposition(|&b| b == block)?;
                    Some((first, last + 1))
                };
                let (x0, x1) = span(column, mine % px)?;
                let (y0, y1) = span(row, mine / px)?;
                Some(([x0, y0], [x1, y1]))
            }
            Owners::Map(owner) => bounding_box(owner, self.grid.n, 0, 0, mine),
            // A rank's window holds its own nodes' box.
            Owners::Window { window, owner, .. } => {
                bounding_box(owner, window.nx, window.x0, window.y0, mine)
            }
        }
    }

    /// Nodes owned by each rank.
    pub fn owned_counts(&self) -> Vec<usize> {
        let mut counts = vec![0; self.ranks];
        match &self.owners {
            Owners::Blocks { column, row } => {
                let px = self.blocks.map_or(1, |(px, _)| px);
                for &by in row {
                    for &bx in column {
                        counts[by as usize * px + bx as usize] += 1;
                    }
                }
            }
            Owners::Map(owner) => {
                for &r in owner {
                    counts[r as usize] += 1;
                }
            }
            Owners::Window { counts: all, .. } => counts.clone_from(all),
        }
        counts
    }

    /// max owned / mean owned: 1 for a perfect balance.
    pub fn imbalance(&self) -> f64 {
        let max = self.owned_counts().into_iter().max().unwrap_or(0);
        max as f64 * self.ranks as f64 / self.grid.nodes() as f64
    }

    /// What a run reports of its partition: kept once each rank has taken its share, so that the
    /// map of every node's owner (the whole grid) is not held through the run.
    pub fn summary(&self) -> PartitionSummary {
        PartitionSummary {
            ranks: self.ranks,
            blocks: self.blocks,
            imbalance: self.imbalance(),
        }
    }
}

/// The box ([x₀, y₀], [x₁, y₁]) of the cells of `owner` (rows of `width`, the first at (x0, y0))
/// that hold `rank`.
fn bounding_box(
    owner: &[u32],
    width: usize,
    x0: usize,
    y0: usize,
    rank: u32,
) -> Option<([usize; 2], [usize; 2])> {
    let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
    for (k, _) in owner.iter().enumerate().filter(|(_, &r)| r == rank) {
        let (x, y) = (x0 + k % width, y0 + k / width);
        lo = [lo[0].min(x), lo[1].min(y)];
        hi = [hi[0].max(x + 1), hi[1].max(y + 1)];
    }
    (lo[0] < hi[0]).then_some((lo, hi))
}

/// A partition as the record describes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PartitionSummary {
    pub ranks: usize,
    pub blocks: Option<(usize, usize)>,
    pub imbalance: f64,
}

/// The partition the case asks for.
pub fn ownership(case: &Case, stencil: &Stencil) -> Result<Ownership, CaseError> {
    match case.partition {
        Partition::Block => block(case, stencil),
        Partition::Graph => graph(case, stencil.grid),
    }
}

/// The block partition of the case: px × py given or chosen, then each node's block.
pub fn block(case: &Case, stencil: &Stencil) -> Result<Ownership, CaseError> {
    let grid = stencil.grid;
    let (px, py) = block_shape(case, stencil)?;
    Ok(Ownership {
        grid,
        ranks: px * py,
        owners: Owners::Blocks {
            column: block_of_each_index(grid.n, px),
            row: block_of_each_index(grid.rows(), py),
        },
        blocks: Some((px, py)),
    })
}

/// The graph partition of the case by METIS (deterministic: METIS's seed is fixed).
pub fn graph(case: &Case, grid: Grid) -> Result<Ownership, CaseError> {
    let ranks = case.ranks;
    let owner: Vec<u32> = if ranks == 1 {
        vec![0; grid.nodes()]
    } else {
        metis_parts(grid, ranks)?
    };
    let ownership = Ownership::of_map(grid, ranks, owner);
    let empty = ownership.owned_counts().iter().filter(|&&c| c == 0).count();
    if empty > 0 {
        return Err(CaseError::new(
            "ranks",
            format!(
                "METIS left {empty} of {ranks} ranks without nodes on this {}-node grid; use fewer ranks or `partition: block`",
                grid.nodes()
            ),
        ));
    }
    Ok(ownership)
}

/// METIS's k-way partition of the grid's lattice graph: each node's rank.
#[cfg(feature = "mpi")]
fn metis_parts(grid: Grid, ranks: usize) -> Result<Vec<u32>, CaseError> {
    let (xadj, adjncy) = lattice_graph(&grid);
    let mut part = vec![0 as metis::Idx; grid.nodes()];
    let metis_failed = |e: &dyn std::fmt::Display| {
        CaseError::new(
            "partition",
            format!("METIS failed: {e}; use `partition: block`"),
        )
    };
    metis::Graph::new(1, ranks as metis::Idx, &xadj, &adjncy)
        .map_err(|e| metis_failed(&e))?
        .set_option(metis::option::Seed(1))
        .part_kway(&mut part)
        .map_err(|e| metis_failed(&e))?;
    Ok(part.into_iter().map(|p| p as u32).collect())
}

/// A build without the `mpi` feature has no METIS (validation refuses ranks > 1 there first).
#[cfg(not(feature = "mpi"))]
fn metis_parts(_: Grid, _: usize) -> Result<Vec<u32>, CaseError> {
    Err(CaseError::new(
        "partition",
        "the graph partition needs METIS, and this nlsolve was built without it (`--no-default-features`); use `partition: block` or build with the default features",
    ))
}

/// px × py: as given (checked), or the factor pair of R whose halo is smallest (ties go to the
/// smaller px, i.e. wider blocks, whose rows the stencil sweeps in longer runs).
fn block_shape(case: &Case, stencil: &Stencil) -> Result<(usize, usize), CaseError> {
    let grid = stencil.grid;
    let ranks = case.ranks;
    let (n, rows) = (grid.n, grid.rows());
    if grid.dim == 1 {
        if case.py.is_some_and(|py| py != 1) {
            return Err(CaseError::new(
                "py",
                "a 1D grid is split along x only; leave `py` out",
            ));
        }
        if case.px.is_some_and(|px| px != ranks) {
            return Err(CaseError::new(
                "px",
                format!("in 1D px must equal ranks = {ranks}; leave `px` out"),
            ));
        }
        return Ok((ranks, 1));
    }
    let fits = |px: usize, py: usize| px * py == ranks && px <= n && py <= rows;
    let shape = match (case.px, case.py) {
        (Some(px), Some(py)) => Some((px, py)),
        (Some(px), None) => ranks.is_multiple_of(px).then(|| (px, ranks / px)),
        (None, Some(py)) => ranks.is_multiple_of(py).then(|| (ranks / py, py)),
        // The implicit integrators' preconditioner transforms slabs of rows: with those as the
        // blocks no value changes rank before it (the halo grows from the perimeter of a
        // square to two rows, a few values per node against the N/P two all-to-alls would move).
        (None, None) if case.integrator.is_implicit() && fits(1, ranks) => Some((1, ranks)),
        (None, None) => (1..=ranks)
            .filter(|&px| ranks.is_multiple_of(px) && fits(px, ranks / px))
            .map(|px| (px, ranks / px))
            .min_by_key(|&(px, py)| (block_halo(stencil, px, py), px)),
    };
    match shape {
        Some((px, py)) if fits(px, py) => Ok((px, py)),
        _ if case.px.is_some() || case.py.is_some() => Err(CaseError::new(
            if case.px.is_some() { "px" } else { "py" },
            format!(
                "px × py must equal ranks = {ranks} with px, py ≤ n = {n} (got px = {:?}, py = {:?}); leave both out to have them chosen",
                case.px, case.py
            ),
        )),
        _ => Err(CaseError::new(
            "ranks",
            format!(
                "{ranks} ranks have no factor pair px × py with px, py ≤ n = {n}, so no block partition exists; use `partition: graph` or another rank count"
            ),
        )),
    }
}

/// block_of[i]: the block holding index i when 0..len is cut into `parts` at ⌊k·len/parts⌋.
fn block_of_each_index(len: usize, parts: usize) -> Vec<u32> {
    let mut block_of = vec![0; len];
    for b in 0..parts {
        block_of[b * len / parts..(b + 1) * len / parts].fill(b as u32);
    }
    block_of
}

/// Total ghost nodes of the px × py block partition, counted exactly from the stencil's shape: a
/// block's ghosts in the row d rows beyond its edge reach as far sideways as the stencil row
/// |dy| = d does, since the ball narrows away from its centre.
pub fn block_halo(stencil: &Stencil, px: usize, py: usize) -> usize {
    let grid = stencil.grid;
    let (n, rows) = (grid.n, grid.rows());
    // reach_at[d]: half-width of the stencil row |dy| = d.
    let mut reach_at = vec![0usize; stencil.reach() + 1];
    for row in &stencil.rows {
        reach_at[row.dy.unsigned_abs() as usize] = row.dx_min.unsigned_abs() as usize;
    }
    let dilated_width = |x0: usize, x1: usize, k: usize| (x1 + k).min(n) - x0.saturating_sub(k);
    let mut ghosts = 0;
    for by in 0..py {
        let (y0, y1) = (by * rows / py, (by + 1) * rows / py);
        for bx in 0..px {
            let (x0, x1) = (bx * n / px, (bx + 1) * n / px);
            ghosts += (y1 - y0) * (dilated_width(x0, x1, reach_at[0]) - (x1 - x0));
            for (d, &k) in reach_at.iter().enumerate().skip(1) {
                let beyond = usize::from(y0 >= d) + usize::from(y1 + d <= rows);
                ghosts += beyond * dilated_width(x0, x1, k);
            }
        }
    }
    ghosts
}

/// The lattice's nearest-neighbour graph in METIS's CSR form (xadj, adjncy).
#[cfg(feature = "mpi")]
fn lattice_graph(grid: &Grid) -> (Vec<metis::Idx>, Vec<metis::Idx>) {
    let (n, rows) = (grid.n as i64, grid.rows() as i64);
    let mut xadj = Vec::with_capacity(grid.nodes() + 1);
    let mut adjncy = Vec::with_capacity(grid.nodes() * 2 * grid.dim);
    xadj.push(0);
    for y in 0..rows {
        for x in 0..n {
            for (dx, dy) in [(0, -1), (-1, 0), (1, 0), (0, 1)] {
                let (jx, jy) = (x + dx, y + dy);
                if (0..n).contains(&jx) && (0..rows).contains(&jy) {
                    adjncy.push((jy * n + jx) as metis::Idx);
                }
            }
            xadj.push(adjncy.len() as metis::Idx);
        }
    }
    (xadj, adjncy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block partition's rule gives every node the owner, every rank the bounding box and the
    /// node count of the literal cut at ⌊k·n/p⌋, and of the same partition held as a map, and a
    /// rank's part of that map (its window) agrees with the whole of it.
    #[test]
    fn the_block_rule_owns_what_the_map_of_every_node_owns() {
        for (dim, n, px, py) in [(2, 13, 3, 2), (2, 16, 4, 4), (2, 7, 1, 5), (1, 29, 4, 1)] {
            let grid = Grid::new(dim, n);
            let rows = grid.rows();
            let literal: Vec<u32> = (0..grid.nodes())
                .map(|i| {
                    let (x, y) = (i % n, i / n);
                    let bx = (0..px).find(|b| x < (b + 1) * n / px).unwrap();
                    let by = (0..py).find(|b| y < (b + 1) * rows / py).unwrap();
                    (by * px + bx) as u32
                })
                .collect();
            let rule = Ownership {
                grid,
                ranks: px * py,
                owners: Owners::Blocks {
                    column: block_of_each_index(n, px),
                    row: block_of_each_index(rows, py),
                },
                blocks: Some((px, py)),
            };
            let map = Ownership::of_map(grid, px * py, literal.clone());
            for (i, &owner) in literal.iter().enumerate() {
                assert_eq!(rule.owner(i), owner, "{dim}D n {n} {px} × {py}: node {i}");
            }
            assert_eq!(rule.owned_counts(), map.owned_counts());
            for rank in 0..px * py {
                assert_eq!(
                    rule.bounding_box(rank),
                    map.bounding_box(rank),
                    "rank {rank}"
                );
            }
            // A rank's part of the map (over MPI): its window, with every rank's count.
            for rank in 0..px * py {
                let window = map.window_of(rank, 2).unwrap();
                let part = Ownership::of_window(
                    grid,
                    px * py,
                    window,
                    map.owners_in(window),
                    map.owned_counts(),
                );
                assert_eq!(
                    part.bounding_box(rank),
                    map.bounding_box(rank),
                    "rank {rank}"
                );
                assert_eq!(part.window_of(rank, 2), Some(window));
                assert_eq!(part.owned_counts(), map.owned_counts());
                for y in window.y0..window.y0 + window.ny {
                    for x in window.x0..window.x0 + window.nx {
                        assert_eq!(part.owner(y * n + x), literal[y * n + x]);
                    }
                }
            }
            assert_eq!(map.into_map(), Some(literal));
            assert_eq!(rule.into_map(), None);
        }
    }
}
