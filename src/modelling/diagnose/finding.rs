//! What a diagnosis says: the [`Finding`] it names, each ranked [`Candidate`] with the numbers
//! behind it, and the test that tells two close candidates apart.

use serde::Serialize;

#[cfg(doc)]
use super::parameter_penalty;
use super::{Beside, Evidence, OrderRule, Remedy};
use crate::effects::{self, EffectKind};
use crate::fit::model::Uncertainty;

/// What a diagnosis names: a missing effect, nothing missing, or something missing that no
/// effect of the catalogue explains. Its text is the candidate's `kind` in `--json`: the
/// effect's name, exactly what `unlag fit --add` takes ([`EffectKind`]), or `none`, or
/// `unexplained` (verdicts, not effects: there is nothing to add for them, so they are no
/// [`EffectKind`]).
///
/// ```
/// use unlag::modelling::diagnose::Finding;
/// use unlag::effects::EffectKind;
///
/// assert_eq!(Finding::Missing(EffectKind::Leak).to_string(), "leak");
/// assert_eq!(Finding::Nothing.to_string(), "none");
/// assert_eq!("unexplained".parse(), Ok(Finding::Unexplained));
/// assert_eq!(Finding::Missing(EffectKind::Mode).effect(), Some(EffectKind::Mode));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Finding {
    /// This effect is missing: `unlag fit --add` it.
    Missing(EffectKind),
    /// `none`: the residual is what the noise leaves; nothing to add.
    Nothing,
    /// `unexplained`: the residual is above the noise floor and no effect's trial lowers it.
    Unexplained,
}

impl Finding {
    /// The effect to add, when one is named.
    #[must_use]
    pub const fn effect(self) -> Option<EffectKind> {
        match self {
            Self::Missing(k) => Some(k),
            Self::Nothing | Self::Unexplained => None,
        }
    }

    /// Its text: the effect's name, `none` or `unexplained`.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Missing(k) => k.as_str(),
            Self::Nothing => "none",
            Self::Unexplained => "unexplained",
        }
    }
}

impl core::fmt::Display for Finding {
    /// Its text ([`Finding::as_str`]), padded as the formatter asks.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.pad(self.as_str())
    }
}

impl core::str::FromStr for Finding {
    type Err = effects::UnknownKind;

    fn from_str(s: &str) -> core::result::Result<Self, Self::Err> {
        match s {
            "none" => Ok(Self::Nothing),
            "unexplained" => Ok(Self::Unexplained),
            _ => s.parse().map(Self::Missing),
        }
    }
}

impl Serialize for Finding {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> serde::Deserialize<'de> for Finding {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl PartialEq<EffectKind> for Finding {
    fn eq(&self, other: &EffectKind) -> bool {
        *self == Self::Missing(*other)
    }
}

/// One ranked candidate.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// What it names: an effect, exactly what `unlag fit --add` takes (`mode`, `leak`,
    /// `offset`, `drift`, `delay`, `coloured-noise`, `nonlinear-damping`, `sensor-resonance`,
    /// `temperature`, `temperature-viscous`, `temperature-diffusive`), or `none` or `unexplained`.
    pub kind: Finding,
    /// `ln(error before / error after)` of the trial, less [`parameter_penalty`] per
    /// parameter the effect adds; larger is stronger.
    pub score: f64,
    /// The numbers behind it, by its kind.
    pub evidence: Evidence,
    /// What it means physically.
    pub reading: String,
    /// The change that adds it (a front end words it as its own command).
    pub change: Remedy,
    /// Held-out error before the trial.
    pub nrmse_before: f64,
    /// Held-out error after the trial of its effect alone (what its change leaves, with a
    /// mode beside it, is [`Beside::nrmse_after`]); for a quadratic loss fitted on the tests together
    /// (which holds none out), the error before over the fall of the tests' RMS error that
    /// fit shows ([`Candidate::error_change`] says so).
    pub nrmse_after: f64,
    /// How far ahead of the next candidate it is (score difference; the last one's score;
    /// for a temperature and a quadratic loss both fitted on all the tests, the log of the
    /// ratio of what each leaves over them, the footing they are ordered on). Negative where a rule of the order put it ahead of one that scores more, or put the
    /// next one behind it ([`Candidate::ordered_by`] of the one or the other).
    pub margin: f64,
    /// When the next candidate is within [`CLOSE_MARGIN`], or ahead of it in score: the test
    /// that would tell the two apart.
    pub separated_by: Option<SeparatingTest>,
    /// The rule of the order that moved it from where its score put it, if one did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordered_by: Option<OrderRule>,
    /// The model's stated uncertainty before the trial (its fit report's), when it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty_before: Option<Uncertainty>,
    /// The trial refit's stated uncertainty, when it could say: with `coloured-noise` it is
    /// computed on the data its noise model whitens, so coloured noise is no longer counted
    /// as independent samples.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty_after: Option<Uncertainty>,
    /// A mode added beside its effect, in its change, where the model is short of its own
    /// estimation test as well and the mode's trial lowers the held-out error further.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub beside: Option<Beside>,
}

