//! Outputs that outlive nothing: a run interrupted by SIGTERM, SIGINT or SIGHUP while it writes
//! a large output removes its temporary file, leaves the file that was there as it was, says so
//! in one line and exits with 128 + the signal's number.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]
#![cfg(unix)]

mod common;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The temporaries (`.unlag-*.partial`) in `dir`.
fn partials(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(".unlag-") && n.ends_with(".partial"))
        })
        .collect()
}

/// A probe recording of `rows` samples at the example model's 10 kHz.
fn recording(path: &Path, rows: usize) {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    writeln!(w, "t,y").unwrap();
    for k in 0..rows {
        let t = k as f64 * 1e-4;
        writeln!(w, "{t:.4},{:.5}", (t * 7.0).sin() + 0.3 * (t * 130.0).sin()).unwrap();
    }
    w.flush().unwrap();
}

/// Starts `unlag compensate` on a large recording over an earlier output, sends `signal`
/// (`TERM`, `INT`, `HUP`) once its temporary appears, and checks what is left.
fn interrupted_while_writing(signal: &str, number: i32) {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("run.csv");
    recording(&input, 3_000_000);
    let output = dir.path().join("out.csv");
    let earlier = "t,y,u_hat\n0,0,0\n";
    std::fs::write(&output, earlier).unwrap();
    let model = format!(
        "{}/examples/data/board_model.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let child = Command::new(env!("CARGO_BIN_EXE_unlag"))
        .arg("compensate")
        .arg(&model)
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for the temporary: the output is being written.
    let start = Instant::now();
    while partials(dir.path()).is_empty() {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no temporary appeared"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    let killed = Command::new("kill")
        .arg(format!("-{signal}"))
        .arg(child.id().to_string())
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    // Had the write finished before the signal, the test would prove nothing.
    assert_eq!(o.status.code(), Some(128 + number), "{stderr}");
    assert_eq!(
        stderr.lines().count(),
        1,
        "one line expected on stderr: {stderr}"
    );
    assert!(
        stderr.starts_with(&format!("error: interrupted by SIG{signal}: "))
            && stderr.contains("out.csv was not written"),
        "{stderr}"
    );
    assert!(
        partials(dir.path()).is_empty(),
        "{:?}",
        partials(dir.path())
    );
    assert_eq!(std::fs::read_to_string(&output).unwrap(), earlier);
}

#[test]
fn sigterm_while_writing_removes_the_temporary_and_keeps_the_old_output() {
    interrupted_while_writing("TERM", 15);
}

#[test]
fn sigint_while_writing_removes_the_temporary_and_keeps_the_old_output() {
    interrupted_while_writing("INT", 2);
}

#[test]
fn sighup_while_writing_removes_the_temporary_and_keeps_the_old_output() {
    interrupted_while_writing("HUP", 1);
}
