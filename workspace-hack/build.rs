// Empty: a build script is required for cargo to consider `[build-dependencies]` (as in the
// workspace-hack crates cargo-hakari writes), whose features unify with the host's.
fn main() {}
