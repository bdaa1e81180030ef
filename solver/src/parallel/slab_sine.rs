//! The sine-transform preconditioner of the implicit integrators over ranks, in 2D: the grid
//! in slabs of rows, turned between the axes by all-to-alls.
//!
//! Rank q holds the rows y ∈ [⌊qn/P⌋, ⌊(q+1)n/P⌋) for the transforms along x, and the same
//! range of columns, whole, for those along y. One application:
//! 1. the operator's values go to the slabs of their rows (one all-to-all; none when the
//!    partition is these slabs, as the block partition chooses for the implicit integrators);
//! 2. each row is transformed along x;
//! 3. the slabs are transposed (one all-to-all, (P − 1)/P · N/P values out of each rank);
//! 4. each column is transformed along y, scaled by the inverse symbol, and transformed back;
//! 5. transposed back, 6. transformed back along x, 7. returned to the operator's partition.
//!
//! Every row and column goes through the serial preconditioner's operations in the same order
//! (`operator::sine`), so the result has its bits whatever P and the partition. A rank holds
//! O(N/P) values (its slab, its columns, its share of the scaling) and does O(N log N / P) work.

use crate::discretization::stencil::Stencil;
use crate::operator::sine::{transform_and_scaled_inverse, transform_rows, Transform};
use crate::operator::LinearOperator;
use crate::parallel::exchange::{offsets, Ranks};
use crate::threads::row_tasks;
use rayon::prelude::*;
use std::ops::Range;

pub struct SlabSine<'a> {
    n: usize,
    /// Rank q's rows (and columns) are bounds[q] .. bounds[q + 1].
    bounds: Vec<usize>,
    rank: usize,
    transform: Transform,
    /// The inverse symbol, scaled, for this rank's columns: at [x − x₀][k₂].
    scaled_inverse: Vec<f64>,
    /// How the operator's values reach the slabs.
    route: Route,
    ranks: Ranks<'a>,
}

/// How the values of the operator's partition reach the slabs and come back.
enum Route {
    /// Each rank's values are its slab, in order.
    Slab,
    /// Each rank's values are its slab's, in another order (a block partition's compact order:
    /// interior row runs, then boundary ones), as runs of consecutive nodes.
    Permuted(Vec<Run>),
    /// Values change ranks, by one all-to-all each way.
    Moved(Redistribution),
}

/// `len` consecutive values at `from` in the operator's order, at `to` in the slab.
struct Run {
    from: usize,
    to: usize,
    len: usize,
}

/// The runs of consecutive nodes of `nodes`, each placed in the slab that starts at node `first`.
fn runs(nodes: &[usize], first: usize) -> Vec<Run> {
    let mut runs: Vec<Run> = Vec::new();
    for (k, &i) in nodes.iter().enumerate() {
        match runs.last_mut() {
            Some(run) if run.to + run.len == i - first => run.len += 1,
            _ => runs.push(Run {
                from: k,
                to: i - first,
                len: 1,
            }),
        }
    }
    runs
}

/// The operator's partition to the slabs and back: where each of this rank's values goes in
/// what it sends, and where each value it receives lies in its slab.
struct Redistribution {
    send_at: Vec<usize>,
    send_counts: Vec<usize>,
    receive_at: Vec<usize>,
    receive_counts: Vec<usize>,
}

/// The slab (when values change ranks; otherwise the output vector is the slab), the transposed
/// columns, the messages and a transform scratch per task.
pub struct SlabWorkspace {
    slab: Vec<f64>,
    columns: Vec<f64>,
    send: Vec<f64>,
    receive: Vec<f64>,
    scratch: Vec<Vec<f64>>,
}

