//! A firmware that runs `CHANNELS` compensator channels of one kind, one sample per channel per
//! pass, as an ADC interrupt would, and nothing else. bench/channel-size.sh builds it with 0,
//! 1 and 2 channels and reads the flash and RAM of each build from the ELF: the difference
//! between 0 and 1 channel is what the first channel costs (the kernel and constructor code,
//! the exported coefficients, the validated coefficients in RAM, one state), between 1 and 2
//! what each further channel costs (its state: the channels share the coefficients).
//!
//! Each channel is built the way docs/firmware.md shows: the exported coefficients checked
//! once at start-up, the state started in equilibrium with the first reading (all zero with
//! the feature `zero-start`), then `process(&mut state, x)` per sample. Everything lives in a `static` (cortex-m-rt's
//! `static mut` in `#[entry]`), so that `arm-none-eabi-size` counts it as RAM (bss);
//! the readings come through `black_box` as from an ADC register.
#![no_std]
#![no_main]

#[cfg(any(
    all(feature = "f32", feature = "fixed"),
    all(feature = "f32", feature = "direct"),
    all(feature = "fixed", feature = "direct")
))]
compile_error!("one kind at most: f32, fixed or direct");
#[cfg(all(
    any(feature = "f32", feature = "fixed", feature = "direct"),
    not(any(feature = "m2", feature = "m4", feature = "m8"))
))]
compile_error!("choose the capacity: m2, m4 or m8");
#[cfg(all(
    any(feature = "f32", feature = "fixed", feature = "direct"),
    not(any(feature = "ch1", feature = "ch2"))
))]
compile_error!("choose the channel count: ch1 or ch2");

use core::hint::black_box;

use cortex_m_rt::entry;
use panic_halt as _;

/// Second-order sections of capacity: an order-m compensator has m/2.
#[cfg(feature = "m2")]
const N: usize = 1;
#[cfg(feature = "m4")]
const N: usize = 2;
#[cfg(feature = "m8")]
const N: usize = 4;
#[cfg(not(any(feature = "m2", feature = "m4", feature = "m8")))]
#[allow(dead_code)]
const N: usize = 0;

/// Channels sharing one set of coefficients.
#[cfg(feature = "ch2")]
const CHANNELS: usize = 2;
#[cfg(all(feature = "ch1", not(feature = "ch2")))]
const CHANNELS: usize = 1;
#[cfg(not(any(feature = "ch1", feature = "ch2")))]
const CHANNELS: usize = 1;

/// The shipped design (`unlag export --format rust` of examples/data/board_model.toml): the
/// first `N` of its four sections.
#[cfg(feature = "f32")]
mod kind {
    use super::{CHANNELS, N};
    use unlag::board::compensator::{CascadeCoefficients, CascadeState};

    #[allow(dead_code)]
    mod coefficients {
        include!("../../../examples/data/board_coefficients.rs");
    }

    pub type Sample = f32;

    /// A channel's state at start-up: in equilibrium with the first reading, or (feature
    /// `zero-start`) all zero.
    fn start(c: &CascadeCoefficients<f32, N>, x: Sample) -> CascadeState<f32, N> {
        if cfg!(feature = "zero-start") {
            CascadeState::default()
        } else {
            c.equilibrium(x)
        }
    }

    pub struct Board {
        coefficients: CascadeCoefficients<f32, N>,
        states: [CascadeState<f32, N>; CHANNELS],
    }

    impl Board {
        pub fn new(first: [Sample; CHANNELS]) -> Option<Self> {
            let sections = coefficients::SECTIONS.get(..N)?;
            let coefficients = CascadeCoefficients::new(coefficients::GAIN, sections).ok()?;
            Some(Self {
                states: first.map(|x| start(&coefficients, x)),
                coefficients,
            })
        }

        pub fn sample(&mut self, x: [Sample; CHANNELS]) -> [Sample; CHANNELS] {
            let mut out = x;
            for (y, state) in out.iter_mut().zip(&mut self.states) {
                *y = self.coefficients.process(state, *y);
            }
            out
        }
    }
}

/// The fixed-point plan of the same design, normal form, for order m.
#[cfg(feature = "fixed")]
mod kind {
    use super::{CHANNELS, N};
    use unlag::board::fixed::{FixedCascade, FixedSection, FixedState};

    #[allow(dead_code)]
    mod plan {
        include!("../../../examples/data/board_fixed.rs");
    }

    #[cfg(feature = "m2")]
    const SECTIONS: &[FixedSection] = &plan::SECTIONS_M2;
    #[cfg(feature = "m4")]
    const SECTIONS: &[FixedSection] = &plan::SECTIONS_M4;
    #[cfg(feature = "m8")]
    const SECTIONS: &[FixedSection] = &plan::SECTIONS_M8;

    pub type Sample = i32;

