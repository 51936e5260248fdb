//! The fixed-point compensator's guarantees, over random stable models: the arithmetic is
//! exactly the documented one (checked against an independent `i128` implementation), no
//! zero-input limit cycle, no overflow where the plan says none can happen, and the command
//! line's `--arithmetic fixed` runs the same integers.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

mod common;

use std::f64::consts::PI;
use std::process::Command;

use proptest::prelude::*;
use unlag::board::fixed::{FixedCascade, FixedSection, FixedState};
use unlag::design::inverse::{self, Options};
use unlag::design::quantise::FixedPlan;
use unlag::fit::model::Model;

/// A probe model from pole pairs `(radius, angle)` and zeros inside or outside the circle.
fn model(poles: &[(f64, f64)], zeros: &[f64], fs: f64) -> Model {
    let mut a = vec![1.0];
    for &(r, th) in poles {
        a = mul(&a, &[1.0, -2.0 * r * th.cos(), r * r]);
    }
    let mut b = vec![1.0];
    for &z in zeros {
        b = mul(&b, &[1.0, -z]);
    }
    let gain = a.iter().sum::<f64>() / b.iter().sum::<f64>();
    Model {
        fs,
        delay: 1,
        a: a[1..].to_vec(),
        b: b.iter().map(|v| v * gain).collect(),
    }
}

fn mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; p.len() + q.len() - 1];
    for (i, x) in p.iter().enumerate() {
        for (j, y) in q.iter().enumerate() {
            r[i + j] += x * y;
        }
    }
    r
}

/// The documented arithmetic, written independently: `i128`, floor division for the shifts.
fn reference(sections: &[FixedSection], inputs: &[i32]) -> Vec<i32> {
    let mut x = vec![[0i128; 2]; sections.len()];
    let clamp = |v: i128| v.clamp(i128::from(i32::MIN), i128::from(i32::MAX));
    let toward_zero = |v: i128, bits: u32| {
        let q = v.abs() / (1i128 << bits);
        if v < 0 {
            -q
        } else {
            q
        }
    };
    let nearest = |v: i128, bits: u32| (v + (1i128 << (bits - 1))).div_euclid(1i128 << bits);
    inputs
        .iter()
        .map(|&input| {
            let mut v = i128::from(input);
            for (s, st) in sections.iter().zip(x.iter_mut()) {
                let a: Vec<i128> = s.a.iter().map(|&c| i128::from(c)).collect();
                let (b1, b2) = (i128::from(s.b[0]), i128::from(s.b[1]));
                let (c1, c2, d) = (i128::from(s.c[0]), i128::from(s.c[1]), i128::from(s.d));
                let [x1, x2] = *st;
                let n1 = clamp(toward_zero(a[0] * x1 + a[1] * x2 + b1 * v, 30));
                let n2 = clamp(toward_zero(a[2] * x1 + a[3] * x2 + b2 * v, 30));
                let y = clamp(nearest(c1 * x1 + c2 * x2 + d * v, u32::from(s.shift)));
                *st = [n1, n2];
                v = y;
            }
            v as i32
        })
        .collect()
}

prop_compose! {
    fn random_plan()(
        pairs in prop::collection::vec((0.3f64..0.995, 0.002f64..3.0), 1..=2),
        zeros in prop::collection::vec(-1.5f64..0.95, 1..=3),
        corner in 0.01f64..0.3,
        full_scale in 0.1f64..100.0,
    ) -> (inverse::Design, FixedPlan) {
        let fs = 10_000.0;
        let m = model(&pairs, &zeros, fs);
        let design = inverse::design(&m, corner * fs, &Options::default()).unwrap();
        let plan = FixedPlan::new(&design, full_scale).unwrap();
        (design, plan)
    }
}

