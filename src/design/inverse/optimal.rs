//! The noise-aware optimal reconstruction: the fixed-lag Kalman smoother of the probe model
//! under a random-walk signal prior, realised as second-order sections, and the predicted error
//! budget of any compensator.
//!
//! # The problem
//! The probe gives `y = G u + n_y`, `G = z^-d B/A` the fitted model, `n_y` the probe's noise
//! (white, plus an AR(1) part when the quiet segment before the step shows one). The
//! compensator `C` should make `C y` as close as possible to `u[k - L]` for a latency `L`
//! the user accepts. With a prior for the pressure `u` (default: a random walk, whose spectrum
//! falls like `1/f^2`, the spectrum of steps and ramps), the filter with the least mean-square
//! error for that latency is the fixed-lag Kalman smoother (Mendel, *Optimal Seismic
//! Deconvolution*, 1983, and the literature on input estimation by Kalman filtering).
//!
//! # Method
//! 1. State space of the delay-free model (transposed direct form II), with the pressure `u`
//!    appended as a random-walk state (increment standard deviation
//!    [`SignalPrior::increment_std`]) and, when measured, the AR(1) part of the probe noise.
//! 2. The steady-state filter Riccati equation is solved once by the structure-preserving
//!    doubling algorithm (faer LU solves, no explicit inverse), which converges quadratically
//!    even for poles next to `z = 1` (leaks, the random walk itself).
//! 3. The fixed-lag gains follow from the filter's solution without enlarging the state:
//!    `u_hat[k-L|k] = u_hat[k-L|k-L-1] + sum_{i=0..L} G_i e[k-L+i]`, `e` the innovations,
//!    `G_i = e_u' P (A_cl')^i H' / s`. The error variance for every lag comes out of the same
//!    sum ([`Smoother::error_std`]), so the latency is chosen from the whole curve.
//! 4. The smoother is a rational filter with the Kalman filter's closed-loop poles and `L` poles
//!    at the origin: its impulse response times the denominator gives the numerator exactly;
//!    poles and zeros are paired into sections as for every other compensator
//!    ([`super::to_sections`]), and the sections' response is checked against the state space.
//!
//! # The error budget
//! For any compensator `C` with latency `L`, the error spectrum is
//! `|C G - z^-L|^2 S_u + |C|^2 S_ny`: the first term is the band-limit part (what the
//! compensator does not restore), the second the noise part. [`budget`] integrates both on a
//! grid dense near DC; a measured error adds the reference channel's own noise (it is a sensor
//! too) and the model's error, which [`Budget`] carries apart.

use std::f64::consts::PI;

use super::{cascade_response, model_response};
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::poly::Complex;

mod error_budget;
pub mod on_run;
mod smoother;
mod spectra;

pub use crate::fit::step::NoiseSource;
use error_budget::BudgetGrid;
pub use error_budget::{budget, offline, Budget};
pub use on_run::{RunPressure, RunSpectrum};
pub use smoother::Smoother;
pub use spectra::{
    estimate_noise, estimate_prior, prior_from_runs, NoiseModel, PriorSource, SignalPrior,
    MAX_INCREMENT_POLE, MIN_QUIET,
};

/// Largest number of sections a realisation may have (a 32nd-order compensator; `unlag
/// export` writes at most this many).
pub const MAX_SECTIONS: usize = 16;

/// A reduced-order realisation is preferred when its predicted error is within this factor of
/// the full smoother's.
pub const REDUCED_TOLERANCE: f64 = 1.10;

/// The default lag is the shortest whose predicted error is within this factor of the best
/// lag the capacity allows.
pub const LAG_TOLERANCE: f64 = 1.02;

/// How to design the optimal compensator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OptimalOptions {
    /// Largest latency the user accepts, in samples (the model's delay included).
    pub max_latency_samples: Option<usize>,
    /// Largest -3 dB band of the corrected probe the user accepts, in Hz.
    pub max_band_hz: Option<f64>,
    /// The reduced-order family's low-pass (a stable inverse times this low-pass, its corner
    /// chosen by the predicted error).
    pub lowpass: super::LowpassKind,
    /// Its order.
    pub lowpass_order: usize,
}

impl Default for OptimalOptions {
    fn default() -> Self {
        Self {
            max_latency_samples: None,
            max_band_hz: None,
            lowpass: super::LowpassKind::Bessel,
            lowpass_order: 4,
        }
    }
}

