//! Puts the repository's `memory.x` (the QEMU mps2 map) where cortex-m-rt's `link.x` finds it
//! when this package's own examples are linked for a Cortex-M target, and nowhere else. Also
//! tells the library which Cortex-M kernels the target can run.
//!
//! Who gets the map: only `examples/` of this package, through
//! `cargo:rustc-link-arg-examples=-L<OUT_DIR>`. Never `cargo:rustc-link-search`: that puts the
//! directory on the link path of every crate that depends on this one, and a firmware whose
//! own map comes from a board-support crate's build script (embassy-stm32's `memory-x`
//! feature, say) would then link with whichever `memory.x` the linker finds first. With a
//! dependency whose name sorts after `unlag` that was this one: the vector table at 0x00000000
//! instead of the part's flash, a firmware that does not boot, and no error.
//! `host-tests/firmware.rs` builds `host-tests/link-check/` with both orders to keep it so.
//!
//! How the examples' linker finds it: rust-lld (the thumb targets' default) searches every
//! `-L` directory for `link.x`'s `INCLUDE memory.x`, wherever the `-L` stands. GNU ld
//! (`-C linker=arm-none-eabi-ld`) searches only the `-L` directories given before
//! `-Tlink.x`, and cargo passes this one after the `RUSTFLAGS` that hold `-Tlink.x`; GNU ld
//! finds the file all the same because both linkers also look in the current directory, and
//! cargo links this package's examples from its root, beside `memory.x`. Host builds are
//! untouched.
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
    // Set only by bench/board.sh, which links CMSIS-DSP into examples/bench_board.rs.
    println!("cargo:rustc-check-cfg=cfg(unlag_bench_cmsis)");
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
    // The examples' link only (see the module doc): not `rustc-link-search`, which would hand
    // this map to every dependent firmware.
    if fs::copy("memory.x", out.join("memory.x")).is_ok() {
        println!("cargo:rustc-link-arg-examples=-L{}", out.display());
    }
    // defmt's linker script for the board examples when they log through defmt.
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-examples=-Tdefmt.x");
    }
}
