//! Step tests with a hidden physical effect, for the modelling loop's tests and its score table
//! (`host-tests/modelling.rs`, `examples/bench_diagnose.rs`).
//!
//! Each case simulates an estimation test (a rising step) and validation tests (steps of other
//! amplitudes, falling by default) of a line, with one effect the user's plain model does not
//! have; the user fits the plain model with the case's options, runs the diagnosis, adds what
//! it names and refits.
//!
//! Where the tests come from:
//!
//! * the cases of [`cases`] before the `physics ...` ones: lumped second-order modes
//!   ([`continuous_line`], RK4, written apart from the crate), with the effect added by hand;
//!   the `temperature` ones take the speed of sound from the physics module's air;
//! * the `physics ...` cases ([`physical_cases`], [`Hidden::Physics`]): every test simulated by
//!   the physics module at the library level ([`unlag::physics::simulate`]): the
//!   Bergh-Tijdeman response of a tube and its end volume in air (non-rational: viscothermal
//!   damping that depends on frequency, every acoustic mode, the front delay `L/a`), driven by
//!   a shock tube, a balloon or a valve; the hidden effect is what the physics puts there:
//!   - `mode`: lines whose second acoustic mode the plain order-2 model misses, and series
//!     lines (tube, intermediate volume, tube, transducer volume) whose second stage adds one;
//!   - `leak`: a large end cavity whose gas relaxes thermally (the physics module's
//!     `CavityThermal::Relaxing`): a slow creep after the step, the catalogue's `leak`
//!     signature (a slow pole-zero pair). The physics module's cavity *leak* to the reference
//!     pressure (`leak_m3_per_s_pa`) only lowers the DC gain (`1/(1 + R_line G)`) with the
//!     dynamics unchanged; the plain model's free gain absorbs it, so that case is a `none`;
//!   - `none`: short lines with a large volume (the first mode well separated, the higher
//!     ones weakly excited), where the plain order 2 is adequate, and the leaking cavity;
//!   - `temperature`: the same line's Bergh-Tijdeman response with the validation tests in air
//!     at another temperature (speed of sound, Sutherland viscosity, density: all move); on
//!     the well-damped line the damping moves too, and the diagnosis offers the effect's
//!     viscous damping law (`temperature-viscous`);
//! * [`physical_limits`]: physical cases that do not meet the criterion, kept apart (shown by
//!   the score table, not asserted), each with the reason beside it: a thermal creep behind a
//!   line whose second mode is named first, a reference transducer's resonance that the line
//!   makes invisible, and the physics module's describing-function minor losses.

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
    /// AR(1) measurement noise with this lag-1 correlation and `ratio` times the white
    /// noise's level, on top of it; the user fits by output error (unbiased by it: only a
    /// noise model lowers the error).
    ColouredNoiseOe { rho: f64, ratio: f64 },
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
    /// Every test simulated by the physics module ([`unlag::physics::simulate`]): the
    /// Bergh-Tijdeman response of this tube and end volume in air, sampled from a facility's
    /// excitation. What is hidden is whatever the physics makes of it (named by the case's
    /// `kind`); the case's `mode`, `delay` and `second` are not used.
    Physics(Physical),
}

/// How a facility makes each step of a [`Physical`] case (the physics module's excitations).
#[derive(Debug, Clone, Copy)]
pub enum Facility {
    /// A shock-tube step (1 µs rise).
    ShockTube,
    /// A burst balloon (700 µs raised-cosine fall; a rising step rises the same way).
    Balloon,
    /// A fast-opening valve (200 µs opening).
    Valve,
}

/// A probe of the physics module: one Bergh-Tijdeman tube ending in a volume, in air at
/// one atmosphere.
#[derive(Debug, Clone, Copy)]
pub struct Physical {
    /// Tube length (m).
    pub length_m: f64,
    /// Tube inner radius (m).
    pub radius_m: f64,
    /// The end (transducer) volume (m^3).
    pub volume_m3: f64,
    /// Leak conductance of the end volume to the reference pressure (m^3/(s Pa)); 0: tight.
    pub leak_m3_per_s_pa: f64,
    /// The end volume's gas relaxes thermally (a cylindrical cavity of this radius, m), else
    /// it is isentropic.
    pub relaxing_radius_m: Option<f64>,
    /// Gas temperature of the validation tests (K); the estimation test is at [`REFERENCE_K`].
    pub validation_k: f64,
    /// How the steps are made.
    pub facility: Facility,
    /// Minor (orifice) loss coefficient `K` of the line's ends (0: none), applied by the
    /// physics module's describing function for each test's step amplitude
    /// ([`unlag::physics::nonlinear`]).
    pub minor_loss_k: f64,
    /// Pascal per unit of the steps (sets the flow amplitude of the minor losses).
    pub pa_per_unit: f64,
    /// The reference transducer's diaphragm resonance `(Hz, damping)`, if any (the probe's
    /// transducer is ideal).
    pub reference_sensor: Option<(f64, f64)>,
    /// A second tube and volume `(length m, radius m, volume m^3)` after the first volume
    /// (which is then an intermediate volume: a series line, BT section 2), if any.
    pub second_stage: Option<(f64, f64, f64)>,
}

