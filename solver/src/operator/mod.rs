//! The discrete nonlocal operator L_h of eq. 2.1 behind one interface, with interchangeable backends.
//!
//! Every backend is planned once (neighbour lists, weights or transforms built) and then applied
//! every step without allocating. Each output value is computed by exactly one thread in a fixed
//! order, so the result does not depend on the thread count, bit for bit.

mod cost;
mod fft;
mod interface;
mod neighbour_list;
pub(crate) mod stencil;

pub use cost::{choose, Cost};
pub use fft::FftOperator;
pub use interface::NonlocalOperator;
pub use neighbour_list::NeighbourList;
pub use stencil::StencilOperator;

use crate::case::Backend;
use crate::discretization::stencil::Stencil;

impl Backend {
    /// The backend that runs: `Auto` made concrete by the cost model, the others as they are.
    pub fn resolve(self, stencil: &Stencil) -> Backend {
        match self {
            Backend::Auto => choose(stencil),
            concrete => concrete,
        }
    }
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
