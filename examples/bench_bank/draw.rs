//! Drawing the bank's cases: a seeded generator and the distributions of every parameter.
//!
//! Kinds and families are dealt round-robin (so every kind meets every family); everything
//! else is drawn: the generator (Bergh-Tijdeman physics or a lumped model), the probe's
//! dynamics or geometry, the effect's size, the noise, the step and the validation test.

use unlag::physics::{find_modes, gas::Gas, lumped, HoleCavity, Line, POISEUILLE_INERTANCE};

/// Gas temperature of every estimation test [K].
pub const REFERENCE_K: f64 = 293.15;

/// A tiny deterministic generator (SplitMix64) with uniform, log-uniform and Gaussian draws.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Log-uniform in `[lo, hi)`.
    pub fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.uniform()).exp()
    }

    /// A whole number in `lo..=hi`.
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as usize
    }

    /// +1 or -1 with equal odds.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Standard normal (Box-Muller).
    pub fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// The paper's three probe families.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Pneumatic lines sampled at 5-10 kHz, natural frequency 20-150 Hz, damping 0.1-1.5.
    Pneumatic,
    /// Recessed or flush sensors (hole and cavity, Helmholtz) at 1 MHz, 30-120 kHz.
    Flush,
    /// Overdamped capillaries (damping 1.5-5) at 2-10 kHz.
    Capillary,
}

/// Every family, in report order.
pub const FAMILIES: [Family; 3] = [Family::Pneumatic, Family::Flush, Family::Capillary];

impl Family {
    /// Name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Self::Pneumatic => "pneumatic",
            Self::Flush => "flush",
            Self::Capillary => "capillary",
        }
    }

    /// Multiplies every slow rate (leak corner, drift) so that it shows in the family's
    /// records: 1 for the kHz families, 100 at 1 MHz (records of milliseconds).
    pub fn slow_scale(self) -> f64 {
        match self {
            Self::Flush => 100.0,
            _ => 1.0,
        }
    }
}

/// The effect a case hides, one per case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Nothing hidden.
    None,
    /// A real pole-zero pair (leak).
    Leak,
    /// A ramp on the probe channel.
    Drift,
    /// A zero offset of the probe channel.
    Offset,
    /// AR(1) noise on the probe channel.
    ColouredNoise,
    /// An extra line mode.
    Mode,
    /// The transducers' diaphragm resonance, on both channels.
    SensorResonance,
    /// Quadratic (orifice) damping.
    NonlinearDamping,
    /// The validation test at another gas temperature.
    Temperature,
}

/// Every kind, in report order.
pub const KINDS: [Kind; 9] = [
    Kind::None,
    Kind::Leak,
    Kind::Drift,
    Kind::Offset,
    Kind::ColouredNoise,
    Kind::Mode,
    Kind::SensorResonance,
    Kind::NonlinearDamping,
    Kind::Temperature,
];

impl Kind {
    /// Name in the report (the CLI's effect names).
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Leak => "leak",
            Self::Drift => "drift",
            Self::Offset => "offset",
            Self::ColouredNoise => "coloured-noise",
            Self::Mode => "mode",
            Self::SensorResonance => "sensor-resonance",
            Self::NonlinearDamping => "nonlinear-damping",
            Self::Temperature => "temperature",
        }
    }
}

/// The drawn effect with its size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Effect {
    /// Nothing.
    None,
    /// `H(s) = (s + g p)/(s + p)`, `p = 2 pi corner`: DC gain `g`, unity at high frequency.
    Leak { corner_hz: f64, dc_gain: f64 },
    /// Probe channel ramp, fraction of the step per second.
    Drift { per_s: f64 },
    /// Probe channel offset, fraction of the step.
    Offset { fraction: f64 },
    /// AR(1) probe noise: lag-1 correlation and its RMS as a multiple of the white level.
    ColouredNoise { rho: f64, ratio: f64 },
    /// An extra second-order mode (lumped) or a second tube and volume (physics).
    Mode {
        f_hz: f64,
        zeta: f64,
        second_stage: Option<(f64, f64, f64)>,
    },
    /// The diaphragm of both transducers.
    SensorResonance { f_hz: f64, zeta: f64 },
    /// Quadratic damping `k |v| v`, `k = ratio 2 zeta / step`: at a velocity of
    /// `step * omega_n` the quadratic term is `ratio` times the linear one.
    NonlinearDamping { ratio: f64 },
    /// Gas temperature of the validation test [K].
    Temperature { kelvin: f64 },
}

