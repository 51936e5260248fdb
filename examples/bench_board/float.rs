//! The `f32` compensator (`unlag`) beside idsp's `f32` biquad cascade on the same
//! coefficients and samples: m = 2K, one call per sample and over a block, each checked
//! against an f64 reference of the design.

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use dsp_process::SplitProcess;
use idsp::iir::{Biquad, Cascade, DirectForm};
use unlag::board::compensator::{CascadeCoefficients, CascadeState};

use crate::board::{coefficients, measure, report, N};

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

/// Largest |a - b| over the samples.
fn max_diff(a: &[f32], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - y).abs())
        .fold(0.0, f64::max)
}

/// One model order: K = m/2 sections of the exported design. Returns whether both
/// implementations match the f64 reference.
pub fn bench<const K: usize>(x: &[f32; N], y: &mut [f32; N], reference: &mut [f64; N]) -> bool {
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
    // CMSIS-DSP's biquads take the same arrays.
    let mut first = true;
    let ba: [[f32; 5]; K] = core::array::from_fn(|i| {
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
        [b0 * g, b1 * g, b2 * g, -a1, -a2].map(|v| v as f32)
    });
    let idsp = Cascade(ba.map(Biquad::from));
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
    // CMSIS-DSP (only when bench/board.sh links it), compared with unlag's output too.
    #[cfg(unlag_bench_cmsis)]
    let cmsis_ok = crate::cmsis::bench_f32(&ba, x, reference, y);
    #[cfg(not(unlag_bench_cmsis))]
    let cmsis_ok = true;
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
    ok && cmsis_ok
}
