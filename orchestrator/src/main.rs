//! `nlstudy`: runs studies of the nonlocal and local diffusion solvers. A study file expands to
//! cases; each case runs as an `nlsolve` process (or under mpirun) unless its record is already
//! stored; records are gathered into tables and figures. The work is done in the library
//! (`orchestrator::commands`, given the flags of `orchestrator::cli`); this is the process boundary.

use clap::Parser;
use orchestrator::cli::Cli;
use std::process::ExitCode;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    orchestrator::allocator::return_freed_memory_sooner();
    orchestrator::commands::main(Cli::parse())
}
