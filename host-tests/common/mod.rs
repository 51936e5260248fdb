//! Test fixtures shared by the integration tests: a deterministic noise source and an
//! independent simulation of continuous-time probe dynamics (RK4 on the state equations with
//! the input held between samples), so that the tests do not check the crate with its own code.
#![allow(dead_code)]

/// Runs the built `unlag` binary with `args` and collects its output.
pub fn unlag(args: &[&str]) -> std::process::Output {
    std::process::Command::new(option_env!("CARGO_BIN_EXE_unlag").unwrap_or("unlag"))
        .args(args)
        .output()
        .expect("run unlag")
}

/// The path of a shipped test file under `host-tests/data/`.
pub fn data(name: &str) -> String {
    format!("{}/host-tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Deterministic PRNG (SplitMix64) with Gaussian samples (Box-Muller).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let a = self.uniform().max(1e-300);
        let b = self.uniform();
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// Output of a cascade of unit-DC-gain continuous second-order stages
/// `wn^2 / (s^2 + 2 zeta wn s + wn^2)` driven by `u` held constant between samples (ZOH) and
/// delayed by `delay` whole samples. Starts at rest with the first input value.
pub fn continuous_line(u: &[f64], fs: f64, modes: &[(f64, f64)], delay: usize) -> Vec<f64> {
    let dt = 1.0 / fs;
    let sub = 64;
    let h = dt / sub as f64;
    let u0 = u[0];
    // State per stage: (x, x'), starting in equilibrium at u0.
    let mut st: Vec<(f64, f64)> = modes.iter().map(|_| (u0, 0.0)).collect();
    let mut y = Vec::with_capacity(u.len());
    for k in 0..u.len() {
        y.push(st.last().map_or(u0, |s| s.0));
        let uk = if k >= delay { u[k - delay] } else { u0 };
        for _ in 0..sub {
            let mut input = uk;
            for (s, &(f, z)) in st.iter_mut().zip(modes) {
                let w = 2.0 * std::f64::consts::PI * f;
                let deriv = |x: f64, v: f64| (v, w * w * (input - x) - 2.0 * z * w * v);
                let (x, v) = *s;
                let k1 = deriv(x, v);
                let k2 = deriv(x + 0.5 * h * k1.0, v + 0.5 * h * k1.1);
                let k3 = deriv(x + 0.5 * h * k2.0, v + 0.5 * h * k2.1);
                let k4 = deriv(x + h * k3.0, v + h * k3.1);
                let nx = x + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
                let nv = v + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
                // The next stage sees this stage's output; with sub-steps this is a fine
                // approximation of the cascade (error far below the noise used in tests).
                input = nx;
                *s = (nx, nv);
            }
        }
    }
    y
}

/// A step from `lo` to `hi` at sample `at`, `n` samples long.
pub fn step(n: usize, at: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n).map(|k| if k >= at { hi } else { lo }).collect()
}

/// Adds white Gaussian noise of standard deviation `sigma`.
pub fn add_noise(x: &[f64], sigma: f64, rng: &mut Rng) -> Vec<f64> {
    x.iter().map(|v| v + sigma * rng.gauss()).collect()
}

/// `y = q^-d B/A u`, zero initial conditions, written independently of the crate.
pub fn arx_filter(b: &[f64], a: &[f64], d: usize, u: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; u.len()];
    for k in 0..u.len() {
        let mut acc = 0.0;
        for (i, bi) in b.iter().enumerate() {
            if k >= i + d {
                acc += bi * u[k - i - d];
            }
        }
        for (i, ai) in a.iter().enumerate() {
            if k > i {
                acc -= ai * y[k - i - 1];
            }
        }
        y[k] = acc;
    }
    y
}

/// Normalised RMS difference over the range of `reference`.
pub fn nrmse(reference: &[f64], other: &[f64]) -> f64 {
    let n = reference.len().min(other.len());
    let rms = (reference
        .iter()
        .zip(other)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / n as f64)
        .sqrt();
    let lo = reference.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = reference.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    rms / (hi - lo)
}

/// Writes a `t,u,y` CSV.
pub fn write_csv(path: &std::path::Path, fs: f64, u: &[f64], y: &[f64]) {
    let mut s = String::from("t,u,y\n");
    for (k, (a, b)) in u.iter().zip(y).enumerate() {
        s.push_str(&format!("{:.9},{a},{b}\n", k as f64 / fs));
    }
    std::fs::write(path, s).expect("write test csv");
}
pub mod hidden;