impl Candidate {
    /// A candidate as its trial leaves it: no margin, separating test, order rule, stated
    /// uncertainty or mode beside it yet (the order and the diagnosis set those).
    #[must_use]
    pub(crate) fn new(
        kind: Finding,
        score: f64,
        (evidence, reading): (Evidence, String),
        change: Remedy,
        (nrmse_before, nrmse_after): (f64, f64),
    ) -> Self {
        Self {
            kind,
            score,
            evidence,
            reading,
            change,
            nrmse_before,
            nrmse_after,
            margin: 0.0,
            separated_by: None,
            ordered_by: None,
            uncertainty_before: None,
            uncertainty_after: None,
            beside: None,
        }
    }

    /// How the error changes in its trial, in words: `held-out error 1.000 % -> 0.500 %`, or
    /// for the tests fitted together, their RMS error with one linear model and with the loss.
    #[must_use]
    pub fn error_change(&self) -> String {
        let pct = |v: f64| format!("{:.3} %", 100.0 * v);
        match &self.evidence {
            Evidence::NonlinearDamping(super::NonlinearDamping { joint: Some(j), .. }) => format!(
                "the tests fitted together {} -> {} (RMS; none held out)",
                pct(effects::rms(&j.linear_nrmse)),
                pct(j.rms())
            ),
            _ => format!(
                "held-out error {} -> {}{}",
                pct(self.nrmse_before),
                pct(self.nrmse_after),
                self.beside.as_ref().map_or(String::new(), |b| format!(
                    "; with a {} beside it {}",
                    b.kind,
                    pct(b.nrmse_after)
                ))
            ),
        }
    }

    /// The stated uncertainty before and after the trial in one sentence, when both are
    /// known; with a noise model added, which figure to quote.
    #[must_use]
    pub fn uncertainty_text(&self) -> Option<String> {
        let (b, a) = (
            self.uncertainty_before.as_ref()?,
            self.uncertainty_after.as_ref()?,
        );
        let quote = if !b.noise_model && a.noise_model {
            " (both count the noise's colour; the whitened one is the model's own, the one to \
             quote)"
        } else {
            ""
        };
        Some(format!(
            "stated uncertainty (1 sigma): before, from {}: {}; after, from {}: {}{quote}",
            b.noise_text(),
            b.summary(),
            a.noise_text(),
            a.summary()
        ))
    }
}

/// Two candidates closer than this in score are close: the diagnosis names the test that
/// would separate them.
pub const CLOSE_MARGIN: f64 = 0.3;

/// What to record to tell two close candidates apart ([`SeparatingTest`]). Its JSON name is
/// kebab-case: `longer-record`, `steady-record`, `another-temperature`, `steps-of-other-sizes`,
/// `reference-alone`, `another-step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TestToRecord {
    /// A longer record after the step.
    LongerRecord,
    /// A record with no step, the pressure steady.
    SteadyRecord,
    /// A test at another gas temperature, or at the estimation test's.
    AnotherTemperature,
    /// Steps of other sizes at the estimation test's temperature.
    StepsOfOtherSizes,
    /// The reference transducer alone on a step.
    ReferenceAlone,
    /// Another step test, of another size and direction, held out.
    AnotherStep,
}

