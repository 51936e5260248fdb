//! The change a candidate asks for, as a type: [`Remedy`]. Its text ([`Display`]) is in the
//! library's words and the model file's terms; [`Remedy::command`] words it as the `unlag`
//! command that makes it (what the command line and its report tell the user to type).
//!
//! [`Display`]: core::fmt::Display

use serde::{Serialize, Serializer};

use crate::effects::{Effect, EffectKind, SensorRemedy, TemperatureDamping, DEFAULT_REFERENCE_K};

/// The change that adds what a candidate names.
///
/// ```
/// use unlag::modelling::diagnose::Remedy;
/// use unlag::effects::Effect;
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
    /// Add this effect, fitted on the estimation test and these tests (their names) together:
    /// a quadratic loss, which one step cannot identify and steps of other sizes can.
    AddJointly {
        /// The effect.
        effect: Effect,
        /// The tests fitted together with the estimation test.
        also: Vec<String>,
    },
    /// Add this effect and keep the model's delay at this many samples (a `delay` effect
    /// beside it in the model file): the fit that adds it searches the delay again, and the
    /// delay it would find there raises the held-out error over the effect's trial at the
    /// delay kept.
    AddKeepingDelay {
        /// The effect.
        effect: Effect,
        /// The delay kept (samples).
        samples: usize,
    },
    /// The change `change` (an [`Remedy::Add`] or [`Remedy::AddKeepingDelay`]) with the effect
    /// `beside` (a mode) added in the same fit: the model is short of its own estimation test
    /// as well as of what `change` adds ([`super::Beside`]).
    AddBeside {
        /// The candidate's own change.
        change: Box<Remedy>,
        /// The effect added beside it.
        beside: Effect,
    },
    /// The change `change` with the model's own `modes` mode effects named again. The model's
    /// order was given (`--order N`), and a refit with an order given drops the modes the
    /// model carries ([`crate::pipeline::carried_effects`]: the order asked for wins), so the
    /// change names them as its trial kept them.
    KeepingModes {
        /// The candidate's own change.
        change: Box<Remedy>,
        /// How many mode effects the model carries.
        modes: usize,
    },
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
    /// (`temperature-viscous`, `temperature-diffusive`, `sensor-resonance-prefilter`); `delay` for
    /// [`Remedy::SetDelay`]; `None` when it adds no effect.
    #[must_use]
    pub fn kind(&self) -> Option<EffectKind> {
        match self {
            Self::Add(e) | Self::AddKeepingDelay { effect: e, .. } => Some(spelled(e)),
            Self::AddJointly { effect: e, .. } => Some(e.kind()),
            Self::AddBeside { change, .. } | Self::KeepingModes { change, .. } => change.kind(),
            Self::SetDelay { .. } => Some(EffectKind::Delay),
            Self::RaiseOrder | Self::Nothing => None,
        }
    }

    /// The delay it fixes, for [`Remedy::SetDelay`] (or an added [`Effect::Delay`]).
    #[must_use]
    pub fn delay(&self) -> Option<usize> {
        match self {
            Self::SetDelay { samples } | Self::Add(Effect::Delay { samples }) => Some(*samples),
            Self::KeepingModes { change, .. } => change.delay(),
            _ => None,
        }
    }

    /// What to write in the model file for it, with what a value means when the entry does
    /// not say (`effects = [{ kind = "temperature", reference_k = 293.15 }]; the estimation
    /// test's temperature`); `None` when it adds no effect. Frequencies are given to the
    /// hertz.
    #[must_use]
    pub fn model_file(&self) -> Option<String> {
        self.entries()
            .map(|(entries, note)| format!("effects = [{}]{note}", entries.join(", ")))
    }

    /// The model file's `effects` entries it adds, and what a value means when an entry does
    /// not say it ([`entry_note`]); `None` when it adds no effect.
    fn entries(&self) -> Option<(Vec<String>, &'static str)> {
        match self {
            Self::SetDelay { samples } => Some((vec![delay_entry(*samples)], "")),
            Self::Add(e) | Self::AddJointly { effect: e, .. } => {
                Some((vec![entry(e)], entry_note(e)))
            }
            Self::AddKeepingDelay { effect, samples } => Some((
                vec![entry(effect), delay_entry(*samples)],
                entry_note(effect),
            )),
            Self::AddBeside { change, beside } => {
                let (mut entries, note) = change.entries()?;
                entries.insert(1.min(entries.len()), entry(beside));
                Some((entries, note))
            }
            Self::KeepingModes { change, .. } => change.entries(),
            Self::RaiseOrder | Self::Nothing => None,
        }
    }

    /// What `--add` takes, once for each effect, of a change that adds effects without
    /// `--also`: `leak`; `temperature-viscous`, `mode`, `delay=20`.
    fn added(&self) -> Option<Vec<String>> {
        match self {
            Self::Add(e) => Some(vec![add_argument(e, spelled(e))]),
            Self::AddKeepingDelay { effect, samples } => Some(vec![
                add_argument(effect, spelled(effect)),
                format!("delay={samples}"),
            ]),
            Self::AddBeside { change, beside } => {
                let mut added = change.added()?;
                added.insert(1.min(added.len()), add_argument(beside, spelled(beside)));
                Some(added)
            }
            _ => None,
        }
    }

    /// The change as the `unlag` command that makes it: `unlag fit ... --add leak   (model
    /// file: effects = [{ kind = "leak" }])`, `unlag fit ... --delay 27   (model file: ...)`,
    /// `unlag fit ... --order auto   (or a higher --order N)`, `none`.
    #[must_use]
    pub fn command(&self) -> String {
        self.arguments()
            .map_or_else(|| "none".into(), |a| format!("{FIT}{a}"))
    }

    /// What the command adds after the user's fit ([`Remedy::command`]), its note included;
    /// `None` for [`Remedy::Nothing`].
    fn arguments(&self) -> Option<String> {
        if let Self::KeepingModes { change, modes } = self {
            let own = change.arguments()?;
            return Some(format!(
                "{}{own}; {}",
                " --add mode".repeat(*modes),
                modes_named_again(*modes)
            ));
        }
        let file = self.model_file().unwrap_or_default();
        if let Some(d) = self.delay() {
            return Some(format!(" --delay {d}   (model file: {file})"));
        }
        match (self, self.kind()) {
            (Self::RaiseOrder, _) => Some(" --order auto   (or a higher --order N)".into()),
            (Self::AddJointly { also, .. }, Some(kind)) => {
                let also: String = also.iter().map(|t| format!(" --also {t}")).collect();
                Some(format!("{also} --add {kind}   (model file: {file})"))
            }
            _ => self.added().map(|added| {
                let added: String = added.iter().map(|a| format!(" --add {a}")).collect();
                format!("{added}   (model file: {file})")
            }),
        }
    }
}

