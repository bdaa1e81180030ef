//! Time integration of du/dt = L u + b: the timed loop every method shares (`timed`), the
//! right-hand side and the stepper interface (`stepper`), the step's measured growth per step
//! (`amplification`), the integrators (`euler`,
//! `runge_kutta`, `theta`) and the one a case names (`integrator`), what a run measured (`measure`) and the time step a case runs with
//! (`time_step`).

pub mod amplification;
pub mod checkpoint;
pub mod euler;
pub mod integrator;
pub mod measure;
pub mod progress;
pub mod runge_kutta;
pub mod spectra;
pub mod stepper;
pub mod theta;
pub mod time_step;
pub mod timed;
