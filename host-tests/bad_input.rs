//! The bad-input matrix: every command that reads a file, given every kind of bad file, and
//! every writer given an output that would lose something. Each case must end with exit 1 (2
//! for a usage error), one `error:` line on stderr (and, with `--json`, one JSON object on
//! stdout), no panic or abort, no output written, and every input byte for byte as it was.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;
use common::{data, unlag};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("unlag-bad-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn tmp(name: &str) -> String {
    dir().join(name).to_str().unwrap().to_string()
}

/// A good model of the shipped line test, fitted once.
fn good_model() -> &'static str {
    static MODEL: OnceLock<String> = OnceLock::new();
    MODEL.get_or_init(|| {
        let path = tmp("good.toml");
        let o = unlag(&["fit", &data("line_est.csv"), "--order", "2", "-o", &path]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        path
    })
}

fn digest(path: &str) -> Option<Vec<u8>> {
    std::fs::read(path).ok()
}

/// Runs `args` and checks the refusal: exit `code`, one `error:` line naming `expect`, no
/// panic, `output` not created, inputs unchanged; then again with `--json` and checks that
/// stdout is one JSON object with the error's kind.
fn refuses(args: &[&str], output: Option<&str>, expect: &str) {
    let inputs: Vec<(String, Option<Vec<u8>>)> = args
        .iter()
        .filter(|a| Path::new(a).is_file())
        .map(|a| (a.to_string(), digest(a)))
        .collect();
    for json in [false, true] {
        let mut argv = args.to_vec();
        if json {
            argv.push("--json");
        }
        let o = unlag(&argv);
        let stdout = String::from_utf8_lossy(&o.stdout);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let what = format!("unlag {}: {stdout}{stderr}", argv.join(" "));
        assert_eq!(o.status.code(), Some(1), "{what}");
        assert!(!stderr.contains("panicked"), "{what}");
        assert_eq!(stderr.lines().count(), 1, "one line expected: {what}");
        assert!(stderr.starts_with("error: "), "{what}");
        assert!(stderr.contains(expect), "expected '{expect}': {what}");
        assert!(
            !stderr.contains(".tmp") && !stderr.contains(".partial"),
            "{what}"
        );
        if json {
            let v: serde_json::Value = serde_json::from_str(stdout.trim())
                .unwrap_or_else(|e| panic!("--json error is not JSON ({e}): {what}"));
            assert!(v["error"]["kind"].is_string(), "{what}");
            assert!(
                v["error"]["message"].as_str().unwrap().contains(expect),
                "{what}"
            );
        }
        if let Some(out) = output {
            let existed = inputs.iter().any(|(p, _)| p == out);
            assert!(
                existed || !Path::new(out).exists(),
                "output written: {what}"
            );
        }
        for (p, before) in &inputs {
            assert_eq!(&digest(p), before, "input {p} changed: {what}");
        }
    }
}

/// Every command that reads a CSV, with `csv` in the place of its test file.
fn csv_readers(csv: &str, expect: &str) {
    let m = good_model();
    let out = tmp("out.csv");
    let html = tmp("out.html");
    let toml = tmp("out.toml");
    refuses(&["fit", csv, "-o", &toml], Some(&toml), expect);
    refuses(&["compensate", m, csv, "-o", &out], Some(&out), expect);
    refuses(&["simulate", m, csv, "-o", &out], Some(&out), expect);
    refuses(&["invert", m, csv, "-o", &toml], Some(&toml), expect);
    refuses(&["compare", m, csv], None, expect);
    refuses(&["diagnose", m, csv], None, expect);
    refuses(&["report", m, csv, "-o", &html], Some(&html), expect);
}

#[test]
fn every_csv_reader_refuses_every_bad_trace() {
    // (file, what the message must say): the shipped bad traces.
    let cases = [
        ("empty.csv", "the file is empty"),
        ("header_only.csv", "the file is empty"),
        ("missing_column.csv", "missing column"),
        ("not_a_number.csv", "is not a number"),
        ("not_finite.csv", "is not finite"),
        ("backwards.csv", "does not increase"),
        ("jitter.csv", "jitter"),
        ("ragged.csv", "bad/ragged.csv:"),
        ("clipped.csv", "looks clipped"),
    ];
    for (file, expect) in cases {
        csv_readers(&data(&format!("bad/{file}")), expect);
    }
    // Not there at all.
    csv_readers(&tmp("nothere.csv"), "nothere.csv: cannot read");
}

