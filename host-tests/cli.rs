//! The `unlag` command line on recorded traces: the workflow end to end, and every bad input
//! rejected with one clear message naming file, line and column, a non-zero exit, no panic, and
//! no output file.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;
use common::{data, unlag};

use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unlag-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Runs `fit` on a bad file and checks: exit code 1, exactly one line on stderr starting with
/// `error: ` and containing `expect`, no panic, no model written.
fn rejects(file: &str, extra: &[&str], expect: &[&str]) {
    let out = tmp(&format!("{file}.toml"));
    let path = data(&format!("bad/{file}"));
    let mut args = vec!["fit", path.as_str(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = unlag(&args);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{file}: {stdout}{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        stderr.lines().count(),
        1,
        "{file}: one line expected: {stderr}"
    );
    assert!(stderr.starts_with("error: "), "{stderr}");
    for e in expect {
        assert!(stderr.contains(e), "{file}: expected '{e}' in: {stderr}");
    }
    assert!(!Path::new(&out).exists(), "{file}: no model may be written");
}

#[test]
fn empty_file() {
    rejects("empty.csv", &[], &["bad/empty.csv:1: the file is empty"]);
    rejects(
        "header_only.csv",
        &[],
        &["header_only.csv:2: the file is empty"],
    );
}

#[test]
fn missing_column() {
    rejects(
        "missing_column.csv",
        &[],
        &["missing_column.csv:1: missing column 'y'", "t, u, p", "--y"],
    );
    // Named by flag, it works.
    let out = tmp("renamed.toml");
    let p = data("bad/missing_column.csv");
    let o = unlag(&[
        "fit",
        &p,
        "--y",
        "p",
        "--order",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
}

#[test]
fn not_a_number_and_not_finite() {
    rejects(
        "not_a_number.csv",
        &[],
        &["not_a_number.csv:59:3:", "'0.0x3'", "column 'y'"],
    );
    rejects(
        "not_finite.csv",
        &[],
        &["not_finite.csv:214:2:", "'inf'", "not finite"],
    );
}

#[test]
fn time_must_increase_uniformly() {
    rejects(
        "jitter.csv",
        &[],
        &["jitter.csv:152:1:", "more than 1 % jitter"],
    );
    rejects(
        "backwards.csv",
        &[],
        &["backwards.csv:302:1:", "does not increase"],
    );
}

#[test]
fn ragged_row() {
    rejects("ragged.csv", &[], &["ragged.csv:22:", "expected 3 fields"]);
}

#[test]
fn too_short_for_order_and_delay() {
    rejects(
        "short.csv",
        &["--order", "4"],
        &["short.csv", "too short for order 4"],
    );
}

#[test]
fn clipped_adc() {
    rejects(
        "clipped.csv",
        &[],
        &["clipped.csv:", ":3:", "clipped", "1.2"],
    );
}

#[test]
fn no_step() {
    rejects("no_step.csv", &[], &["no_step.csv", "no step found"]);
}

#[test]
fn no_time_column_needs_fs() {
    rejects("no_time.csv", &[], &["missing column 't'", "--fs"]);
    let out = tmp("no_time.toml");
    let p = data("bad/no_time.csv");
    let o = unlag(&[
        "fit",
        &p,
        "--fs",
        "1000",
        "--order",
        "1",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    rejects("no_time.csv", &["--fs", "0"], &["--fs", "positive"]);
}

#[test]
fn mismatched_sample_rates() {
    // Estimation at 10 kHz, "validation" at 1 kHz.
    let out = tmp("mismatch.toml");
    let a = data("line_est.csv");
    let b = tmp("one_khz.csv");
    let rows: String = (0..400)
        .map(|k| {
            let (u, y) = if k < 100 {
                (0.0, 0.0)
            } else {
                (1.0, 1.0 - (-(k as f64 - 100.0) / 5.0).exp())
            };
            format!("{},{u},{y}\n", k as f64 * 1e-3)
        })
        .collect();
    std::fs::write(&b, format!("t,u,y\n{rows}")).unwrap();
    let o = unlag(&["fit", &a, b.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr.contains("one_khz.csv") && stderr.contains("resample"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn unstable_and_non_invertible_models_are_refused() {
    let model = tmp("unstable.toml");
    std::fs::write(
        &model,
        "format_version = 1\nfs = 10000.0\ndelay = 2\na = [-2.1]\nb = [1.0, 0.0]\n",
    )
    .unwrap();
    let out = tmp("unstable_out.csv");
    let o = unlag(&[
        "compensate",
        model.to_str().unwrap(),
        &data("line_val.csv"),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("unstable") && stderr.contains("2.1"),
        "{stderr}"
    );
    assert!(!out.exists());

    std::fs::write(
        &model,
        "format_version = 1\nfs = 10000.0\ndelay = 2\na = [-0.5]\nb = [0.2, -0.42]\n",
    )
    .unwrap();
    let o = unlag(&[
        "compensate",
        model.to_str().unwrap(),
        &data("line_val.csv"),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("zero 2.1"), "{stderr}");
    assert!(!out.exists());

    // A syntax error names line and column of the model file.
    std::fs::write(
        &model,
        "format_version = 1\nfs = 10000.0\ndelay = 2\na = [-0.5,\n",
    )
    .unwrap();
    let o = unlag(&[
        "simulate",
        model.to_str().unwrap(),
        &data("line_val.csv"),
        "-o",
        out.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("unstable.toml:4:") || stderr.contains("unstable.toml:5:"),
        "{stderr}"
    );
}

#[test]
fn fit_compensate_simulate_end_to_end() {
    let model = tmp("line.toml");
    let o = unlag(&[
        "fit",
        &data("line_est.csv"),
        &data("line_val.csv"),
        "-o",
        model.to_str().unwrap(),
        "--json",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    // One JSON object on stdout.
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).expect("one JSON object");
    let sources = v["sources"].as_array().unwrap();
    assert_eq!(sources.len(), 2);
    for s in sources {
        let e = s["nrmse"].as_f64().unwrap();
        let floor = s["noise_floor"].as_f64().unwrap();
        assert!(e < 1.5 * floor, "{s}");
        assert_eq!(s["sha256"].as_str().unwrap().len(), 64);
    }
    // The model file holds what the issue asks for.
    let text_model = std::fs::read_to_string(&model).unwrap();
    for key in [
        "format_version = 1",
        "fs = 10000",
        "delay = ",
        "a = [",
        "b = [",
        "method = \"bj\"",
        "[[sources]]",
        "sha256",
    ] {
        assert!(text_model.contains(key), "{key} missing in\n{text_model}");
    }

    // simulate adds y_model and keeps the columns.
    let sim = tmp("sim.csv");
    let o = unlag(&[
        "simulate",
        model.to_str().unwrap(),
        &data("line_val.csv"),
        "-o",
        sim.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{:?}", text(&o));
    let s = std::fs::read_to_string(&sim).unwrap();
    assert!(s.starts_with("t,u,y,y_model\n"));
    assert_eq!(s.lines().count(), 3001);

    // compensate adds u_hat; f32 and f64 agree closely.
    let c32 = tmp("c32.csv");
    let c64 = tmp("c64.csv");
    for (out, ar) in [(&c32, "f32"), (&c64, "f64")] {
        let o = unlag(&[
            "compensate",
            model.to_str().unwrap(),
            &data("line_val.csv"),
            "-o",
            out.to_str().unwrap(),
            "--arithmetic",
            ar,
            "--json",
        ]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{stderr}");
        let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
        assert!(v["nrmse_u_hat"].as_f64().unwrap().is_finite());
    }
    let col = |p: &Path| -> Vec<f64> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
            .collect()
    };
    let (a, b) = (col(&c32), col(&c64));
    assert_eq!(a.len(), 3000);
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-2 * scale, "f32 vs f64: {worst} of {scale}");
}

/// The traces' pressure unit, read from the column names or given with `--unit`, is stored in
/// the model file and carried by every pressure printed, with the prefix that suits it; the
/// model itself does not change with it.
#[test]
fn pressures_are_printed_in_the_traces_unit() {
    let original = std::fs::read_to_string(format!(
        "{}/examples/data/step_test_1.csv",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let (_, rows) = original.split_once('\n').unwrap();
    let named = tmp("named_kpa.csv");
    std::fs::write(&named, format!("t,p_kPa,y_kPa\n{rows}")).unwrap();
    let (plain_model, named_model, psi_model) =
        (tmp("plain.toml"), tmp("named.toml"), tmp("psi.toml"));
    let fit = |file: &Path, extra: &[&str], model: &Path| {
        let mut args = vec!["fit", file.to_str().unwrap(), "--order", "4"];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", model.to_str().unwrap()]);
        let o = unlag(&args);
        assert!(o.status.success(), "{:?}", text(&o));
        text(&o).0
    };
    let steps = format!(
        "{}/examples/data/step_test_1.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let plain = fit(Path::new(&steps), &[], &plain_model);
    let by_name = fit(&named, &["--u", "p_kPa", "--y", "y_kPa"], &named_model);
    let by_flag = fit(Path::new(&steps), &["--unit", "psi"], &psi_model);
    let line = |out: &str| {
        out.lines()
            .find(|l| l.trim_start().starts_with("full scale +-"))
            .unwrap()
            .to_string()
    };
    // Without a unit the number alone; the shipped test's largest |y| is 1375.29.
    assert!(
        line(&plain).contains("largest |y|, 1375,"),
        "{}",
        line(&plain)
    );
    // In kPa the same numbers are MPa: 1375.29 kPa is 1.375 MPa.
    assert!(
        line(&by_name).contains("largest |y|, 1.375 MPa,"),
        "{}",
        line(&by_name)
    );
    assert!(
        line(&by_flag).contains("largest |y|, 1375 psi,"),
        "{}",
        line(&by_flag)
    );
    let board = |path: &Path| {
        let text = std::fs::read_to_string(path).unwrap();
        let v: toml::Value = toml::from_str(&text).unwrap();
        (
            v.get("board")
                .and_then(|b| b.get("unit"))
                .and_then(|u| u.as_str())
                .map(String::from),
            v.get("a").cloned(),
        )
    };
    let (p, n, s) = (board(&plain_model), board(&named_model), board(&psi_model));
    assert_eq!(
        (p.0.as_deref(), n.0.as_deref(), s.0.as_deref()),
        (None, Some("kPa"), Some("psi"))
    );
    assert_eq!(p.1, n.1, "the unit changes the printing, not the model");
    // A unit unlag does not know is refused with the ones it does.
    let o = unlag(&[
        "fit",
        &steps,
        "--unit",
        "furlong",
        "-o",
        tmp("bad.toml").to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("'furlong'") && err.contains("kPa"), "{err}");
}
