//! The modelling loop on step tests with hidden effects: for every case the diagnosis names the
//! hidden kind first (or `none`), and adding it cuts the validation error at least 3x or to
//! within 1.5x of the noise floor. The cases are in `common/hidden.rs`; the score table in
//! BENCHMARKS.md comes from `examples/bench_diagnose.rs` on the same cases.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;

use common::hidden::{cases, run};

#[test]
fn every_hidden_effect_is_named_and_adding_it_cuts_the_error() {
    let mut failures = Vec::new();
    for case in cases() {
        let o = run(&case, 11);
        eprintln!(
            "{:<45} named {:?}: {:.3} % -> {:.3} % (floor {:.3} %)",
            case.name,
            o.named,
            100.0 * o.before,
            100.0 * o.after,
            100.0 * o.floor
        );
        if !o.passed(case.kind) {
            failures.push(format!("{}: {:?}", case.name, o));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The README's walkthrough, through the command line, on the shipped example data (whose probe
/// has a second line mode): a plain 2nd-order model, the diagnosis, the effect added, the
/// error history falling, and nothing left.
#[test]
fn the_readme_walkthrough_on_the_shipped_data() {
    use std::process::Command;
    let dir = std::env::temp_dir().join(format!("unlag-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("probe.toml");
    let m = model.to_str().unwrap();
    let t1 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_1.csv");
    let t2 = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_2.csv");
    let run = |args: &[&str]| -> serde_json::Value {
        let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success(),
            "{args:?}: {out}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_str(out.trim()).expect(&out)
    };
    run(&["fit", t1, t2, "--order", "2", "--fresh", "-o", m, "--json"]);
    let d = run(&["diagnose", m, t1, t2, "--json"]);
    let first = &d["candidates"][0];
    assert_eq!(first["kind"], "mode", "{d}");
    let scores: Vec<f64> = d["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["score"].as_f64().unwrap())
        .collect();
    assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");
    assert!(d["tests"][0]["fit_percent"].as_f64().unwrap() > 90.0);
    run(&[
        "fit", t1, t2, "--order", "2", "--add", "mode", "-o", m, "--json",
    ]);
    let c = run(&["compare", m, t1, t2, "--json"]);
    let history = c["history"].as_array().unwrap();
    assert_eq!(history.len(), 2, "{c}");
    let mean = |row: &serde_json::Value| {
        let t = row["tests"].as_array().unwrap();
        t.iter().map(|x| x["nrmse"].as_f64().unwrap()).sum::<f64>() / t.len() as f64
    };
    assert!(mean(&history[1]) < mean(&history[0]) / 2.0, "{c}");
    assert_eq!(history[1]["effects"][0], "mode");
    for t in c["tests"].as_array().unwrap() {
        let (e, floor) = (
            t["nrmse"].as_f64().unwrap(),
            t["noise_floor"].as_f64().unwrap(),
        );
        assert!(e < 1.5 * floor, "{e} against {floor}");
    }
    assert_eq!(c["across_tests"].as_array().unwrap().len(), 2);
    let d = run(&["diagnose", m, t1, t2, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "none", "{d}");
    // Bad input is one line and exit 1.
    let o = Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(["diagnose", m, "no-such-test.csv"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no-such-test.csv"), "{err}");
}

/// Runs the binary; `(success, stdout, stderr)`.
fn unlag(args: &[&str]) -> (bool, String, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn unlag_json(args: &[&str]) -> serde_json::Value {
    let (ok, out, err) = unlag(args);
    assert!(ok, "{args:?}: {out}{err}");
    serde_json::from_str(out.trim()).expect(&out)
}

/// The two cases' tests written as CSV: `(estimation, validation)` paths.
fn case_files(kind: &str, dir: &std::path::Path) -> (String, String, common::hidden::Case) {
    let case = cases().into_iter().find(|c| c.kind == kind).unwrap();
    let [(ue, ye), (uv, yv)] = case.tests(11);
    let (e, v) = (
        dir.join(format!("{kind}-est.csv")),
        dir.join(format!("{kind}-val.csv")),
    );
    common::write_csv(&e, case.fs, &ue, &ye);
    common::write_csv(&v, case.fs, &uv, &yv);
    (
        e.to_str().unwrap().to_string(),
        v.to_str().unwrap().to_string(),
        case,
    )
}

/// `sensor-resonance` through the whole product: `fit --add` finds the diaphragm in the
/// reference and prefilters at half of it, `simulate` applies it, the compensator (and so the
/// export) runs the prefilter's sections first.
#[test]
fn sensor_resonance_through_the_command_line() {
    let dir = std::env::temp_dir().join(format!("unlag-sensor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, _) = case_files("sensor-resonance", &dir);
    let p = dir.join("plain.toml");
    let s = dir.join("sensor.toml");
    let (p, s) = (p.to_str().unwrap(), s.to_str().unwrap());
    unlag_json(&["fit", &est, &val, "--order", "2", "-o", p, "--json"]);
    let d = unlag_json(&["diagnose", p, &est, &val, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "sensor-resonance", "{d}");
    let f = unlag_json(&[
        "fit",
        &est,
        &val,
        "--order",
        "2",
        "--add",
        "sensor-resonance",
        "-o",
        s,
        "--json",
    ]);
    let e = &f["effects"][0];
    assert_eq!(e["kind"], "sensor-resonance", "{f}");
    let fn_hz = e["natural_frequency_hz"].as_f64().unwrap();
    assert!((fn_hz / 2000.0 - 1.0).abs() < 0.05, "{fn_hz}");
    assert!((e["prefilter_hz"].as_f64().unwrap() - 0.5 * fn_hz).abs() < 1e-9);
    let sections = f["inverse"]["sections"].as_array().unwrap().len();
    assert!(
        f["inverse"]["method"]
            .as_str()
            .unwrap()
            .starts_with("sensor-resonance prefilter"),
        "{f}"
    );
    let out = dir.join("y.csv");
    let o = out.to_str().unwrap();
    let plain = unlag_json(&["simulate", p, &val, "-o", o, "--json"])["nrmse"]
        .as_f64()
        .unwrap();
    let with = unlag_json(&["simulate", s, &val, "-o", o, "--json"])["nrmse"]
        .as_f64()
        .unwrap();
    assert!(with * 3.0 < plain, "{with} against {plain}");
    let c = unlag_json(&["compensate", s, &val, "-o", o, "--json"]);
    let (u_hat, raw) = (
        c["nrmse_u_hat"].as_f64().unwrap(),
        c["nrmse_raw"].as_f64().unwrap(),
    );
    assert!(u_hat < raw / 2.0, "{c}");
    let bin = dir.join("s.bin");
    let x = unlag_json(&[
        "export",
        s,
        "--format",
        "bin",
        "-o",
        bin.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(x["sections"].as_u64().unwrap() as usize, sections, "{x}");
}

/// `temperature` through the whole product: `fit --add temperature`, then `simulate`,
/// `compensate` and `export` at the gas temperature of the recording; a model without the
/// effect refuses `--temperature` in one line.
#[test]
fn temperature_through_the_command_line() {
    let dir = std::env::temp_dir().join(format!("unlag-temperature-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (est, val, case) = case_files("temperature", &dir);
    let t_val = match case.hidden {
        common::hidden::Hidden::Temperature(t) => t,
        _ => unreachable!(),
    };
    let t = format!("{t_val}");
    let m = dir.join("t.toml");
    let p = dir.join("plain.toml");
    let (m, p) = (m.to_str().unwrap(), p.to_str().unwrap());
    unlag_json(&["fit", &est, &val, "--order", "2", "-o", p, "--json"]);
    let d = unlag_json(&["diagnose", p, &est, &val, "--json"]);
    assert_eq!(d["candidates"][0]["kind"], "temperature", "{d}");
    let ratio = d["candidates"][0]["evidence"]["temperature_ratio"]
        .as_f64()
        .unwrap();
    assert!((ratio / (t_val / 293.15) - 1.0).abs() < 0.03, "{ratio}");
    unlag_json(&[
        "fit",
        &est,
        &val,
        "--order",
        "2",
        "--add",
        "temperature",
        "-o",
        m,
        "--json",
    ]);
    let out = dir.join("y.csv");
    let o = out.to_str().unwrap();
    let at = |model: &str, extra: &[&str], cmd: &str, key: &str| {
        let mut args = vec![cmd, model, val.as_str(), "-o", o, "--json"];
        args.extend_from_slice(extra);
        unlag_json(&args)[key].as_f64().unwrap()
    };
    let hot = at(m, &["--temperature", &t], "simulate", "nrmse");
    let cold = at(m, &["--temperature", "293.15"], "simulate", "nrmse");
    assert!(hot * 3.0 < cold, "{hot} against {cold}");
    let hot = at(m, &["--temperature", &t], "compensate", "nrmse_u_hat");
    let cold = at(m, &[], "compensate", "nrmse_u_hat");
    assert!(hot < cold, "{hot} against {cold}");
    let rs = dir.join("t.rs");
    unlag_json(&[
        "export",
        m,
        "--format",
        "rust",
        "--temperature",
        &t,
        "-o",
        rs.to_str().unwrap(),
        "--json",
    ]);
    let (ok, _, err) = unlag(&[
        "export",
        p,
        "--format",
        "rust",
        "--temperature",
        "300",
        "-o",
        rs.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.lines().count() == 1 && err.contains("temperature"),
        "{err}"
    );
}
