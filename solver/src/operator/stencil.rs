//! The stencil backend: L_h u_i = Σ_o w_o u_{i+o} − W u_i with precomputed weights.
//!
//! The serial kernel copies u once per application into a buffer with a zero collar of width
//! `reach`, so no bond needs a bounds check, and then register-blocks: a block of `LANES`
//! consecutive outputs of a row stays in registers while every bond of the stencil is added to it
//! (one load, one multiply and one add per bond and lane, no store). The distributed operator runs
//! the same `WindowKernel` on each rank's window, so both agree bit for bit.
//!
//! The kernel is compiled three times: portable (SSE2 on x86-64, the default build's target), for
//! AVX2 and for AVX-512, and the widest the processor has runs (`InstructionSet::detected`), so
//! the default binary runs at the host's speed. The three do the same operations in the same
//! order per output (wider blocks of outputs, no fused multiply–add, which Rust never forms
//! unasked), so they give the same bits; a test checks it on random fields.

use super::linear::LinearOperator;
use crate::discretization::grid::{Grid, PaddedWindow, RowRun, Window};
use crate::discretization::stencil::Stencil;
use crate::threads::BLOCK;
use rayon::prelude::*;

/// Outputs summed together in registers by the portable kernel: enough independent accumulators
/// to hide the latency of the additions (8 vectors of the widest unit the build targets).
const LANES: usize = if cfg!(target_feature = "avx512f") {
    64
} else if cfg!(target_feature = "avx") {
    32
} else {
    16
};

/// The code the stencil kernel runs: compiled for the build's target, or for a wider vector unit
/// the processor has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InstructionSet {
    Portable,
    Avx2,
    Avx512,
}

impl InstructionSet {
    /// The widest this processor runs.
    pub fn detected() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f") {
                return InstructionSet::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") {
                return InstructionSet::Avx2;
            }
        }
        InstructionSet::Portable
    }

    /// Every instruction set this processor runs, the portable one first.
    pub fn available() -> Vec<Self> {
        let detected = Self::detected();
        [
            InstructionSet::Portable,
            InstructionSet::Avx2,
            InstructionSet::Avx512,
        ]
        .into_iter()
        .filter(|&isa| isa == InstructionSet::Portable || isa as u8 <= detected as u8)
        .collect()
    }

    /// Its name in the record's provenance.
    pub fn name(self) -> &'static str {
        match self {
            InstructionSet::Portable => "portable",
            InstructionSet::Avx2 => "avx2",
            InstructionSet::Avx512 => "avx512f",
        }
    }
}

/// Rows per task in 2D, and the width of the column tiles each task sweeps its rows by.
const BAND: usize = 16;
const TILE: usize = 1024;

/// The stencil laid out for one padded window: every bond in summation order (rows by dy, then
/// dx), as its weight and the distance in the padded storage from a node to its neighbour.
pub(crate) struct WindowKernel {
    layout: PaddedWindow,
    weights: Vec<f64>,
    shifts: Vec<isize>,
    /// dy of each bond, for finding the bonds whose row lies in D.
    bond_dy: Vec<i64>,
    total_weight: f64,
    /// Rows of D.
    rows: i64,
    isa: InstructionSet,
}

impl WindowKernel {
    /// The kernel of `stencil` on `window`, padded by the stencil's reach, running the widest
    /// instruction set the processor has.
    pub(crate) fn new(stencil: &Stencil, window: Window) -> Self {
        Self::with_instruction_set(stencil, window, InstructionSet::detected())
    }

    /// The same, running `isa` (which the processor must have: see `InstructionSet::available`).
    pub(crate) fn with_instruction_set(
        stencil: &Stencil,
        window: Window,
        isa: InstructionSet,
    ) -> Self {
        assert!(
            InstructionSet::available().contains(&isa),
            "{isa:?} is not available here"
        );
        let layout = PaddedWindow {
            window,
            pad: stencil.reach(),
        };
        let stride = layout.stride() as isize;
        let (mut weights, mut shifts, mut bond_dy) = (Vec::new(), Vec::new(), Vec::new());
        for row in &stencil.rows {
            for (dx, w) in row.bonds() {
                weights.push(w);
                shifts.push(row.dy as isize * stride + dx as isize);
                bond_dy.push(row.dy);
            }
        }
        WindowKernel {
            layout,
            weights,
            shifts,
            bond_dy,
            total_weight: stencil.total_weight,
            rows: stencil.grid.rows() as i64,
            isa,
        }
    }

    pub(crate) fn layout(&self) -> &PaddedWindow {
        &self.layout
    }

