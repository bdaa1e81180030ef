//! L_h on one rank's nodes (seed 000, Algorithm 3): the owned values go into the rank's padded
//! window, the values other ranks need go out and the ghosts come in (non-blocking), and while
//! the messages fly the interior nodes, whose balls hold no ghost, are computed; the boundary
//! nodes follow. The kernel is the serial stencil operator's, so every value equals the serial
//! one bit for bit.
//!
//! Vectors are in the rank's compact order (`RankShare::runs`): interior runs, then boundary runs.

use crate::discretization::grid::RowRun;
use crate::discretization::stencil::Stencil;
use crate::operator::stencil::WindowKernel;
use crate::operator::LinearOperator;
use crate::parallel::exchange::Ranks;
use crate::parallel::share::RankShare;
use rayon::prelude::*;

pub struct DistributedOperator<'a> {
    kernel: WindowKernel,
    interior: &'a [RowRun],
    boundary: &'a [RowRun],
    ranks: Ranks<'a>,
    /// Per window row, the owned runs in it: (column in the padded row, compact offset, length).
    row_runs: Vec<Vec<(usize, usize, usize)>>,
    interior_nodes: usize,
    /// The ranks this one exchanges with, and per rank the places of the owned nodes it sends
    /// and of the ghosts it receives (both sides list the same nodes in the same order).
    peers: Vec<usize>,
    sends: Vec<Vec<usize>>,
    receives: Vec<Vec<usize>>,
}

/// The padded window and the message buffers of one rank.
pub struct HaloWorkspace {
    padded: Vec<f64>,
    send: Vec<Vec<f64>>,
    receive: Vec<Vec<f64>>,
}

impl<'a> DistributedOperator<'a> {
    pub fn new(stencil: &Stencil, share: &'a RankShare, ranks: Ranks<'a>) -> Self {
        let kernel = WindowKernel::new(stencil, share.window);
        let layout = *kernel.layout();
        let place = |w: usize| {
            let (x, y) = share.window.column_row(w);
            layout.index(x, y)
        };
        let mut row_runs = vec![Vec::new(); share.window.ny];
        for run in share.runs() {
            let start = layout.index(run.x0, run.y);
            let row = start / layout.stride();
            row_runs[row].push((start % layout.stride(), run.offset, run.len()));
        }
        let neighbours = &share.neighbours;
        DistributedOperator {
            interior: &share.interior,
            boundary: &share.boundary,
            ranks,
            row_runs,
            interior_nodes: share.interior.iter().map(RowRun::len).sum(),
            peers: neighbours.iter().map(|nb| nb.rank).collect(),
            sends: neighbours
                .iter()
                .map(|nb| nb.send.iter().map(|&w| place(w)).collect())
                .collect(),
            receives: neighbours
                .iter()
                .map(|nb| nb.receive.iter().map(|&w| place(w)).collect())
                .collect(),
            kernel,
        }
    }
}

impl LinearOperator for DistributedOperator<'_> {
    type Workspace = HaloWorkspace;

    fn workspace(&self) -> HaloWorkspace {
        let buffers = |lists: &[Vec<usize>]| lists.iter().map(|l| vec![0.0; l.len()]).collect();
        HaloWorkspace {
            padded: vec![0.0; self.kernel.layout().len()],
            send: buffers(&self.sends),
            receive: buffers(&self.receives),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], workspace: &mut HaloWorkspace) {
        let HaloWorkspace {
            padded,
            send,
            receive,
        } = workspace;
        let (ranks, kernel, row_runs) = (self.ranks, &self.kernel, &self.row_runs);
        let stride = kernel.layout().stride();
        // The owned values into the window (the cells outside D stay zero).
        ranks.on(|| {
            padded
                .par_chunks_mut(stride)
                .zip(row_runs)
                .for_each(|(row, runs)| {
                    for &(column, offset, len) in runs {
                        row[column..column + len].copy_from_slice(&u[offset..offset + len]);
                    }
                })
        });
        for (buffer, places) in send.iter_mut().zip(&self.sends) {
            for (b, &place) in buffer.iter_mut().zip(places) {
                *b = padded[place];
            }
        }
        let (out_interior, out_boundary) = out.split_at_mut(self.interior_nodes);
        {
            let (padded, interior) = (&padded[..], self.interior);
            ranks
                .exchange
                .swap_overlapped(&self.peers, send, receive, &mut || {
                    ranks.on(|| kernel.apply_on_runs(interior, padded, out_interior))
                });
        }
        for (buffer, places) in receive.iter().zip(&self.receives) {
            for (&b, &place) in buffer.iter().zip(places) {
                padded[place] = b;
            }
        }
        let (padded, boundary) = (&padded[..], self.boundary);
        ranks.on(|| kernel.apply_on_runs(boundary, padded, out_boundary));
    }
}
