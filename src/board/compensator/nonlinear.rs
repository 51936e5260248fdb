//! The board's nonlinear-damping correction: `gain * lowpass(|dy| dy)` added to the linear
//! compensator's output for the same sample.

use super::{CascadeCoefficients, CascadeState, InverseError, Sample};

/// The board's share of the `nonlinear-damping` effect (see `unlag::effects` (host)): the
/// correction `gain * lowpass(|dy| dy)`, `dy = y[k] - y[k-1]`, to add to the linear
/// compensator's output ([`CascadeCoefficients`]) for the same sample.
///
/// A probe with quadratic losses obeys `A y = B (q^-d u - g N)` with
/// `N = fs^2 |dy| dy`; its inverse is the linear one plus `g N`, both reconstructing `u[k-d]`,
/// so the correction needs no delay of its own. It passes through the design's own low-pass,
/// so that it is band-limited like the linear part. `gain` here is `g fs^2` (the correction
/// per squared sample difference); the low-pass is `N` sections, like the cascade. Per sample:
/// one subtraction, two multiplies and the low-pass (5 multiplies per section, the gain folded
/// into the first).
///
/// ```
/// use unlag::board::compensator::NonlinearDampingCoefficients;
///
/// // g fs^2 = 0.3 through the one-section low-pass 0.5 / (1 - 0.5 z^-1).
/// let c = NonlinearDampingCoefficients::<f32, 1>::new(0.3, 0.5, &[[1.0, 0.0, 0.0, -0.5, 0.0]])?;
/// let mut state = c.equilibrium(0.0);
/// // A steady probe needs no correction; a rise of 1 gives 0.3 * 0.5 * |1| * 1, then the
/// // low-pass lets it decay by half per sample; a fall of 2 gives a negative term.
/// let terms = [0.0f32, 1.0, 1.0, 1.0, -1.0].map(|y| c.process(&mut state, y));
/// let expected = [0.0f32, 0.15, 0.075, 0.0375, 0.5 * 0.0375 - 0.15 * 4.0];
/// for (t, e) in terms.iter().zip(expected) {
///     assert!((t - e).abs() < 1e-6, "{terms:?}");
/// }
/// # Ok::<(), unlag::board::compensator::InverseError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearDampingCoefficients<T, const N: usize> {
    lowpass: CascadeCoefficients<T, N>,
}

/// The state of one channel's nonlinear correction: the previous probe sample and the
/// low-pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearDampingState<T, const N: usize> {
    previous: T,
    lowpass: CascadeState<T, N>,
}

impl<T: Sample, const N: usize> NonlinearDampingCoefficients<T, N> {
    /// Builds the correction from `gain` (per squared sample difference of the probe signal)
    /// and the low-pass `lowpass_gain`, `lowpass` sections `[b0, b1, b2, a1, a2]`, designed in
    /// `f64`.
    ///
    /// # Errors
    /// As [`CascadeCoefficients::new`] ([`InverseError::NonFinite`] for a gain that is not
    /// finite).
    pub fn new(gain: f64, lowpass_gain: f64, lowpass: &[[f64; 5]]) -> Result<Self, InverseError> {
        if !gain.is_finite() {
            return Err(InverseError::NonFinite);
        }
        Ok(Self {
            lowpass: CascadeCoefficients::new(gain * lowpass_gain, lowpass)?,
        })
    }

    /// The correction for the probe sample `y`. Panic-free and allocation-free.
    #[inline]
    pub fn process(&self, state: &mut NonlinearDampingState<T, N>, y: T) -> T {
        let d = y - state.previous;
        state.previous = y;
        let magnitude = if d < T::ZERO { T::ZERO - d } else { d };
        self.lowpass.process(&mut state.lowpass, magnitude * d)
    }

    /// The state after the constant probe signal `y0` forever (no correction, no transient).
    #[must_use]
    pub fn equilibrium(&self, y0: T) -> NonlinearDampingState<T, N> {
        NonlinearDampingState {
            previous: y0,
            lowpass: self.lowpass.equilibrium(T::ZERO),
        }
    }
}
