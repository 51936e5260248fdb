//! Model analysis against independent computations, and the `inspect` / `resample` commands.
//!
//! The frequency response (the paper's eq. 6) is checked against the discrete Fourier transform
//! of the model's impulse response, computed here by direct summation: the two share no code
//! beyond the recursion that produces the impulse response.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

use std::f64::consts::PI;
use std::path::PathBuf;
use std::process::{Command, Output};

use unlag::fit::analysis::frequency_response;
use unlag::fit::model::{filter, Model};

/// `(re, im)` of `sum_n h[n] e^{-j 2 pi k n / N}`, by direct summation with the angle reduced
/// modulo `N` (exact in integers) so that large `k n` lose no accuracy.
fn dft_bin(h: &[f64], k: usize) -> (f64, f64) {
    let n = h.len();
    h.iter().enumerate().fold((0.0, 0.0), |(re, im), (i, &v)| {
        let phase = -2.0 * PI * ((k * i) % n) as f64 / n as f64;
        (re + v * phase.cos(), im + v * phase.sin())
    })
}

/// A 2nd-order section's denominator `[a1, a2]` with poles `exp(s / fs)`.
fn pair(fs: f64, fn_hz: f64, zeta: f64) -> [f64; 2] {
    let wn = 2.0 * PI * fn_hz;
    let (re, im) = (-zeta * wn / fs, wn * (1.0 - zeta * zeta).sqrt() / fs);
    [-2.0 * re.exp() * im.cos(), (2.0 * re).exp()]
}

fn models() -> Vec<Model> {
    let fs = 10_000.0;
    let [a1, a2] = pair(fs, 95.0, 0.12);
    let second = Model {
        fs,
        delay: 3,
        a: vec![a1, a2],
        b: vec![0.004, 0.0027, 0.0005],
    };
    // 4th order with the paper's delay of 18 samples and a zero of B at 2.1 (non-minimum-phase).
    let [c1, c2] = pair(fs, 420.0, 0.08);
    let a = vec![a1 + c1, a2 + a1 * c1 + c2, a1 * c2 + a2 * c1, a2 * c2];
    // B = 0.001 (-1 + 2.1 z^-1)(1 + 0.5 z^-1)(1 + 0.2 z^-2): positive DC gain.
    let b = vec![-0.001, 0.0016, 0.00085, 0.00032, 0.00021];
    let fourth = Model {
        fs,
        delay: 18,
        a,
        b,
    };
    vec![second, fourth]
}

#[test]
fn frequency_response_matches_the_dft_of_the_impulse_response() {
    for m in models() {
        let n = 16_384;
        let mut impulse = vec![0.0; n];
        impulse[0] = 1.0;
        let h = filter(&m.b, &m.a, m.delay, &impulse);
        assert!(
            h[n - 1].abs() < 1e-20,
            "impulse response not decayed: {}",
            h[n - 1]
        );
        let bins: Vec<usize> = (0..=n / 2).step_by(37).chain([1, 2, 3, n / 2]).collect();
        let freqs: Vec<f64> = bins.iter().map(|&k| k as f64 * m.fs / n as f64).collect();
        let response = frequency_response(&m, &freqs);
        let mut worst: f64 = 0.0;
        for (&k, &(mag, phase)) in bins.iter().zip(&response) {
            let (re, im) = dft_bin(&h, k);
            let err = ((mag * phase.cos() - re).powi(2) + (mag * phase.sin() - im).powi(2)).sqrt();
            worst = worst.max(err / mag.max(1.0));
        }
        assert!(worst < 1e-9, "order {}: worst error {worst:e}", m.order());
    }
}