impl<'a> SlabSine<'a> {
    /// Preconditions I − shift · L_h for the 2D grid of `stencil`, on the values of this rank's
    /// `nodes` (grid indices, in the order of its vectors).
    pub fn new(stencil: &Stencil, shift: f64, nodes: &[usize], ranks: Ranks<'a>) -> Self {
        let n = stencil.grid.n;
        assert_eq!(stencil.grid.dim, 2, "the 1D preconditioner gathers its row");
        let (rank, count) = (ranks.exchange.rank(), ranks.exchange.ranks());
        let bounds: Vec<usize> = (0..=count).map(|q| q * n / count).collect();
        let columns = bounds[rank]..bounds[rank + 1];
        let (transform, scaled_inverse) = transform_and_scaled_inverse(stencil, shift, columns);
        let slab = bounds[rank] * n..bounds[rank + 1] * n;
        let here = match () {
            _ if nodes.iter().copied().eq(slab.clone()) => 0.0,
            _ if nodes.len() == slab.len() && nodes.iter().all(|i| slab.contains(i)) => 1.0,
            _ => 2.0,
        };
        // Every rank takes the same route: the all-to-alls are collective.
        let route = match ranks.max(here) as u8 {
            0 => Route::Slab,
            1 => Route::Permuted(runs(nodes, slab.start)),
            _ => Route::Moved(Redistribution::new(nodes, n, &bounds, rank, ranks)),
        };
        SlabSine {
            n,
            bounds,
            rank,
            transform,
            scaled_inverse,
            route,
            ranks,
        }
    }

    fn rows(&self, q: usize) -> Range<usize> {
        span(&self.bounds, q)
    }

    /// For each rank q, the count of a block of `mine` × q's rows.
    fn block_counts(&self, mine: usize) -> Vec<usize> {
        (0..self.bounds.len() - 1)
            .map(|q| mine * self.rows(q).len())
            .collect()
    }

    /// A transpose's sizes: this rank's rows (its columns are as many: rows and columns are split
    /// alike), and the values each rank gets from it (what comes back is blocks of the same sizes).
    fn transpose_counts(&self) -> (usize, Vec<usize>) {
        let mine = self.rows(self.rank).len();
        (mine, self.block_counts(mine))
    }

    /// Slab rows [y₀, y₁) × all x → columns [x₀, x₁) × all y, at [x − x₀][y].
    fn transpose(&self, slab: &[f64], columns: &mut [f64], send: &mut [f64], receive: &mut [f64]) {
        let (n, bounds, (mine, counts)) = (self.n, &self.bounds[..], self.transpose_counts());
        let (send, receive) = (&mut send[..mine * n], &mut receive[..mine * n]);
        // To rank q: my rows × q's columns, row by row.
        self.ranks.on(|| {
            let mut blocks = split(send, &counts);
            blocks.par_iter_mut().enumerate().for_each(|(q, block)| {
                let theirs = span(bounds, q);
                for (r, out) in block.chunks_mut(theirs.len().max(1)).enumerate() {
                    out.copy_from_slice(&slab[r * n + theirs.start..r * n + theirs.end]);
                }
            });
        });
        self.ranks
            .exchange
            .all_to_all(send, &counts, receive, &counts);
        // From rank p: p's rows × my columns, row by row.
        self.ranks.on(|| {
            let blocks = split(receive, &counts);
            columns
                .par_chunks_mut(n)
                .enumerate()
                .for_each(|(c, column)| {
                    for (p, block) in blocks.iter().enumerate() {
                        for (r, y) in span(bounds, p).enumerate() {
                            column[y] = block[r * mine + c];
                        }
                    }
                });
        });
    }

    /// The inverse of `transpose`.
    fn transpose_back(
        &self,
        columns: &[f64],
        slab: &mut [f64],
        send: &mut [f64],
        receive: &mut [f64],
    ) {
        let (n, bounds, (mine, counts)) = (self.n, &self.bounds[..], self.transpose_counts());
        let (send, receive) = (&mut send[..mine * n], &mut receive[..mine * n]);
        // To rank p: p's rows × my columns, row by row.
        self.ranks.on(|| {
            let mut blocks = split(send, &counts);
            blocks.par_iter_mut().enumerate().for_each(|(p, block)| {
                for (r, y) in span(bounds, p).enumerate() {
                    for (c, column) in columns.chunks(n).enumerate() {
                        block[r * mine + c] = column[y];
                    }
                }
            });
        });
        self.ranks
            .exchange
            .all_to_all(send, &counts, receive, &counts);
        // From rank q: my rows × q's columns.
        self.ranks.on(|| {
            let blocks = split(receive, &counts);
            slab.par_chunks_mut(n).enumerate().for_each(|(r, row)| {
                for (q, block) in blocks.iter().enumerate() {
                    let theirs = span(bounds, q);
                    let w = theirs.len();
                    row[theirs].copy_from_slice(&block[r * w..(r + 1) * w]);
                }
            });
        });
    }
}