impl Effect {
    /// Its parameters as one short text (report and CSV).
    pub fn describe(&self) -> String {
        match *self {
            Self::None => "-".into(),
            Self::Leak { corner_hz, dc_gain } => {
                format!("corner {corner_hz:.3} Hz, dc gain {dc_gain:.3}")
            }
            Self::Drift { per_s } => format!("{:.2} %/s", 100.0 * per_s),
            Self::Offset { fraction } => format!("{:.2} %", 100.0 * fraction),
            Self::ColouredNoise { rho, ratio } => format!("AR(1) {rho:.3}, {ratio:.1}x white"),
            Self::Mode {
                f_hz,
                zeta,
                second_stage,
            } => match second_stage {
                Some((l, r, v)) => format!(
                    "second stage {:.1} mm x {:.2} mm dia to {:.1} mm3",
                    1e3 * l,
                    2e3 * r,
                    1e9 * v
                ),
                None => format!("{f_hz:.0} Hz, damping {zeta:.3}"),
            },
            Self::SensorResonance { f_hz, zeta } => {
                format!("{f_hz:.0} Hz, damping {zeta:.3}")
            }
            Self::NonlinearDamping { ratio } => format!("quadratic/linear {ratio:.2}"),
            Self::Temperature { kelvin } => format!("validation at {kelvin:.1} K"),
        }
    }
}

/// How the probe is simulated.
#[derive(Debug, Clone, PartialEq)]
pub enum Generator {
    /// A lumped second-order line (plus the effect's stages), natural frequency, damping and
    /// a whole-sample delay: RK4 on the state equations, the truth by exact ZOH.
    Lumped { f_hz: f64, zeta: f64, delay: usize },
    /// A Bergh-Tijdeman line of the physics module; the truth is `unlag fit` on a long,
    /// noise-free test.
    Physics { geometry: Geometry },
}

/// A physical probe's geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Geometry {
    /// A tube of this length and radius into a volume [m, m, m^3].
    Tube {
        length_m: f64,
        radius_m: f64,
        volume_m3: f64,
    },
    /// A flush hole of this length and diameter into a cavity [m, m, m^3].
    Hole {
        length_m: f64,
        diameter_m: f64,
        volume_m3: f64,
    },
}

impl Geometry {
    /// The physics module's line in `gas`.
    pub fn line(&self, gas: &Gas) -> Line {
        match *self {
            Self::Tube {
                length_m,
                radius_m,
                volume_m3,
            } => Line::new().tube(length_m, radius_m).volume(volume_m3),
            Self::Hole {
                length_m,
                diameter_m,
                volume_m3,
            } => HoleCavity::flush(length_m, diameter_m, volume_m3).line(gas),
        }
    }

    /// Short text for the report.
    pub fn describe(&self) -> String {
        match *self {
            Self::Tube {
                length_m,
                radius_m,
                volume_m3,
            } => format!(
                "tube {:.3} m x {:.2} mm dia, {:.1} mm3",
                length_m,
                2e3 * radius_m,
                1e9 * volume_m3
            ),
            Self::Hole {
                length_m,
                diameter_m,
                volume_m3,
            } => format!(
                "hole {:.2} mm x {:.2} mm dia, {:.3} mm3",
                1e3 * length_m,
                1e3 * diameter_m,
                1e9 * volume_m3
            ),
        }
    }
}

/// The pressure of one test: `base + ` a facility's excitation from `event_s` on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Test {
    /// What the facility does (the physics module's excitations, used by both generators).
    pub excitation: unlag::physics::Excitation,
    /// Level before the event (a balloon: the final level) [Pa].
    pub base_pa: f64,
    /// Time of the event from the record start [s].
    pub event_s: f64,
    /// Samples.
    pub n: usize,
    /// Short name: step, balloon, valve, wake.
    pub name: &'static str,
}

