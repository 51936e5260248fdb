//! Reconstruction quality of the compensator on simulated noisy step tests with known truth.
//!
//! For each case: fit on one step test, design the compensator on a second (the bandwidth is
//! chosen there), then reconstruct a third, independent test and compare with its *true*
//! (noise-free) reference: the raw probe, the paper's direct inverse `A/B` with the same
//! low-pass, and the stable band-limited inverse. Errors are RMS / range of the reference at
//! the best time alignment. Prints a Markdown table for BENCHMARKS.md.
//!
//! ```sh
//! cargo run --release --example bench_inverse
//! ```

#[path = "../host-tests/common/mod.rs"]
mod common;

use common::{add_noise, continuous_line, Rng};
use unlag::design::inverse::{self, aligned_error};
use unlag::fit::{self, Options, Order, Test};

struct Case {
    name: &'static str,
    fs: f64,
    modes: &'static [(f64, f64)],
    delay: usize,
    noise: f64,
    order: Order,
    n: usize,
}

fn valve(n: usize, at: usize, lo: f64, hi: f64, rise: f64) -> Vec<f64> {
    (0..n)
        .map(|k| lo + (hi - lo) * ((k as f64 - at as f64) / rise).clamp(0.0, 1.0))
        .collect()
}

fn main() {
    let cases = [
        Case {
            name: "line, 2nd order (95 Hz, 0.22), 10 kHz, 0.2 % noise",
            fs: 10_000.0,
            modes: &[(95.0, 0.22)],
            delay: 17,
            noise: 0.002,
            order: Order::Fixed(2),
            n: 4000,
        },
        Case {
            name: "line, two modes (112 Hz 0.32, 362 Hz 0.16), 10 kHz, 0.2 % noise",
            fs: 10_000.0,
            modes: &[(112.0, 0.32), (362.0, 0.16)],
            delay: 17,
            noise: 0.002,
            order: Order::Fixed(4),
            n: 4000,
        },
        Case {
            name: "recessed sensor (80 kHz, 0.1), 1 MHz, 0.2 % noise",
            fs: 1_000_000.0,
            modes: &[(80_000.0, 0.1)],
            delay: 3,
            noise: 0.002,
            order: Order::Fixed(2),
            n: 4000,
        },
    ];
    println!("| case | raw probe | direct inverse A/B + same low-pass | stable inverse (unlag) | gain over raw | same design from a noise-free fit | stable inverse vs band-limited reference | corner / corrected bandwidth | noise gain |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for case in &cases {
        let mut rng = Rng::new(42);
        let mk = |rng: &mut Rng, at: usize, lo: f64, hi: f64| {
            let u_true = valve(case.n, at, lo, hi, 2.0);
            let y = continuous_line(&u_true, case.fs, case.modes, case.delay);
            let span = (hi - lo).abs();
            let y = add_noise(&y, case.noise * span, rng);
            let u = add_noise(&u_true, 0.3 * case.noise * span, rng);
            (u_true, u, y)
        };
        let (ut_e, u_e, y_e) = mk(&mut rng, 500, 0.0, 1.0);
        let (_, u_v, y_v) = mk(&mut rng, 800, 1.0, 0.3);
        let (u_t, _, y_t) = mk(&mut rng, 650, 0.2, 0.9);
        let est = Test {
            name: "estimation",
            u: &u_e,
            y: &y_e,
        };
        let val = Test {
            name: "validation",
            u: &u_v,
            y: &y_v,
        };
        let fitted = match fit::fit(
            &est,
            &[val],
            case.fs,
            &Options {
                order: case.order,
                ..Options::default()
            },
        ) {
            Ok(f) => f,
            Err(e) => {
                println!("| {} | fit failed: {e} | | | | | | | |", case.name);
                continue;
            }
        };
        let model = fitted.model;
        // The best a fit can do: the same order fitted to the noise-free estimation test, its
        // inverse designed the same way on the same noisy validation test.
        let y_clean = continuous_line(&ut_e, case.fs, case.modes, case.delay);
        let clean = Test {
            name: "noise-free estimation",
            u: &ut_e,
            y: &y_clean,
        };
        let e_true = fit::fit(
            &clean,
            &[],
            case.fs,
            &Options {
                order: case.order,
                ..Options::default()
            },
        )
        .ok()
        .and_then(|f| inverse::design_auto(&f.model, &[val], &inverse::Options::default()).ok())
        .map_or(f64::NAN, |d| {
            let nominal = d.latency_samples.round() as usize;
            let u_hat = d.run::<f32>(&y_t).unwrap_or_default();
            aligned_error(&u_t, &u_hat, nominal.saturating_sub(6)..=nominal + 6).0
        });
        let stable = match inverse::design_auto(&model, &[val], &inverse::Options::default()) {
            Ok(d) => d,
            Err(e) => {
                println!("| {} | design failed: {e} | | | | | | | |", case.name);
                continue;
            }
        };
        let direct = inverse::design(
            &model,
            stable.lowpass_hz,
            &inverse::Options {
                stabilise: false,
                ..inverse::Options::default()
            },
        );
        let nominal = stable.latency_samples.round() as usize;
        let window = nominal.saturating_sub(6)..=nominal + 6;
        let (raw, _) = aligned_error(&u_t, &y_t, 0..=nominal + 60);
        let u_hat = stable.run::<f32>(&y_t).unwrap_or_default();
        let (e_stable, _) = aligned_error(&u_t, &u_hat, window.clone());
        // The reference through the same low-pass: what a perfect compensator with this band
        // limit would give. The difference isolates the compensator's own error.
        let lp = inverse::lowpass(
            stable.lowpass,
            stable.lowpass_order,
            stable.lowpass_hz,
            case.fs,
        )
        .expect("low-pass");
        let (g, secs) = inverse::to_sections(&lp);
        let lp_design = inverse::Design {
            gain: g,
            sections: secs,
            ..stable.clone()
        };
        let u_lp = lp_design.run::<f64>(&u_t).unwrap_or_default();
        let lp_delay = (stable.latency_samples - model.delay as f64).max(0.0);
        // u_hat[k] ~ u_lp[k - (latency - lp delay)]: align u_hat against the band-limited reference.
        let shift = (stable.latency_samples - lp_delay).round().max(0.0) as usize;
        let (e_bl, _) = aligned_error(&u_lp, &u_hat, shift.saturating_sub(6)..=shift + 6);
        let e_direct = match direct.as_ref().map(|d| d.run::<f32>(&y_t)) {
            Ok(Ok(v)) => {
                let (e, _) = aligned_error(&u_t, &v, window.clone());
                if e.is_finite() {
                    format!("{:.3} %", 100.0 * e)
                } else {
                    "diverges".into()
                }
            }
            Ok(Err(e)) => format!("refused: {e}"),
            Err(e) => format!("refused: {e}"),
        };
        println!(
            "| {} | {:.3} % | {} | {:.3} % | {:.1}x | {:.3} % ({:.1}x) | {:.3} % | {:.0} / {:.0} Hz | {:.2} |",
            case.name,
            100.0 * raw,
            e_direct,
            100.0 * e_stable,
            raw / e_stable,
            100.0 * e_true,
            raw / e_true,
            100.0 * e_bl,
            stable.lowpass_hz,
            stable.corrected_bandwidth_hz,
            stable.noise_gain
        );
    }
}
