//! Board benchmark: instructions per sample of the `f32` compensator on a Cortex-M4F in QEMU,
//! for model orders m = 2, 4, 8 (m/2 second-order sections), called once per sample (ISR
//! style, state by reference) and over a block, with the `idsp` crate's biquad cascade run
//! beside it on the same coefficients and samples as the baseline, and CMSIS-DSP's when
//! `bash bench/board.sh` links it in.
//!
//! ```sh
//! bash bench/board.sh          # builds, runs in QEMU, prints the Markdown table
//! ```
//!
//! Counting: QEMU runs with `-icount shift=0` (one guest instruction = 1 ns of virtual time)
//! and SysTick on the 25 MHz CPU clock, so one tick is 40 instructions. Every window covers
//! 1024 samples (512 for the marginal row), which bounds the counting error by 0.04
//! instructions per sample. The per-call figures include the caller's loop (load the
//! sample, call, store the result, count), reported alone as the `empty call` row.
//!
//! The benchmarks live beside it in `bench_board/`: `float.rs` (the `f32` compensator and
//! idsp's `f32` cascade), `fixed_point.rs` (the fixed-point forms and idsp's `Q32<30>`
//! cascade), `effects.rs` (the nonlinear-damping correction and the temperature bank) and
//! `cmsis.rs` (CMSIS-DSP's `f32` and Q31 biquad cascades: only with `--cfg unlag_bench_cmsis`
//! and the static library bench/board.sh builds from CMSIS-DSP's sources; a plain
//! `cargo build` leaves it out).
//!
//! On the host this example only prints how to run it.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    println!("bench_board runs on the board: bash bench/board.sh (QEMU, thumbv7em-none-eabihf)");
}

#[cfg(target_os = "none")]
mod board {
    //! The harness: the trace and the design's coefficients, the SysTick window and the
    //! `RESULT` line, the blob parsers, the empty call, and the entry that runs every
    //! benchmark and exits with its verdict.

    use core::hint::black_box;
    use core::sync::atomic::{compiler_fence, Ordering::SeqCst};

    use cortex_m::peripheral::{syst::SystClkSource, SYST};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    use panic_semihosting as _;

    use crate::{effects, fixed_point, float};

    pub(crate) mod coefficients {
        #![allow(dead_code)]
        include!("data/board_coefficients.rs");
    }
    mod trace {
        include!("data/board_trace.rs");
    }
    /// Fixed-point sections of the same design (`unlag::design::quantise::FixedPlan`, made by
    /// host-tests/export.rs).
    pub(crate) mod fixed {
        include!("data/board_fixed.rs");
    }
    /// Direct-form sections of the same design (`unlag::design::quantise::DirectPlan`, made by
    /// host-tests/export.rs).
    pub(crate) mod direct {
        include!("data/board_direct.rs");
    }

    pub(crate) const N: usize = 1024;
    /// Guest instructions per SysTick tick (25 MHz SysTick, `-icount shift=0`).
    const INSN_PER_TICK: u64 = 40;

    /// SysTick ticks spent in `f`.
    #[inline(always)]
    pub(crate) fn measure(f: impl FnOnce()) -> u32 {
        compiler_fence(SeqCst);
        let t0 = SYST::get_current();
        compiler_fence(SeqCst);
        f();
        compiler_fence(SeqCst);
        let t1 = SYST::get_current();
        compiler_fence(SeqCst);
        t0.wrapping_sub(t1) & 0x00FF_FFFF
    }

    /// `RESULT <impl> m=<m> <mode> n=<n> ticks=<t> insn/sample=<x.xx>`.
    pub(crate) fn report(name: &str, m: usize, mode: &str, n: usize, ticks: u32) {
        let n = n.max(1) as u64;
        let x100 = (u64::from(ticks) * INSN_PER_TICK * 100 + n / 2) / n;
        hprintln!(
            "RESULT {:<6} m={} {:<6} n={:<5} ticks={:<7} insn/sample={}.{:02}",
            name,
            m,
            mode,
            n,
            ticks,
            x100 / 100,
            x100 % 100
        );
    }

    /// The board-side blob parser, out of line so that `.ci/no-panic.sh` can check it too.
    #[inline(never)]
    fn parse_blob(
        bytes: &[u8],
    ) -> Result<unlag::board::blob::CoefficientSet<4>, unlag::board::blob::BlobError> {
        unlag::board::blob::parse(bytes)
    }