/// The band-limited inverse whose corner gives the lowest predicted error (a log grid from
/// fs/2000 to 0.45 fs, refined by golden section), with its budget.
fn best_band_limited(
    model: &Model,
    noise: &NoiseModel,
    prior: &SignalPrior,
    options: &OptimalOptions,
    max_latency: f64,
) -> Option<(super::Design, Budget)> {
    let fs = model.fs;
    let inverse_options = super::Options {
        bandwidth_hz: None,
        lowpass: options.lowpass,
        lowpass_order: options.lowpass_order,
        stabilise: true,
    };
    // The model's response and the spectra on the budget's grid are the same at every corner:
    // computed once. Each corner is scored by its cascade alone; only the chosen one is
    // finished into a design (its responses on a grid and its noise gain).
    let spectra = BudgetGrid::new(model, noise, prior);
    let score = |fc: f64| -> Option<(f64, (f64, super::Core), Budget)> {
        let d = super::design_core(model, fc, &inverse_options).ok()?;
        if d.latency > max_latency || d.pole_margin < crate::board::compensator::MIN_POLE_MARGIN {
            return None;
        }
        let b = spectra.budget(d.gain, &d.sections, d.latency);
        Some((b.total, (fc, d), b))
    };
    let (lo, hi) = (fs / 2000.0, 0.45 * fs);
    let n = 36;
    let grid: Vec<f64> = (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect();
    let mut best: Option<(f64, (f64, super::Core), Budget, usize)> = None;
    // The corners are scored on the cores there are and taken in order: the same choice.
    for (i, scored) in crate::fit::in_parallel(&grid, |&fc| score(fc))
        .into_iter()
        .enumerate()
    {
        if let Some((e, d, b)) = scored {
            if best.as_ref().is_none_or(|x| e < x.0) {
                best = Some((e, d, b, i));
            }
        }
    }
    let (mut e, mut d, mut b, i) = best?;
    let mut a = grid.get(i.saturating_sub(1)).copied().unwrap_or(lo).ln();
    let mut c = grid.get(i + 1).copied().unwrap_or(hi).ln();
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..10 {
        let x1 = c - g * (c - a);
        let x2 = a + g * (c - a);
        let [s1, s2]: [_; 2] = crate::fit::in_parallel(&[x1, x2], |x| score(x.exp()))
            .try_into()
            .ok()?;
        let e1 = s1.as_ref().map_or(f64::INFINITY, |x| x.0);
        let e2 = s2.as_ref().map_or(f64::INFINITY, |x| x.0);
        for cand in [s1, s2].into_iter().flatten() {
            if cand.0 < e {
                (e, d, b) = cand;
            }
        }
        if e1 < e2 {
            c = x2;
        } else {
            a = x1;
        }
    }
    let (fc, core) = d;
    Some((core.finish(model, fc, &inverse_options), b))
}

/// Corrected bandwidth (where `H C` leaves +/-1 dB or +/-5 degrees of the pure delay
/// `latency`), the -3 dB band of `H C`, and the worst magnitude (dB) and phase (degrees)
/// errors below half that band.
fn response_numbers(
    model: &Model,
    gain: f64,
    sections: &[[f64; 5]],
    latency: f64,
) -> (f64, f64, f64, f64) {
    let fs = model.fs;
    let n = 4000;
    let freqs: Vec<f64> = (1..=n).map(|i| 0.5 * fs * i as f64 / n as f64).collect();
    let t: Vec<Complex> = freqs
        .iter()
        .map(|&f| {
            let z = super::unit(f, fs);
            model_response(model, z) * cascade_response(gain, sections, z)
        })
        .collect();
    let phase = super::unwrap(&t);
    let errors: Vec<(f64, f64)> = freqs
        .iter()
        .zip(&t)
        .zip(&phase)
        .map(|((f, v), ph)| {
            (
                20.0 * v.norm().log10(),
                (ph + 2.0 * PI * f / fs * latency).to_degrees(),
            )
        })
        .collect();
    let corrected = freqs
        .iter()
        .zip(&errors)
        .find(|(_, (db, deg))| db.abs() > 1.0 || deg.abs() > 5.0)
        .map_or(0.5 * fs, |(f, _)| *f);
    let band = freqs
        .iter()
        .zip(&errors)
        .find(|(_, (db, _))| *db < -3.0)
        .map_or(0.5 * fs, |(f, _)| *f);
    let (mut worst_db, mut worst_deg) = (0.0f64, 0.0f64);
    for (f, (db, deg)) in freqs.iter().zip(&errors) {
        if *f > 0.5 * band {
            break;
        }
        worst_db = worst_db.max(db.abs());
        worst_deg = worst_deg.max(deg.abs());
    }
    (corrected, band, worst_db, worst_deg)
}

/// Designs the compensator with the least predicted error for the model, the measured noise
/// and the signal prior: the fixed-lag Kalman smoother at the shortest lag whose error is
/// within [`LAG_TOLERANCE`] of the best the capacity and `max_latency_samples` allow, or the
/// band-limited inverse whose corner minimises the same predicted error when that one is
/// within [`REDUCED_TOLERANCE`] of the smoother with fewer sections.
///
/// # Errors
/// [`Error::InvalidArgument`] when the latency cap is below the model's delay;
/// [`crate::design::DesignError`] as [`Smoother::new`] and [`Smoother::realise`], and when the
/// smoother's poles are too close to the unit circle for the board.
pub fn design(
    model: &Model,
    noise: &NoiseModel,
    prior: &SignalPrior,
    options: &OptimalOptions,
) -> Result<super::Design> {
    let first = design_for(model, noise, prior, options)?;
    let Some(cap) = options.max_band_hz else {
        return Ok(first);
    };
    if first.lowpass_hz <= cap {
        return Ok(first);
    }
    // A band cap: the quietest prior whose design stays within it, by bisection on the
    // logarithm of the prior's level (the band falls as the prior quietens).
    let scaled = |factor: f64| SignalPrior {
        increment_std: prior.increment_std * factor,
        ..*prior
    };
    let (mut lo, mut hi) = (-12.0f64, 0.0f64);
    let mut best = None;
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        match design_for(model, noise, &scaled(10f64.powf(mid)), options) {
            Ok(d) if d.lowpass_hz <= cap => {
                lo = mid;
                best = Some((10f64.powf(mid), d));
            }
            Ok(_) => hi = mid,
            // Too quiet a prior puts the smoother's poles on the unit circle: louder.
            Err(_) => lo = mid,
        }
    }
    let (factor, mut d) = best.ok_or_else(|| Error::InvalidArgument {
        what: "band",
        message: format!("no optimal compensator has a band below {cap} Hz"),
    })?;
    d.bandwidth_selection = format!(
        "{}; capped at {cap} Hz by a prior {factor:.3e} times the measured level",
        d.bandwidth_selection
    );
    // The error to expect is the measured prior's (the quieter one only placed the band); the
    // stored prior stays the quieter one, so that a redesign keeps the cap.
    d.budget = Some(budget(
        model,
        d.gain,
        &d.sections,
        d.latency_samples,
        noise,
        prior,
    ));
    Ok(d)
}

