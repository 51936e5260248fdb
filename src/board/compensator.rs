//! The per-sample inverse compensator: the only code that runs for every ADC sample.
//!
//! This module owns the streaming reconstruction of the reference pressure from the probe's
//! output, the paper's eq. 7, in `no_std` with no allocation and no panic path. The same code
//! runs on the host (`unlag compensate`) and on the board.
//!
//! # Sign convention (stated once, used everywhere)
//!
//! The probe model is
//!
//! ```text
//! y[k] = sum_{i=0..m} b[i] u[k-i-d]  -  sum_{i=1..m} a[i] y[k-i]
//!
//!         b0 z^-d + b1 z^-(1+d) + ... + bm z^-(m+d)
//! H(z) = -------------------------------------------        (paper eq. 2)
//!              1 + a1 z^-1 + ... + am z^-m
//! ```
//!
//! with `a = [a1..am]` (no leading one) and `b = [b0..bm]`. Solving for the input gives the
//! inverse, which reconstructs the reference `d` samples late:
//!
//! ```text
//! u_hat[k-d] = ( y[k] + sum_{i=1..m} a[i] y[k-i]  -  sum_{i=1..m} b[i] u_hat[k-d-i] ) / b0
//! ```
//!
//! The division by `b0` is done once, when the coefficients are built; the per-sample path only
//! multiplies and adds. Coefficients live apart from state ([`InverseCoefficients`] and
//! [`InverseState`]) so one validated set can serve several channels and be swapped between
//! samples; [`Compensator`] bundles the two for the common one-channel case.
//!
//! A board that measures the gas temperature runs a table of cascades, one per temperature,
//! through [`bank::TemperatureBank`] (the `temperature` effect of `unlag::effects` (host)).
//!
//! # Capacity
//!
//! The model order capacity is the const generic `M`; a model of lower order is zero-padded.
//! A model of higher order is refused when the coefficients are built.
//!
//! # Example
//!
//! ```
//! use unlag::board::compensator::Compensator;
//! // y[k] = 0.5 u[k-2] + 0.5 y[k-1]: a first-order lag with a delay of two samples.
//! let mut c = Compensator::<f32, 2>::new(&[0.5], &[-0.5], 0.0).unwrap();
//! let u = [0.0f32, 1.0, 1.0, 1.0, 1.0, 1.0];
//! let mut y_prev = 0.0f32;
//! let mut out = [0.0f32; 6];
//! for (k, o) in out.iter_mut().enumerate() {
//!     let u_in = if k >= 2 { u[k - 2] } else { 0.0 };
//!     let y = 0.5 * u_in + 0.5 * y_prev;
//!     y_prev = y;
//!     *o = c.push(y);
//! }
//! // The output is the input, two samples late.
//! assert_eq!(out, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
//! ```
#![deny(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::unreachable,
    clippy::todo,
    clippy::unimplemented
)]

use core::fmt;
use core::ops::{Add, Mul, Sub};

/// The sample types the compensator runs in: `f32` on the board, `f64` on the host.
pub trait Sample:
    Copy + PartialOrd + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + private::Sealed
{
    /// Additive identity.
    const ZERO: Self;
    /// Multiplicative identity.
    const ONE: Self;
    /// Converts from the host's `f64` (coefficients are designed in f64).
    fn from_f64(x: f64) -> Self;
    /// Widens to `f64`.
    fn to_f64(self) -> f64;
}

