//! The discrete nonlocal operator's ingredients on the uniform grid of D = [0,1]^d: the grid and
//! the horizon, the influence function and its moments, the quadrature's bond volumes, the
//! stencil of weights they make, and the stable time step its symbol gives; and a horizon that
//! varies along D (\[LSSM]) with its two formulations.

pub mod finite_element;
pub mod grid;
pub mod influence;
pub mod quadrature;
pub mod stability;
pub mod stencil;
pub mod variable_horizon;
