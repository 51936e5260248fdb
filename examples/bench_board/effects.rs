//! The m = 4 compensator with what the modelling loop adds on the board: the
//! nonlinear-damping correction, and the temperature bank (a call at a steady temperature,
//! then a set swap with its warm-up), each checked against an f64 reference.

use core::hint::black_box;

use cortex_m_semihosting::hprintln;
use unlag::board::compensator::{
    BankChannel, CascadeCoefficients, CascadeState, NonlinearDampingCoefficients,
    NonlinearDampingState, TemperatureBank,
};

use crate::board::{coefficients, measure, report, N};

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
pub fn bench_nonlinear(x: &[f32; N], y: &mut [f32; N]) -> bool {
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

/// The temperature bank's per-sample call (the `temperature` effect on the board).
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
pub fn bench_bank(x: &[f32; N], y: &mut [f32; N]) -> bool {
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