/// SplitMix64 for the input sequences.
fn codes(seed: u64, n: usize) -> Vec<i32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (z ^ (z >> 31)) as i32
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn arithmetic_is_exactly_the_documented_one((_d, plan) in random_plan(), seed in any::<u64>()) {
        let sections = plan.board_sections();
        let cascade = FixedCascade::<8>::new(&sections).unwrap();
        // Random full-scale codes, then a held level: both the noisy and the quiet regime.
        let mut input = codes(seed, 3000);
        input.extend(std::iter::repeat_n(input[0] / 3, 2000));
        let mut st = FixedState::<8>::default();
        let board: Vec<i32> = input.iter().map(|&v| cascade.process(&mut st, v)).collect();
        prop_assert_eq!(board, reference(&sections, &input));
    }

    #[test]
    fn zero_input_reaches_exactly_zero_within_the_bound(
        (design, plan) in random_plan(),
        seed in any::<u64>(),
    ) {
        let cascade = FixedCascade::<8>::new(&plan.board_sections()).unwrap();
        let mut st = FixedState::<8>::default();
        for v in codes(seed, 2000) {
            cascade.process(&mut st, v);
        }
        // Magnitude truncation shrinks each section's state by its pole radius r per sample:
        // 31 ln 2 / -ln r samples to zero, twice for a pair of real poles, section after
        // section.
        let bound: f64 = design
            .sections
            .iter()
            .map(|s| {
                let r = unlag::board::compensator::section_pole_radius(s[3], s[4]);
                2.0 * (31.0 * 2f64.ln() / -r.ln()).ceil() + 2.0
            })
            .sum();
        let mut n = 0usize;
        while !st.is_zero() && (n as f64) <= bound {
            cascade.process(&mut st, 0);
            n += 1;
        }
        prop_assert!(st.is_zero(), "not at rest after {} samples (bound {})", n, bound);
        prop_assert_eq!(cascade.process(&mut st, 0), 0);
        prop_assert!(st.is_zero());
    }

    #[test]
    fn the_worst_case_input_does_not_overflow((design, plan) in random_plan()) {
        // The input that maximises the output at sample n: the sign of the time-reversed
        // impulse response, at full scale. It reaches the L1 bound the plan is scaled for.
        let c = unlag::board::compensator::CascadeCoefficients::<f64, 8>::new(design.gain, &design.sections)
            .unwrap();
        let mut st = unlag::board::compensator::CascadeState::default();
        let n = 20_000;
        let h: Vec<f64> = (0..n)
            .map(|k| c.process(&mut st, if k == 0 { 1.0 } else { 0.0 }))
            .collect();
        let worst: Vec<i32> = h
            .iter()
            .rev()
            .map(|v| if *v >= 0.0 { i32::MAX } else { i32::MIN })
            .collect();
        let cascade = FixedCascade::<8>::new(&plan.board_sections()).unwrap();
        let mut fst = FixedState::<8>::default();
        let mut last = 0;
        for v in &worst {
            last = cascade.process(&mut fst, *v);
        }
        prop_assert!(!fst.overflowed());
        // The output at the end is the bound itself (up to the truncated tail and rounding):
        // the scaling is not wastefully loose either.
        let out = f64::from(last).abs() / 2f64.powi(31);
        let bound = plan.sections.last().unwrap().output_bound;
        prop_assert!(out <= bound * (1.0 + 1e-6) && out > 0.9 * bound, "{} vs {}", out, bound);
    }
}

