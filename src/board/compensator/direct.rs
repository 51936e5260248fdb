//! The direct inverse of the paper (eq. 7) on the board: coefficients validated once, a state
//! of its last inputs and outputs, one step per sample.

use super::{schur_stable, InverseError, Sample};

/// Validated coefficients of the direct inverse (paper eq. 7), pre-divided by `b0`.
///
/// Recurrence, with `g = 1/b0`:
///
/// ```text
/// u_hat[k] = g y[k] + sum_i (g a[i]) y[k-i] - sum_i (b[i]/b0) u_hat[k-i]
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseCoefficients<T, const M: usize> {
    /// `1/b0`.
    g: T,
    /// `a[i]/b0`, i = 1..M (zero-padded).
    num: [T; M],
    /// `b[i]/b0`, i = 1..M (zero-padded).
    den: [T; M],
    /// DC gain of the inverse, `(1 + sum a) / sum b`, for starting in equilibrium.
    dc_gain: T,
}

impl<T: Sample, const M: usize> InverseCoefficients<T, M> {
    /// Builds the inverse of the model `b = [b0..bm]`, `a = [a1..am]` (the crate's sign
    /// convention, see the module docs). Coefficients are taken in `f64`, as designed on the
    /// host, and rounded to `T` once.
    ///
    /// # Errors
    /// [`InverseError`] when the order exceeds `M`, a coefficient is not finite, `b0` is zero,
    /// or `B(z)` has a zero on or outside the unit circle.
    ///
    /// ```
    /// use unlag::board::compensator::{InverseCoefficients, InverseError, InverseState};
    ///
    /// // The probe y[k] = 0.5 u[k] + 0.5 y[k-1]: its inverse is u = 2 y[k] - y[k-1].
    /// let c = InverseCoefficients::<f32, 2>::new(&[0.5], &[-0.5])?;
    /// assert_eq!(c.dc_gain(), 1.0);
    /// let mut state = InverseState::default();
    /// let probe = [0.5f32, 0.75, 0.875]; // the probe's answer to a unit step
    /// assert_eq!(probe.map(|y| c.process(&mut state, y)), [1.0, 1.0, 1.0]);
    ///
    /// // b0 = 0 cannot be inverted, nor can a zero outside the unit circle (b1 > b0).
    /// assert_eq!(
    ///     InverseCoefficients::<f32, 2>::new(&[0.0, 0.5], &[-0.5]),
    ///     Err(InverseError::LeadingZero)
    /// );
    /// assert!(matches!(
    ///     InverseCoefficients::<f32, 2>::new(&[0.2, 0.4], &[-0.4]),
    ///     Err(InverseError::UnstableInverse { .. })
    /// ));
    /// # Ok::<(), InverseError>(())
    /// ```
    pub fn new(b: &[f64], a: &[f64]) -> Result<Self, InverseError> {
        let order = a.len().max(b.len().saturating_sub(1));
        if a.len() > M || b.len() > M + 1 {
            return Err(InverseError::OrderTooHigh { order, capacity: M });
        }
        let Some((&b0, b_tail)) = b.split_first() else {
            return Err(InverseError::EmptyNumerator);
        };
        if b.iter().chain(a).any(|c| !c.is_finite()) {
            return Err(InverseError::NonFinite);
        }
        let g = 1.0 / b0;
        if b0 == 0.0 || !g.is_finite() {
            return Err(InverseError::LeadingZero);
        }
        schur_stable(b).map_err(|reflection| InverseError::UnstableInverse { reflection })?;
        let mut num = [T::ZERO; M];
        let mut den = [T::ZERO; M];
        for (n, ai) in num.iter_mut().zip(a) {
            *n = T::from_f64(ai * g);
        }
        for (d, bi) in den.iter_mut().zip(b_tail) {
            *d = T::from_f64(bi * g);
        }
        let sum_a: f64 = a.iter().sum();
        let sum_b: f64 = b.iter().sum();
        // B has no zero at z = 1 (it passed the stability test), so sum_b != 0.
        let dc = (1.0 + sum_a) / sum_b;
        Ok(Self {
            g: T::from_f64(g),
            num,
            den,
            dc_gain: T::from_f64(if dc.is_finite() { dc } else { 0.0 }),
        })
    }

