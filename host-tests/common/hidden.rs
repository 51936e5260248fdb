//! Step tests with a hidden physical effect, for the modelling loop's tests and its score table
//! (`host-tests/modelling.rs`, `examples/bench_diagnose.rs`).
//!
//! Each case simulates an estimation test (a rising step) and a validation test (a falling step
//! of another amplitude) of a lumped line, with one effect the user's plain model does not
//! have; the user fits the plain model with the case's options, runs the diagnosis, adds what
//! it names and refits.

use super::{continuous_line, step, Rng};
use unlag::fit::{Method, Options, Order};

/// One hidden effect (or none).
#[derive(Debug, Clone, Copy)]
pub enum Hidden {
    /// A second line mode (natural frequency, damping) the plain model lacks.
    Mode(f64, f64),
    /// A leaking side volume: the probe first reaches `fraction` of the step, the rest creeps
    /// in with time constant `tau_s`.
    Leak { fraction: f64, tau_s: f64 },
    /// A zero offset, as a fraction of the step.
    Offset(f64),
    /// A drift, as a fraction of the step per second.
    Drift(f64),
    /// The user fits with this (wrong) delay.
    WrongDelay(usize),
    /// AR(1) measurement noise with this lag-1 correlation; the user fits by direct least
    /// squares.
    ColouredNoise(f64),
    /// The transducers' diaphragm resonance (natural frequency Hz, damping): the reference is
    /// measured through it (`u = S p`), and the probe's identical transducer, shaken by the
    /// same shock, rings by `probe` times the step (`y = L p + probe (S p - p)`).
    SensorResonance { f: f64, zeta: f64, probe: f64 },
    /// The validation test is made at this gas temperature (K), the estimation test at
    /// 293.15 K: the line's natural frequencies scale by the ratio of the speeds of sound
    /// (the physics module's air), its delay by the inverse.
    Temperature(f64),
    /// Nothing hidden.
    None,
}

/// Gas temperature of the estimation tests (K).
pub const REFERENCE_K: f64 = 293.15;

/// One case.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    /// Name in the score table.
    pub name: &'static str,
    /// The machine-readable kind the diagnosis must name first.
    pub kind: &'static str,
    /// Sample rate (Hz).
    pub fs: f64,
    /// The line's (first) mode.
    pub mode: (f64, f64),
    /// True delay (samples).
    pub delay: usize,
    /// White noise, fraction of the step.
    pub noise: f64,
    /// Samples per test.
    pub n: usize,
    /// The hidden effect.
    pub hidden: Hidden,
    /// The order of the user's plain model.
    pub order: usize,
    /// Reference levels `(before, after)` of the estimation and the validation step.
    pub levels: [(f64, f64); 2],
    /// A second line mode present in every test (natural frequency, damping), if any.
    pub second: Option<(f64, f64)>,
}

impl Case {
    /// The options of the user's plain fit.
    #[must_use]
    pub fn options(&self) -> Options {
        Options {
            method: match self.hidden {
                Hidden::ColouredNoise(_) => Method::Arx,
                _ => Method::Oe,
            },
            order: Order::Fixed(self.order),
            delay: match self.hidden {
                Hidden::WrongDelay(d) => Some(d),
                _ => None,
            },
        }
    }