/// Rank q's rows (and columns).
fn span(bounds: &[usize], q: usize) -> Range<usize> {
    bounds[q]..bounds[q + 1]
}

/// `buffer` cut into consecutive pieces of `counts` values.
fn split<'b>(mut buffer: &'b mut [f64], counts: &[usize]) -> Vec<&'b mut [f64]> {
    counts
        .iter()
        .map(|&count| {
            let (piece, rest) = std::mem::take(&mut buffer).split_at_mut(count);
            buffer = rest;
            piece
        })
        .collect()
}

impl Redistribution {
    /// Agrees with every rank on who sends what: the counts, then the grid index of each value.
    fn new(nodes: &[usize], n: usize, bounds: &[usize], rank: usize, ranks: Ranks) -> Self {
        let count = bounds.len() - 1;
        let slab_of = |i: usize| bounds.partition_point(|&b| b <= i / n) - 1;
        let mut send_counts = vec![0; count];
        for &i in nodes {
            send_counts[slab_of(i)] += 1;
        }
        let mut next: Vec<usize> = offsets(&send_counts);
        let send_at: Vec<usize> = nodes
            .iter()
            .map(|&i| {
                let q = slab_of(i);
                next[q] += 1;
                next[q] - 1
            })
            .collect();
        let exchange = ranks.exchange;
        let mut receive_counts = vec![0.0; count];
        let sent: Vec<f64> = send_counts.iter().map(|&c| c as f64).collect();
        exchange.all_to_all(&sent, &vec![1; count], &mut receive_counts, &vec![1; count]);
        let receive_counts: Vec<usize> = receive_counts.iter().map(|&c| c as usize).collect();
        // Grid indices travel as f64: exact below 2⁵³.
        let mut indices = vec![0.0; nodes.len()];
        for (&i, &at) in nodes.iter().zip(&send_at) {
            indices[at] = i as f64;
        }
        let mut received = vec![0.0; receive_counts.iter().sum()];
        exchange.all_to_all(&indices, &send_counts, &mut received, &receive_counts);
        let first = bounds[rank] * n;
        let receive_at: Vec<usize> = received.iter().map(|&i| i as usize - first).collect();
        assert_eq!(
            receive_at.len(),
            (bounds[rank + 1] - bounds[rank]) * n,
            "every node of the slab comes from exactly one rank"
        );
        Redistribution {
            send_at,
            send_counts,
            receive_at,
            receive_counts,
        }
    }
}