    /// out[k] = (L_h u) at node (x0 + k, y) of D, from the padded copy of u on the window, which
    /// must hold every node of D within reach of the segment. Each value is summed in the same
    /// order (−W uᵢ first, then the bonds in order) whatever the window, segment or instruction
    /// set, so serial, threaded and distributed runs agree bit for bit.
    pub(crate) fn segment(&self, padded: &[f64], y: usize, x0: usize, out: &mut [f64]) {
        match self.isa {
            // SAFETY: `with_instruction_set` admits only the instruction sets the processor has.
            #[cfg(target_arch = "x86_64")]
            InstructionSet::Avx512 => unsafe { self.segment_avx512(padded, y, x0, out) },
            #[cfg(target_arch = "x86_64")]
            InstructionSet::Avx2 => unsafe { self.segment_avx2(padded, y, x0, out) },
            _ => self.blocked::<LANES>(padded, y, x0, out),
        }
    }

    /// `blocked` compiled for AVX-512: 8 vectors of 8 lanes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn segment_avx512(&self, padded: &[f64], y: usize, x0: usize, out: &mut [f64]) {
        self.blocked::<64>(padded, y, x0, out)
    }

    /// `blocked` compiled for AVX2: 8 vectors of 4 lanes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn segment_avx2(&self, padded: &[f64], y: usize, x0: usize, out: &mut [f64]) {
        self.blocked::<32>(padded, y, x0, out)
    }

    /// The register-blocked sum of `segment`, `B` outputs at a time.
    #[inline(always)]
    fn blocked<const B: usize>(&self, padded: &[f64], y: usize, x0: usize, out: &mut [f64]) {
        // The bonds whose row lies in D (collar rows add nothing); bonds are sorted by dy.
        let in_d = |dy: &i64| (0..self.rows).contains(&(y as i64 + dy));
        let first = self.bond_dy.partition_point(|dy| !in_d(dy) && *dy < 0);
        let last = first + self.bond_dy[first..].partition_point(in_d);
        let (weights, shifts) = (&self.weights[first..last], &self.shifts[first..last]);
        let centre = self.layout.index(x0, y);
        let total_weight = self.total_weight;
        let block = |x: usize, out: &mut [f64]| match out.len() {
            n if n == B => Self::block::<B>(padded, centre + x, total_weight, weights, shifts, out),
            8 => Self::block::<8>(padded, centre + x, total_weight, weights, shifts, out),
            _ => Self::block::<1>(padded, centre + x, total_weight, weights, shifts, out),
        };
        let len = out.len();
        let mut x = 0;
        while x + B <= len {
            block(x, &mut out[x..x + B]);
            x += B;
        }
        if x == len {
            return;
        }
        if len >= B {
            // The rest as one block ending at the segment's end: its first outputs are computed
            // again, to the same bits (each output is its own sum in a fixed order). Short row
            // runs (a graph partition's) would otherwise leave up to B − 1 outputs to the
            // one-at-a-time loop.
            block(len - B, &mut out[len - B..]);
            return;
        }
        while x + 8 <= len {
            block(x, &mut out[x..x + 8]);
            x += 8;
        }
        while x < len {
            block(x, &mut out[x..x + 1]);
            x += 1;
        }
    }

    /// W consecutive outputs from `own` on: −W u then every bond added in order, in registers.
    #[inline(always)]
    fn block<const W: usize>(
        padded: &[f64],
        own: usize,
        total_weight: f64,
        weights: &[f64],
        shifts: &[isize],
        out: &mut [f64],
    ) {
        let mut acc = [0.0; W];
        for (a, &ui) in acc.iter_mut().zip(&padded[own..own + W]) {
            *a = -total_weight * ui;
        }
        for (&w, &shift) in weights.iter().zip(shifts) {
            let from = own.wrapping_add_signed(shift);
            let s: &[f64; W] = padded[from..from + W].try_into().unwrap();
            for l in 0..W {
                acc[l] += w * s[l];
            }
        }
        out.copy_from_slice(&acc);
    }

    /// out = L_h u on the nodes of `runs`, whose compact offsets start at `runs[0].offset` with
    /// out[0], from the padded copy of u. Runs are split between threads, each value still
    /// summed by `segment` alone.
    pub(crate) fn apply_on_runs(&self, runs: &[RowRun], padded: &[f64], out: &mut [f64]) {
        let Some(first) = runs.first() else { return };
        if runs.len() == 1 || out.len() <= BLOCK {
            for run in runs {
                let at = run.offset - first.offset;
                self.segment(padded, run.y, run.x0, &mut out[at..at + run.len()]);
            }
            return;
        }
        let mid = runs.len() / 2;
        let (left, right) = out.split_at_mut(runs[mid].offset - first.offset);
        rayon::join(
            || self.apply_on_runs(&runs[..mid], padded, left),
            || self.apply_on_runs(&runs[mid..], padded, right),
        );
    }
}