    /// `(u, y)` of the estimation and the validation test.
    #[must_use]
    pub fn tests(&self, seed: u64) -> [(Vec<f64>, Vec<f64>); 2] {
        let mut rng = Rng::new(seed);
        let [(l0, h0), (l1, h1)] = self.levels;
        [(l0, h0, self.n / 8, 0), (l1, h1, self.n / 5, 1)].map(|(lo, hi, at, i)| {
            let u_true = step(self.n, at, lo, hi);
            let size = hi - lo;
            let mut modes: Vec<(f64, f64)> = match self.hidden {
                Hidden::Mode(f, z) => vec![self.mode, (f, z)],
                _ => vec![self.mode],
            };
            modes.extend(self.second);
            let mut delay = self.delay;
            if let (Hidden::Temperature(t), 1) = (self.hidden, i) {
                let a = |t| unlag::physics::gas::Gas::air(t, 101_325.0).speed_of_sound();
                let k = a(t) / a(REFERENCE_K);
                modes.iter_mut().for_each(|m| m.0 *= k);
                delay = (self.delay as f64 / k).round() as usize;
            }
            let mut y = continuous_line(&u_true, self.fs, &modes, delay);
            // The transducers' ringing: the reference through its diaphragm, the probe shaken.
            let u_true = match self.hidden {
                Hidden::SensorResonance { f, zeta, probe } => {
                    let sp = continuous_line(&u_true, self.fs, &[(f, zeta)], 0);
                    y.iter_mut()
                        .zip(sp.iter().zip(&u_true))
                        .for_each(|(v, (s, p))| *v += probe * (s - p));
                    sp
                }
                _ => u_true,
            };
            match self.hidden {
                Hidden::Leak { fraction, tau_s } => {
                    // y = fraction * line + (1 - fraction) * slow(line), slow a first-order lag
                    // in equilibrium at the start.
                    let p = (-1.0 / (tau_s * self.fs)).exp();
                    let mut s = y[0];
                    for v in &mut y {
                        let line = *v;
                        s = p * s + (1.0 - p) * line;
                        *v = fraction * line + (1.0 - fraction) * s;
                    }
                }
                Hidden::Offset(c) => y.iter_mut().for_each(|v| *v += c),
                Hidden::Drift(rate) => y
                    .iter_mut()
                    .enumerate()
                    .for_each(|(k, v)| *v += rate * k as f64 / self.fs),
                _ => {}
            }
            let sigma = self.noise * size.abs();
            match self.hidden {
                Hidden::ColouredNoise(rho) => {
                    let mut e = 0.0;
                    let scale = (1.0 - rho * rho).sqrt();
                    for v in &mut y {
                        e = rho * e + scale * sigma * rng.gauss();
                        *v += e;
                    }
                }
                _ => y.iter_mut().for_each(|v| *v += sigma * rng.gauss()),
            }
            let u: Vec<f64> = u_true
                .iter()
                .map(|v| v + 0.2 * sigma * rng.gauss())
                .collect();
            (u, y)
        })
    }
}

/// The catalogue's cases: every supported kind twice, with different parameters and sample
/// rates, and two cases with nothing hidden.
#[must_use]
pub fn cases() -> Vec<Case> {
    let line = |name, kind, fs, delay, hidden, order| Case {
        name,
        kind,
        fs,
        mode: (95.0, 0.3),
        delay,
        noise: 0.002,
        n: 4000,
        hidden,
        order,
        levels: [(0.0, 1.0), (1.0, 0.35)],
        second: None,
    };
    vec![
        line(
            "mode: second mode 362 Hz",
            "mode",
            10_000.0,
            17,
            Hidden::Mode(362.0, 0.16),
            2,
        ),
        line(
            "mode: cavity 300 Hz, 20 kHz",
            "mode",
            20_000.0,
            30,
            Hidden::Mode(300.0, 0.1),
            2,
        ),
        line(
            "leak: 8 % creep, 20 ms",
            "leak",
            10_000.0,
            17,
            Hidden::Leak {
                fraction: 0.92,
                tau_s: 0.02,
            },
            2,
        ),
        line(
            "leak: 4 % creep, 40 ms, 20 kHz",
            "leak",
            20_000.0,
            30,
            Hidden::Leak {
                fraction: 0.96,
                tau_s: 0.04,
            },
            2,
        ),
        line(
            "offset: +2 % of the step",
            "offset",
            10_000.0,
            17,
            Hidden::Offset(0.02),
            2,
        ),
        line(
            "offset: -1 %, 20 kHz",
            "offset",
            20_000.0,
            30,
            Hidden::Offset(-0.01),
            2,
        ),
        line(
            "drift: +5 %/s",
            "drift",
            10_000.0,
            17,
            Hidden::Drift(0.05),
            2,
        ),
        line(
            "drift: -8 %/s, 20 kHz",
            "drift",
            20_000.0,
            30,
            Hidden::Drift(-0.08),
            2,
        ),
        line(
            "delay: fitted with 8, true 17",
            "delay",
            10_000.0,
            17,
            Hidden::WrongDelay(8),
            2,
        ),
        line(
            "delay: fitted with 20, true 50, 20 kHz",
            "delay",
            20_000.0,
            50,
            Hidden::WrongDelay(20),
            2,
        ),
        line(
            "coloured noise: AR(1) 0.9, ARX fit",
            "coloured-noise",
            10_000.0,
            17,
            Hidden::ColouredNoise(0.9),
            2,
        ),
        line(
            "coloured noise: AR(1) 0.97, ARX fit, 20 kHz",
            "coloured-noise",
            20_000.0,
            30,
            Hidden::ColouredNoise(0.97),
            2,
        ),
        line(
            "sensor resonance: 2 kHz, both channels",
            "sensor-resonance",
            10_000.0,
            17,
            Hidden::SensorResonance {
                f: 2_000.0,
                zeta: 0.03,
                probe: 0.3,
            },
            2,
        ),
        Case {
            levels: [(1.0, 0.0), (0.2, 0.9)],
            ..line(
                "sensor resonance: 5 kHz, falling step, 20 kHz",
                "sensor-resonance",
                20_000.0,
                30,
                Hidden::SensorResonance {
                    f: 5_000.0,
                    zeta: 0.05,
                    probe: 0.5,
                },
                2,
            )
        },
        line(
            "temperature: validation at 343 K",
            "temperature",
            10_000.0,
            17,
            Hidden::Temperature(343.15),
            2,
        ),
        Case {
            levels: [(1.0, 0.0), (0.2, 0.9)],
            second: Some((362.0, 0.16)),
            ..line(
                "temperature: two modes, validation at 253 K, falling step, 20 kHz",
                "temperature",
                20_000.0,
                30,
                Hidden::Temperature(253.15),
                4,
            )
        },
        line("none: clean line", "none", 10_000.0, 17, Hidden::None, 2),
        line(
            "none: clean line, 20 kHz",
            "none",
            20_000.0,
            30,
            Hidden::None,
            2,
        ),
    ]
}

