//! The cheaper fixed-point form: direct-form-I biquads with first-order error feedback.
//!
//! This module owns the per-sample integer arithmetic of [`DirectCascade`], the alternative to
//! the normal-form [`crate::board::fixed::FixedCascade`] that costs about a third of its instructions
//! on a Cortex-M4 and gives up part of its guarantees (see "What it guarantees" below, and the
//! trade table in BENCHMARKS.md). Coefficients are planned on the host
//! (`crate::design::quantise::DirectPlan`) and validated once, in [`DirectCascade::new`].
//!
//! # The form
//!
//! Section `k` maps its input `x` (the previous section's output, or the ADC code) to its
//! output `y`, both `i32`, with coefficients in Q2.30 (30 fractional bits):
//!
//! ```text
//! acc  = e + b0 x[n] + b1 x[n-1] + b2 x[n-2] + na1 y[n-1] + na2 y[n-2]     (exact, i64)
//! y[n] = acc >> 30      (rounded towards minus infinity; see saturation below)
//! e    = acc & (2^30 - 1)   (the truncation residual, 0 <= e < 2^30, fed to the next sample)
//! ```
//!
//! `na1 = -a1`, `na2 = -a2`: the section is `H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 +
//! a2 z^-2)` in the crate's sign convention, and the board stores the **negated** denominator
//! so that every term is a multiply-accumulate (SMLAL). The sections share their delay lines:
//! section `k`'s output history is section `k + 1`'s input history, so the state is the two
//! last ADC codes and, per section, `y[n-1], y[n-2], e`.
//!
//! Carrying the residual `e` into the next accumulator is first-order error feedback: the
//! truncation error reaches the output through `(1 - z^-1) / A(z)` instead of `1 / A(z)`, a
//! zero at DC against the poles' gain near `z = 1`. At high sample rates (fs/fn in the
//! hundreds) that is what keeps the rounding noise far below the signal; the error left is
//! the quantisation of the coefficients themselves (`a1 = -2 r cos(theta)` near -2 has a
//! coarse pole grid there), which the normal form avoids.
//!
//! # What it guarantees
//!
//! - **No overflow for planned coefficients.** The host scales each section's numerator so
//!   that, by the L1 norm of the impulse response from the cascade's input (all of `i32`, the
//!   ADC's full scale) to the section's output, computed with the quantised integers, plus an
//!   L1 bound of the error feedback's contribution, every output stays within half of `i32`:
//!   no input can make any value leave its range. No input clamp is needed: every `i32` is
//!   inside the full scale.
//! - **Overflow is still detected.** Should a section's output leave `i32` anyway
//!   (coefficients made by hand), it is clamped (to within 3 codes of `i32::MIN`/`i32::MAX`:
//!   the high word of the accumulator is saturated with one SSAT) and
//!   [`DirectState::overflowed`] says so until cleared.
//! - **No accumulator overflow, no panic.** [`DirectCascade::new`] checks that the magnitudes
//!   of a section's five coefficients sum to less than `2^32` ([`MAX_COEFFICIENT_SUM`]):
//!   with `|x|, |y| <= 2^31` and `e < 2^30`, every partial sum stays below `2^63`.
//! - **Limit cycles: not excluded.** Unlike magnitude truncation in normal form, error
//!   feedback in direct form does not provably bring a zero-input state to rest; the
//!   benchmark (`examples/bench_fixed.rs`) measures what remains after full-scale excitation.
//! - **Bit-exact**: integer arithmetic, so the host (`DirectPlan::run`) and the board's
//!   Thumb-2 kernels (module `m4`) compute the same bits.
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

use super::{I1F31, I2F30};

/// Fractional bits of every coefficient (Q2.30).
pub const COEFFICIENT_BITS: u32 = 30;

/// Bound on the sum of a section's five coefficient magnitudes (exclusive): `2^32`. Keeps the
/// `i64` accumulator exact for every `i32` input and state.
pub const MAX_COEFFICIENT_SUM: u64 = 1 << 32;

