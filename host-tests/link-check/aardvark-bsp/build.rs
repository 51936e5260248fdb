//! Writes this board's `memory.x` to `OUT_DIR` and puts that directory on the link path of
//! every crate that depends on this one, where cortex-m-rt's `link.x` finds it.

use std::{env, fs, path::PathBuf};

/// The map of an STM32F407-like part: 1 MiB of flash at 0x0800_0000, 128 KiB of RAM at
/// 0x2000_0000. `host-tests/firmware.rs` checks the firmware's vector table against it.
const MEMORY_X: &str = "\
MEMORY
{
  FLASH : ORIGIN = 0x08000000, LENGTH = 1M
  RAM   : ORIGIN = 0x20000000, LENGTH = 128K
}
";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), MEMORY_X).expect("OUT_DIR is writable");
    println!("cargo:rustc-link-search={}", out.display());
}