/// [`design`] without the band cap.
fn design_for(
    model: &Model,
    noise: &NoiseModel,
    prior: &SignalPrior,
    options: &OptimalOptions,
) -> Result<super::Design> {
    let mut smoother = Smoother::new(model, noise, prior)?;
    let delay = smoother.delay();
    let states = smoother.h.len();
    let capacity_lag = (2 * MAX_SECTIONS).saturating_sub(states);
    let cap = match options.max_latency_samples {
        Some(max) if max < delay => {
            return Err(Error::InvalidArgument {
                what: "latency",
                message: format!(
                    "a latency of at most {max} samples is less than the model's delay of {delay} samples: the probe has not answered yet"
                ),
            })
        }
        Some(max) => (max - delay).min(capacity_lag),
        None => capacity_lag,
    };
    let curve = smoother.error_std(cap);
    let best = curve.last().copied().unwrap_or(f64::INFINITY);
    let mut lag = curve
        .iter()
        .position(|e| *e <= LAG_TOLERANCE * best)
        .unwrap_or(cap);
    // Root finding of a long numerator can fail to reproduce it: fall to shorter lags.
    let (gain, sections) = loop {
        match smoother.realise(lag) {
            Ok(r) => break r,
            Err(e) if lag == 0 => return Err(e),
            Err(_) => lag = lag.saturating_sub(2),
        }
    };
    let latency = (delay + lag) as f64;
    let full_budget = budget(model, gain, &sections, latency, noise, prior);
    let max_latency = options
        .max_latency_samples
        .map_or(f64::INFINITY, |m| m as f64);
    if let Some((mut reduced, b)) = best_band_limited(model, noise, prior, options, max_latency) {
        if b.total <= REDUCED_TOLERANCE * full_budget.total
            && reduced.sections.len() < sections.len()
        {
            reduced.method = super::DesignMethod::new(super::MethodKind::ReducedOptimal, &format!(
                "a stable inverse times a {:?} low-pass at the corner of least predicted error, {:.2}x the fixed-lag Kalman smoother's error ({} sections against {}, predicted {:.4} against {:.4})",
                options.lowpass,
                b.total / full_budget.total,
                reduced.sections.len(),
                sections.len(),
                b.total,
                full_budget.total
            ));
            reduced.bandwidth_selection =
                "the corner of least predicted error (noise and band limit)".into();
            reduced.noise = Some(*noise);
            reduced.prior = Some(*prior);
            reduced.budget = Some(b);
            return Ok(reduced);
        }
    }
    let (corrected, band, worst_db, worst_deg) = response_numbers(model, gain, &sections, latency);
    let pole_margin = 1.0
        - sections
            .iter()
            .map(|s| {
                let disc = s[3] * s[3] - 4.0 * s[4];
                if disc >= 0.0 {
                    let r = disc.sqrt();
                    (0.5 * (-s[3] + r)).abs().max((0.5 * (-s[3] - r)).abs())
                } else {
                    s[4].abs().sqrt()
                }
            })
            .fold(0.0, f64::max);
    if pole_margin.is_nan() || pole_margin < crate::board::compensator::MIN_POLE_MARGIN {
        return Err(crate::design::DesignError::SmootherPoleMargin {
            margin: pole_margin,
        }
        .into());
    }
    Ok(super::Design {
        method: super::DesignMethod::new(super::MethodKind::Smoother, &format!(
            "fixed-lag Kalman smoother, lag {lag} samples ({} prior, measured probe noise{})",
            if prior.increment_pole > 0.0 { "steps-and-ramps" } else { "random-walk" },
            if noise.probe_ar_std > 0.0 { " with its AR(1) part" } else { "" }
        )),
        lowpass: options.lowpass,
        lowpass_order: options.lowpass_order,
        lowpass_hz: band,
        bandwidth_selection: format!(
            "the smoother's -3 dB band; lag chosen within {:.0} % of the best error the latency cap allows ({} samples)",
            100.0 * (LAG_TOLERANCE - 1.0),
            delay + cap
        ),
        gain,
        noise_gain: super::noise_gain(gain, &sections),
        sections,
        latency_samples: latency,
        latency_s: latency / model.fs,
        corrected_bandwidth_hz: corrected,
        in_band_magnitude_error_db: worst_db,
        in_band_phase_error_deg: worst_deg,
        pole_margin,
        reflected_zeros: Vec::new(),
        pulled_zeros: Vec::new(),
        candidates: Vec::new(),
        reconstruction: Vec::new(),
        fixed: None,
        fixed_direct: None,
        noise: Some(*noise),
        prior: Some(*prior),
        budget: Some(full_budget),
        check: None,
        model_sha256: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line() -> Model {
        // 95 Hz, damping 0.22 at 10 kHz, step invariant, delay 18.
        let fs = 10_000.0;
        let (wn, z) = (2.0 * PI * 95.0, 0.22);
        let t = 1.0 / fs;
        let r = (-z * wn * t).exp();
        let wd = wn * (1.0 - z * z).sqrt();
        let a1 = -2.0 * r * (wd * t).cos();
        let a2 = r * r;
        // Step-invariant numerator from the step response at two samples.
        let step = |k: f64| {
            let tk = k * t;
            1.0 - (-z * wn * tk).exp()
                * ((wd * tk).cos() + z / (1.0 - z * z).sqrt() * (wd * tk).sin())
        };
        // y[1] = b1 and y[2] = b1 + b2 - a1 y[1] for a unit step from rest.
        let (s1, s2) = (step(1.0), step(2.0));
        let b1 = s1;
        let b2 = s2 + a1 * s1 - b1;
        Model {
            fs,
            delay: 18,
            a: vec![a1, a2],
            b: vec![0.0, b1, b2],
        }
    }

    fn levels() -> (NoiseModel, SignalPrior) {
        (
            NoiseModel {
                probe_white_std: 2e-3,
                probe_ar_pole: 0.0,
                probe_ar_std: 0.0,
                reference_std: 2e-3,
                source: NoiseSource::Given,
            },
            SignalPrior {
                increment_std: (1.0f64 / 4000.0).sqrt(),
                increment_pole: 0.0,
                source: PriorSource::Given,
            },
        )
    }

    #[test]
    fn the_model_is_a_calibrated_line() {
        assert!(
            (line().dc_gain() - 1.0).abs() < 1e-9,
            "{}",
            line().dc_gain()
        );
    }

    #[test]
    fn smoother_error_falls_with_lag_and_matches_its_frequency_budget() {
        let model = line();
        let (noise, prior) = levels();
        let mut s = Smoother::new(&model, &noise, &prior).unwrap();
        let e = s.error_std(40);
        assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-15), "{e:?}");
        // Waiting for the probe's answer to a sample pays: less than half the filter's error.
        assert!(e[40] < 0.5 * e[0], "{} {}", e[0], e[40]);
        for lag in [0, 5, 20] {
            let (g, sec) = s.realise(lag).unwrap();
            let b = budget(&model, g, &sec, (s.delay() + lag) as f64, &noise, &prior);
            let rel = (b.total - e[lag]).abs() / e[lag];
            assert!(
                rel < 1e-3,
                "lag {lag}: budget {} against Riccati {}",
                b.total,
                e[lag]
            );
        }
    }

    #[test]
    fn a_ramp_prior_is_the_state_space_its_spectrum_says_and_boosts_less() {
        // The augmented state (increment with pole rho) against the frequency budget of
        // the prior's spectrum q / (|1 - z^-1|^2 |1 - rho z^-1|^2).
        let model = line();
        let (noise, steps) = levels();
        let ramps = SignalPrior {
            increment_pole: 0.95,
            increment_std: steps.increment_std * 0.05,
            ..steps
        };
        let mut s = Smoother::new(&model, &noise, &ramps).unwrap();
        let e = s.error_std(30);
        for lag in [0, 10, 30] {
            let (g, sec) = s.realise(lag).unwrap();
            let b = budget(&model, g, &sec, (s.delay() + lag) as f64, &noise, &ramps);
            assert!(
                (b.total - e[lag]).abs() / e[lag] < 1e-3,
                "lag {lag}: budget {} against Riccati {}",
                b.total,
                e[lag]
            );
        }
        // A smooth signal has little above the corner: the smoother amplifies the noise less.
        let step_design = design(&model, &noise, &steps, &OptimalOptions::default()).unwrap();
        let ramp_design = design(&model, &noise, &ramps, &OptimalOptions::default()).unwrap();
        assert!(
            ramp_design.noise_gain < step_design.noise_gain,
            "{} against {}",
            ramp_design.noise_gain,
            step_design.noise_gain
        );
    }

    #[test]
    fn a_band_limited_inverse_is_never_better_than_the_smoother_at_its_latency() {
        let model = line();
        let (noise, prior) = levels();
        let mut s = Smoother::new(&model, &noise, &prior).unwrap();
        for fc in [200.0, 400.0, 800.0, 1600.0] {
            let d = super::super::design(&model, fc, &super::super::Options::default()).unwrap();
            let b = budget(
                &model,
                d.gain,
                &d.sections,
                d.latency_samples,
                &noise,
                &prior,
            );
            let lag = (d.latency_samples - s.delay() as f64).floor().max(0.0) as usize;
            let e = s.error_std(lag)[lag];
            assert!(b.total >= 0.98 * e, "fc {fc}: {} < smoother {e}", b.total);
        }
    }

    #[test]
    fn smoother_sections_pass_a_steady_pressure_unchanged() {
        let model = line();
        let (noise, prior) = levels();
        let mut s = Smoother::new(&model, &noise, &prior).unwrap();
        let (g, sec) = s.realise(12).unwrap();
        let dc = cascade_response(g, &sec, Complex::new(1.0, 0.0))
            * model_response(&model, Complex::new(1.0, 0.0));
        assert!((dc.re - 1.0).abs() < 1e-6 && dc.im.abs() < 1e-9, "{dc:?}");
    }

    #[test]
    fn a_band_cap_narrows_the_optimum_to_just_below_it() {
        let model = line();
        let (noise, prior) = levels();
        let free = design(&model, &noise, &prior, &OptimalOptions::default()).unwrap();
        let cap = 0.5 * free.lowpass_hz;
        let capped = design(
            &model,
            &noise,
            &prior,
            &OptimalOptions {
                max_band_hz: Some(cap),
                ..OptimalOptions::default()
            },
        )
        .unwrap();
        assert!(capped.lowpass_hz <= cap, "{} > {cap}", capped.lowpass_hz);
        assert!(
            capped.lowpass_hz > 0.8 * cap,
            "{} far below {cap}",
            capped.lowpass_hz
        );
        let (b_free, b_capped) = (free.budget.unwrap(), capped.budget.unwrap());
        // Less noise, more band-limit error, more in all: the free optimum is the optimum.
        assert!(b_capped.noise < b_free.noise, "{b_capped:?} {b_free:?}");
        assert!(b_capped.total > b_free.total, "{b_capped:?} {b_free:?}");
    }
}