impl Test {
    /// Short text for the report.
    pub fn describe(&self) -> String {
        use unlag::physics::Excitation as E;
        match self.excitation {
            E::ShockTube { amplitude_pa, .. } => format!(
                "step {:.0} -> {:.0} Pa",
                self.base_pa,
                self.base_pa + amplitude_pa
            ),
            E::Balloon { amplitude_pa, .. } => format!(
                "balloon {:.0} -> {:.0} Pa",
                self.base_pa + amplitude_pa,
                self.base_pa
            ),
            E::Valve {
                amplitude_pa,
                chamber_hz,
                chamber_fraction,
                ..
            } => format!(
                "valve {:.0} -> {:.0} Pa, chamber {:.0} Hz x {:.2}",
                self.base_pa,
                self.base_pa + amplitude_pa,
                chamber_hz,
                chamber_fraction
            ),
            E::CascadeWake {
                wake_depth_pa,
                wake_hz,
                tunnel_amplitude_pa,
                tunnel_hz,
                ..
            } => format!(
                "wake {wake_depth_pa:.0} Pa at {wake_hz:.0} Hz, tunnel {tunnel_amplitude_pa:.0} Pa at {tunnel_hz:.1} Hz"
            ),
        }
    }
}

/// One case of the bank.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// Number, also the directory `case-NNN`.
    pub id: usize,
    /// Probe family.
    pub family: Family,
    /// Hidden effect kind.
    pub kind: Kind,
    /// Its size.
    pub effect: Effect,
    /// How the probe is simulated.
    pub generator: Generator,
    /// Natural frequency [Hz] and damping of the line: drawn (lumped) or the physics
    /// module's prediction (physics: the lumped approximation of a tube, the exact first
    /// Bergh-Tijdeman mode of a hole and cavity).
    pub f_hz: f64,
    /// See `f_hz`.
    pub zeta: f64,
    /// Sample rate [Hz].
    pub fs: f64,
    /// Size of the estimation step [Pa] (the unit of noise, offset, drift).
    pub step_pa: f64,
    /// White noise of the reference channel, fraction of the step.
    pub noise_u: f64,
    /// White noise of the probe channel, fraction of the step.
    pub noise_y: f64,
    /// The estimation test (a step).
    pub est: Test,
    /// The validation test (another excitation).
    pub val: Test,
    /// Seed of this case's noise.
    pub seed: u64,
}

impl Case {
    /// The 16-bit ADC of both channels for signals within `[lo, hi]`: 2.5 steps of full
    /// scale centred on them, wider (by a fifth of a step of margin) only when a ringing
    /// probe or a drift needs it, as an experimenter sets the range after a trial run.
    pub fn adc(&self, lo: f64, hi: f64) -> unlag::physics::simulate::Adc {
        let span = (2.5 * self.step_pa).max(hi - lo + 0.2 * self.step_pa);
        let centre = 0.5 * (lo + hi);
        unlag::physics::simulate::Adc {
            bits: 16,
            min_pa: centre - 0.5 * span,
            max_pa: centre + 0.5 * span,
        }
    }

    /// `lumped` or `physics`.
    pub fn generator_name(&self) -> &'static str {
        match self.generator {
            Generator::Lumped { .. } => "lumped",
            Generator::Physics { .. } => "physics",
        }
    }

    /// The probe in a few words.
    pub fn probe_text(&self) -> String {
        match &self.generator {
            Generator::Lumped { f_hz, zeta, delay } => {
                format!("lumped {f_hz:.1} Hz, damping {zeta:.3}, delay {delay}")
            }
            Generator::Physics { geometry } => format!(
                "{} (predicted {:.1} Hz, damping {:.3})",
                geometry.describe(),
                self.f_hz,
                self.zeta
            ),
        }
    }
}

/// Slowest decay rate [1/s] of a mode.
fn slowest_rate(f_hz: f64, zeta: f64) -> f64 {
    let w = 2.0 * std::f64::consts::PI * f_hz;
    if zeta < 1.0 {
        zeta * w
    } else {
        w * (zeta - (zeta * zeta - 1.0).sqrt())
    }
}

