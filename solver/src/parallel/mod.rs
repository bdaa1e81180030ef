//! Running one case over MPI ranks: how the nodes are divided (`partition`), what each rank
//! holds (`share`: its window, row runs and neighbours), the collectives and partner swaps the
//! methods need (`exchange`, over MPI in `world`), L_h on a rank's nodes with its ghost exchange (`operator`), a
//! whole-grid operator on a spread vector (`gathered`), and the 2D sine-transform preconditioner
//! on slabs of rows (`slab_sine`).

pub mod exchange;
pub mod gathered;
pub mod operator;
pub mod partition;
pub mod share;
pub mod slab_sine;
#[cfg(feature = "mpi")]
pub mod world;

/// Gives the pages of freed memory back to the system (glibc's `malloc_trim`). Under Open MPI,
/// whose memory hooks keep glibc from unmapping large blocks, a rank's set-up (the owner of
/// every node, its node list) would otherwise stay resident through the run as freed heap.
pub fn release_freed_memory() {
    #[cfg(all(feature = "mpi", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of the allocator's own heap to the kernel.
    unsafe {
        libc::malloc_trim(0);
    }
}
