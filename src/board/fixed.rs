//! The fixed-point compensator: the same cascade as [`crate::board::compensator`], in 32-bit integers,
//! for boards without an FPU and for MHz sample rates.
//!
//! This module owns the per-sample integer arithmetic and nothing else: coefficients are
//! realised, scaled and quantised on the host (`crate::design::quantise`, `unlag invert`), and arrive
//! here as plain integers that are validated once, in [`FixedCascade::new`].
//!
//! # The form: normal (coupled) state-space sections
//!
//! Each second-order section is a 2-state realisation with 32-bit states `x`:
//!
//! ```text
//! x1' = Qt( a11 x1 + a12 x2 + b1 u )        a, b: Q2.30 (i32, 30 fractional bits)
//! x2' = Qt( a21 x1 + a22 x2 + b2 u )
//! y   = Qr( c1 x1  + c2 x2  + d u  )        c, d: i32 with `shift` fractional bits
//! ```
//!
//! accumulated in `i64`. For a complex pole pair `sigma +- j omega` the state matrix is the
//! scaled rotation `[[sigma, -omega], [omega, sigma]]`; for two real poles it is the cascade of
//! two first-order lags `[[p1, 0], [g, p2]]`. Both keep their accuracy where direct forms lose
//! it, poles crowding towards `z = 1` at high sample rates: the pole positions are quantised on
//! a uniform grid in the plane, not through `a1 = -2 r cos(theta)`, `a2 = r^2`.
//!
//! # No limit cycles, no overflow, no panic
//!
//! - `Qt` truncates towards zero (magnitude truncation), so a state component never grows in
//!   magnitude by rounding. With zero input, a rotation section's state norm shrinks by the
//!   pole radius `r < 1` every sample, `|x_k| <= r^k |x_0|`, and a real-pole section's first
//!   state does the same, then its second: every state reaches exactly zero within
//!   `31 ln 2 / -ln r` samples (plus the same for the second real pole), and the output with
//!   it. `Qr` (round to nearest) only touches outputs, which are not fed back.
//! - The host scales each section (its `b` and `c`, `d`) from an L1-norm bound of its impulse
//!   responses, so that no state or output can leave the `i32` range for inputs inside the
//!   ADC's full scale. Should one still do so (an input outside the design's range), it
//!   saturates, never wraps, and [`FixedState::overflowed`] says so until cleared.
//! - Every coefficient's magnitude is at most `2^30` ([`MAX_COEFFICIENT`]), checked once in
//!   [`FixedCascade::new`]: a product of an `i32` state by a coefficient stays below `2^61` and
//!   a sum of three below `2^63`, so the `i64` accumulators cannot overflow.
//!
//! Integer arithmetic is exact, so the host (`unlag compensate --arithmetic fixed`) computes
//! bit for bit what the board computes.
//!
//! # The cheaper form
//!
//! [`direct`] holds the alternative the user can choose (`--fixed-form direct`): direct-form-I
//! sections with first-order error feedback, about a third of the instructions on a
//! Cortex-M4, no overflow for planned coefficients and a flag, but limit cycles of a few codes
//! not excluded and about 90 dB instead of 100 at fs/fn = 1000 (BENCHMARKS.md, "Fixed point:
//! the two forms"). This form stays the default.
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

/// Q2.30, the format of every state-matrix and input-vector coefficient here and of every
/// direct-form coefficient ([`direct`]): `fixed`'s signed 32-bit number with 30 fractional
/// bits, the same bits as the `i32` fields.
pub use ::fixed::types::I2F30;

/// Q1.31, the format of every sample in and out of [`FixedCascade`] and
/// [`direct::DirectCascade`]: `fixed`'s signed 32-bit number with 31 fractional bits, the same
/// bits as the `i32` codes, range `[-1, 1)`.
///
/// The two ends are fractions of different scales. The input is Q1.31 of the ADC's full
/// scale `F` the host planned for (`y = F` is `1.0`, the code `2^31`, one past the range: a
/// reading at `+F` saturates to the largest code, `1 - 2^-31`). The output is Q1.31 of
/// `F * 2^e`, where `e` is the plan's output exponent (`FixedPlan::output_exponent` on the
/// host, [`super::blob::FixedCoefficientSet::output_exponent`] on the board, beside
/// `full_scale`): the host's scaling picks `e` so that the output keeps its headroom, per
/// design, so it is a run-time value and not part of the type.
pub use ::fixed::types::I1F31;

