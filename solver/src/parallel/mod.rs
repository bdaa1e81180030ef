//! Running one case over MPI ranks: how the nodes are divided (`partition`), what each rank
//! holds (`subdomain`), the ghost values it exchanges every step (`halo`), and the collectives
//! and partner swaps the methods need (`exchange`).

pub mod exchange;
pub mod halo;
pub mod partition;
pub mod subdomain;
