//! The Cortex-M kernels of the `f32` cascade: this module owns the hand-scheduled Thumb-2
//! assembly (`m4_kernels.s`, written by `bench/gen_m4_kernels.py`) and the only `unsafe` code
//! of the crate, the calls into it.
//!
//! Built on `thumbv7em-none-eabihf` (`cfg(all(unlag_armv7m, target_abi = "eabihf"))`, see
//! `build.rs`): Thumb-2, a single-precision VFP with 32 S registers, and the AAPCS-VFP calling
//! convention that passes `f32` arguments in S registers. The soft-float targets
//! (`thumbv7em-none-eabi`, `thumbv7m-none-eabi`) pass them in integer registers, and the M3 has
//! no FPU: they run the portable code. The kernels exist for 1..=4 sections; other capacities
//! run the portable code.
//!
//! Why assembly: LLVM loads every coefficient and state with its own VLDR, gives every Rust
//! function a frame (the thumbv7em targets force frame pointers), keeps VMUL and VADD apart
//! on the M4, and in a block cannot keep `5 N + 2 N` values in registers without moving them.
//! The kernels load all coefficients with one VLDM and the state with one more, do 5
//! VMLA/VMLS/VMUL per section, and store the state with one VSTM; the block kernel keeps
//! coefficients and states in registers and lets each section's three registers rotate roles
//! from sample to sample, so its loop moves nothing.
//!
//! Bit-exactness: VMLA computes `d + round(n * m)` and VMLS `d - round(n * m)`, each rounded
//! once more (not fused; VFMA would not match), in the same order as
//! `CascadeCoefficients::process_portable`. `host-tests/firmware.rs` checks this in QEMU.
//!
//! Safety of the calls: the kernels read `5 N` floats from the start of a `#[repr(C)]`
//! [`CascadeCoefficients`] (`head` then `b2`, contiguous), read and write `2 N` floats of a
//! `#[repr(C)]` [`CascadeState`] (`s2` then `s1`), and the block kernel reads and writes
//! `len` floats of `buf`. Nothing else is touched besides the registers the AAPCS lets a
//! callee clobber (s16 and up are saved and restored).
#![allow(unsafe_code)]

use super::{CascadeCoefficients, CascadeState};

core::arch::global_asm!(include_str!("m4_kernels.s"), options(raw));

extern "C" {
    fn unlag_m4_cascade_call_1(c: *const f32, s: *mut f32, x: f32) -> f32;
    fn unlag_m4_cascade_call_2(c: *const f32, s: *mut f32, x: f32) -> f32;
    fn unlag_m4_cascade_call_3(c: *const f32, s: *mut f32, x: f32) -> f32;
    fn unlag_m4_cascade_call_4(c: *const f32, s: *mut f32, x: f32) -> f32;
    fn unlag_m4_cascade_block_1(c: *const f32, s: *mut f32, buf: *mut f32, len: usize);
    fn unlag_m4_cascade_block_2(c: *const f32, s: *mut f32, buf: *mut f32, len: usize);
    fn unlag_m4_cascade_block_3(c: *const f32, s: *mut f32, buf: *mut f32, len: usize);
    fn unlag_m4_cascade_block_4(c: *const f32, s: *mut f32, buf: *mut f32, len: usize);
}

/// One sample through the kernel for `N` sections; `None` when there is none for `N`.
#[inline(always)]
pub(super) fn process<const N: usize>(
    c: &CascadeCoefficients<f32, N>,
    s: &mut CascadeState<f32, N>,
    x: f32,
) -> Option<f32> {
    let cp = core::ptr::from_ref(c).cast::<f32>();
    let sp = core::ptr::from_mut(s).cast::<f32>();
    // SAFETY: see the module docs; `N` matches the kernel, the layouts are `#[repr(C)]`.
    unsafe {
        match N {
            1 => Some(unlag_m4_cascade_call_1(cp, sp, x)),
            2 => Some(unlag_m4_cascade_call_2(cp, sp, x)),
            3 => Some(unlag_m4_cascade_call_3(cp, sp, x)),
            4 => Some(unlag_m4_cascade_call_4(cp, sp, x)),
            _ => None,
        }
    }
}

/// A block in place through the kernel for `N` sections; `false` when there is none for `N`.
#[inline(always)]
pub(super) fn process_in_place<const N: usize>(
    c: &CascadeCoefficients<f32, N>,
    s: &mut CascadeState<f32, N>,
    buf: &mut [f32],
) -> bool {
    let cp = core::ptr::from_ref(c).cast::<f32>();
    let sp = core::ptr::from_mut(s).cast::<f32>();
    let (bp, len) = (buf.as_mut_ptr(), buf.len());
    // SAFETY: see the module docs; `buf` is valid for `len` reads and writes.
    unsafe {
        match N {
            1 => unlag_m4_cascade_block_1(cp, sp, bp, len),
            2 => unlag_m4_cascade_block_2(cp, sp, bp, len),
            3 => unlag_m4_cascade_block_3(cp, sp, bp, len),
            4 => unlag_m4_cascade_block_4(cp, sp, bp, len),
            _ => return false,
        }
    }
    true
}
