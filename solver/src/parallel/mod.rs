//! Running one case over MPI ranks: how the nodes are divided (`partition`), what each rank
//! holds (`share`: its window, row runs and neighbours), the collectives and partner swaps the methods need (`exchange`), and L_h
//! on a rank's nodes with its ghost exchange (`operator`).

pub mod exchange;
pub mod operator;
pub mod partition;
pub mod share;
