//! Physical effects added to a model in the modelling loop, and what each changes.
//!
//! This module owns [`Effect`] (stored in the model file as `effects = [...]`), how a fit
//! honours each effect ([`FitChanges`]), and how the model's prediction and the compensator's
//! input are corrected for the additive ones ([`Additive`]). Finding which effect is missing is
//! [`crate::modelling::diagnose`]'s job; measuring the residual is [`crate::modelling::evidence`]'s.
//!
//! | kind | change to the model | on the board |
//! |---|---|---|
//! | `mode` | two more poles and zeros (a second-order section) | one more section |
//! | `leak` | one more pole and zero (the slow creep of a leaking cavity) | part of a section |
//! | `offset` | a constant added to the prediction | subtracted before compensation |
//! | `drift` | a ramp added to the prediction | subtracted (the board counts samples) |
//! | `delay` | the delay the evidence points to, instead of the fitted one | the delay |
//! | `coloured-noise` | output-error fit (the noise needs no model then) | nothing |
//! | `nonlinear-damping` | a quadratic loss `gain * \|dy/dt\| dy/dt` taken off the input the dynamics see (fitted by least squares, alternating with the linear part) | `gain * lowpass(\|dy\| dy)` added to the linear inverse ([`crate::compensator::NonlinearDampingCoefficients`]); f32 only, the fixed-point export refuses it |
//! | `sensor-resonance` | both channels low-passed below the transducers' diaphragm resonance (Butterworth, order [`PREFILTER_ORDER`], at half the resonance, as the paper does) before fitting; the model describes the probe below it, and errors are measured on the prefiltered signals | the prefilter's sections run first, in the compensator's cascade |
//! | `temperature` | the model belongs to `reference_k`; at a gas temperature `T` every natural frequency scales by `k = sqrt(T / reference_k)` (speed of sound) and the delay by `1 / k`, through the continuous-time model ([`scaled`]); the damping of every resonance is kept (`damping = "constant"`, `--add temperature`) or scaled by the viscous law `(nu(T) / nu(reference_k)) / k` of a tube-volume system (`damping = "viscous"`, `--add temperature-viscous`; [`TemperatureDamping`], [`scaled_with`]) | a coefficient set rescaled for the temperature it is given (`unlag export --temperature K`, swapped in as a blob), or a bank of sets by temperature for a board that measures it (`unlag export --temperatures FROM:TO:STEP`, [`crate::compensator::TemperatureBank`]: nearest set with hysteresis, state handed over without a step) |
//!
//! A test's temperature: `unlag simulate`, `unlag compensate` and `unlag export` take it as
//! `--temperature K`. Where tests are judged against the model (`fit`, `compare`, `diagnose`)
//! each test's scale factor `k` is estimated from the test itself (one number, like the
//! offset of an `offset`: [`estimate_scale`]) and reported with the temperature it implies,
//! `reference_k k^2`.
//!
//! # Nonlinear damping
//!
//! Orifice and turbulent losses grow with the square of the flow: a probe obeys
//! `y'' + (2 zeta w + k |y'|) y' + w^2 y = w^2 u(t - tau)` rather than the linear equation.
//! Written as the input the linear dynamics see, `u(t - tau) - gain |y'| y'` with
//! `gain = k / w^2` (s^2 per probe unit), the model is
//!
//! ```text
//! A(q) y = B(q) ( q^-d u  -  gain * N ),    N[k] = fs^2 |y[k] - y[k-1]| (y[k] - y[k-1])
//! ```
//!
//! and its inverse is the linear one plus a correction from the probe signal alone:
//! `u[k-d] = (A/B) y + gain * N[k]`. The board adds `gain * lowpass(N)` (the design's own
//! low-pass) to the linear compensator's output; nothing else changes.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::fit::continuous::Continuous;
use crate::fit::model::Model;
use crate::fit::{Fitted, Method, Options, Order, Test};
use crate::poly::Complex;

/// One effect added to the model, with its parameters once fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Effect {
    /// An unmodelled resonance: a higher acoustic mode of the line, a cavity's Helmholtz
    /// resonance. Adds a second-order section.
    Mode {
        /// Frequency where the evidence put it (Hz), for the record.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        near_hz: Option<f64>,
    },
    /// A leaking cavity or side volume: a slow pole-zero pair (creep after the step).
    Leak,
    /// A zero offset of the probe against the reference.
    Offset {
        /// Offset in the probe's units (fitted).
        #[serde(default)]
        value: f64,
    },
    /// A slow drift of the probe in time (thermal drift of the sensor).
    Drift {
        /// Offset at the start of a test (fitted).
        #[serde(default)]
        value: f64,
        /// Drift rate in the probe's units per second (fitted).
        #[serde(default)]
        rate_per_s: f64,
    },
    /// The delay, corrected.
    Delay {
        /// Delay in samples.
        samples: usize,
    },
    /// Residuals correlated in time but not explained by the input: the dynamics by output
    /// error, and beside them a noise model, AR(p) on what they leave
    /// ([`crate::fit::noise`]); the error reported is then the one-step-ahead prediction
    /// error `D(q) (y - G u)`.
    ColouredNoise {
        /// `[d1..dp]` of `D(q) = 1 + d1 q^-1 + ...` (fitted; empty until fitted).
        #[serde(default)]
        ar: Vec<f64>,
        /// Standard deviation of the white innovation, probe units (fitted).
        #[serde(default)]
        innovation_std: f64,
    },
    /// Amplitude-dependent (quadratic, orifice or turbulent) losses: the input the linear
    /// dynamics see is lowered by `gain * |dy/dt| dy/dt` (see the module docs).
    NonlinearDamping {
        /// Quadratic loss coefficient, s^2 per probe unit (fitted); the linear damping ratio
        /// rises by about `gain * w * |dy/dt| / 2` at the rate `dy/dt`.
        #[serde(default)]
        gain: f64,
    },
    /// The transducers' own diaphragm resonance, ringing in both channels. Modelled
    /// ([`SensorRemedy::Modes`], what `--add sensor-resonance` writes): two more poles and
    /// zeros, the probe transducer's mode and the reference transducer's as zeros, fitted on
    /// the raw signals; or, as the paper does ([`SensorRemedy::Prefilter`],
    /// `--add sensor-resonance-prefilter`), both channels low-passed below it before fitting.
    SensorResonance {
        /// The diaphragm's natural frequency (Hz); 0 until found in the reference's spectrum.
        #[serde(default)]
        natural_frequency_hz: f64,
        /// Corner of the prefilter (Hz): half the natural frequency; 0 without a prefilter.
        #[serde(default)]
        prefilter_hz: f64,
        /// How the resonance enters the model (a file without the field is a prefiltered one,
        /// as every file written before the modes existed).
        #[serde(default)]
        remedy: SensorRemedy,
    },
    /// Tests at other gas temperatures: the model scaled by `sqrt(T / reference_k)`.
    Temperature {
        /// Gas temperature the model's coefficients belong to (K): the estimation test's.
        #[serde(default = "default_reference_k")]
        reference_k: f64,
        /// How the damping of the resonances follows the temperature (`constant` when the
        /// file does not say: model files written before the law existed load unchanged).
        #[serde(default, skip_serializing_if = "TemperatureDamping::is_constant")]
        damping: TemperatureDamping,
    },
}

/// How a sensor resonance enters the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SensorRemedy {
    /// Both channels low-passed (Butterworth, order [`PREFILTER_ORDER`], at half the
    /// diaphragm's frequency) before fitting, the prefilter run first on the board, as the
    /// paper does. The model then says nothing about the band above the corner: its
    /// simulation against the raw probe does not improve.
    #[default]
    Prefilter,
    /// The transducers' modes in the model: the order raised by two (a pole pair at the
    /// probe transducer's resonance, a zero pair at the reference transducer's), fitted on
    /// the raw signals. The simulation against the measured probe improves, and `u_hat`
    /// reconstructs the reference as its transducer measures it.
    Modes,
}

/// How a `temperature` effect moves the damping ratio of every resonance with the gas
/// temperature (the natural frequencies always scale by `k = sqrt(T / T_ref)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TemperatureDamping {
    /// The damping ratios are kept.
    #[default]
    Constant,
    /// The viscous law of a tube-volume system (`zeta = (4 / c_I) nu / (R^2 w_n)`, the
    /// physics module's lumped model): at `T` every damping ratio is multiplied by
    /// `(nu(T) / nu(T_ref)) / k` ([`viscous_damping_factor`]), with `nu = mu / rho` of air,
    /// `mu` by Sutherland's law and `rho = p / (R_g T)` at one fixed mean pressure.
    Viscous,
}

impl TemperatureDamping {
    /// Whether it is [`TemperatureDamping::Constant`] (not written to the model file then).
    #[must_use]
    pub fn is_constant(&self) -> bool {
        *self == Self::Constant
    }

    /// The factor on every damping ratio at time-scale factor `k` for a model at
    /// `reference_k` (the temperature is `reference_k k^2`): 1 for `constant`; for `viscous`
    /// [`viscous_damping_factor`], 1 when the temperatures are not positive numbers.
    #[must_use]
    pub fn factor(self, k: f64, reference_k: f64) -> f64 {
        match self {
            Self::Constant => 1.0,
            Self::Viscous => {
                viscous_damping_factor(reference_k * k * k, reference_k).unwrap_or(1.0)
            }
        }
    }

    /// The `--add` spelling of a `temperature` effect with this law.
    #[must_use]
    pub fn spelling(self) -> EffectKind {
        match self {
            Self::Constant => EffectKind::Temperature,
            Self::Viscous => EffectKind::TemperatureViscous,
        }
    }
}

/// Mean pressure (Pa) at which [`viscous_damping_factor`] evaluates the air: one standard
/// atmosphere. The factor depends on it only through the density, which is proportional to
/// the pressure at both temperatures, so the ratio `nu(T) / nu(T_ref)` is the same at any
/// fixed mean pressure; this is only where the two gases are built.
pub const VISCOUS_PRESSURE_PA: f64 = crate::physics::gas::STANDARD_PRESSURE;

