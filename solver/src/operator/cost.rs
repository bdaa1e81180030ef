//! The cost model behind `backend: auto`: predicted seconds per application of the stencil and
//! FFT backends, with constants fitted to `studies/perf.json` on the development machine (see
//! docs/performance.md). Only the ratio matters for the choice, so one set of constants serves
//! every thread count; the model is a property of the case, never a timing taken at run time, so
//! the same case always runs the same backend.

use super::fft::transform_length;
use super::Backend;
use crate::stencil::Stencil;

/// Seconds per bond update of the stencil backend.
const STENCIL_PER_BOND: f64 = 1.0e-10;
/// Seconds per node of the stencil backend's fixed work (the padded copy, −W u, the store).
const STENCIL_PER_NODE: f64 = 1.0e-9;
/// Seconds per (transform point × log₂ of the transform's size) of the FFT backend, both
/// directions together.
const FFT_PER_POINT_LOG: f64 = 1.0e-9;

/// Predicted seconds per application of each fast backend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cost {
    pub stencil: f64,
    pub fft: f64,
}

impl Cost {
    pub fn of(stencil: &Stencil) -> Self {
        let grid = stencil.grid;
        let nodes = grid.nodes() as f64;
        let reach = stencil.reach().min(grid.n - 1);
        let points = (transform_length(grid.n + reach) as f64).powi(grid.dim as i32);
        Cost {
            stencil: nodes * (STENCIL_PER_BOND * stencil.offsets as f64 + STENCIL_PER_NODE),
            fft: FFT_PER_POINT_LOG * points * points.log2(),
        }
    }
}

/// The backend `auto` runs: the FFT when the model predicts it faster, else the stencil.
pub fn choose(stencil: &Stencil) -> Backend {
    let cost = Cost::of(stencil);
    if cost.fft < cost.stencil {
        Backend::Fft
    } else {
        Backend::Stencil
    }
}
