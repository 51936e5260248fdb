//! Host benchmark (a benchmark, not a test): fit time on `N = 1e6` samples of a 4th-order
//! step test, and host compensation throughput.
//!
//! ```sh
//! cargo run --release --example bench_host -- [--out DIR]
//! ```
//!
//! `bench/run-host.sh` runs this, then `bench/host_baseline.py` (numpy's `lstsq`, scipy's
//! `lfilter`) on the data written here, and puts both into `BENCHMARKS.md`.
//!
//! What it does:
//!
//! 1. Generates a deterministic step test (SplitMix64 noise, no clock or OS entropy): a
//!    4th-order probe model at 10 kHz (two modes, 112 Hz / damping 0.32 and 362 Hz / 0.16, real
//!    zeros inside the unit circle so the inverse is stable, DC gain 1, delay 17 samples), a unit
//!    step at sample 2000, white noise of 3e-4 on `u` and 1e-3 on `y`.
//! 2. Writes to `DIR` (default `target/bench-host`), so the baseline reads the *same* data:
//!    `u.f64`, `y.f64` (f64 little-endian), `meta.json` (n, m, nb, d, fs, a, b, ...), and the
//!    results the baseline checks against: `theta.f64` (the ARX least-squares solution
//!    `[a1..am, b0..bm]`), `comp_f32.f32` and `comp_f64.f64` (the compensator's output from a
//!    zero state, as `lfilter`'s).
//! 3. Times, best and median of several repetitions (`std::time::Instant`):
//!    - the ARX regression matrix build (`fit::arx::regression`), the column-pivoted QR solve
//!      (`fit::arx::lstsq`), and the two together;
//!    - the whole default fit (`fit::fit`, output error, fixed order 4, known delay), for
//!      information; if one run on `N` samples takes more than 60 s it is timed on the first
//!      1e5 samples instead, and the output says so;
//!    - compensation throughput of the board's compensator (`InverseCoefficients<f32, 4>` and
//!      `<f64, 4>`, `process_in_place` on a buffer), and of the CLI path
//!      (`Model::compensate::<f32>`, a `Vec` in and out).
//!
//! Each figure is printed on one line, `RESULT name value unit`, for the script to read.

use std::error::Error;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use unlag::board::compensator::{
    CascadeCoefficients, CascadeState, InverseCoefficients, InverseState, Sample,
};
use unlag::design::inverse;
use unlag::fit::arx::{self, Data};
use unlag::fit::model::Model;
use unlag::fit::{self, Method, Options, Order, Test};

/// Samples in the step test.
const N: usize = 1_000_000;
/// Model order.
const M: usize = 4;
/// Delay in samples.
const DELAY: usize = 17;
/// Sample rate in Hz.
const FS: f64 = 10_000.0;
/// Sample where the reference steps from 0 to 1.
const STEP_AT: usize = 2_000;
/// Noise standard deviations on the reference and the probe.
const SIGMA_U: f64 = 3e-4;
const SIGMA_Y: f64 = 1e-3;
/// PRNG seed.
const SEED: u64 = 2;
/// Probe modes: (natural frequency in Hz, damping ratio).
const MODES: [(f64, f64); 2] = [(112.0, 0.32), (362.0, 0.16)];
/// Zeros of `B(z)`, all inside the unit circle (minimum phase: the inverse is stable).
const ZEROS: [f64; 4] = [0.6, 0.3, -0.2, -0.5];
/// A whole fit that takes longer than this on `N` samples is timed on `N_FIT_SMALL`.
const FIT_BUDGET: Duration = Duration::from_secs(60);
const N_FIT_SMALL: usize = 100_000;

/// SplitMix64 with Box-Muller Gaussians: deterministic, small, no crate.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal.
    fn gauss(&mut self) -> f64 {
        let r = self.uniform().max(1e-300);
        let t = self.uniform();
        (-2.0 * r.ln()).sqrt() * (std::f64::consts::TAU * t).cos()
    }
}