impl LinearOperator for SlabSine<'_> {
    type Workspace = SlabWorkspace;

    fn workspace(&self) -> SlabWorkspace {
        let (n, mine) = (self.n, self.rows(self.rank).len());
        let (slab, moved) = match &self.route {
            Route::Moved(r) => (mine * n, r.send_at.len()),
            _ => (0, 0),
        };
        SlabWorkspace {
            slab: vec![0.0; slab],
            columns: vec![0.0; mine * n],
            send: vec![0.0; (mine * n).max(moved)],
            receive: vec![0.0; (mine * n).max(moved)],
            scratch: Vec::new(),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], work: &mut SlabWorkspace) {
        let (n, mine) = (self.n, self.rows(self.rank).len());
        let tasks = self.ranks.on(|| row_tasks(2, mine.max(1)));
        let SlabWorkspace {
            slab,
            columns,
            send,
            receive,
            scratch,
        } = work;
        while scratch.len() < tasks {
            scratch.push(vec![0.0; self.transform.scratch_len()]);
        }
        let (scratch, transform) = (&mut scratch[..tasks], &self.transform);
        let exchange = self.ranks.exchange;
        // This rank's slab: `out` itself unless values change ranks.
        let slab: &mut [f64] = match &self.route {
            Route::Slab => {
                out.copy_from_slice(u);
                out
            }
            Route::Permuted(runs) => {
                for run in runs {
                    out[run.to..run.to + run.len].copy_from_slice(&u[run.from..run.from + run.len]);
                }
                out
            }
            Route::Moved(r) => {
                let send = &mut send[..u.len()];
                for (&v, &at) in u.iter().zip(&r.send_at) {
                    send[at] = v;
                }
                let receive = &mut receive[..r.receive_at.len()];
                exchange.all_to_all(send, &r.send_counts, receive, &r.receive_counts);
                for (&v, &at) in receive.iter().zip(&r.receive_at) {
                    slab[at] = v;
                }
                slab
            }
        };
        self.ranks
            .on(|| transform_rows(transform, n, slab, scratch, true));
        self.transpose(slab, columns, send, receive);
        let scaled_inverse = &self.scaled_inverse;
        self.ranks.on(|| {
            transform_rows(transform, n, columns, scratch, true);
            columns
                .par_iter_mut()
                .zip(scaled_inverse)
                .for_each(|(v, &d)| *v *= d);
            transform_rows(transform, n, columns, scratch, false);
        });
        self.transpose_back(columns, slab, send, receive);
        self.ranks
            .on(|| transform_rows(transform, n, slab, scratch, false));
        match &self.route {
            Route::Slab => {}
            Route::Permuted(runs) => {
                let slab = &mut send[..slab.len()];
                slab.copy_from_slice(out);
                for run in runs {
                    out[run.from..run.from + run.len]
                        .copy_from_slice(&slab[run.to..run.to + run.len]);
                }
            }
            Route::Moved(r) => {
                let back = &mut send[..r.receive_at.len()];
                for (v, &at) in back.iter_mut().zip(&r.receive_at) {
                    *v = slab[at];
                }
                let receive = &mut receive[..out.len()];
                exchange.all_to_all(back, &r.receive_counts, receive, &r.send_counts);
                for (o, &at) in out.iter_mut().zip(&r.send_at) {
                    *o = receive[at];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::{Grid, Horizon};
    use crate::operator::SinePreconditioner;
    use crate::parallel::exchange::Exchange;
    use std::sync::{Barrier, Mutex};

    /// Ranks as threads of one process: each posts what it sends, all wait, each reads its part,
    /// all wait again before anyone posts anew.
    struct Board {
        barrier: Barrier,
        posts: Mutex<Vec<(Vec<f64>, Vec<usize>)>>,
    }

    struct ThreadRank<'a> {
        rank: usize,
        board: &'a Board,
    }

    impl ThreadRank<'_> {
        /// Posts `values` (`counts[q]` of them for rank q), then reads what every rank posted.
        fn post_and_read<T>(
            &self,
            values: &[f64],
            counts: &[usize],
            read: impl FnOnce(&[(Vec<f64>, Vec<usize>)]) -> T,
        ) -> T {
            self.board.posts.lock().unwrap()[self.rank] = (values.to_vec(), counts.to_vec());
            self.board.barrier.wait();
            let read = read(&self.board.posts.lock().unwrap());
            self.board.barrier.wait();
            read
        }
    }

    impl Exchange for ThreadRank<'_> {
        fn rank(&self) -> usize {
            self.rank
        }
        fn ranks(&self) -> usize {
            self.board.posts.lock().unwrap().len()
        }
        fn all_sum(&self, _: &mut [f64]) {
            unreachable!("the transform sums no vector")
        }
        fn sum(&self, local: f64) -> f64 {
            self.post_and_read(&[local], &[], |posts| posts.iter().map(|p| p.0[0]).sum())
        }
        fn max(&self, local: f64) -> f64 {
            self.post_and_read(&[local], &[], |posts| {
                posts.iter().map(|p| p.0[0]).fold(f64::MIN, f64::max)
            })
        }
        fn swap_overlapped(
            &self,
            _: &[usize],
            _: &[Vec<f64>],
            _: &mut [Vec<f64>],
            _: &mut dyn FnMut(),
        ) {
            unreachable!("the transform swaps no halo")
        }
        fn all_to_all(
            &self,
            send: &[f64],
            send_counts: &[usize],
            receive: &mut [f64],
            receive_counts: &[usize],
        ) {
            assert_eq!(send.len(), send_counts.iter().sum::<usize>());
            assert_eq!(receive.len(), receive_counts.iter().sum::<usize>());
            self.post_and_read(send, send_counts, |posts| {
                let mut at = 0;
                for ((values, counts), &count) in posts.iter().zip(receive_counts) {
                    assert_eq!(counts[self.rank], count, "the counts agree");
                    let start: usize = counts[..self.rank].iter().sum();
                    receive[at..at + count].copy_from_slice(&values[start..start + count]);
                    at += count;
                }
            })
        }
        fn seconds(&self) -> f64 {
            0.0
        }
    }

    /// Each rank's nodes, in its order: the slabs, the slabs backwards, or scattered.
    fn partitions(n: usize, ranks: usize) -> [Vec<Vec<usize>>; 3] {
        let bounds: Vec<usize> = (0..=ranks).map(|q| q * n / ranks).collect();
        let slabs: Vec<Vec<usize>> = (0..ranks)
            .map(|q| (bounds[q] * n..bounds[q + 1] * n).collect())
            .collect();
        let backwards = slabs
            .iter()
            .map(|s| s.iter().rev().copied().collect())
            .collect();
        let mut scattered = vec![Vec::new(); ranks];
        for i in 0..n * n {
            scattered[(i * 7919 + i / 5) % ranks].push(i);
        }
        [slabs, backwards, scattered]
    }

    /// Over 1 to 5 ranks, slab counts that divide n and that do not, both transforms (DST-II at
    /// n = 12, DST-I at n = 14) and every route, each rank's values are the serial
    /// preconditioner's bits at its nodes.
    #[test]
    fn the_slabs_give_the_serial_preconditioners_bits_on_every_rank_count_and_partition() {
        for n in [12, 14] {
            let grid = Grid::new(2, n);
            let stencil = Stencil::new(
                grid,
                Horizon::from_m(&grid, 3),
                Kernel::Constant,
                Quadrature::Midpoint,
                1.0,
            );
            let shift = 0.7 / stencil.total_weight;
            let r: Vec<f64> = (0..n * n)
                .map(|i| ((i * 7907 % 211) as f64 / 105.0 - 1.0) * (1.0 + i as f64).sqrt())
                .collect();
            let mut serial = vec![0.0; r.len()];
            SinePreconditioner::new(&stencil, shift).apply_once(&r, &mut serial);
            for ranks in 1..=5 {
                for (route, owned) in partitions(n, ranks).iter().enumerate() {
                    let board = Board {
                        barrier: Barrier::new(ranks),
                        posts: Mutex::new(vec![(Vec::new(), Vec::new()); ranks]),
                    };
                    let results: Vec<Vec<f64>> = std::thread::scope(|scope| {
                        let runs: Vec<_> = owned
                            .iter()
                            .enumerate()
                            .map(|(rank, nodes)| {
                                let (board, stencil, r) = (&board, &stencil, &r);
                                scope.spawn(move || {
                                    let exchange = ThreadRank { rank, board };
                                    let ranks = Ranks {
                                        exchange: &exchange,
                                        pool: None,
                                    };
                                    let slabs = SlabSine::new(stencil, shift, nodes, ranks);
                                    let mine: Vec<f64> = nodes.iter().map(|&i| r[i]).collect();
                                    let mut out = vec![0.0; mine.len()];
                                    let mut work = slabs.workspace();
                                    // Twice: a reused workspace gives the same bits.
                                    slabs.apply(&mine, &mut out, &mut work);
                                    slabs.apply(&mine, &mut out, &mut work);
                                    out
                                })
                            })
                            .collect();
                        runs.into_iter().map(|run| run.join().unwrap()).collect()
                    });
                    for (nodes, out) in owned.iter().zip(&results) {
                        for (&i, v) in nodes.iter().zip(out) {
                            assert_eq!(
                                v.to_bits(),
                                serial[i].to_bits(),
                                "n {n}, {ranks} ranks, route {route}, node {i}: {v} vs {}",
                                serial[i]
                            );
                        }
                    }
                }
            }
        }
    }
}
