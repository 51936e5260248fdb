//! The change a candidate asks for, as a type: [`Remedy`]. Its text ([`Display`]) is in the
//! library's words and the model file's terms; a front end words it as its own command.
//!
//! [`Display`]: core::fmt::Display

use serde::{Serialize, Serializer};

#[cfg(test)]
use crate::modelling::effects::DEFAULT_REFERENCE_K;
use crate::modelling::effects::{Effect, EffectKind, SensorRemedy, TemperatureDamping};

/// The change that adds what a candidate names.
///
/// ```
/// use unlag::modelling::diagnose::Remedy;
/// use unlag::modelling::effects::Effect;
///
/// let r = Remedy::Add(Effect::Mode { near_hz: Some(120.2) });
/// assert_eq!(
///     r.model_file().unwrap(),
///     r#"effects = [{ kind = "mode", near_hz = 120 }]"#
/// );
/// assert_eq!(
///     r.to_string(),
///     r#"add the mode effect   (model file: effects = [{ kind = "mode", near_hz = 120 }])"#
/// );
/// assert_eq!(Remedy::Nothing.to_string(), "none");
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Remedy {
    /// Add this effect to the model, with the values a diagnosis can give (a mode's
    /// frequency, a sensor resonance's, a temperature's reference and damping law); the
    /// values a fit fills are left to the fit. An [`Effect::Delay`] is the same change as
    /// [`Remedy::SetDelay`].
    Add(Effect),
    /// Fix the model's delay at this many samples (a `delay` effect in the model file).
    SetDelay {
        /// The delay (samples).
        samples: usize,
    },
    /// Raise the model order, or let the fit choose it: what is missing is outside the
    /// catalogue of effects.
    RaiseOrder,
    /// Nothing to change: the model is at its noise floor.
    Nothing,
}

impl Remedy {
    /// The name of the effect it adds, as [`EffectKind`] spells it with the variant chosen
    /// (`temperature-viscous`, `sensor-resonance-prefilter`); `delay` for
    /// [`Remedy::SetDelay`]; `None` when it adds no effect.
    #[must_use]
    pub fn kind(&self) -> Option<EffectKind> {
        match self {
            Self::Add(Effect::Temperature { damping, .. }) => Some(damping.spelling()),
            Self::Add(Effect::SensorResonance {
                remedy: SensorRemedy::Prefilter,
                ..
            }) => Some(EffectKind::SensorResonancePrefilter),
            Self::Add(e) => Some(e.kind()),
            Self::SetDelay { .. } => Some(EffectKind::Delay),
            Self::RaiseOrder | Self::Nothing => None,
        }
    }

    /// The delay it fixes, for [`Remedy::SetDelay`] (or an added [`Effect::Delay`]).
    #[must_use]
    pub fn delay(&self) -> Option<usize> {
        match self {
            Self::SetDelay { samples } | Self::Add(Effect::Delay { samples }) => Some(*samples),
            _ => None,
        }
    }

    /// What to write in the model file for it, with what a value means when the entry does
    /// not say (`effects = [{ kind = "temperature", reference_k = 293.15 }]; the estimation
    /// test's temperature`); `None` when it adds no effect. Frequencies are given to the
    /// hertz.
    #[must_use]
    pub fn model_file(&self) -> Option<String> {
        let entry = match self {
            Self::SetDelay { samples } | Self::Add(Effect::Delay { samples }) => {
                format!("{{ kind = \"delay\", samples = {samples} }}")
            }
            Self::Add(Effect::Mode { near_hz: Some(f) }) => {
                format!("{{ kind = \"mode\", near_hz = {f:.0} }}")
            }
            Self::Add(Effect::SensorResonance {
                natural_frequency_hz,
                remedy,
                ..
            }) => {
                let remedy = match remedy {
                    SensorRemedy::Modes => "modes",
                    SensorRemedy::Prefilter => "prefilter",
                };
                if *natural_frequency_hz > 0.0 {
                    format!(
                        "{{ kind = \"sensor-resonance\", natural_frequency_hz = \
                         {natural_frequency_hz:.0}, remedy = \"{remedy}\" }}"
                    )
                } else {
                    format!("{{ kind = \"sensor-resonance\", remedy = \"{remedy}\" }}")
                }
            }
            Self::Add(Effect::Temperature {
                reference_k,
                damping,
            }) => {
                let law = match damping {
                    TemperatureDamping::Constant => "",
                    TemperatureDamping::Viscous => ", damping = \"viscous\"",
                };
                return Some(format!(
                    "effects = [{{ kind = \"temperature\", reference_k = {reference_k}{law} }}]; \
                     the estimation test's temperature"
                ));
            }
            Self::Add(e) => format!("{{ kind = \"{}\" }}", e.kind()),
            Self::RaiseOrder | Self::Nothing => return None,
        };
        Some(format!("effects = [{entry}]"))
    }
}

impl core::fmt::Display for Remedy {
    /// In the library's words, with the model file's entry: `add the leak effect   (model
    /// file: effects = [{ kind = "leak" }])`, `set the delay to 27 samples   (model file:
    /// ...)`, `raise the model order, or let the fit choose it`, `none`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let file = self.model_file().unwrap_or_default();
        match (self.delay(), self.kind()) {
            (Some(d), _) => write!(f, "set the delay to {d} samples   (model file: {file})"),
            (None, Some(k)) => write!(f, "add the {k} effect   (model file: {file})"),
            (None, None) => match self {
                Self::RaiseOrder => f.write_str("raise the model order, or let the fit choose it"),
                _ => f.write_str("none"),
            },
        }
    }
}

impl Serialize for Remedy {
    /// Its text ([`Display`](core::fmt::Display)).
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_library_words_each_remedy_in_model_file_terms() {
        let cases = [
            (
                Remedy::Add(Effect::Leak),
                r#"add the leak effect   (model file: effects = [{ kind = "leak" }])"#,
            ),
            (
                Remedy::Add(Effect::Mode { near_hz: None }),
                r#"add the mode effect   (model file: effects = [{ kind = "mode" }])"#,
            ),
            (
                Remedy::Add(Effect::SensorResonance {
                    natural_frequency_hz: 2998.4,
                    prefilter_hz: 0.0,
                    remedy: SensorRemedy::Modes,
                }),
                r#"add the sensor-resonance effect   (model file: effects = [{ kind = "sensor-resonance", natural_frequency_hz = 2998, remedy = "modes" }])"#,
            ),
            (
                Remedy::Add(Effect::Temperature {
                    reference_k: DEFAULT_REFERENCE_K,
                    damping: TemperatureDamping::Viscous,
                }),
                r#"add the temperature-viscous effect   (model file: effects = [{ kind = "temperature", reference_k = 293.15, damping = "viscous" }]; the estimation test's temperature)"#,
            ),
            (
                Remedy::SetDelay { samples: 27 },
                r#"set the delay to 27 samples   (model file: effects = [{ kind = "delay", samples = 27 }])"#,
            ),
            (
                Remedy::RaiseOrder,
                "raise the model order, or let the fit choose it",
            ),
            (Remedy::Nothing, "none"),
        ];
        for (r, text) in cases {
            assert_eq!(r.to_string(), text);
            assert_eq!(
                serde_json::to_string(&r).unwrap(),
                serde_json::to_string(text).unwrap()
            );
            // No command line in the library's words.
            assert!(!text.contains("--") && !text.contains("unlag"), "{text}");
        }
        assert_eq!(
            Remedy::Add(Effect::Delay { samples: 3 }).to_string(),
            Remedy::SetDelay { samples: 3 }.to_string()
        );
    }
}
