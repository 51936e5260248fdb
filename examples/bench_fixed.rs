//! Accuracy of the fixed-point compensator, a benchmark, not a test.
//!
//! For three probes, from a few samples per period to a thousand (fs/fn about 16, 100 and
//! 1000), the stable band-limited compensator is designed in f64 and run three ways on the same
//! long simulated probe signal: in f64 (the reference), in the board's 32-bit fixed point
//! (normal-form sections, `unlag::board::fixed`), and, beside it, as one 32-bit direct-form filter
//! of the whole compensator (coefficients quantised the same way, exact `i128` accumulation,
//! so only the form differs). Then a 10^8-sample full-scale random walk counts overflows, and a
//! zero input after full-scale excitation shows how long the states take to reach exactly zero.
//!
//! ```sh
//! cargo run --release --example bench_fixed            # add --quick for 10^6-sample walks
//! ```

use std::f64::consts::PI;

use unlag::board::compensator::{CascadeCoefficients, CascadeState};
use unlag::board::fixed::direct::{DirectCascade, DirectState};
use unlag::board::fixed::{FixedCascade, FixedState};
use unlag::design::inverse::{self, Design, Options};
use unlag::design::quantise::{DirectPlan, FixedPlan};
use unlag::fit::model::{filter, Model};

/// ADC full scale of the simulated probe signals.
const FULL_SCALE: f64 = 2.0;

struct Case {
    name: &'static str,
    fs: f64,
    fn_hz: f64,
    zeta: f64,
    bandwidth: f64,
}

/// SplitMix64.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A 2nd-order probe with poles `exp(s / fs)`, unit DC gain, a zero at -2/3, delay 2.
fn probe(c: &Case) -> Model {
    let wn = 2.0 * PI * c.fn_hz / c.fs;
    let (re, im) = (-c.zeta * wn, wn * (1.0 - c.zeta * c.zeta).sqrt());
    let a = vec![-2.0 * re.exp() * im.cos(), (2.0 * re).exp()];
    let dc = 1.0 + a[0] + a[1];
    Model {
        fs: c.fs,
        delay: 2,
        a,
        b: vec![0.6 * dc, 0.4 * dc],
    }
}

/// Probe output for random pressure steps (levels within +-0.7 of full scale, one every
/// 2-20 natural periods) plus a little noise: what the compensator sees.
fn probe_signal(c: &Case, model: &Model, n: usize, rng: &mut Rng) -> Vec<f64> {
    let period = (c.fs / c.fn_hz).max(2.0);
    let mut u = Vec::with_capacity(n);
    let mut level = 0.0;
    let mut next = 0usize;
    for k in 0..n {
        if k >= next {
            level = 1.4 * rng.uniform() - 0.7;
            next = k + (period * (2.0 + 18.0 * rng.uniform())) as usize;
        }
        u.push(level);
    }
    let mut y = filter(&model.b, &model.a, model.delay, &u);
    for v in &mut y {
        *v += 1e-4 * (rng.uniform() - 0.5);
    }
    y
}

fn snr_db(reference: &[f64], test: &[f64]) -> f64 {
    let s: f64 = reference.iter().map(|v| v * v).sum();
    let e: f64 = reference
        .iter()
        .zip(test)
        .map(|(r, t)| (r - t).powi(2))
        .sum();
    10.0 * (s / e).log10()
}

fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            r[i + j] += a * b;
        }
    }
    r
}

