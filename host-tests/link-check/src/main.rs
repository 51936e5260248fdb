//! A firmware that runs unlag's board compensator on a board whose memory map comes from a
//! board-support crate (feature `aardvark` or `zebra`). `host-tests/firmware.rs` builds it
//! with each and checks that the vector table sits at the start of that map's flash,
//! 0x0800_0000, whatever the order of the crates' names: unlag's own `memory.x` (the QEMU map,
//! flash at 0x0000_0000) is for unlag's examples only.
#![no_std]
#![no_main]

#[cfg(not(any(feature = "aardvark", feature = "zebra")))]
compile_error!("choose the board-support crate: --features aardvark or --features zebra");
#[cfg(all(feature = "aardvark", feature = "zebra"))]
compile_error!("choose one board-support crate, not both");

// The board-support crate brings nothing but its memory map, through its build script.
#[cfg(feature = "aardvark")]
use aardvark_bsp as _;
#[cfg(feature = "zebra")]
use zebra_bsp as _;

use panic_halt as _;

use core::hint::black_box;

use cortex_m_rt::entry;
use unlag::board::compensator::{CascadeCoefficients, CascadeState};

/// One section `[b0, b1, b2, a1, a2]`: a first-order low-pass with a pole at 0.5.
const SECTIONS: [[f64; 5]; 1] = [[0.5, 0.0, 0.0, -0.5, 0.0]];

/// The sample the compensator reads; read through `black_box` so that the computation stays.
static SAMPLE: f32 = 1.0;

#[entry]
fn main() -> ! {
    let Ok(cascade) = CascadeCoefficients::<f32, 1>::new(1.0, &SECTIONS) else {
        panic!("the section is stable");
    };
    let mut state = CascadeState::default();
    loop {
        black_box(cascade.process(&mut state, black_box(SAMPLE)));
        cortex_m::asm::wfi();
    }
}