/// One direct-form-I section, as integers (Q2.30).
///
/// `#[repr(C)]`: the Cortex-M kernels read it at fixed offsets (`b0, b1, b2, na1, na2`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(C)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DirectSection {
    /// Numerator `[b0, b1, b2]`, Q2.30.
    pub b: [i32; 3],
    /// The **negated** denominator `[-a1, -a2]`, Q2.30, for `1 + a1 z^-1 + a2 z^-2`.
    pub neg_a: [i32; 2],
}

impl DirectSection {
    /// The identity section (`y = x`, exactly), used for unused capacity.
    pub const IDENTITY: Self = Self {
        b: [1 << 30, 0, 0],
        neg_a: [0, 0],
    };

    /// A section from its numerator `[b0, b1, b2]` and **negated** denominator `[-a1, -a2]`
    /// as Q2.30 numbers.
    ///
    /// ```
    /// use unlag::board::fixed::{direct::DirectSection, I2F30};
    ///
    /// let q = I2F30::from_num;
    /// let lag = DirectSection::from_q([q(0.5), q(0.0), q(0.0)], [q(0.5), q(0.0)]);
    /// assert_eq!(lag, DirectSection { b: [1 << 29, 0, 0], neg_a: [1 << 29, 0] });
    /// assert_eq!(lag.negated_denominator()[0], q(0.5));
    /// ```
    #[must_use]
    pub const fn from_q(b: [I2F30; 3], neg_a: [I2F30; 2]) -> Self {
        let [b0, b1, b2] = b;
        let [na1, na2] = neg_a;
        Self {
            b: [b0.to_bits(), b1.to_bits(), b2.to_bits()],
            neg_a: [na1.to_bits(), na2.to_bits()],
        }
    }

    /// The numerator `[b0, b1, b2]` as Q2.30 numbers.
    #[must_use]
    pub const fn numerator(&self) -> [I2F30; 3] {
        let [b0, b1, b2] = self.b;
        [
            I2F30::from_bits(b0),
            I2F30::from_bits(b1),
            I2F30::from_bits(b2),
        ]
    }

    /// The negated denominator `[-a1, -a2]` as Q2.30 numbers.
    #[must_use]
    pub const fn negated_denominator(&self) -> [I2F30; 2] {
        let [na1, na2] = self.neg_a;
        [I2F30::from_bits(na1), I2F30::from_bits(na2)]
    }
}

/// Why a set of direct-form coefficients was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DirectError {
    /// More sections than the capacity `N`.
    TooManySections {
        /// Sections given.
        sections: usize,
        /// Capacity.
        capacity: usize,
    },
    /// The magnitudes of the section's coefficients sum to [`MAX_COEFFICIENT_SUM`] or more.
    CoefficientSumTooLarge {
        /// 0-based section.
        index: usize,
    },
    /// The denominator's poles are not strictly inside the unit circle.
    Unstable {
        /// 0-based section.
        index: usize,
    },
}

impl fmt::Display for DirectError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManySections { sections, capacity } => write!(
                f,
                "{sections} direct-form sections exceed the capacity of {capacity}"
            ),
            Self::CoefficientSumTooLarge { index } => write!(
                f,
                "section {index}: the coefficient magnitudes sum to 2^32 or more (accumulator \
                 overflow)"
            ),
            Self::Unstable { index } => write!(
                f,
                "section {index}: the denominator has a pole on or outside the unit circle"
            ),
        }
    }
}

impl core::error::Error for DirectError {}

/// Validated direct-form coefficients of a cascade of up to `N` sections.
///
/// `#[repr(C)]`: the Cortex-M kernels read the `N` sections from its start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct DirectCascade<const N: usize> {
    sections: [DirectSection; N],
}

/// The states of one channel, and the overflow flag.
///
/// `#[repr(C)]`: the Cortex-M kernels read and write, in this order, the two last inputs
/// `[x[n-1], x[n-2]]`, then per section `[y[n-1], y[n-2], e]`, then the flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct DirectState<const N: usize> {
    x: [i32; 2],
    s: [[i32; 3]; N],
    overflow: bool,
}