/// How a change's command starts: the user's fit, its arguments elided.
const FIT: &str = "unlag fit ...";

/// Why a change names the model's own modes again ([`Remedy::KeepingModes`]).
fn modes_named_again(modes: usize) -> String {
    format!(
        "the model's {} named again: a refit with an order given drops the modes a model carries",
        if modes == 1 {
            "mode".to_string()
        } else {
            format!("{modes} modes")
        }
    )
}

/// The kind an added `effect` is spelled as, with the variant chosen (`temperature-viscous`,
/// `sensor-resonance-prefilter`).
fn spelled(effect: &Effect) -> EffectKind {
    match effect {
        Effect::Temperature { damping, .. } => damping.spelling(),
        Effect::SensorResonance {
            remedy: SensorRemedy::Prefilter,
            ..
        } => EffectKind::SensorResonancePrefilter,
        e => e.kind(),
    }
}

/// What `--add` takes for `effect`: its kind, with the value the diagnosis gives (a sensor
/// resonance's frequency, a temperature's reference other than the default).
fn add_argument(effect: &Effect, kind: EffectKind) -> String {
    match effect {
        Effect::SensorResonance {
            natural_frequency_hz: f,
            ..
        } if *f > 0.0 => format!("{kind}={f:.0}"),
        Effect::Temperature { reference_k, .. }
            if reference_k.to_bits() != DEFAULT_REFERENCE_K.to_bits() =>
        {
            format!("{kind}={reference_k}")
        }
        _ => kind.to_string(),
    }
}

