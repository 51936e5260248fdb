//! Board example: replays a recorded probe trace through the compensator, sample by sample,
//! with the coefficients `unlag export --format bin` wrote, and reports every output over
//! semihosting.
//!
//! ```sh
//! # In QEMU (Cortex-M4F, mps2-an386), through the runner in .cargo/config.toml:
//! cargo run --release --target thumbv7em-none-eabihf --no-default-features --example board_replay
//! # A Cortex-M3 without FPU (mps2-an385): the fixed-point kernels, the f32 code in software
//! cargo run --release --target thumbv7m-none-eabi --no-default-features --example board_replay
//! # The same computation on the host, same output:
//! cargo run --release --example board_replay
//! ```
//!
//! Built in at compile time (no file system on the board):
//! * `examples/data/board_coefficients.bin`: `unlag export examples/data/board_model.toml
//!   --format bin -o examples/data/board_coefficients.bin`, parsed and validated on the board
//!   by [`unlag::board::blob::parse`];
//! * `examples/data/board_trace.rs`: 1024 samples of the probe column of
//!   `examples/data/step_test_2.csv`, a falling pressure step.
//!
//! Output: `SET ...`, then one line `Y <k> <bits>` per sample with the `f32` bit pattern of the
//! reconstruction in hex, then `UPDATE ...` (a corrupted blob is refused and the running set
//! kept) and `DONE`. `host-tests/firmware.rs` runs this in QEMU and checks every output bit
//! against the host running the same compensator on the same trace. Exit status 0 on success.
#![cfg_attr(target_os = "none", no_std, no_main)]

use core::fmt::Write;

use unlag::board::blob::{self, CoefficientSet};

mod trace {
    include!("data/board_trace.rs");
}

/// The same design as Rust constants (`unlag export --format rust`), for the cascades of the
/// first K sections.
#[allow(dead_code)]
mod coefficients {
    include!("data/board_coefficients.rs");
}

/// The fixed-point compensator of the same design (`unlag::design::quantise::FixedPlan`); only the
/// full design (m = 8) is replayed here.
#[allow(dead_code)]
mod fixed {
    include!("data/board_fixed.rs");
}

static BLOB: &[u8] = include_bytes!("data/board_coefficients.bin");

/// The direct-form fixed-point compensator of the same design (`unlag::design::quantise::DirectPlan`).
#[allow(dead_code)]
mod direct {
    include!("data/board_direct.rs");
}

/// Fixed-point sections and input that make the fixed-point cascade saturate on purpose.
mod stress {
    include!("data/fixed_stress.rs");
}

/// The ADC code (Q1.31 of the full scale) of a probe sample, as a board would read it.
fn code(y: f32) -> i32 {
    // `as` saturates: no panic for any input.
    libm::round(f64::from(y) / fixed::FULL_SCALE * 2_147_483_648.0) as i32
}

/// The fixed-point compensator on the same trace: one output code per sample, on the host and
/// on the board alike (integer arithmetic, so the two must agree bit for bit).
fn replay_fixed(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let Ok(c) = unlag::board::fixed::FixedCascade::<4>::new(&fixed::SECTIONS_M8) else {
        writeln!(out, "ERROR fixed-point sections refused")?;
        return Ok(false);
    };
    let kind = if unlag::board::fixed::uses_kernel() {
        "asm"
    } else {
        "portable"
    };
    writeln!(out, "FKERNEL {kind}")?;
    let first = trace::TRACE.first().copied().unwrap_or(0.0);
    let mut state = c.equilibrium(code(first));
    for (k, &y) in trace::TRACE.iter().enumerate() {
        let v = c.process(&mut state, code(y));
        writeln!(out, "F {k} {:08x}", v as u32)?;
    }
    writeln!(out, "FIXED overflow={}", state.overflowed())?;
    Ok(!state.overflowed())
}

