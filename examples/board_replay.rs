//! Board example: replays a recorded probe trace through the compensator, sample by sample,
//! with the coefficients `unlag export --format bin` wrote, and reports every output over
//! semihosting.
//!
//! ```sh
//! # In QEMU (Cortex-M4F, mps2-an386), through the runner in .cargo/config.toml:
//! cargo run --release --target thumbv7em-none-eabihf --no-default-features --example board_replay
//! # The same computation on the host, same output:
//! cargo run --release --example board_replay
//! ```
//!
//! Built in at compile time (no file system on the board):
//! * `examples/data/board_coefficients.bin`: `unlag export examples/data/board_model.toml
//!   --format bin -o examples/data/board_coefficients.bin`, parsed and validated on the board
//!   by [`unlag::blob::parse`];
//! * `examples/data/board_trace.rs`: 1024 samples of the probe column of
//!   `examples/data/step_test_2.csv`, a falling pressure step.
//!
//! Output: `SET ...`, then one line `Y <k> <bits>` per sample with the `f32` bit pattern of the
//! reconstruction in hex, then `UPDATE ...` (a corrupted blob is refused and the running set
//! kept) and `DONE`. `host-tests/firmware.rs` runs this in QEMU and checks every output bit
//! against the host running the same compensator on the same trace. Exit status 0 on success.
#![cfg_attr(target_os = "none", no_std, no_main)]

use core::fmt::Write;

use unlag::blob::{self, CoefficientSet};

mod trace {
    include!("data/board_trace.rs");
}

/// The exported coefficient blob.
/// The fixed-point compensator of the same design (`unlag::quantise::FixedPlan`); only the
/// full design (m = 8) is replayed here.
#[allow(dead_code)]
mod fixed {
    include!("data/board_fixed.rs");
}

static BLOB: &[u8] = include_bytes!("data/board_coefficients.bin");

/// The ADC code (Q1.31 of the full scale) of a probe sample, as a board would read it.
fn code(y: f32) -> i32 {
    // `as` saturates: no panic for any input.
    libm::round(f64::from(y) / fixed::FULL_SCALE * 2_147_483_648.0) as i32
}

/// The fixed-point compensator on the same trace: one output code per sample, on the host and
/// on the board alike (integer arithmetic, so the two must agree bit for bit).
fn replay_fixed(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let Ok(c) = unlag::fixed::FixedCascade::<4>::new(&fixed::SECTIONS_M8) else {
        writeln!(out, "ERROR fixed-point sections refused")?;
        return Ok(false);
    };
    let first = trace::TRACE.first().copied().unwrap_or(0.0);
    let mut state = c.equilibrium(code(first));
    for (k, &y) in trace::TRACE.iter().enumerate() {
        let v = c.process(&mut state, code(y));
        writeln!(out, "F {k} {:08x}", v as u32)?;
    }
    writeln!(out, "FIXED overflow={}", state.overflowed())?;
    Ok(!state.overflowed())
}

/// Section capacity of this firmware: up to an 8th-order compensator.
const SECTIONS: usize = 4;

/// Runs the whole replay, writing its report to `out`; `Ok(true)` when everything checked out.
fn replay(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let mut set: CoefficientSet<SECTIONS> = match blob::parse(BLOB) {
        Ok(set) => set,
        Err(e) => {
            writeln!(out, "ERROR coefficient blob refused: {e}")?;
            return Ok(false);
        }
    };
    writeln!(
        out,
        "SET fs={} Hz delay={} sections={} samples={}",
        set.sample_rate_hz,
        set.delay_samples,
        set.sections,
        trace::TRACE.len()
    )?;
    // Start in equilibrium with the first reading: no start-up transient.
    let first = trace::TRACE.first().copied().unwrap_or(0.0);
    let mut state = set.cascade.equilibrium(first);
    for (k, &y) in trace::TRACE.iter().enumerate() {
        let u = set.cascade.process(&mut state, y);
        writeln!(out, "Y {k} {:08x}", u.to_bits())?;
    }
    // A blob damaged in transit is refused, and the running set stays as it was.
    let mut damaged = [0u8; blob::encoded_len(SECTIONS)];
    let n = BLOB.len().min(damaged.len());
    for (d, s) in damaged.iter_mut().zip(BLOB) {
        *d = *s;
    }
    if let Some(b) = damaged.get_mut(40) {
        *b ^= 0x10;
    }
    let before = set;
    let refused = match set.update(damaged.get(..n).unwrap_or(&[])) {
        Err(e) => {
            writeln!(out, "UPDATE refused: {e}")?;
            set == before
        }
        Ok(()) => {
            writeln!(out, "UPDATE accepted a corrupted blob")?;
            false
        }
    };
    let fixed_ok = replay_fixed(out)?;
    let ok = refused && fixed_ok;
    writeln!(out, "DONE {}", if ok { "ok" } else { "FAILED" })?;
    Ok(ok)
}

#[cfg(target_os = "none")]
mod board {
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hio};
    use panic_semihosting as _;

    #[entry]
    fn main() -> ! {
        let ok = match hio::hstdout() {
            Ok(mut out) => matches!(super::replay(&mut out), Ok(true)),
            Err(()) => false,
        };
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        #[allow(clippy::empty_loop)]
        loop {}
    }
}

#[cfg(not(target_os = "none"))]
fn main() -> std::process::ExitCode {
    let mut out = String::new();
    let ok = matches!(replay(&mut out), Ok(true));
    print!("{out}");
    if ok {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