/// Product of two polynomials in `z^-1` (coefficient lists, leading term first).
fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; p.len() + q.len() - 1];
    for (i, pi) in p.iter().enumerate() {
        for (j, qj) in q.iter().enumerate() {
            out[i + j] += pi * qj;
        }
    }
    out
}

/// The model in the crate's convention: `a = [a1..a4]`, `b = [b0..b4]`.
fn model_coefficients() -> (Vec<f64>, Vec<f64>) {
    let mut den = vec![1.0];
    for (f_hz, zeta) in MODES {
        // A continuous pair s = -zeta w +- j w sqrt(1 - zeta^2), mapped by z = exp(s / fs).
        let w = std::f64::consts::TAU * f_hz / FS;
        let r = (-zeta * w).exp();
        let theta = w * (1.0 - zeta * zeta).sqrt();
        den = poly_mul(&den, &[1.0, -2.0 * r * theta.cos(), r * r]);
    }
    let mut num = vec![1.0];
    for z in ZEROS {
        num = poly_mul(&num, &[1.0, -z]);
    }
    // DC gain 1: B(1) = A(1).
    let scale = den.iter().sum::<f64>() / num.iter().sum::<f64>();
    let b = num.iter().map(|v| v * scale).collect();
    let a = den[1..].to_vec();
    (a, b)
}

/// The step test: `y = q^-d B/A u` from rest (direct form I, written here so the data do not
/// depend on the crate), plus noise on both channels.
fn step_test(a: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64(SEED);
    let clean_u: Vec<f64> = (0..N).map(|k| f64::from(u8::from(k >= STEP_AT))).collect();
    let mut y = vec![0.0; N];
    for k in 0..N {
        let mut acc = 0.0;
        for (i, bi) in b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + DELAY) {
                acc += bi * clean_u[j];
            }
        }
        for (i, ai) in a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                acc -= ai * y[j];
            }
        }
        y[k] = acc;
    }
    let u = clean_u.iter().map(|v| v + SIGMA_U * rng.gauss()).collect();
    let y = y.iter().map(|v| v + SIGMA_Y * rng.gauss()).collect();
    (u, y)
}

/// Best and median wall time of `reps` runs.
#[derive(Debug, Clone, Copy)]
struct Timing {
    best: f64,
    median: f64,
    reps: usize,
}

/// Best and median of measured durations (at least one).
fn stats(mut seconds: Vec<f64>) -> Timing {
    seconds.sort_by(f64::total_cmp);
    let n = seconds.len();
    let median = match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => seconds[n / 2],
        _ => 0.5 * (seconds[n / 2 - 1] + seconds[n / 2]),
    };
    Timing {
        best: seconds.first().copied().unwrap_or(f64::NAN),
        median,
        reps: n,
    }
}

/// Runs `f` `reps` times (at least once) and returns the timing and the first result.
fn time<R>(reps: usize, mut f: impl FnMut() -> R) -> (Timing, R) {
    let t0 = Instant::now();
    let first = black_box(f());
    let mut seconds = vec![t0.elapsed().as_secs_f64()];
    for _ in 1..reps {
        let t0 = Instant::now();
        let r = black_box(f());
        seconds.push(t0.elapsed().as_secs_f64());
        // Freed outside the timed region.
        drop(r);
    }
    (stats(seconds), first)
}

/// Prints a time figure (best and median, seconds).
fn report_time(name: &str, t: Timing) {
    println!("RESULT {name}_best {:.6e} s", t.best);
    println!("RESULT {name}_median {:.6e} s", t.median);
    println!("RESULT {name}_reps {} count", t.reps);
}

/// Prints a throughput figure (samples per second, from the best and the median time).
fn report_throughput(name: &str, samples: usize, t: Timing) {
    println!(
        "RESULT {name}_best {:.6e} samples/s",
        samples as f64 / t.best
    );
    println!(
        "RESULT {name}_median {:.6e} samples/s",
        samples as f64 / t.median
    );
    println!("RESULT {name}_reps {} count", t.reps);
}

fn write_f64(path: &Path, x: &[f64]) -> std::io::Result<()> {
    let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(path, bytes)
}

fn write_f32(path: &Path, x: &[f32]) -> std::io::Result<()> {
    let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(path, bytes)
}