/// The factor on a tube-volume system's damping ratio from `reference_k` to `temperature_k`:
/// `zeta = (4 / c_I) nu / (R^2 w_n)` (see `../shared/physics/README.md`, 1.3) with `w_n`
/// scaling as the speed of sound, so `(nu(T) / nu(T_ref)) / sqrt(T / T_ref)`, air at
/// [`VISCOUS_PRESSURE_PA`] ([`crate::physics::Gas::air`]: Sutherland viscosity, ideal-gas
/// density). About 1.22 from 293.15 K to 343.15 K.
///
/// # Errors
/// As [`scale_for`].
pub fn viscous_damping_factor(temperature_k: f64, reference_k: f64) -> Result<f64> {
    let k = scale_for(temperature_k, reference_k)?;
    let nu = |t: f64| crate::physics::Gas::air(t, VISCOUS_PRESSURE_PA).kinematic_viscosity();
    Ok(nu(temperature_k) / nu(reference_k) / k)
}

/// Reference temperature when the user gives none (K): 20 degrees Celsius.
pub const DEFAULT_REFERENCE_K: f64 = 293.15;

fn default_reference_k() -> f64 {
    DEFAULT_REFERENCE_K
}

/// Order of the sensor-resonance prefilter (Butterworth): -24 dB at the resonance when the
/// corner is at half of it.
pub const PREFILTER_ORDER: usize = 4;

/// Range of the time-scale factor `k` searched per test (temperatures from about 0.5 to 2
/// times the reference).
pub const SCALE_RANGE: (f64, f64) = (0.7, 1.4);

/// The name of an effect: what `unlag fit --add` takes (without a `=VALUE`), what a
/// diagnosis names ([`crate::modelling::diagnose::Finding`]), and, for the nine kinds of [`Effect`]'s
/// variants, the `kind` of an effect in the model file.
///
/// Two names are not kinds of their own in the model file: `sensor-resonance-prefilter` is a
/// `sensor-resonance` with the paper's prefilter as its remedy ([`SensorRemedy`]), and
/// `temperature-viscous` a `temperature` with the viscous damping law
/// ([`TemperatureDamping`]); [`EffectKind::family`] gives the kind they are stored as, which
/// is what [`Effect::kind`] returns.
///
/// The text forms ([`Display`](core::fmt::Display), [`FromStr`](core::str::FromStr) and
/// serde's) are the same strings everywhere: model files, `--json` output, `--add`.
///
/// ```
/// use unlag::modelling::effects::EffectKind;
///
/// let k: EffectKind = "temperature-viscous".parse().unwrap();
/// assert_eq!(k, EffectKind::TemperatureViscous);
/// assert_eq!(k.to_string(), "temperature-viscous");
/// assert_eq!(k.family(), EffectKind::Temperature);
/// assert_eq!(EffectKind::Mode.parameters(), 4);
/// assert!("gremlins".parse::<EffectKind>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EffectKind {
    /// `mode`: an unmodelled resonance ([`Effect::Mode`]).
    Mode,
    /// `leak`: a leaking cavity ([`Effect::Leak`]).
    Leak,
    /// `offset`: a zero offset ([`Effect::Offset`]).
    Offset,
    /// `drift`: a drift in time ([`Effect::Drift`]).
    Drift,
    /// `delay`: the delay corrected ([`Effect::Delay`]).
    Delay,
    /// `coloured-noise`: a noise model beside the dynamics ([`Effect::ColouredNoise`]).
    ColouredNoise,
    /// `nonlinear-damping`: quadratic losses ([`Effect::NonlinearDamping`]).
    NonlinearDamping,
    /// `sensor-resonance`: the transducers' modes in the model ([`Effect::SensorResonance`]
    /// with [`SensorRemedy::Modes`]).
    SensorResonance,
    /// `sensor-resonance-prefilter`: the same resonance filtered out instead
    /// ([`SensorRemedy::Prefilter`]); stored as a `sensor-resonance`.
    SensorResonancePrefilter,
    /// `temperature`: the model scaled with the gas temperature, damping kept
    /// ([`Effect::Temperature`] with [`TemperatureDamping::Constant`]).
    Temperature,
    /// `temperature-viscous`: the same with the viscous damping law
    /// ([`TemperatureDamping::Viscous`]); stored as a `temperature`.
    TemperatureViscous,
}

/// Text that names no [`EffectKind`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect kind '{0}'")]
pub struct UnknownKind(pub String);

impl EffectKind {
    /// Every name, in catalogue order (each family's variants after it).
    pub const ALL: [Self; 11] = [
        Self::Mode,
        Self::Leak,
        Self::Offset,
        Self::Drift,
        Self::Delay,
        Self::ColouredNoise,
        Self::NonlinearDamping,
        Self::SensorResonance,
        Self::SensorResonancePrefilter,
        Self::Temperature,
        Self::TemperatureViscous,
    ];

    /// Its text: `mode`, `coloured-noise`, `temperature-viscous`, ...
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Mode => "mode",
            Self::Leak => "leak",
            Self::Offset => "offset",
            Self::Drift => "drift",
            Self::Delay => "delay",
            Self::ColouredNoise => "coloured-noise",
            Self::NonlinearDamping => "nonlinear-damping",
            Self::SensorResonance => "sensor-resonance",
            Self::SensorResonancePrefilter => "sensor-resonance-prefilter",
            Self::Temperature => "temperature",
            Self::TemperatureViscous => "temperature-viscous",
        }
    }

    /// The kind it is stored as in the model file (one per [`Effect`] variant):
    /// `sensor-resonance` for `sensor-resonance-prefilter`, `temperature` for
    /// `temperature-viscous`, itself for the others.
    #[must_use]
    pub const fn family(self) -> Self {
        match self {
            Self::SensorResonancePrefilter => Self::SensorResonance,
            Self::TemperatureViscous => Self::Temperature,
            k => k,
        }
    }

    /// Parameters it adds to the model, as the diagnosis charges them
    /// ([`crate::modelling::diagnose::PARAMETER_PENALTY`] each): a section's four for a mode or the
    /// transducers' modes, a pole and a zero for a leak, offset and rate for a drift, one
    /// coefficient for an offset, a quadratic loss or a temperature (its reference). None for
    /// a delay (it replaces the fitted one), a prefilter (fixed by the resonance's frequency)
    /// or a noise model (beside the dynamics: it changes no prediction of the probe).
    #[must_use]
    pub const fn parameters(self) -> usize {
        match self {
            Self::Mode | Self::SensorResonance => 4,
            Self::Leak | Self::Drift => 2,
            Self::Offset
            | Self::NonlinearDamping
            | Self::Temperature
            | Self::TemperatureViscous => 1,
            Self::Delay | Self::ColouredNoise | Self::SensorResonancePrefilter => 0,
        }
    }
}

impl core::fmt::Display for EffectKind {
    /// Its text ([`EffectKind::as_str`]), padded as the formatter asks.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.pad(self.as_str())
    }
}

impl core::str::FromStr for EffectKind {
    type Err = UnknownKind;

    fn from_str(s: &str) -> core::result::Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| UnknownKind(s.to_string()))
    }
}

impl Serialize for EffectKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for EffectKind {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// The kinds of the model file (one per [`Effect`] variant), in catalogue order.
pub const KINDS: [EffectKind; 9] = [
    EffectKind::Mode,
    EffectKind::Leak,
    EffectKind::Offset,
    EffectKind::Drift,
    EffectKind::Delay,
    EffectKind::ColouredNoise,
    EffectKind::NonlinearDamping,
    EffectKind::SensorResonance,
    EffectKind::Temperature,
];

impl Effect {
    /// Its kind as the model file names it ([`EffectKind::family`]: a prefiltered sensor
    /// resonance is a `sensor-resonance`, a viscous temperature a `temperature`).
    #[must_use]
    pub fn kind(&self) -> EffectKind {
        match self {
            Self::Mode { .. } => EffectKind::Mode,
            Self::Leak => EffectKind::Leak,
            Self::Offset { .. } => EffectKind::Offset,
            Self::Drift { .. } => EffectKind::Drift,
            Self::Delay { .. } => EffectKind::Delay,
            Self::ColouredNoise { .. } => EffectKind::ColouredNoise,
            Self::NonlinearDamping { .. } => EffectKind::NonlinearDamping,
            Self::SensorResonance { .. } => EffectKind::SensorResonance,
            Self::Temperature { .. } => EffectKind::Temperature,
        }
    }

    /// A fresh effect of `kind` (parameters to be fitted; a sensor resonance's frequency
    /// found in the reference's spectrum), or `None` for [`EffectKind::Delay`], which has no
    /// value to start from.
    #[must_use]
    pub fn fresh(kind: EffectKind) -> Option<Self> {
        Some(match kind {
            EffectKind::Mode => Self::Mode { near_hz: None },
            EffectKind::Leak => Self::Leak,
            EffectKind::Offset => Self::Offset { value: 0.0 },
            EffectKind::Drift => Self::Drift {
                value: 0.0,
                rate_per_s: 0.0,
            },
            EffectKind::Delay => return None,
            EffectKind::ColouredNoise => Self::ColouredNoise {
                ar: Vec::new(),
                innovation_std: 0.0,
            },
            EffectKind::NonlinearDamping => Self::NonlinearDamping { gain: 0.0 },
            EffectKind::SensorResonance => Self::SensorResonance {
                natural_frequency_hz: 0.0,
                prefilter_hz: 0.0,
                remedy: SensorRemedy::Modes,
            },
            EffectKind::SensorResonancePrefilter => Self::SensorResonance {
                natural_frequency_hz: 0.0,
                prefilter_hz: 0.0,
                remedy: SensorRemedy::Prefilter,
            },
            EffectKind::Temperature => Self::Temperature {
                reference_k: DEFAULT_REFERENCE_K,
                damping: TemperatureDamping::Constant,
            },
            EffectKind::TemperatureViscous => Self::Temperature {
                reference_k: DEFAULT_REFERENCE_K,
                damping: TemperatureDamping::Viscous,
            },
        })
    }

