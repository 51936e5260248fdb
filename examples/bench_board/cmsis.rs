//! CMSIS-DSP's biquad cascades on the same coefficients and samples, as a second baseline:
//! `arm_biquad_cascade_df2T_f32` (`cmsis`) and `arm_biquad_cascade_df1_f32` (`cmsis1`) on the
//! `f32` sections in CMSIS's convention (`[b0, b1, b2, -a1, -a2]`, the gain folded into the
//! first numerator: idsp's arrays), `arm_biquad_cascade_df1_q31` (`cmsisq`) and
//! `arm_biquad_cas_df1_32x64_q31` (`cmsq64`: 64-bit feedback state) on the direct form's
//! Q2.30 integers with `postShift = 1`. One call per sample (`blockSize = 1`) and over a
//! block, like the other rows.
//!
//! Compiled only when `bash bench/board.sh` sets `--cfg unlag_bench_cmsis` and hands the
//! linker the static library it builds from CMSIS-DSP's C sources (`libcmsisbench.a`, with
//! arm-none-eabi-gcc). Nothing of CMSIS-DSP is in the repository.
#![allow(unsafe_code)] // the C functions and their instance structures

use core::hint::black_box;

use cortex_m_semihosting::hprintln;

use crate::board::{measure, report, N};

/// `arm_biquad_cascade_df2T_instance_f32`.
#[repr(C)]
struct Df2TF32 {
    num_stages: u8,
    state: *mut f32,
    coeffs: *const f32,
}

/// `arm_biquad_casd_df1_inst_f32`.
#[repr(C)]
struct Df1F32 {
    num_stages: u32,
    state: *mut f32,
    coeffs: *const f32,
}

/// `arm_biquad_casd_df1_inst_q31`.
#[repr(C)]
struct Df1Q31 {
    num_stages: u32,
    state: *mut i32,
    coeffs: *const i32,
    post_shift: u8,
}

/// `arm_biquad_cas_df1_32x64_ins_q31`.
#[repr(C)]
struct Df1Q31x64 {
    num_stages: u8,
    state: *mut i64,
    coeffs: *const i32,
    post_shift: u8,
}

#[link(name = "cmsisbench", kind = "static")]
extern "C" {
    fn arm_biquad_cascade_df2T_init_f32(s: *mut Df2TF32, n: u8, c: *const f32, st: *mut f32);
    fn arm_biquad_cascade_df2T_f32(s: *const Df2TF32, x: *const f32, y: *mut f32, n: u32);
    fn arm_biquad_cascade_df1_init_f32(s: *mut Df1F32, n: u8, c: *const f32, st: *mut f32);
    fn arm_biquad_cascade_df1_f32(s: *const Df1F32, x: *const f32, y: *mut f32, n: u32);
    fn arm_biquad_cascade_df1_init_q31(
        s: *mut Df1Q31,
        n: u8,
        c: *const i32,
        st: *mut i32,
        post_shift: i8,
    );
    fn arm_biquad_cascade_df1_q31(s: *const Df1Q31, x: *const i32, y: *mut i32, n: u32);
    fn arm_biquad_cas_df1_32x64_init_q31(
        s: *mut Df1Q31x64,
        n: u8,
        c: *const i32,
        st: *mut i64,
        post_shift: u8,
    );
    fn arm_biquad_cas_df1_32x64_q31(s: *const Df1Q31x64, x: *const i32, y: *mut i32, n: u32);
}

/// One of the four: its instance, a sample through it and a block through it.
trait Filter {
    type T: Copy + Default;
    fn run(&self, x: &[Self::T], y: &mut [Self::T]);
}

macro_rules! filter {
    ($inst:ty, $t:ty, $f:ident) => {
        impl Filter for $inst {
            type T = $t;
            #[inline(always)]
            fn run(&self, x: &[$t], y: &mut [$t]) {
                let n = x.len().min(y.len()) as u32;
                // SAFETY: the instance was set up by its init function on coefficient and
                // state arrays that outlive it; x and y hold n samples each.
                unsafe { $f(self, x.as_ptr(), y.as_mut_ptr(), n) }
            }
        }
    };
}
filter!(Df2TF32, f32, arm_biquad_cascade_df2T_f32);
filter!(Df1F32, f32, arm_biquad_cascade_df1_f32);
filter!(Df1Q31, i32, arm_biquad_cascade_df1_q31);
filter!(Df1Q31x64, i32, arm_biquad_cas_df1_32x64_q31);