/// A physical geometry of `family` whose lumped prediction falls in the family's ranges,
/// drawn by rejection; `(geometry, f_hz, zeta)`.
fn draw_geometry(rng: &mut Rng, family: Family) -> (Geometry, f64, f64) {
    let gas = Gas::air(REFERENCE_K, 101_325.0);
    loop {
        let (geometry, f_range, z_range) = match family {
            Family::Pneumatic => (
                Geometry::Tube {
                    length_m: rng.log_range(0.2, 3.0),
                    radius_m: rng.log_range(0.25e-3, 1.0e-3),
                    volume_m3: rng.log_range(5e-9, 2000e-9),
                },
                (20.0, 150.0),
                (0.1, 1.5),
            ),
            Family::Flush => (
                Geometry::Hole {
                    length_m: rng.log_range(0.2e-3, 2e-3),
                    diameter_m: rng.log_range(0.3e-3, 1.0e-3),
                    volume_m3: rng.log_range(0.05e-9, 3e-9),
                },
                (30e3, 120e3),
                (0.0, 1.0),
            ),
            Family::Capillary => (
                Geometry::Tube {
                    length_m: rng.log_range(1.0, 5.0),
                    radius_m: rng.log_range(0.1e-3, 0.4e-3),
                    volume_m3: rng.log_range(20e-9, 1000e-9),
                },
                (5.0, 80.0),
                (1.5, 5.0),
            ),
        };
        let (f, z) = match geometry {
            Geometry::Hole {
                length_m,
                diameter_m,
                volume_m3,
            } => {
                // The closed form to draw by; the exact first mode (its Poiseuille damping
                // is far too low) to report and to size the record.
                let h = HoleCavity::flush(length_m, diameter_m, volume_m3);
                if !(f_range.0..=f_range.1).contains(&h.helmholtz_frequency_hz(&gas)) {
                    continue;
                }
                match find_modes(&geometry.line(&gas), &gas, 1) {
                    Ok(m) if !m.modes.is_empty() => {
                        (m.modes[0].natural_frequency_hz, m.modes[0].damping)
                    }
                    _ => continue,
                }
            }
            Geometry::Tube { .. } => match lumped(&geometry.line(&gas), &gas, POISEUILLE_INERTANCE)
            {
                Ok(l) => (l.natural_frequency_hz, l.damping),
                Err(_) => continue,
            },
        };
        if (f_range.0..=f_range.1).contains(&f) && (z_range.0..=z_range.1).contains(&z) {
            return (geometry, f, z);
        }
    }
}

/// Two levels `(from, to)` in `[lo, hi]` steps (times `step`), `|to - from|` in
/// `[min, max]` steps, rising or falling as `rising` says.
fn levels(
    rng: &mut Rng,
    step: f64,
    (lo, hi): (f64, f64),
    (min, max): (f64, f64),
    rising: bool,
) -> (f64, f64) {
    let size = rng.range(min, max.min(hi - lo));
    let start = rng.range(lo, hi - size);
    let (a, b) = (start, start + size);
    if rising {
        (a * step, b * step)
    } else {
        (b * step, a * step)
    }
}

/// The effect of `kind` with its size, for a line of `f_hz` at `fs`.
fn draw_effect(
    rng: &mut Rng,
    kind: Kind,
    family: Family,
    generator: &Generator,
    f_hz: f64,
    fs: f64,
) -> Effect {
    let slow = family.slow_scale();
    match kind {
        Kind::None => Effect::None,
        Kind::Leak => Effect::Leak {
            corner_hz: slow * rng.log_range(0.5, 5.0),
            dc_gain: rng.range(0.9, 0.98),
        },
        Kind::Drift => Effect::Drift {
            per_s: slow * rng.sign() * rng.range(0.01, 0.1),
        },
        Kind::Offset => Effect::Offset {
            fraction: rng.sign() * rng.range(0.005, 0.05),
        },
        Kind::ColouredNoise => Effect::ColouredNoise {
            rho: rng.range(0.8, 0.99),
            ratio: rng.range(2.0, 10.0),
        },
        Kind::Mode => {
            let second_stage = match (&generator, family) {
                (Generator::Physics { .. }, Family::Flush) => Some((
                    rng.log_range(0.3e-3, 2e-3),
                    rng.log_range(0.1e-3, 0.3e-3),
                    rng.log_range(0.05e-9, 1e-9),
                )),
                (Generator::Physics { .. }, _) => Some((
                    rng.log_range(0.02, 0.3),
                    rng.log_range(0.2e-3, 0.6e-3),
                    rng.log_range(5e-9, 200e-9),
                )),
                _ => None,
            };
            Effect::Mode {
                f_hz: (f_hz * rng.range(2.0, 5.0)).min(0.3 * fs),
                zeta: rng.log_range(0.05, 0.3),
                second_stage,
            }
        }
        Kind::SensorResonance => Effect::SensorResonance {
            f_hz: rng.range(0.15, 0.4) * fs,
            zeta: rng.range(0.03, 0.1),
        },
        Kind::NonlinearDamping => Effect::NonlinearDamping {
            ratio: rng.log_range(0.3, 3.0),
        },
        Kind::Temperature => Effect::Temperature {
            kelvin: REFERENCE_K + rng.sign() * rng.range(30.0, 70.0),
        },
    }
}

