//! The discrete nonlocal operator L_h of eq. 2.1 behind one interface, with interchangeable backends.
//!
//! Every backend is planned once (neighbour lists, weights or transforms built) and then applied
//! every step without allocating. Each output value is computed by exactly one thread in a fixed
//! order, so the result does not depend on the thread count, bit for bit.

mod cost;
mod fft;
mod linear;
mod neighbour_list;
mod rows;
pub(crate) mod sine;
pub(crate) mod stencil;

pub use cost::{choose, Cost};
pub use fft::FftOperator;
pub use linear::{Identity, LinearOperator};
pub use neighbour_list::NeighbourList;
pub use rows::RowOperator;
pub use sine::SinePreconditioner;
pub use stencil::{InstructionSet, StencilOperator};

use crate::case::Backend;
use crate::discretization::stencil::Stencil;

/// The backend that runs: `Auto` made concrete by the cost model, the others as they are.
pub fn resolve(backend: Backend, stencil: &Stencil) -> Backend {
    match backend {
        Backend::Auto => choose(stencil),
        concrete => concrete,
    }
}

/// The operator of one backend, planned for a case.
pub enum Planned {
    Stencil(StencilOperator),
    Fft(FftOperator),
    NeighbourList(NeighbourList),
}

/// The workspace of a `Planned` operator: its backend's.
pub enum PlannedWorkspace {
    Stencil(<StencilOperator as LinearOperator>::Workspace),
    Fft(<FftOperator as LinearOperator>::Workspace),
    NeighbourList,
}

/// Plans the operator of `backend` (`Auto` resolved first) for the case whose grid, horizon,
/// kernel and weights `stencil` holds.
pub fn plan(backend: Backend, stencil: &Stencil) -> Planned {
    match resolve(backend, stencil) {
        Backend::Auto => unreachable!("resolve makes the backend concrete"),
        Backend::Stencil => Planned::Stencil(StencilOperator::new(stencil)),
        Backend::Fft => Planned::Fft(FftOperator::new(stencil)),
        Backend::NeighbourList => Planned::NeighbourList(NeighbourList::new(stencil)),
    }
}

impl LinearOperator for Planned {
    type Workspace = PlannedWorkspace;

    fn workspace(&self) -> PlannedWorkspace {
        match self {
            Planned::Stencil(op) => PlannedWorkspace::Stencil(op.workspace()),
            Planned::Fft(op) => PlannedWorkspace::Fft(op.workspace()),
            Planned::NeighbourList(_) => PlannedWorkspace::NeighbourList,
        }
    }

    fn apply(&self, u: &[f64], out: &mut [f64], workspace: &mut PlannedWorkspace) {
        match (self, workspace) {
            (Planned::Stencil(op), PlannedWorkspace::Stencil(ws)) => op.apply(u, out, ws),
            (Planned::Fft(op), PlannedWorkspace::Fft(ws)) => op.apply(u, out, ws),
            (Planned::NeighbourList(op), PlannedWorkspace::NeighbourList) => {
                op.apply(u, out, &mut ())
            }
            _ => panic!("a workspace is applied with the operator that made it"),
        }
    }
}