#[test]
fn phase_is_continuous_on_a_fine_grid() {
    for m in models() {
        let freqs: Vec<f64> = (0..=5000).map(|k| k as f64).collect();
        let r = frequency_response(&m, &freqs);
        assert!(r[0].1.abs() < 1e-12);
        for (i, w) in r.windows(2).enumerate() {
            // The delay alone turns the phase by 2 pi d / fs per Hz; resonances add less than
            // pi/2 per 1 Hz step at these dampings.
            assert!(
                (w[1].1 - w[0].1).abs() < PI / 2.0,
                "order {}: jump at {i} Hz: {:?}",
                m.order(),
                w
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Command line.

fn unlag(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unlag"))
        .args(args)
        .output()
        .expect("run unlag")
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("unlag-analysis-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn write_model(name: &str, m: &Model) -> PathBuf {
    let path = tmp(name);
    let a: Vec<String> = m.a.iter().map(|v| format!("{v:e}")).collect();
    let b: Vec<String> = m.b.iter().map(|v| format!("{v:e}")).collect();
    let text = format!(
        "format_version = 1\nfs = {:e}\ndelay = {}\na = [{}]\nb = [{}]\n",
        m.fs,
        m.delay,
        a.join(", "),
        b.join(", ")
    );
    std::fs::write(&path, text).unwrap();
    path
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn inspect_prints_the_analysis_as_json() {
    let m = &models()[1];
    let path = write_model("fourth.toml", m);
    let o = unlag(&[
        "inspect",
        path.to_str().unwrap(),
        "--json",
        "--freqs",
        "0,100,420",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).expect(&stdout);
    assert_eq!(v["analysis"]["delay_samples"], 18);
    assert_eq!(v["analysis"]["stable"], true);
    assert_eq!(v["analysis"]["minimum_phase"], false);
    let modes = v["analysis"]["modes"].as_array().unwrap();
    let mut fns: Vec<f64> = modes
        .iter()
        .map(|m| m["natural_frequency_hz"].as_f64().unwrap())
        .collect();
    fns.sort_by(f64::total_cmp);
    assert!(
        (fns[0] - 95.0).abs() < 1e-6 && (fns[1] - 420.0).abs() < 1e-6,
        "{fns:?}"
    );
    let rows = v["frequency_response"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    let dc = m.dc_gain().abs();
    assert!((rows[0]["magnitude"].as_f64().unwrap() - dc).abs() < 1e-10 * dc);
    assert!(v["continuous"]["delay_s"].as_f64().unwrap() > 17.0 / m.fs);
}

#[test]
fn inspect_prints_a_table() {
    let path = write_model("second.toml", &models()[0]);
    let o = unlag(&["inspect", path.to_str().unwrap(), "--grid", "0:1000:11"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    for needle in [
        "stable",
        "minimum phase",
        "DC gain",
        "resonance",
        "delay",
        "dB",
    ] {
        assert!(stdout.contains(needle), "'{needle}' missing in:\n{stdout}");
    }
}

#[test]
fn inspect_and_resample_refuse_an_unstable_model_in_one_line() {
    let m = Model {
        fs: 1000.0,
        delay: 1,
        a: vec![-1.69, 0.65], // poles 1.098 and 0.592
        b: vec![0.05],
    };
    let path = write_model("unstable.toml", &m);
    let out = tmp("unstable-resampled.toml");
    for args in [
        vec!["inspect", path.to_str().unwrap()],
        vec!["inspect", path.to_str().unwrap(), "--json"],
        vec![
            "resample",
            path.to_str().unwrap(),
            "--fs",
            "5000",
            "-o",
            out.to_str().unwrap(),
        ],
    ] {
        let o = unlag(&args);
        let (stdout, stderr) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stdout}{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.starts_with("error: ") && stderr.contains("unstable"),
            "{stderr}"
        );
    }
    assert!(!out.exists());
}

#[test]
fn inspect_rejects_a_bad_grid() {
    let path = write_model("grid.toml", &models()[0]);
    for grid in ["1:2", "a:b:3", "0:100:0", "10:0:5"] {
        let o = unlag(&["inspect", path.to_str().unwrap(), "--grid", grid]);
        let (stdout, stderr) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{grid}: {stdout}{stderr}");
        assert!(stderr.contains("--grid"), "{stderr}");
    }
}

#[test]
fn resample_round_trip_through_the_command_line() {
    let m = &models()[0];
    let path = write_model("rt.toml", m);
    let up = tmp("rt-50k.toml");
    let back = tmp("rt-10k.toml");
    let o = unlag(&[
        "resample",
        path.to_str().unwrap(),
        "--fs",
        "50000",
        "-o",
        up.to_str().unwrap(),
        "--json",
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).expect(&stdout);
    assert!(
        v["step_agreement"]["max_error"].as_f64().unwrap() < 1e-6,
        "{v}"
    );
    assert!(
        v["step_agreement"]["instants"].as_u64().unwrap() > 100,
        "{v}"
    );
    let o = unlag(&[
        "resample",
        up.to_str().unwrap(),
        "--fs",
        "10000",
        "-o",
        back.to_str().unwrap(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("delay"), "{stdout}");
    let text = std::fs::read_to_string(&back).unwrap();
    let back: toml::Value = toml::from_str(&text).unwrap();
    assert_eq!(back["delay"].as_integer(), Some(3));
    let b0 = back["b"][0].as_float().unwrap();
    assert!((b0 - m.b[0]).abs() < 1e-9, "{b0}");
    let o = unlag(&[
        "resample",
        path.to_str().unwrap(),
        "--fs",
        "-3",
        "-o",
        up.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
}
