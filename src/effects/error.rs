//! What can go wrong in the effects' fits and their scalings, in their own words (no
//! command-line flags).

/// What the effects own of the host's errors: a numerical step of an effect's fit or
/// scaling that failed, and an effect that cannot be resolved from the tests without a value.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EffectError {
    /// A fit was asked for without an estimation test.
    #[error("fit: no estimation test")]
    NoEstimationTest,
    /// The effects' fit loop ended without a fitted model.
    #[error("fit: no fit")]
    NoFit,
    /// Scaling the damping to another temperature put two poles together, so the model has
    /// no modal form to scale.
    #[error("temperature scaling: the damping scaled by {damping_factor} puts two poles together: no modal form")]
    CoincidentPoles {
        /// The factor the damping was scaled by.
        damping_factor: f64,
    },
    /// A sensor resonance without a frequency, and an estimation test whose reference shows
    /// no resonance to find it in.
    #[error(
        "invalid sensor-resonance: the estimation test's reference shows no resonance to \
         filter below; give the transducer's natural frequency: the effect sensor-resonance=HZ"
    )]
    NoSensorResonance,
}

impl EffectError {
    /// The kind of problem, one stable kebab-case word per variant (as
    /// [`crate::error::Error::kind`]): `numerical`, or `invalid-argument` for a value that
    /// must be given.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::NoEstimationTest | Self::NoFit | Self::CoincidentPoles { .. } => "numerical",
            Self::NoSensorResonance => "invalid-argument",
        }
    }
}

impl crate::error::StageError for EffectError {
    fn kind(&self) -> &'static str {
        EffectError::kind(self)
    }
}
crate::error::stage_error!(EffectError);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    #[test]
    fn the_text_and_kind_are_those_of_before() {
        let e: Error = EffectError::NoEstimationTest.into();
        assert_eq!(e.to_string(), "fit: no estimation test");
        assert_eq!(e.kind(), "numerical");
        assert_eq!(e.location(), (None, None, None));
        let e: Error = EffectError::NoSensorResonance.into();
        assert_eq!(e.kind(), "invalid-argument");
        assert_eq!(
            e.to_string(),
            "invalid sensor-resonance: the estimation test's reference shows no resonance to \
             filter below; give the transducer's natural frequency: the effect \
             sensor-resonance=HZ"
        );
    }
}