impl<const N: usize> Default for DirectState<N> {
    fn default() -> Self {
        Self {
            x: [0; 2],
            s: [[0; 3]; N],
            overflow: false,
        }
    }
}

impl<const N: usize> DirectState<N> {
    /// `true` when a section's output left `i32` since the flag was last cleared.
    #[must_use]
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Reads and clears the overflow flag.
    pub fn take_overflow(&mut self) -> bool {
        core::mem::replace(&mut self.overflow, false)
    }

    /// `true` when every state is exactly zero, truncation residuals included.
    #[must_use]
    pub fn is_zero(&self) -> bool {
        self.x
            .iter()
            .chain(self.s.iter().flatten())
            .all(|&v| v == 0)
    }

    /// `true` when every input and output history is zero (the residuals may not be): the
    /// output is zero for as long as the input is.
    #[must_use]
    pub fn is_quiet(&self) -> bool {
        self.x.iter().all(|&v| v == 0) && self.s.iter().all(|&[y1, y2, _]| y1 == 0 && y2 == 0)
    }

    /// The largest output-history magnitude over all sections: what a limit cycle leaves.
    #[must_use]
    pub fn largest_output(&self) -> u32 {
        self.s
            .iter()
            .flat_map(|&[y1, y2, _]| [y1.unsigned_abs(), y2.unsigned_abs()])
            .max()
            .unwrap_or(0)
    }
}

/// `acc >> 30` as `i32` with the high word saturated to 30 bits (SSAT), the residual, and
/// whether it saturated.
#[inline(always)]
fn quantise(acc: i64) -> (i32, i32, bool) {
    // The two words of the accumulator; truncations are the point.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    let (hi, lo) = ((acc >> 32) as i32, acc as u32);
    let top = 1i32 << 29;
    let sat = hi.clamp(top.wrapping_neg(), top.wrapping_sub(1));
    // lo >> 30 is at most 3; the residual below 2^30: both fit i32.
    #[allow(clippy::cast_possible_wrap)]
    let y = sat.wrapping_shl(2) | (lo >> 30) as i32;
    #[allow(clippy::cast_possible_wrap)]
    let e = (lo & 0x3FFF_FFFF) as i32;
    (y, e, sat != hi)
}

#[inline(always)]
fn mac(acc: i64, c: i32, v: i32) -> i64 {
    // |c| summed over a section is below 2^32 and |v| <= 2^31: no partial sum reaches 2^63,
    // so wrapping never wraps (checked in `DirectCascade::new`).
    acc.wrapping_add(i64::from(c).wrapping_mul(i64::from(v)))
}

impl<const N: usize> DirectCascade<N> {
    /// Validates the sections: count, accumulator range, stability.
    ///
    /// # Errors
    /// A [`DirectError`] naming the section.
    ///
    /// ```
    /// use unlag::board::fixed::direct::{DirectCascade, DirectError, DirectSection, DirectState};
    ///
    /// const HALF: i32 = 1 << 29; // 0.5 in Q2.30
    /// // y[n] = 0.5 x[n] + 0.5 y[n-1], then an identity: a DC gain of one.
    /// let lag = DirectSection { b: [HALF, 0, 0], neg_a: [HALF, 0] };
    /// let c = DirectCascade::<2>::new(&[lag, DirectSection::IDENTITY])?;
    /// let mut state = DirectState::default();
    /// let mut buf = [1000i32; 40];
    /// c.process_in_place(&mut state, &mut buf);
    /// assert_eq!(buf[..4], [500, 750, 875, 937]);
    /// // The truncation residual is carried over, so the output reaches the input exactly.
    /// assert_eq!(buf[39], 1000);
    /// assert_eq!(c.process(&mut state, 1000), 1000);
    /// assert!(!state.overflowed());
    ///
    /// // Poles on or outside the unit circle (here a2 = 1) are refused.
    /// let ring = DirectSection { b: [HALF, 0, 0], neg_a: [0, -(1 << 30)] };
    /// assert!(matches!(
    ///     DirectCascade::<2>::new(&[lag, ring]),
    ///     Err(DirectError::Unstable { index: 1 })
    /// ));
    /// # Ok::<(), DirectError>(())
    /// ```
    pub fn new(sections: &[DirectSection]) -> Result<Self, DirectError> {
        if sections.len() > N {
            return Err(DirectError::TooManySections {
                sections: sections.len(),
                capacity: N,
            });
        }
        let mut out = [DirectSection::IDENTITY; N];
        for (index, (dst, s)) in out.iter_mut().zip(sections).enumerate() {
            let sum =
                s.b.iter()
                    .chain(&s.neg_a)
                    .map(|v| u64::from(v.unsigned_abs()))
                    .fold(0u64, u64::wrapping_add);
            if sum >= MAX_COEFFICIENT_SUM {
                return Err(DirectError::CoefficientSumTooLarge { index });
            }
            if !stable(s.neg_a) {
                return Err(DirectError::Unstable { index });
            }
            *dst = *s;
        }
        Ok(Self { sections: out })
    }

