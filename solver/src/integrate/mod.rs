//! Time integration of du/dt = L u + b: the time loop with its measurements (`euler`) and the
//! time step a case runs with (`time_step`).

pub mod euler;
pub mod time_step;
