//! The ADC's readings as the fixed-point compensators' input codes (Q1.31 of the plan's full
//! scale), saturated, with a count of the samples clamped.
//!
//! A fixed-point plan is made for a full scale `F` in the probe's units (`unlag fit
//! --full-scale`): the input code `2^31` is `F`. When `F` is the ADC's own range, a `bits`-bit
//! reading is its code shifted left by `32 - bits` and nothing can clamp ([`AdcInput::matching`]).
//! When the plan was made for a smaller range than the ADC's (a default full scale chosen from
//! the step tests), readings beyond `F` clamp: [`AdcInput::block`] counts them, so that the
//! firmware can report what `unlag compensate --arithmetic fixed` reports on the host.
#![deny(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::todo,
    clippy::arithmetic_side_effects
)]

use core::fmt;

/// Fractional bits of [`AdcInput`]'s ratio (Q2.30).
const RATIO_BITS: u32 = 30;

/// Why an [`AdcInput`] was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InputError {
    /// The ADC's width is outside 2..=32 bits.
    Bits {
        /// The width given.
        bits: u32,
    },
    /// The ADC's range over the plan's full scale is not a positive number below 2: the plan
    /// was made for less than half the ADC's range (plan it for the ADC's range:
    /// `unlag export --full-scale`), or a range is not a positive number.
    Ratio {
        /// The ADC's range over the plan's full scale.
        ratio: f64,
    },
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Bits { bits } => write!(f, "an ADC of {bits} bits: 2 to 32 are supported"),
            Self::Ratio { ratio } => write!(
                f,
                "the ADC's range is {ratio} times the plan's full scale: it must be above 0 and \
                 below 2 (plan the compensator for the ADC's range)"
            ),
        }
    }
}

impl core::error::Error for InputError {}

/// A signed `bits`-bit ADC's readings as Q1.31 codes of a fixed-point plan's full scale:
///
/// ```text
/// code = saturate_i32( (reading << (32 - bits)) * ratio >> 30 )     ratio: Q2.30, in (0, 2)
/// ```
///
/// with `ratio` the ADC's range over the plan's full scale, rounded to Q2.30 once, at
/// construction; the product is floored (arithmetic shift). A reading whose code leaves the
/// `i32` range is clamped to it, and counted by [`AdcInput::block`].
///
/// ```
/// use unlag::board::fixed::input::AdcInput;
///
/// // A 16-bit ADC reading +-3000 Pa; the plan was made for +-2000 Pa.
/// let input = AdcInput::new(16, 3000.0, 2000.0)?;
/// let readings = [0, 6000, 21_845, 21_846, -32_768];
/// let mut codes = [0; 5];
/// // 21_845 is 1999.97 Pa; 21_846 (2000.06 Pa) and -32_768 (-3000 Pa) are beyond 2000 Pa.
/// assert_eq!(input.block(&readings, &mut codes), 2);
/// assert_eq!(codes[4], i32::MIN);
/// // Planned for the ADC's own range, nothing clamps.
/// let matching = AdcInput::matching(16)?;
/// assert_eq!(matching.block(&readings, &mut codes), 0);
/// assert_eq!(codes, [0, 6000 << 16, 21_845 << 16, 21_846 << 16, i32::MIN]);
/// # Ok::<(), unlag::board::fixed::input::InputError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdcInput {
    /// `32 - bits`.
    shift: u32,
    /// The ADC's range over the plan's full scale, Q2.30, in `(0, 2^31)`.
    ratio: i32,
}

impl AdcInput {
    /// For a `bits`-bit ADC whose range is the plan's full scale: each reading shifted left by
    /// `32 - bits`, never clamped.
    ///
    /// # Errors
    /// [`InputError::Bits`] outside 2..=32 bits.
    pub const fn matching(bits: u32) -> Result<Self, InputError> {
        if bits < 2 || bits > 32 {
            return Err(InputError::Bits { bits });
        }
        Ok(Self {
            // 0..=30, checked above.
            shift: 32u32.wrapping_sub(bits),
            ratio: 1 << RATIO_BITS,
        })
    }

