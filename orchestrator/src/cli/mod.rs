//! The command line: its flags (`args`), parsed by clap; `commands` runs them.

pub mod args;

pub use args::Cli;