#[test]
fn a_test_whose_reference_does_not_move_is_refused_where_tests_judge_the_model() {
    // Noise alone on the reference: no step, no change.
    let mut s = String::from("t,u,y\n");
    let mut state = 11u64;
    for k in 0..2000 {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let n = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        s.push_str(&format!(
            "{},{},{}\n",
            k as f64 * 1e-4,
            1.0 + 1e-3 * n,
            1.0 - 1e-3 * n
        ));
    }
    let flat = tmp("flat.csv");
    std::fs::write(&flat, s).unwrap();
    let m = good_model();
    let toml = tmp("flat-out.toml");
    let html = tmp("flat-out.html");
    let expect = "does not move above its noise";
    refuses(
        &["fit", &data("line_est.csv"), &flat, "-o", &toml],
        Some(&toml),
        expect,
    );
    refuses(&["invert", m, &flat, "-o", &toml], Some(&toml), expect);
    refuses(&["compare", m, &flat], None, expect);
    refuses(&["report", m, &flat, "-o", &html], Some(&html), expect);
    // Compensating such a run is ordinary work; only the verdict against its reference is
    // withheld.
    let out = tmp("flat-out.csv");
    let o = unlag(&["compensate", m, &flat, "-o", &out]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}");
    // (The run's own spectrum may still choose its compensator, and say so: that needs no
    // reference.)
    assert!(
        stdout.contains(expect) && !stdout.contains("error against the recorded reference"),
        "{stdout}"
    );
}

/// Every command that reads a model file, with `model` in its place.
fn model_readers(model: &str, expect: &str) {
    let csv = data("line_val.csv");
    let out = tmp("m-out.csv");
    let toml = tmp("m-out.toml");
    let html = tmp("m-out.html");
    let code = tmp("m-out.h");
    refuses(&["inspect", model], None, expect);
    refuses(
        &["resample", model, "--fs", "20000", "-o", &toml],
        Some(&toml),
        expect,
    );
    refuses(
        &["export", model, "--format", "c", "-o", &code],
        Some(&code),
        expect,
    );
    refuses(&["compensate", model, &csv, "-o", &out], Some(&out), expect);
    refuses(&["simulate", model, &csv, "-o", &out], Some(&out), expect);
    refuses(&["invert", model, &csv, "-o", &toml], Some(&toml), expect);
    refuses(&["compare", model, &csv], None, expect);
    refuses(&["diagnose", model, &csv], None, expect);
    refuses(&["report", model, &csv, "-o", &html], Some(&html), expect);
    refuses(
        &[
            "predict", "--line", "0.5,1e-3", "--volume", "1e-8", "--model", model,
        ],
        None,
        expect,
    );
}

/// A copy of the good model with the line starting `prefix` replaced by `line`; the path and
/// the line's number.
fn model_line(name: &str, prefix: &str, line: &str) -> (String, usize) {
    let text = std::fs::read_to_string(good_model()).unwrap();
    let at = text.lines().position(|l| l.starts_with(prefix)).unwrap();
    let lines: Vec<&str> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i == at { line } else { l })
        .collect();
    let path = tmp(name);
    std::fs::write(&path, lines.join("\n")).unwrap();
    (path, at + 1)
}

