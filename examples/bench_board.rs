//! Board benchmark: instructions per sample of the `f32` compensator on a Cortex-M4F in QEMU,
//! for model orders m = 2, 4, 8 (m/2 second-order sections), called once per sample (ISR
//! style, state by reference) and over a block, with the `idsp` crate's biquad cascade run
//! beside it on the same coefficients and samples as the baseline.
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
//! On the host this example only prints how to run it.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    println!("bench_board runs on the board: bash bench/board.sh (QEMU, thumbv7em-none-eabihf)");
}

#[cfg(target_os = "none")]
mod board {
    use core::hint::black_box;
    use core::sync::atomic::{compiler_fence, Ordering::SeqCst};

    use cortex_m::peripheral::{syst::SystClkSource, SYST};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    use dsp_fixedpoint::Q32;
    use dsp_process::SplitProcess;
    use idsp::iir::{Biquad, Cascade, DirectForm};
    use panic_semihosting as _;
    use unlag::compensator::{
        BankChannel, CascadeCoefficients, CascadeState, NonlinearDampingCoefficients,
        NonlinearDampingState, TemperatureBank,
    };
    use unlag::fixed::direct::{DirectCascade, DirectSection, DirectState};
    use unlag::fixed::{FixedCascade, FixedSection, FixedState};

    mod coefficients {
        #![allow(dead_code)]
        include!("data/board_coefficients.rs");
    }
    mod trace {
        include!("data/board_trace.rs");
    }
    /// Fixed-point sections of the same design (`unlag::design::quantise::FixedPlan`, made by
    /// host-tests/export.rs).
    mod fixed {
        include!("data/board_fixed.rs");
    }
    /// Direct-form sections of the same design (`unlag::design::quantise::DirectPlan`, made by
    /// host-tests/export.rs).
    mod direct {
        include!("data/board_direct.rs");
    }

    const N: usize = 1024;
    /// Guest instructions per SysTick tick (25 MHz SysTick, `-icount shift=0`).
    const INSN_PER_TICK: u64 = 40;

