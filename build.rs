//! Sets `OGM_GIT_COMMIT` (the short commit, or "unknown" without git) for `ogm-corners bench` records.

use std::path::Path;
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=OGM_GIT_COMMIT={commit}");
    // Rerun only when HEAD moves (a checkout, or a commit on the current branch), not on every source edit.
    // Only existing paths: Cargo reruns on every build for a path that does not exist.
    println!("cargo:rerun-if-changed=build.rs");
    let head = Path::new(".git/HEAD");
    if head.is_file() {
        println!("cargo:rerun-if-changed=.git/HEAD");
        if let Some(r) = std::fs::read_to_string(head)
            .ok()
            .and_then(|s| s.strip_prefix("ref: ").map(|r| r.trim().to_string()))
        {
            let loose = Path::new(".git").join(r);
            if loose.is_file() {
                println!("cargo:rerun-if-changed={}", loose.display());
            }
        }
    }
}
