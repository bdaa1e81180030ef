//! L_h on one rank's nodes (\[JD], Algorithm 3): the owned values go into the rank's padded
//! window, the values other ranks need go out and the ghosts come in (non-blocking), and while
//! the messages fly the interior nodes, whose balls hold no ghost, are computed; the boundary
//! nodes follow. The kernel is the serial stencil operator's, so every value equals the serial
//! one bit for bit.
//!
//! With the FFT backend the rank convolves its whole window (owned nodes and ghosts, zero
//! elsewhere) once the ghosts are in, by a local zero-padded FFT (`FftOperator::on_window`): a
//! node's ball lies inside the window, so the window's linear convolution is L_h at the owned
//! nodes. The transform lengths differ from the serial run's, so values agree with it to
//! rounding, not bit for bit.
//!
//! Vectors are in the rank's compact order (`RankShare::runs`): interior runs, then boundary runs.

use crate::case::Backend;
use crate::discretization::grid::RowRun;
use crate::discretization::stencil::Stencil;
use crate::operator::stencil::WindowKernel;
use crate::operator::{FftOperator, LinearOperator};
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
    /// With the FFT backend, the window's convolution.
    fft: Option<FftOperator>,
}

/// The padded window and the message buffers of one rank, and the FFT backend's window values
/// and workspace.
pub struct HaloWorkspace {
    padded: Vec<f64>,
    send: Vec<Vec<f64>>,
    receive: Vec<Vec<f64>>,
    fft: Option<DistributedFftWorkspace>,
}

/// The FFT backend's window values, before and after the convolution, and its workspace.
pub struct DistributedFftWorkspace {
    window: Vec<f64>,
    convolved: Vec<f64>,
    work: <FftOperator as LinearOperator>::Workspace,
}

impl<'a> DistributedOperator<'a> {
    /// L_h on the rank's nodes by `backend`: `Fft` convolves the window, any other the stencil.
    pub fn new(
        stencil: &Stencil,
        share: &'a RankShare,
        ranks: Ranks<'a>,
        backend: Backend,
    ) -> Self {
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
            fft: (backend == Backend::Fft)
                .then(|| ranks.on(|| FftOperator::on_window(stencil, share.window))),
        }
    }

    /// L_h at the owned nodes by the FFT of the whole window, whose ghosts are in `padded`.
    fn convolve_window(
        &self,
        fft: &FftOperator,
        padded: &[f64],
        out: &mut [f64],
        work: &mut DistributedFftWorkspace,
    ) {
        let DistributedFftWorkspace {
            window,
            convolved,
            work,
        } = work;
        let layout = self.kernel.layout();
        let (nx, pad, stride) = (layout.window.nx, layout.pad, layout.stride());
        let row_runs = &self.row_runs;
        self.ranks.on(|| {
            window
                .par_chunks_mut(nx)
                .zip(padded.par_chunks(stride))
                .for_each(|(row, padded_row)| row.copy_from_slice(&padded_row[pad..pad + nx]));
            fft.apply(window, convolved, work);
            for (y, runs) in row_runs.iter().enumerate() {
                for &(column, offset, len) in runs {
                    let at = y * nx + column - pad;
                    out[offset..offset + len].copy_from_slice(&convolved[at..at + len]);
                }
            }
        });
    }
}

impl LinearOperator for DistributedOperator<'_> {
    type Workspace = HaloWorkspace;

    fn workspace(&self) -> HaloWorkspace {
        let buffers = |lists: &[Vec<usize>]| lists.iter().map(|l| vec![0.0; l.len()]).collect();
        let window = self.kernel.layout().window.len();
        HaloWorkspace {
            padded: vec![0.0; self.kernel.layout().len()],
            send: buffers(&self.sends),
            receive: buffers(&self.receives),
            fft: self.fft.as_ref().map(|fft| DistributedFftWorkspace {
                window: vec![0.0; window],
                convolved: vec![0.0; window],
                work: self.ranks.on(|| fft.workspace()),
            }),
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], workspace: &mut HaloWorkspace) {
        let HaloWorkspace {
            padded,
            send,
            receive,
            fft: fft_work,
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
        if let (Some(fft), Some(fft_work)) = (&self.fft, fft_work) {
            ranks.exchange.swap(&self.peers, send, receive);
            place_ghosts(padded, receive, &self.receives);
            self.convolve_window(fft, padded, out, fft_work);
            return;
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
        place_ghosts(padded, receive, &self.receives);
        let (padded, boundary) = (&padded[..], self.boundary);
        ranks.on(|| kernel.apply_on_runs(boundary, padded, out_boundary));
    }
}

/// The received ghosts into their places in the padded window.
fn place_ghosts(padded: &mut [f64], receive: &[Vec<f64>], places: &[Vec<usize>]) {
    for (buffer, places) in receive.iter().zip(places) {
        for (&b, &place) in buffer.iter().zip(places) {
            padded[place] = b;
        }
    }
}
