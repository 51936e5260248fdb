//! Delay-search benchmark (a benchmark, not a test): a slow probe sampled fast has a long range
//! of candidate delays, each a fit on the step's window. `unlag` searches a long range coarse
//! to fine; the baseline, in the same run, tries every candidate, as `unlag` did before
//! (written here from the crate's public Steiglitz-McBride fit and loss, with the same window,
//! iterations and choice rule).
//!
//! ```sh
//! cargo run --release --example bench_delay
//! taskset -c 0 target/release/examples/bench_delay   # unlag's search on one core too
//! ```
//!
//! Data: an overdamped two-lag probe (a capillary's shape; time constants `tau1` and `tau2`
//! samples) behind a delay, a unit step, white noise of 0.3 % of the step on both channels and
//! a 16-bit ADC over +-2. Printed: a Markdown table for `BENCHMARKS.md`.

use std::time::Instant;
use unlag::fit::arx::Data;
use unlag::fit::{self, oe, Method, Options, Order, Test};

/// One drawn case: record length, step onset, the probe's two time constants and delay (samples).
struct Case {
    n: usize,
    onset: usize,
    tau1: f64,
    tau2: f64,
    delay: usize,
}

/// xorshift64* with Irwin-Hall Gaussians (12 uniforms): deterministic, no crate.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn gauss(&mut self) -> f64 {
        (0..12).map(|_| self.uniform()).sum::<f64>() - 6.0
    }
}

/// The case's reference and probe, with noise on both and a 16-bit ADC over +-2.
fn record(c: &Case, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut noise = Noise(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let adc = |v: f64| (v.clamp(-2.0, 2.0) * 16384.0).round() / 16384.0;
    let (a1, a2) = ((-1.0 / c.tau1).exp(), (-1.0 / c.tau2).exp());
    let (mut s1, mut s2) = (0.0, 0.0);
    let step = |k: usize| if k >= c.onset { 1.0 } else { 0.0 };
    let mut u = Vec::with_capacity(c.n);
    let mut y = Vec::with_capacity(c.n);
    for k in 0..c.n {
        let late = k.checked_sub(c.delay).map_or(0.0, step);
        s1 = a1 * s1 + (1.0 - a1) * late;
        s2 = a2 * s2 + (1.0 - a2) * s1;
        u.push(adc(step(k) + 0.003 * noise.gauss()));
        y.push(adc(s2 + 0.003 * noise.gauss()));
    }
    (u, y)
}

/// The delay search as it was: every candidate from 0 to where the probe has made half its
/// step, a Steiglitz-McBride fit (8 iterations) on the window from 200 samples before the step
/// to 20 000 after it, and the largest delay within 2 noise variances of the best.
/// Returns the delay and the number of candidates tried.
fn every_delay(u: &[f64], y: &[f64], onset: usize, m: usize) -> (usize, usize) {
    let level = |x: &[f64]| x[..onset].iter().sum::<f64>() / onset as f64;
    let (lu, ly) = (level(u), level(y));
    let u: Vec<f64> = u.iter().map(|v| v - lu).collect();
    let y: Vec<f64> = y.iter().map(|v| v - ly).collect();
    let n = y.len();
    let tail = &y[n - n / 10..];
    let yfinal = tail.iter().sum::<f64>() / tail.len() as f64;
    let half = y[onset..]
        .iter()
        .position(|v| v / yfinal > 0.5)
        .unwrap_or(n - onset);
    let hi = (half + 2).min(n / 4);
    let (start, end) = (onset.saturating_sub(200), (onset + 20_000).min(n));
    let sets = [Data {
        u: &u[start..end],
        y: &y[start..end],
    }];
    let energy: f64 = sets[0].y.iter().map(|v| v * v).sum();
    let rows: Vec<(usize, f64)> = (0..=hi)
        .filter_map(|d| {
            let (a, b) = oe::steiglitz_mcbride_nb(&sets, m, m, d, 8).ok()?;
            let l = oe::loss(&sets, (&a, &b), d);
            l.is_finite().then(|| (d, (l / energy).sqrt()))
        })
        .collect();
    let best = rows.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    let tol = best * best * (1.0 + 2.0 / (end - start) as f64);
    let d = rows
        .iter()
        .filter(|r| r.1 * r.1 <= tol)
        .map(|r| r.0)
        .max()
        .unwrap_or(0);
    (d, hi + 1)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let fs = 10_000.0;
    let cases = [
        Case {
            n: 20_000,
            onset: 2_000,
            tau1: 700.0,
            tau2: 60.0,
            delay: 25,
        },
        Case {
            n: 100_000,
            onset: 10_000,
            tau1: 1_500.0,
            tau2: 120.0,
            delay: 60,
        },
        Case {
            n: 1_000_000,
            onset: 20_000,
            tau1: 3_000.0,
            tau2: 200.0,
            delay: 120,
        },
    ];
    println!(
        "| rows | probe (time constants, delay; samples) | candidates | unlag: tried | unlag: search | every delay: search | every / unlag | delay unlag / every | fit nrmse unlag / every |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (i, c) in cases.iter().enumerate() {
        let (u, y) = record(c, i as u64 + 1);
        let test = Test {
            name: "step",
            u: &u,
            y: &y,
        };
        let options = |delay| Options {
            method: Method::Oe,
            order: Order::Fixed(2),
            delay,
        };
        // unlag's whole fit with the delay searched, then the same fit given that delay: the
        // difference is the search.
        let t = Instant::now();
        let searched = fit::fit(&test, &[], fs, &options(None))?;
        let whole = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let given = fit::fit(&test, &[], fs, &options(Some(searched.model.delay)))?;
        let unlag_search = (whole - t.elapsed().as_secs_f64()).max(0.0);
        let tried = searched.report.delay_candidates.len();
        let t = Instant::now();
        let (d_every, candidates) = every_delay(&u, &y, c.onset, 2);
        let every_search = t.elapsed().as_secs_f64();
        let every_fit = fit::fit(&test, &[], fs, &options(Some(d_every)))?;
        println!(
            "| {} | {:.0}, {:.0}; {} | {candidates} | {tried} | {:.2} s | {:.2} s | {:.1}x | {} / {d_every} | {:.4} % / {:.4} % |",
            c.n,
            c.tau1,
            c.tau2,
            c.delay,
            unlag_search,
            every_search,
            every_search / unlag_search.max(1e-9),
            searched.model.delay,
            100.0 * given.nrmse_estimation,
            100.0 * every_fit.nrmse_estimation,
        );
    }
    println!();
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    println!(
        "The search's time is the whole fit with the delay searched less the same fit given the delay found; the baseline's is its loop alone, on one thread. unlag's search used the {cores} core(s) this process may run on (`taskset -c 0` gives it one)."
    );
    Ok(())
}
