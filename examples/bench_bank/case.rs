//! What a case of the bank is: its probe family, the effect it hides (kind and size), how
//! its probe is simulated (generator, geometry), its estimation and validation tests, and the
//! short texts of each for the report and `results.csv`.

use unlag::physics::{gas::Gas, HoleCavity, Line};

/// Gas temperature of every estimation test [K].
pub const REFERENCE_K: f64 = 293.15;

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

    /// The case's `truth.toml` leaves this effect out (it is put on the measured channels, or
    /// the validation is at another temperature than the truth's): the true model's error on
    /// a test with the effect is then at least what the probe's own dynamics leave.
    pub fn truth_lacks_it(self) -> bool {
        matches!(
            self,
            Self::None | Self::Drift | Self::Offset | Self::ColouredNoise | Self::Temperature
        )
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
    /// The `--add` argument of the hidden effect as the truth knows it: a sensor resonance
    /// with its diaphragm's frequency (which `fit` cannot read where the estimation step's
    /// reference does not ring), else the kind's name.
    pub fn true_add(&self) -> String {
        match self.effect {
            Effect::SensorResonance { f_hz, .. } => format!("sensor-resonance={f_hz:.0}"),
            _ => self.kind.name().into(),
        }
    }

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