/// Times `process_in_place` on a fresh copy of `y` (converted to `T` outside the timed
/// region) from a zero state; returns the timing and the output.
fn bench_inverse<T: Sample>(
    b: &[f64],
    a: &[f64],
    y: &[f64],
    reps: usize,
) -> Result<(Timing, Vec<T>), Box<dyn Error>> {
    let coefficients = InverseCoefficients::<T, M>::new(b, a)?;
    let input: Vec<T> = y.iter().map(|&v| T::from_f64(v)).collect();
    let mut buf = input.clone();
    let mut seconds = Vec::with_capacity(reps);
    for _ in 0..reps.max(1) {
        buf.copy_from_slice(&input);
        let mut state = InverseState::default();
        let t0 = Instant::now();
        coefficients.process_in_place(&mut state, black_box(&mut buf));
        black_box(&buf);
        seconds.push(t0.elapsed().as_secs_f64());
    }
    Ok((stats(seconds), buf))
}

/// Band limit of the stable compensator benchmarked (Hz).
const BANDWIDTH_HZ: f64 = 1000.0;

/// As [`bench_inverse`] for the stable band-limited compensator in second-order sections
/// (what `unlag compensate` runs by default).
fn bench_cascade<T: Sample>(
    design: &inverse::Design,
    y: &[f64],
    reps: usize,
) -> Result<(Timing, Vec<T>), Box<dyn Error>> {
    let coefficients = CascadeCoefficients::<T, 4>::new(design.gain, &design.sections)?;
    let input: Vec<T> = y.iter().map(|&v| T::from_f64(v)).collect();
    let mut buf = input.clone();
    let mut seconds = Vec::with_capacity(reps);
    for _ in 0..reps.max(1) {
        buf.copy_from_slice(&input);
        let mut state = CascadeState::default();
        let t0 = Instant::now();
        coefficients.process_in_place(&mut state, black_box(&mut buf));
        black_box(&buf);
        seconds.push(t0.elapsed().as_secs_f64());
    }
    Ok((stats(seconds), buf))
}