/// The validation test: another facility or step, at least `seconds` long (a wake: four
/// tunnel periods).
fn draw_validation(
    rng: &mut Rng,
    family: Family,
    kind: Kind,
    fs: f64,
    step_pa: f64,
    seconds: f64,
) -> Test {
    use unlag::physics::Excitation as E;
    let n_for = |seconds: f64| (seconds * fs).ceil().clamp(2000.0, 20_000.0) as usize;
    // The validation test: another facility or step. Its levels stay well inside the
    // ADC range, closer with a ringing diaphragm.
    let sensor = kind == Kind::SensorResonance;
    let span = if sensor { (0.1, 1.0) } else { (-0.2, 1.3) };
    let sizes = if sensor { (0.3, 0.6) } else { (0.3, 1.4) };
    let val_kind = rng.int(0, 3);
    let (val, val_name) = match val_kind {
        0 => {
            let rising = rng.uniform() < 0.5;
            let (from, to) = levels(rng, step_pa, span, sizes, rising);
            ((E::shock_tube(to - from), from), "step")
        }
        1 => {
            let (from, to) = levels(rng, step_pa, span, sizes, false);
            ((E::balloon(from - to), to), "balloon")
        }
        2 => {
            let (from, to) = levels(rng, step_pa, span, sizes, true);
            let chamber_hz = match family {
                Family::Flush => rng.log_range(5e3, 50e3),
                _ => rng.range(0.02, 0.1) * fs,
            };
            (
                (
                    E::Valve {
                        amplitude_pa: to - from,
                        opening_s: 200e-6,
                        chamber_hz,
                        chamber_fraction: rng.range(0.0, 0.15),
                    },
                    from,
                ),
                "valve",
            )
        }
        _ => {
            let (wake_hz, tunnel_hz) = match family {
                Family::Pneumatic => (rng.range(10.0, 40.0), rng.range(2.0, 8.0)),
                Family::Flush => (rng.range(3e3, 15e3), rng.range(300.0, 1500.0)),
                Family::Capillary => (rng.range(3.0, 15.0), rng.range(1.0, 4.0)),
            };
            let depth = step_pa
                * if sensor {
                    rng.range(0.3, 0.5)
                } else {
                    rng.range(0.3, 0.7)
                };
            (
                (
                    E::CascadeWake {
                        wake_depth_pa: depth,
                        wake_hz,
                        wake_width: rng.range(0.05, 0.15),
                        tunnel_amplitude_pa: depth * rng.range(0.05, 0.25),
                        tunnel_hz,
                    },
                    step_pa * rng.range(0.7, 1.0),
                ),
                "wake",
            )
        }
    };
    let n_val = match val_name {
        "wake" => {
            let tunnel = match val.0 {
                E::CascadeWake { tunnel_hz, .. } => tunnel_hz,
                _ => 1.0,
            };
            n_for(seconds.max(4.0 / tunnel))
        }
        _ => n_for(seconds),
    };
    Test {
        excitation: val.0,
        base_pa: val.1,
        event_s: rng.range(0.1, 0.2) * n_val as f64 / fs,
        n: n_val,
        name: val_name,
    }
}

