//! A run of any size streams: `unlag compensate` reads a recording in passes over its file and
//! writes each row as it is compensated, in memory that does not grow with the recording.
//! Shown without timing anything: a run of millions of rows compensated under an address-space
//! limit (`ulimit -v`, Linux) far below what holding it takes, which the command that holds
//! the run (`--adapt-to-run`) cannot pass.

#![allow(clippy::unwrap_used)]

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A scratch directory of one test of this binary (each test its own: they run in parallel).
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unlag-streaming-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn unlag(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .unwrap()
}

/// `unlag ARGS` under an address-space limit of `kib` KiB.
fn unlag_limited(kib: u64, args: &[&str]) -> Output {
    Command::new("/bin/sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .unwrap()
}

/// A run of `rows` rows at 10 kHz: steps every 4000 samples through a first-order probe, a
/// little deterministic noise on both channels.
fn write_run(path: &Path, rows: usize) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    writeln!(out, "t,u,y").unwrap();
    let mut y = 0.0f64;
    let mut seed = 12345u64;
    let mut noise = || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e-3
    };
    for k in 0..rows {
        let u = if (k / 4000) % 2 == 0 { 0.0 } else { 1.0 };
        y += 0.05 * (u - y);
        let (nu, ny) = (noise(), noise());
        writeln!(out, "{:.4},{:.5},{:.5}", k as f64 * 1e-4, u + nu, y + ny).unwrap();
    }
    out.flush().unwrap();
}

/// Lines of a file and its last line, read as it streams.
fn lines_and_last(path: &Path) -> (usize, String) {
    use std::io::BufRead as _;
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut count = 0;
    let mut last = String::new();
    for line in file.lines() {
        last = line.unwrap();
        count += 1;
    }
    (count, last)
}

/// 4 million rows (about 100 MB of CSV), compensated with a model whose compensator judges the
/// run by its own spectrum, under a 200 MB address-space limit: holding the run takes more
/// (its two signals alone are 64 MB, the output column and the rows' lines as much again,
/// about 45 bytes a row in all: 180 MB), and the command that holds it is refused for memory
/// under the same limit. Streamed, it writes every row, and on the first rows the same bytes
/// as a short run of those rows gives.
#[test]
fn a_run_of_millions_of_rows_is_compensated_in_bounded_memory() {
    if !cfg!(target_os = "linux") || !Path::new("/bin/sh").exists() {
        eprintln!("skipped: the address-space limit is Linux's");
        return;
    }
    let dir = scratch("millions");
    let tmp = |name: &str| dir.join(name);
    let rows = 4_000_000;
    let limit_kib = 150_000;
    let examples = format!("{}/examples/data", env!("CARGO_MANIFEST_DIR"));
    let model = tmp("m.toml");
    let o = unlag(&[
        "fit",
        &format!("{examples}/step_test_1.csv"),
        "-o",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let model_text = std::fs::read_to_string(&model).unwrap();
    assert!(
        model_text.contains("[inverse.noise]"),
        "the compensator should judge runs by their spectrum"
    );
    let run = tmp("run.csv");
    write_run(&run, rows);
    let out = tmp("out.csv");
    let (m, r, o_path) = (
        model.to_str().unwrap(),
        run.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let o = unlag_limited(limit_kib, &["compensate", m, r, "-o", o_path]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "streamed: {stderr}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains(&format!("compensated {rows} samples")),
        "{stdout}"
    );
    let (count, last) = lines_and_last(&out);
    assert_eq!(count, rows + 1);
    assert!(last.starts_with("399.9999,"), "{last}");

    // The run held in memory does not fit under the same limit: one clear line, no output.
    let held = tmp("held.csv");
    let h = held.to_str().unwrap();
    let o = unlag_limited(limit_kib, &["compensate", m, r, "-o", h, "--adapt-to-run"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "held: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("out of memory"), "{stderr}");
    assert!(!held.exists());

    // The first rows of the streamed output are what a short run of them gives: the
    // compensator is causal and the statistics only print.
    let short = tmp("short.csv");
    let text = std::fs::read_to_string(&run).unwrap_or_default();
    let head: String = text
        .lines()
        .take(20_001)
        .map(|l| format!("{l}\n"))
        .collect();
    drop(text);
    std::fs::write(&short, head).unwrap();
    let short_out = tmp("short_out.csv");
    let o = unlag(&[
        "compensate",
        m,
        short.to_str().unwrap(),
        "-o",
        short_out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let expected = std::fs::read_to_string(&short_out).unwrap();
    let file = std::io::BufReader::new(std::fs::File::open(&out).unwrap());
    use std::io::BufRead as _;
    for (a, b) in file.lines().zip(expected.lines()) {
        assert_eq!(a.unwrap(), b);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A pipe cannot be read twice: it is held, and gives the output the same run gives from a
/// file, byte for byte.
#[test]
fn a_piped_run_gives_what_the_file_gives() {
    if !cfg!(unix) || !Path::new("/bin/sh").exists() {
        eprintln!("skipped: no /bin/sh");
        return;
    }
    let examples = format!("{}/examples/data", env!("CARGO_MANIFEST_DIR"));
    let model = format!("{examples}/board_model.toml");
    let run = format!("{examples}/step_test_2.csv");
    let dir = scratch("pipe");
    let (piped, filed) = (dir.join("piped.csv"), dir.join("filed.csv"));
    let o = Command::new("/bin/sh")
        .arg("-c")
        .arg("cat \"$2\" | exec \"$0\" compensate \"$1\" /dev/stdin -o \"$3\"")
        .arg(env!("CARGO_BIN_EXE_unlag"))
        .arg(&model)
        .arg(&run)
        .arg(&piped)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = unlag(&["compensate", &model, &run, "-o", filed.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (
        std::fs::read(&piped).unwrap(),
        std::fs::read(&filed).unwrap(),
    );
    assert!(a.len() > 1000);
    assert!(a == b, "the piped run's output differs from the file's");
    let _ = std::fs::remove_dir_all(&dir);
}