    /// Reconstructs one sample: takes the probe's `y[k]`, returns `u_hat[k-d]`.
    ///
    /// Panic-free and allocation-free; `2M + 1` multiplies.
    #[inline]
    pub fn process(&self, state: &mut InverseState<T, M>, y: T) -> T {
        let mut acc = self.g * y;
        for (c, x) in self.num.iter().zip(state.y.iter()) {
            acc = acc + *c * *x;
        }
        for (c, u) in self.den.iter().zip(state.u.iter()) {
            acc = acc - *c * *u;
        }
        shift_in(&mut state.y, y);
        shift_in(&mut state.u, acc);
        acc
    }

    /// Processes a block in place (`y` in, `u_hat` out), sample by sample.
    #[inline]
    pub fn process_in_place(&self, state: &mut InverseState<T, M>, buf: &mut [T]) {
        for x in buf.iter_mut() {
            *x = self.process(state, *x);
        }
    }

    /// The state of a compensator that has seen the constant probe value `y0` forever:
    /// past outputs equal `y0` divided by the model's DC gain. Starting here avoids the start-up
    /// transient of a zero state when the trace starts at a non-zero pressure.
    #[must_use]
    pub fn equilibrium(&self, y0: T) -> InverseState<T, M> {
        InverseState {
            y: [y0; M],
            u: [self.dc_gain * y0; M],
        }
    }

    /// DC gain of the inverse, `(1 + sum a) / sum b` (1 for a calibrated probe).
    #[must_use]
    pub fn dc_gain(&self) -> T {
        self.dc_gain
    }
}

/// Past inputs and outputs of one compensator channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseState<T, const M: usize> {
    /// `y[k-1], ..., y[k-M]`.
    y: [T; M],
    /// `u_hat[k-1], ..., u_hat[k-M]`.
    u: [T; M],
}

impl<T: Sample, const M: usize> Default for InverseState<T, M> {
    fn default() -> Self {
        Self {
            y: [T::ZERO; M],
            u: [T::ZERO; M],
        }
    }
}

/// Pushes `x` at the front of a fixed history, dropping the oldest value.
#[inline(always)]
fn shift_in<T: Copy, const M: usize>(h: &mut [T; M], x: T) {
    let mut carry = x;
    for slot in h.iter_mut() {
        core::mem::swap(slot, &mut carry);
    }
}

/// One channel: validated coefficients and their state.
///
/// `push(y)` takes the probe's sample and returns the reconstructed reference, `d` samples late.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compensator<T, const M: usize> {
    coefficients: InverseCoefficients<T, M>,
    state: InverseState<T, M>,
}

impl<T: Sample, const M: usize> Compensator<T, M> {
    /// Builds a compensator for `b = [b0..bm]`, `a = [a1..am]` that starts in equilibrium with
    /// the probe reading `y0`.
    ///
    /// # Errors
    /// See [`InverseCoefficients::new`].
    pub fn new(b: &[f64], a: &[f64], y0: T) -> Result<Self, InverseError> {
        let coefficients = InverseCoefficients::new(b, a)?;
        Ok(Self::from_coefficients(coefficients, y0))
    }

    /// Wraps already validated coefficients, starting in equilibrium with `y0`.
    #[must_use]
    pub fn from_coefficients(coefficients: InverseCoefficients<T, M>, y0: T) -> Self {
        Self {
            state: coefficients.equilibrium(y0),
            coefficients,
        }
    }

    /// One ADC sample in, one reconstructed reference sample (`d` samples late) out.
    #[inline]
    pub fn push(&mut self, y: T) -> T {
        self.coefficients.process(&mut self.state, y)
    }

    /// Swaps to a new coefficient set between two samples, keeping the state (bumpless when
    /// the models are close).
    pub fn set_coefficients(&mut self, coefficients: InverseCoefficients<T, M>) {
        self.coefficients = coefficients;
    }

    /// Restarts in equilibrium with the probe reading `y0`.
    pub fn reset(&mut self, y0: T) {
        self.state = self.coefficients.equilibrium(y0);
    }

    /// The coefficients in use.
    #[must_use]
    pub fn coefficients(&self) -> &InverseCoefficients<T, M> {
        &self.coefficients
    }
}