impl Sample for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    #[allow(clippy::cast_possible_truncation)]
    fn from_f64(x: f64) -> Self {
        x as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl Sample for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn from_f64(x: f64) -> Self {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
}

mod private {
    use super::{CascadeCoefficients, CascadeState};

    /// Seals [`super::Sample`], and lets a sample type route the cascade to a hand-written
    /// kernel where it has one (`f32` on Cortex-M with an FPU, see `m4`). `None`: no kernel,
    /// run the portable code.
    pub trait Sealed: Sized {
        #[inline(always)]
        fn kernel_process<const N: usize>(
            _c: &CascadeCoefficients<Self, N>,
            _s: &mut CascadeState<Self, N>,
            _x: Self,
        ) -> Option<Self> {
            None
        }
        /// The value, kept a scalar in a register: the identity, which on x86-64 stops the
        /// compiler from packing the `f32` sections' outputs into a vector (see `f32`'s).
        #[inline(always)]
        fn scalar(self) -> Self {
            self
        }
        /// `true` when the whole block was processed.
        #[inline(always)]
        fn kernel_process_in_place<const N: usize>(
            _c: &CascadeCoefficients<Self, N>,
            _s: &mut CascadeState<Self, N>,
            _buf: &mut [Self],
        ) -> bool {
            false
        }
    }

    #[cfg(not(any(all(unlag_armv7m, target_abi = "eabihf"), target_arch = "x86_64")))]
    impl Sealed for f32 {}

    /// `Sealed` for a float on x86-64, where `scalar` is a value barrier. LLVM's SLP
    /// vectoriser packs the sections of a sample into one SSE vector and puts shuffles on the
    /// loop-carried chain from one sample to the next (`f32` ran at 0.7x the same code in
    /// `f64`). An empty `asm!` that claims to rewrite the value in its XMM register keeps every
    /// section scalar; it emits no instruction and cannot change a bit.
    #[cfg(target_arch = "x86_64")]
    macro_rules! sealed_with_value_barrier {
        ($t:ty) => {
            #[allow(unsafe_code)] // One empty asm! block: no instruction runs.
            impl Sealed for $t {
                #[inline(always)]
                fn scalar(self) -> Self {
                    let mut x = self;
                    // SAFETY: the template is a comment: no instruction runs; `x` stays in its
                    // register unchanged, and no memory, stack or flag is touched.
                    unsafe {
                        core::arch::asm!(
                            "/* {0} */",
                            inout(xmm_reg) x,
                            options(pure, nomem, nostack, preserves_flags)
                        );
                    }
                    x
                }
            }
        };
    }
    #[cfg(target_arch = "x86_64")]
    sealed_with_value_barrier!(f32);
    #[cfg(target_arch = "x86_64")]
    sealed_with_value_barrier!(f64);
    #[cfg(all(unlag_armv7m, target_abi = "eabihf"))]
    impl Sealed for f32 {
        #[inline(always)]
        fn kernel_process<const N: usize>(
            c: &CascadeCoefficients<f32, N>,
            s: &mut CascadeState<f32, N>,
            x: f32,
        ) -> Option<f32> {
            super::m4::process(c, s, x)
        }
        #[inline(always)]
        fn kernel_process_in_place<const N: usize>(
            c: &CascadeCoefficients<f32, N>,
            s: &mut CascadeState<f32, N>,
            buf: &mut [f32],
        ) -> bool {
            super::m4::process_in_place(c, s, buf)
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    impl Sealed for f64 {}
}

/// The Cortex-M kernels of the `f32` cascade (Thumb-2 + single-precision VFP, hard-float ABI:
/// `thumbv7em-none-eabihf`; see `build.rs` for `unlag_armv7m`).
#[cfg(all(unlag_armv7m, target_abi = "eabihf"))]
mod m4;

/// The board's share of the `temperature` effect: coefficient sets by gas temperature.
pub mod bank;
pub use bank::{BankChannel, BankError, TemperatureBank};

/// The direct inverse of the paper (eq. 7): its coefficients, state and per-sample step.
mod direct;
pub use direct::{Compensator, InverseCoefficients, InverseState};

/// The nonlinear-damping correction added to the cascade's output.
mod nonlinear;
pub use nonlinear::{NonlinearDampingCoefficients, NonlinearDampingState};

/// `true` when this build runs the `f32` cascade of `N` sections through the hand-scheduled
/// Cortex-M kernels (`N` = 1..=4 on `thumbv7em-none-eabihf`: Cortex-M4F and M7 with the FPU
/// and the hard-float calling convention), `false` when it runs the portable Rust code (the
/// host, `thumbv7m-none-eabi`, `thumbv7em-none-eabi`, any other target). Both compute the
/// same bits.
///
/// ```
/// use unlag::board::compensator::f32_cascade_uses_kernel;
///
/// // There are kernels for 1 to 4 sections only, and none on the host.
/// assert!(!f32_cascade_uses_kernel(5));
/// assert!(!f32_cascade_uses_kernel(0));
/// # #[cfg(not(target_arch = "arm"))]
/// assert!(!f32_cascade_uses_kernel(2));
/// ```
#[must_use]
pub const fn f32_cascade_uses_kernel(sections: usize) -> bool {
    cfg!(all(unlag_armv7m, target_abi = "eabihf")) && sections >= 1 && sections <= 4
}

/// Why a coefficient set was refused. Checked once, when the coefficients are built; a built
/// [`InverseCoefficients`] is valid and the per-sample path cannot fail.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum InverseError {
    /// `a` has more than `M` entries or `b` more than `M + 1`.
    OrderTooHigh {
        /// The model's order.
        order: usize,
        /// The compensator's capacity `M`.
        capacity: usize,
    },
    /// `b` is empty: the model has no numerator.
    EmptyNumerator,
    /// A coefficient is NaN or infinite.
    NonFinite,
    /// `b0` is zero (or so small that `1/b0` overflows): the inverse would divide by it.
    /// Fold leading zeros of `b` into the delay instead.
    LeadingZero,
    /// `B(z)` has a zero on or outside the unit circle, so the inverse `A(z)/B(z)` is unstable.
    /// Found by the Schur-Cohn test; `reflection` is the first reflection coefficient with
    /// magnitude of at least one.
    UnstableInverse {
        /// The offending reflection coefficient (|k| >= 1 means a zero on or outside |z| = 1).
        reflection: f64,
    },
    /// A cascade has more sections than the capacity `N`.
    TooManySections {
        /// Sections given.
        sections: usize,
        /// The cascade's capacity `N`.
        capacity: usize,
    },
    /// A second-order section's poles are not inside the unit circle by the required margin.
    UnstableSection {
        /// 0-based index of the section.
        index: usize,
        /// Largest pole magnitude of that section.
        radius: f64,
    },
}

impl fmt::Display for InverseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::OrderTooHigh { order, capacity } => write!(
                f,
                "model order {order} exceeds the compensator capacity {capacity}"
            ),
            Self::EmptyNumerator => write!(f, "the model has no numerator coefficients b"),
            Self::NonFinite => write!(f, "a model coefficient is NaN or infinite"),
            Self::LeadingZero => write!(
                f,
                "b0 is zero: the direct inverse would divide by it (fold leading zeros into the delay)"
            ),
            Self::UnstableInverse { reflection } => write!(
                f,
                "B(z) has a zero on or outside the unit circle (Schur-Cohn reflection coefficient {reflection:.6}): the direct inverse is unstable"
            ),
            Self::TooManySections { sections, capacity } => write!(
                f,
                "{sections} sections exceed the cascade capacity {capacity}"
            ),
            Self::UnstableSection { index, radius } => write!(
                f,
                "section {index} has a pole of magnitude {radius:.6}, not inside the unit circle by the margin {MIN_POLE_MARGIN}"
            ),
        }
    }
}

