//! The README's commands run as written: every `unlag ...` line of its `sh` blocks, in order,
//! in a fresh directory holding the shipped example data, with the built binary as `unlag`.
//! A README that tells a newcomer something that fails fails here.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

/// The `unlag` lines of the README's `sh` blocks, trailing comments removed.
fn commands(readme: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in readme.lines() {
        let t = line.trim();
        if t.starts_with("```") {
            in_sh = !in_sh && t == "```sh";
            continue;
        }
        if in_sh && t.starts_with("unlag ") {
            let command = t.split("  #").next().unwrap_or(t).trim();
            out.push(command.to_string());
        }
    }
    out
}

#[test]
fn the_readme_commands_run_as_written() {
    let root = env!("CARGO_MANIFEST_DIR");
    let readme = std::fs::read_to_string(Path::new(root).join("README.md")).unwrap();
    let cmds = commands(&readme);
    assert!(
        cmds.len() >= 10,
        "the README's commands were not found: {cmds:?}"
    );
    let dir = std::env::temp_dir().join(format!("unlag-readme-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("src")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(Path::new(root).join("examples"), dir.join("examples")).unwrap();
    let bin = Path::new(env!("CARGO_BIN_EXE_unlag"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for c in &cmds {
        let o = Command::new("sh")
            .args(["-c", &format!("set -e; {c}")])
            .current_dir(&dir)
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "README command failed: {c}\n{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // What the first session promises is there.
    for f in [
        "probe.toml",
        "sim.csv",
        "compensated.csv",
        "report.html",
        "coefficients.bin",
    ] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
}