/// One sample, out of line (ISR style): `arm_..._(&S, &x, &y, 1)`.
#[inline(never)]
fn call<F: Filter>(f: &F, x: F::T) -> F::T {
    let mut y = F::T::default();
    f.run(core::slice::from_ref(&x), core::slice::from_mut(&mut y));
    y
}

/// A block, out of line.
#[inline(never)]
fn block<F: Filter>(f: &F, x: &[F::T], y: &mut [F::T]) {
    f.run(x, y);
}

/// Measures one call per sample over the N samples (output in `y`), then a block of N and
/// one of N/2, each from a fresh state made by `fresh`.
fn measure_all<F: Filter>(
    name: &str,
    m: usize,
    fresh: &mut dyn FnMut() -> F,
    x: &[F::T; N],
    y: &mut [F::T; N],
    y_block: &mut [F::T; N],
) {
    {
        let f = fresh();
        let f = black_box(&f);
        let t = measure(|| {
            for (xi, yi) in x.iter().zip(y.iter_mut()) {
                *yi = call(f, *xi);
            }
        });
        report(name, m, "call", N, t);
    }
    {
        let f = fresh();
        let f = black_box(&f);
        let t = measure(|| block(f, black_box(&x[..]), black_box(&mut y_block[..])));
        report(name, m, "block", N, t);
        let mut half = [F::T::default(); N];
        let t = measure(|| block(f, black_box(&x[..N / 2]), black_box(&mut half[..N / 2])));
        report(name, m, "block", N / 2, t);
    }
}

/// Largest |a - b|.
fn max_diff_f32(a: &[f32], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - y).abs())
        .fold(0.0, f64::max)
}

/// The `f32` rows for K sections (`coeffs`: `[b0, b1, b2, -a1, -a2]` each, gain in the
/// first); checked against the f64 reference and against unlag's `f32` output (`unlag`).
pub fn bench_f32<const K: usize>(
    coeffs: &[[f32; 5]; K],
    x: &[f32; N],
    reference: &[f64; N],
    unlag: &[f32; N],
) -> bool {
    let m = 2 * K;
    let flat: [f32; 40] = core::array::from_fn(|i| {
        coeffs
            .get(i / 5)
            .and_then(|c| c.get(i % 5))
            .copied()
            .unwrap_or(0.0)
    });
    let mut ok = true;
    let mut y = [0.0f32; N];
    let mut yb = [0.0f32; N];
    let mut check = |name: &str, y: &[f32], yb: &[f32]| {
        for (mode, y) in [("call", y), ("block", yb)] {
            let e = max_diff_f32(y, reference);
            let d = y
                .iter()
                .zip(unlag)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            let pass = e < 0.05;
            ok &= pass;
            hprintln!(
                "CHECK  {:<6} m={} {:<6} max|y - f64 reference|={} Pa max|y - unlag|={} Pa {}",
                name,
                m,
                mode,
                e,
                d,
                if pass { "ok" } else { "FAIL" }
            );
        }
    };
    // The state arrays outlive the instances that point into them (one per measurement).
    let mut st = [[0.0f32; 16]; 3];
    let mut i = 0;
    let [s0, s1, s2] = &mut st;
    let mut states = [s0, s1, s2];
    measure_all(
        "cmsis",
        m,
        &mut || {
            let st = states[i % 3].as_mut_ptr();
            i += 1;
            let mut s = Df2TF32 {
                num_stages: 0,
                state: core::ptr::null_mut(),
                coeffs: core::ptr::null(),
            };
            // SAFETY: 5K coefficients and 2K (of 16) state words, both outliving `s`.
            unsafe { arm_biquad_cascade_df2T_init_f32(&mut s, K as u8, flat.as_ptr(), st) };
            s
        },
        x,
        &mut y,
        &mut yb,
    );
    check("cmsis", &y, &yb);
    measure_all(
        "cmsis1",
        m,
        &mut || {
            let st = states[i % 3].as_mut_ptr();
            i += 1;
            let mut s = Df1F32 {
                num_stages: 0,
                state: core::ptr::null_mut(),
                coeffs: core::ptr::null(),
            };
            // SAFETY: 5K coefficients and 4K (of 16) state words, both outliving `s`.
            unsafe { arm_biquad_cascade_df1_init_f32(&mut s, K as u8, flat.as_ptr(), st) };
            s
        },
        x,
        &mut y,
        &mut yb,
    );
    check("cmsis1", &y, &yb);
    ok
}

