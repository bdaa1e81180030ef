//! Embeds the solver's fingerprint (see build/fingerprint.rs) and the git revision it was built
//! from, for the provenance of every record.

use std::path::Path;
use std::process::Command;

#[path = "build/fingerprint.rs"]
mod fingerprint;

fn main() {
    embed_fingerprint();
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            // `git status` would otherwise refresh .git/index, which this script watches: the
            // next build would then compile the solver again for nothing.
            .env("GIT_OPTIONAL_LOCKS", "0")
            .output()
            .ok()
            .filter(|out| out.status.success())
            .map(|out| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    if let Some(revision) = git(&["rev-parse", "--short=12", "HEAD"]) {
        let dirty =
            git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
        let suffix = if dirty { "-dirty" } else { "" };
        println!("cargo:rustc-env=NLSOLVE_GIT_REVISION={revision}{suffix}");
    }
    if let Some(git_dir) = git(&["rev-parse", "--absolute-git-dir"]) {
        println!("cargo:rerun-if-changed={git_dir}/HEAD");
        println!("cargo:rerun-if-changed={git_dir}/index");
    }
    println!("cargo:rerun-if-changed=build.rs");
}

/// `NLSOLVE_FINGERPRINT`: the hash of the sources and of the build's settings.
fn embed_fingerprint() {
    let env = |name: &str| std::env::var(name).unwrap_or_default();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the solver crate lies in the workspace");
    let rustc = Command::new(env("RUSTC"))
        .arg("-vV")
        .output()
        .map(|out| String::from_utf8_lossy(&out.stdout).into_owned())
        .unwrap_or_default();
    let mut features: Vec<String> = std::env::vars()
        .filter_map(|(name, _)| name.strip_prefix("CARGO_FEATURE_").map(str::to_lowercase))
        .collect();
    features.sort();
    let settings = [
        ("rustc", rustc),
        ("target", env("TARGET")),
        ("target_features", env("CARGO_CFG_TARGET_FEATURE")),
        ("rustflags", env("CARGO_ENCODED_RUSTFLAGS")),
        ("profile", env("PROFILE")),
        ("opt_level", env("OPT_LEVEL")),
        ("features", features.join(",")),
    ];
    let hash = fingerprint::fingerprint(root, fingerprint::SOURCES, &settings);
    println!("cargo:rustc-env=NLSOLVE_FINGERPRINT={hash}");
    for source in fingerprint::SOURCES {
        println!("cargo:rerun-if-changed={}", root.join(source).display());
    }
}