    /// The board-side parser of the direct-form blob, out of line so that `.ci/no-panic.sh`
    /// checks it too.
    #[inline(never)]
    fn parse_direct_blob(
        bytes: &[u8],
    ) -> Result<unlag::board::blob::DirectCoefficientSet<4>, unlag::board::blob::BlobError> {
        unlag::board::blob::parse_direct(bytes)
    }

    #[inline(never)]
    fn call_empty(x: f32) -> f32 {
        black_box(x)
    }

    static X: [f32; N] = trace::TRACE;
    static BLOB: &[u8] = include_bytes!("data/board_coefficients.bin");

    #[entry]
    fn main() -> ! {
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            debug::exit(debug::EXIT_FAILURE);
            #[allow(clippy::empty_loop)]
            loop {}
        };
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(0x00FF_FFFF);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();

        // The exported blob parses on the board (and the parser stays in the ELF for the
        // no-panic check).
        if let Err(e) = parse_blob(black_box(BLOB)) {
            hprintln!("ERROR blob refused: {}", e);
            debug::exit(debug::EXIT_FAILURE);
        }
        // The direct form's blob, written here and parsed back (the parser stays in the ELF).
        let mut direct_blob = [0u8; unlag::board::blob::encoded_len_direct(4)];
        let parsed = unlag::board::blob::encode_direct(
            &mut direct_blob,
            10_000.0,
            2,
            direct::FULL_SCALE,
            direct::OUTPUT_EXPONENT_M8,
            &direct::SECTIONS_M8,
        )
        .and_then(|_| parse_direct_blob(black_box(&direct_blob[..])));
        if let Err(e) = parsed {
            hprintln!("ERROR direct-form blob refused: {}", e);
            debug::exit(debug::EXIT_FAILURE);
        }
        let x = &X;
        let mut y = [0.0f32; N];
        let mut reference = [0.0f64; N];
        report("window", 0, "empty", 1, measure(|| {}));
        let t = measure(|| {
            for (xi, yi) in x.iter().zip(y.iter_mut()) {
                *yi = call_empty(*xi);
            }
        });
        report("empty", 0, "call", N, t);
        let mut ok = float::bench::<1>(x, &mut y, &mut reference);
        ok &= fixed_point::bench_fixed(
            &fixed::SECTIONS_M2,
            fixed::OUTPUT_EXPONENT_M2,
            x,
            &reference,
        );
        ok &= fixed_point::bench_direct(
            &direct::SECTIONS_M2,
            direct::OUTPUT_EXPONENT_M2,
            x,
            &reference,
        );
        ok &= float::bench::<2>(x, &mut y, &mut reference);
        ok &= fixed_point::bench_fixed(
            &fixed::SECTIONS_M4,
            fixed::OUTPUT_EXPONENT_M4,
            x,
            &reference,
        );
        ok &= fixed_point::bench_direct(
            &direct::SECTIONS_M4,
            direct::OUTPUT_EXPONENT_M4,
            x,
            &reference,
        );
        ok &= float::bench::<4>(x, &mut y, &mut reference);
        ok &= fixed_point::bench_fixed(
            &fixed::SECTIONS_M8,
            fixed::OUTPUT_EXPONENT_M8,
            x,
            &reference,
        );
        ok &= fixed_point::bench_direct(
            &direct::SECTIONS_M8,
            direct::OUTPUT_EXPONENT_M8,
            x,
            &reference,
        );
        ok &= effects::bench_nonlinear(x, &mut y);
        ok &= effects::bench_bank(x, &mut y);
        black_box(&y);
        hprintln!("DONE {}", if ok { "ok" } else { "FAIL" });
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        #[allow(clippy::empty_loop)]
        loop {}
    }
}

/// CMSIS-DSP's biquads, linked only by `bash bench/board.sh` (`--cfg unlag_bench_cmsis`).
#[cfg(all(target_os = "none", unlag_bench_cmsis))]
#[path = "bench_board/cmsis.rs"]
mod cmsis;
#[cfg(target_os = "none")]
#[path = "bench_board/effects.rs"]
mod effects;
#[cfg(target_os = "none")]
#[path = "bench_board/fixed_point.rs"]
mod fixed_point;
#[cfg(target_os = "none")]
#[path = "bench_board/float.rs"]
mod float;