    /// For a `bits`-bit ADC reading `+-adc_range` in the probe's units, and a plan made for
    /// `+-full_scale` (the blob's or the exported `FULL_SCALE`).
    ///
    /// # Errors
    /// [`InputError::Bits`] outside 2..=32 bits; [`InputError::Ratio`] when `adc_range /
    /// full_scale` is not a positive number below 2.
    pub fn new(bits: u32, adc_range: f64, full_scale: f64) -> Result<Self, InputError> {
        let Self { shift, .. } = Self::matching(bits)?;
        let ratio = adc_range / full_scale;
        let q = libm::round(ratio * f64::from(1u32 << RATIO_BITS));
        if !(1.0..2_147_483_648.0).contains(&q) {
            return Err(InputError::Ratio { ratio });
        }
        // In 1..2^31, checked above.
        #[allow(clippy::cast_possible_truncation)]
        Ok(Self {
            shift,
            ratio: q as i32,
        })
    }

    /// One reading's code, and whether it was clamped.
    #[inline]
    #[must_use]
    pub fn code(&self, reading: i32) -> (i32, bool) {
        // |reading << shift| <= 2^62 only for readings wider than the ADC; the ratio is below
        // 2^31, so the wrapping operations below never wrap for readings within the ADC's
        // bits (and a wider one saturates all the same unless it exceeds 2^32 codes).
        let wide = i64::from(reading)
            .wrapping_shl(self.shift)
            .wrapping_mul(i64::from(self.ratio))
            .wrapping_shr(RATIO_BITS);
        match i32::try_from(wide) {
            Ok(code) => (code, false),
            Err(_) if wide < 0 => (i32::MIN, true),
            Err(_) => (i32::MAX, true),
        }
    }

    /// A block of readings as codes into `codes` (as many as both hold); the number of
    /// samples clamped in it.
    #[inline]
    pub fn block(&self, readings: &[i32], codes: &mut [i32]) -> u32 {
        readings
            .iter()
            .zip(codes.iter_mut())
            .fold(0u32, |clamped, (&r, c)| {
                let (code, was) = self.code(r);
                *c = code;
                clamped.saturating_add(u32::from(was))
            })
    }
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::arithmetic_side_effects)]
mod tests {
    use super::*;

    #[test]
    fn codes_follow_the_ratio_and_clamp_beyond_the_plans_range() {
        // The ADC reads 1.5 times the plan's range.
        let input = AdcInput::new(12, 3.0, 2.0).unwrap();
        // Full-scale positive reading of a 12-bit ADC: 2047 << 20, times 1.5, clamps.
        assert_eq!(input.code(2047), (i32::MAX, true));
        // Half the ADC's range is 0.75 of the plan's.
        assert_eq!(
            input.code(1024),
            ((((1024i64 << 20) * 3) >> 1) as i32, false)
        );
        assert_eq!(input.code(-2048), (i32::MIN, true));
        // Exactly at the plan's range (1365.33 codes): 1365 is inside.
        assert!(!input.code(1365).1 && input.code(1366).1);
        let mut codes = [0; 4];
        assert_eq!(input.block(&[0, 2047, -2048, 100], &mut codes), 2);
        assert_eq!(codes[0], 0);
        // A shorter output takes what fits.
        let mut two = [0; 2];
        assert_eq!(input.block(&[2047, 2047, 2047], &mut two), 2);
    }

    #[test]
    fn the_ratio_and_the_width_are_checked_once() {
        assert_eq!(AdcInput::matching(1), Err(InputError::Bits { bits: 1 }));
        assert_eq!(AdcInput::matching(33), Err(InputError::Bits { bits: 33 }));
        assert!(AdcInput::matching(32).is_ok());
        assert!(matches!(
            AdcInput::new(16, 2.0, 1.0),
            Err(InputError::Ratio { .. })
        ));
        assert!(matches!(
            AdcInput::new(16, -1.0, 1.0),
            Err(InputError::Ratio { .. })
        ));
        assert!(matches!(
            AdcInput::new(16, f64::NAN, 1.0),
            Err(InputError::Ratio { .. })
        ));
        // A 32-bit ADC matching the plan: the identity.
        let id = AdcInput::matching(32).unwrap();
        for r in [i32::MIN, -1, 0, 1, i32::MAX] {
            assert_eq!(id.code(r), (r, false));
        }
    }
}