/// The whole compensator as one direct-form I filter in 32-bit fixed point: coefficients
/// quantised to at most 2^30 with a common shift, i32 signals, exact i128 accumulation.
fn direct_form_fixed(design: &Design, plan: &FixedPlan, y: &[f64]) -> Vec<f64> {
    let (mut num, mut den) = (vec![design.gain], vec![1.0]);
    for &[b0, b1, b2, a1, a2] in &design.sections {
        num = poly_mul(&num, &[b0, b1, b2]);
        den = poly_mul(&den, &[1.0, a1, a2]);
    }
    // Output in the same Q1.31 of full_scale * 2^e as the sections.
    let out_scale = (-plan.output_exponent as f64).exp2();
    let num: Vec<f64> = num.iter().map(|v| v * out_scale).collect();
    let max = num.iter().chain(&den).fold(0.0f64, |m, v| m.max(v.abs()));
    let shift = (30.0 - max.log2()).floor().min(62.0) as u32;
    let q = |v: f64| (v * (shift as f64).exp2()).round() as i128;
    let (nq, dq): (Vec<i128>, Vec<i128>) = (
        num.iter().map(|&v| q(v)).collect(),
        den.iter().map(|&v| q(v)).collect(),
    );
    let mut xs = vec![0i128; nq.len()];
    let mut ys = vec![0i128; dq.len()];
    let mut out = Vec::with_capacity(y.len());
    for &v in y {
        xs.rotate_right(1);
        xs[0] = i128::from(plan.to_code(v).0);
        let mut acc: i128 = nq.iter().zip(&xs).map(|(c, x)| c * x).sum();
        acc -= dq.iter().zip(&ys).skip(1).map(|(c, y)| c * y).sum::<i128>();
        let r = (acc + (1i128 << (shift - 1))) >> shift;
        let r = r.clamp(i128::from(i32::MIN), i128::from(i32::MAX));
        ys.rotate_right(1);
        ys[0] = r;
        out.push(plan.from_code(r as i32));
    }
    out
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let walk = if quick { 1_000_000 } else { 100_000_000 };
    let cases = [
        Case {
            name: "recessed sensor, 62.5 kHz at 1 MHz (fs/fn 16)",
            fs: 1e6,
            fn_hz: 62_500.0,
            zeta: 0.1,
            bandwidth: 150_000.0,
        },
        Case {
            name: "line, 95 Hz at 10 kHz (fs/fn 105)",
            fs: 1e4,
            fn_hz: 95.0,
            zeta: 0.22,
            bandwidth: 300.0,
        },
        Case {
            name: "cavity, 5 kHz at 5 MHz (fs/fn 1000)",
            fs: 5e6,
            fn_hz: 5_000.0,
            zeta: 0.2,
            bandwidth: 15_000.0,
        },
    ];
    println!(
        "| case | sections (forms) | headroom (bits, L1 bound) | SNR fixed-point sections vs f64 | SNR 32-bit direct form vs f64 | SNR f32 sections vs f64 | full-scale random walk: samples, overflows | zero input: samples to exact zero (bound) |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut rng = Rng(7);
    let mut direct_rows = Vec::new();
    for c in &cases {
        let model = probe(c);
        let design = match inverse::design(&model, c.bandwidth, &Options::default()) {
            Ok(d) => d,
            Err(e) => {
                println!("| {} | design failed: {e} |||||||", c.name);
                continue;
            }
        };
        // The probe overshoots the steps (levels within +-0.7, up to 73 % overshoot): the ADC's
        // full scale is +-2.
        let plan = match FixedPlan::new(&design, FULL_SCALE) {
            Ok(p) => p,
            Err(e) => {
                println!("| {} | plan refused: {e} |||||||", c.name);
                continue;
            }
        };
        let n = 1_000_000;
        let y = probe_signal(c, &model, n, &mut rng);
        let f64c =
            CascadeCoefficients::<f64, 8>::new(design.gain, &design.sections).expect("f64 cascade");
        let mut st = f64c.equilibrium(y[0]);
        let reference: Vec<f64> = y.iter().map(|&v| f64c.process(&mut st, v)).collect();
        let fixed = plan.run(&y).expect("fixed run");
        let f32c =
            CascadeCoefficients::<f32, 8>::new(design.gain, &design.sections).expect("f32 cascade");
        let mut st32 = f32c.equilibrium(y[0] as f32);
        let single: Vec<f64> = y
            .iter()
            .map(|&v| f64::from(f32c.process(&mut st32, v as f32)))
            .collect();
        // The direct form starts from rest: compare after the f64 reference from rest too.
        let mut st0 = CascadeState::default();
        let reference0: Vec<f64> = y.iter().map(|&v| f64c.process(&mut st0, v)).collect();
        let direct = direct_form_fixed(&design, &plan, &y);
        let snr_direct = snr_db(&reference0, &direct);
        let direct_cell = if snr_direct.is_finite() && direct.iter().all(|v| v.is_finite()) {
            format!("{snr_direct:.1} dB")
        } else {
            "fails (saturates)".into()
        };

        // Full-scale random walk (reflecting at +-full scale), overflow flag counted.
        let sections = plan.board_sections();
        let cascade = FixedCascade::<8>::new(&sections).expect("fixed cascade");
        let mut fs_state = FixedState::<8>::default();
        let mut x: i64 = 0;
        let mut overflows = 0u64;
        let step = 1i64 << 27;
        for _ in 0..walk {
            let r = rng.next();
            x += if r & 1 == 0 { step } else { -step };
            x = x.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
            cascade.process(&mut fs_state, x as i32);
            if fs_state.take_overflow() {
                overflows += 1;
            }
        }
        // Zero input after full-scale excitation.
        let mut st = FixedState::<8>::default();
        for k in 0..10_000 {
            let v = if (k / 37) % 2 == 0 {
                i32::MAX
            } else {
                i32::MIN
            };
            cascade.process(&mut st, v);
        }
        let radius = design.sections.iter().fold(0.0f64, |r, s| {
            r.max(unlag::board::compensator::section_pole_radius(s[3], s[4]))
        });
        let bound = (2.0 * 31.0 * 2f64.ln() / -radius.ln()).ceil() as usize;
        let mut steps = 0usize;
        while !st.is_zero() && steps < 10 * bound {
            cascade.process(&mut st, 0);
            steps += 1;
        }
        // The direct form's own random walk (its own generator: the normal form's figures
        // above stay those of the same signals as before).
        direct_rows.push(direct_row(c, &design, &y, &reference, walk, &mut Rng(11)));
        let forms: Vec<&str> = plan.sections.iter().map(|s| s.form.as_str()).collect();
        println!(
            "| {} | {} ({}) | {:.2} | {:.1} dB | {} | {:.1} dB | {:.0e}, {} | {}{} ({}) |",
            c.name,
            plan.sections.len(),
            forms.join(", "),
            plan.headroom_bits,
            snr_db(&reference, &fixed.u_hat),
            direct_cell,
            snr_db(&reference, &single),
            walk as f64,
            overflows,
            steps,
            if st.is_zero() { "" } else { " NOT ZERO" },
            bound
        );
    }
    println!();
    println!("Direct form I with first-order error feedback (`unlag::board::fixed::direct`, `DirectPlan`), same signals:");
    println!();
    println!(
        "| case | headroom (bits, L1 bound incl. error feedback) | SNR direct-form sections vs f64 | SNR same integers, plain truncation (no error feedback) vs f64 | full-scale random walk: samples, overflows | zero input after full-scale excitation: samples until the outputs are zero; largest output code left after 10^6 samples |"
    );
    println!("|---|---|---|---|---|---|");
    for r in direct_rows {
        println!("{r}");
    }
}

/// The direct form's integers without error feedback: every accumulator starts at zero and
/// is truncated towards minus infinity (`>> 30`), wrapping. Starts in the same rounded
/// equilibrium as the plan's run.
fn plain_truncation(plan: &DirectPlan, y: &[f64]) -> Vec<f64> {
    let sections = plan.board_sections();
    let first = i64::from(plan.to_code(y[0]).0);
    let mut x = [first; 2];
    let mut v = first as f64;
    let mut hist: Vec<[i64; 2]> = sections
        .iter()
        .map(|s| {
            let b: f64 = s.b.iter().map(|&c| f64::from(c)).sum();
            let a = (1u64 << 30) as f64 - s.neg_a.iter().map(|&c| f64::from(c)).sum::<f64>();
            v = (v * b / a).floor();
            [v as i64; 2]
        })
        .collect();
    y.iter()
        .map(|&p| {
            let x0 = i64::from(plan.to_code(p).0);
            let (mut v0, mut v1, mut v2) = (x0, x[0], x[1]);
            x = [x0, x[0]];
            for (s, h) in sections.iter().zip(hist.iter_mut()) {
                let b = s.b.map(i64::from);
                let na = s.neg_a.map(i64::from);
                let acc = (b[0] * v0 + b[1] * v1 + b[2] * v2)
                    .wrapping_add(na[0] * h[0])
                    .wrapping_add(na[1] * h[1]);
                let yv = i64::from((acc >> 30) as i32);
                (v0, v1, v2) = (yv, h[0], h[1]);
                *h = [yv, h[0]];
            }
            plan.from_code(v0 as i32)
        })
        .collect()
}

/// The direct-form row of one case: plan, SNR on the same signal, overflow count on a
/// full-scale random walk, and the zero-input behaviour after full-scale excitation.
fn direct_row(
    c: &Case,
    design: &Design,
    y: &[f64],
    reference: &[f64],
    walk: usize,
    rng: &mut Rng,
) -> String {
    let plan = match DirectPlan::new(design, FULL_SCALE) {
        Ok(p) => p,
        Err(e) => return format!("| {} | plan refused: {e} |||||", c.name),
    };
    let run = plan.run(y).expect("direct run");
    let snr = snr_db(reference, &run.u_hat);
    let snr_plain = snr_db(reference, &plain_truncation(&plan, y));
    let cascade = DirectCascade::<8>::new(&plan.board_sections()).expect("direct cascade");
    let mut st = DirectState::<8>::default();
    let mut x: i64 = 0;
    let mut overflows = 0u64;
    let step = 1i64 << 27;
    for _ in 0..walk {
        let r = rng.next();
        x += if r & 1 == 0 { step } else { -step };
        x = x.clamp(i64::from(i32::MIN), i64::from(i32::MAX));
        cascade.process(&mut st, x as i32);
        if st.take_overflow() {
            overflows += 1;
        }
    }
    let mut st = DirectState::<8>::default();
    for k in 0..10_000 {
        let v = if (k / 37) % 2 == 0 {
            i32::MAX
        } else {
            i32::MIN
        };
        cascade.process(&mut st, v);
    }
    let limit = 1_000_000usize;
    let mut quiet_at = None;
    for n in 0..limit {
        let out = cascade.process(&mut st, 0);
        if out != 0 {
            quiet_at = None;
        } else if quiet_at.is_none() && st.is_quiet() {
            quiet_at = Some(n);
        }
    }
    let left = st.largest_output();
    let quiet = match quiet_at {
        Some(n) if st.is_quiet() => format!("{n}; 0"),
        _ => format!("never (limit cycle); {left}"),
    };
    format!(
        "| {} | {:.2} | {:.1} dB | {:.1} dB | {:.0e}, {} | {} |",
        c.name, plan.headroom_bits, snr, snr_plain, walk as f64, overflows, quiet
    )
}
