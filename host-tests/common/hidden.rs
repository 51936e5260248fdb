//! Step tests with a hidden physical effect, for the modelling loop's tests and its score table
//! (`host-tests/modelling.rs`, `examples/bench_diagnose.rs`).
//!
//! Each case simulates an estimation test (a rising step) and validation tests (steps of other
//! amplitudes, falling by default) of a lumped line, with one effect the user's plain model
//! does not have; the user fits the plain model with the case's options, runs the diagnosis,
//! adds what it names and refits.

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
    /// Orifice (quadratic) losses on the line's mode:
    /// `y'' + (2 zeta w + k |y'|) y' + w^2 y = w^2 u(t - delay)`, with this `k` (per probe
    /// unit), simulated by fine-step RK4.
    NonlinearDamping(f64),
    /// The transducers' diaphragm resonance (natural frequency Hz, damping): the reference is
    /// measured through it (`u = S p`), and the probe's identical transducer, shaken by the
    /// same shock, rings by `probe` times the step (`y = L p + probe (S p - p)`).
    SensorResonance { f: f64, zeta: f64, probe: f64 },
    /// The validation tests are made at this gas temperature (K), the estimation test at
    /// 293.15 K: the line's natural frequencies scale by the ratio of the speeds of sound
    /// (the physics module's air), its delay by the inverse.
    Temperature(f64),
    /// Nothing hidden.
    None,
}

/// The default excitation: a rising unit step (estimation), a falling step of 0.65.
pub const TWO_STEPS: &[(f64, f64)] = &[(0.0, 1.0), (1.0, 0.35)];

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
    /// The tests' steps `(from, to)`; the first is the estimation test.
    pub steps: &'static [(f64, f64)],
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

    /// `(u, y)` of the estimation test and the validation tests.
    #[must_use]
    pub fn tests(&self, seed: u64) -> Vec<(Vec<f64>, Vec<f64>)> {
        let mut rng = Rng::new(seed);
        let onsets = [self.n / 8, self.n / 5, self.n / 6, self.n / 7];
        self.steps
            .iter()
            .zip(onsets.iter().cycle())
            .enumerate()
            .map(|(i, (&(lo, hi), &at))| {
                let u_true = step(self.n, at, lo, hi);
                let size = hi - lo;
                let mut modes: Vec<(f64, f64)> = match self.hidden {
                    Hidden::Mode(f, z) => vec![self.mode, (f, z)],
                    _ => vec![self.mode],
                };
                modes.extend(self.second);
                let mut delay = self.delay;
                if let Hidden::Temperature(t) = self.hidden {
                    if i > 0 {
                        let a = |t| unlag::physics::gas::Gas::air(t, 101_325.0).speed_of_sound();
                        let k = a(t) / a(REFERENCE_K);
                        modes.iter_mut().for_each(|m| m.0 *= k);
                        delay = (self.delay as f64 / k).round() as usize;
                    }
                }
                let mut y = match self.hidden {
                    Hidden::NonlinearDamping(k) => {
                        quadratic_line(&u_true, self.fs, self.mode, k, self.delay)
                    }
                    _ => continuous_line(&u_true, self.fs, &modes, delay),
                };
                // The transducers' ringing: the reference through its diaphragm, the probe
                // shaken.
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
            .collect()
    }
}

/// One mode with orifice losses, `y'' + (2 zeta w + k |y'|) y' + w^2 y = w^2 u(t - delay)`,
/// driven by `u` held between samples, by RK4 with 64 steps per sample, from rest at `u[0]`.
/// Written apart from the crate (which models the same losses in discrete time).
pub fn quadratic_line(u: &[f64], fs: f64, mode: (f64, f64), k: f64, delay: usize) -> Vec<f64> {
    let (f, zeta) = mode;
    let w = 2.0 * std::f64::consts::PI * f;
    let sub = 64;
    let h = 1.0 / (fs * sub as f64);
    let u0 = u[0];
    let (mut x, mut v) = (u0, 0.0);
    let mut y = Vec::with_capacity(u.len());
    for i in 0..u.len() {
        y.push(x);
        let ui = if i >= delay { u[i - delay] } else { u0 };
        let deriv = |x: f64, v: f64| (v, w * w * (ui - x) - (2.0 * zeta * w + k * v.abs()) * v);
        for _ in 0..sub {
            let k1 = deriv(x, v);
            let k2 = deriv(x + 0.5 * h * k1.0, v + 0.5 * h * k1.1);
            let k3 = deriv(x + 0.5 * h * k2.0, v + 0.5 * h * k2.1);
            let k4 = deriv(x + h * k3.0, v + h * k3.1);
            x += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            v += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        }
    }
    y
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
        steps: TWO_STEPS,
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
            steps: &[(1.0, 0.0), (0.2, 0.9)],
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
            steps: &[(1.0, 0.0), (0.2, 0.9)],
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
        Case {
            name: "nonlinear damping: orifice, 110 Hz, steps 1, -0.6, 0.3",
            kind: "nonlinear-damping",
            fs: 10_000.0,
            mode: (110.0, 0.12),
            delay: 17,
            noise: 0.002,
            n: 4000,
            hidden: Hidden::NonlinearDamping(0.5),
            order: 2,
            steps: &[(0.0, 1.0), (1.0, 0.4), (0.0, 0.3)],
            second: None,
        },
        Case {
            name: "nonlinear damping: turbulent, 70 Hz, 20 kHz, steps 1.5, -0.5",
            kind: "nonlinear-damping",
            fs: 20_000.0,
            mode: (70.0, 0.2),
            delay: 30,
            noise: 0.002,
            n: 6000,
            hidden: Hidden::NonlinearDamping(0.3),
            order: 2,
            steps: &[(-0.5, 1.0), (1.0, 0.5)],
            second: None,
        },
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
    /// Residual against amplitude across the tests (the plain model's structure fitted to
    /// each alone).
    pub signature: Option<unlag::diagnose::AmplitudeSignature>,
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
    let data = case.tests(seed);
    let names = ["estimation", "validation", "validation 2", "validation 3"];
    let tests: Vec<Test<'_>> = data
        .iter()
        .zip(names.iter().cycle())
        .map(|((u, y), name)| Test { name, u, y })
        .collect();
    let (uv, yv) = (&data[1].0, &data[1].1);
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
    let signature = diagnose::amplitude_signature(&diagnose::per_test(&current, &tests, &evidence));
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
                    let ym = effects::predict(&f.model, &fx, uv, yv);
                    unlag::fit::nrmse_of(&effects::observed(&fx, case.fs, yv), &ym)
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
        signature,
    }
}