/// A `delay` entry of the model file's `effects`.
fn delay_entry(samples: usize) -> String {
    format!("{{ kind = \"delay\", samples = {samples} }}")
}

/// The model file's `effects` entry that adds `effect`, with the values a diagnosis gives
/// (frequencies to the hertz).
fn entry(effect: &Effect) -> String {
    match effect {
        Effect::Delay { samples } => delay_entry(*samples),
        Effect::Mode { near_hz: Some(f) } => format!("{{ kind = \"mode\", near_hz = {f:.0} }}"),
        Effect::SensorResonance {
            natural_frequency_hz,
            remedy,
            ..
        } => {
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
        Effect::Temperature {
            reference_k,
            damping,
        } => {
            let law = match damping {
                TemperatureDamping::Constant => "",
                TemperatureDamping::Viscous => ", damping = \"viscous\"",
                TemperatureDamping::Diffusive => ", damping = \"diffusive\"",
            };
            format!("{{ kind = \"temperature\", reference_k = {reference_k}{law} }}")
        }
        e => format!("{{ kind = \"{}\" }}", e.kind()),
    }
}

/// What an entry's value means when the entry does not say it: a temperature's is the
/// estimation test's.
fn entry_note(effect: &Effect) -> &'static str {
    match effect {
        Effect::Temperature { .. } => "; the estimation test's temperature",
        _ => "",
    }
}

