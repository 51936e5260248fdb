//! What can go wrong in fitting a model: the data do not determine it, no delay or order gives
//! a usable one, its compensator does not validate, or it has no continuous-time equivalent.
//! In the fit room's own words (no command-line flags); reached as [`crate::Error::Stage`].

use crate::board::compensator::InverseError;
use crate::fit::continuous::REPEATED_POLE_TOLERANCE;
use crate::poly::{format_root, Complex};

/// What can go wrong in fitting: one variant per problem, each saying the step it happened in.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// A least-squares problem has fewer equations than unknowns.
    #[error("{context}: {equations} equations for {unknowns} unknowns: the data are too short")]
    TooFewEquations {
        /// The fit that set it up ("arx", "output error").
        context: String,
        /// Equations (rows).
        equations: usize,
        /// Unknowns (columns).
        unknowns: usize,
    },
    /// The regression matrix is rank deficient: the data do not determine the parameters.
    #[error("{context}: the regression is rank deficient: the data do not excite the model (is there a step?)")]
    RankDeficient {
        /// The fit that set it up.
        context: String,
    },
    /// The least-squares solution has a NaN or infinite parameter.
    #[error("{context}: least squares gave a non-finite solution")]
    NonFiniteSolution {
        /// The fit that set it up.
        context: String,
    },
    /// No candidate delay gave a finite loss.
    #[error("delay search: no candidate delay gave a usable fit")]
    NoUsableDelay,
    /// No candidate order gave a stable model with a finite criterion.
    #[error("{test}: no order gave a usable model")]
    NoUsableOrder {
        /// The estimation test's name.
        test: String,
    },
    /// No usable order met the selection rule.
    #[error("{test}: order selection failed")]
    OrderSelectionFailed {
        /// The estimation test's name.
        test: String,
    },
    /// The model's inverse does not validate as the board's compensator.
    #[error("compensate: {error}")]
    Compensator {
        /// The board's reason.
        error: InverseError,
    },
    /// The model has no continuous-time equivalent, or it cannot be re-discretised.
    #[error("continuous-time equivalent: {0}")]
    Continuous(#[from] ContinuousError),
}

/// Why a model has no (step-invariant) continuous-time equivalent, or why it cannot be
/// re-discretised ([`crate::fit::continuous`]); the message without the step's name.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ContinuousError {
    /// The numerator is all zeros.
    #[error("b is all zeros: the model's output is always zero")]
    ZeroNumerator,
    /// More numerator coefficients after the delay than the denominator allows: poles at
    /// `z = 0`.
    #[error("b has {numerator} coefficients after the delay but a only {denominator}: the model has poles at z = 0 (a finite-impulse-response part), which have no continuous-time equivalent")]
    FiniteImpulsePart {
        /// Numerator coefficients after the delay.
        numerator: usize,
        /// Denominator coefficients (without the leading 1).
        denominator: usize,
    },
    /// A pole is at the origin.
    #[error("pole {} is at z = 0 (a finite-impulse-response part): it has no continuous-time equivalent", format_root(*.pole))]
    PoleAtOrigin {
        /// The pole.
        pole: Complex,
    },
    /// A pole is on or outside the unit circle.
    #[error("pole {} has |z| = {radius:.6} >= 1: an unstable model has no step-invariant continuous-time equivalent", format_root(*.pole))]
    UnstablePole {
        /// The pole.
        pole: Complex,
        /// Its magnitude.
        radius: f64,
    },
    /// A pole is on the negative real axis (`s = fs ln p` is not real).
    #[error("pole {} is on the negative real axis: it oscillates at Nyquist and has no continuous-time equivalent (s = fs ln p is not real)", format_root(*.pole))]
    NegativeRealPole {
        /// The pole.
        pole: Complex,
    },
    /// Two poles are repeated (closer than [`REPEATED_POLE_TOLERANCE`]).
    #[error("poles {} and {} are repeated (closer than {:e}): the modal expansion does not exist; refit with a different order", format_root(*.first), format_root(*.second), REPEATED_POLE_TOLERANCE)]
    RepeatedPoles {
        /// One pole.
        first: Complex,
        /// The other.
        second: Complex,
    },
    /// The modal expansion does not reproduce the model's step response.
    #[error("the modal expansion misses the step response by {relative:.3e} of its size (poles nearly repeated?)")]
    ExpansionMismatch {
        /// Largest miss relative to the step response's size.
        relative: f64,
    },
    /// The re-discretised coefficients came out complex (round-off on ill-conditioned poles).
    #[error("re-discretised coefficients are not real (imaginary part {imaginary:e} of {scale:e}): the poles are too ill-conditioned at {rate_hz} Hz")]
    ComplexCoefficients {
        /// Largest imaginary part.
        imaginary: f64,
        /// Largest coefficient magnitude.
        scale: f64,
        /// The new sample rate.
        rate_hz: f64,
    },
}

impl crate::error::StageError for FitError {}
crate::error::stage_error!(FitError);
