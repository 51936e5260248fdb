//! How a compensator was designed: the method, typed, and the words that name it.
//!
//! This module owns [`MethodKind`] (which design it is, for the code that redesigns, judges or
//! describes one) and [`DesignMethod`] (the kind, whether the sensor-resonance prefilter runs
//! first, and the words the CLI prints and the model file stores as the design's `method`).
//! The words are `[PREFILTER, then ]NAME[: DETAIL]`, for example
//! `optimal: fixed-lag Kalman smoother, lag 12 samples (...)`; a model file's `method` is read
//! back into its kind by the name it starts with (after the prefilter's words), so the files
//! of every earlier version load as they were written.

use serde::{Deserialize, Serialize};

/// Which design a compensator is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MethodKind {
    /// The stable inverse: zeros of `B` outside the unit circle reflected, near it pulled in,
    /// times a low-pass ([`super::design`] with `stabilise`).
    StableInverse,
    /// The paper's direct inverse `A/B` times a low-pass ([`super::design`] without
    /// `stabilise`).
    DirectInverse,
    /// The noise-aware optimum: the fixed-lag Kalman smoother ([`super::optimal::design`]).
    Smoother,
    /// The optimum's reduced order: a stable inverse times a low-pass at the corner of least
    /// predicted error, chosen when it comes close to the smoother with fewer sections.
    ReducedOptimal,
    /// The probe signal over the model's DC gain ([`super::check::delay_only`]).
    DelayOnly,
    /// The probe signal unchanged.
    PassThrough,
}

impl MethodKind {
    /// Every kind.
    pub const ALL: [Self; 6] = [
        Self::StableInverse,
        Self::DirectInverse,
        Self::Smoother,
        Self::ReducedOptimal,
        Self::DelayOnly,
        Self::PassThrough,
    ];

    /// Its name: the words before the details (`optimal`, `delay only`), or the whole words
    /// of a method that has no details (the two inverses).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::StableInverse => {
                "stable inverse (zeros of B outside the unit circle reflected, near it pulled in) \
                 times low-pass"
            }
            Self::DirectInverse => "the paper's direct inverse A/B times low-pass",
            Self::Smoother => "optimal",
            Self::ReducedOptimal => "optimal, reduced order",
            Self::DelayOnly => "delay only",
            Self::PassThrough => "pass-through",
        }
    }

    /// The details that always follow its name, when they are fixed.
    const fn fixed_detail(self) -> &'static str {
        match self {
            Self::DelayOnly => "the probe signal over the model's DC gain",
            Self::PassThrough => "the probe signal unchanged",
            Self::StableInverse | Self::DirectInverse | Self::Smoother | Self::ReducedOptimal => "",
        }
    }

    /// Whether it is one of the noise-aware optimum's designs (the smoother or its reduced
    /// order), which a redesign makes anew from the design's noise and prior.
    #[must_use]
    pub const fn is_optimal(self) -> bool {
        matches!(self, Self::Smoother | Self::ReducedOptimal)
    }
}

/// Words that name no design method: what reading a `method` fails with.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown compensator method '{0}'")]
pub struct UnknownMethod(pub String);

/// How a compensator was built: its [`MethodKind`], whether the sensor-resonance prefilter
/// runs before it, and its words (see the module docs), which are what `Display` and serde
/// give.
///
/// ```
/// use unlag::design::inverse::{DesignMethod, MethodKind};
///
/// let m = DesignMethod::new(MethodKind::Smoother, "fixed-lag Kalman smoother, lag 4 samples")
///     .after_prefilter("sensor-resonance prefilter (Butterworth order 4 at 900.0 Hz)");
/// assert_eq!(m.kind(), MethodKind::Smoother);
/// assert!(m.is_prefiltered());
/// assert_eq!(
///     m.to_string(),
///     "sensor-resonance prefilter (Butterworth order 4 at 900.0 Hz), then optimal: \
///      fixed-lag Kalman smoother, lag 4 samples"
/// );
/// assert_eq!(
///     m.short(),
///     "sensor-resonance prefilter (Butterworth order 4 at 900.0 Hz), then optimal"
/// );
/// assert_eq!(m.to_string().parse::<DesignMethod>(), Ok(m));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DesignMethod {
    kind: MethodKind,
    /// Bytes of the words before the method's own (the prefilter's and `, then `).
    lead: usize,
    text: String,
}

/// What joins the prefilter's words to the method's.
const THEN: &str = ", then ";

/// How the prefilter's words start.
const PREFILTER: &str = "sensor-resonance prefilter";

impl DesignMethod {
    /// The method of `kind` with `detail` after its name (`NAME: DETAIL`; the name alone when
    /// `detail` is empty).
    #[must_use]
    pub fn new(kind: MethodKind, detail: &str) -> Self {
        let text = if detail.is_empty() {
            kind.name().to_string()
        } else {
            format!("{}: {detail}", kind.name())
        };
        Self {
            kind,
            lead: 0,
            text,
        }
    }

    /// The method of `kind` in its usual words: the name, with the fixed details of
    /// `delay only` and `pass-through`.
    #[must_use]
    pub fn of(kind: MethodKind) -> Self {
        Self::new(kind, kind.fixed_detail())
    }

    /// The same method with the sensor-resonance prefilter run first, `prefilter` its words
    /// (`sensor-resonance prefilter (Butterworth order 4 at 900.0 Hz)`): `PREFILTER, then
    /// METHOD`.
    #[must_use]
    pub fn after_prefilter(self, prefilter: &str) -> Self {
        Self {
            kind: self.kind,
            lead: prefilter.len() + THEN.len() + self.lead,
            text: format!("{prefilter}{THEN}{}", self.text),
        }
    }