impl core::fmt::Display for Remedy {
    /// In the library's words, with the model file's entry: `add the leak effect   (model
    /// file: effects = [{ kind = "leak" }])`, `set the delay to 27 samples   (model file:
    /// ...)`, `raise the model order, or let the fit choose it`, `none`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        if let Self::KeepingModes { change, modes } = self {
            return write!(f, "{change}; {}", modes_named_again(*modes));
        }
        let file = self.model_file().unwrap_or_default();
        match (self.delay(), self.kind()) {
            (Some(d), _) => write!(f, "set the delay to {d} samples   (model file: {file})"),
            (None, Some(k)) => match self {
                Self::AddJointly { also, .. } => write!(
                    f,
                    "add the {k} effect, fitted on the estimation test and {} together   \
                     (model file: {file})",
                    also.join(", ")
                ),
                Self::AddKeepingDelay { samples, .. } => write!(
                    f,
                    "add the {k} effect, keeping the delay at {samples} samples   (model file: \
                     {file})"
                ),
                Self::AddBeside { change, beside } => {
                    let beside = spelled(beside);
                    let which = if beside == k { "a second" } else { "the" };
                    let kept = match **change {
                        Self::AddKeepingDelay { samples, .. } => {
                            format!(", keeping the delay at {samples} samples")
                        }
                        _ => String::new(),
                    };
                    write!(
                        f,
                        "add the {k} effect and {which} {beside} effect beside it{kept}   (model \
                         file: {file})"
                    )
                }
                _ => write!(f, "add the {k} effect   (model file: {file})"),
            },
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
                Remedy::AddKeepingDelay {
                    effect: Effect::Leak,
                    samples: 6,
                },
                r#"add the leak effect, keeping the delay at 6 samples   (model file: effects = [{ kind = "leak" }, { kind = "delay", samples = 6 }])"#,
            ),
            (
                Remedy::AddBeside {
                    change: Box::new(Remedy::Add(Effect::Leak)),
                    beside: Effect::Mode { near_hz: None },
                },
                r#"add the leak effect and the mode effect beside it   (model file: effects = [{ kind = "leak" }, { kind = "mode" }])"#,
            ),
            (
                Remedy::AddBeside {
                    change: Box::new(Remedy::AddKeepingDelay {
                        effect: Effect::Leak,
                        samples: 6,
                    }),
                    beside: Effect::Mode { near_hz: None },
                },
                r#"add the leak effect and the mode effect beside it, keeping the delay at 6 samples   (model file: effects = [{ kind = "leak" }, { kind = "mode" }, { kind = "delay", samples = 6 }])"#,
            ),
            (
                Remedy::AddBeside {
                    change: Box::new(Remedy::Add(Effect::Mode {
                        near_hz: Some(240.3),
                    })),
                    beside: Effect::Mode { near_hz: None },
                },
                r#"add the mode effect and a second mode effect beside it   (model file: effects = [{ kind = "mode", near_hz = 240 }, { kind = "mode" }])"#,
            ),
            (
                Remedy::KeepingModes {
                    change: Box::new(Remedy::Add(Effect::Leak)),
                    modes: 1,
                },
                r#"add the leak effect   (model file: effects = [{ kind = "leak" }]); the model's mode named again: a refit with an order given drops the modes a model carries"#,
            ),
            (
                Remedy::SetDelay { samples: 27 },
                r#"set the delay to 27 samples   (model file: effects = [{ kind = "delay", samples = 27 }])"#,
            ),
            (
                Remedy::AddJointly {
                    effect: Effect::NonlinearDamping { gain: 0.0 },
                    also: vec!["wake.csv".into()],
                },
                r#"add the nonlinear-damping effect, fitted on the estimation test and wake.csv together   (model file: effects = [{ kind = "nonlinear-damping" }])"#,
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

    /// The command text of every kind of change, as `unlag diagnose` has always printed it.
    #[test]
    fn each_change_reads_as_the_command_that_makes_it() {
        let bare = |e: Effect, kind: &str| {
            (
                Remedy::Add(e),
                format!(
                    "unlag fit ... --add {kind}   (model file: effects = [{{ kind = \"{kind}\" }}])"
                ),
            )
        };
        let cases = [
            (
                Remedy::Add(Effect::Mode {
                    near_hz: Some(303.4),
                }),
                r#"unlag fit ... --add mode   (model file: effects = [{ kind = "mode", near_hz = 303 }])"#.to_string(),
            ),
            bare(Effect::Mode { near_hz: None }, "mode"),
            bare(Effect::Offset { value: 0.0 }, "offset"),
            bare(
                Effect::Drift {
                    value: 0.0,
                    rate_per_s: 0.0,
                },
                "drift",
            ),
            bare(Effect::Leak, "leak"),
            bare(Effect::NonlinearDamping { gain: 0.0 }, "nonlinear-damping"),
            bare(
                Effect::ColouredNoise {
                    ar: Vec::new(),
                    innovation_std: 0.0,
                },
                "coloured-noise",
            ),
            (
                Remedy::Add(Effect::SensorResonance {
                    natural_frequency_hz: 2998.2,
                    prefilter_hz: 0.0,
                    remedy: SensorRemedy::Modes,
                }),
                r#"unlag fit ... --add sensor-resonance=2998   (model file: effects = [{ kind = "sensor-resonance", natural_frequency_hz = 2998, remedy = "modes" }])"#.into(),
            ),
            (
                Remedy::Add(Effect::Temperature {
                    reference_k: DEFAULT_REFERENCE_K,
                    damping: TemperatureDamping::Constant,
                }),
                r#"unlag fit ... --add temperature   (model file: effects = [{ kind = "temperature", reference_k = 293.15 }]; the estimation test's temperature)"#.into(),
            ),
            (
                Remedy::Add(Effect::Temperature {
                    reference_k: DEFAULT_REFERENCE_K,
                    damping: TemperatureDamping::Viscous,
                }),
                r#"unlag fit ... --add temperature-viscous   (model file: effects = [{ kind = "temperature", reference_k = 293.15, damping = "viscous" }]; the estimation test's temperature)"#.into(),
            ),
            (
                Remedy::AddKeepingDelay {
                    effect: Effect::Temperature {
                        reference_k: 300.0,
                        damping: TemperatureDamping::Viscous,
                    },
                    samples: 6,
                },
                r#"unlag fit ... --add temperature-viscous=300 --add delay=6   (model file: effects = [{ kind = "temperature", reference_k = 300, damping = "viscous" }, { kind = "delay", samples = 6 }]; the estimation test's temperature)"#.into(),
            ),
            (
                Remedy::AddBeside {
                    change: Box::new(Remedy::Add(Effect::Temperature {
                        reference_k: DEFAULT_REFERENCE_K,
                        damping: TemperatureDamping::Viscous,
                    })),
                    beside: Effect::Mode { near_hz: None },
                },
                r#"unlag fit ... --add temperature-viscous --add mode   (model file: effects = [{ kind = "temperature", reference_k = 293.15, damping = "viscous" }, { kind = "mode" }]; the estimation test's temperature)"#.into(),
            ),
            (
                Remedy::AddBeside {
                    change: Box::new(Remedy::AddKeepingDelay {
                        effect: Effect::Drift {
                            value: 0.0,
                            rate_per_s: 0.0,
                        },
                        samples: 20,
                    }),
                    beside: Effect::Mode { near_hz: None },
                },
                r#"unlag fit ... --add drift --add mode --add delay=20   (model file: effects = [{ kind = "drift" }, { kind = "mode" }, { kind = "delay", samples = 20 }])"#.into(),
            ),
            (
                Remedy::SetDelay { samples: 27 },
                r#"unlag fit ... --delay 27   (model file: effects = [{ kind = "delay", samples = 27 }])"#.into(),
            ),
            (
                Remedy::AddJointly {
                    effect: Effect::NonlinearDamping { gain: 0.0 },
                    also: vec!["wake.csv".into()],
                },
                r#"unlag fit ... --also wake.csv --add nonlinear-damping   (model file: effects = [{ kind = "nonlinear-damping" }])"#.into(),
            ),
            // A model whose order was given and which carries modes: the change names them
            // again before its own, whatever it is.
            (
                Remedy::KeepingModes {
                    change: Box::new(Remedy::Add(Effect::Mode {
                        near_hz: Some(433.0),
                    })),
                    modes: 1,
                },
                r#"unlag fit ... --add mode --add mode   (model file: effects = [{ kind = "mode", near_hz = 433 }]); the model's mode named again: a refit with an order given drops the modes a model carries"#.into(),
            ),
            (
                Remedy::KeepingModes {
                    change: Box::new(Remedy::SetDelay { samples: 27 }),
                    modes: 2,
                },
                r#"unlag fit ... --add mode --add mode --delay 27   (model file: effects = [{ kind = "delay", samples = 27 }]); the model's 2 modes named again: a refit with an order given drops the modes a model carries"#.into(),
            ),
            (
                Remedy::KeepingModes {
                    change: Box::new(Remedy::AddJointly {
                        effect: Effect::NonlinearDamping { gain: 0.0 },
                        also: vec!["wake.csv".into()],
                    }),
                    modes: 1,
                },
                r#"unlag fit ... --add mode --also wake.csv --add nonlinear-damping   (model file: effects = [{ kind = "nonlinear-damping" }]); the model's mode named again: a refit with an order given drops the modes a model carries"#.into(),
            ),
            (
                Remedy::RaiseOrder,
                "unlag fit ... --order auto   (or a higher --order N)".into(),
            ),
            (Remedy::Nothing, "none".into()),
        ];
        for (r, text) in cases {
            assert_eq!(r.command(), text, "{r:?}");
        }
    }
}