    /// The effect `unlag fit --add` names: a bare kind ([`Effect::fresh`]) or one with its
    /// value (`delay=N`, `sensor-resonance[-prefilter]=HZ`, `temperature[-viscous]=K`);
    /// `None` for an unknown kind, a value that is not a positive number, or a bare `delay`.
    #[must_use]
    pub fn parse(kind: &str) -> Option<Self> {
        if let Ok(k) = kind.parse::<EffectKind>() {
            return Self::fresh(k);
        }
        Some(match kind {
            _ if kind.starts_with("sensor-resonance") => {
                let (remedy, f) = if let Some(f) = kind.strip_prefix("sensor-resonance=") {
                    (SensorRemedy::Modes, f)
                } else {
                    (
                        SensorRemedy::Prefilter,
                        kind.strip_prefix("sensor-resonance-prefilter=")?,
                    )
                };
                let f: f64 = f.parse().ok()?;
                if !(f.is_finite() && f > 0.0) {
                    return None;
                }
                Self::SensorResonance {
                    natural_frequency_hz: f,
                    prefilter_hz: if remedy == SensorRemedy::Prefilter {
                        0.5 * f
                    } else {
                        0.0
                    },
                    remedy,
                }
            }
            _ if kind.starts_with("temperature") => {
                let (damping, t) = if let Some(t) = kind.strip_prefix("temperature=") {
                    (TemperatureDamping::Constant, t)
                } else {
                    (
                        TemperatureDamping::Viscous,
                        kind.strip_prefix("temperature-viscous=")?,
                    )
                };
                let t: f64 = t.parse().ok()?;
                if !(t.is_finite() && t > 0.0) {
                    return None;
                }
                Self::Temperature {
                    reference_k: t,
                    damping,
                }
            }
            _ => {
                let d = kind.strip_prefix("delay=")?.parse().ok()?;
                Self::Delay { samples: d }
            }
        })
    }
}

/// What a list of effects changes in a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FitChanges {
    /// Poles to add to the order the user asked for.
    pub extra_order: usize,
    /// The delay to use instead of searching.
    pub delay: Option<usize>,
    /// The method to use instead of the user's.
    pub method: Option<Method>,
    /// Whether an offset is fitted.
    pub offset: bool,
    /// Whether a drift is fitted.
    pub drift: bool,
    /// Whether a quadratic damping term is fitted.
    pub nonlinear: bool,
}

impl FitChanges {
    /// Collects the changes of `effects`.
    #[must_use]
    pub fn of(effects: &[Effect]) -> Self {
        let mut c = Self::default();
        for e in effects {
            match e {
                Effect::Mode { .. } => c.extra_order += 2,
                Effect::Leak => c.extra_order += 1,
                Effect::Offset { .. } => c.offset = true,
                Effect::Drift { .. } => c.drift = true,
                Effect::Delay { samples } => c.delay = Some(*samples),
                Effect::ColouredNoise { .. } => c.method = Some(Method::Bj),
                Effect::NonlinearDamping { .. } => c.nonlinear = true,
                Effect::SensorResonance {
                    remedy: SensorRemedy::Modes,
                    ..
                } => c.extra_order += 2,
                Effect::SensorResonance { .. } | Effect::Temperature { .. } => {}
            }
        }
        c
    }
}

/// The additive part of a model's effects: `offset + rate * t` (t from the test's start).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Additive {
    /// Constant, probe units.
    pub offset: f64,
    /// Rate, probe units per second.
    pub rate_per_s: f64,
}

impl Additive {
    /// The additive part of `effects`.
    #[must_use]
    pub fn of(effects: &[Effect]) -> Self {
        let mut a = Self::default();
        for e in effects {
            match e {
                Effect::Offset { value } => a.offset += value,
                Effect::Drift { value, rate_per_s } => {
                    a.offset += value;
                    a.rate_per_s += rate_per_s;
                }
                _ => {}
            }
        }
        a
    }

    /// The value at sample `k` of a test sampled at `fs`.
    #[must_use]
    pub fn at(&self, k: usize, fs: f64) -> f64 {
        self.offset + self.rate_per_s * k as f64 / fs
    }

    /// Adds itself to a prediction.
    pub fn add_to(&self, y: &mut [f64], fs: f64) {
        for (k, v) in y.iter_mut().enumerate() {
            *v += self.at(k, fs);
        }
    }

    /// The probe signal with the additive effects removed (what the compensator is given).
    #[must_use]
    pub fn removed_from(&self, y: &[f64], fs: f64) -> Vec<f64> {
        y.iter()
            .enumerate()
            .map(|(k, v)| v - self.at(k, fs))
            .collect()
    }
}

/// The additive effects of one test, estimated from its residual `r = y - y_dynamics` by
/// least squares: an offset from the samples before the step (or all, without a step), an
/// offset and a rate from the whole record. They are nuisances of each record (a drift is not
/// the same in two tests), so each test gets its own.
#[must_use]
pub fn estimate_additive(changes: &FitChanges, r: &[f64], onset: usize, fs: f64) -> Additive {
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len().max(1) as f64;
    if changes.drift {
        let n = r.len() as f64;
        let tm = (n - 1.0) / 2.0;
        let rm = mean(r);
        let (mut num, mut den) = (0.0, 0.0);
        for (i, v) in r.iter().enumerate() {
            let t = i as f64 - tm;
            num += t * (v - rm);
            den += t * t;
        }
        let per_sample = if den > 0.0 { num / den } else { 0.0 };
        Additive {
            offset: rm - per_sample * tm,
            rate_per_s: per_sample * fs,
        }
    } else if changes.offset {
        let pre = if onset >= 20 { &r[..onset] } else { r };
        Additive {
            offset: mean(pre),
            rate_per_s: 0.0,
        }
    } else {
        Additive::default()
    }
}

/// The quadratic damping gain of `effects` (s^2 per probe unit; 0 without the effect).
#[must_use]
pub fn nonlinear_gain(effects: &[Effect]) -> f64 {
    effects
        .iter()
        .map(|e| match e {
            Effect::NonlinearDamping { gain } => *gain,
            _ => 0.0,
        })
        .sum()
}

/// The quadratic rate term of the probe signal, `N[k] = fs^2 |y[k] - y[k-1]| (y[k] - y[k-1])`
/// (`N[0] = 0`): `|dy/dt| dy/dt` by the backward difference, what the board computes.
#[must_use]
pub fn quadratic_rate(y: &[f64], fs: f64) -> Vec<f64> {
    let mut prev = y.first().copied().unwrap_or(0.0);
    y.iter()
        .map(|&v| {
            let d = v - prev;
            prev = v;
            fs * fs * d.abs() * d
        })
        .collect()
}

/// The model's output with quadratic damping `gain` (see the module docs), started in
/// equilibrium with its resting level ([`crate::fit::model::resting_level`]): `A y = B (q^-d u - gain N(y))`. The term of `b0`, which needs
/// `N[k]` of the sample being computed, is solved exactly (a quadratic in the step
/// `y[k] - y[k-1]`); with `gain = 0` this is [`Model::simulate`].
#[must_use]
pub fn simulate_nonlinear(model: &Model, gain: f64, u: &[f64]) -> Vec<f64> {
    let u0 = crate::fit::model::resting_level(u);
    let y0 = model.dc_gain() * u0;
    let fs2 = model.fs * model.fs;
    let n = u.len();
    let mut y = vec![0.0; n];
    let mut q = vec![0.0; n];
    let b0 = model.b.first().copied().unwrap_or(0.0);
    for k in 0..n {
        let mut acc = 0.0;
        for (i, bi) in model.b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + model.delay) {
                acc += bi * (u[j] - u0);
            }
            if i > 0 {
                if let Some(j) = k.checked_sub(i) {
                    acc -= gain * bi * q[j];
                }
            }
        }
        for (i, ai) in model.a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                acc -= ai * y[j];
            }
        }
        // y[k] = acc - gain b0 fs^2 |D| D with D = y[k] - y[k-1]: D = c - beta |D| D.
        let prev = if k > 0 { y[k - 1] } else { 0.0 };
        let c = acc - prev;
        let beta = gain * b0 * fs2;
        let disc = 1.0 + 4.0 * beta * c.abs();
        let d = if beta == 0.0 {
            c
        } else if disc >= 0.0 {
            c.signum() * 2.0 * c.abs() / (1.0 + disc.sqrt())
        } else {
            // No solution of the implicit step (a negative b0 and a large step): the term of
            // b0 is taken from the previous sample instead.
            c - beta * if k > 0 { q[k - 1] / fs2 } else { 0.0 }
        };
        y[k] = prev + d;
        q[k] = fs2 * d.abs() * d;
    }
    for v in &mut y {
        *v += y0;
    }
    y
}

/// The model's full prediction for a test: the dynamics (with their quadratic damping, if
/// any) started in equilibrium with `u[0]`, plus the additive effects estimated on this test. With a `sensor-resonance` it predicts
/// the prefiltered probe signal ([`observed`]); with a `temperature` the model is scaled by
/// the factor estimated on this test ([`estimate_scale`]).
#[must_use]
pub fn predict(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    predict_with(model, effects, u, y, None)
}