    /// SysTick ticks spent in `f`.
    #[inline(always)]
    fn measure(f: impl FnOnce()) -> u32 {
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
    fn report(name: &str, m: usize, mode: &str, n: usize, ticks: u32) {
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

    #[inline(never)]
    fn call_unlag<const K: usize>(
        c: &CascadeCoefficients<f32, K>,
        s: &mut CascadeState<f32, K>,
        x: f32,
    ) -> f32 {
        c.process(s, x)
    }

    #[inline(never)]
    fn block_unlag<const K: usize>(
        c: &CascadeCoefficients<f32, K>,
        s: &mut CascadeState<f32, K>,
        buf: &mut [f32],
    ) {
        c.process_in_place(s, buf);
    }

    #[inline(never)]
    fn call_idsp<const K: usize>(
        c: &Cascade<[Biquad<f32>; K]>,
        s: &mut DirectForm<f32, K>,
        x: f32,
    ) -> f32 {
        c.process(s, x)
    }

    #[inline(never)]
    fn block_idsp<const K: usize>(
        c: &Cascade<[Biquad<f32>; K]>,
        s: &mut DirectForm<f32, K>,
        x: &[f32],
        y: &mut [f32],
    ) {
        c.block(s, x, y);
    }

    /// The board-side blob parser, out of line so that `.ci/no-panic.sh` can check it too.
    #[inline(never)]
    fn parse_blob(bytes: &[u8]) -> Result<unlag::blob::CoefficientSet<4>, unlag::blob::BlobError> {
        unlag::blob::parse(bytes)
    }

    /// The board-side parser of the direct-form blob, out of line so that `.ci/no-panic.sh`
    /// checks it too.
    #[inline(never)]
    fn parse_direct_blob(
        bytes: &[u8],
    ) -> Result<unlag::blob::DirectCoefficientSet<4>, unlag::blob::BlobError> {
        unlag::blob::parse_direct(bytes)
    }

    #[inline(never)]
    fn call_fixed<const K: usize>(c: &FixedCascade<K>, s: &mut FixedState<K>, x: i32) -> i32 {
        c.process(s, x)
    }

    #[inline(never)]
    fn block_fixed<const K: usize>(c: &FixedCascade<K>, s: &mut FixedState<K>, buf: &mut [i32]) {
        c.process_in_place(s, buf);
    }

    #[inline(never)]
    fn call_direct<const K: usize>(c: &DirectCascade<K>, s: &mut DirectState<K>, x: i32) -> i32 {
        c.process(s, x)
    }

    #[inline(never)]
    fn block_direct<const K: usize>(c: &DirectCascade<K>, s: &mut DirectState<K>, buf: &mut [i32]) {
        c.process_in_place(s, buf);
    }

    #[inline(never)]
    fn call_idspq<const K: usize>(
        c: &Cascade<[Biquad<Q32<30>>; K]>,
        s: &mut DirectForm<i32, K>,
        x: i32,
    ) -> i32 {
        c.process(s, x)
    }

    #[inline(never)]
    fn block_idspq<const K: usize>(
        c: &Cascade<[Biquad<Q32<30>>; K]>,
        s: &mut DirectForm<i32, K>,
        x: &[i32],
        y: &mut [i32],
    ) {
        c.block(s, x, y);
    }

    /// The compensator with the nonlinear-damping correction, one sample.
    #[inline(never)]
    fn call_nonlinear<const K: usize, const L: usize>(
        c: &CascadeCoefficients<f32, K>,
        s: &mut CascadeState<f32, K>,
        nc: &NonlinearDampingCoefficients<f32, L>,
        ns: &mut NonlinearDampingState<f32, L>,
        x: f32,
    ) -> f32 {
        c.process(s, x) + nc.process(ns, x)
    }

    /// The m = 4 compensator plus the nonlinear-damping correction through a two-section
    /// low-pass (what a 4th-order Bessel band limit gives), one call per sample, checked
    /// against the same in f64. The low-pass here reuses the design's own sections: the
    /// cost does not depend on the values. Reports `nonlin m=4 call`.
    fn bench_nonlinear(x: &[f32; N], y: &mut [f32; N]) -> bool {
        let Some(sections) = coefficients::SECTIONS.get(..2) else {
            return false;
        };
        // Correction gain per squared sample difference: the trace's steps make it a few
        // percent of the output.
        let gain = 1e-4;
        let (Ok(c), Ok(nc), Ok(c64), Ok(nc64)) = (
            CascadeCoefficients::<f32, 2>::new(coefficients::GAIN, sections),
            NonlinearDampingCoefficients::<f32, 2>::new(gain, 1.0, sections),
            CascadeCoefficients::<f64, 2>::new(coefficients::GAIN, sections),
            NonlinearDampingCoefficients::<f64, 2>::new(gain, 1.0, sections),
        ) else {
            hprintln!("ERROR nonlinear: coefficients refused");
            return false;
        };
        let x0 = x.first().copied().unwrap_or(0.0);
        let (c, nc) = (black_box(&c), black_box(&nc));
        let mut s = c.equilibrium(x0);
        let mut ns = nc.equilibrium(x0);
        let t = measure(|| {
            for (xi, yi) in x.iter().zip(y.iter_mut()) {
                *yi = call_nonlinear(c, &mut s, nc, &mut ns, *xi);
            }
        });
        report("nonlin", 4, "call", N, t);
        let mut s64 = c64.equilibrium(f64::from(x0));
        let mut ns64 = nc64.equilibrium(f64::from(x0));
        let mut e = 0.0f64;
        for (xi, yi) in x.iter().zip(y.iter()) {
            let v = f64::from(*xi);
            let r = c64.process(&mut s64, v) + nc64.process(&mut ns64, v);
            e = e.max((f64::from(*yi) - r).abs());
        }
        let pass = e < 0.05;
        hprintln!(
            "CHECK  nonlin m=4 call   max|y - f64 reference|={} Pa {}",
            e,
            if pass { "ok" } else { "FAIL" }
        );
        pass
    }

    /// The temperature bank's per-sample call (issue 7's `temperature` on the board).
    #[inline(never)]
    fn call_bank<const S: usize, const K: usize>(
        bank: &TemperatureBank<f32, S, K>,
        ch: &mut BankChannel<f32, K>,
        x: f32,
    ) -> f32 {
        bank.process(ch, x)
    }

    /// A new gas temperature for the channel, between samples.
    #[inline(never)]
    fn bank_temperature<const S: usize, const K: usize>(
        bank: &TemperatureBank<f32, S, K>,
        ch: &mut BankChannel<f32, K>,
        t: f32,
    ) -> bool {
        bank.set_temperature(ch, t)
    }

    /// A bank of three m = 4 sets (the design's sections; the cost does not depend on the
    /// values), one call per sample at a steady temperature: the output must be bit-identical
    /// to the plain cascade's. Then a swap with its warm-up, checked against the f64
    /// reference of the same sets. Reports `bank m=4 call`.
    fn bench_bank(x: &[f32; N], y: &mut [f32; N]) -> bool {
        let Some(sections) = coefficients::SECTIONS.get(..2) else {
            return false;
        };
        let sets = [sections, sections, sections];
        let gains = [coefficients::GAIN; 3];
        let (Ok(bank), Ok(c)) = (
            TemperatureBank::<f32, 3, 2>::new(&[273.15, 293.15, 313.15], &gains, &sets, 10.0, 64),
            CascadeCoefficients::<f32, 2>::new(coefficients::GAIN, sections),
        ) else {
            hprintln!("ERROR bank: coefficients refused");
            return false;
        };
        let x0 = x.first().copied().unwrap_or(0.0);
        let bank = black_box(&bank);
        let mut ch = bank.channel(293.15, x0);
        let t = measure(|| {
            for (xi, yi) in x.iter().zip(y.iter_mut()) {
                *yi = call_bank(bank, &mut ch, *xi);
            }
        });
        report("bank", 4, "call", N, t);
        let mut s = c.equilibrium(x0);
        let same = x
            .iter()
            .zip(y.iter())
            .all(|(xi, yi)| c.process(&mut s, *xi).to_bits() == yi.to_bits());
        // A swap to the 313 K set (identical sections) half-way: its warm-up starts it in
        // equilibrium with the last input, so it joins the reference within the warm-up.
        let Ok(c64) = CascadeCoefficients::<f64, 2>::new(coefficients::GAIN, sections) else {
            return false;
        };
        let mut ch = bank.channel(293.15, x0);
        let mut s64 = c64.equilibrium(f64::from(x0));
        let mut swapped = false;
        let mut e = 0.0f64;
        for (k, xi) in x.iter().enumerate() {
            if k == N / 2 {
                swapped = bank_temperature(bank, &mut ch, black_box(320.0));
            }
            let v = call_bank(bank, &mut ch, *xi);
            let r = c64.process(&mut s64, f64::from(*xi));
            e = e.max((f64::from(v) - r).abs());
        }
        let pass = same && swapped && ch.selected() == 2 && e < 0.05;
        hprintln!(
            "CHECK  bank m=4 call     same bits as the cascade: {}, swap to set {}, max|y - f64 reference|={} Pa {}",
            same,
            ch.selected(),
            e,
            if pass { "ok" } else { "FAIL" }
        );
        pass
    }

    #[inline(never)]
    fn call_empty(x: f32) -> f32 {
        black_box(x)
    }

    /// Largest |a - b| over the samples.
    fn max_diff(a: &[f32], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (f64::from(*x) - y).abs())
            .fold(0.0, f64::max)
    }

    /// One model order: K = m/2 sections of the exported design. Returns whether both
    /// implementations match the f64 reference.
    fn bench<const K: usize>(x: &[f32; N], y: &mut [f32; N], reference: &mut [f64; N]) -> bool {
        let m = 2 * K;
        let Some(sections) = coefficients::SECTIONS.get(..K) else {
            return false;
        };
        let (Ok(c), Ok(c64)) = (
            CascadeCoefficients::<f32, K>::new(coefficients::GAIN, sections),
            CascadeCoefficients::<f64, K>::new(coefficients::GAIN, sections),
        ) else {
            hprintln!("ERROR m={}: coefficients refused", m);
            return false;
        };
        // f64 reference (soft float on the M4; outside the windows).
        let mut s64 = CascadeState::default();
        for (r, xi) in reference.iter_mut().zip(x) {
            *r = c64.process(&mut s64, f64::from(*xi));
        }
        // idsp: the same sections in its convention ([b0, b1, b2, -a1, -a2]), gain folded
        // into the first section's numerator.
        let mut first = true;
        let ba: [Biquad<f32>; K] = core::array::from_fn(|i| {
            let [b0, b1, b2, a1, a2] = sections
                .get(i)
                .copied()
                .unwrap_or([1.0, 0.0, 0.0, 0.0, 0.0]);
            let g = if core::mem::take(&mut first) {
                coefficients::GAIN
            } else {
                1.0
            };
            #[allow(clippy::cast_possible_truncation)]
            Biquad::from([b0 * g, b1 * g, b2 * g, -a1, -a2].map(|v| v as f32))
        });
        let idsp = Cascade(ba);
        let mut ok = true;
        let mut check = |name: &str, mode: &str, y: &[f32], reference: &[f64]| {
            let e = max_diff(y, reference);
            let pass = e < 0.05;
            ok &= pass;
            hprintln!(
                "CHECK  {:<6} m={} {:<6} max|y - f64 reference|={} Pa {}",
                name,
                m,
                mode,
                e,
                if pass { "ok" } else { "FAIL" }
            );
        };

        // unlag, one call per sample, state by reference.
        {
            let c = black_box(&c);
            let mut s = CascadeState::default();
            let t = measure(|| {
                for (xi, yi) in x.iter().zip(y.iter_mut()) {
                    *yi = call_unlag(c, &mut s, *xi);
                }
            });
            report("unlag", m, "call", N, t);
            check("unlag", "call", y, reference);
        }
        // unlag, block in place: 1024, then 512 (the difference is the marginal cost).
        {
            let c = black_box(&c);
            let mut s = CascadeState::default();
            y.copy_from_slice(x);
            let t = measure(|| block_unlag(c, &mut s, black_box(&mut y[..])));
            report("unlag", m, "block", N, t);
            check("unlag", "block", y, reference);
            let t = measure(|| block_unlag(c, &mut s, black_box(&mut y[..N / 2])));
            report("unlag", m, "block", N / 2, t);
        }
        // idsp, one call per sample.
        {
            let c = black_box(&idsp);
            let mut s = DirectForm::<f32, K> {
                x: [0.0; 2],
                y: [[0.0; 2]; K],
            };
            let t = measure(|| {
                for (xi, yi) in x.iter().zip(y.iter_mut()) {
                    *yi = call_idsp(c, &mut s, *xi);
                }
            });
            report("idsp", m, "call", N, t);
            check("idsp", "call", y, reference);
        }
        // idsp, block.
        {
            let c = black_box(&idsp);
            let mut s = DirectForm::<f32, K> {
                x: [0.0; 2],
                y: [[0.0; 2]; K],
            };
            let t = measure(|| block_idsp(c, &mut s, black_box(&x[..]), black_box(&mut y[..])));
            report("idsp", m, "block", N, t);
            check("idsp", "block", y, reference);
            let t = measure(|| {
                block_idsp(
                    c,
                    &mut s,
                    black_box(&x[..N / 2]),
                    black_box(&mut y[..N / 2]),
                )
            });
            report("idsp", m, "block", N / 2, t);
        }
        ok
    }

    /// The fixed-point compensator for K sections (m = 2K) on the same samples, as Q1.31 codes
    /// of the full scale; its output is checked against the f64 reference in `reference`.
    fn bench_fixed<const K: usize>(
        sections: &[FixedSection; K],
        output_exponent: i32,
        x: &[f32; N],
        reference: &[f64; N],
    ) -> bool {
        let m = 2 * K;
        let Ok(c) = FixedCascade::<K>::new(sections) else {
            hprintln!("ERROR m={}: fixed-point sections refused", m);
            return false;
        };
        let to_code = |p: f32| -> i32 {
            let v = libm::round(f64::from(p) / fixed::FULL_SCALE * 2_147_483_648.0);
            #[allow(clippy::cast_possible_truncation)]
            let code = v.clamp(-2_147_483_648.0, 2_147_483_647.0) as i32;
            code
        };
        let out_scale = libm::exp2(f64::from(output_exponent) - 31.0) * fixed::FULL_SCALE;
        let mut codes = [0i32; N];
        for (c, p) in codes.iter_mut().zip(x) {
            *c = to_code(*p);
        }
        let mut y = [0i32; N];
        let mut ok = true;
        let mut check = |mode: &str, y: &[i32], overflowed: bool| {
            let e = y
                .iter()
                .zip(reference)
                .map(|(q, r)| (f64::from(*q) * out_scale - r).abs())
                .fold(0.0, f64::max);
            let pass = e < 0.05 && !overflowed;
            ok &= pass;
            hprintln!(
                "CHECK  {:<6} m={} {:<6} max|y - f64 reference|={} Pa overflow={} {}",
                "fixed",
                m,
                mode,
                e,
                overflowed,
                if pass { "ok" } else { "FAIL" }
            );
        };
        {
            let c = black_box(&c);
            let mut s = FixedState::<K>::default();
            let t = measure(|| {
                for (xi, yi) in codes.iter().zip(y.iter_mut()) {
                    *yi = call_fixed(c, &mut s, *xi);
                }
            });
            report("fixed", m, "call", N, t);
            check("call", &y, s.overflowed());
        }
        {
            let c = black_box(&c);
            let mut s = FixedState::<K>::default();
            y.copy_from_slice(&codes);
            let t = measure(|| block_fixed(c, &mut s, black_box(&mut y[..])));
            report("fixed", m, "block", N, t);
            check("block", &y, s.overflowed());
            let t = measure(|| block_fixed(c, &mut s, black_box(&mut y[..N / 2])));
            report("fixed", m, "block", N / 2, t);
        }
        ok
    }

    /// The direct-form compensator (`direct`) for K sections (m = 2K) on the same samples as
    /// Q1.31 codes, and beside it idsp's fixed-point cascade (`idspq`: `Biquad<Q32<30>>`, the
    /// same integer coefficients, truncation without error feedback, wrapping); both checked
    /// against the f64 reference in `reference` (idsp's result reported, not required).
    fn bench_direct<const K: usize>(
        sections: &[DirectSection; K],
        output_exponent: i32,
        x: &[f32; N],
        reference: &[f64; N],
    ) -> bool {
        let m = 2 * K;
        let Ok(c) = DirectCascade::<K>::new(sections) else {
            hprintln!("ERROR m={}: direct-form sections refused", m);
            return false;
        };
        let idsp = Cascade(sections.map(|s| {
            let [b0, b1, b2] = s.b;
            let [na1, na2] = s.neg_a;
            Biquad {
                ba: [b0, b1, b2, na1, na2].map(Q32::<30>::from_bits),
            }
        }));
        let mut codes = [0i32; N];
        for (c, p) in codes.iter_mut().zip(x) {
            let v = libm::round(f64::from(*p) / direct::FULL_SCALE * 2_147_483_648.0);
            #[allow(clippy::cast_possible_truncation)]
            let code = v.clamp(-2_147_483_648.0, 2_147_483_647.0) as i32;
            *c = code;
        }
        let out_scale = libm::exp2(f64::from(output_exponent) - 31.0) * direct::FULL_SCALE;
        let mut y = [0i32; N];
        let mut ok = true;
        let mut check = |name: &str, mode: &str, y: &[i32], overflowed: bool, required: bool| {
            let e = y
                .iter()
                .zip(reference)
                .map(|(q, r)| (f64::from(*q) * out_scale - r).abs())
                .fold(0.0, f64::max);
            let pass = e < 0.05 && !overflowed;
            ok &= pass || !required;
            hprintln!(
                "CHECK  {:<6} m={} {:<6} max|y - f64 reference|={} Pa overflow={} {}",
                name,
                m,
                mode,
                e,
                overflowed,
                if pass {
                    "ok"
                } else if required {
                    "FAIL"
                } else {
                    "(reference only)"
                }
            );
        };
        {
            let c = black_box(&c);
            let mut s = DirectState::<K>::default();
            let t = measure(|| {
                for (xi, yi) in codes.iter().zip(y.iter_mut()) {
                    *yi = call_direct(c, &mut s, *xi);
                }
            });
            report("direct", m, "call", N, t);
            check("direct", "call", &y, s.overflowed(), true);
        }
        {
            let c = black_box(&c);
            let mut s = DirectState::<K>::default();
            y.copy_from_slice(&codes);
            let t = measure(|| block_direct(c, &mut s, black_box(&mut y[..])));
            report("direct", m, "block", N, t);
            check("direct", "block", &y, s.overflowed(), true);
            let t = measure(|| block_direct(c, &mut s, black_box(&mut y[..N / 2])));
            report("direct", m, "block", N / 2, t);
        }
        {
            let c = black_box(&idsp);
            let mut s = DirectForm::<i32, K> {
                x: [0; 2],
                y: [[0; 2]; K],
            };
            let t = measure(|| {
                for (xi, yi) in codes.iter().zip(y.iter_mut()) {
                    *yi = call_idspq(c, &mut s, *xi);
                }
            });
            report("idspq", m, "call", N, t);
            check("idspq", "call", &y, false, false);
        }
        {
            let c = black_box(&idsp);
            let mut s = DirectForm::<i32, K> {
                x: [0; 2],
                y: [[0; 2]; K],
            };
            let t =
                measure(|| block_idspq(c, &mut s, black_box(&codes[..]), black_box(&mut y[..])));
            report("idspq", m, "block", N, t);
            check("idspq", "block", &y, false, false);
            let t = measure(|| {
                block_idspq(
                    c,
                    &mut s,
                    black_box(&codes[..N / 2]),
                    black_box(&mut y[..N / 2]),
                )
            });
            report("idspq", m, "block", N / 2, t);
        }
        ok
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
        let mut direct_blob = [0u8; unlag::blob::encoded_len_direct(4)];
        let parsed = unlag::blob::encode_direct(
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
        let mut ok = bench::<1>(x, &mut y, &mut reference);
        ok &= bench_fixed(
            &fixed::SECTIONS_M2,
            fixed::OUTPUT_EXPONENT_M2,
            x,
            &reference,
        );
        ok &= bench_direct(
            &direct::SECTIONS_M2,
            direct::OUTPUT_EXPONENT_M2,
            x,
            &reference,
        );
        ok &= bench::<2>(x, &mut y, &mut reference);
        ok &= bench_fixed(
            &fixed::SECTIONS_M4,
            fixed::OUTPUT_EXPONENT_M4,
            x,
            &reference,
        );
        ok &= bench_direct(
            &direct::SECTIONS_M4,
            direct::OUTPUT_EXPONENT_M4,
            x,
            &reference,
        );
        ok &= bench::<4>(x, &mut y, &mut reference);
        ok &= bench_fixed(
            &fixed::SECTIONS_M8,
            fixed::OUTPUT_EXPONENT_M8,
            x,
            &reference,
        );
        ok &= bench_direct(
            &direct::SECTIONS_M8,
            direct::OUTPUT_EXPONENT_M8,
            x,
            &reference,
        );
        ok &= bench_nonlinear(x, &mut y);
        ok &= bench_bank(x, &mut y);
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