/// L_h on all of D: u copied into a padded buffer (the workspace), then the kernel by bands of
/// rows and tiles of columns.
pub struct StencilOperator {
    grid: Grid,
    kernel: WindowKernel,
}

impl StencilOperator {
    pub fn new(stencil: &Stencil) -> Self {
        Self::with_instruction_set(stencil, InstructionSet::detected())
    }

    /// The operator running `isa`'s kernel; panics unless the processor has it.
    pub fn with_instruction_set(stencil: &Stencil, isa: InstructionSet) -> Self {
        StencilOperator {
            grid: stencil.grid,
            kernel: WindowKernel::with_instruction_set(stencil, Window::whole(&stencil.grid), isa),
        }
    }
}

impl LinearOperator for StencilOperator {
    /// u on D with a zero collar of the stencil's reach on both ends of every row.
    type Workspace = Vec<f64>;

    fn workspace(&self) -> Vec<f64> {
        vec![0.0; self.kernel.layout().len()]
    }

    fn apply(&self, u: &[f64], out: &mut [f64], padded: &mut Vec<f64>) {
        let n = self.grid.n;
        let layout = self.kernel.layout();
        // Only the interior changes: the collar was zeroed when the buffer was made.
        padded
            .par_chunks_mut(layout.stride())
            .zip(u.par_chunks(n))
            .for_each(|(padded_row, u_row)| {
                padded_row[layout.pad..layout.pad + n].copy_from_slice(u_row)
            });
        let padded = &padded[..];
        if self.grid.dim == 1 {
            out.par_chunks_mut(BLOCK)
                .enumerate()
                .for_each(|(b, segment)| self.kernel.segment(padded, 0, b * BLOCK, segment));
            return;
        }
        // Each task takes a band of rows and sweeps it one column tile at a time, so the source
        // rows a tile reads (2·reach + 1 of them) stay in cache from one output row to the next.
        let tile = TILE.min(n);
        out.par_chunks_mut(BAND * n)
            .enumerate()
            .for_each(|(b, band)| {
                for x0 in (0..n).step_by(tile) {
                    for (r, row) in band.chunks_mut(n).enumerate() {
                        let width = tile.min(n - x0);
                        let segment = &mut row[x0..x0 + width];
                        self.kernel.segment(padded, b * BAND + r, x0, segment);
                    }
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Kernel, Quadrature};
    use crate::discretization::grid::Horizon;

    /// Every segment, whatever its start and length (whole register blocks, the overlapped last
    /// block, the blocks of 8 and 1 of short runs), gives each output the bits of the literal sum
    /// −W uᵢ + Σ_o w_o u_{i+o} in bond order, on every instruction set: distributed row runs cut
    /// rows anywhere, and must still equal the serial run bit for bit.
    #[test]
    fn any_segment_gives_the_literal_sums_bits() {
        let n = 150;
        let grid = Grid::new(2, n);
        let stencil = Stencil::new(
            grid,
            Horizon::from_m(&grid, 3),
            Kernel::Linear,
            Quadrature::Ac,
            0.7,
        );
        let mut rng = fastrand::Rng::with_seed(12345);
        let mut random = move || rng.f64() - 0.5;
        for isa in InstructionSet::available() {
            let kernel = WindowKernel::with_instruction_set(&stencil, Window::whole(&grid), isa);
            let layout = kernel.layout();
            let stride = layout.stride() as isize;
            let mut padded = vec![0.0; layout.len()];
            for y in 0..n {
                for x in 0..n {
                    padded[layout.index(x, y)] = random();
                }
            }
            let literal = |x: usize, y: usize| {
                let i = layout.index(x, y) as isize;
                let mut sum = -stencil.total_weight * padded[i as usize];
                for row in stencil
                    .rows
                    .iter()
                    .filter(|r| (0..n as i64).contains(&(y as i64 + r.dy)))
                {
                    for (dx, w) in row.bonds() {
                        sum += w * padded[(i + row.dy as isize * stride + dx as isize) as usize];
                    }
                }
                sum
            };
            for y in [1, 75] {
                for x0 in [0, 1, 5, 17] {
                    for len in 1..=(n - x0).min(140) {
                        let mut out = vec![f64::NAN; len];
                        kernel.segment(&padded, y, x0, &mut out);
                        for (k, value) in out.iter().enumerate() {
                            assert_eq!(
                                value.to_bits(),
                                literal(x0 + k, y).to_bits(),
                                "{isa:?}: row {y}, segment {x0}+{len}, output {k}"
                            );
                        }
                    }
                }
            }
        }
    }
}
