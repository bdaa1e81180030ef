//! Time integration of du/dt = L u + b: the timed loop every method shares (`timed`), forward
//! Euler (`euler`), what a run measured (`measure`) and the time step a case runs with
//! (`time_step`).

pub mod euler;
pub mod measure;
pub mod time_step;
pub mod timed;
