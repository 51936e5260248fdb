//! The fixed-point compensators on Q1.31 codes of the same samples: the normal form
//! (`fixed`), the direct form (`direct`), and idsp's `Q32<30>` cascade on the direct form's
//! integers (`idspq`), one call per sample and over a block, each checked against the f64
//! reference.

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use dsp_fixedpoint::Q32;
use dsp_process::SplitProcess;
use idsp::iir::{Biquad, Cascade, DirectForm};
use unlag::board::fixed::direct::{DirectCascade, DirectSection, DirectState};
use unlag::board::fixed::{FixedCascade, FixedSection, FixedState};

use crate::board::{direct, fixed, measure, report, N};

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

/// The fixed-point compensator for K sections (m = 2K) on the same samples, as Q1.31 codes
/// of the full scale; its output is checked against the f64 reference in `reference`.
pub fn bench_fixed<const K: usize>(
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
pub fn bench_direct<const K: usize>(
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
    #[cfg(unlag_bench_cmsis)]
    let mut y_direct = [0i32; N];
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
        #[cfg(unlag_bench_cmsis)]
        y_direct.copy_from_slice(&y);
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
    // CMSIS-DSP (only when bench/board.sh links it) on the same integers, compared with
    // idsp's output and unlag's direct form too.
    #[cfg(unlag_bench_cmsis)]
    crate::cmsis::bench_q31(
        &sections.map(|s| {
            let [b0, b1, b2] = s.b;
            let [na1, na2] = s.neg_a;
            [b0, b1, b2, na1, na2]
        }),
        &codes,
        out_scale,
        reference,
        &y,
        &y_direct,
    );
    {
        let c = black_box(&idsp);
        let mut s = DirectForm::<i32, K> {
            x: [0; 2],
            y: [[0; 2]; K],
        };
        let t = measure(|| block_idspq(c, &mut s, black_box(&codes[..]), black_box(&mut y[..])));
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