/// FNV-1a (64 bits) over the `f32` bit patterns, in order: one line per run instead of
/// 1024 (`host-tests/firmware.rs` computes the same from the host's outputs).
fn fnv1a(bits: impl Iterator<Item = u32>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bits {
        for byte in b.to_le_bytes() {
            h ^= u64::from(byte);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// Block lengths for the block-mode run: every remainder modulo 6 and 3 (the Cortex-M block
/// kernels' loops are six samples long for one or two sections, three for more), an empty
/// block, and long ones.
const CHUNKS: [usize; 12] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 64, 100];

/// The cascade of the first `K` sections on the whole trace, from equilibrium: one sample per
/// call (`C`), and in blocks of the lengths in [`CHUNKS`] (`B`, the rest of the trace in one
/// last block). Reports whether this build runs the Cortex-M kernel and the FNV-1a hash of the
/// output bits of each run.
fn replay_sections<const K: usize>(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let Some(Ok(c)) = coefficients::SECTIONS.get(..K).map(|s| {
        unlag::board::compensator::CascadeCoefficients::<f32, K>::new(coefficients::GAIN, s)
    }) else {
        writeln!(out, "ERROR K={K}: sections refused")?;
        return Ok(false);
    };
    let first = trace::TRACE.first().copied().unwrap_or(0.0);
    let kind = if unlag::board::compensator::f32_cascade_uses_kernel(K) {
        "asm"
    } else {
        "portable"
    };
    writeln!(out, "KERNEL K={K} {kind}")?;
    let mut state = c.equilibrium(first);
    let calls = fnv1a(
        trace::TRACE
            .iter()
            .map(|&y| c.process(&mut state, y).to_bits()),
    );
    writeln!(out, "H K={K} call {calls:016x}")?;
    let mut buf = trace::TRACE;
    let mut state = c.equilibrium(first);
    let mut rest = &mut buf[..];
    for n in CHUNKS.iter().cycle().take(40) {
        let (head, tail) = rest.split_at_mut((*n).min(rest.len()));
        c.process_in_place(&mut state, head);
        rest = tail;
    }
    c.process_in_place(&mut state, rest);
    let blocks = fnv1a(buf.iter().map(|v| v.to_bits()));
    writeln!(out, "H K={K} block {blocks:016x}")?;
    Ok(true)
}

/// The fixed-point cascade through its saturation paths: the hash of the outputs and of the
/// overflow flag after each sample (read and cleared every sample), and how many samples
/// overflowed.
fn replay_fixed_stress(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let Ok(c) = unlag::board::fixed::FixedCascade::<4>::new(&stress::STRESS_SECTIONS) else {
        writeln!(out, "ERROR stress sections refused")?;
        return Ok(false);
    };
    let mut state = unlag::board::fixed::FixedState::default();
    let mut overflows = 0u32;
    let bits = (0..stress::STRESS_LEN).flat_map(|k| {
        let y = c.process(&mut state, stress::stress_input(k));
        let flag = state.take_overflow();
        overflows += u32::from(flag);
        [y as u32, u32::from(flag)]
    });
    let h = fnv1a(bits);
    writeln!(out, "STRESS {h:016x} overflows={overflows}")?;
    Ok(true)
}

/// The direct-form cascade's first `K` sections of `sections` on `input(k)` for `len` samples,
/// one call per sample (`DC`, the overflow flag read and cleared after each sample and hashed
/// with the output), then in blocks of the lengths in [`CHUNKS`] (`DB`, the flag read after
/// each block). Reports whether this build runs the Cortex-M kernel and the FNV-1a hashes.
fn replay_direct<const K: usize>(
    out: &mut impl Write,
    name: &str,
    sections: &[unlag::board::fixed::direct::DirectSection],
    len: usize,
    input: impl Fn(usize) -> i32,
) -> Result<bool, core::fmt::Error> {
    use unlag::board::fixed::direct::{uses_kernel, DirectCascade, DirectState};
    let Some(Ok(c)) = sections.get(..K).map(DirectCascade::<K>::new) else {
        writeln!(out, "ERROR direct {name} K={K}: sections refused")?;
        return Ok(false);
    };
    let kind = if uses_kernel(K) { "asm" } else { "portable" };
    writeln!(out, "DKERNEL {name} K={K} {kind}")?;
    let mut state = DirectState::<K>::default();
    let mut overflows = 0u32;
    let calls = fnv1a((0..len).flat_map(|k| {
        let y = c.process(&mut state, input(k));
        let flag = state.take_overflow();
        overflows += u32::from(flag);
        [y as u32, u32::from(flag)]
    }));
    writeln!(
        out,
        "DH {name} K={K} call {calls:016x} overflows={overflows}"
    )?;
    let mut buf = [0i32; 4096];
    let Some(buf) = buf.get_mut(..len) else {
        return Ok(false);
    };
    for (k, v) in buf.iter_mut().enumerate() {
        *v = input(k);
    }
    let mut state = DirectState::<K>::default();
    let mut flags = [0u32; 64];
    let mut rest = &mut buf[..];
    for (n, f) in CHUNKS.iter().cycle().zip(flags.iter_mut()) {
        let (head, tail) = rest.split_at_mut((*n).min(rest.len()));
        c.process_in_place(&mut state, head);
        *f = u32::from(state.take_overflow());
        rest = tail;
    }
    c.process_in_place(&mut state, rest);
    let last = u32::from(state.take_overflow());
    let blocks = fnv1a(
        buf.iter()
            .map(|v| *v as u32)
            .chain(flags)
            .chain(core::iter::once(last)),
    );
    writeln!(out, "DH {name} K={K} block {blocks:016x}")?;
    Ok(true)
}

/// The direct-form runs: the planned sections on the trace's codes (K = 1, 2, 3, 4: the
/// first K of the m = 8 plan), and the stress sections on the stress input.
fn replay_direct_all(out: &mut impl Write) -> Result<bool, core::fmt::Error> {
    let trace = |k: usize| code(trace::TRACE.get(k).copied().unwrap_or(0.0));
    let n = trace::TRACE.len();
    let s = &direct::SECTIONS_M8;
    let mut ok = replay_direct::<1>(out, "trace", s, n, trace)?;
    ok &= replay_direct::<2>(out, "trace", s, n, trace)?;
    ok &= replay_direct::<3>(out, "trace", s, n, trace)?;
    ok &= replay_direct::<4>(out, "trace", s, n, trace)?;
    let st = &stress::DIRECT_STRESS_SECTIONS;
    let len = stress::STRESS_LEN;
    ok &= replay_direct::<1>(out, "stress", st, len, stress::stress_input)?;
    ok &= replay_direct::<2>(out, "stress", st, len, stress::stress_input)?;
    ok &= replay_direct::<3>(out, "stress", st, len, stress::stress_input)?;
    ok &= replay_direct::<4>(out, "stress", st, len, stress::stress_input)?;
    Ok(ok)
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
    let mut sections_ok = replay_sections::<1>(out)?;
    sections_ok &= replay_sections::<2>(out)?;
    sections_ok &= replay_sections::<3>(out)?;
    sections_ok &= replay_sections::<4>(out)?;
    sections_ok &= replay_fixed_stress(out)?;
    sections_ok &= replay_direct_all(out)?;
    let ok = refused && fixed_ok && sections_ok;
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
