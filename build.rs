//! Puts `memory.x` where cortex-m-rt's `link.x` finds it, for Cortex-M builds only; host
//! builds are untouched. Also tells the library which Cortex-M kernels the target can run.
//!
//! `cfg(unlag_armv7m)`: a bare-metal ARMv7-M or ARMv7E-M target (`thumbv7m-none-eabi`, Cortex-M3;
//! `thumbv7em-none-eabi` and `thumbv7em-none-eabihf`, Cortex-M4 and M7). These have the
//! Thumb-2 instructions the fixed-point kernels use (SMULL, SMLAL, SSAT, BFC, RRX, LDRD/STRD,
//! MRS/MSR of the APSR with its Q flag); none of them needs the DSP extension of ARMv7E-M.
//! The `f32` kernels need the FPU and the hard-float calling convention besides:
//! `cfg(all(unlag_armv7m, target_abi = "eabihf"))`. Read from the target's name because
//! stable Rust does not report Arm target features (`target_feature = "thumb2"`, `"dsp"`,
//! `"v7"`) to `cfg`: they are unstable, and `cfg(target_feature = "thumb2")` is false on
//! `thumbv7m-none-eabi`. Any other target runs the portable Rust code, which computes the
//! same bits.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rustc-check-cfg=cfg(unlag_armv7m)");
    let target = env::var("TARGET").unwrap_or_default();
    let bare_metal = env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "none");
    if bare_metal && (target.starts_with("thumbv7m-") || target.starts_with("thumbv7em-")) {
        println!("cargo:rustc-cfg=unlag_armv7m");
    }
    if !target.starts_with("thumb") {
        return;
    }
    let Some(out) = env::var_os("OUT_DIR").map(PathBuf::from) else {
        return;
    };
    if fs::copy("memory.x", out.join("memory.x")).is_ok() {
        println!("cargo:rustc-link-search={}", out.display());
    }
    // defmt's linker script for the board examples when they log through defmt.
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-examples=-Tdefmt.x");
    }
}