#[test]
fn fixed_point_tracks_f64_at_high_sample_rates() {
    // A 5 kHz resonance sampled at 5 MHz (fs/fn = 1000): poles crowd towards z = 1.
    let fs = 5e6;
    let wn = 2.0 * PI * 5e3 / fs;
    let m = model(
        &[((-0.2 * wn).exp(), wn * (1.0f64 - 0.04).sqrt())],
        &[-0.6],
        fs,
    );
    let design = inverse::design(&m, 15e3, &Options::default()).unwrap();
    let plan = FixedPlan::new(&design, 2.0).unwrap();
    let y: Vec<f64> = (0..200_000)
        .map(|k| 0.8 * (2.0 * PI * 1e3 * k as f64 / fs).sin() + 0.3 * (k > 50_000) as i32 as f64)
        .collect();
    let run = plan.run(&y).unwrap();
    assert!(!run.overflowed && run.clipped_inputs == 0);
    let c = unlag::board::compensator::CascadeCoefficients::<f64, 8>::new(
        design.gain,
        &design.sections,
    )
    .unwrap();
    let mut st = c.equilibrium(y[0]);
    let reference: Vec<f64> = y.iter().map(|&v| c.process(&mut st, v)).collect();
    let s: f64 = reference.iter().map(|v| v * v).sum();
    let e: f64 = reference
        .iter()
        .zip(&run.u_hat)
        .map(|(r, f)| (r - f).powi(2))
        .sum();
    let snr = 10.0 * (s / e).log10();
    assert!(snr > 100.0, "SNR {snr:.1} dB");
}