/// What one case gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The kinds named, best first.
    pub named: Vec<String>,
    /// Validation error of the plain model.
    pub before: f64,
    /// Validation error after adding the first candidate and refitting.
    pub after: f64,
    /// Noise floor of the validation test.
    pub floor: f64,
}

impl Outcome {
    /// The loop worked: the hidden kind named first, and adding it cut the error 3x or to
    /// within 1.5x of the noise floor (for `none`: nothing to add).
    #[must_use]
    pub fn passed(&self, kind: &str) -> bool {
        self.named.first().map(String::as_str) == Some(kind)
            && (kind == "none" || self.before / self.after >= 3.0 || self.after <= 1.5 * self.floor)
    }
}

/// Runs the loop on a case: plain fit, diagnosis, add the first candidate, refit.
///
/// # Panics
/// When the plain fit fails (a broken case).
#[must_use]
pub fn run(case: &Case, seed: u64) -> Outcome {
    use unlag::diagnose::{self, Current};
    use unlag::effects::{self, Effect};
    use unlag::fit::Test;
    let [(ue, ye), (uv, yv)] = case.tests(seed);
    let tests = [
        Test {
            name: "estimation",
            u: &ue,
            y: &ye,
        },
        Test {
            name: "validation",
            u: &uv,
            y: &yv,
        },
    ];
    let options = case.options();
    let (plain, fx) =
        effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[]).expect("plain fit");
    let current = Current {
        model: &plain.model,
        effects: &fx,
        method: options.method,
    };
    let evidence = diagnose::evidence(&current, &tests);
    let candidates = diagnose::diagnose(&current, &tests, &evidence).expect("diagnosis");
    let named: Vec<String> = candidates.iter().map(|c| c.kind.clone()).collect();
    let before = evidence[1].nrmse;
    let floor = evidence[1].noise_floor;
    let after = match candidates.first() {
        Some(c) if c.kind != "none" => {
            let effect = if c.kind == "delay" {
                let d = c.evidence["best_delay"].as_u64().unwrap_or(0) as usize;
                Effect::Delay { samples: d }
            } else {
                Effect::parse(&c.kind).expect("a known kind")
            };
            match effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[effect]) {
                Ok((f, fx)) => {
                    let ym = effects::predict(&f.model, &fx, &uv, &yv);
                    unlag::fit::nrmse_of(&effects::observed(&fx, case.fs, &yv), &ym)
                }
                Err(_) => f64::NAN,
            }
        }
        _ => before,
    };
    Outcome {
        named,
        before,
        after,
        floor,
    }
}
