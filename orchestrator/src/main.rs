//! `nlstudy`: the study orchestrator. Its issue has not landed yet; until then this binary says so,
//! and the README's main job runs a demonstration case with `nlsolve` directly.

fn main() {
    eprintln!(
        "nlstudy is not built yet: run one case with `nlsolve run --case FILE` (see README.md)."
    );
    std::process::exit(2);
}