impl core::error::Error for InverseError {}

/// Largest order the Schur-Cohn test handles without allocation.
pub const MAX_TEST_ORDER: usize = 32;

/// Schur-Cohn (step-down) test: are all zeros of `p[0] + p[1] z^-1 + ... + p[n] z^-n`
/// strictly inside the unit circle?
///
/// Returns `Ok(())` when they are, or the first reflection coefficient of magnitude `>= 1`.
/// Runs in `O(n^2)` with no allocation, so a board can check a coefficient set it received.
/// Polynomials longer than [`MAX_TEST_ORDER`]` + 1` are refused as unstable (reflection `inf`).
///
/// # Errors
/// The offending reflection coefficient, when a zero lies on or outside `|z| = 1`.
pub fn schur_stable(p: &[f64]) -> Result<(), f64> {
    let mut buf = [0.0f64; MAX_TEST_ORDER + 1];
    let mut tmp = [0.0f64; MAX_TEST_ORDER + 1];
    if p.len() > buf.len() {
        return Err(f64::INFINITY);
    }
    let mut n = 0usize;
    for (dst, src) in buf.iter_mut().zip(p) {
        *dst = *src;
        n += 1;
    }
    // Drop trailing zeros (they are zeros at z = 0, which are inside).
    while n > 1 && buf.get(n - 1).copied() == Some(0.0) {
        n -= 1;
    }
    while n > 1 {
        let lead = buf.first().copied().unwrap_or(0.0);
        let last = buf.get(n - 1).copied().unwrap_or(0.0);
        if lead == 0.0 || !lead.is_finite() {
            return Err(f64::INFINITY);
        }
        let k = last / lead;
        if !k.is_finite() || k.abs() >= 1.0 {
            return Err(k);
        }
        // p_new[i] = (p[i] - k p[n-1-i]) / (1 - k^2), i = 0..n-2
        let scale = 1.0 - k * k;
        for (i, t) in tmp.iter_mut().enumerate().take(n - 1) {
            let pi = buf.get(i).copied().unwrap_or(0.0);
            let pr = buf.get(n - 1 - i).copied().unwrap_or(0.0);
            *t = (pi - k * pr) / scale;
        }
        for (dst, src) in buf.iter_mut().zip(tmp.iter()).take(n - 1) {
            *dst = *src;
        }
        n -= 1;
    }
    Ok(())
}