/// Fractional bits of the state matrix `a` and the input vector `b` (Q2.30).
pub const STATE_BITS: u32 = 30;

/// Largest coefficient magnitude accepted (`2^30`): keeps every accumulator inside `i64`.
pub const MAX_COEFFICIENT: i32 = 1 << 30;

/// One second-order section in normal (coupled) state-space form, as integers.
///
/// `#[repr(C)]`: the Cortex-M kernel (module `m4`) reads it at fixed offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(C)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixedSection {
    /// State matrix `[a11, a12, a21, a22]`, Q2.30.
    pub a: [i32; 4],
    /// Input vector `[b1, b2]`, Q2.30.
    pub b: [i32; 2],
    /// Output vector `[c1, c2]`, `shift` fractional bits.
    pub c: [i32; 2],
    /// Direct term, `shift` fractional bits.
    pub d: i32,
    /// Fractional bits of `c` and `d` (1..=62).
    pub shift: u8,
}

impl FixedSection {
    /// The identity section (`y = u`), used for unused capacity.
    pub const IDENTITY: Self = Self {
        a: [0; 4],
        b: [0; 2],
        c: [0; 2],
        d: 1 << 30,
        shift: 30,
    };

    /// A section from its Q2.30 state matrix `a` and input vector `b` as [`I2F30`], and its
    /// output vector `c` and direct term `d` as integers with `shift` fractional bits (their
    /// format is chosen per section by the host's scaling, so it has no type of its own).
    ///
    /// ```
    /// use unlag::board::fixed::{FixedSection, I2F30};
    ///
    /// let q = I2F30::from_num;
    /// let lag = FixedSection::from_q([q(0.9), q(0.0), q(0.0), q(0.0)], [q(0.5), q(0.0)], [1 << 29, 0], 0, 30);
    /// assert_eq!(lag.a, [966_367_642, 0, 0, 0]); // round(0.9 * 2^30)
    /// assert_eq!(lag.state_matrix()[0], q(0.9));
    /// assert_eq!(lag.input_vector()[0].to_num::<f64>(), 0.5);
    /// ```
    #[must_use]
    pub const fn from_q(a: [I2F30; 4], b: [I2F30; 2], c: [i32; 2], d: i32, shift: u8) -> Self {
        let [a11, a12, a21, a22] = a;
        let [b1, b2] = b;
        Self {
            a: [a11.to_bits(), a12.to_bits(), a21.to_bits(), a22.to_bits()],
            b: [b1.to_bits(), b2.to_bits()],
            c,
            d,
            shift,
        }
    }

    /// The state matrix `[a11, a12, a21, a22]` as Q2.30 numbers.
    #[must_use]
    pub const fn state_matrix(&self) -> [I2F30; 4] {
        let [a11, a12, a21, a22] = self.a;
        [
            I2F30::from_bits(a11),
            I2F30::from_bits(a12),
            I2F30::from_bits(a21),
            I2F30::from_bits(a22),
        ]
    }

    /// The input vector `[b1, b2]` as Q2.30 numbers.
    #[must_use]
    pub const fn input_vector(&self) -> [I2F30; 2] {
        let [b1, b2] = self.b;
        [I2F30::from_bits(b1), I2F30::from_bits(b2)]
    }
}

/// Why a set of fixed-point coefficients was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixedError {
    /// More sections than the capacity `N`.
    TooManySections {
        /// Sections given.
        sections: usize,
        /// Capacity.
        capacity: usize,
    },
    /// A coefficient's magnitude exceeds [`MAX_COEFFICIENT`].
    CoefficientTooLarge {
        /// 0-based section.
        index: usize,
    },
    /// `shift` is outside 1..=62.
    BadShift {
        /// 0-based section.
        index: usize,
    },
    /// The state matrix is not of a limit-cycle-free form (a scaled rotation, or lower
    /// triangular), or its poles are not strictly inside the unit circle.
    NotNormalForm {
        /// 0-based section.
        index: usize,
    },
}

