//! The transducer itself: its diaphragm resonance, and the acquisition's analog anti-alias
//! filter. Both are rational, causal responses multiplied onto the line's response.
//!
//! * Diaphragm: `H_s(s) = ω_s²/(s² + 2ζ_sω_s s + ω_s²)` (README 1.6). The VKI paper quotes
//!   about 250 kHz for a Kulite XCQ-062; `ζ_s = 0.03` is an assumption (a lightly damped
//!   silicon diaphragm in gas), see [`Diaphragm::kulite_xcq062`].
//! * Anti-alias filter: an analog Butterworth low-pass of order `n`, poles on the circle
//!   `s_k = ω_c e^{iπ(2k+n+1)/(2n)}`.

use num_complex::Complex64;

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
    /// Order `n` [-] (1..=12).
    pub order: u32,
}

impl Butterworth {
    /// Checks the corner is positive and the order 1..=12.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        let f_ok = self.corner_hz.is_finite() && self.corner_hz > 0.0;
        if !(f_ok && (1..=12).contains(&self.order)) {
            return Err(Error::InvalidArgument {
                what: "anti-alias filter",
                message: format!(
                    "corner {} Hz must be positive and order {} in 1..=12",
                    self.corner_hz, self.order
                ),
            });
        }
        Ok(())
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
}