    /// One ADC code (Q1.31 of the design's full scale) through the cascade; the output is the
    /// reconstructed reference in the design's output format. Panic-free, allocation-free.
    ///
    /// On the Cortex-M3, M4 and M7 targets (`thumbv7m-none-eabi`, `thumbv7em-none-eabi`,
    /// `thumbv7em-none-eabihf`) with 1 to 4 sections this runs a hand-written Thumb-2 kernel
    /// (module `m4`, see [`uses_kernel`]), elsewhere
    /// [`Self::process_portable`]: the same bits (`host-tests/firmware.rs` checks it in QEMU).
    #[inline]
    pub fn process(&self, state: &mut DirectState<N>, input: i32) -> i32 {
        #[cfg(unlag_armv7m)]
        {
            if let Some(y) = m4::process(self, state, input) {
                return y;
            }
        }
        self.process_portable(state, input)
    }

    /// [`Self::process`] with the sample formats as types: the input is Q1.31 of the full
    /// scale `F`, the output Q1.31 of `F * 2^e` with the plan's output exponent `e` (see
    /// [`I1F31`]). The same bits as [`Self::process`] (`to_bits` in, `from_bits` out), at no
    /// cost; the block functions stay on `i32` codes, the words an ADC's DMA writes.
    ///
    /// ```
    /// use unlag::board::fixed::direct::{DirectCascade, DirectSection, DirectState};
    /// use unlag::board::fixed::I1F31;
    ///
    /// // The host's plan for F = 4000 Pa with output exponent e = 1: a section that halves the
    /// // codes (y[n] = 0.5 x[n]) while the output's unit doubles, one bit of headroom at gain 1.
    /// let (full_scale, output_exponent) = (4000.0, 1);
    /// let halve = DirectSection { b: [1 << 29, 0, 0], neg_a: [0, 0] };
    /// let c = DirectCascade::<1>::new(&[halve])?;
    /// let mut state = DirectState::default();
    ///
    /// let reading = -1000.0; // Pa
    /// let u = I1F31::from_num(reading / full_scale); // -0.25 of F, the code -2^29
    /// let y = c.process_q(&mut state, u);
    /// assert_eq!(y.to_num::<f64>(), -0.125); // of F * 2^e
    /// assert_eq!(y.to_num::<f64>() * full_scale * 2f64.powi(output_exponent), -1000.0); // Pa
    /// assert_eq!(y.to_bits(), c.process(&mut state, u.to_bits())); // the same bits as i32
    /// # Ok::<(), unlag::board::fixed::direct::DirectError>(())
    /// ```
    #[inline]
    pub fn process_q(&self, state: &mut DirectState<N>, input: I1F31) -> I1F31 {
        I1F31::from_bits(self.process(state, input.to_bits()))
    }

