//! The Python package (`python/`): built into a virtual environment with maturin and its
//! pytest suite run (`python/tests`: the API, its errors, and the same models, model files,
//! messages and `u_hat` bit for bit as this build's `unlag` binary).
//!
//! The environment is `target/py-venv` (or `$UNLAG_PYTHON_VENV`) with maturin, numpy and
//! pytest in it; create it once with
//! `python3 -m venv target/py-venv && target/py-venv/bin/pip install maturin numpy pytest`.
//! Without it the test is skipped with that message, unless `UNLAG_REQUIRE_PYTHON=1`
//! (`.ci/run` sets it, after making the environment), which turns a missing one into a failure.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn required() -> bool {
    std::env::var("UNLAG_REQUIRE_PYTHON").is_ok_and(|v| v == "1")
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A missing prerequisite: skipped with `why` and what to do, or a failure when required.
fn skip(why: &str) {
    let how =
        "python3 -m venv target/py-venv && target/py-venv/bin/pip install maturin numpy pytest";
    assert!(
        !required(),
        "UNLAG_REQUIRE_PYTHON=1 but {why}; create the environment with: {how}"
    );
    eprintln!("SKIPPED the Python package's tests: {why}; to run them, create the environment once with: {how}");
}

/// The virtual environment's `bin` directory (`Scripts` on Windows).
fn bin(venv: &Path) -> PathBuf {
    if cfg!(windows) {
        venv.join("Scripts")
    } else {
        venv.join("bin")
    }
}

#[test]
fn the_python_package_passes_its_tests() {
    let venv = std::env::var_os("UNLAG_PYTHON_VENV")
        .map_or_else(|| root().join("target").join("py-venv"), PathBuf::from);
    let python = bin(&venv).join(if cfg!(windows) {
        "python.exe"
    } else {
        "python"
    });
    let maturin = bin(&venv).join(if cfg!(windows) {
        "maturin.exe"
    } else {
        "maturin"
    });
    if !python.exists() || !maturin.exists() {
        return skip(&format!(
            "there is no Python environment with maturin at {}",
            venv.display()
        ));
    }
    let has = Command::new(&python)
        .args(["-c", "import numpy, pytest"])
        .output()
        .expect("the environment's python runs");
    if !has.status.success() {
        return skip(&format!(
            "numpy or pytest is missing from {}: {}",
            venv.display(),
            String::from_utf8_lossy(&has.stderr).trim()
        ));
    }
    // Built with the test profile's optimisation (`python-test`: no LTO, the release
    // profile's fat LTO takes minutes) in a target directory of its own (the outer
    // `cargo test` may hold the main one's lock), and installed into the environment.
    let target_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("python");
    let out = Command::new(&maturin)
        .current_dir(root())
        .args(["develop", "--quiet", "--profile", "python-test", "-m"])
        .arg(root().join("python").join("Cargo.toml"))
        .arg("--target-dir")
        .arg(&target_dir)
        .env("VIRTUAL_ENV", &venv)
        .env_remove("CONDA_PREFIX")
        .env_remove("RUSTFLAGS")
        .output()
        .expect("maturin runs");
    assert!(
        out.status.success(),
        "maturin develop failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    run_pytest(&python);
}

/// Runs `python/tests` with the environment's `python`, against this build's `unlag`.
fn run_pytest(python: &Path) {
    let out = Command::new(python)
        .current_dir(root().join("python"))
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"])
        .env("UNLAG_CLI", env!("CARGO_BIN_EXE_unlag"))
        .output()
        .expect("pytest runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}");
    assert!(
        out.status.success(),
        "the Python package's tests failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Every test ran: none skipped for want of the command line.
    assert!(
        !stdout.contains("skipped"),
        "pytest skipped tests:\n{stdout}"
    );
}