    /// Which design it is.
    #[must_use]
    pub const fn kind(&self) -> MethodKind {
        self.kind
    }

    /// Whether the sensor-resonance prefilter runs before it.
    #[must_use]
    pub const fn is_prefiltered(&self) -> bool {
        self.lead > 0
    }

    /// Its words.
    #[must_use]
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// Its words without the method's details (the prefilter's kept): what a fall-back names.
    #[must_use]
    pub fn short(&self) -> &str {
        self.text
            .get(..self.lead + self.kind.name().len())
            .unwrap_or(&self.text)
    }
}

impl core::fmt::Display for DesignMethod {
    /// Its words, padded as the formatter asks.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.pad(&self.text)
    }
}

impl core::str::FromStr for DesignMethod {
    type Err = UnknownMethod;

    /// Reads words written by [`DesignMethod`]'s `Display` (of this or an earlier version):
    /// the kind is the one whose name they start with, after the prefilter's words.
    fn from_str(s: &str) -> core::result::Result<Self, Self::Err> {
        let lead = if s.starts_with(PREFILTER) {
            s.find(THEN).map_or(0, |i| i + THEN.len())
        } else {
            0
        };
        let own = s.get(lead..).unwrap_or("");
        let kind = MethodKind::ALL
            .into_iter()
            .find(|k| {
                own.strip_prefix(k.name())
                    .is_some_and(|rest| rest.is_empty() || rest.starts_with(": "))
            })
            .ok_or_else(|| UnknownMethod(s.to_string()))?;
        Ok(Self {
            kind,
            lead,
            text: s.to_string(),
        })
    }
}

impl Serialize for DesignMethod {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.serialize_str(&self.text)
    }
}

impl<'de> Deserialize<'de> for DesignMethod {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The words every version has written, and what the code before the typed method read
    /// from them.
    #[test]
    fn the_words_of_every_version_read_back_and_short_is_the_text_before_the_colon() {
        let prefilter = "sensor-resonance prefilter (Butterworth order 4 at 1234.5 Hz)";
        let written = [
            (
                "stable inverse (zeros of B outside the unit circle reflected, near it pulled \
                 in) times low-pass",
                MethodKind::StableInverse,
            ),
            (
                "the paper's direct inverse A/B times low-pass",
                MethodKind::DirectInverse,
            ),
            (
                "optimal: fixed-lag Kalman smoother, lag 7 samples (steps-and-ramps prior, \
                 measured probe noise with its AR(1) part)",
                MethodKind::Smoother,
            ),
            (
                "optimal, reduced order: a stable inverse times a Bessel low-pass at the corner \
                 of least predicted error, within 5 % of the fixed-lag Kalman smoother (2 \
                 sections against 6, predicted 0.0100 against 0.0098)",
                MethodKind::ReducedOptimal,
            ),
            (
                "optimal, reduced order: a stable inverse times a Bessel low-pass at the corner \
                 of least predicted error, 1.02x the fixed-lag Kalman smoother's error (2 \
                 sections against 6, predicted 0.0100 against 0.0098)",
                MethodKind::ReducedOptimal,
            ),
            (
                "delay only: the probe signal over the model's DC gain",
                MethodKind::DelayOnly,
            ),
            (
                "pass-through: the probe signal unchanged",
                MethodKind::PassThrough,
            ),
        ];
        for (text, kind) in written {
            for text in [text.to_string(), format!("{prefilter}, then {text}")] {
                let m: DesignMethod = text.parse().unwrap();
                assert_eq!(m.kind(), kind, "{text}");
                assert_eq!(m.is_prefiltered(), text.starts_with(prefilter));
                assert_eq!(m.to_string(), text);
                assert_eq!(m.short(), text.split(':').next().unwrap_or(""), "{text}");
                // What the code asked of the words before.
                assert_eq!(
                    m.kind() != MethodKind::DirectInverse,
                    !text.contains("direct inverse")
                );
                assert_eq!(
                    !m.is_prefiltered() && m.kind().is_optimal(),
                    text.starts_with("optimal")
                );
                assert_eq!(
                    !m.is_prefiltered() && m.kind() == MethodKind::Smoother,
                    text.starts_with("optimal: fixed-lag")
                );
                let json = serde_json::to_string(&m).unwrap();
                assert_eq!(json, serde_json::to_string(&text).unwrap());
                assert_eq!(serde_json::from_str::<DesignMethod>(&json).unwrap(), m);
            }
        }
        // The words of every constructor are the words of before.
        for kind in MethodKind::ALL {
            let text = written
                .iter()
                .find(|(_, k)| *k == kind)
                .map_or("", |(t, _)| *t);
            if matches!(kind, MethodKind::Smoother | MethodKind::ReducedOptimal) {
                let detail = text.split_once(": ").map_or("", |(_, d)| d);
                assert_eq!(DesignMethod::new(kind, detail).as_str(), text);
            } else {
                assert_eq!(DesignMethod::of(kind).as_str(), text);
            }
            assert_eq!(
                DesignMethod::of(kind)
                    .after_prefilter(prefilter)
                    .to_string(),
                format!("{prefilter}, then {}", DesignMethod::of(kind))
            );
        }
        assert!("a crystal ball".parse::<DesignMethod>().is_err());
        assert!("optimalish: no".parse::<DesignMethod>().is_err());
        assert!(toml::Value::String("a crystal ball".into())
            .try_into::<DesignMethod>()
            .is_err());
    }
}