impl fmt::Display for FixedError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooManySections { sections, capacity } => write!(
                f,
                "{sections} fixed-point sections exceed the capacity of {capacity}"
            ),
            Self::CoefficientTooLarge { index } => write!(
                f,
                "section {index}: a coefficient exceeds 2^30 in magnitude (accumulator overflow)"
            ),
            Self::BadShift { index } => write!(f, "section {index}: shift outside 1..=62"),
            Self::NotNormalForm { index } => write!(
                f,
                "section {index}: the state matrix is neither a stable scaled rotation nor a \
                 stable lower-triangular pair (limit cycles possible)"
            ),
        }
    }
}

impl core::error::Error for FixedError {}

/// Validated fixed-point coefficients of a cascade of up to `N` sections.
///
/// ```
/// use unlag::board::fixed::{FixedCascade, FixedError, FixedSection, FixedState};
///
/// const HALF: i32 = 1 << 29; // 0.5 in Q2.30
/// // A lag x' = Qt(0.5 x + 0.5 u), y = x (c in Q.30), then an exact halving y = Qr(0.5 u).
/// let lag = FixedSection { a: [HALF, 0, 0, 0], b: [HALF, 0], c: [1 << 30, 0], d: 0, shift: 30 };
/// let halve = FixedSection { d: HALF, ..FixedSection::IDENTITY };
/// let c = FixedCascade::<3>::new(&[lag, halve])?; // the third section is an identity
/// let mut state = FixedState::default();
/// let y: Vec<i32> = (0..4).map(|_| c.process(&mut state, 1000)).collect();
/// assert_eq!(y, [0, 250, 375, 438]); // 437.5 rounds half up
/// assert!(!state.overflowed());
///
/// // Started in equilibrium with a steady reading, there is no start-up transient.
/// let mut state = c.equilibrium(1000);
/// assert_eq!(c.process(&mut state, 1000), 500);
///
/// // A pole on the unit circle, or a shift out of 1..=62, is refused.
/// let integrator = FixedSection { a: [1 << 30, 0, 0, 0], ..lag };
/// assert_eq!(
///     FixedCascade::<3>::new(&[lag, integrator]),
///     Err(FixedError::NotNormalForm { index: 1 })
/// );
/// let bad_shift = FixedSection { shift: 0, ..lag };
/// assert_eq!(FixedCascade::<3>::new(&[bad_shift]), Err(FixedError::BadShift { index: 0 }));
/// # Ok::<(), FixedError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FixedCascade<const N: usize> {
    sections: [FixedSection; N],
}

/// The states of one channel, and the overflow flag.
///
/// `#[repr(C)]`: the Cortex-M kernel reads and writes the states `x` in place.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct FixedState<const N: usize> {
    x: [[i32; 2]; N],
    overflow: bool,
}

impl<const N: usize> Default for FixedState<N> {
    fn default() -> Self {
        Self {
            x: [[0; 2]; N],
            overflow: false,
        }
    }
}

impl<const N: usize> FixedState<N> {
    /// `true` when a state or output saturated since the flag was last cleared.
    #[must_use]
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Reads and clears the overflow flag.
    pub fn take_overflow(&mut self) -> bool {
        core::mem::replace(&mut self.overflow, false)
    }

    /// `true` when every state is exactly zero (the cascade is at rest).
    #[must_use]
    pub fn is_zero(&self) -> bool {
        self.x.iter().flatten().all(|&v| v == 0)
    }
}

/// `acc >> bits`, rounded towards zero, saturated to `i32`; `true` when it saturated.
#[inline(always)]
fn truncate(acc: i64, bits: u32) -> (i32, bool) {
    // Arithmetic shift rounds towards minus infinity; adding 2^bits - 1 to a negative value
    // first rounds towards zero. `bits` is at most 62 and `acc` below 2^63 - 2^62 in
    // magnitude (see the module docs), so nothing here can overflow.
    let bias = (acc >> 63) & ((1i64 << bits).wrapping_sub(1));
    saturate(acc.wrapping_add(bias) >> bits)
}

/// `acc >> bits`, rounded to nearest (half up), saturated to `i32`. Computed as
/// `((acc >> (bits - 1)) + 1) >> 1`, which equals `(acc + 2^(bits-1)) >> bits` exactly and needs
/// one variable 64-bit shift instead of two.
#[inline(always)]
fn round(acc: i64, bits: u32) -> (i32, bool) {
    saturate((acc >> bits.wrapping_sub(1)).wrapping_add(1) >> 1)
}