/// The Q31 rows for K sections of the direct form (`coeffs`: `[b0, b1, b2, -a1, -a2]` as
/// Q2.30 integers, run as Q1.31 with `postShift = 1`) on the input codes; `out_scale` turns
/// an output code into Pa. Checked against the f64 reference (reported, not required, like
/// idsp's row), against idsp's `Q32<30>` output (`idspq`: the same arithmetic as `cmsisq`) and
/// against unlag's direct form (`direct`).
pub fn bench_q31<const K: usize>(
    coeffs: &[[i32; 5]; K],
    codes: &[i32; N],
    out_scale: f64,
    reference: &[f64; N],
    idspq: &[i32; N],
    direct: &[i32; N],
) {
    let m = 2 * K;
    let flat: [i32; 40] = core::array::from_fn(|i| {
        coeffs
            .get(i / 5)
            .and_then(|c| c.get(i % 5))
            .copied()
            .unwrap_or(0)
    });
    let mut y = [0i32; N];
    let mut yb = [0i32; N];
    let check = |name: &str, y: &[i32], yb: &[i32]| {
        for (mode, y) in [("call", y), ("block", yb)] {
            let e = y
                .iter()
                .zip(reference)
                .map(|(q, r)| (f64::from(*q) * out_scale - r).abs())
                .fold(0.0, f64::max);
            let diff = |other: &[i32; N]| {
                y.iter()
                    .zip(other)
                    .map(|(a, b)| a.abs_diff(*b))
                    .max()
                    .unwrap_or(0)
            };
            hprintln!(
                "CHECK  {:<6} m={} {:<6} max|y - f64 reference|={} Pa max|y - idspq|={} codes max|y - direct|={} codes {}",
                name,
                m,
                mode,
                e,
                diff(idspq),
                diff(direct),
                if e < 0.05 { "ok" } else { "(reference only)" }
            );
        }
    };
    let mut st = [[0i32; 16]; 3];
    let mut i = 0;
    {
        let [s0, s1, s2] = &mut st;
        let mut states = [s0, s1, s2];
        measure_all(
            "cmsisq",
            m,
            &mut || {
                let st = states[i % 3].as_mut_ptr();
                i += 1;
                let mut s = Df1Q31 {
                    num_stages: 0,
                    state: core::ptr::null_mut(),
                    coeffs: core::ptr::null(),
                    post_shift: 0,
                };
                // SAFETY: 5K coefficients and 4K (of 16) state words, both outliving `s`.
                unsafe { arm_biquad_cascade_df1_init_q31(&mut s, K as u8, flat.as_ptr(), st, 1) };
                s
            },
            codes,
            &mut y,
            &mut yb,
        );
    }
    check("cmsisq", &y, &yb);
    let mut st64 = [[0i64; 16]; 3];
    let [s0, s1, s2] = &mut st64;
    let mut states = [s0, s1, s2];
    measure_all(
        "cmsq64",
        m,
        &mut || {
            let st = states[i % 3].as_mut_ptr();
            i += 1;
            let mut s = Df1Q31x64 {
                num_stages: 0,
                state: core::ptr::null_mut(),
                coeffs: core::ptr::null(),
                post_shift: 0,
            };
            // SAFETY: 5K coefficients and 4K (of 16) state words, both outliving `s`.
            unsafe { arm_biquad_cas_df1_32x64_init_q31(&mut s, K as u8, flat.as_ptr(), st, 1) };
            s
        },
        codes,
        &mut y,
        &mut yb,
    );
    check("cmsq64", &y, &yb);
}