#[test]
fn every_model_reader_refuses_every_bad_model_naming_line_and_column() {
    // A value out of its limits, named with its own line and column.
    for (name, prefix, line, column, expect) in [
        (
            "delay.toml",
            "delay = ",
            "delay = 4000000000",
            9,
            "delay 4000000000 samples",
        ),
        (
            "fs.toml",
            "fs = ",
            "fs = -1.0",
            6,
            "fs must be a sample rate",
        ),
        (
            "gain.toml",
            "gain = ",
            "gain = nan",
            8,
            "inverse.gain = NaN is not a finite number",
        ),
        (
            "version.toml",
            "format_version = ",
            "format_version = 7",
            18,
            "format_version 7",
        ),
        ("type.toml", "fs = ", "fs = \"ten\"", 6, "invalid type"),
    ] {
        let (path, n) = model_line(name, prefix, line);
        model_readers(&path, &format!("{name}:{n}:{column}: {expect}"));
    }
    // A misspelt field, refused with the nearest known name, at its line.
    let (path, n) = model_line("dlay.toml", "delay = ", "dlay = 3");
    model_readers(&path, &format!("dlay.toml:{n}:1: unknown field `dlay`"));
    model_readers(&path, "did you mean `delay`?");
    let (path, _) = model_line("lowpas.toml", "lowpass_hz = ", "lowpas_hz = 100.0");
    model_readers(&path, "did you mean `lowpass_hz`?");
    let (path, _) = model_line("syntax.toml", "a = [", "a = [[,");
    model_readers(&path, "syntax.toml:");
    // An unstable stored compensator.
    let (unstable, n) = model_line(
        "unstable.toml",
        "sections = ",
        "sections = [[1.0, 0.0, 0.0, -2.5, 1.5]]",
    );
    model_readers(
        &unstable,
        &format!("unstable.toml:{n}:12: the stored compensator cannot run"),
    );
    // Not a model at all: a CSV, random bytes, nothing there.
    model_readers(&data("line_est.csv"), "line_est.csv:1:");
    let garbage = tmp("garbage.toml");
    std::fs::write(&garbage, [0xff, 0xfe, 0x00, 0x12, 0x80]).unwrap();
    model_readers(&garbage, "garbage.toml");
    model_readers(&tmp("nothere.toml"), "nothere.toml: cannot read");
}