/// Draws `count` cases from `seed`.
pub fn draw(seed: u64, count: usize) -> Vec<Case> {
    use unlag::physics::Excitation as E;
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|id| {
            let kind = KINDS[id % KINDS.len()];
            let family = FAMILIES[(id / KINDS.len()) % FAMILIES.len()];
            let physics = kind != Kind::NonlinearDamping && rng.uniform() < 0.35;
            let fs = match family {
                Family::Pneumatic => rng.range(5e3, 10e3).round(),
                Family::Flush => 1e6,
                Family::Capillary => rng.range(2e3, 10e3).round(),
            };
            let (generator, f_hz, zeta) = if physics {
                let (geometry, f, z) = draw_geometry(&mut rng, family);
                (Generator::Physics { geometry }, f, z)
            } else {
                let (f, z, d) = match family {
                    Family::Pneumatic => (
                        rng.log_range(20.0, 150.0),
                        rng.log_range(0.1, 1.5),
                        rng.int(0, 40),
                    ),
                    Family::Flush => (
                        rng.log_range(30e3, 120e3),
                        rng.log_range(0.05, 0.4),
                        rng.int(0, 8),
                    ),
                    Family::Capillary => (
                        rng.log_range(5.0, 60.0),
                        rng.log_range(1.5, 5.0),
                        rng.int(0, 30),
                    ),
                };
                (
                    Generator::Lumped {
                        f_hz: f,
                        zeta: z,
                        delay: d,
                    },
                    f,
                    z,
                )
            };
            let effect = draw_effect(&mut rng, kind, family, &generator, f_hz, fs);
            // Record length: eight time constants of the slowest dynamics, 2 000 to 20 000.
            let mut rate = slowest_rate(f_hz, zeta);
            if let Effect::Leak { corner_hz, .. } = effect {
                rate = rate.min(2.0 * std::f64::consts::PI * corner_hz);
            }
            let n_for = |seconds: f64| (seconds * fs).ceil().clamp(2000.0, 20_000.0) as usize;
            let n_est = n_for(8.0 / rate / 0.8);
            let step_pa = rng.log_range(1e3, 2e4);
            let noise_u = rng.range(0.001, 0.005);
            let noise_y = rng.range(0.001, 0.005);
            let est_exc = if family != Family::Flush && rng.uniform() < 0.3 {
                E::valve(step_pa)
            } else {
                E::shock_tube(step_pa)
            };
            let est = Test {
                excitation: est_exc,
                base_pa: 0.0,
                event_s: rng.range(0.1, 0.2) * n_est as f64 / fs,
                n: n_est,
                name: "step",
            };
            let val = draw_validation(&mut rng, family, kind, fs, step_pa, 8.0 / rate / 0.8);
            Case {
                id,
                family,
                kind,
                effect,
                generator,
                f_hz,
                zeta,
                fs,
                step_pa,
                noise_u,
                noise_y,
                est,
                val,
                seed: rng.next_u64(),
            }
        })
        .collect()
}

/// Another run of `test`'s kind, as a user records several: the same facility, its sizes
/// and frequencies drawn again within +-20 % (levels only smaller, so that the run stays in
/// the ADC range the bank's tests set), and its own event time.
pub fn sibling(test: &Test, rng: &mut Rng) -> Test {
    use unlag::physics::Excitation as E;
    let size = rng.range(0.8, 1.0);
    let mut spread = || rng.range(0.8, 1.2);
    let excitation = match test.excitation {
        E::ShockTube {
            amplitude_pa,
            rise_s,
        } => E::ShockTube {
            amplitude_pa: amplitude_pa * size,
            rise_s,
        },
        E::Balloon {
            amplitude_pa,
            fall_s,
        } => E::Balloon {
            amplitude_pa: amplitude_pa * size,
            fall_s: fall_s * spread(),
        },
        E::Valve {
            amplitude_pa,
            opening_s,
            chamber_hz,
            chamber_fraction,
        } => E::Valve {
            amplitude_pa: amplitude_pa * size,
            opening_s: opening_s * spread(),
            chamber_hz: chamber_hz * spread(),
            chamber_fraction: chamber_fraction * spread(),
        },
        E::CascadeWake {
            wake_depth_pa,
            wake_hz,
            wake_width,
            tunnel_amplitude_pa,
            tunnel_hz,
        } => E::CascadeWake {
            wake_depth_pa: wake_depth_pa * size,
            wake_hz: wake_hz * spread(),
            wake_width: wake_width * spread(),
            tunnel_amplitude_pa: tunnel_amplitude_pa * size,
            tunnel_hz: tunnel_hz * spread(),
        },
    };
    Test {
        excitation,
        event_s: test.event_s * rng.range(0.8, 1.2),
        ..*test
    }
}
