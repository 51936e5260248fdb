//! The error a compensator leaves, from the spectra: the predicted budget of any cascade, and
//! the non-causal optimum on a recorded run that every causal compensator is measured against.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::{NoiseModel, SignalPrior};
use crate::design::inverse::{cascade_response_at_inverse, model_response};
use crate::error::Result;
use crate::fit::model::Model;
use crate::poly::Complex;

/// Predicted error of a compensator, as standard deviations in pressure units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Budget {
    /// The probe noise through the compensator.
    pub noise: f64,
    /// The pressure the compensator does not restore within its latency (band limit and
    /// smoothing).
    pub band_limit: f64,
    /// `noise` and `band_limit` together: the error of `u_hat` against the true pressure.
    pub total: f64,
    /// The reference channel's own noise, which a comparison with the recorded reference adds.
    pub reference: f64,
}

/// The non-causal optimum on a recorded run (host only, `unlag compensate --offline`):
/// `F = conj(G) S_u / (|G|^2 S_u + S_ny)` applied by FFT, the model's delay included in `G`, so
/// `u_hat` has no latency at all and the least error any linear filter can reach: the oracle a
/// causal compensator is measured against. The record is extended at both ends by its edge
/// values (a quarter of its length, at least 4096 samples) before the circular transform, so
/// that neither end wraps into the other.
///
/// # Errors
/// [`crate::design::DesignError::RecordTooLong`] when the record is too long for a power-of-two
/// transform.
pub fn offline(
    model: &Model,
    noise: &NoiseModel,
    prior: &SignalPrior,
    y: &[f64],
) -> Result<Vec<f64>> {
    let n = y.len();
    let (Some(&first), Some(&last)) = (y.first(), y.last()) else {
        return Ok(Vec::new());
    };
    let pad = (n / 4).max(4096);
    let size = (n + 2 * pad)
        .checked_next_power_of_two()
        .ok_or(crate::design::DesignError::RecordTooLong { samples: n })?;
    let head = size - n - pad;
    let mut buf: Vec<Complex> = Vec::with_capacity(size);
    buf.extend(std::iter::repeat_n(Complex::new(first, 0.0), head));
    buf.extend(y.iter().map(|v| Complex::new(*v, 0.0)));
    buf.extend(std::iter::repeat_n(Complex::new(last, 0.0), pad));
    let mut planner = rustfft::FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(size);
    let inverse = planner.plan_fft_inverse(size);
    // faer's c64 and rustfft's Complex64 are both num-complex: the buffer goes through as is.
    forward.process(&mut buf);
    let dc = model_response(model, Complex::new(1.0, 0.0));
    for (k, v) in buf.iter_mut().enumerate() {
        let w = 2.0 * PI * k as f64 / size as f64;
        let f = if k == 0 {
            Complex::new(1.0, 0.0) / dc
        } else {
            let g = model_response(model, Complex::new(w.cos(), w.sin()));
            let su = prior.psd(w);
            g.conj() * su / (g.norm_sqr() * su + noise.probe_psd(w))
        };
        *v *= f;
    }
    inverse.process(&mut buf);
    let scale = 1.0 / size as f64;
    Ok(buf
        .iter()
        .skip(head)
        .take(n)
        .map(|v| v.re * scale)
        .collect())
}

/// Frequency grid on `(0, pi]`, dense near DC where the prior's spectrum rises: `pi (i/n)^2`,
/// with trapezoid weights.
fn grid(n: usize) -> Vec<(f64, f64)> {
    let w: Vec<f64> = (1..=n)
        .map(|i| PI * (i as f64 / n as f64).powi(2))
        .collect();
    w.iter()
        .enumerate()
        .map(|(i, &x)| {
            let lo = if i == 0 { 0.0 } else { w[i - 1] };
            let hi = w.get(i + 1).copied().unwrap_or(PI);
            (x, 0.5 * (hi - lo))
        })
        .collect()
}

/// Predicted error of the cascade `(gain, sections)` run on the probe signal, against the
/// pressure `latency` samples earlier.
#[must_use]
pub fn budget(
    model: &Model,
    gain: f64,
    sections: &[[f64; 5]],
    latency: f64,
    noise: &NoiseModel,
    prior: &SignalPrior,
) -> Budget {
    BudgetGrid::new(model, noise, prior).budget(gain, sections, latency)
}

/// One point of [`BudgetGrid`]: what the budget's integrand takes there that no compensator
/// changes.
struct Point {
    w: f64,
    dw: f64,
    zi: Complex,
    g: Complex,
    signal_psd: f64,
    noise_psd: f64,
}

/// The budget's frequency grid with the model's response and both spectra on it: computed
/// once for a search that scores many compensators of one model ([`budget`] of each is the
/// same number, to the bit).
pub(crate) struct BudgetGrid {
    points: Vec<Point>,
    reference_std: f64,
}

impl BudgetGrid {
    /// The grid for `model` under `noise` and `prior`.
    pub(crate) fn new(model: &Model, noise: &NoiseModel, prior: &SignalPrior) -> Self {
        let points = grid(6000)
            .into_iter()
            .map(|(w, dw)| {
                let z = Complex::new(w.cos(), w.sin());
                Point {
                    w,
                    dw,
                    zi: Complex::new(1.0, 0.0) / z,
                    g: model_response(model, z),
                    signal_psd: prior.psd(w),
                    noise_psd: noise.probe_psd(w),
                }
            })
            .collect();
        Self {
            points,
            reference_std: noise.reference_std,
        }
    }

    /// [`budget`] of the cascade `(gain, sections)` with `latency`.
    pub(crate) fn budget(&self, gain: f64, sections: &[[f64; 5]], latency: f64) -> Budget {
        let (mut band, mut noise_var) = (0.0, 0.0);
        for p in &self.points {
            let c = cascade_response_at_inverse(gain, sections, p.zi);
            let target = Complex::new((p.w * latency).cos(), -(p.w * latency).sin());
            band += (c * p.g - target).norm_sqr() * p.signal_psd * p.dw;
            noise_var += c.norm_sqr() * p.noise_psd * p.dw;
        }
        // (1/2pi) over (-pi, pi] = (1/pi) over (0, pi].
        let band = (band / PI).sqrt();
        let noise_part = (noise_var / PI).sqrt();
        Budget {
            noise: noise_part,
            band_limit: band,
            total: band.hypot(noise_part),
            reference: self.reference_std,
        }
    }
}
