//! The Cortex-M kernels of the direct-form cascade: this module owns the generated Thumb-2
//! assembly `m4_direct.s` (written by `bench/gen_m4_direct.py`) and the `unsafe` calls into
//! it. Kernels exist for 1..=4 sections; other capacities run the portable code.
//!
//! Built on every ARMv7-M and ARMv7E-M bare-metal target (`cfg(unlag_armv7m)`, see `build.rs`):
//! `thumbv7m-none-eabi` (Cortex-M3), `thumbv7em-none-eabi` and `thumbv7em-none-eabihf`
//! (Cortex-M4 and M7). It uses only ARMv7-M instructions (SMLAL, SSAT, BFC, LDM/STM, MRS/MSR of
//! the APSR and its Q flag), none of the DSP extension and no FPU, and takes only integer and
//! pointer arguments, so the float calling convention does not matter.
//!
//! Same arithmetic as [`DirectCascade::process_portable`] (exact 64-bit SMLAL accumulation
//! seeded with the residual, SSAT of the high word, the new residual by BFC), so the same
//! bits; `host-tests/firmware.rs` checks it in QEMU. The call kernel loads a section's
//! coefficients with one LDM, its state with one more (the first section's together with the
//! input history) and stores it with one STM; the block kernel does the same per sample, with
//! two LDMs for the coefficients so that a section needs ten registers, and for one or two
//! sections a state pointer that stays put (LDMDB/STMDB reach the first section's state).
//! Overflow is detected through the sticky Q flag, cleared on entry and read once on exit.
//!
//! Safety of the calls: the kernels read `N` `#[repr(C)]` [`DirectSection`]s (20 bytes each)
//! from the start of the `#[repr(C)]` [`DirectCascade`], read and write the `2 + 3 N` words at
//! the start of the `#[repr(C)]` [`DirectState`], and write `true` to its flag right after
//! them; the block kernel reads and writes `len` words of `buf`.
#![allow(unsafe_code)]

use super::{DirectCascade, DirectSection, DirectState};

core::arch::global_asm!(include_str!("m4_direct.s"), options(raw));

// The kernels' offsets.
const _: () = assert!(core::mem::size_of::<DirectSection>() == 20);
const _: () = assert!(core::mem::offset_of!(DirectState<1>, overflow) == 20);
const _: () = assert!(core::mem::offset_of!(DirectState<4>, overflow) == 56);

extern "C" {
    fn unlag_m4_direct_call_1(c: *const DirectSection, s: *mut u8, x: i32) -> i32;
    fn unlag_m4_direct_call_2(c: *const DirectSection, s: *mut u8, x: i32) -> i32;
    fn unlag_m4_direct_call_3(c: *const DirectSection, s: *mut u8, x: i32) -> i32;
    fn unlag_m4_direct_call_4(c: *const DirectSection, s: *mut u8, x: i32) -> i32;
    fn unlag_m4_direct_block_1(c: *const DirectSection, s: *mut u8, buf: *mut i32, len: usize);
    fn unlag_m4_direct_block_2(c: *const DirectSection, s: *mut u8, buf: *mut i32, len: usize);
    fn unlag_m4_direct_block_3(c: *const DirectSection, s: *mut u8, buf: *mut i32, len: usize);
    fn unlag_m4_direct_block_4(c: *const DirectSection, s: *mut u8, buf: *mut i32, len: usize);
}

/// One sample through the kernel for `N` sections; `None` when there is none for `N`.
#[inline(always)]
pub(super) fn process<const N: usize>(
    c: &DirectCascade<N>,
    s: &mut DirectState<N>,
    x: i32,
) -> Option<i32> {
    let cp = c.sections.as_ptr();
    let sp = core::ptr::from_mut(s).cast::<u8>();
    // SAFETY: see the module docs; `N` matches the kernel, the layouts are `#[repr(C)]`.
    unsafe {
        match N {
            1 => Some(unlag_m4_direct_call_1(cp, sp, x)),
            2 => Some(unlag_m4_direct_call_2(cp, sp, x)),
            3 => Some(unlag_m4_direct_call_3(cp, sp, x)),
            4 => Some(unlag_m4_direct_call_4(cp, sp, x)),
            _ => None,
        }
    }
}

/// A block in place through the kernel for `N` sections; `false` when there is none for `N`.
#[inline(always)]
pub(super) fn process_in_place<const N: usize>(
    c: &DirectCascade<N>,
    s: &mut DirectState<N>,
    buf: &mut [i32],
) -> bool {
    let cp = c.sections.as_ptr();
    let sp = core::ptr::from_mut(s).cast::<u8>();
    let (bp, len) = (buf.as_mut_ptr(), buf.len());
    // SAFETY: see the module docs; `buf` is valid for `len` reads and writes.
    unsafe {
        match N {
            1 => unlag_m4_direct_block_1(cp, sp, bp, len),
            2 => unlag_m4_direct_block_2(cp, sp, bp, len),
            3 => unlag_m4_direct_block_3(cp, sp, bp, len),
            4 => unlag_m4_direct_block_4(cp, sp, bp, len),
            _ => return false,
        }
    }
    true
}