/// Smallest distance from the unit circle a cascade's poles must keep (in `|z|`).
pub const MIN_POLE_MARGIN: f64 = 1e-4;

/// One second-order section in the crate's sign convention:
///
/// ```text
///        b0 + b1 z^-1 + b2 z^-2
/// H(z) = ----------------------      y[k] = b0 x[k] + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]
///         1 + a1 z^-1 + a2 z^-2
/// ```
///
/// A first-order section has `b2 = a2 = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad<T> {
    /// `[b0, b1, b2]`.
    pub b: [T; 3],
    /// `[a1, a2]` (no leading one).
    pub a: [T; 2],
}

impl<T: Sample> Biquad<T> {
    /// The section that passes its input unchanged.
    pub const IDENTITY: Self = Self {
        b: [T::ONE, T::ZERO, T::ZERO],
        a: [T::ZERO, T::ZERO],
    };
}

/// Largest pole magnitude of `1 + a1 z^-1 + a2 z^-2` (complex pair or two real poles).
#[must_use]
pub fn section_pole_radius(a1: f64, a2: f64) -> f64 {
    let disc = a1 * a1 - 4.0 * a2;
    if disc < 0.0 {
        // Complex pair: |p|^2 = a2.
        libm::sqrt(a2.abs())
    } else {
        let r = libm::sqrt(disc);
        let p1 = (-a1 + r) / 2.0;
        let p2 = (-a1 - r) / 2.0;
        p1.abs().max(p2.abs())
    }
}