impl Physical {
    /// The line of the physics module.
    #[must_use]
    pub fn line(&self) -> unlag::physics::Line {
        use unlag::physics::{CavityThermal, Element, Line, Volume};
        let line = Line::new()
            .tube(self.length_m, self.radius_m)
            .with(Element::Volume(Volume {
                volume_m3: self.volume_m3,
                sigma: 0.0,
                thermal: match self.relaxing_radius_m {
                    Some(radius_m) => CavityThermal::Relaxing { radius_m },
                    None => CavityThermal::Polytropic(1.4),
                },
                leak_m3_per_s_pa: self.leak_m3_per_s_pa,
            }));
        match self.second_stage {
            Some((length_m, radius_m, volume_m3)) => {
                line.tube(length_m, radius_m).volume(volume_m3)
            }
            None => line,
        }
    }

    /// Noise-free `(reference, probe)` of a step from `lo` to `hi` at sample `at`, `n`
    /// samples at `fs`, in air at `temperature_k`, by the physics module's time-domain
    /// simulation (32x oversampled). The levels are the step's units (the line is linear).
    ///
    /// # Panics
    /// When the physics module refuses the settings (a broken case).
    #[must_use]
    pub fn step_test(
        &self,
        fs: f64,
        n: usize,
        at: usize,
        (lo, hi): (f64, f64),
        temperature_k: f64,
    ) -> (Vec<f64>, Vec<f64>) {
        use unlag::physics::{simulate, Acquisition, Excitation, Gas, Probe};
        let gas = Gas::air(temperature_k, 101_325.0);
        let line = if self.minor_loss_k > 0.0 {
            let losses = unlag::physics::nonlinear::MinorLosses {
                k: self.minor_loss_k,
                step_amplitude_pa: (hi - lo).abs() * self.pa_per_unit,
            };
            unlag::physics::nonlinear::equivalent_resistance(&self.line(), &gas, &losses)
                .expect("minor losses")
                .line
        } else {
            self.line()
        };
        let dc = line.dc_gain(&gas);
        let probe = Probe::new(line, gas);
        let excitation = match self.facility {
            Facility::ShockTube => Excitation::shock_tube(hi - lo),
            // A balloon starts `amplitude` above its final level.
            Facility::Balloon => Excitation::balloon(lo - hi),
            Facility::Valve => Excitation::valve(hi - lo),
        };
        let mut acquisition = Acquisition::new(fs, n as f64 / fs);
        // Mid-sample, so the step's first sample is a cell average like a real ADC's.
        acquisition.event_time_s = (at as f64 - 0.5) / fs;
        acquisition.reference_sensor =
            self.reference_sensor
                .map(
                    |(natural_frequency_hz, damping)| unlag::physics::Diaphragm {
                        natural_frequency_hz,
                        damping,
                    },
                );
        let t = simulate(&probe, &excitation, &acquisition).expect("physics step test");
        let base = match self.facility {
            Facility::Balloon => hi,
            _ => lo,
        };
        let u = t.reference.iter().map(|v| v + base).collect();
        let y = t.probe_clean.iter().map(|v| v + dc * base).collect();
        (u, y)
    }
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
                let size = hi - lo;
                if let Hidden::Physics(p) = self.hidden {
                    let t = if i > 0 { p.validation_k } else { REFERENCE_K };
                    let (u_true, mut y) = p.step_test(self.fs, self.n, at, (lo, hi), t);
                    let sigma = self.noise * size.abs();
                    y.iter_mut().for_each(|v| *v += sigma * rng.gauss());
                    let u: Vec<f64> = u_true
                        .iter()
                        .map(|v| v + 0.2 * sigma * rng.gauss())
                        .collect();
                    return (u, y);
                }
                let u_true = step(self.n, at, lo, hi);
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
                    Hidden::ColouredNoiseOe { rho, ratio } => {
                        let mut e = 0.0;
                        let scale = (1.0 - rho * rho).sqrt();
                        for v in &mut y {
                            e = rho * e + scale * ratio * sigma * rng.gauss();
                            *v += e + sigma * rng.gauss();
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

/// The catalogue's cases: every supported kind at least twice, with different parameters and
/// sample rates, and two cases with nothing hidden.
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
    let mut v = vec![
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
            "coloured noise: AR(1) 0.97, 10x white, output-error fit",
            "coloured-noise",
            10_000.0,
            17,
            Hidden::ColouredNoiseOe {
                rho: 0.97,
                ratio: 10.0,
            },
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
        // A 5 kHz ringing of half the step that dies in 13 samples: the plain model sits under
        // this test's noise floor (0.82 % against 0.94 %), and was kept apart as one the
        // diagnosis cannot see while its trial kept the plain model's delay. The transducers'
        // modes move the step's apparent onset; searched again, the delay lets their trial
        // lower the held-out error 1.5x, to 0.55 %, and the diagnosis names them.
        Case {
            name: "sensor resonance: 5 kHz, falling step, 20 kHz",
            kind: "sensor-resonance",
            fs: 20_000.0,
            mode: (95.0, 0.3),
            delay: 30,
            noise: 0.002,
            n: 4000,
            hidden: Hidden::SensorResonance {
                f: 5_000.0,
                zeta: 0.05,
                probe: 0.5,
            },
            order: 2,
            steps: &[(1.0, 0.0), (0.2, 0.9)],
            second: None,
        },
    ];
    v.extend(physical_cases());
    v
}

/// The cases simulated by the physics module (Bergh-Tijdeman lines, [`Hidden::Physics`]).
#[must_use]
pub fn physical_cases() -> Vec<Case> {
    let tight = Physical {
        length_m: 0.6,
        radius_m: 0.55e-3,
        volume_m3: 20e-9,
        leak_m3_per_s_pa: 0.0,
        relaxing_radius_m: None,
        validation_k: REFERENCE_K,
        facility: Facility::ShockTube,
        minor_loss_k: 0.0,
        pa_per_unit: 1.0,
        reference_sensor: None,
        second_stage: None,
    };
    let case = |name, kind, fs, n, order, steps, p| Case {
        name,
        kind,
        fs,
        mode: (0.0, 0.0),
        delay: 0,
        noise: 0.002,
        n,
        hidden: Hidden::Physics(p),
        order,
        steps,
        second: None,
    };
    vec![
        case(
            "physics mode: BT 0.6 m x 1.1 mm, 20 mm3 (112/362 Hz), shock tube",
            "mode",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            tight,
        ),
        case(
            "physics mode: BT 1 m x 1.5 mm, 50 mm3, valve, 20 kHz",
            "mode",
            20_000.0,
            8000,
            2,
            &[(0.2, 1.2), (1.0, 0.4)],
            Physical {
                length_m: 1.0,
                radius_m: 0.75e-3,
                volume_m3: 50e-9,
                facility: Facility::Valve,
                ..tight
            },
        ),
        case(
            "physics mode: two stages, 0.1 m x 1 mm to 1000 mm3, 0.05 m x 0.6 mm to 100 mm3",
            "mode",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.5e-3,
                volume_m3: 1000e-9,
                second_stage: Some((0.05, 0.3e-3, 100e-9)),
                ..tight
            },
        ),
        case(
            "physics mode: two stages, 0.2 m x 1.6 mm to 2000 mm3, 0.05 m x 1 mm to 50 mm3, balloon",
            "mode",
            10_000.0,
            4000,
            2,
            &[(1.0, 0.0), (0.2, 0.9)],
            Physical {
                length_m: 0.2,
                radius_m: 0.8e-3,
                volume_m3: 2000e-9,
                second_stage: Some((0.05, 0.5e-3, 50e-9)),
                facility: Facility::Balloon,
                ..tight
            },
        ),
        case(
            "physics leak: thermal creep, 0.5 m x 1.34 mm, 4000 mm3 r 2.5 mm, balloon, 20 kHz",
            "leak",
            20_000.0,
            8000,
            2,
            &[(1.0, 0.0), (0.2, 0.9)],
            Physical {
                length_m: 0.5,
                radius_m: 0.67e-3,
                volume_m3: 4000e-9,
                relaxing_radius_m: Some(2.5e-3),
                facility: Facility::Balloon,
                ..tight
            },
        ),
        case(
            "physics leak: thermal creep, 0.5 m x 1.34 mm, 4000 mm3 cavity r 2 mm",
            "leak",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.5,
                radius_m: 0.67e-3,
                volume_m3: 4000e-9,
                relaxing_radius_m: Some(2e-3),
                ..tight
            },
        ),
        case(
            "physics none: leaking cavity (G 5e-10, DC gain 0.964), BT 0.1 m x 1 mm",
            "none",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.5e-3,
                volume_m3: 1000e-9,
                leak_m3_per_s_pa: 5e-10,
                ..tight
            },
        ),
        case(
            "physics none: BT 0.1 m x 1 mm, 1000 mm3",
            "none",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.5e-3,
                volume_m3: 1000e-9,
                ..tight
            },
        ),
        case(
            "physics none: BT 0.3 m x 0.7 mm, 300 mm3, balloon, 20 kHz",
            "none",
            20_000.0,
            8000,
            2,
            &[(1.0, 0.0), (0.2, 0.9)],
            Physical {
                length_m: 0.3,
                radius_m: 0.35e-3,
                volume_m3: 300e-9,
                facility: Facility::Balloon,
                ..tight
            },
        ),
        case(
            "physics temperature: BT 0.1 m x 1.6 mm, 1000 mm3, 343 K",
            "temperature",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.8e-3,
                volume_m3: 1000e-9,
                validation_k: 343.15,
                ..tight
            },
        ),
        // A well-damped line (damping about 0.22): its Bergh-Tijdeman damping rises some 20 %
        // from 293 to 343 K with the kinematic viscosity, which only the viscous law of the
        // `temperature` effect follows (`--add temperature-viscous`; with the damping kept the
        // error fell only 1.6x, 0.752 % -> 0.473 %, floor 0.138 %, seed 11).
        case(
            "physics temperature: BT 0.1 m x 1 mm, 1000 mm3, validation at 343 K",
            "temperature",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.5e-3,
                volume_m3: 1000e-9,
                validation_k: 343.15,
                ..tight
            },
        ),
        case(
            "physics temperature: BT 0.2 m x 2 mm, 2000 mm3, 253 K, valve, 20 kHz",
            "temperature",
            20_000.0,
            8000,
            2,
            &[(1.0, 0.0), (0.2, 0.9)],
            Physical {
                length_m: 0.2,
                radius_m: 1e-3,
                volume_m3: 2000e-9,
                validation_k: 253.15,
                facility: Facility::Valve,
                ..tight
            },
        ),
    ]
}