/// As [`predict`], with the time-scale factor `k = sqrt(T / reference_k)` given instead of
/// estimated (`None`: estimated when the effects have a `temperature`); the damping follows
/// the `temperature`'s law ([`TemperatureDamping`]).
#[must_use]
pub fn predict_with(
    model: &Model,
    effects: &[Effect],
    u: &[f64],
    y: &[f64],
    scale: Option<f64>,
) -> Vec<f64> {
    let fs = model.fs;
    let (u, y) = (prefiltered(effects, fs, u), prefiltered(effects, fs, y));
    let law = temperature_law(effects);
    let k = match (scale, law) {
        (Some(k), _) => k,
        (None, Some((reference, damping))) => {
            estimate_scale_with(model, damping, reference, &u, &y)
        }
        (None, None) => 1.0,
    };
    let rescaled = if (k - 1.0).abs() > 1e-12 {
        let factor = law.map_or(1.0, |(reference, damping)| damping.factor(k, reference));
        scaled_with(model, k, factor).ok()
    } else {
        None
    };
    let model = rescaled.as_ref().unwrap_or(model);
    let gain = nonlinear_gain(effects);
    let mut ym = if gain == 0.0 {
        model.simulate(&u)
    } else {
        simulate_nonlinear(model, gain, &u)
    };
    let changes = FitChanges::of(effects);
    if changes.offset || changes.drift {
        let onset = crate::fit::step::find_step(&u).map_or(0, |s| s.onset);
        let r: Vec<f64> = y.iter().zip(&ym).map(|(a, b)| a - b).collect();
        estimate_additive(&changes, &r, onset, fs).add_to(&mut ym, fs);
    }
    ym
}

/// Points of the coarse grid over the quadratic loss before the golden-section refinement.
pub const NONLINEAR_GRID: usize = 9;

/// Golden-section steps refining the quadratic loss between the grid's neighbours.
pub const NONLINEAR_REFINE: usize = 10;