    /// [`Self::process`] in portable Rust, on every target: the reference the Cortex-M
    /// kernels are checked against.
    #[inline]
    pub fn process_portable(&self, state: &mut DirectState<N>, input: i32) -> i32 {
        let [x1, x2] = state.x;
        state.x = [input, x1];
        let (mut v0, mut v1, mut v2) = (input, x1, x2);
        let mut overflow = false;
        for (sec, st) in self.sections.iter().zip(state.s.iter_mut()) {
            let [y1, y2, e] = *st;
            let [b0, b1, b2] = sec.b;
            let [na1, na2] = sec.neg_a;
            let acc = mac(
                mac(mac(mac(mac(i64::from(e), b0, v0), b1, v1), b2, v2), na1, y1),
                na2,
                y2,
            );
            let (y, e, o) = quantise(acc);
            *st = [y, y1, e];
            overflow |= o;
            (v0, v1, v2) = (y, y1, y2);
        }
        state.overflow |= overflow;
        v0
    }

    /// Processes a block in place (the same arithmetic as [`Self::process`], sample by
    /// sample). On Cortex-M with 1 to 4 sections a block kernel keeps the loop in assembly.
    #[inline]
    pub fn process_in_place(&self, state: &mut DirectState<N>, buf: &mut [i32]) {
        #[cfg(unlag_armv7m)]
        {
            if m4::process_in_place(self, state, buf) {
                return;
            }
        }
        self.process_in_place_portable(state, buf);
    }

    /// [`Self::process_in_place`] in portable Rust.
    #[inline]
    pub fn process_in_place_portable(&self, state: &mut DirectState<N>, buf: &mut [i32]) {
        for v in buf.iter_mut() {
            *v = self.process_portable(state, *v);
        }
    }

    /// The state after the constant input `input` forever (no start-up transient), computed
    /// in floating point from the integer coefficients and rounded; the residuals start at 0.
    #[must_use]
    pub fn equilibrium(&self, input: i32) -> DirectState<N> {
        let mut state = DirectState::<N> {
            x: [input; 2],
            ..DirectState::default()
        };
        let mut v = f64::from(input);
        for (s, st) in self.sections.iter().zip(state.s.iter_mut()) {
            let [b0, b1, b2] = s.b.map(f64::from);
            let [na1, na2] = s.neg_a.map(f64::from);
            let one = f64::from(1u32 << COEFFICIENT_BITS);
            // DC gain B(1) / A(1); A(1) > 0 for an accepted (stable) section.
            let y = v * (b0 + b1 + b2) / (one - na1 - na2);
            // `as` saturates and maps NaN to 0: no panic.
            let y = libm::floor(y) as i32;
            *st = [y, y, 0];
            v = f64::from(y);
        }
        state
    }

    /// [`Self::equilibrium`] for an input in Q1.31 of the full scale (see [`I1F31`]).
    #[must_use]
    #[inline]
    pub fn equilibrium_q(&self, input: I1F31) -> DirectState<N> {
        self.equilibrium(input.to_bits())
    }

    /// The sections, identities included.
    #[must_use]
    pub fn sections(&self) -> &[DirectSection; N] {
        &self.sections
    }
}

/// `true` when this build runs [`DirectCascade::process`] and
/// [`DirectCascade::process_in_place`] for `sections` sections through the Cortex-M kernels
/// (`N` = 1..=4 on the ARMv7-M and ARMv7E-M targets `thumbv7m-none-eabi`, Cortex-M3, and
/// `thumbv7em-none-eabi(hf)`, Cortex-M4 and M7, with or without an FPU), `false` when it runs
/// the portable Rust code. Both compute the same bits.
///
/// ```
/// use unlag::board::fixed::direct::uses_kernel;
///
/// // There are kernels for 1 to 4 sections only, and none on the host.
/// assert!(!uses_kernel(5));
/// # #[cfg(not(target_arch = "arm"))]
/// assert!(!uses_kernel(4));
/// ```
#[must_use]
pub const fn uses_kernel(sections: usize) -> bool {
    cfg!(unlag_armv7m) && sections >= 1 && sections <= 4
}

/// Poles strictly inside the unit circle: `|a2| < 1` and `|a1| < 1 + a2`, in Q2.30 integers.
fn stable(neg_a: [i32; 2]) -> bool {
    let [na1, na2] = neg_a.map(i64::from);
    let one = 1i64 << COEFFICIENT_BITS;
    // a2 = -na2, 1 + a2 = one - na2; all in i64 without overflow (|na| < 2^31).
    na2.abs() < one && na1.abs() < one.wrapping_sub(na2)
}

