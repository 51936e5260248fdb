//! The names of the effects: [`EffectKind`], what `unlag fit --add` takes and a diagnosis
//! names, its text forms, and the kinds the model file stores.

use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::{Effect, SensorRemedy, TemperatureDamping};

/// The name of an effect: what `unlag fit --add` takes (without a `=VALUE`), what a
/// diagnosis names ([`crate::modelling::diagnose::Finding`]), and, for the nine kinds of [`Effect`]'s
/// variants, the `kind` of an effect in the model file.
///
/// Three names are not kinds of their own in the model file: `sensor-resonance-prefilter` is
/// a `sensor-resonance` with the paper's prefilter as its remedy ([`SensorRemedy`]), and
/// `temperature-viscous` and `temperature-diffusive` are a `temperature` with another law
/// ([`TemperatureDamping`]); [`EffectKind::family`] gives the kind they are stored as, which
/// is what [`Effect::kind`] returns.
///
/// The text forms ([`Display`](core::fmt::Display), [`FromStr`](core::str::FromStr) and
/// serde's) are the same strings everywhere: model files, `--json` output, `--add`.
///
/// ```
/// use unlag::effects::EffectKind;
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
    /// `temperature-diffusive`: the same for an overdamped line, every time scale going as the
    /// gas viscosity ([`TemperatureDamping::Diffusive`]); stored as a `temperature`.
    TemperatureDiffusive,
}

/// Text that names no [`EffectKind`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect kind '{0}'")]
pub struct UnknownKind(pub String);

impl EffectKind {
    /// Every name, in catalogue order (each family's variants after it).
    pub const ALL: [Self; 12] = [
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
        Self::TemperatureDiffusive,
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
            Self::TemperatureDiffusive => "temperature-diffusive",
        }
    }

    /// The kind it is stored as in the model file (one per [`Effect`] variant):
    /// `sensor-resonance` for `sensor-resonance-prefilter`, `temperature` for
    /// `temperature-viscous` and `temperature-diffusive`, itself for the others.
    #[must_use]
    pub const fn family(self) -> Self {
        match self {
            Self::SensorResonancePrefilter => Self::SensorResonance,
            Self::TemperatureViscous | Self::TemperatureDiffusive => Self::Temperature,
            k => k,
        }
    }

    /// Parameters it adds to the model, as the diagnosis charges them
    /// ([`crate::modelling::diagnose::parameter_penalty`] each): a section's four for a mode or the
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
            | Self::TemperatureViscous
            | Self::TemperatureDiffusive => 1,
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