/// Validated coefficients of a cascade of second-order sections with an input gain: the
/// stable, band-limited compensator designed on the host (`unlag invert`), stored as sections
/// because a single high-order polynomial loses its accuracy in `f32` and fixed point.
///
/// Each section runs in transposed direct form II (two states per section), evaluated in this
/// order (each step a multiply-accumulate onto the running sum):
///
/// ```text
/// y  = s1 + b0 x
/// s1 = (s2 + b1 x) - a1 y
/// s2 = b2 x - a2 y
/// ```
///
/// The input gain is folded into the first section's numerator when the coefficients are
/// built, so a sample costs 5 multiplies per section and nothing else. `N` is the capacity in
/// sections; unused sections are identities.
///
/// Cost on a Cortex-M4F: instructions counted in QEMU, see BENCHMARKS.md "Board (Cortex-M4,
/// QEMU)".
///
/// On Cortex-M4F and M7 with the hard-float calling convention (`thumbv7em-none-eabihf`) an
/// `f32` cascade of 1 to 4 sections runs through hand-scheduled Thumb-2 kernels
/// (module `m4`: one VLDM for all coefficients, VMLA/VMLS, no stack frame; in a block the
/// coefficients and states stay in registers): 29 instructions per call (the caller's loop
/// included) and 12.7 per sample in a block for two sections. VMLA and VMLS round the
/// product before adding, like the portable code, so the results are the same bits (proven
/// in QEMU by `host-tests/firmware.rs`); see [`f32_cascade_uses_kernel`].
///
/// Memory layout (`#[repr(C)]`, read by the kernels): per section `[b0, b1, a1, a2]`, then
/// `b2` of every section, contiguous.
///
/// ```
/// use unlag::board::compensator::{CascadeCoefficients, CascadeState, InverseError};
///
/// // 0.5 / (1 - 0.5 z^-1): the gain 0.5 and one section [b0, b1, b2, a1, a2], a DC gain of
/// // one. Room for two sections: the second stays an identity.
/// let c = CascadeCoefficients::<f32, 2>::new(0.5, &[[1.0, 0.0, 0.0, -0.5, 0.0]])?;
/// let mut state = CascadeState::default();
/// let step = [1.0f32; 4].map(|x| c.process(&mut state, x));
/// assert_eq!(step, [0.5, 0.75, 0.875, 0.9375]);
///
/// // A block gives the same bits as one call per sample.
/// let mut state = CascadeState::default();
/// let mut buf = [1.0f32; 4];
/// c.process_in_place(&mut state, &mut buf);
/// assert_eq!(buf, step);
///
/// // Started in equilibrium with a steady reading, there is no start-up transient.
/// let mut state = c.equilibrium(3.0);
/// assert_eq!(c.process(&mut state, 3.0), 3.0);
///
/// // A pole on the unit circle is refused when the coefficients are built.
/// let integrator = [1.0, 0.0, 0.0, -1.0, 0.0];
/// assert!(matches!(
///     CascadeCoefficients::<f32, 2>::new(1.0, &[integrator]),
///     Err(InverseError::UnstableSection { index: 0, .. })
/// ));
/// # Ok::<(), InverseError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct CascadeCoefficients<T, const N: usize> {
    /// `[b0, b1, a1, a2]` of each section.
    head: [[T; 4]; N],
    /// `b2` of each section (right after `head`: one contiguous block of `5 N` values).
    b2: [T; N],
    gain: T,
    /// DC gain of each section, for starting in equilibrium.
    dc: [T; N],
}

/// The states of one cascade channel, `s1` and `s2` of each section.
///
/// Memory layout (`#[repr(C)]`, read and written by the Cortex-M kernels): `s2` of every
/// section, then `s1` of every section.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct CascadeState<T, const N: usize> {
    s2: [T; N],
    s1: [T; N],
}

impl<T: Sample, const N: usize> Default for CascadeState<T, N> {
    fn default() -> Self {
        Self {
            s2: [T::ZERO; N],
            s1: [T::ZERO; N],
        }
    }
}