/// The Cortex-M kernels of the direct-form cascade (ARMv7-M: Cortex-M3, M4, M7; see `build.rs`
/// for `unlag_armv7m`).
#[cfg(unlag_armv7m)]
mod m4;

#[cfg(test)]
mod tests {
    use super::*;

    fn q30(v: f64) -> i32 {
        (v * (1u64 << 30) as f64).round() as i32
    }

    /// A resonance `r, theta` with unit DC gain, numerator `g (1 + z^-1)^2 / 4`.
    fn lowpass(r: f64, theta: f64) -> DirectSection {
        let (a1, a2) = (-2.0 * r * theta.cos(), r * r);
        let g = (1.0 + a1 + a2) / 4.0;
        DirectSection {
            b: [q30(g), q30(2.0 * g), q30(g)],
            neg_a: [q30(-a1), q30(-a2)],
        }
    }

    #[test]
    fn quantise_floors_keeps_the_residual_and_saturates() {
        assert_eq!(quantise((5 << 30) | 7), (5, 7, false));
        assert_eq!(quantise(-(5 << 30) + 7), (-5, 7, false));
        assert_eq!(quantise(-1), (-1, (1 << 30) - 1, false));
        assert_eq!(quantise(i64::from(i32::MAX) << 30), (i32::MAX, 0, false));
        assert_eq!(quantise(i64::from(i32::MIN) << 30), (i32::MIN, 0, false));
        // One past the top: the high word saturates, the flag is set.
        let (y, _, o) = quantise(1 << 61);
        assert!(o && y >= i32::MAX - 3);
        let (y, _, o) = quantise(-(1 << 61) - (1 << 30));
        assert!(o && y <= i32::MIN + 3);
    }

    #[test]
    fn identity_capacity_passes_samples_through() {
        let c = DirectCascade::<3>::new(&[]).unwrap();
        let mut st = DirectState::default();
        for v in [0, 1, -1, i32::MAX, i32::MIN, 12345] {
            assert_eq!(c.process(&mut st, v), v);
        }
        assert!(!st.overflowed());
    }

    #[test]
    fn refuses_what_it_cannot_run_safely() {
        let ok = lowpass(0.99, 0.1);
        assert!(DirectCascade::<1>::new(&[ok, ok]).is_err());
        let mut big = ok;
        big.b = [i32::MAX, i32::MIN, 0];
        assert_eq!(
            DirectCascade::<2>::new(&[ok, big]),
            Err(DirectError::CoefficientSumTooLarge { index: 1 })
        );
        let mut unstable = ok;
        unstable.neg_a = [q30(1.2), q30(-0.2)]; // a pole at z = 1
        assert_eq!(
            DirectCascade::<2>::new(&[unstable]),
            Err(DirectError::Unstable { index: 0 })
        );
    }

    #[test]
    fn dc_gain_and_equilibrium() {
        let c = DirectCascade::<2>::new(&[lowpass(0.99, 0.05), lowpass(0.9, 0.5)]).unwrap();
        let x = 1 << 29;
        let mut st = c.equilibrium(x);
        for _ in 0..100 {
            let y = c.process(&mut st, x);
            assert!((y - x).abs() < 64, "{y} vs {x}");
        }
        let mut st = DirectState::default();
        let mut y = 0;
        for _ in 0..20_000 {
            y = c.process(&mut st, x);
        }
        assert!((y - x).abs() < 64, "{y} vs {x}");
        assert!(!st.overflowed());
    }

    #[test]
    fn saturates_and_flags_instead_of_wrapping() {
        // Gain 2 at DC.
        let mut s = lowpass(0.5, 0.3);
        s.b = s.b.map(|v| v * 2);
        let c = DirectCascade::<1>::new(&[s]).unwrap();
        let mut st = DirectState::default();
        let mut y = 0;
        for _ in 0..50 {
            y = c.process(&mut st, i32::MAX);
        }
        assert!(y >= i32::MAX - 3);
        assert!(st.take_overflow());
        assert!(!st.overflowed());
    }
}
