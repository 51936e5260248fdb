//! The transducer itself: its diaphragm resonance, and the acquisition's analog anti-alias
//! filter. Both are rational, causal responses multiplied onto the line's response.
//!
//! * Diaphragm: `H_s(s) = ω_s²/(s² + 2ζ_sω_s s + ω_s²)` (README 1.6). The VKI paper quotes
//!   about 250 kHz for a Kulite XCQ-062; `ζ_s = 0.03` is an assumption (a lightly damped
//!   silicon diaphragm in gas), see [`Diaphragm::kulite_xcq062`].
//! * Anti-alias filter: an analog Butterworth low-pass of order `n`, poles on the circle
//!   `s_k = ω_c e^{iπ(2k+n+1)/(2n)}`.

use num_complex::Complex64;

use super::PhysicsError;
use crate::error::{Error, Result};

/// A second-order diaphragm resonance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Diaphragm {
    /// Natural frequency `f_s` \[Hz\].
    pub natural_frequency_hz: f64,
    /// Damping ratio `ζ_s` [-].
    pub damping: f64,
}

impl Diaphragm {
    /// The VKI paper's reference transducer: 250 kHz, with an assumed `ζ = 0.03`.
    #[must_use]
    pub fn kulite_xcq062() -> Self {
        Self {
            natural_frequency_hz: 250e3,
            damping: 0.03,
        }
    }

    /// Checks the natural frequency is positive and the damping non-negative.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        let f_ok = self.natural_frequency_hz.is_finite() && self.natural_frequency_hz > 0.0;
        let z_ok = self.damping.is_finite() && self.damping >= 0.0;
        if !(f_ok && z_ok) {
            return Err(Error::InvalidArgument {
                what: "diaphragm",
                message: format!(
                    "natural frequency {} Hz must be positive and damping {} non-negative",
                    self.natural_frequency_hz, self.damping
                ),
            });
        }
        Ok(())
    }

    /// `H_s(s)` [-] at complex frequency `s` [rad/s]; DC gain 1.
    #[must_use]
    pub fn response(&self, s: Complex64) -> Complex64 {
        let w = 2.0 * core::f64::consts::PI * self.natural_frequency_hz;
        w * w / (s * s + 2.0 * self.damping * w * s + w * w)
    }
}

/// An analog Butterworth low-pass (the DAQ's anti-alias filter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Butterworth {
    /// Corner (−3 dB) frequency \[Hz\].
    pub corner_hz: f64,
    /// Order `n` [-] (1..=[`Self::MAX_ORDER`]).
    pub order: u32,
}

impl Butterworth {
    /// Highest order of the filter.
    pub const MAX_ORDER: u32 = 12;

    /// Checks the corner is positive and the order 1..=[`Self::MAX_ORDER`].
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a corner that is not a positive number of Hz;
    /// [`PhysicsError::FilterOrder`] for an order out of range ([`Self::check_order`]).
    pub fn validate(&self) -> Result<()> {
        let f_ok = self.corner_hz.is_finite() && self.corner_hz > 0.0;
        if !f_ok {
            return Err(Error::InvalidArgument {
                what: "anti-alias filter",
                message: format!(
                    "corner {} Hz must be positive and order {} in 1..={}",
                    self.corner_hz,
                    self.order,
                    Self::MAX_ORDER
                ),
            });
        }
        Ok(self.check_order()?)
    }

    /// Checks the order is 1..=[`Self::MAX_ORDER`].
    ///
    /// # Errors
    /// [`PhysicsError::FilterOrder`].
    pub fn check_order(&self) -> core::result::Result<(), PhysicsError> {
        if (1..=Self::MAX_ORDER).contains(&self.order) {
            Ok(())
        } else {
            Err(PhysicsError::FilterOrder { order: self.order })
        }
    }

    /// `H(s)` [-] at complex frequency `s` [rad/s]; DC gain 1, `|H| = 1/√2` at the corner.
    #[must_use]
    pub fn response(&self, s: Complex64) -> Complex64 {
        let wc = 2.0 * core::f64::consts::PI * self.corner_hz;
        let n = f64::from(self.order);
        let mut h = Complex64::new(1.0, 0.0);
        for k in 0..self.order {
            let angle = core::f64::consts::PI * (2.0 * f64::from(k) + n + 1.0) / (2.0 * n);
            let pole = Complex64::from_polar(wc, angle);
            h *= -pole / (s - pole);
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diaphragm_peak_and_dc() {
        let d = Diaphragm::kulite_xcq062();
        assert!((d.response(Complex64::new(0.0, 0.0)) - 1.0).norm() < 1e-15);
        let at = d.response(Complex64::new(0.0, 2.0 * core::f64::consts::PI * 250e3));
        // |H| = 1/(2ζ) at ω = ω_s, phase −90°.
        assert!((at.norm() - 1.0 / 0.06).abs() < 1e-9);
        assert!((at.arg() + core::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn butterworth_corner() {
        for order in [1, 2, 5] {
            let b = Butterworth {
                corner_hz: 1000.0,
                order,
            };
            let h = b.response(Complex64::new(0.0, 2.0 * core::f64::consts::PI * 1000.0));
            assert!((h.norm() - core::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
            assert!((b.response(Complex64::new(0.0, 0.0)) - 1.0).norm() < 1e-12);
        }
    }

    /// An order 1..=MAX_ORDER passes, one outside is refused with its typed error; a bad
    /// corner is refused before the order.
    #[test]
    fn butterworth_order_range() {
        let with = |corner_hz, order| Butterworth { corner_hz, order };
        assert!(with(1000.0, 1).validate().is_ok());
        assert!(with(1000.0, Butterworth::MAX_ORDER).validate().is_ok());
        for order in [0, Butterworth::MAX_ORDER + 1] {
            assert!(matches!(
                with(1000.0, order).check_order(),
                Err(PhysicsError::FilterOrder { order: o }) if o == order
            ));
            let e = with(1000.0, order).validate().unwrap_err();
            assert!(
                matches!(e.stage(), Some(PhysicsError::FilterOrder { .. })),
                "{e}"
            );
        }
        assert!(matches!(
            with(0.0, 0).validate(),
            Err(Error::InvalidArgument { .. })
        ));
    }
}
