//! The discrete nonlocal operator L_h of eq. 2.1 behind one interface, with interchangeable backends.
//!
//! Every backend is planned once (neighbour lists, weights or transforms built) and then applied
//! every step without allocating. Each output value is computed by exactly one thread in a fixed
//! order, so the result does not depend on the thread count, bit for bit.

mod cost;
mod fft;
mod neighbour_list;
pub(crate) mod stencil;

pub use cost::{choose, Cost};
pub use fft::FftOperator;
pub use neighbour_list::NeighbourList;
pub use stencil::StencilOperator;

use crate::stencil::Stencil;
use serde::{Deserialize, Serialize};

/// Which implementation of L_h a case runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    /// The stencil or the FFT, whichever the calibrated cost model (`cost`) says is faster.
    #[default]
    Auto,
    /// Precomputed weights per lattice offset, register-blocked (uniform grids): O(N m^d).
    Stencil,
    /// Zero-padded FFT convolution with the weights (uniform grids): O(N log N) for any m.
    Fft,
    /// Algorithm 1 of seed 000 literally: a neighbour list per node, distances and J recomputed
    /// for every bond at every application. The oracle the fast backends are tested against.
    NeighbourList,
}

impl Backend {
    /// The backend that runs: `Auto` made concrete by the cost model, the others as they are.
    pub fn resolve(self, stencil: &Stencil) -> Backend {
        match self {
            Backend::Auto => choose(stencil),
            concrete => concrete,
        }
    }
}

pub trait NonlocalOperator: Send + Sync {
    /// out = L_h u on the nodes of D, with u = 0 on the collar (eq. 2.2).
    fn apply(&self, u: &[f64], out: &mut [f64]);
}

/// Plans the operator of `backend` (`Auto` resolved first) for the case whose grid, horizon,
/// kernel and weights `stencil` holds.
pub fn plan(backend: Backend, stencil: &Stencil) -> Box<dyn NonlocalOperator> {
    match backend.resolve(stencil) {
        Backend::Auto => unreachable!("resolve makes the backend concrete"),
        Backend::Stencil => Box::new(StencilOperator::new(stencil.clone())),
        Backend::Fft => Box::new(FftOperator::new(stencil)),
        Backend::NeighbourList => Box::new(NeighbourList::new(stencil)),
    }
}
