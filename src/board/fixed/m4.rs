//! The Cortex-M kernel of the fixed-point cascade: this module owns the hand-written Thumb-2
//! assembly `m4_fixed.s` and the `unsafe` call into it.
//!
//! Built on every ARMv7-M and ARMv7E-M bare-metal target (`cfg(unlag_armv7m)`, see `build.rs`):
//! `thumbv7m-none-eabi` (Cortex-M3), `thumbv7em-none-eabi` and `thumbv7em-none-eabihf`
//! (Cortex-M4 and M7). It uses only ARMv7-M instructions (SMULL, SMLAL, SSAT, RRX, LDRD/STRD),
//! none of the DSP extension and no FPU, and takes only integer and pointer arguments, so the
//! float calling convention does not matter.
//!
//! Same arithmetic as [`FixedCascade::process_portable`] (exact 64-bit accumulation, magnitude
//! truncation of the states, rounding of the output, saturation with the overflow flag), so
//! the same bits; `host-tests/firmware.rs` checks it in QEMU. What it saves over the compiled
//! Rust: no spills of the three 64-bit accumulators (they are computed one after the other),
//! the truncation bias in one shifted-operand add, the saturation test in one SSAT and one
//! compare with the fix-up out of line, and a branch instead of the branch-free variable
//! 64-bit shift for the output.
//!
//! Safety of the call: the kernel reads `N` `#[repr(C)]` [`FixedSection`]s of 40 bytes from
//! the coefficients, reads and writes the `2 N` states at the start of the `#[repr(C)]`
//! [`FixedState`], and writes `true` to its overflow flag right after them when a value
//! saturated; it needs every `shift` in 1..=62, which [`FixedCascade::new`] guarantees.
#![allow(unsafe_code)]

use super::{FixedCascade, FixedSection, FixedState};

core::arch::global_asm!(include_str!("m4_fixed.s"), options(raw));

// The kernel's offsets.
const _: () = assert!(core::mem::size_of::<FixedSection>() == 40);
const _: () = assert!(core::mem::offset_of!(FixedSection, shift) == 36);
const _: () = assert!(core::mem::offset_of!(FixedState<3>, overflow) == 24);

extern "C" {
    fn unlag_m4_fixed_process(
        sections: *const FixedSection,
        state: *mut u8,
        v: i32,
        n: usize,
    ) -> i32;
}

/// One sample through the kernel.
#[inline(always)]
pub(super) fn process<const N: usize>(
    c: &FixedCascade<N>,
    s: &mut FixedState<N>,
    input: i32,
) -> i32 {
    let state = core::ptr::from_mut(s).cast::<u8>();
    // SAFETY: see the module docs.
    unsafe { unlag_m4_fixed_process(c.sections.as_ptr(), state, input, N) }
}