/// What one case gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The kinds named, best first.
    pub named: Vec<unlag::modelling::diagnose::Finding>,
    /// Validation error of the plain model.
    pub before: f64,
    /// Validation error after adding the first candidate and refitting.
    pub after: f64,
    /// Noise floor of the validation test.
    pub floor: f64,
    /// Residual against amplitude across the tests (the plain model's structure fitted to
    /// each alone).
    pub signature: Option<unlag::modelling::diagnose::AmplitudeSignature>,
    /// The effects the plain fit found by itself (a clear offset before the step).
    pub found: Vec<unlag::effects::EffectKind>,
}

impl Outcome {
    /// The loop worked: the hidden kind named first, and adding it cut the error 3x or to
    /// within 1.5x of the noise floor (for `none`: nothing to add); or the plain fit found it
    /// by itself, nothing else is named and the plain model is within 1.5x of the floor.
    ///
    /// # Panics
    /// When `kind` names nothing a diagnosis can name.
    #[must_use]
    pub fn passed(&self, kind: &str) -> bool {
        use unlag::effects::EffectKind;
        use unlag::modelling::diagnose::Finding;
        let kind: Finding = kind.parse().expect("a kind a diagnosis names");
        let first = self.named.first().copied();
        // An effect the plain fit already found and removed (an offset the quiet segment
        // shows): nothing is left to name, and the plain model is at the noise floor.
        if kind.effect().is_some_and(|k| self.found.contains(&k)) {
            return first == Some(Finding::Nothing) && self.before <= 1.5 * self.floor;
        }
        // `temperature` and `temperature-viscous` are one effect with two damping laws.
        let same = first == Some(kind)
            || (kind == EffectKind::Temperature
                && first
                    .and_then(Finding::effect)
                    .is_some_and(|f| f.family() == EffectKind::Temperature));
        same && (kind == Finding::Nothing
            || self.before / self.after >= 3.0
            || self.after <= 1.5 * self.floor)
    }
}