/// Saturates to `i32`: the value fits when its high word is the sign of its low word.
#[inline(always)]
fn saturate(v: i64) -> (i32, bool) {
    // Truncation to the low word is the point here; it is checked against `v` at once.
    #[allow(clippy::cast_possible_truncation)]
    let lo = v as i32;
    if i64::from(lo) == v {
        (lo, false)
    } else {
        (if v < 0 { i32::MIN } else { i32::MAX }, true)
    }
}

#[inline(always)]
fn mac3(c: [i32; 3], x: [i32; 3]) -> i64 {
    let [c0, c1, c2] = c;
    let [x0, x1, x2] = x;
    // Each product is below 2^61 in magnitude, their sum below 2^63: wrapping never wraps.
    (i64::from(c0).wrapping_mul(i64::from(x0)))
        .wrapping_add(i64::from(c1).wrapping_mul(i64::from(x1)))
        .wrapping_add(i64::from(c2).wrapping_mul(i64::from(x2)))
}

impl<const N: usize> FixedCascade<N> {
    /// Validates the sections: count, coefficient range, shifts, and the limit-cycle-free form
    /// of each state matrix.
    ///
    /// # Errors
    /// A [`FixedError`] naming the section.
    pub fn new(sections: &[FixedSection]) -> Result<Self, FixedError> {
        if sections.len() > N {
            return Err(FixedError::TooManySections {
                sections: sections.len(),
                capacity: N,
            });
        }
        let mut out = [FixedSection::IDENTITY; N];
        for (index, (dst, s)) in out.iter_mut().zip(sections).enumerate() {
            let coefficients = s.a.iter().chain(&s.b).chain(&s.c).chain([&s.d]);
            if coefficients
                .map(|v| v.unsigned_abs())
                .any(|v| v > MAX_COEFFICIENT.unsigned_abs())
            {
                return Err(FixedError::CoefficientTooLarge { index });
            }
            if !(1..=62).contains(&s.shift) {
                return Err(FixedError::BadShift { index });
            }
            if !normal_form(s.a) {
                return Err(FixedError::NotNormalForm { index });
            }
            *dst = *s;
        }
        Ok(Self { sections: out })
    }

    /// One ADC sample (Q1.31 of the design's full scale) through the cascade; the output is
    /// the reconstructed reference in the design's output format. Panic-free, allocation-free.
    ///
    /// On the Cortex-M3, M4 and M7 targets (`thumbv7m-none-eabi`, `thumbv7em-none-eabi`,
    /// `thumbv7em-none-eabihf`) this runs a hand-written Thumb-2 kernel (SMULL/SMLAL, SSAT;
    /// module `m4`, see [`uses_kernel`]), elsewhere
    /// [`Self::process_portable`]: the same integer arithmetic, the same bits
    /// (`host-tests/firmware.rs` checks it in QEMU).
    #[inline]
    pub fn process(&self, state: &mut FixedState<N>, input: i32) -> i32 {
        #[cfg(unlag_armv7m)]
        {
            m4::process(self, state, input)
        }
        #[cfg(not(unlag_armv7m))]
        {
            self.process_portable(state, input)
        }
    }

    /// [`Self::process`] with the sample formats as types: the input is Q1.31 of the full
    /// scale `F`, the output Q1.31 of `F * 2^e` with the plan's output exponent `e` (see
    /// [`I1F31`]). The same bits as [`Self::process`] (`to_bits` in, `from_bits` out), at no
    /// cost; the block functions stay on `i32` codes, the words an ADC's DMA writes.
    ///
    /// ```
    /// use unlag::board::fixed::{FixedCascade, FixedSection, FixedState, I1F31};
    ///
    /// // The host's plan for F = 4000 Pa with output exponent e = 1: a section that halves the
    /// // codes (y = Qr(0.5 u)) while the output's unit doubles, one bit of headroom at gain 1.
    /// let (full_scale, output_exponent) = (4000.0, 1);
    /// let halve = FixedSection { d: 1 << 29, ..FixedSection::IDENTITY };
    /// let c = FixedCascade::<1>::new(&[halve])?;
    /// let mut state = FixedState::default();
    ///
    /// let reading = 1000.0; // Pa
    /// let u = I1F31::from_num(reading / full_scale); // 0.25 of F, the code 2^29
    /// let y = c.process_q(&mut state, u);
    /// assert_eq!(y.to_num::<f64>(), 0.125); // of F * 2^e
    /// assert_eq!(y.to_num::<f64>() * full_scale * 2f64.powi(output_exponent), 1000.0); // Pa
    /// assert_eq!(y.to_bits(), c.process(&mut state, u.to_bits())); // the same bits as i32
    /// # Ok::<(), unlag::board::fixed::FixedError>(())
    /// ```
    #[inline]
    pub fn process_q(&self, state: &mut FixedState<N>, input: I1F31) -> I1F31 {
        I1F31::from_bits(self.process(state, input.to_bits()))
    }