#[test]
fn a_corrupted_blob_gets_the_board_parsers_error() {
    let blob = tmp("good.bin");
    let o = unlag(&["export", good_model(), "--format", "bin", "-o", &blob]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = unlag(&["inspect", &blob]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && stdout.contains("a valid coefficient blob"),
        "{stdout}"
    );
    let good = std::fs::read(&blob).unwrap();
    let mut flipped = good.clone();
    flipped[30] ^= 0x01;
    let bad = tmp("flipped.bin");
    std::fs::write(&bad, &flipped).unwrap();
    refuses(&["inspect", &bad], None, "CRC-32");
    let cut = tmp("cut.bin");
    std::fs::write(&cut, &good[..good.len() - 3]).unwrap();
    refuses(&["inspect", &cut], None, "truncated");
}

#[test]
fn no_output_may_destroy_an_input() {
    let m = good_model();
    let csv = tmp("keep.csv");
    std::fs::copy(data("line_val.csv"), &csv).unwrap();
    let msg = "this output is the input";
    refuses(&["fit", &csv, "-o", &csv], None, msg);
    refuses(&["compensate", m, &csv, "-o", &csv], None, msg);
    refuses(&["simulate", m, &csv, "-o", &csv], None, msg);
    refuses(&["compensate", m, &csv, "-o", m], None, msg);
    refuses(&["report", m, &csv, "-o", m], None, msg);
    refuses(&["export", m, "--format", "c", "-o", m], None, msg);
    refuses(&["resample", m, "--fs", "20000", "-o", m], None, msg);
    refuses(&["diagnose", m, &csv, "--report", &csv], None, msg);
    // The report of a fit may not replace the model it writes, existing or not.
    let fresh = tmp("not-yet-written.toml");
    let _ = std::fs::remove_file(&fresh);
    refuses(&["fit", &csv, "-o", &fresh, "--report", &fresh], None, msg);
    // ... while a refit onto its own model, with a report, goes through again and again.
    let (model, page) = (tmp("refit.toml"), tmp("refit.html"));
    for _ in 0..2 {
        let o = unlag(&["fit", &csv, "-o", &model, "--report", &page]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // Through a symbolic link too.
    #[cfg(unix)]
    {
        let link = tmp("link-to-keep.csv");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&csv, &link).unwrap();
        refuses(&["simulate", m, &csv, "-o", &link], None, msg);
    }
    // A file in the way of `fit -o` that is not a model is not replaced.
    let other = tmp("other.csv");
    std::fs::copy(data("line_est.csv"), &other).unwrap();
    refuses(
        &["fit", &csv, "--order", "2", "--fresh", "-o", &other],
        None,
        "is not a model file (not TOML)",
    );
    refuses(
        &["fit", &csv, "--order", "2", "-o", &other],
        None,
        "is not a model this fit can continue",
    );
}

#[cfg(unix)]
#[test]
fn outputs_follow_the_umask_keep_a_files_mode_and_a_links_target() {
    use std::os::unix::fs::PermissionsExt as _;
    let m = good_model();
    let csv = data("line_val.csv");
    let bin = env!("CARGO_BIN_EXE_unlag");
    let mode = |p: &str| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    // A new file: 0666 less the umask.
    let new = tmp("umask.csv");
    let _ = std::fs::remove_file(&new);
    let o = Command::new("sh")
        .args([
            "-c",
            &format!("umask 027 && exec '{bin}' simulate '{m}' '{csv}' -o '{new}'"),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(mode(&new), 0o640);
    // An existing file keeps its mode.
    std::fs::set_permissions(&new, std::fs::Permissions::from_mode(0o664)).unwrap();
    let o = unlag(&["simulate", m, &csv, "-o", &new]);
    assert!(o.status.success());
    assert_eq!(mode(&new), 0o664);
    // A link stays a link; the file it names is written.
    let target = tmp("target.csv");
    let link = tmp("link.csv");
    let _ = std::fs::remove_file(&link);
    // An earlier output of simulate, recognised through the link (another file is refused).
    let old = "t,u,y,y_model\n0,0,0,0\n";
    std::fs::write(&target, old).unwrap();
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let o = unlag(&["simulate", m, &csv, "-o", &link]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_ne!(std::fs::read_to_string(&target).unwrap(), old);
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read_to_string(&target)
        .unwrap()
        .starts_with("t,u,y,y_model"));
    // A device is written in place, never replaced: /dev/null stays a device.
    let o = unlag(&["simulate", m, &csv, "-o", "/dev/null"]);
    assert!(o.status.success());
    assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
}

#[test]
fn dash_is_standard_output_and_a_full_device_is_an_error() {
    let m = good_model();
    let csv = data("line_val.csv");
    let o = unlag(&["compensate", m, &csv, "-o", "-"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.starts_with("t,u,y,u_hat\n"),
        "{}",
        &stdout[..stdout.len().min(200)]
    );
    // The command's own text went to stderr, out of the data's way.
    assert!(String::from_utf8_lossy(&o.stderr).contains("wrote"));
    assert!(!Path::new("-").exists());
    // `--json` wants standard output too: refused, as JSON.
    let o = unlag(&["compensate", m, &csv, "-o", "-", "--json"]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["error"]["kind"], "invalid-argument");
    if Path::new("/dev/full").exists() {
        // Output and standard output on a full device: an error, never a panic.
        refuses(
            &["simulate", m, &csv, "-o", "/dev/full"],
            None,
            "No space left",
        );
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(["inspect", m])
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("cannot write to standard output"),
            "{stderr}"
        );
        // Help on a full standard output: an error too, not a silent success.
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .arg("--help")
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1));
        // A full standard error: the error has nowhere to go, but the exit status says it.
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(["inspect", "nothere.toml"])
            .stderr(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1));
    }
    // A directory that is not there is named, not a temporary file.
    let out = dir().join("no/such/dir/x.csv");
    refuses(
        &["simulate", m, &csv, "-o", out.to_str().unwrap()],
        None,
        "does not exist",
    );
}

#[test]
fn refitting_into_a_model_says_what_it_keeps_and_the_order_given_wins() {
    let model = tmp("loop.toml");
    let _ = std::fs::remove_file(&model);
    let est = data("line_est.csv");
    let o = unlag(&["fit", &est, "--order", "2", "--add", "mode", "-o", &model]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = unlag(&["fit", &est, "--order", "2", "-o", &model]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("continuing")
            && stdout.contains("dropped because --order is given")
            && stdout.contains("each `--add mode` names one again"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&model).unwrap();
    let a_line = text.lines().find(|l| l.starts_with("a = ")).unwrap();
    assert_eq!(
        a_line.matches(',').count() + 1,
        2,
        "order 2 asked: {a_line}"
    );
    // A mode named again in the refit keeps the model's order, and needs no hint.
    let o = unlag(&["fit", &est, "--order", "2", "--add", "mode", "-o", &model]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = unlag(&["fit", &est, "--order", "2", "--add", "mode", "-o", &model]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("1 mode effect(s) dropped because --order is given")
            && !stdout.contains("names one again"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&model).unwrap();
    let a_line = text.lines().find(|l| l.starts_with("a = ")).unwrap();
    assert_eq!(
        a_line.matches(',').count() + 1,
        4,
        "order 2 and a mode: {a_line}"
    );
}

#[test]
fn numbers_out_of_range_on_the_command_line_are_refused_quickly() {
    let m = good_model();
    let est = data("line_est.csv");
    let toml = tmp("range.toml");
    let csv = tmp("range.csv");
    refuses(
        &["resample", m, "--fs", "1e300", "-o", &toml],
        Some(&toml),
        "--fs",
    );
    refuses(
        &["fit", &est, "--fs", "1e300", "-o", &toml],
        Some(&toml),
        "--fs",
    );
    refuses(
        &["inspect", m, "--grid", "1:100:100000000"],
        None,
        "N may be at most",
    );
    refuses(
        &[
            "fit",
            &est,
            "--order",
            "2",
            "--delay",
            "4000000000",
            "-o",
            &toml,
        ],
        Some(&toml),
        "too short",
    );
    refuses(
        &[
            "simulate-test",
            "--line",
            "1e6,1e-3",
            "--volume",
            "1e-8",
            "--excitation",
            "valve",
            "--fs",
            "10000",
            "--duration",
            "0.05",
            "-o",
            &csv,
        ],
        Some(&csv),
        "the lines add up to",
    );
    refuses(
        &[
            "simulate-test",
            "--line",
            "0.5,1e-3",
            "--volume",
            "1e-8",
            "--excitation",
            "valve",
            "--fs",
            "1e9",
            "--duration",
            "1",
            "-o",
            &csv,
        ],
        Some(&csv),
        "need 2 to 10 million",
    );
}

/// A usage error with `--json` names what is missing in its JSON message, not only on stderr
/// (clap lists missing arguments on the lines after its first).
#[test]
fn a_usage_error_as_json_names_the_missing_argument() {
    let o = unlag(&["predict", "--line", "0.1,0.0005", "--json"]);
    assert_eq!(o.status.code(), Some(2));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["error"]["kind"], "usage");
    let message = v["error"]["message"].as_str().unwrap();
    assert!(message.contains("--volume"), "{message}");
    assert!(
        !message.contains("Usage:") && !message.contains('\n'),
        "{message}"
    );
}

/// A line without end (`/dev/zero`) given as the trace, the test or a `--signal` run, under a
/// 3 GB address-space limit: one error line naming the file and line, never the allocator's
/// abort (the CSV reader's buffer used to double until it asked for 4 GiB), and no output.
#[test]
fn an_endless_line_is_refused_under_a_memory_limit() {
    if !Path::new("/dev/zero").exists() || !Path::new("/bin/bash").exists() {
        eprintln!("skipped: no /dev/zero or no bash");
        return;
    }
    let examples = format!("{}/examples/data", env!("CARGO_MANIFEST_DIR"));
    let model = format!("{examples}/board_model.toml");
    let step = format!("{examples}/step_test_1.csv");
    let (csv, toml) = (tmp("zero.csv"), tmp("zero.toml"));
    let cases: [(&[&str], &str); 3] = [
        (&["compensate", &model, "/dev/zero", "-o", &csv], &csv),
        (&["fit", "/dev/zero", "-o", &toml], &toml),
        (&["fit", &step, "--signal", "/dev/zero", "-o", &toml], &toml),
    ];
    for (args, output) in cases {
        let o = Command::new("/bin/bash")
            .arg("-c")
            .arg("ulimit -v 3000000 && exec \"$0\" \"$@\"")
            .arg(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        let what = format!("unlag {}: {stderr}", args.join(" "));
        assert_eq!(o.status.code(), Some(1), "{what}");
        assert_eq!(stderr.lines().count(), 1, "one line expected: {what}");
        assert_eq!(
            stderr.trim_end(),
            "error: /dev/zero:1: line 1 is longer than 1 MiB: a row of numbers is a few hundred \
             bytes; is this a text CSV file?",
            "{what}"
        );
        assert!(!Path::new(output).exists(), "output written: {what}");
    }
}

/// A step test at 10 kHz (400 rows, a first-order response), written to `name` with the
/// header `header`, fields joined by `sep`, time multiplied by `time_scale`, and decimal
/// commas when `comma`.
fn step_file(name: &str, header: &str, sep: &str, time_scale: f64, comma: bool) -> String {
    let mut s = format!("{header}\n");
    for k in 0..400 {
        let u = if k < 100 { 0.0 } else { 1.0 };
        let y = if k < 100 {
            0.0
        } else {
            1.0 - (-(f64::from(k) - 100.0) / 5.0).exp()
        };
        let t = f64::from(k) * 1e-4 * time_scale;
        let row = [format!("{t:.9}"), format!("{u}"), format!("{y:.6}")]
            .map(|f| if comma { f.replace('.', ",") } else { f })
            .join(sep);
        s.push_str(&row);
        s.push('\n');
    }
    let path = tmp(name);
    std::fs::write(&path, s).unwrap();
    path
}

/// The sample rate a model file was fitted at.
fn model_fs(path: &str) -> f64 {
    let text = std::fs::read_to_string(path).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("fs = "))
        .unwrap_or_else(|| panic!("no fs in {text}"));
    line.trim_start_matches("fs = ").parse().unwrap()
}

/// A file separated by semicolons or tabs, or with decimal commas, is named as such with the
/// flag that reads it, by every command; read with the flags it fits, and the results are
/// written back in the file's own dialect.
#[test]
fn delimiters_and_decimal_commas_are_named_with_their_fix() {
    let toml = tmp("dialect.toml");
    let out = tmp("dialect_out.csv");
    let semi = step_file("semi.csv", "t;u;y", ";", 1.0, false);
    csv_readers(
        &semi,
        "semi.csv:1: the header 't;u;y' is one column: its names are separated by ';', not by \
         ','; read the file with the delimiter ';' (--delimiter ';')",
    );
    let tab = step_file("tab.csv", "t\tu\ty", "\t", 1.0, false);
    refuses(
        &["fit", &tab, "-o", &toml],
        Some(&toml),
        "separated by tab, not by ','; read the file with the delimiter tab (--delimiter tab)",
    );
    let comma = step_file("comma.csv", "t;u;y", ";", 1.0, true);
    refuses(
        &["fit", &comma, "-o", &toml],
        Some(&toml),
        "the rows have decimal commas) (--delimiter ';' --decimal-comma)",
    );
    refuses(
        &["fit", &comma, "--delimiter", ";", "-o", &toml],
        Some(&toml),
        "comma.csv:2:1: '0,000000000' in column 't' is not a number: it has a decimal comma; \
         read commas in numbers as decimal points (--decimal-comma)",
    );
    refuses(
        &["fit", &comma, "--decimal-comma", "-o", &toml],
        Some(&toml),
        "need a delimiter other than ',' (every decimal comma would split a field) \
         (--decimal-comma with --delimiter ';' or tab)",
    );
    let o = unlag(&["fit", &tab, "--delimiter", "long", "-o", &toml]);
    assert_eq!(o.status.code(), Some(2));
    // Read as they are written.
    let flags = ["--delimiter", ";", "--decimal-comma"];
    let o = unlag(&[&["fit", &comma, "--order", "2", "-o", &toml][..], &flags].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!((model_fs(&toml) - 10_000.0).abs() < 1e-6);
    let o = unlag(&[&["compensate", &toml, &comma, "-o", &out][..], &flags].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let written = std::fs::read_to_string(&out).unwrap();
    let mut rows = written.lines();
    assert_eq!(rows.next(), Some("t;u;y;u_hat"));
    let second = rows.nth(1).unwrap();
    assert!(second.starts_with("0,000100000;0;0,000000;"), "{second}");
    let o = unlag(&[
        "fit",
        &tab,
        "--delimiter",
        "tab",
        "--order",
        "2",
        "-o",
        &toml,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The time column's unit comes from its name; a column without one that steps too slowly for
/// seconds is refused with the fix, not fitted at a thousandth of its rate.
#[test]
fn time_units_are_read_from_the_column_name_or_asked_for() {
    let toml = tmp("units.toml");
    let samples = step_file("samples.csv", "t,u,y", ",", 1e4, false);
    refuses(
        &["fit", &samples, "-o", &toml],
        Some(&toml),
        "samples.csv:3:1: time column 't' steps by 1 per row: as seconds that is 1 Hz, below the \
         10 Hz a probe's step test is sampled at (milliseconds or sample numbers?); name the unit \
         in the column's name (t_ms, t_us) or give the sample rate (--fs HZ, or rename the \
         column t_ms and give --t t_ms)",
    );
    let o = unlag(&[
        "fit", &samples, "--fs", "10000", "--order", "2", "-o", &toml,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!((model_fs(&toml) - 10_000.0).abs() < 1e-6);
    for (name, scale) in [("t_ms", 1e3), ("t[us]", 1e6), ("time (s)", 1.0)] {
        let path = step_file("units.csv", &format!("{name},u,y"), ",", scale, false);
        let o = unlag(&["fit", &path, "--t", name, "--order", "2", "-o", &toml]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!((model_fs(&toml) - 10_000.0).abs() < 1e-3, "{name}");
    }
}

/// Values no sum can hold, and columns that hold one value, are refused where they are read,
/// not later as a fit that found nothing.
#[test]
fn huge_values_and_constant_columns_are_refused_where_they_are() {
    let toml = tmp("values.toml");
    let good = std::fs::read_to_string(step_file("values.csv", "t,u,y", ",", 1.0, false)).unwrap();
    let huge = tmp("huge.csv");
    std::fs::write(
        &huge,
        good.replacen(
            "\n0.000200000,0,0.000000\n",
            "\n0.000200000,1e300,0.000000\n",
            1,
        ),
    )
    .unwrap();
    csv_readers(
        &huge,
        "huge.csv:4:2: '1e300' in column 'u': |value| above 1e100 cannot be a pressure or a \
         time in any unit and overflows the fit's sums; is the column scaled?",
    );
    let constant: String = good
        .lines()
        .map(|l| match l.rsplit_once(',') {
            Some((head, _)) if l != "t,u,y" => format!("{head},0.25\n"),
            _ => format!("{l}\n"),
        })
        .collect();
    let flat = tmp("flat.csv");
    std::fs::write(&flat, constant).unwrap();
    refuses(
        &["fit", &flat, "-o", &toml],
        Some(&toml),
        "flat.csv: the probe column 'y' is constant (0.25) from line 2 to line 401: nothing to \
         fit; is it the right column, or was the probe connected?",
    );
    let long = tmp("long_cell.csv");
    std::fs::write(
        &long,
        good.replacen(
            "\n0.000100000,0,",
            &format!("\n0.000100000,{},", "7".repeat(100_000)),
            1,
        ),
    )
    .unwrap();
    refuses(
        &["fit", &long, "-o", &toml],
        Some(&toml),
        "long_cell.csv:3:2: value '77777777777777777777777777777777…' (100000 bytes at byte \
         41) in column 'u' is not finite",
    );
}

#[cfg(unix)]
#[test]
fn an_output_replaces_only_its_own_kind_of_file_and_never_a_read_only_one() {
    use std::os::unix::fs::PermissionsExt as _;
    let m = good_model();
    let csv = data("line_val.csv");
    let est = data("line_est.csv");
    let ok = |args: &[&str]| {
        let o = unlag(args);
        assert!(
            o.status.success(),
            "unlag {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&o.stderr)
        );
    };
    // Another recording in the way: refused before any work, byte for byte as it was
    // (`refuses` checks), the message naming the way out.
    let other = tmp("other_recording.csv");
    std::fs::copy(&csv, &other).unwrap();
    let not = |what: &str| format!("exists and is not {what}");
    let fit_model = tmp("report_in_the_way.toml");
    let _ = std::fs::remove_file(&fit_model);
    for (args, what) in [
        (
            vec!["compensate", m, &csv, "-o", &other],
            "an output of unlag compensate",
        ),
        (
            vec!["simulate", m, &csv, "-o", &other],
            "an output of unlag simulate",
        ),
        (
            vec!["export", m, "--format", "c", "-o", &other],
            "an output of unlag export",
        ),
        (vec!["report", m, &est, "-o", &other], "an unlag report"),
        (
            vec!["compare", m, &est, "--report", &other],
            "an unlag report",
        ),
        (
            vec!["diagnose", m, &est, "--report", &other],
            "an unlag report",
        ),
        (
            vec!["fit", &est, "-o", &fit_model, "--report", &other],
            "an unlag report",
        ),
    ] {
        refuses(&args, Some(&other), &not(what));
        refuses(&args, Some(&other), "--force");
    }
    // Their own outputs are replaced; one command's output is not another's.
    let comp = tmp("own_compensate.csv");
    let _ = std::fs::remove_file(&comp);
    ok(&["compensate", m, &csv, "-o", &comp]);
    ok(&["compensate", m, &csv, "-o", &comp]);
    refuses(
        &["simulate", m, &csv, "-o", &comp],
        Some(&comp),
        &not("an output of unlag simulate"),
    );
    let code = tmp("own_export.h");
    let _ = std::fs::remove_file(&code);
    for format in ["c", "rust", "bin", "c"] {
        ok(&["export", m, "--format", format, "-o", &code]);
    }
    // Refused before any work: fit wrote no model.
    assert!(!Path::new(&fit_model).exists());
    // --force replaces another file.
    let page = tmp("other_for_a_report.csv");
    std::fs::copy(&csv, &page).unwrap();
    ok(&["compare", m, &est, "--report", &page, "--force"]);
    assert!(std::fs::read_to_string(&page).unwrap().contains("<html"));
    ok(&["simulate", m, &csv, "-o", &other, "--force"]);
    assert_ne!(std::fs::read(&other).unwrap(), std::fs::read(&csv).unwrap());
    // A read-only file is never replaced, not even an own output under --force.
    std::fs::set_permissions(&comp, std::fs::Permissions::from_mode(0o444)).unwrap();
    refuses(
        &["compensate", m, &csv, "-o", &comp, "--force"],
        Some(&comp),
        "is read-only",
    );
    refuses(
        &["compensate", m, &csv, "-o", &comp],
        Some(&comp),
        "is read-only",
    );
    std::fs::set_permissions(&comp, std::fs::Permissions::from_mode(0o644)).unwrap();
}

#[test]
fn a_closed_standard_output_is_one_line_saying_what_was_written() {
    let m = good_model();
    let csv = data("line_val.csv");
    let out = tmp("closed_stdout.csv");
    let _ = std::fs::remove_file(&out);
    let run = |args: &[&str]| {
        // The reader is gone before the command starts (`| head -c 0`): closed here, before the
        // spawn, so that no print can reach the pipe while it is still open.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .stdout(writer)
            .stderr(std::process::Stdio::piped())
            .output()
            .unwrap()
    };
    let o = run(&["compensate", m, &csv, "-o", &out]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert_eq!(
        stderr,
        format!("error: standard output closed (broken pipe); {out} was written\n")
    );
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .starts_with("t,u,y,u_hat"));
    let o = run(&["inspect", m]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert_eq!(
        stderr,
        "error: standard output closed (broken pipe); no file was written\n"
    );
}