/// Runs the loop on a case: plain fit, diagnosis, add the first candidate, refit.
///
/// # Panics
/// When the plain fit fails (a broken case).
#[must_use]
pub fn run(case: &Case, seed: u64) -> Outcome {
    use unlag::effects::{self, Effect, EffectKind};
    use unlag::fit::Test;
    use unlag::modelling::diagnose::{self, Current, Finding};
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
        uncertainty: plain.report.uncertainty.as_ref(),
        order_given: true,
    };
    let evidence = diagnose::evidence(&current, &tests);
    let candidates = diagnose::diagnose(&current, &tests, &evidence).expect("diagnosis");
    let named: Vec<Finding> = candidates.iter().map(|c| c.kind).collect();
    let signature = diagnose::amplitude_signature(&diagnose::per_test(&current, &tests, &evidence));
    let before = evidence[1].nrmse;
    let floor = evidence[1].noise_floor;
    let after = match candidates.first() {
        // Nothing to add for `none`, nothing named for `unexplained`.
        Some(c) if c.kind.effect().is_some() => {
            let effect = if c.kind == EffectKind::Delay {
                let d = c.change.delay().unwrap_or(0);
                Effect::Delay { samples: d }
            } else {
                // The `--add` spelling (`temperature-viscous` with its damping law).
                let add = c.kind.effect().expect("an effect");
                Effect::fresh(add).expect("a kind with no value to give")
            };
            match effects::fit_with(&tests[0], &tests[1..], case.fs, &options, &[effect]) {
                // The error the remedy is judged by: the one-step-ahead prediction error
                // with a noise model, the simulation error without (the same for white
                // residuals).
                Ok((f, fx)) => effects::judged_nrmse(&f.model, &fx, uv, yv),
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
        found: fx.iter().map(Effect::kind).collect(),
    }
}

/// Physical cases that do not meet the criterion of [`Outcome::passed`], kept apart (shown by
/// `examples/bench_diagnose.rs`, not asserted): see the comment on each.
#[must_use]
pub fn physical_limits() -> Vec<Case> {
    let tight = physical_cases()
        .first()
        .and_then(|c| match c.hidden {
            Hidden::Physics(p) => Some(p),
            _ => None,
        })
        .expect("a physical case");
    let case = |name, kind, fs, n, order, steps, p| Case {
        name,
        kind,
        fs,
        mode: (0.0, 0.0),
        delay: 0,
        noise: 0.002,
        n,
        hidden: Hidden::Physics(p),
        order,
        steps,
        second: None,
    };
    vec![
        // The thermal creep is there, but so is the 1 m line's second acoustic mode: the
        // diagnosis names `mode` first (both are real; the user's plain model misses both).
        case(
            "physics leak: thermal creep, 1 m x 1.34 mm, 2000 mm3 cavity r 2 mm",
            "leak",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 1.0,
                radius_m: 0.67e-3,
                volume_m3: 2000e-9,
                relaxing_radius_m: Some(2e-3),
                ..tight
            },
        ),
        // Only the reference transducer rings (2 kHz): the probe's line takes nothing above a
        // few hundred Hz from it, so the plain model is already at the noise floor and the
        // diagnosis says `none`, rightly. The catalogue's `sensor-resonance` cases have the
        // probe's transducer shaken by the shock (mechanical ringing), which the physics module
        // does not model: behind a line, a pressure transducer's diaphragm is never excited.
        case(
            "physics sensor resonance: reference transducer 2 kHz, 0.1 m x 1 mm",
            "sensor-resonance",
            10_000.0,
            4000,
            2,
            TWO_STEPS,
            Physical {
                length_m: 0.1,
                radius_m: 0.5e-3,
                volume_m3: 1000e-9,
                reference_sensor: Some((2_000.0, 0.03)),
                ..tight
            },
        ),
        // The physics module's minor losses are a describing function: each test is linear,
        // with its own damping (0.35, 0.41, 0.48 for steps of 0.3, 0.6, 1: the rise is there),
        // but without the waveform distortion of a real quadratic loss, so the residual of each
        // test fitted alone grows like the step (exponent 0.89), not faster; the diagnosis
        // needs both signatures and says `none` (validation error 0.64 % against a floor of
        // 0.15 %). The lumped `nonlinear damping` cases above integrate the real quadratic loss.
        case(
            "physics nonlinear damping: K 1.5, 0.2 m x 1.1 mm, 1000 mm3, 30/18/9 kPa",
            "nonlinear-damping",
            10_000.0,
            4000,
            2,
            &[(0.0, 1.0), (1.0, 0.4), (0.0, 0.3)],
            Physical {
                length_m: 0.2,
                radius_m: 0.55e-3,
                volume_m3: 1000e-9,
                minor_loss_k: 1.5,
                pa_per_unit: 30e3,
                ..tight
            },
        ),
    ]
}
