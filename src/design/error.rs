//! What can go wrong in designing a compensator: the model cannot be inverted, no corner or
//! smoother gives a usable one, its poles are too near the unit circle for the board, or it
//! cannot be realised in the board's fixed point. In the design room's own words (no
//! command-line flags: the CLI adds them); reached as [`crate::Error::Stage`].

use crate::board::compensator::{InverseError, MIN_POLE_MARGIN};
use crate::board::fixed::direct::DirectError;
use crate::board::fixed::FixedError;

/// What can go wrong in designing or realising a compensator: one variant per problem, each
/// saying the step it happened in.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DesignError {
    /// The model's numerator is zero: there is nothing to invert.
    #[error("{context}: the model's numerator b is zero")]
    ZeroNumerator {
        /// The design that needed it ("inverse", "optimal compensator").
        context: &'static str,
    },
    /// `B(1) = 0`: the model does not pass a steady pressure.
    #[error("inverse: B(1) = 0: the model does not pass a steady pressure, it cannot be inverted")]
    NoSteadyGain,
    /// No low-pass corner of the search grid gave a compensator with a noise gain of at most
    /// 10 (the CLI names the flag that gives a bandwidth).
    #[error("inverse: no low-pass corner gave a usable compensator (noise gain above 10 everywhere); give a bandwidth")]
    NoUsableBandwidth,
    /// The compensator's poles are too close to the unit circle for the board.
    #[error("inverse: the compensator's poles are {margin:.2e} from the unit circle, less than the required margin {MIN_POLE_MARGIN:.0e}: refusing to export it")]
    PoleMargin {
        /// `1 -` the largest pole radius.
        margin: f64,
    },
    /// The design's sections do not validate as the board's cascade.
    #[error("compensator: {error}")]
    Cascade {
        /// The board's reason.
        error: InverseError,
    },
    /// The nonlinear-damping correction's coefficients do not validate on the board.
    #[error("nonlinear-damping correction: {error}")]
    NonlinearCorrection {
        /// The board's reason.
        error: InverseError,
    },
    /// The model's DC gain is zero or not finite, so not even the delay-only design exists.
    #[error("delay-only compensator: the model's DC gain is {dc_gain}")]
    DcGain {
        /// The model's DC gain.
        dc_gain: f64,
    },
    /// The optimal compensator's signal prior or probe noise is not positive and finite.
    #[error("optimal compensator: the signal prior ({prior_std:.3e}) and the probe noise ({probe_std:.3e}) must be positive and finite")]
    NoiseLevels {
        /// The prior's increment standard deviation.
        prior_std: f64,
        /// The probe noise's standard deviation.
        probe_std: f64,
    },
    /// The Kalman filter's Riccati equation did not converge.
    #[error("optimal compensator: the Kalman filter's Riccati equation did not converge (is the model stable and its DC gain non-zero?)")]
    RiccatiNotConverged,
    /// The eigenvalues of the Kalman filter did not converge.
    #[error("optimal compensator: eigenvalues of the Kalman filter did not converge: {error:?}")]
    KalmanEigenvalues {
        /// faer's reason.
        error: faer::linalg::evd::EvdError,
    },
    /// The smoother's sections do not reproduce its rational response.
    #[error("optimal compensator: the sections do not reproduce the smoother at lag {lag} (|error| {error:.2e} at {frequency:.3} rad/sample): ask for a shorter latency")]
    SmootherSections {
        /// The smoother's lag in samples.
        lag: usize,
        /// The worst difference found.
        error: f64,
        /// Where, in rad/sample.
        frequency: f64,
    },
    /// The smoother's poles are too close to the unit circle for the board.
    #[error("optimal compensator: the smoother's poles are {margin:.2e} from the unit circle, less than the board's margin {MIN_POLE_MARGIN:.0e}")]
    SmootherPoleMargin {
        /// `1 -` the largest pole radius.
        margin: f64,
    },
    /// A record is too long for a power-of-two transform.
    #[error("offline reconstruction: a record of {samples} samples is too long")]
    RecordTooLong {
        /// Samples in the record.
        samples: usize,
    },
    /// A fixed-point plan was asked of a design without sections.
    #[error("fixed point: the design has no sections")]
    NoSections,
    /// A section pole is not inside the unit circle, so its fixed-point bounds do not exist.
    #[error("fixed point: a section pole has radius {radius}")]
    SectionPoleRadius {
        /// The largest section pole radius.
        radius: f64,
    },
    /// A normal-form coefficient does not fit the board's integer at its fractional bits.
    #[error("fixed point: {what} = {value:e} does not fit 2^30 at {bits} fractional bits")]
    CoefficientRange {
        /// Which coefficient.
        what: &'static str,
        /// Its value.
        value: f64,
        /// Its fractional bits.
        bits: u32,
    },
    /// A direct-form coefficient does not fit Q2.30.
    #[error("fixed point: {what} = {value:e} does not fit Q2.30 (direct form)")]
    DirectCoefficientRange {
        /// Which coefficient.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// An output coefficient is NaN or infinite.
    #[error("fixed point: an output coefficient is not finite")]
    OutputCoefficientNotFinite,
    /// An output coefficient is too large for the board's integer part.
    #[error("fixed point: an output coefficient of {max:e} needs more than 29 integer bits")]
    OutputCoefficientRange {
        /// The largest output coefficient's magnitude.
        max: f64,
    },
    /// A section's L1 bound is not finite.
    #[error("fixed point: section {section}: the L1 bound is not finite")]
    L1Bound {
        /// 0-based section.
        section: usize,
    },
    /// A direct-form section's L1 bound is not finite and positive.
    #[error("fixed point: section {section}: the L1 bound is not finite and positive")]
    DirectL1Bound {
        /// 0-based section.
        section: usize,
    },
    /// The whole cascade's L1 gain needs an output scale beyond `2^60`.
    #[error("fixed point: L1 gain {gain:e} out of range")]
    L1Gain {
        /// The cascade's L1 gain.
        gain: f64,
    },
    /// A direct-form section's scaled numerator does not fit Q2.30.
    #[error("fixed point: section {section}: a scaled numerator coefficient does not fit Q2.30")]
    ScaledNumeratorRange {
        /// 0-based section.
        section: usize,
    },
    /// A direct-form section's rounded numerator overflows `i32`.
    #[error("fixed point: section {section}: a numerator coefficient overflows")]
    NumeratorOverflow {
        /// 0-based section.
        section: usize,
    },
    /// A direct-form section's output bound leaves no headroom.
    #[error("fixed point: section {section}: output bound {bound} leaves no headroom")]
    NoHeadroom {
        /// 0-based section.
        section: usize,
        /// Its output bound, noise included, in units of the `i32` range.
        bound: f64,
    },
    /// The board refuses the normal-form plan's integers.
    #[error("fixed point: {error}")]
    FixedBoard {
        /// The board's reason.
        error: FixedError,
    },
    /// The board refuses the direct-form plan's integers.
    #[error("fixed point: {error}")]
    DirectBoard {
        /// The board's reason.
        error: DirectError,
    },
}

impl crate::error::StageError for DesignError {}
crate::error::stage_error!(DesignError);