impl<T: Sample, const N: usize> CascadeCoefficients<T, N> {
    /// Builds a cascade from `gain` and sections `[b0, b1, b2, a1, a2]` designed in `f64`.
    ///
    /// # Errors
    /// [`InverseError::TooManySections`], [`InverseError::NonFinite`], or
    /// [`InverseError::UnstableSection`] when a section's poles are not inside the unit circle
    /// by [`MIN_POLE_MARGIN`].
    pub fn new(gain: f64, sections: &[[f64; 5]]) -> Result<Self, InverseError> {
        if sections.len() > N {
            return Err(InverseError::TooManySections {
                sections: sections.len(),
                capacity: N,
            });
        }
        if !gain.is_finite() || sections.iter().flatten().any(|c| !c.is_finite()) {
            return Err(InverseError::NonFinite);
        }
        let mut out = [Biquad::IDENTITY; N];
        let mut dc = [T::ONE; N];
        for (index, ((dst, d), &[b0, b1, b2, a1, a2])) in
            out.iter_mut().zip(dc.iter_mut()).zip(sections).enumerate()
        {
            let radius = section_pole_radius(a1, a2);
            if radius.is_nan() || radius > 1.0 - MIN_POLE_MARGIN {
                return Err(InverseError::UnstableSection { index, radius });
            }
            // The input gain is folded into the first section's numerator, in f64.
            let g = if index == 0 { gain } else { 1.0 };
            *dst = Biquad {
                b: [
                    T::from_f64(g * b0),
                    T::from_f64(g * b1),
                    T::from_f64(g * b2),
                ],
                a: [T::from_f64(a1), T::from_f64(a2)],
            };
            // Stable, so 1 + a1 + a2 > 0.
            *d = T::from_f64(g * (b0 + b1 + b2) / (1.0 + a1 + a2));
        }
        // No section given: the gain alone, in the first (identity) section. With no room
        // for a section at all (`N == 0`) the gain stays apart, see `process`.
        if sections.is_empty() {
            if let (Some(first), Some(d)) = (out.first_mut(), dc.first_mut()) {
                first.b = [T::from_f64(gain), T::ZERO, T::ZERO];
                *d = T::from_f64(gain);
            }
        }
        Ok(Self {
            head: out.map(
                |Biquad {
                     b: [b0, b1, _],
                     a: [a1, a2],
                 }| [b0, b1, a1, a2],
            ),
            b2: out.map(|Biquad { b: [_, _, b2], .. }| b2),
            gain: T::from_f64(gain),
            dc,
        })
    }

    /// One sample through the cascade. Panic-free and allocation-free; 5 multiplies per
    /// section (the gain is folded into the first). Runs the Cortex-M kernel where there is
    /// one ([`f32_cascade_uses_kernel`]), [`Self::process_portable`] elsewhere: the same bits.
    #[inline]
    pub fn process(&self, state: &mut CascadeState<T, N>, x: T) -> T {
        match T::kernel_process(self, state, x) {
            Some(y) => y,
            None => self.process_portable(state, x),
        }
    }

    /// [`Self::process`] in portable Rust, on every target: the reference the Cortex-M
    /// kernels are checked against, bit for bit.
    #[inline]
    pub fn process_portable(&self, state: &mut CascadeState<T, N>, x: T) -> T {
        if N == 0 {
            return self.gain * x;
        }
        let mut v = x;
        let sections = self.head.iter().zip(&self.b2);
        let states = state.s1.iter_mut().zip(state.s2.iter_mut());
        for ((&[b0, b1, a1, a2], &b2), (s1, s2)) in sections.zip(states) {
            let y = (*s1 + b0 * v).scalar();
            *s1 = (*s2 + b1 * v - a1 * y).scalar();
            *s2 = (b2 * v - a2 * y).scalar();
            v = y;
        }
        v
    }

    /// Processes a block in place, sample by sample: the same bits as [`Self::process`] on
    /// each sample. On Cortex-M ([`f32_cascade_uses_kernel`]) the coefficients and states
    /// stay in registers over the whole block.
    #[inline]
    pub fn process_in_place(&self, state: &mut CascadeState<T, N>, buf: &mut [T]) {
        if !T::kernel_process_in_place(self, state, buf) {
            self.process_in_place_portable(state, buf);
        }
    }

    /// [`Self::process_in_place`] in portable Rust, on every target.
    #[inline]
    pub fn process_in_place_portable(&self, state: &mut CascadeState<T, N>, buf: &mut [T]) {
        for x in buf.iter_mut() {
            *x = self.process_portable(state, *x);
        }
    }