impl TestToRecord {
    /// What to record, in words.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::LongerRecord => "a longer record after the step",
            Self::SteadyRecord => "a record with no step, the pressure steady",
            Self::AnotherTemperature => {
                "a test at another gas temperature, or the same temperature as the estimation test"
            }
            Self::StepsOfOtherSizes => "steps of other sizes at the estimation test's temperature",
            Self::ReferenceAlone => "the reference transducer alone on a step",
            Self::AnotherStep => "another step test of another size and direction, held out",
        }
    }
}

/// The test that would tell two close candidates apart: what to record, and what each one's
/// signature does in it. In `--json`, `{"test": "longer-record", "text": "a longer record
/// after the step (...)"}`; its text is its [`Display`](core::fmt::Display).
///
/// ```
/// use unlag::modelling::diagnose::{separating_test, Finding, TestToRecord};
/// use unlag::effects::EffectKind;
///
/// let t = separating_test(
///     Finding::Missing(EffectKind::Temperature),
///     Finding::Missing(EffectKind::NonlinearDamping),
/// );
/// assert_eq!(t.test, TestToRecord::StepsOfOtherSizes);
/// assert!(t.to_string().starts_with("steps of other sizes"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeparatingTest {
    /// What to record.
    pub test: TestToRecord,
    /// What each candidate's signature does in it.
    pub why: &'static str,
}

impl core::fmt::Display for SeparatingTest {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{} ({})", self.test.as_str(), self.why)
    }
}

impl Serialize for SeparatingTest {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("SeparatingTest", 2)?;
        st.serialize_field("test", &self.test)?;
        st.serialize_field("text", &self.to_string())?;
        st.end()
    }
}

/// The test that tells what `a` names from what `b` names, by what each one's signature
/// depends on.
#[must_use]
pub fn separating_test(a: Finding, b: Finding) -> SeparatingTest {
    use EffectKind::{ColouredNoise, Drift, Leak, Mode, NonlinearDamping, Offset, SensorResonance};
    use TestToRecord::{
        AnotherStep, AnotherTemperature, LongerRecord, ReferenceAlone, SteadyRecord,
        StepsOfOtherSizes,
    };
    let pair = |x: EffectKind, y: EffectKind| (a == x && b == y) || (a == y && b == x);
    let temperature = |k: Finding| {
        k.effect()
            .is_some_and(|k| k.family() == EffectKind::Temperature)
    };
    let (test, why) = if pair(Leak, Mode) {
        (
            LongerRecord,
            "a leak settles below the step, its DC gain under 1; a mode rings out at its \
             frequency and settles at the step",
        )
    } else if pair(Drift, Offset) || pair(Leak, Drift) {
        (
            LongerRecord,
            "a drift keeps growing, an offset stays, a leak settles",
        )
    } else if pair(ColouredNoise, Drift) || pair(ColouredNoise, Offset) {
        (
            SteadyRecord,
            "the noise alone: it wanders both ways, a drift one way",
        )
    } else if (temperature(a) && b == NonlinearDamping) || (temperature(b) && a == NonlinearDamping)
    {
        (
            StepsOfOtherSizes,
            "a quadratic loss damps a larger step more; a temperature moves every natural \
             frequency by one factor whatever the step",
        )
    } else if temperature(a) || temperature(b) {
        (
            AnotherTemperature,
            "a temperature moves every natural frequency by one factor",
        )
    } else if a == NonlinearDamping || b == NonlinearDamping {
        (
            StepsOfOtherSizes,
            "amplitude-dependent losses change with the step, a linear effect does not",
        )
    } else if pair(Mode, SensorResonance) {
        (
            ReferenceAlone,
            "a diaphragm rings in it, a line mode does not",
        )
    } else {
        (
            AnotherStep,
            "each effect's trial judged on a test it was not fitted on",
        )
    };
    SeparatingTest { test, why }
}
