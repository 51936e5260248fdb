//! Writes the memory map of an STM32F407-like part (1 MiB of flash at 0x0800_0000, 128 KiB of
//! RAM at 0x2000_0000) to `OUT_DIR`, where cortex-m-rt's `link.x` finds it: in a real firmware
//! this comes from the board-support crate or the HAL. The sizes measured do not depend on it.

use std::{env, fs, path::PathBuf};

const MEMORY_X: &str = "\
MEMORY
{
  FLASH : ORIGIN = 0x08000000, LENGTH = 1M
  RAM   : ORIGIN = 0x20000000, LENGTH = 128K
}
";

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let Some(out) = env::var_os("OUT_DIR").map(PathBuf::from) else {
        return;
    };
    if fs::write(out.join("memory.x"), MEMORY_X).is_ok() {
        println!("cargo:rustc-link-search={}", out.display());
    }
}