fn parse_out() -> Result<PathBuf, Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let mut out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench-host");
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--out" => out = args.next().ok_or("--out needs a directory")?.into(),
            "-h" | "--help" => {
                println!("usage: bench_host [--out DIR]");
                std::process::exit(0);
            }
            other => {
                return Err(
                    format!("unknown argument {other:?} (usage: bench_host [--out DIR])").into(),
                )
            }
        }
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let out = parse_out()?;
    std::fs::create_dir_all(&out)?;

    // 1. Data.
    let (a, b) = model_coefficients();
    let (u, y) = step_test(&a, &b);
    println!("INFO n={N} m={M} d={DELAY} fs={FS} a={a:?} b={b:?}");
    println!("RESULT n {N} samples");

    // 2. The same data for the baseline.
    write_f64(&out.join("u.f64"), &u)?;
    write_f64(&out.join("y.f64"), &y)?;
    let model = Model {
        fs: FS,
        delay: DELAY,
        a: a.clone(),
        b: b.clone(),
    };
    let design = inverse::design(&model, BANDWIDTH_HZ, &inverse::Options::default())?;
    let sos: Vec<[f64; 6]> = design
        .sections
        .iter()
        .map(|s| [s[0], s[1], s[2], 1.0, s[3], s[4]])
        .collect();
    let meta = serde_json::json!({
        "n": N, "m": M, "nb": M + 1, "d": DELAY, "fs": FS, "step_at": STEP_AT,
        "sigma_u": SIGMA_U, "sigma_y": SIGMA_Y, "seed": SEED,
        "a": a, "b": b,
        "sos": sos, "sos_gain": design.gain, "bandwidth_hz": BANDWIDTH_HZ,
        "files": {
            "u": "u.f64", "y": "y.f64", "theta": "theta.f64",
            "comp_f32": "comp_f32.f32", "comp_f64": "comp_f64.f64",
            "sos_f32": "sos_f32.f32", "sos_f64": "sos_f64.f64",
        },
        "format": "little-endian, no header",
    });
    std::fs::write(out.join("meta.json"), serde_json::to_string_pretty(&meta)?)?;

    // 3a. Regression matrix and least squares.
    let sets = [Data { u: &u, y: &y }];
    let reps = 7;
    let (t_build, (x, t)) = time(reps, || arx::regression(&sets, M, M + 1, DELAY));
    println!(
        "INFO regression matrix {} x {} (rows k = {}..{})",
        x.nrows(),
        x.ncols(),
        M + DELAY,
        N - 1
    );
    println!("RESULT arx_rows {} count", x.nrows());
    println!("RESULT arx_cols {} count", x.ncols());
    report_time("arx_build", t_build);
    let (t_solve, theta) = time(reps, || arx::lstsq(&x, &t, "bench"));
    let theta = theta?;
    report_time("arx_solve", t_solve);
    let (t_total, theta_total) = time(reps, || {
        let (x, t) = arx::regression(&sets, M, M + 1, DELAY);
        arx::lstsq(&x, &t, "bench")
    });
    report_time("arx_total", t_total);
    if theta_total? != theta {
        return Err("the ARX solution changed between repetitions".into());
    }
    drop((x, t));
    println!("INFO arx theta={theta:?}");
    write_f64(&out.join("theta.f64"), &theta)?;

    // 3b. The whole default fit, for information.
    let options = Options {
        method: Method::Oe,
        order: Order::Fixed(M),
        delay: Some(DELAY),
    };
    let run_fit = |n: usize| {
        fit::fit(
            &Test {
                name: "bench",
                u: &u[..n],
                y: &y[..n],
            },
            &[],
            FS,
            &options,
        )
    };
    let timed_fit = |n: usize, seconds: &mut Vec<f64>| {
        let t0 = Instant::now();
        let r = black_box(run_fit(n));
        seconds.push(t0.elapsed().as_secs_f64());
        r
    };
    let mut seconds = Vec::new();
    let fitted = timed_fit(N, &mut seconds)?;
    let first = seconds.first().copied().unwrap_or(f64::NAN);
    let n_fit = if first > FIT_BUDGET.as_secs_f64() {
        println!(
            "INFO the whole fit took {first:.1} s on {N} samples (> {} s): timed on {N_FIT_SMALL}",
            FIT_BUDGET.as_secs()
        );
        seconds.clear();
        for _ in 0..3 {
            timed_fit(N_FIT_SMALL, &mut seconds)?;
        }
        N_FIT_SMALL
    } else {
        // A median of three when that fits in about a minute.
        if first < 20.0 {
            for _ in 0..2 {
                timed_fit(N, &mut seconds)?;
            }
        }
        N
    };
    let t_fit = stats(seconds);
    println!(
        "INFO oe fit a={:?} b={:?} nrmse={:.4e}",
        fitted.model.a, fitted.model.b, fitted.nrmse_estimation
    );
    println!("RESULT fit_oe_n {n_fit} samples");
    report_time("fit_oe", t_fit);

    // 3c. Compensation throughput.
    let reps = 51;
    let (t32, out32) = bench_inverse::<f32>(&b, &a, &y, reps)?;
    report_throughput("comp_f32_inplace", N, t32);
    write_f32(&out.join("comp_f32.f32"), &out32)?;
    let (t64, out64) = bench_inverse::<f64>(&b, &a, &y, reps)?;
    report_throughput("comp_f64_inplace", N, t64);
    write_f64(&out.join("comp_f64.f64"), &out64)?;
    let (t_model, r) = time(reps, || model.compensate::<f32>(&y));
    r?;
    report_throughput("comp_model_f32", N, t_model);
    let (t, sos32) = bench_cascade::<f32>(&design, &y, reps)?;
    report_throughput("sos_f32_inplace", N, t);
    write_f32(&out.join("sos_f32.f32"), &sos32)?;
    let (t, sos64) = bench_cascade::<f64>(&design, &y, reps)?;
    report_throughput("sos_f64_inplace", N, t);
    write_f64(&out.join("sos_f64.f64"), &sos64)?;
    Ok(())
}
