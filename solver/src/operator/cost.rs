//! The cost model behind `backend: auto`: predicted seconds per step with the stencil and with
//! the FFT backend, with constants fitted to `studies/perf.json` on the development machine (see
//! docs/performance.md). The stencil costs N·(offsets·a + b), the FFT P^d log₂(P^d)·c + N·b:
//! the FFT wins from m ≈ 8–16 in 2D on n = 256…4096 (measured: from m = 7 at n = 256, between 8
//! and 16 at n = 1024 and 4096). Only the ratio matters for the choice, so one set of constants serves
//! every thread count; the model is a property of the case, never a timing taken at run time, so
//! the same case always runs the same backend.

use super::fft::transform_length;
use crate::case::Backend;
use crate::discretization::stencil::Stencil;

// Least-squares fits (in relative error) to the median step times of `studies/perf.json` (2D,
// 2 threads, the default build with its run-time dispatch; 27 points per backend, each within 2×
// of the fit), the Euler update included.
/// Seconds per bond update of the stencil backend.
const STENCIL_PER_BOND: f64 = 2.25e-11;
/// Seconds per node of either backend's work that does not depend on m (the Euler update, the
/// stencil's padded copy, the FFT's −W u).
const PER_NODE: f64 = 6.7e-10;
/// Seconds per (transform point × log₂ of the transform's size) of the FFT backend, every pass.
const FFT_PER_POINT_LOG: f64 = 2.0e-10;

/// Predicted seconds per application of each fast backend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cost {
    pub stencil: f64,
    pub fft: f64,
}

impl Cost {
    pub fn of_stencil(stencil: &Stencil) -> Self {
        let grid = stencil.grid;
        let nodes = grid.nodes() as f64;
        let reach = stencil.reach().min(grid.n - 1);
        let points = (transform_length(grid.n + reach) as f64).powi(grid.dim as i32);
        Cost {
            stencil: nodes * (STENCIL_PER_BOND * stencil.offsets as f64 + PER_NODE),
            fft: FFT_PER_POINT_LOG * points * points.log2() + PER_NODE * nodes,
        }
    }
}

/// The backend `auto` runs: the FFT when the model predicts it faster, else the stencil.
pub fn choose(stencil: &Stencil) -> Backend {
    let cost = Cost::of_stencil(stencil);
    if cost.fft < cost.stencil {
        Backend::Fft
    } else {
        Backend::Stencil
    }
}