    /// [`Self::process`] in portable Rust, on every target: the reference the Cortex-M
    /// kernel is checked against.
    #[inline]
    pub fn process_portable(&self, state: &mut FixedState<N>, input: i32) -> i32 {
        let mut v = input;
        let mut overflow = false;
        for (s, x) in self.sections.iter().zip(state.x.iter_mut()) {
            let [x1, x2] = *x;
            let [a11, a12, a21, a22] = s.a;
            let [b1, b2] = s.b;
            let [c1, c2] = s.c;
            let (n1, o1) = truncate(mac3([a11, a12, b1], [x1, x2, v]), STATE_BITS);
            let (n2, o2) = truncate(mac3([a21, a22, b2], [x1, x2, v]), STATE_BITS);
            let (y, o3) = round(mac3([c1, c2, s.d], [x1, x2, v]), u32::from(s.shift));
            *x = [n1, n2];
            overflow |= o1 | o2 | o3;
            v = y;
        }
        state.overflow |= overflow;
        v
    }

    /// Processes a block in place, sample by sample (the same arithmetic as [`Self::process`]).
    #[inline]
    pub fn process_in_place(&self, state: &mut FixedState<N>, buf: &mut [i32]) {
        for v in buf.iter_mut() {
            *v = self.process(state, *v);
        }
    }

    /// The state after the constant input `input` forever (no start-up transient), computed
    /// in floating point from the integer coefficients and rounded; used to start a channel on
    /// a probe that already reads a steady pressure.
    #[must_use]
    pub fn equilibrium(&self, input: i32) -> FixedState<N> {
        let mut state = FixedState::default();
        let q = 1.0 / f64::from(MAX_COEFFICIENT);
        let mut v = f64::from(input);
        for (s, x) in self.sections.iter().zip(state.x.iter_mut()) {
            let [a11, a12, a21, a22] = s.a.map(|c| f64::from(c) * q);
            let [b1, b2] = s.b.map(|c| f64::from(c) * q);
            // (I - A) x = b v; det(I - A) > 0 for the accepted (stable) forms.
            let (m11, m12, m21, m22) = (1.0 - a11, -a12, -a21, 1.0 - a22);
            let det = m11 * m22 - m12 * m21;
            let (r1, r2) = (b1 * v, b2 * v);
            let x1 = (r1 * m22 - m12 * r2) / det;
            let x2 = (m11 * r2 - m21 * r1) / det;
            let scale = libm::exp2(-f64::from(s.shift));
            let [c1, c2] = s.c.map(f64::from);
            let y = (c1 * x1 + c2 * x2 + f64::from(s.d) * v) * scale;
            // `as` saturates and maps NaN to 0: no panic.
            *x = [libm::round(x1) as i32, libm::round(x2) as i32];
            v = f64::from(libm::round(y) as i32);
        }
        state
    }

    /// [`Self::equilibrium`] for an input in Q1.31 of the full scale (see [`I1F31`]).
    #[must_use]
    #[inline]
    pub fn equilibrium_q(&self, input: I1F31) -> FixedState<N> {
        self.equilibrium(input.to_bits())
    }

    /// The sections, identities included.
    #[must_use]
    pub fn sections(&self) -> &[FixedSection; N] {
        &self.sections
    }
}

/// The Cortex-M kernel of the fixed-point cascade (ARMv7-M: Cortex-M3, M4, M7; see `build.rs`
/// for `unlag_armv7m`).
#[cfg(unlag_armv7m)]
mod m4;