    /// The state after the constant input `x0` forever (no start-up transient).
    #[must_use]
    pub fn equilibrium(&self, x0: T) -> CascadeState<T, N> {
        let mut state = CascadeState::default();
        let mut v = if N == 0 { self.gain * x0 } else { x0 };
        let sections = self.head.iter().zip(&self.b2).zip(self.dc);
        let states = state.s1.iter_mut().zip(state.s2.iter_mut());
        for (((&[b0, _, _, a2], &b2), dc), (s1, s2)) in sections.zip(states) {
            let y = dc * v;
            *s1 = y - b0 * v;
            *s2 = b2 * v - a2 * y;
            v = y;
        }
        state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schur_accepts_inside_and_rejects_outside() {
        // (1 - 0.5 z^-1)(1 + 0.9 z^-1) = 1 + 0.4 z^-1 - 0.45 z^-2: zeros 0.5, -0.9.
        assert!(schur_stable(&[1.0, 0.4, -0.45]).is_ok());
        // Zero at 2.1: (1 - 2.1 z^-1).
        assert!(schur_stable(&[1.0, -2.1]).is_err());
        // Zero on the circle.
        assert!(schur_stable(&[1.0, -1.0]).is_err());
        // Complex pair at radius 0.99.
        let r: f64 = 0.99;
        let th: f64 = 0.3;
        assert!(schur_stable(&[1.0, -2.0 * r * th.cos(), r * r]).is_ok());
        let r: f64 = 1.01;
        assert!(schur_stable(&[1.0, -2.0 * r * th.cos(), r * r]).is_err());
        // Leading-coefficient scaling does not matter.
        assert!(schur_stable(&[0.1, 0.04, -0.045]).is_ok());
    }

    #[test]
    fn refuses_bad_coefficients() {
        assert_eq!(
            InverseCoefficients::<f32, 2>::new(&[0.0, 1.0], &[0.1]),
            Err(InverseError::LeadingZero)
        );
        assert_eq!(
            InverseCoefficients::<f32, 1>::new(&[1.0, 0.1, 0.1], &[0.1]),
            Err(InverseError::OrderTooHigh {
                order: 2,
                capacity: 1
            })
        );
        assert_eq!(
            InverseCoefficients::<f32, 2>::new(&[1.0, f64::NAN], &[0.1]),
            Err(InverseError::NonFinite)
        );
        assert!(matches!(
            InverseCoefficients::<f32, 2>::new(&[1.0, -2.1], &[0.1]),
            Err(InverseError::UnstableInverse { .. })
        ));
        assert_eq!(
            InverseCoefficients::<f32, 2>::new(&[], &[]),
            Err(InverseError::EmptyNumerator)
        );
    }

    #[test]
    fn inverts_a_second_order_model_exactly() {
        // y[k] = 0.2 u[k] + 0.1 u[k-1] - (-1.2 y[k-1] + 0.5 y[k-2])
        let b = [0.2, 0.1, 0.0];
        let a = [-1.2, 0.5];
        let c = InverseCoefficients::<f64, 4>::new(&b, &a).unwrap();
        let mut s = InverseState::default();
        let u: [f64; 8] = [0.0, 1.0, 1.0, 0.5, -0.25, 2.0, 0.0, 0.0];
        let (mut y1, mut y2, mut u1) = (0.0, 0.0, 0.0);
        for &uk in &u {
            let y = 0.2 * uk + 0.1 * u1 + 1.2 * y1 - 0.5 * y2;
            y2 = y1;
            y1 = y;
            u1 = uk;
            let uh = c.process(&mut s, y);
            assert!((uh - uk).abs() < 1e-12, "{uh} vs {uk}");
        }
    }

    #[test]
    fn cascade_matches_the_direct_recurrence_and_starts_in_equilibrium() {
        // Two sections: a resonance and a first-order lag, with gain 0.5.
        let secs = [[1.0, -0.5, 0.1, -1.2, 0.72], [0.3, 0.2, 0.0, -0.5, 0.0]];
        let c = CascadeCoefficients::<f64, 3>::new(0.5, &secs).unwrap();
        let mut st = CascadeState::default();
        // Reference: each section as its own direct form I.
        let mut h = [[0.0f64; 4]; 2];
        for k in 0..50 {
            let x = if k % 7 < 3 { 1.0 } else { -0.25 };
            let mut v = 0.5 * x;
            for (s, c) in h.iter_mut().zip(&secs) {
                let y = c[0] * v + c[1] * s[0] + c[2] * s[1] - c[3] * s[2] - c[4] * s[3];
                *s = [v, s[0], y, s[2]];
                v = y;
            }
            let got = c.process(&mut st, x);
            assert!((got - v).abs() < 1e-12, "{k}: {got} vs {v}");
        }
        let mut st = c.equilibrium(2.0);
        let dc = 0.5 * (0.6 / 0.52) * (0.5 / 0.5);
        for _ in 0..5 {
            assert!((c.process(&mut st, 2.0) - 2.0 * dc).abs() < 1e-12);
        }
        assert!(matches!(
            CascadeCoefficients::<f32, 1>::new(1.0, &secs),
            Err(InverseError::TooManySections { .. })
        ));
        assert!(matches!(
            CascadeCoefficients::<f32, 2>::new(1.0, &[[1.0, 0.0, 0.0, -2.0, 1.0]]),
            Err(InverseError::UnstableSection { index: 0, .. })
        ));
    }

    #[test]
    fn gain_alone_is_kept_with_no_sections_and_no_capacity() {
        let none = CascadeCoefficients::<f64, 0>::new(2.5, &[]).unwrap();
        let mut s0 = none.equilibrium(1.0);
        assert_eq!(none.process(&mut s0, 4.0), 10.0);
        let empty = CascadeCoefficients::<f64, 2>::new(2.5, &[]).unwrap();
        let mut s2 = empty.equilibrium(1.0);
        assert_eq!(empty.process(&mut s2, 4.0), 10.0);
        assert_eq!(empty.process(&mut s2, -2.0), -5.0);
    }

    #[test]
    fn equilibrium_start_has_no_transient() {
        // DC gain 0.9: y settles at 0.9 for u = 1.
        let b = [0.3, 0.15];
        let a = [-0.5];
        let mut c = Compensator::<f32, 2>::new(&b, &a, 0.9).unwrap();
        for _ in 0..5 {
            assert!((c.push(0.9) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn nonlinear_correction_is_the_filtered_quadratic_rate() {
        // A pass-through low-pass: the correction is exactly gain * |dy| dy.
        let c = NonlinearDampingCoefficients::<f32, 2>::new(4.0, 1.0, &[]).unwrap();
        let mut st = c.equilibrium(1.0);
        assert_eq!(c.process(&mut st, 1.0), 0.0);
        assert_eq!(c.process(&mut st, 1.5), 4.0 * 0.25);
        assert_eq!(c.process(&mut st, 1.0), -4.0 * 0.25);
        assert_eq!(c.process(&mut st, 1.0), 0.0);
        // Odd in the rate, zero on a steady signal whatever its level, and low-passed.
        let lp = [[0.1, 0.0, 0.0, -0.9, 0.0]];
        let c = NonlinearDampingCoefficients::<f64, 2>::new(2.0, 1.0, &lp).unwrap();
        let ramp = |slope: f64| {
            let mut st = c.equilibrium(3.0);
            let mut out = 0.0;
            for k in 0..200 {
                out = c.process(&mut st, 3.0 + slope * f64::from(k));
            }
            out
        };
        // A ramp of 0.1 per sample: N = 0.01, the low-pass's DC gain 1.
        assert!((ramp(0.1) - 2.0 * 0.01).abs() < 1e-9, "{}", ramp(0.1));
        assert!((ramp(-0.1) + 2.0 * 0.01).abs() < 1e-9);
        assert!(ramp(0.0).abs() < 1e-15);
        // A low-pass that is not stable, or a gain that is not finite, is refused.
        assert!(NonlinearDampingCoefficients::<f32, 2>::new(
            1.0,
            1.0,
            &[[1.0, 0.0, 0.0, -1.0, 0.0]]
        )
        .is_err());
        assert_eq!(
            NonlinearDampingCoefficients::<f32, 2>::new(f64::NAN, 1.0, &[]),
            Err(InverseError::NonFinite)
        );
    }
}