#[test]
fn compensate_with_fixed_arithmetic_runs_the_planned_integers() {
    let dir = std::env::temp_dir().join(format!("unlag-fixed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("model.toml");
    let unlag = |args: &[&str]| {
        let o = common::unlag(args);
        assert!(
            o.status.success(),
            "{args:?}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/host-tests/data/line_est.csv");
    let val = concat!(env!("CARGO_MANIFEST_DIR"), "/host-tests/data/line_val.csv");
    let m = model.to_str().unwrap();
    let printed = unlag(&[
        "fit",
        data,
        val,
        "-o",
        m,
        "--order",
        "2",
        "--full-scale",
        "4",
    ]);
    assert!(printed.contains("fixed point"), "{printed}");
    let out1 = dir.join("a.csv");
    let out2 = dir.join("b.csv");
    for out in [&out1, &out2] {
        unlag(&[
            "compensate",
            m,
            val,
            "-o",
            out.to_str().unwrap(),
            "--arithmetic",
            "fixed",
        ]);
    }
    let (a, b) = (std::fs::read(&out1).unwrap(), std::fs::read(&out2).unwrap());
    assert_eq!(a, b, "two runs differ");
    // The CLI's u_hat is the library's plan run on the same trace.
    let file = unlag::file::ModelFile::load(&model).unwrap();
    let plan = file.inverse.unwrap().fixed.unwrap();
    assert_eq!(plan.full_scale, 4.0);
    let trace =
        unlag::trace::Trace::read(std::path::Path::new(val), &unlag::trace::Columns::default())
            .unwrap();
    let expected = plan.run(&trace.y).unwrap().u_hat;
    let text = String::from_utf8(a).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "u_hat").unwrap();
    let got: Vec<f64> = lines
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(&expected) {
        assert!(
            (g - e).abs() <= 1e-12 * e.abs().max(1e-300) + 1e-15,
            "{g} vs {e}"
        );
    }
}

// ---- The direct form: DF-I sections with first-order error feedback.

use unlag::board::fixed::direct::{DirectCascade, DirectSection, DirectState};
use unlag::design::quantise::DirectPlan;

/// The direct form's documented arithmetic, written independently: `i128`, floor division,
/// the residual carried, the high word clamped to 30 bits (the output then within 3 codes of
/// the `i32` limits). Returns the outputs and whether anything was clamped.
fn direct_reference(sections: &[DirectSection], inputs: &[i32]) -> (Vec<i32>, bool) {
    let mut x = [0i128; 2];
    let mut st = vec![[0i128; 3]; sections.len()];
    let mut clamped = false;
    let out = inputs
        .iter()
        .map(|&input| {
            let (mut v0, mut v1, mut v2) = (i128::from(input), x[0], x[1]);
            x = [v0, v1];
            for (s, [y1, y2, e]) in sections.iter().zip(st.iter_mut()) {
                let b = s.b.map(i128::from);
                let na = s.neg_a.map(i128::from);
                let acc = *e + b[0] * v0 + b[1] * v1 + b[2] * v2 + na[0] * *y1 + na[1] * *y2;
                let y = acc.div_euclid(1 << 30);
                let y = if y > i128::from(i32::MAX) || y < i128::from(i32::MIN) {
                    clamped = true;
                    let hi = (acc >> 32).clamp(-(1 << 29), (1 << 29) - 1);
                    (hi << 2) | ((acc >> 30) & 3)
                } else {
                    y
                };
                let old = *y1;
                (v0, v1, v2) = (y, old, *y2);
                *e = acc.rem_euclid(1 << 30);
                (*y1, *y2) = (y, old);
            }
            v0 as i32
        })
        .collect();
    (out, clamped)
}

prop_compose! {
    fn random_direct_plan()(
        pairs in prop::collection::vec((0.3f64..0.995, 0.002f64..3.0), 1..=2),
        zeros in prop::collection::vec(-1.5f64..0.95, 1..=3),
        corner in 0.01f64..0.3,
        full_scale in 0.1f64..100.0,
    ) -> (inverse::Design, DirectPlan) {
        let fs = 10_000.0;
        let m = model(&pairs, &zeros, fs);
        let design = inverse::design(&m, corner * fs, &Options::default()).unwrap();
        let plan = DirectPlan::new(&design, full_scale).unwrap();
        (design, plan)
    }
}

/// The impulse response of the f64 cascade, `n` samples.
fn impulse(design: &inverse::Design, n: usize) -> Vec<f64> {
    let c = unlag::board::compensator::CascadeCoefficients::<f64, 8>::new(
        design.gain,
        &design.sections,
    )
    .unwrap();
    let mut st = unlag::board::compensator::CascadeState::default();
    (0..n)
        .map(|k| c.process(&mut st, if k == 0 { 1.0 } else { 0.0 }))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn direct_arithmetic_is_exactly_the_documented_one(
        (_d, plan) in random_direct_plan(),
        seed in any::<u64>(),
    ) {
        let sections = plan.board_sections();
        let cascade = DirectCascade::<8>::new(&sections).unwrap();
        let mut input = codes(seed, 3000);
        input.extend(std::iter::repeat_n(input[0] / 3, 2000));
        let mut st = DirectState::<8>::default();
        let board: Vec<i32> = input.iter().map(|&v| cascade.process(&mut st, v)).collect();
        let (want, clamped) = direct_reference(&sections, &input);
        prop_assert_eq!(board, want);
        // Planned coefficients never clamp, even on random full-scale codes.
        prop_assert!(!clamped && !st.overflowed());
        // Blocks compute the same as calls.
        let mut st = DirectState::<8>::default();
        let mut buf = input.clone();
        for chunk in buf.chunks_mut(37) {
            cascade.process_in_place(&mut st, chunk);
        }
        prop_assert_eq!(buf, direct_reference(&sections, &input).0);
    }

    #[test]
    fn direct_worst_case_input_does_not_overflow((design, plan) in random_direct_plan()) {
        // The full-scale input that maximises the output at the last sample: it reaches the
        // L1 bound the plan is scaled for, and nothing overflows.
        let h = impulse(&design, 20_000);
        let worst: Vec<i32> = h
            .iter()
            .rev()
            .map(|v| if *v >= 0.0 { i32::MAX } else { i32::MIN })
            .collect();
        let cascade = DirectCascade::<8>::new(&plan.board_sections()).unwrap();
        let mut st = DirectState::<8>::default();
        let mut last = 0;
        for v in &worst {
            last = cascade.process(&mut st, *v);
        }
        prop_assert!(!st.overflowed());
        let out = f64::from(last).abs() / 2f64.powi(31);
        let s = plan.sections.last().unwrap();
        let bound = s.output_bound + s.noise_bound / 2f64.powi(31);
        prop_assert!(out <= bound && out > 0.9 * s.output_bound, "{} vs {}", out, bound);
    }

    #[test]
    fn direct_overflow_beyond_the_plan_is_clamped_and_flagged((design, plan) in random_direct_plan()) {
        // The same worst case through a numerator made large enough to reach twice the i32
        // range (within the accumulator bound): the output leaves the range, is clamped, and
        // the flag says so.
        // The last section whose numerator can be so amplified within the accumulator bound
        // (later sections scale the overflow further up or leave it saturated).
        let planned = plan.board_sections();
        let amplified = (0..planned.len()).rev().find_map(|k| {
            let mut sections = planned.clone();
            let factor = (2.0 / plan.sections[k].output_bound).ceil() as i32;
            let b = sections[k].b.map(|v| v.checked_mul(factor));
            if b.iter().any(Option::is_none) {
                return None;
            }
            sections[k].b = b.map(|v| v.unwrap_or(0));
            DirectCascade::<8>::new(&sections).ok().map(|c| (c, sections, k))
        });
        let Some((cascade, sections, k)) = amplified else {
            // Beyond the accumulator bound everywhere: refused, the other correct outcome.
            return Ok(());
        };
        if k + 1 != planned.len() {
            // The overflow of an earlier section need not reach the output clamped; the flag
            // must still be set.
            let h = impulse(&design, 20_000);
            let worst: Vec<i32> = h
                .iter()
                .rev()
                .map(|v| if *v >= 0.0 { i32::MAX } else { i32::MIN })
                .collect();
            let mut st = DirectState::<8>::default();
            let board: Vec<i32> = worst.iter().map(|v| cascade.process(&mut st, *v)).collect();
            let (want, clamped) = direct_reference(&sections, &worst);
            prop_assert_eq!(board, want);
            prop_assert_eq!(st.overflowed(), clamped);
            return Ok(());
        }
        let h = impulse(&design, 20_000);
        let worst: Vec<i32> = h
            .iter()
            .rev()
            .map(|v| if *v >= 0.0 { i32::MAX } else { i32::MIN })
            .collect();
        let mut st = DirectState::<8>::default();
        let mut y = 0;
        for v in &worst {
            y = cascade.process(&mut st, *v);
        }
        prop_assert!(st.overflowed());
        prop_assert!(y >= i32::MAX - 3 || y <= i32::MIN + 3, "{}", y);
        let (want, clamped) = direct_reference(&sections, &worst);
        prop_assert!(clamped);
        prop_assert_eq!(y, *want.last().unwrap());
    }
}

#[test]
fn direct_form_accuracy_at_three_sample_rates() {
    // The trade the direct form makes: better than 100 dB where the poles are not crowded
    // towards z = 1, about 90 dB at fs/fn = 1000 (the coarse pole and zero grid of a1 near -2;
    // the normal form keeps 100 dB there). Same probes as examples/bench_fixed.rs.
    for (fs, f_n, zeta, bw, min_db) in [
        (1e6, 62_500.0, 0.1, 150_000.0, 100.0),
        (1e4, 95.0, 0.22, 300.0, 100.0),
        (5e6, 5e3, 0.2, 15e3, 85.0),
    ] {
        let wn = 2.0 * PI * f_n / fs;
        let m = model(
            &[((-zeta * wn).exp(), wn * (1.0f64 - zeta * zeta).sqrt())],
            &[-0.6],
            fs,
        );
        let design = inverse::design(&m, bw, &Options::default()).unwrap();
        let plan = DirectPlan::new(&design, 2.0).unwrap();
        assert!(plan.headroom_bits >= 0.99, "{plan:?}");
        let y: Vec<f64> = (0..200_000)
            .map(|k| {
                0.8 * (2.0 * PI * f_n * 0.2 * k as f64 / fs).sin()
                    + 0.3 * (k > 50_000) as i32 as f64
            })
            .collect();
        let run = plan.run(&y).unwrap();
        assert!(!run.overflowed && run.clipped_inputs == 0);
        let c = unlag::board::compensator::CascadeCoefficients::<f64, 8>::new(
            design.gain,
            &design.sections,
        )
        .unwrap();
        let mut st = c.equilibrium(y[0]);
        let reference: Vec<f64> = y.iter().map(|&v| c.process(&mut st, v)).collect();
        let s: f64 = reference.iter().map(|v| v * v).sum();
        let e: f64 = reference
            .iter()
            .zip(&run.u_hat)
            .map(|(r, f)| (r - f).powi(2))
            .sum();
        let snr = 10.0 * (s / e).log10();
        assert!(snr > min_db, "fs/fn {}: SNR {snr:.1} dB", fs / f_n);
    }
}

#[test]
fn the_direct_form_is_chosen_on_the_command_line_and_runs_bit_exact() {
    let dir = std::env::temp_dir().join(format!("unlag-direct-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = dir.join("model.toml");
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_unlag"))
            .args(args)
            .output()
            .unwrap()
    };
    let unlag = |args: &[&str]| {
        let o = run(args);
        assert!(
            o.status.success(),
            "{args:?}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/host-tests/data/line_est.csv");
    let val = concat!(env!("CARGO_MANIFEST_DIR"), "/host-tests/data/line_val.csv");
    let m = model.to_str().unwrap();
    let printed = unlag(&[
        "fit",
        data,
        val,
        "-o",
        m,
        "--order",
        "2",
        "--full-scale",
        "4",
        "--fixed-form",
        "direct",
    ]);
    assert!(
        printed.contains("direct form with error feedback"),
        "{printed}"
    );
    let file = unlag::file::ModelFile::load(&model).unwrap();
    let design = file.inverse.unwrap();
    assert!(design.fixed.is_none());
    let plan = design.fixed_direct.unwrap();
    assert_eq!(plan.full_scale, 4.0);
    // compensate --arithmetic fixed runs the stored direct plan.
    let out = dir.join("u.csv");
    unlag(&[
        "compensate",
        m,
        val,
        "-o",
        out.to_str().unwrap(),
        "--arithmetic",
        "fixed",
    ]);
    let trace =
        unlag::trace::Trace::read(std::path::Path::new(val), &unlag::trace::Columns::default())
            .unwrap();
    let expected = plan.run(&trace.y).unwrap().u_hat;
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "u_hat").unwrap();
    let got: Vec<f64> = lines
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(&expected) {
        assert!(
            (g - e).abs() <= 1e-12 * e.abs().max(1e-300) + 1e-15,
            "{g} vs {e}"
        );
    }
    // export: the stored form by default, in Rust, C and the blob (number format 2).
    let rs = dir.join("c.rs");
    unlag(&[
        "export",
        m,
        "--format",
        "rust",
        "--number-format",
        "fixed",
        "-o",
        rs.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&rs).unwrap();
    assert!(
        text.contains("unlag::board::fixed::direct::DirectSection { b: ["),
        "{text}"
    );
    for s in &plan.board_sections() {
        assert!(text.contains(&format!("b: {:?}, neg_a: {:?}", s.b, s.neg_a)));
    }
    let h = dir.join("c.h");
    unlag(&[
        "export",
        m,
        "--format",
        "c",
        "--number-format",
        "fixed",
        "--fixed-form",
        "direct",
        "-o",
        h.to_str().unwrap(),
    ]);
    assert!(std::fs::read_to_string(&h)
        .unwrap()
        .contains("unlag_direct_sections"));
    let bin = dir.join("c.bin");
    let o = run(&[
        "export",
        m,
        "--format",
        "bin",
        "--number-format",
        "fixed",
        "-o",
        bin.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let set: unlag::board::blob::DirectCoefficientSet<8> =
        unlag::board::blob::parse_direct(&std::fs::read(&bin).unwrap()).unwrap();
    assert_eq!(set.sections, plan.sections.len());
    assert_eq!(set.full_scale, 4.0);
    assert_eq!(set.output_exponent, plan.output_exponent);
    assert_eq!(
        set.cascade,
        unlag::board::fixed::direct::DirectCascade::<8>::new(&plan.board_sections()).unwrap()
    );
    // --fixed-form normal on the same model plans the normal form anew (number format 1).
    let o = run(&[
        "export",
        m,
        "--format",
        "bin",
        "--number-format",
        "fixed",
        "--fixed-form",
        "normal",
        "--full-scale",
        "4",
        "-o",
        bin.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(unlag::board::blob::parse_fixed::<8>(&std::fs::read(&bin).unwrap()).is_ok());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run well above the step test (a reflected shock: 2.6 times the step) is not clamped by
/// a fixed-point board whose full scale `unlag fit` chose by default, where the old default (the
/// tests' largest |y| plus 25 %) clamped it; a full scale stated below the run clamps, and the
/// count is reported.
#[test]
fn the_default_full_scale_holds_a_reflected_shock_and_a_clamped_run_is_counted() {
    let dir = std::env::temp_dir().join(format!("unlag-full-scale-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let unlag = |args: &[&str]| {
        let o = common::unlag(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        (
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let step = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/data/step_test_1.csv");
    // The run: the same step 2.6 times as large, as a reflected shock brings it.
    let text = std::fs::read_to_string(step).unwrap();
    let mut lines = text.lines();
    let mut run = format!("{}\n", lines.next().unwrap());
    let mut run_peak = 0.0f64;
    let mut step_peak = 0.0f64;
    for l in lines {
        let cells: Vec<f64> = l.split(',').map(|c| c.trim().parse().unwrap()).collect();
        step_peak = step_peak.max(cells[2].abs());
        run_peak = run_peak.max((2.6 * cells[2]).abs());
        run.push_str(&format!(
            "{},{},{}\n",
            cells[0],
            2.6 * cells[1],
            2.6 * cells[2]
        ));
    }
    let run_path = dir.join("reflected.csv");
    std::fs::write(&run_path, run).unwrap();
    assert!(
        run_peak > 1.25 * step_peak,
        "the run must leave the old default"
    );
    let model = dir.join("probe.toml");
    let m = model.to_str().unwrap();
    let (printed, _) = unlag(&["fit", step, "-o", m, "--board", "fixed", "--json"]);
    let fit: serde_json::Value = serde_json::from_str(&printed).unwrap();
    assert_eq!(fit["full_scale"]["stated"], false, "{fit}");
    assert!(
        fit["full_scale"]["value"].as_f64().unwrap() > run_peak,
        "{fit}"
    );
    let out = dir.join("out.csv");
    let compensate = |model: &str| {
        let (printed, stderr) = unlag(&[
            "compensate",
            model,
            run_path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--json",
        ]);
        (
            serde_json::from_str::<serde_json::Value>(&printed).unwrap(),
            stderr,
        )
    };
    // The board's arithmetic by default, nothing clamped.
    let (c, stderr) = compensate(m);
    assert_eq!(c["arithmetic"], "32-bit fixed point", "{c}");
    assert_eq!(c["clamped_inputs"], 0, "{c} {stderr}");
    assert!(!stderr.contains("clamped"), "{stderr}");
    // The ADC's range stated below the run: the samples beyond it are clamped and counted.
    let small = dir.join("small.toml");
    let s = small.to_str().unwrap();
    let (printed, _) = unlag(&[
        "fit",
        step,
        "-o",
        s,
        "--board",
        "fixed",
        "--full-scale",
        "2000",
    ]);
    assert!(
        printed.contains("full scale +-2000 (the ADC's range, as stated)"),
        "{printed}"
    );
    let (c, stderr) = compensate(s);
    let clamped = c["clamped_inputs"].as_u64().unwrap();
    assert!(clamped > 100, "{c}");
    assert!(
        stderr.contains(&format!("warning: {clamped} samples of")) && stderr.contains("+-2000"),
        "{stderr}"
    );
}