/// `true` when this build runs [`FixedCascade::process`] through the Cortex-M kernel (on the
/// ARMv7-M and ARMv7E-M targets `thumbv7m-none-eabi`, Cortex-M3, and
/// `thumbv7em-none-eabi(hf)`, Cortex-M4 and M7, with or without an FPU), `false` when it runs
/// [`FixedCascade::process_portable`]. Both compute the same bits.
///
/// ```
/// # #[cfg(not(target_arch = "arm"))]
/// assert!(!unlag::board::fixed::uses_kernel());
/// ```
#[must_use]
pub const fn uses_kernel() -> bool {
    cfg!(unlag_armv7m)
}

pub mod direct;
pub mod input;

/// A scaled rotation `[[s, -w], [w, s]]` with `s^2 + w^2 < 1`, or lower triangular
/// `[[p1, 0], [g, p2]]` with `|p1|, |p2| < 1`: the forms for which magnitude truncation
/// provably leaves no zero-input limit cycle.
fn normal_form(a: [i32; 4]) -> bool {
    let [a11, a12, a21, a22] = a;
    let one = 1i64 << STATE_BITS;
    let rotation = a11 == a22 && i64::from(a12) == i64::from(a21).wrapping_neg() && {
        // s^2 + w^2 < 2^60, in i64 (each square below 2^60).
        let s = i64::from(a11);
        let w = i64::from(a21);
        s.wrapping_mul(s).wrapping_add(w.wrapping_mul(w)) < one.wrapping_mul(one)
    };
    let triangular = a12 == 0 && i64::from(a11).abs() < one && i64::from(a22).abs() < one;
    rotation || triangular
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn q30(v: f64) -> i32 {
        (v * (1u64 << 30) as f64).round() as i32
    }

    proptest! {
        /// The Q2.30 views are the integer fields, bit for bit, both ways.
        #[test]
        fn q_views_round_trip(a in any::<[i32; 4]>(), b in any::<[i32; 2]>(), c in any::<[i32; 2]>(), d: i32, shift in 1u8..=62) {
            let s = FixedSection { a, b, c, d, shift };
            prop_assert_eq!(FixedSection::from_q(s.state_matrix(), s.input_vector(), c, d, shift), s);
            prop_assert_eq!(s.state_matrix().map(|q| q.to_num::<f64>()), a.map(|v| f64::from(v) / f64::from(1u32 << 30)));
            prop_assert_eq!(s.input_vector().map(I2F30::to_bits), b);
        }

        /// The same for the direct form.
        #[test]
        fn direct_q_views_round_trip(b in any::<[i32; 3]>(), neg_a in any::<[i32; 2]>()) {
            let s = direct::DirectSection { b, neg_a };
            prop_assert_eq!(direct::DirectSection::from_q(s.numerator(), s.negated_denominator()), s);
            prop_assert_eq!(s.numerator().map(|q| q.to_num::<f64>()), b.map(|v| f64::from(v) / f64::from(1u32 << 30)));
        }
    }

    fn rotation(r: f64, theta: f64) -> FixedSection {
        let (s, w) = (r * theta.cos(), r * theta.sin());
        FixedSection {
            a: [q30(s), q30(-w), q30(w), q30(s)],
            b: [q30(0.01), 0],
            c: [q30(0.5), q30(0.25)],
            d: q30(0.5),
            shift: 30,
        }
    }

    /// Deterministic codes over the whole `i32` range, the extremes included.
    fn codes(n: usize) -> impl Iterator<Item = i32> {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        [i32::MIN, i32::MAX, 0, -1]
            .into_iter()
            .chain((0..n).map(move |_| {
                seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                (seed >> 32) as i32 >> (seed % 4) // full scale and quieter stretches
            }))
    }

    #[test]
    fn typed_samples_are_the_i32_path_bit_for_bit() {
        let c = FixedCascade::<3>::new(&[rotation(0.999, 0.01), rotation(0.9, 2.0)]).unwrap();
        let start = I1F31::from_num(0.25);
        let (mut typed, mut plain) = (c.equilibrium_q(start), c.equilibrium(start.to_bits()));
        assert_eq!(typed, plain);
        for u in codes(400) {
            let y = c.process_q(&mut typed, I1F31::from_bits(u));
            assert_eq!(y.to_bits(), c.process(&mut plain, u));
            assert_eq!(typed, plain);
        }
    }

    #[test]
    fn direct_typed_samples_are_the_i32_path_bit_for_bit() {
        let s = direct::DirectSection {
            b: [q30(0.25), q30(0.5), q30(0.25)].map(|v| v / 64),
            neg_a: [q30(1.9), q30(-0.95)],
        };
        let c = direct::DirectCascade::<3>::new(&[s, s]).unwrap();
        let start = I1F31::from_num(-0.5);
        let (mut typed, mut plain) = (c.equilibrium_q(start), c.equilibrium(start.to_bits()));
        assert_eq!(typed, plain);
        for u in codes(400) {
            let y = c.process_q(&mut typed, I1F31::from_bits(u));
            assert_eq!(y.to_bits(), c.process(&mut plain, u));
            assert_eq!(typed, plain);
        }
    }

    #[test]
    fn truncation_rounds_towards_zero_and_saturates() {
        assert_eq!(truncate(5 << 30 | 7, 30), (5, false));
        assert_eq!(truncate(-(5 << 30 | 7), 30), (-5, false));
        assert_eq!(truncate(-1, 30), (0, false));
        assert_eq!(truncate(1 << 62, 30), (i32::MAX, true));
        assert_eq!(truncate(-(1 << 62), 30), (i32::MIN, true));
        assert_eq!(round(3 << 29, 30), (2, false)); // 1.5 -> 2
        assert_eq!(round(-(1 << 28), 30), (0, false)); // -0.25 -> 0
    }

    #[test]
    fn refuses_what_it_cannot_run_safely() {
        let ok = rotation(0.99, 0.1);
        assert!(FixedCascade::<1>::new(&[ok, ok]).is_err());
        let mut big = ok;
        big.d = i32::MAX;
        assert_eq!(
            FixedCascade::<2>::new(&[big]),
            Err(FixedError::CoefficientTooLarge { index: 0 })
        );
        let mut shift = ok;
        shift.shift = 0;
        assert_eq!(
            FixedCascade::<2>::new(&[ok, shift]),
            Err(FixedError::BadShift { index: 1 })
        );
        // A direct-form companion matrix is not accepted: it can sit in a limit cycle.
        let mut companion = ok;
        companion.a = [q30(0.9), q30(-0.5), q30(1.0) - 1, 0];
        assert_eq!(
            FixedCascade::<2>::new(&[companion]),
            Err(FixedError::NotNormalForm { index: 0 })
        );
        // A rotation outside the unit circle is refused.
        let mut unit = ok;
        unit.a = [q30(0.61), q30(-0.8), q30(0.8), q30(0.61)];
        assert!(FixedCascade::<2>::new(&[unit]).is_err());
    }

    #[test]
    fn zero_input_reaches_exactly_zero() {
        let c = FixedCascade::<2>::new(&[rotation(0.999, 0.01), rotation(0.9, 2.0)]).unwrap();
        let mut st = FixedState::default();
        for _ in 0..200 {
            c.process(&mut st, i32::MAX / 2);
        }
        assert!(!st.is_zero());
        // Bound: 31 ln 2 / -ln 0.999 = 21,476 samples for the slow section.
        let mut n = 0;
        while !st.is_zero() && n < 30_000 {
            c.process(&mut st, 0);
            n += 1;
        }
        assert!(st.is_zero(), "still ringing after {n} samples");
        assert_eq!(c.process(&mut st, 0), 0);
        assert!(!st.overflowed());
    }

    #[test]
    fn saturates_and_flags_instead_of_wrapping() {
        let mut s = rotation(0.5, 0.3);
        s.d = MAX_COEFFICIENT; // gain 1 ...
        s.shift = 28; // ... times 4
        let c = FixedCascade::<1>::new(&[s]).unwrap();
        let mut st = FixedState::default();
        assert_eq!(c.process(&mut st, i32::MAX), i32::MAX);
        assert!(st.take_overflow());
        assert!(!st.overflowed());
        assert_eq!(c.process(&mut st, i32::MIN), i32::MIN);
        assert!(st.take_overflow());
    }
}