    /// A channel's state at start-up: in equilibrium with the first reading, or (feature
    /// `zero-start`) all zero.
    fn start(c: &FixedCascade<N>, x: Sample) -> FixedState<N> {
        if cfg!(feature = "zero-start") {
            FixedState::default()
        } else {
            c.equilibrium(x)
        }
    }

    pub struct Board {
        cascade: FixedCascade<N>,
        states: [FixedState<N>; CHANNELS],
    }

    impl Board {
        pub fn new(first: [Sample; CHANNELS]) -> Option<Self> {
            let cascade = FixedCascade::new(SECTIONS).ok()?;
            Some(Self {
                states: first.map(|x| start(&cascade, x)),
                cascade,
            })
        }

        pub fn sample(&mut self, x: [Sample; CHANNELS]) -> [Sample; CHANNELS] {
            let mut out = x;
            for (y, state) in out.iter_mut().zip(&mut self.states) {
                *y = self.cascade.process(state, *y);
            }
            out
        }
    }
}

/// The fixed-point plan of the same design, direct form, for order m.
#[cfg(feature = "direct")]
mod kind {
    use super::{CHANNELS, N};
    use unlag::board::fixed::direct::{DirectCascade, DirectSection, DirectState};

    #[allow(dead_code)]
    mod plan {
        include!("../../../examples/data/board_direct.rs");
    }

    #[cfg(feature = "m2")]
    const SECTIONS: &[DirectSection] = &plan::SECTIONS_M2;
    #[cfg(feature = "m4")]
    const SECTIONS: &[DirectSection] = &plan::SECTIONS_M4;
    #[cfg(feature = "m8")]
    const SECTIONS: &[DirectSection] = &plan::SECTIONS_M8;

    pub type Sample = i32;

    /// A channel's state at start-up: in equilibrium with the first reading, or (feature
    /// `zero-start`) all zero.
    fn start(c: &DirectCascade<N>, x: Sample) -> DirectState<N> {
        if cfg!(feature = "zero-start") {
            DirectState::default()
        } else {
            c.equilibrium(x)
        }
    }

    pub struct Board {
        cascade: DirectCascade<N>,
        states: [DirectState<N>; CHANNELS],
    }

    impl Board {
        pub fn new(first: [Sample; CHANNELS]) -> Option<Self> {
            let cascade = DirectCascade::new(SECTIONS).ok()?;
            Some(Self {
                states: first.map(|x| start(&cascade, x)),
                cascade,
            })
        }

        pub fn sample(&mut self, x: [Sample; CHANNELS]) -> [Sample; CHANNELS] {
            let mut out = x;
            for (y, state) in out.iter_mut().zip(&mut self.states) {
                *y = self.cascade.process(state, *y);
            }
            out
        }
    }
}

/// The baseline: no compensator, the readings passed through.
#[cfg(not(any(feature = "f32", feature = "fixed", feature = "direct")))]
mod kind {
    use super::CHANNELS;

    pub type Sample = f32;

    pub struct Board;

    impl Board {
        pub fn new(_first: [Sample; CHANNELS]) -> Option<Self> {
            Some(Self)
        }

        pub fn sample(&mut self, x: [Sample; CHANNELS]) -> [Sample; CHANNELS] {
            x
        }
    }
}

/// Where the channels live: an empty slot at reset, filled at start-up. The explicit tag makes
/// the empty slot all zeros, so it lands in `.bss` (as in a `StaticCell` or RTIC's resources);
/// an `Option` could take its tag from a niche of the state (the fixed-point overflow flag) and
/// put the whole slot in `.data`, with an image of it in flash.
#[repr(u8)]
enum Slot {
    Empty,
    Full(kind::Board),
}

#[entry]
fn main() -> ! {
    // cortex-m-rt turns this into a `&'static mut`: RAM the ELF's size counts.
    static mut BOARD: Slot = Slot::Empty;
    let Some(board) = kind::Board::new(black_box([kind::Sample::default(); CHANNELS])) else {
        #[allow(clippy::empty_loop)]
        loop {}
    };
    // Every firmware links `memcpy` (any copy of a length known at run time calls it); so does
    // this one, in every build, so that a build whose moves happen to call it does not count
    // it against its channels.
    let mut scratch = [0u8; 16];
    let n = black_box(scratch.len());
    if let (Some(dst), Some(src)) = (scratch.get_mut(..n), black_box(&[1u8; 16]).get(..n)) {
        dst.copy_from_slice(src);
    }
    black_box(&scratch);
    *BOARD = Slot::Full(board);
    let Slot::Full(board) = BOARD else {
        #[allow(clippy::empty_loop)]
        loop {}
    };
    loop {
        // One reading per channel, as from the ADC's data register.
        let x = black_box([kind::Sample::default(); CHANNELS]);
        black_box(board.sample(x));
    }
}
