//! What can go wrong in predicting a probe from its geometry: a transform of an unusable
//! length, a response that is not finite or does not decay, a line without the dynamics or
//! modes asked for. In the physics room's own words; reached as [`crate::Error::Stage`].

/// What can go wrong in the physics room: one variant per problem, each saying the step it
/// happened in.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PhysicsError {
    /// An FFT was asked of a length that is not a power of two.
    #[error("FFT: length {length} is not a power of two")]
    FftLength {
        /// The length given.
        length: usize,
    },
    /// A convolution's transform length would overflow.
    #[error("convolution: length {length} is too large")]
    ConvolutionLength {
        /// The length the convolution needs.
        length: usize,
    },
    /// The frequency response is not finite on the impulse response's grid.
    #[error("impulse response: the response is not finite at {frequency_hz} Hz")]
    ResponseNotFinite {
        /// The first frequency where it is not.
        frequency_hz: f64,
    },
    /// The impulse response does not decay within the longest transform.
    #[error("impulse response: the response does not decay within {seconds:.3} s at {rate_hz} Hz (an undamped mode?)")]
    NoDecay {
        /// The longest response looked at, in seconds.
        seconds: f64,
        /// The sample rate.
        rate_hz: f64,
    },
    /// The line has no second-order dynamics (no inertance or no compliance).
    #[error(
        "lumped approximation: the line has no second-order dynamics (no tube, or no compliance)"
    )]
    NoSecondOrder,
    /// The lumped approximation's iteration did not run.
    #[error("lumped approximation: no iteration ran")]
    NoIteration,
    /// The mode finder found no pole of the line's response.
    #[error("mode finder: no pole of the line response was found")]
    NoMode,
    /// The prediction compared with a model has no mode.
    #[error("comparison: the prediction has no mode")]
    NoPredictedMode,
    /// A probe was described with neither a tube nor a hole.
    #[error("the probe needs at least one tube (or a hole)")]
    NoTube,
    /// More or fewer exact modes were asked for than the prediction reports.
    #[error("prediction: {count} exact modes asked for, not 1..={max}", max = super::compare::MAX_MODES)]
    ModeCount {
        /// The number asked for.
        count: usize,
    },
    /// An anti-alias filter of an order outside its range.
    #[error("anti-alias filter: order {order} is not 1..={max}", max = super::Butterworth::MAX_ORDER)]
    FilterOrder {
        /// The order given.
        order: u32,
    },
    /// The fitted model compared with a prediction has no mode.
    #[error("comparison: the fitted model has no mode (no complex pole pair, fewer than two real poles)")]
    NoFittedMode,
}

impl crate::error::StageError for PhysicsError {
    fn kind(&self) -> &'static str {
        match self {
            // The request is wrong, not the arithmetic.
            Self::NoTube | Self::ModeCount { .. } | Self::FilterOrder { .. } => "invalid-argument",
            _ => "numerical",
        }
    }
}
crate::error::stage_error!(PhysicsError);
