//! The documentation's commands run as written, and its links lead somewhere.
//!
//! Every `unlag ...` line of the `sh` blocks of README.md and of each `docs/*.md` runs, in
//! order, in a fresh directory holding the shipped example data, with the built binary as
//! `unlag`. A guide that tells a newcomer something that fails fails here. Every relative
//! link of those files (`[text](path)`) must name a file or directory of the repository.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// README.md and every `docs/*.md`, in a fixed order.
fn documents() -> Vec<PathBuf> {
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    docs.sort();
    docs.insert(0, root().join("README.md"));
    docs
}

/// The `unlag` lines of a document's `sh` blocks, trailing comments removed.
fn commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in text.lines() {
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

/// Runs `cmds` in order in a fresh directory named after `name`, which holds `examples/`
/// (the repository's), an empty `src/`, and `step.csv` and `run.csv` (the shipped step tests,
/// standing for the reader's own recordings). Returns the directory.
fn run_in_fresh_dir(name: &str, cmds: &[String]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unlag-doc-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("src")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(root().join("examples"), dir.join("examples")).unwrap();
    let data = root().join("examples/data");
    std::fs::copy(data.join("step_test_1.csv"), dir.join("step.csv")).unwrap();
    std::fs::copy(data.join("step_test_2.csv"), dir.join("run.csv")).unwrap();
    let bin = Path::new(env!("CARGO_BIN_EXE_unlag"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for c in cmds {
        let o = Command::new("sh")
            .args(["-c", &format!("set -e; {c}")])
            .current_dir(&dir)
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{name}: command failed: {c}\n{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    dir
}

#[test]
fn the_readme_commands_run_as_written() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let cmds = commands(&readme);
    assert!(
        cmds.len() >= 10,
        "the README's commands were not found: {cmds:?}"
    );
    let dir = run_in_fresh_dir("README", &cmds);
    // What the tour promises is there.
    for f in [
        "probe.toml",
        "sim.csv",
        "compensated.csv",
        "report.html",
        "coefficients.bin",
    ] {
        assert!(dir.join(f).is_file(), "{f} not written");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_guides_commands_run_as_written() {
    let mut ran = 0;
    for doc in documents().into_iter().skip(1) {
        let text = std::fs::read_to_string(&doc).unwrap();
        let cmds = commands(&text);
        if cmds.is_empty() {
            continue;
        }
        let name = doc.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = run_in_fresh_dir(&name, &cmds);
        let _ = std::fs::remove_dir_all(&dir);
        ran += cmds.len();
    }
    assert!(ran >= 10, "the guides' commands were not found ({ran})");
}

/// The targets of a document's markdown links `[text](target)` outside fenced code blocks.
fn link_targets(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        let mut rest = line;
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let Some(end) = after.find(')') else { break };
            out.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    out
}

/// `path` (under the repository's root) as a path from the root, `..` resolved:
/// `ROOT/docs/../README.md` is `README.md`.
fn from_root(path: &Path) -> String {
    let mut parts: Vec<String> = Vec::new();
    for c in path.strip_prefix(root()).unwrap_or(path).components() {
        match c {
            std::path::Component::ParentDir => {
                parts.pop();
            }
            std::path::Component::Normal(p) => parts.push(p.to_string_lossy().into_owned()),
            _ => {}
        }
    }
    parts.join("/")
}

#[test]
fn every_relative_link_in_the_documentation_leads_to_a_file() {
    let mut checked = 0;
    let mut broken = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        let base = doc.parent().unwrap();
        for target in link_targets(&text) {
            let external = ["http://", "https://", "mailto:", "#"]
                .iter()
                .any(|p| target.starts_with(p));
            if external {
                continue;
            }
            let path = target.split('#').next().unwrap_or("");
            let resolved = base.join(path);
            checked += 1;
            if !resolved.exists() {
                broken.push(format!("{}: {target}", doc.display()));
            }
        }
    }
    assert!(checked >= 10, "too few links found ({checked})");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn link_targets_are_found_outside_code() {
    let text = "see [a](docs/a.md) and ![b](img.png#x)\n```sh\n[c](no.md)\n```\n[d](#top)";
    assert_eq!(link_targets(text), ["docs/a.md", "img.png#x", "#top"]);
    assert_eq!(from_root(&root().join("docs/../README.md")), "README.md");
    assert_eq!(from_root(&root().join("docs/cli.md")), "docs/cli.md");
}