/// Fits the linear part and the quadratic loss together on one test: for each trial loss the
/// linear part is fitted (by the user's method, delay fixed by a plain fit first) to the input
/// less the loss times the quadratic rate of the (lightly smoothed, centred) measurement, and
/// the loss is chosen where the whole model's simulation error is lowest: a grid from zero to
/// the loss that would take twice the step off the input at the peak rate, refined by golden
/// section. Returns the fit and the loss.
fn fit_nonlinear(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    opts: &Options,
) -> Result<(Fitted, f64)> {
    let plain = crate::fit::fit(estimation, validation, fs, opts)?;
    let opts = Options {
        delay: Some(plain.model.delay),
        ..*opts
    };
    let d = plain.model.delay;
    // Centred 5-point mean: the rate's noise is much reduced, its timing kept.
    let n = estimation.y.len();
    let smooth: Vec<f64> = (0..n)
        .map(|k| {
            let lo = k.saturating_sub(2);
            let hi = (k + 3).min(n);
            estimation.y[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect();
    let q = quadratic_rate(&smooth, fs);
    let last = q.last().copied().unwrap_or(0.0);
    let advanced: Vec<f64> = (0..n)
        .map(|k| q.get(k + d).copied().unwrap_or(last))
        .collect();
    let (lo, hi) = estimation
        .u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let q_max = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(q_max > 0.0 && hi > lo) {
        return Ok((plain, 0.0));
    }
    let g_max = 2.0 * (hi - lo) / q_max;
    let trial = |g: f64| -> Option<(f64, Fitted)> {
        let u: Vec<f64> = estimation
            .u
            .iter()
            .zip(&advanced)
            .map(|(u, q)| u - g * q)
            .collect();
        let t = Test {
            name: estimation.name,
            u: &u,
            y: estimation.y,
        };
        let f = crate::fit::fit(&t, validation, fs, &opts).ok()?;
        let e = crate::fit::nrmse_of(estimation.y, &simulate_nonlinear(&f.model, g, estimation.u));
        e.is_finite().then_some((e, f))
    };
    let step = g_max / (NONLINEAR_GRID - 1) as f64;
    let mut best: Option<(f64, f64, Fitted)> = None;
    let consider = |g: f64, best: &mut Option<(f64, f64, Fitted)>| -> f64 {
        match trial(g) {
            Some((e, f)) => {
                if best.as_ref().is_none_or(|b| e < b.0) {
                    *best = Some((e, g, f));
                }
                e
            }
            None => f64::INFINITY,
        }
    };
    for i in 0..NONLINEAR_GRID {
        consider(step * i as f64, &mut best);
    }
    let centre = best.as_ref().map_or(0.0, |b| b.1);
    let (mut a, mut b) = ((centre - step).max(0.0), centre + step);
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = b - ratio * (b - a);
    let mut x2 = a + ratio * (b - a);
    let mut e1 = consider(x1, &mut best);
    let mut e2 = consider(x2, &mut best);
    for _ in 0..NONLINEAR_REFINE {
        if e1 <= e2 {
            b = x2;
            x2 = x1;
            e2 = e1;
            x1 = b - ratio * (b - a);
            e1 = consider(x1, &mut best);
        } else {
            a = x1;
            x1 = x2;
            e1 = e2;
            x2 = a + ratio * (b - a);
            e2 = consider(x2, &mut best);
        }
    }
    Ok(best.map_or((plain, 0.0), |(_, g, f)| (f, g)))
}

/// What a prediction of [`predict`] is compared with: the probe signal, prefiltered when the
/// effects have a `sensor-resonance`.
#[must_use]
pub fn observed<'a>(effects: &[Effect], fs: f64, y: &'a [f64]) -> std::borrow::Cow<'a, [f64]> {
    match prefilter_hz(effects) {
        Some(_) => std::borrow::Cow::Owned(prefiltered(effects, fs, y)),
        None => std::borrow::Cow::Borrowed(y),
    }
}

/// The prefilter corner of `effects` (Hz), when they have a sensor resonance with a known
/// frequency.
#[must_use]
pub fn prefilter_hz(effects: &[Effect]) -> Option<f64> {
    effects.iter().find_map(|e| match e {
        Effect::SensorResonance { prefilter_hz, .. } if *prefilter_hz > 0.0 => Some(*prefilter_hz),
        _ => None,
    })
}

/// The prefilter as `(gain, sections [b0, b1, b2, a1, a2])` at sample rate `fs`: a Butterworth
/// low-pass of order [`PREFILTER_ORDER`] with unit DC gain.
///
/// # Errors
/// [`crate::error::Error::InvalidArgument`] when the corner is not below half the sample
/// rate.
pub fn prefilter_sections(corner_hz: f64, fs: f64) -> Result<(f64, Vec<[f64; 5]>)> {
    let zpk = crate::design::inverse::lowpass(
        crate::design::inverse::LowpassKind::Butterworth,
        PREFILTER_ORDER,
        corner_hz,
        fs,
    )?;
    Ok(crate::design::inverse::to_sections(&zpk))
}

/// `x` through the prefilter of `effects`, started in equilibrium with its resting level
/// ([`crate::fit::model::resting_level`]); `x` unchanged when there is none.
#[must_use]
pub fn prefiltered(effects: &[Effect], fs: f64, x: &[f64]) -> Vec<f64> {
    match prefilter_hz(effects).and_then(|fc| prefilter_sections(fc, fs).ok()) {
        Some((gain, sections)) => {
            let x0 = crate::fit::model::resting_level(x);
            let mut v: Vec<f64> = x.iter().map(|a| a - x0).collect();
            for s in &sections {
                v = crate::fit::model::filter(&s[..3], &s[3..], 0, &v);
            }
            v.iter().map(|a| gain * a + x0).collect()
        }
        None => x.to_vec(),
    }
}

/// The reference temperature of `effects` (K), when they have a `temperature`.
#[must_use]
pub fn reference_k(effects: &[Effect]) -> Option<f64> {
    temperature_law(effects).map(|(t, _)| t)
}

/// The reference temperature (K) and damping law of `effects`' `temperature`, if any.
#[must_use]
pub fn temperature_law(effects: &[Effect]) -> Option<(f64, TemperatureDamping)> {
    effects.iter().find_map(|e| match e {
        Effect::Temperature {
            reference_k,
            damping,
        } => Some((*reference_k, *damping)),
        _ => None,
    })
}

/// The time-scale factor at gas temperature `temperature_k` for a model at `reference_k`:
/// `sqrt(T / T_ref)`, the ratio of the speeds of sound of an ideal gas.
///
/// # Errors
/// [`crate::error::Error::InvalidArgument`] for a temperature that is not a positive number
/// of kelvin.
pub fn scale_for(temperature_k: f64, reference_k: f64) -> Result<f64> {
    if !(temperature_k.is_finite()
        && temperature_k > 0.0
        && reference_k.is_finite()
        && reference_k > 0.0)
    {
        return Err(crate::error::Error::InvalidArgument {
            what: "--temperature",
            message: format!(
                "temperatures must be positive numbers of kelvin, not {temperature_k} K (model at {reference_k} K)"
            ),
        });
    }
    Ok((temperature_k / reference_k).sqrt())
}

/// Damping ratios closer to 1 than this after scaling are moved to `1 + this` (two real poles
/// that stay apart: the modal form has no repeated poles).
const CRITICAL_GAP: f64 = 1e-3;

/// The pole `s` (of a resonance: `s = -zeta w + j w sqrt(1 - zeta^2)`) with its damping ratio
/// times `factor` and its natural frequency `w = |s|` kept. A real pole is kept; a resonance
/// damped past critical becomes two real poles `-w (zeta -+ sqrt(zeta^2 - 1))` (the upper pole
/// of the pair takes the slower one).
fn damped_pole(s: Complex, factor: f64) -> Complex {
    let w = s.norm();
    if s.im == 0.0 || s.im.abs() <= 1e-12 * w || factor == 1.0 {
        return s;
    }
    let zeta = (-s.re / w) * factor;
    if zeta < 1.0 - CRITICAL_GAP {
        return Complex::new(-zeta * w, s.im.signum() * w * (1.0 - zeta * zeta).sqrt());
    }
    let zeta = zeta.max(1.0 + CRITICAL_GAP);
    let root = (zeta * zeta - 1.0).sqrt();
    Complex::new(-w * (zeta - s.im.signum() * root), 0.0)
}

fn scale_continuous(ct: &Continuous, k: f64, damping_factor: f64, fs: f64) -> Result<Model> {
    let mut out = ct.clone();
    let one = Complex::new(1.0, 0.0);
    // Time scaled by k: H(s / k) has the poles k s_i and the residues k r_i.
    let old: Vec<Complex> = ct
        .poles
        .iter()
        .map(|r| Complex::new(k * r.re, k * r.im))
        .collect();
    let res: Vec<Complex> = ct
        .residues
        .iter()
        .map(|r| Complex::new(k * r.re, k * r.im))
        .collect();
    let new: Vec<Complex> = old
        .iter()
        .map(|&s| damped_pole(s, damping_factor))
        .collect();
    // The damping moved: H'(s) = H(s / k) Q(s), Q(s) = C prod_j (s - old_j) / (s - new_j) with
    // C = prod_j new_j / old_j (Q(0) = 1: the DC gain kept; the zeros of H(s / k) kept). Its
    // residue at new_i, written so that it is k r_i when nothing moved.
    let c = new.iter().zip(&old).fold(one, |acc, (n, o)| acc * *n / *o);
    let residues: Vec<Complex> = (0..new.len())
        .map(|i| {
            let (ni, mut rest, mut ratio) = (new[i], Complex::new(ct.feedthrough, 0.0), one);
            for j in (0..new.len()).filter(|&j| j != i) {
                rest += res[j] / (ni - old[j]);
                ratio = ratio * (ni - old[j]) / (ni - new[j]);
            }
            c * (rest * (ni - old[i]) + res[i]) * ratio
        })
        .collect();
    if residues
        .iter()
        .any(|r| !(r.re.is_finite() && r.im.is_finite()))
    {
        return Err(crate::error::Error::Numerical {
            context: "temperature scaling".into(),
            message: format!(
                "the damping scaled by {damping_factor} puts two poles together: no modal form"
            ),
        });
    }
    out.poles = new
        .into_iter()
        .map(crate::fit::analysis::Root::from)
        .collect();
    out.residues = residues
        .into_iter()
        .map(crate::fit::analysis::Root::from)
        .collect();
    out.feedthrough = ct.feedthrough * c.re;
    out.delay_s /= k;
    Ok(out.discretise(fs)?.model)
}

/// The model with time scaled by `k`: `H_k(s) = H(s / k)`, every pole (natural frequency) times
/// `k` and the delay over `k`, re-discretised at the model's rate (step invariant, through
/// [`Continuous`]). The damping ratios are kept ([`scaled_with`] moves them too).
///
/// # Errors
/// As [`Continuous::from_model`] and [`Continuous::discretise`].
pub fn scaled(model: &Model, k: f64) -> Result<Model> {
    scaled_with(model, k, 1.0)
}

/// As [`scaled`], and the damping ratio of every resonance (complex pole pair) multiplied by
/// `damping_factor`, its natural frequency kept: the poles `s = -zeta w +- j w sqrt(1 - zeta^2)`
/// move to `zeta' = damping_factor zeta` (two real poles beyond critical damping); real poles
/// only scale by `k`. The zeros of `H(s / k)` and the DC gain are kept, the feedthrough (if
/// any) is multiplied by the product of the new poles over the old.
///
/// # Errors
/// As [`scaled`]; [`crate::error::Error::Numerical`] when two moved poles coincide.
pub fn scaled_with(model: &Model, k: f64, damping_factor: f64) -> Result<Model> {
    let ct = Continuous::from_model(model)?;
    scale_continuous(&ct, k, damping_factor, model.fs)
}

/// The time-scale factor `k` in [`SCALE_RANGE`] that makes the scaled model fit the test best
/// (least squares of the residual about its mean: a log grid, then a golden-section search
/// between the best point's neighbours). 1 when the model has no continuous-time equivalent.
/// The damping is kept ([`estimate_scale_with`] follows a law).
#[must_use]
pub fn estimate_scale(model: &Model, u: &[f64], y: &[f64]) -> f64 {
    estimate_scale_with(
        model,
        TemperatureDamping::Constant,
        DEFAULT_REFERENCE_K,
        u,
        y,
    )
}

/// As [`estimate_scale`], with the damping following `damping` for a model at `reference_k`:
/// still one parameter, the damping factor follows from `k` through `T = reference_k k^2`.
#[must_use]
pub fn estimate_scale_with(
    model: &Model,
    damping: TemperatureDamping,
    reference_k: f64,
    u: &[f64],
    y: &[f64],
) -> f64 {
    let Ok(ct) = Continuous::from_model(model) else {
        return 1.0;
    };
    let cost = |ln_k: f64| -> f64 {
        let k = ln_k.exp();
        let Ok(m) = scale_continuous(&ct, k, damping.factor(k, reference_k), model.fs) else {
            return f64::INFINITY;
        };
        let r: Vec<f64> = y.iter().zip(m.simulate(u)).map(|(a, b)| a - b).collect();
        let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
        let sse: f64 = r.iter().map(|v| (v - mean) * (v - mean)).sum();
        if sse.is_finite() {
            sse
        } else {
            f64::INFINITY
        }
    };
    let (lo, hi) = (SCALE_RANGE.0.ln(), SCALE_RANGE.1.ln());
    let n = 29;
    let grid: Vec<f64> = (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect();
    let costs: Vec<f64> = grid.iter().map(|&x| cost(x)).collect();
    let best = costs
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(n - 1)]);
    let g = 0.5 * (5.0f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (cost(x1), cost(x2));
    for _ in 0..30 {
        if f1 < f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = cost(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = cost(x2);
        }
    }
    let x = 0.5 * (a + b);
    if cost(x) <= costs[best] {
        x.exp()
    } else {
        grid[best].exp()
    }
}

/// The sensor-resonance prefilter's group delay at low frequency (samples), 0 without one.
#[must_use]
pub fn prefilter_delay(effects: &[Effect], fs: f64) -> f64 {
    let Some((gain, sections)) =
        prefilter_hz(effects).and_then(|fc| prefilter_sections(fc, fs).ok())
    else {
        return 0.0;
    };
    // From the phase at a low frequency (the prefilter's phase is linear there).
    let w: f64 = 1e-4;
    let h = crate::design::inverse::cascade_response(
        gain,
        &sections,
        crate::poly::Complex::new(w.cos(), w.sin()),
    );
    -h.im.atan2(h.re) / w
}

/// Puts the sensor-resonance prefilter of `effects` in front of a compensator designed for
/// the model (which was fitted on prefiltered signals): its sections run first on the board,
/// its gain multiplies the cascade's, its group delay at low frequency adds to the latency,
/// and the pole margin is the smaller of the two. Nothing happens without a prefilter.
///
/// # Errors
/// As [`prefilter_sections`].
pub fn with_prefilter(
    design: &mut crate::design::inverse::Design,
    effects: &[Effect],
    fs: f64,
) -> Result<()> {
    let Some(fc) = prefilter_hz(effects) else {
        return Ok(());
    };
    let (gain, sections) = prefilter_sections(fc, fs)?;
    let delay = prefilter_delay(effects, fs);
    let margin = sections
        .iter()
        .map(|s| {
            // |poles| of 1 + a1 z^-1 + a2 z^-2: sqrt(a2) for a complex pair.
            let (a1, a2) = (s[3], s[4]);
            let disc = a1 * a1 - 4.0 * a2;
            let r = if disc < 0.0 {
                a2.abs().sqrt()
            } else {
                0.5 * (a1.abs() + disc.sqrt())
            };
            1.0 - r
        })
        .fold(f64::INFINITY, f64::min);
    design.sections.splice(0..0, sections);
    design.gain *= gain;
    design.latency_samples += delay;
    design.latency_s = design.latency_samples / fs;
    design.pole_margin = design.pole_margin.min(margin);
    design.method = design.method.clone().after_prefilter(&format!(
        "sensor-resonance prefilter (Butterworth order {PREFILTER_ORDER} at {fc:.1} Hz)"
    ));
    Ok(())
}

/// The effects with their frequency-domain parameters resolved on the estimation test: a
/// sensor resonance without a frequency takes the reference's ringing peak, and its prefilter
/// half of it.
///
/// # Errors
/// [`crate::error::Error::InvalidArgument`] when the reference shows no resonance to filter
/// below, or the prefilter's corner is not below half the sample rate.
pub fn resolve(effects: &[Effect], u: &[f64], fs: f64) -> Result<Vec<Effect>> {
    effects
        .iter()
        .map(|e| match e {
            Effect::SensorResonance {
                natural_frequency_hz,
                prefilter_hz,
                remedy,
            } => {
                let f = if *natural_frequency_hz > 0.0 {
                    *natural_frequency_hz
                } else {
                    crate::modelling::evidence::reference_ringing(u, fs)
                        .map(|p| p.frequency_hz)
                        .ok_or_else(|| crate::error::Error::InvalidArgument {
                            what: "sensor-resonance",
                            message: "the estimation test's reference shows no resonance to \
                                      filter below; give the transducer's natural frequency: \
                                      --add sensor-resonance=HZ"
                                .into(),
                        })?
                };
                if *remedy == SensorRemedy::Modes {
                    if f >= 0.5 * fs {
                        return Err(crate::error::Error::InvalidArgument {
                            what: "sensor-resonance",
                            message: format!(
                                "the transducer's natural frequency {f} Hz is not below half \
                                 the sample rate ({} Hz): the record cannot show it",
                                0.5 * fs
                            ),
                        });
                    }
                    return Ok(Effect::SensorResonance {
                        natural_frequency_hz: f,
                        prefilter_hz: 0.0,
                        remedy: *remedy,
                    });
                }
                let corner = if *prefilter_hz > 0.0 {
                    *prefilter_hz
                } else {
                    0.5 * f
                };
                prefilter_sections(corner, fs)?;
                Ok(Effect::SensorResonance {
                    natural_frequency_hz: f,
                    prefilter_hz: corner,
                    remedy: *remedy,
                })
            }
            Effect::Temperature { reference_k, .. } => {
                scale_for(*reference_k, *reference_k)?;
                Ok(e.clone())
            }
            other => Ok(other.clone()),
        })
        .collect()
}

/// Fits with `effects`: the order raised by the modes and leaks, the delay and method they
/// impose, and the drift removed before the dynamics are fitted (alternating three times).
/// With `nonlinear-damping` the linear part and the quadratic loss are fitted together (a
/// search over the loss, the linear part refitted at each; see `fit_nonlinear`).
/// Returns the fit and the effects with their fitted parameters (from the estimation test).
///
/// # Errors
/// As [`crate::fit::fit`].
pub fn fit_with(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    options: &Options,
    effects: &[Effect],
) -> Result<(Fitted, Vec<Effect>)> {
    let (estimation_raw, validation_raw) = (estimation, validation);
    let changes = FitChanges::of(effects);
    let order = match options.order {
        Order::Fixed(m) => Order::Fixed(m + changes.extra_order),
        Order::Auto { max } => Order::Auto {
            max: max + changes.extra_order,
        },
    };
    let opts = Options {
        method: changes.method.unwrap_or(options.method),
        order,
        delay: changes.delay.or(options.delay),
    };
    // A sensor resonance: both channels of every test prefiltered below it.
    let effects = resolve(effects, estimation.u, fs)?;
    let filtered: Vec<(Vec<f64>, Vec<f64>)> = std::iter::once(estimation)
        .chain(validation)
        .map(|t| {
            (
                prefiltered(&effects, fs, t.u),
                prefiltered(&effects, fs, t.y),
            )
        })
        .collect();
    let mut tests = filtered
        .iter()
        .zip(std::iter::once(estimation).chain(validation))
        .map(|((u, y), t)| Test { name: t.name, u, y });
    let Some(estimation) = tests.next() else {
        return Err(crate::error::Error::Numerical {
            context: "fit".into(),
            message: "no estimation test".into(),
        });
    };
    let validation: Vec<Test<'_>> = tests.collect();
    let validation = validation.as_slice();
    let onset = crate::fit::step::find_step(estimation.u).map_or(0, |s| s.onset);
    // A drift starts from the record's ends, so that the first fit does not take it into
    // the dynamics (from which the residual could no longer separate it).
    let mut additive = if changes.drift {
        initial_drift(estimation.u, estimation.y, onset, fs)
    } else {
        Additive::default()
    };
    let rounds = if changes.drift { 4 } else { 1 };
    let mut gain = 0.0;
    let mut fitted = None;
    for _ in 0..rounds {
        let y = additive.removed_from(estimation.y, fs);
        let est = Test {
            name: estimation.name,
            u: estimation.u,
            y: &y,
        };
        let f = if changes.nonlinear {
            let (f, g) = fit_nonlinear(&est, validation, fs, &opts)?;
            gain = g;
            f
        } else {
            crate::fit::fit(&est, validation, fs, &opts)?
        };
        let r: Vec<f64> = estimation
            .y
            .iter()
            .zip(simulate_nonlinear(&f.model, gain, estimation.u))
            .map(|(a, b)| a - b)
            .collect();
        additive = estimate_additive(&changes, &r, onset, fs);
        fitted = Some(f);
    }
    let fitted = fitted.ok_or_else(|| crate::error::Error::Numerical {
        context: "fit".into(),
        message: "no fit".into(),
    })?;
    let out: Vec<Effect> = effects
        .iter()
        .map(|e| match e {
            Effect::Offset { .. } => Effect::Offset {
                value: additive.offset,
            },
            Effect::Drift { .. } => Effect::Drift {
                value: additive.offset,
                rate_per_s: additive.rate_per_s,
            },
            Effect::NonlinearDamping { .. } => Effect::NonlinearDamping { gain },
            other => other.clone(),
        })
        .collect();
    let out = with_noise_model(&fitted.model, out, estimation_raw);
    // A real pole slower than the record is not resolved by it: a drift makes the same
    // creep, and a near-integrator pole-zero pair inverts it into a runaway. Unless the user
    // asked for a leak or a drift, try the drift and keep it when it explains the estimation
    // test as well (within 10 %) with the dynamics it leaves.
    let asked = effects
        .iter()
        .any(|e| matches!(e, Effect::Leak | Effect::Drift { .. }));
    let after_step = estimation.y.len().saturating_sub(onset) as f64;
    let slow = fitted.model.poles().ok().and_then(|poles| {
        poles
            .iter()
            .filter(|p| p.im.abs() < 1e-9 && p.re > 0.0 && p.re < 1.0)
            .map(|p| -1.0 / p.re.ln())
            .find(|tau| *tau > after_step)
    });
    if let (false, Some(tau)) = (asked, slow) {
        let mut with_drift = out.clone();
        with_drift.push(Effect::Drift {
            value: 0.0,
            rate_per_s: 0.0,
        });
        if let Ok((mut f, fx)) = fit_with(estimation_raw, validation_raw, fs, options, &with_drift)
        {
            let still_slow = f.model.poles().map_or(true, |poles| {
                poles.iter().any(|p| {
                    p.im.abs() < 1e-9 && p.re > 0.0 && p.re < 1.0 && -1.0 / p.re.ln() > after_step
                })
            });
            if !still_slow && f.nrmse_estimation <= 1.1 * fitted.nrmse_estimation {
                f.report.notes.push(format!(
                    "a real pole with time constant {:.4} s, longer than the {:.4} s after the step, was read as a drift of {:.4e} per second (a drift is removed before compensation, never inverted): `--add leak` keeps it as dynamics",
                    tau / fs,
                    after_step / fs,
                    additive_rate(&fx)
                ));
                return Ok((f, fx));
            }
        }
    }
    Ok((fitted, out))
}

/// Fits the `coloured-noise` effect's AR model, if `effects` has one, to what the model and
/// the other effects leave on the estimation test.
fn with_noise_model(model: &Model, effects: Vec<Effect>, estimation: &Test<'_>) -> Vec<Effect> {
    if !effects
        .iter()
        .any(|e| matches!(e, Effect::ColouredNoise { .. }))
    {
        return effects;
    }
    let v = residual(model, &effects, estimation.u, estimation.y);
    let noise = crate::fit::noise::fit(&v, crate::fit::noise::MAX_NOISE_ORDER);
    effects
        .into_iter()
        .map(|e| match e {
            Effect::ColouredNoise { .. } => Effect::ColouredNoise {
                ar: noise.ar.clone(),
                innovation_std: noise.innovation_std,
            },
            other => other,
        })
        .collect()
}

/// What a model with effects cannot predict of a test one step ahead: `y - G u` (effects
/// included) whitened by the `coloured-noise` effect's noise model; without one it is the
/// simulation error `y - G u` itself.
#[must_use]
pub fn prediction_error(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    let v = residual(model, effects, u, y);
    match noise_model(effects) {
        Some(ar) => crate::fit::noise::whiten(ar, &v),
        None => v,
    }
}

/// What the model with its effects leaves of a test: the observed probe signal less
/// [`predict`].
fn residual(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    let ym = predict(model, effects, u, y);
    observed(effects, model.fs, y)
        .iter()
        .zip(&ym)
        .map(|(a, b)| a - b)
        .collect()
}

/// The fitted AR noise model of a `coloured-noise` effect, if any.
#[must_use]
pub fn noise_model(effects: &[Effect]) -> Option<&[f64]> {
    effects.iter().find_map(|e| match e {
        Effect::ColouredNoise { ar, .. } if !ar.is_empty() => Some(ar.as_slice()),
        _ => None,
    })
}

/// The innovation standard deviation of a `coloured-noise` effect's noise model (0 without).
#[must_use]
pub fn innovation_std(effects: &[Effect]) -> f64 {
    effects
        .iter()
        .find_map(|e| match e {
            Effect::ColouredNoise { innovation_std, .. } => Some(*innovation_std),
            _ => None,
        })
        .unwrap_or(0.0)
}

/// The normalised RMS error a model with effects is judged by on a test: the one-step-ahead
/// prediction error when it has a noise model, else the simulation error (the same thing for
/// white residuals); over the range of the observed probe signal.
#[must_use]
pub fn judged_nrmse(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> f64 {
    crate::fit::nrmse_of_error(
        &observed(effects, model.fs, y),
        prediction_error(model, effects, u, y),
    )
}

/// A first drift estimate from the record's ends: the probe's slope over its last 30 % less
/// the reference's slope there scaled by the probe's step gain, and the level before the step.
fn initial_drift(u: &[f64], y: &[f64], onset: usize, fs: f64) -> Additive {
    let slope = |x: &[f64]| -> (f64, f64) {
        let n = x.len() as f64;
        let tm = 0.5 * (n - 1.0);
        let m = x.iter().sum::<f64>() / n.max(1.0);
        let (mut num, mut den) = (0.0, 0.0);
        for (k, v) in x.iter().enumerate() {
            let t = k as f64 - tm;
            num += t * (v - m);
            den += t * t;
        }
        (m, if den > 0.0 { num / den } else { 0.0 })
    };
    let n = y.len().min(u.len());
    let tail = n - (3 * n / 10).max(2).min(n);
    let (Some(yt), Some(ut)) = (y.get(tail..n), u.get(tail..n)) else {
        return Additive::default();
    };
    let (y_tail, y_slope) = slope(yt);
    let (u_tail, u_slope) = slope(ut);
    let pre = onset.max(1).min(n);
    let y0 = y
        .get(..pre)
        .map_or(0.0, |x| x.iter().sum::<f64>() / x.len().max(1) as f64);
    let u0 = u
        .get(..pre)
        .map_or(0.0, |x| x.iter().sum::<f64>() / x.len().max(1) as f64);
    let gain = if (u_tail - u0).abs() > 0.0 {
        (y_tail - y0) / (u_tail - u0)
    } else {
        1.0
    };
    let rate_per_sample = y_slope - gain * u_slope;
    // The ramp passes through zero at the onset: the level before the step is the probe's.
    Additive {
        offset: -rate_per_sample * onset as f64,
        rate_per_s: rate_per_sample * fs,
    }
}

/// The drift rate among `effects` (0 without one).
fn additive_rate(effects: &[Effect]) -> f64 {
    Additive::of(effects).rate_per_s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::second_order;

    #[test]
    fn every_kind_has_the_text_of_before_in_every_form() {
        // The strings of model files, `--json` and `--add` before the kinds were typed.
        let texts = [
            "mode",
            "leak",
            "offset",
            "drift",
            "delay",
            "coloured-noise",
            "nonlinear-damping",
            "sensor-resonance",
            "sensor-resonance-prefilter",
            "temperature",
            "temperature-viscous",
        ];
        for (k, t) in EffectKind::ALL.into_iter().zip(texts) {
            assert_eq!(k.to_string(), t);
            assert_eq!(t.parse::<EffectKind>(), Ok(k));
            assert_eq!(serde_json::to_string(&k).unwrap(), format!("\"{t}\""));
            assert_eq!(
                serde_json::from_str::<EffectKind>(&format!("\"{t}\"")).unwrap(),
                k
            );
            // The kind of the effect it adds is its family, the model file's `kind`.
            if let Some(e) = Effect::fresh(k) {
                assert_eq!(e.kind(), k.family());
                let text = toml::to_string(&e).unwrap();
                assert!(
                    text.contains(&format!("kind = \"{}\"", k.family())),
                    "{text}"
                );
            }
        }
        assert_eq!(format!("{:<8}|", EffectKind::Leak), "leak    |");
        assert_eq!(
            "temperature=300".parse::<EffectKind>(),
            Err(UnknownKind("temperature=300".into()))
        );
        // The parameters charged are those of before, per name.
        let charged: Vec<usize> = EffectKind::ALL.map(EffectKind::parameters).to_vec();
        assert_eq!(charged, [4, 2, 1, 2, 0, 0, 1, 4, 0, 1, 1]);
    }

    #[test]
    fn kinds_round_trip_through_toml() {
        #[derive(Serialize, Deserialize)]
        struct W {
            effects: Vec<Effect>,
        }
        let w = W {
            effects: vec![
                Effect::Mode {
                    near_hz: Some(410.0),
                },
                Effect::Leak,
                Effect::Drift {
                    value: 0.1,
                    rate_per_s: -0.5,
                },
                Effect::Delay { samples: 17 },
                Effect::ColouredNoise {
                    ar: vec![-0.9],
                    innovation_std: 0.01,
                },
                Effect::NonlinearDamping { gain: 1.25e-6 },
            ],
        };
        let text = toml::to_string(&w).unwrap();
        assert!(text.contains("kind = \"coloured-noise\""), "{text}");
        assert!(text.contains("kind = \"nonlinear-damping\""), "{text}");
        let back: W = toml::from_str(&text).unwrap();
        assert_eq!(back.effects, w.effects);
        for k in KINDS {
            let e = if k == EffectKind::Delay {
                Effect::parse("delay=3")
            } else {
                Effect::parse(k.as_str())
            };
            assert_eq!(e.map(|e| e.kind()), Some(k));
        }
        assert!(Effect::parse("gremlins").is_none());
        assert!(Effect::parse("delay").is_none());
    }

    #[test]
    fn changes_and_additive_parts() {
        let e = [
            Effect::Mode { near_hz: None },
            Effect::Leak,
            Effect::Offset { value: 2.0 },
            Effect::Drift {
                value: 1.0,
                rate_per_s: 10.0,
            },
        ];
        let c = FitChanges::of(&e);
        assert_eq!(c.extra_order, 3);
        assert!(c.offset && c.drift);
        let a = Additive::of(&e);
        assert_eq!(a.at(0, 100.0), 3.0);
        assert_eq!(a.at(100, 100.0), 13.0);
        assert_eq!(a.removed_from(&[3.0, 3.1], 100.0), vec![0.0, 0.0]);
        // Estimated back from a residual that is exactly a ramp.
        let r: Vec<f64> = (0..1000).map(|k| 0.5 + 2.0 * k as f64 / 1000.0).collect();
        let est = estimate_additive(&c, &r, 100, 1000.0);
        assert!((est.offset - 0.5).abs() < 1e-9 && (est.rate_per_s - 2.0).abs() < 1e-9);
    }

    #[test]
    fn quadratic_losses_obey_the_model_equation_and_invert_exactly() {
        // DC gain 1, zeros of B at |z|^2 = 0.2 (invertible), delay 3.
        let model = Model {
            fs: 1000.0,
            delay: 3,
            a: vec![-1.6, 0.7],
            b: vec![0.05, 0.04, 0.01],
        };
        let u: Vec<f64> = (0..400)
            .map(|k| match k {
                0..20 => 0.0,
                20..150 => 1.0,
                _ => 0.2,
            })
            .collect();
        // Without the loss it is the linear model (to rounding: the sums run in another order).
        let linear = model.simulate(&u);
        for (x, l) in simulate_nonlinear(&model, 0.0, &u).iter().zip(&linear) {
            assert!((x - l).abs() < 1e-12, "{x} vs {l}");
        }
        let g = 2e-5;
        let y = simulate_nonlinear(&model, g, &u);
        let n = quadratic_rate(&y, model.fs);
        // The loss is a real part of the response (peak |g N| well above rounding) ...
        let peak = n.iter().fold(0.0f64, |m, v| m.max((g * v).abs()));
        assert!(peak > 0.05, "{peak}");
        // ... and every sample satisfies A y = B (q^-d u - g N), the b0 term included.
        for k in 5..u.len() {
            let mut e = y[k] + model.a[0] * y[k - 1] + model.a[1] * y[k - 2];
            for (i, bi) in model.b.iter().enumerate() {
                e -= bi * (u[k - i - 3] - g * n[k - i]);
            }
            assert!(e.abs() < 1e-12, "sample {k}: {e}");
        }
        // The inverse is the linear one plus g N: the reference comes back, d samples late.
        let linear = model.compensate::<f64>(&y).unwrap();
        for k in 3..u.len() {
            let u_hat = linear[k] + g * n[k];
            assert!((u_hat - u[k - 3]).abs() < 1e-9, "sample {k}: {u_hat}");
        }
        // Without the correction it does not.
        let worst = (3..u.len())
            .map(|k| (linear[k] - u[k - 3]).abs())
            .fold(0.0, f64::max);
        assert!(worst > 0.05, "{worst}");
    }

    /// A ZOH-discretised second-order probe (unit DC gain), built from its poles
    /// `z = exp(s / fs)` directly.
    #[test]
    fn scaling_multiplies_every_pole_and_divides_the_delay() {
        let fs = 10_000.0;
        let (m, s) = second_order(95.0, 0.3, fs, 17);
        let k = 1.08;
        let scaled_model = scaled(&m, k).unwrap();
        let want = (s * k / fs).exp();
        let got = scaled_model.poles().unwrap();
        assert!(
            got.iter().any(|p| (*p - want).norm() < 1e-9)
                && got.iter().any(|p| (*p - want.conj()).norm() < 1e-9),
            "{got:?} against {want:?}"
        );
        assert!((scaled_model.dc_gain() - 1.0).abs() < 1e-9);
        // 17 samples plus the fraction the b coefficients carry, over 1.08.
        assert!(
            scaled_model.delay <= 17 && scaled_model.delay >= 15,
            "{}",
            scaled_model.delay
        );
        // And back: scaling by 1/k returns the model's step response.
        let back = scaled(&scaled_model, 1.0 / k).unwrap();
        let (s0, s1) = (
            crate::fit::continuous::step_response(&m, 400),
            crate::fit::continuous::step_response(&back, 400),
        );
        let worst = s0
            .iter()
            .zip(&s1)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{worst}");
        assert!((scale_for(343.15, 293.15).unwrap() - (343.15f64 / 293.15).sqrt()).abs() < 1e-15);
        assert!(scale_for(-1.0, 293.15).is_err());
    }

    #[test]
    fn the_scale_of_a_test_is_estimated_from_it() {
        let fs = 10_000.0;
        let (m, _) = second_order(95.0, 0.3, fs, 17);
        let u: Vec<f64> = (0..4000)
            .map(|k| if k >= 500 { 1.0 } else { 0.0 })
            .collect();
        let mut seed = 7u64;
        let truth = scaled(&m, 0.93).unwrap();
        let y: Vec<f64> = truth
            .simulate(&u)
            .iter()
            .map(|v| {
                seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                v + 0.002 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
            })
            .collect();
        let k = estimate_scale(&m, &u, &y);
        assert!((k - 0.93).abs() < 0.002, "{k}");
        let e = [Effect::Temperature {
            reference_k: 293.15,
            damping: TemperatureDamping::Constant,
        }];
        let ym = predict(&m, &e, &u, &y);
        assert!(crate::fit::nrmse_of(&y, &ym) < 0.002);
        assert!(crate::fit::nrmse_of(&y, &m.simulate(&u)) > 0.01);
    }

    #[test]
    fn the_viscous_damping_factor_follows_the_kinematic_viscosity_of_air() {
        use crate::physics::Gas;
        // Independently: nu = mu / rho of the physics module's air at both temperatures, and
        // the natural frequency's ratio from the speeds of sound.
        let zeta_ratio = |t0: f64, t1: f64, p: f64| {
            let (g0, g1) = (Gas::air(t0, p), Gas::air(t1, p));
            let nu = (g1.viscosity_pa_s / g1.density()) / (g0.viscosity_pa_s / g0.density());
            nu / (g1.speed_of_sound() / g0.speed_of_sound())
        };
        for (t0, t1) in [(293.15, 343.15), (293.15, 253.15), (310.0, 400.0)] {
            let got = viscous_damping_factor(t1, t0).unwrap();
            let want = zeta_ratio(t0, t1, 101_325.0);
            assert!(
                (got / want - 1.0).abs() < 1e-12,
                "{t0} -> {t1}: {got} against {want}"
            );
            // The mean pressure cancels in the ratio.
            let low = zeta_ratio(t0, t1, 20_000.0);
            assert!((got / low - 1.0).abs() < 1e-12, "{got} against {low}");
        }
        // About +22 % from 20 to 70 degrees Celsius (the brief's "about +20 %"), below 1 colder.
        let hot = viscous_damping_factor(343.15, 293.15).unwrap();
        assert!(hot > 1.19 && hot < 1.25, "{hot}");
        assert!(viscous_damping_factor(253.15, 293.15).unwrap() < 0.9);
        // Through the law, from k: the temperature is reference k^2.
        let k = (343.15f64 / 293.15).sqrt();
        assert!((TemperatureDamping::Viscous.factor(k, 293.15) / hot - 1.0).abs() < 1e-12);
        assert_eq!(TemperatureDamping::Constant.factor(k, 293.15), 1.0);
        assert!(viscous_damping_factor(0.0, 293.15).is_err());
    }

    #[test]
    fn damping_scaling_moves_every_pole_to_the_expected_place() {
        let fs = 10_000.0;
        let (m, s) = second_order(95.0, 0.3, fs, 17);
        let (k, f) = (1.08, 1.2);
        let w = s.norm();
        // zeta 0.3 -> 0.36 at natural frequency k w.
        let want_s = Complex::new(-0.36 * k * w, k * w * (1.0 - 0.36f64 * 0.36).sqrt());
        let want = (want_s / fs).exp();
        let got = scaled_with(&m, k, f).unwrap();
        let poles = got.poles().unwrap();
        assert!(
            poles.iter().any(|p| (*p - want).norm() < 1e-9)
                && poles.iter().any(|p| (*p - want.conj()).norm() < 1e-9),
            "{poles:?} against {want:?}"
        );
        assert!((got.dc_gain() - 1.0).abs() < 1e-9, "{}", got.dc_gain());
        // More damping: a smaller overshoot of the step response than the frequency-only scaling.
        let peak = |m: &Model| {
            crate::fit::continuous::step_response(m, 600)
                .into_iter()
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let frequency_only = scaled(&m, k).unwrap();
        assert!(peak(&got) < peak(&frequency_only) - 0.01);
        // A factor of 1 is the frequency-only scaling.
        let same = scaled_with(&m, k, 1.0).unwrap();
        assert_eq!(same, frequency_only);
        // Past critical damping: two real poles -k w (zeta -+ sqrt(zeta^2 - 1)), zeta = 1.2.
        let over = scaled_with(&m, k, 4.0).unwrap();
        let mut got: Vec<f64> = over.poles().unwrap().iter().map(|p| p.re).collect();
        got.sort_by(f64::total_cmp);
        let root = (1.2f64 * 1.2 - 1.0).sqrt();
        let mut want: Vec<f64> = [1.2 - root, 1.2 + root]
            .iter()
            .map(|z| (-k * w * z / fs).exp())
            .collect();
        want.sort_by(f64::total_cmp);
        assert!(
            got.iter().zip(&want).all(|(a, b)| (a - b).abs() < 1e-9),
            "{got:?} against {want:?}"
        );
        assert!((over.dc_gain() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_viscous_temperature_is_estimated_and_predicted_with_its_damping() {
        let fs = 10_000.0;
        let (m, _) = second_order(95.0, 0.3, fs, 17);
        let u: Vec<f64> = (0..4000)
            .map(|k| if k >= 500 { 1.0 } else { 0.0 })
            .collect();
        // The probe at 343.15 K: zeta x1.22 at k w (where `scaled_with` puts the poles is
        // checked against their formula above).
        let k_true = (343.15f64 / 293.15).sqrt();
        let f = viscous_damping_factor(343.15, 293.15).unwrap();
        let truth = scaled_with(&m, k_true, f).unwrap();
        let y = truth.simulate(&u);
        let k = estimate_scale_with(&m, TemperatureDamping::Viscous, 293.15, &u, &y);
        assert!((k / k_true - 1.0).abs() < 0.01, "{k} against {k_true}");
        let viscous = [Effect::parse("temperature-viscous").unwrap()];
        let constant = [Effect::parse("temperature").unwrap()];
        let e_viscous = crate::fit::nrmse_of(&y, &predict(&m, &viscous, &u, &y));
        let e_constant = crate::fit::nrmse_of(&y, &predict(&m, &constant, &u, &y));
        assert!(
            e_viscous < 0.3 * e_constant,
            "{e_viscous} against {e_constant}"
        );
    }

    #[test]
    fn the_damping_law_round_trips_and_old_files_load_constant() {
        #[derive(Serialize, Deserialize)]
        struct W {
            effects: Vec<Effect>,
        }
        let old: W =
            toml::from_str("effects = [{ kind = \"temperature\", reference_k = 300.0 }]").unwrap();
        assert_eq!(
            temperature_law(&old.effects),
            Some((300.0, TemperatureDamping::Constant))
        );
        // Constant is not written (files stay as they were); viscous is.
        let text = toml::to_string(&old).unwrap();
        assert!(!text.contains("damping"), "{text}");
        let w = W {
            effects: vec![Effect::parse("temperature-viscous=310").unwrap()],
        };
        let text = toml::to_string(&w).unwrap();
        assert!(text.contains("damping = \"viscous\""), "{text}");
        let back: W = toml::from_str(&text).unwrap();
        assert_eq!(
            temperature_law(&back.effects),
            Some((310.0, TemperatureDamping::Viscous))
        );
        assert_eq!(back.effects[0].kind(), EffectKind::Temperature);
        assert!(Effect::parse("temperature-viscous=-1").is_none());
        assert!(Effect::parse("temperature-sticky").is_none());
    }

    #[test]
    fn the_prefilter_passes_a_step_and_stops_the_resonance() {
        let fs = 10_000.0;
        let e = resolve(
            &[Effect::parse("sensor-resonance-prefilter=2000").unwrap()],
            &[],
            fs,
        )
        .unwrap();
        assert_eq!(prefilter_hz(&e), Some(1000.0));
        // The transducers' modes (the default remedy) prefilter nothing: two more poles and
        // zeros instead.
        let m = resolve(&[Effect::parse("sensor-resonance=2000").unwrap()], &[], fs).unwrap();
        assert_eq!(prefilter_hz(&m), None);
        assert_eq!(FitChanges::of(&m).extra_order, 2);
        let step: Vec<f64> = (0..2000)
            .map(|k| if k >= 100 { 3.0 } else { 1.0 })
            .collect();
        let f = prefiltered(&e, fs, &step);
        assert!((f[0] - 1.0).abs() < 1e-12 && (f[1999] - 3.0).abs() < 1e-9);
        let ring: Vec<f64> = (0..4000)
            .map(|k| (2.0 * std::f64::consts::PI * 2000.0 * k as f64 / fs).sin())
            .collect();
        let out = prefiltered(&e, fs, &ring);
        // Amplitude from the RMS over whole periods (2000 samples are 400 of them).
        let peak = (2.0 * out[2000..].iter().map(|v| v * v).sum::<f64>() / 2000.0).sqrt();
        // Butterworth of order 4 by the bilinear transform: |H| = 1 / sqrt(1 + r^8) with
        // r = tan(pi f / fs) / tan(pi fc / fs) (about -28 dB here).
        let r = (std::f64::consts::PI * 0.2).tan() / (std::f64::consts::PI * 0.1).tan();
        let want = 1.0 / (1.0 + r.powi(8)).sqrt();
        assert!((peak / want - 1.0).abs() < 0.01, "{peak} against {want}");
        // Without a frequency and without ringing in the reference it refuses.
        assert!(resolve(&[Effect::parse("sensor-resonance").unwrap()], &step, fs).is_err());
        assert!(resolve(
            &[Effect::parse("sensor-resonance=12000").unwrap()],
            &step,
            fs
        )
        .is_err());
        // On the board: the prefilter's sections run first.
        let (m, _) = second_order(95.0, 0.3, fs, 17);
        let mut d =
            crate::design::inverse::design(&m, 800.0, &crate::design::inverse::Options::default())
                .unwrap();
        let (n, latency) = (d.sections.len(), d.latency_samples);
        with_prefilter(&mut d, &e, fs).unwrap();
        assert_eq!(d.sections.len(), n + PREFILTER_ORDER / 2);
        assert!(
            d.latency_samples > latency + 1.0,
            "{} {latency}",
            d.latency_samples
        );
        let out = d.run::<f64>(&step).unwrap();
        assert!(
            (out[1999] - 3.0 / m.dc_gain()).abs() < 1e-6,
            "{}",
            out[1999]
        );
    }

    #[test]
    fn new_kinds_round_trip_through_toml() {
        #[derive(Serialize, Deserialize)]
        struct W {
            effects: Vec<Effect>,
        }
        let text = "effects = [{ kind = \"sensor-resonance\", natural_frequency_hz = 2000.0, prefilter_hz = 1000.0 }, { kind = \"temperature\" }]";
        let w: W = toml::from_str(text).unwrap();
        assert_eq!(
            w.effects,
            vec![
                Effect::SensorResonance {
                    natural_frequency_hz: 2000.0,
                    prefilter_hz: 1000.0,
                    remedy: SensorRemedy::Prefilter,
                },
                Effect::Temperature {
                    reference_k: DEFAULT_REFERENCE_K,
                    damping: TemperatureDamping::Constant,
                }
            ]
        );
        assert_eq!(
            Effect::parse("temperature=310"),
            Some(Effect::Temperature {
                reference_k: 310.0,
                damping: TemperatureDamping::Constant,
            })
        );
        assert!(Effect::parse("temperature=-3").is_none());
    }
}
