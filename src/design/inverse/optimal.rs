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
//! error for that latency is the fixed-lag Kalman smoother (`../shared/reference/`
//! optimal-reconstruction.md, section 3).
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

use faer::linalg::solvers::Solve;
use faer::Mat;
use serde::{Deserialize, Serialize};

use super::{cascade_response, model_response, to_sections, Zpk};
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::fit::step::{self, detrend};
use crate::fit::Test;
use crate::poly::{self, Complex};

pub use crate::fit::step::NoiseSource;

/// The noise of both channels, as the design sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseModel {
    /// White part of the probe noise, standard deviation in probe units.
    pub probe_white_std: f64,
    /// AR(1) pole of the coloured part of the probe noise (0 when none was found).
    pub probe_ar_pole: f64,
    /// Standard deviation of the AR(1) part (0 when none was found).
    pub probe_ar_std: f64,
    /// Noise of the reference channel, standard deviation in pressure units.
    pub reference_std: f64,
    /// Where the probe noise was measured.
    pub source: NoiseSource,
}

impl NoiseModel {
    /// Probe noise power spectral density (per sample, two-sided) at `omega` rad/sample.
    #[must_use]
    pub fn probe_psd(&self, omega: f64) -> f64 {
        let white = self.probe_white_std * self.probe_white_std;
        if self.probe_ar_std > 0.0 {
            let phi = self.probe_ar_pole;
            let innovation = self.probe_ar_std * self.probe_ar_std * (1.0 - phi * phi);
            let den = 1.0 + phi * phi - 2.0 * phi * omega.cos();
            white + innovation / den
        } else {
            white
        }
    }

    /// Takes the coloured part of the probe noise from an AR noise model `D(q) v = e`
    /// (`ar` = `[d1..dp]`, `innovation_std` of `e`), as the AR(1) with the same variance and
    /// lag-1 correlation, less the white part already measured.
    pub fn take_ar_part(&mut self, ar: &[f64], innovation_std: f64) {
        // Impulse response of 1 / D(q), long enough for a pole at 0.9995 to fade.
        let mut impulse = vec![0.0f64; 8192];
        if let Some(first) = impulse.first_mut() {
            *first = 1.0;
        }
        let h = crate::fit::oe::allpole(ar, &impulse);
        let var = |lag: usize| -> f64 {
            innovation_std
                * innovation_std
                * h.iter()
                    .zip(h.iter().skip(lag))
                    .map(|(a, b)| a * b)
                    .sum::<f64>()
        };
        let (r0, r1) = (var(0), var(1));
        let coloured = r0 - self.probe_white_std * self.probe_white_std;
        if r0 > 0.0 && coloured > 0.0 && r0.is_finite() {
            self.probe_ar_pole = (r1 / r0).clamp(0.0, 0.9995);
            self.probe_ar_std = coloured.sqrt();
        }
    }

    /// Total probe noise standard deviation.
    #[must_use]
    pub fn probe_std(&self) -> f64 {
        self.probe_white_std.hypot(self.probe_ar_std)
    }
}

/// The prior for the pressure: steps and ramps, a random walk whose increments may be
/// correlated, spectrum `q / (|1 - z^-1|^2 |1 - rho z^-1|^2)`. With `rho = 0` (steps, the
/// default from step tests) it falls like `1/f^2`; with `rho` near 1 (smooth runs: ramps,
/// balloons, wakes) like `1/f^4` above the corner `rho` sets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SignalPrior {
    /// Standard deviation of the increments' innovation, `sqrt(q)`, in pressure units.
    pub increment_std: f64,
    /// Correlation `rho` of successive increments (0: a plain random walk).
    #[serde(default)]
    pub increment_pole: f64,
    /// Where it came from.
    pub source: PriorSource,
}

/// Where the signal prior came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PriorSource {
    /// The step tests' references: their mean-square increment less the reference noise's.
    StepTests,
    /// The user's recorded runs (`--signal`).
    Runs,
    /// Given by the caller.
    Given,
}

impl SignalPrior {
    /// Pressure power spectral density at `omega` rad/sample.
    #[must_use]
    pub fn psd(&self, omega: f64) -> f64 {
        let s = 2.0 * (0.5 * omega).sin();
        let rho = self.increment_pole;
        let ramp = 1.0 - 2.0 * rho * omega.cos() + rho * rho;
        self.increment_std * self.increment_std / (s * s * ramp).max(1e-300)
    }
}

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

/// Fewest quiet samples before a step that the noise is measured on; a test with fewer (a
/// traverse, a balloon burst at once) gives its noise from its highest frequencies.
pub const MIN_QUIET: usize = 64;

/// Measures both channels' noise on `tests`: before the step where there are at least 64 quiet
/// samples (with an AR(1) part when the quiet segment is correlated), else from first
/// differences of the record.
#[must_use]
pub fn estimate_noise(tests: &[Test<'_>]) -> NoiseModel {
    let mut white_var = Vec::new();
    let mut ar = Vec::new();
    let mut reference_var = Vec::new();
    let mut source = NoiseSource::PreStep;
    for t in tests {
        let onset = step::find_step(t.u).map(|s| s.onset).unwrap_or(0);
        if onset >= MIN_QUIET {
            let (w, a) = quiet_noise(t.y.get(..onset).unwrap_or(&[]));
            white_var.push(w);
            ar.push(a);
            let u = detrend(t.u.get(..onset).unwrap_or(&[]));
            reference_var.push(u.iter().map(|v| v * v).sum::<f64>() / u.len().max(1) as f64);
        } else {
            source = NoiseSource::HighFrequency;
            white_var.push(step::noise_std(t.y).powi(2));
            ar.push((0.0, 0.0));
            reference_var.push(step::noise_std(t.u).powi(2));
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    // The AR part only when every test with a quiet segment shows one.
    let (pole, ar_var) = if ar.iter().all(|(p, _)| *p > 0.0) && !ar.is_empty() {
        (
            mean(&ar.iter().map(|a| a.0).collect::<Vec<_>>()),
            mean(&ar.iter().map(|a| a.1).collect::<Vec<_>>()),
        )
    } else {
        (0.0, 0.0)
    };
    let white = if pole > 0.0 {
        mean(&white_var)
    } else {
        // Without a coloured part the whole quiet variance is white.
        mean(
            &white_var
                .iter()
                .zip(&ar)
                .map(|(w, a)| w + a.1)
                .collect::<Vec<_>>(),
        )
    };
    NoiseModel {
        probe_white_std: white.sqrt(),
        probe_ar_pole: pole,
        probe_ar_std: ar_var.sqrt(),
        reference_std: mean(&reference_var).sqrt(),
        source,
    }
}

/// White variance and `(pole, variance)` of an AR(1) part of a quiet segment, from its
/// autocovariances at lags 0, 1, 2: `c1 = phi s^2`, `c2 = phi^2 s^2`, `c0 = w + s^2`. The AR
/// part is kept only when the lag-1 correlation is significant (three standard errors) and the
/// three covariances are consistent with it; otherwise all is white (`(c0, (0, 0))`).
fn quiet_noise(y: &[f64]) -> (f64, (f64, f64)) {
    let x = detrend(y);
    let n = x.len();
    let cov = |lag: usize| -> f64 {
        x.iter()
            .zip(x.iter().skip(lag))
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / n.max(1) as f64
    };
    let (c0, c1, c2) = (cov(0), cov(1), cov(2));
    if c0 <= 0.0 {
        return (0.0, (0.0, 0.0));
    }
    let significant = c1 / c0 > 3.0 / (n as f64).sqrt();
    if significant && c2 > 0.0 && c1 > 0.0 {
        let phi = (c2 / c1).clamp(0.0, 0.9995);
        let s2 = c1 / phi.max(1e-9);
        if phi > 0.05 && s2 < c0 {
            return (c0 - s2, (phi, s2));
        }
    }
    (c0, (0.0, 0.0))
}

/// The random-walk prior from the step tests' references: the mean-square increment less the
/// part the reference noise makes (`2 sigma_u^2`), and at least one step of the test's size per
/// record (`size^2 / N`).
#[must_use]
pub fn estimate_prior(tests: &[Test<'_>], noise: &NoiseModel) -> SignalPrior {
    let mut q = Vec::new();
    for t in tests {
        let n = t.u.len().max(2);
        let msi = t.u.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (n - 1) as f64;
        let size = step::find_step(t.u).map(|s| s.size()).unwrap_or(0.0);
        let floor = size * size / n as f64;
        q.push((msi - 2.0 * noise.reference_std.powi(2)).max(floor));
    }
    let q = q.iter().sum::<f64>() / q.len().max(1) as f64;
    SignalPrior {
        increment_std: q.sqrt(),
        increment_pole: 0.0,
        source: PriorSource::StepTests,
    }
}

/// The prior from the user's own recorded runs. From the reference where a run has one: the
/// increments' variance and lag-1 correlation, less what the reference's white noise adds to
/// them (`2 sigma_u^2` and `-sigma_u^2`), give `q` and `rho` (steps give `rho` near 0, smooth
/// runs near 1). Else from the probe signal over the model's DC gain, its increments taken
/// over `scale` samples (the probe's response time) so that the probe's noise and lag weigh
/// little, less the noise's share `2 sigma_y^2`, as a plain random walk.
#[must_use]
pub fn prior_from_runs(
    runs: &[(Option<&[f64]>, &[f64])],
    dc_gain: f64,
    noise: &NoiseModel,
    scale: usize,
) -> SignalPrior {
    let m = scale.max(1);
    let mut q = Vec::new();
    let mut shaped = Vec::new();
    for (u, y) in runs {
        if let Some(u) = u {
            if let Some(qr) = increments_of(u, noise.reference_std) {
                shaped.push(qr);
                continue;
            }
        }
        let (x, gain, sigma, lag): (&[f64], f64, f64, usize) = match u {
            Some(u) => (u, 1.0, noise.reference_std, 1),
            None => (y, dc_gain, noise.probe_std(), m),
        };
        if x.len() <= lag + 1 || gain == 0.0 {
            continue;
        }
        let count = x.len() - lag;
        let msi = x
            .iter()
            .zip(x.iter().skip(lag))
            .map(|(a, b)| (b - a).powi(2))
            .sum::<f64>()
            / count as f64;
        q.push(((msi - 2.0 * sigma * sigma) / (gain * gain * lag as f64)).max(0.0));
    }
    if !shaped.is_empty() && q.is_empty() {
        // Pooled over the runs: mean increment variance and mean correlation per sample.
        let count = shaped.len() as f64;
        let var = shaped.iter().map(|s| s.0).sum::<f64>() / count;
        let rho = (shaped.iter().map(|s| s.1).sum::<f64>() / count).clamp(0.0, MAX_INCREMENT_POLE);
        return SignalPrior {
            increment_std: (var * (1.0 - rho * rho)).max(0.0).sqrt(),
            increment_pole: rho,
            source: PriorSource::Runs,
        };
    }
    // Probe-only runs (or a mixture): a plain random walk, each run's increment variance.
    q.extend(shaped.iter().map(|s| s.0));
    let q = q.iter().sum::<f64>() / q.len().max(1) as f64;
    SignalPrior {
        increment_std: q.sqrt(),
        increment_pole: 0.0,
        source: PriorSource::Runs,
    }
}

/// Largest increment correlation a learnt prior takes (a corner at `fs / 2000`).
pub const MAX_INCREMENT_POLE: f64 = 0.997;

/// Variance of the pressure's increments in a recorded reference `u`, less its white noise's
/// share `2 sigma^2`, and their lag-1 correlation, the noise's `-sigma^2` added back (0 when
/// not significant: within three standard errors, noise included); `None` for a record too
/// short.
fn increments_of(u: &[f64], sigma: f64) -> Option<(f64, f64)> {
    let d: Vec<f64> = u.windows(2).map(|w| w[1] - w[0]).collect();
    if d.len() < 4 {
        return None;
    }
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let c0 = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64;
    let c1 = d
        .iter()
        .zip(d.iter().skip(1))
        .map(|(a, b)| (a - mean) * (b - mean))
        .sum::<f64>()
        / (d.len() - 1) as f64;
    let s2 = sigma * sigma;
    let var = (c0 - 2.0 * s2).max(0.0);
    let significant = 3.0 * c0 / (d.len() as f64).sqrt();
    let cov = c1 + s2;
    let rho = if var > 0.0 && cov > significant {
        (cov / var).min(1.0)
    } else {
        0.0
    };
    Some((var, rho))
}

/// The delay-free model's state space with the signal and noise states appended.
struct Augmented {
    /// Transition.
    phi: Mat<f64>,
    /// Measurement row.
    h: Vec<f64>,
    /// Process noise covariance (diagonal).
    q: Vec<f64>,
    /// White measurement noise variance.
    r: f64,
    /// Index of the pressure state.
    iu: usize,
    /// Delay in samples of the model, leading zero coefficients of `b` included.
    delay: usize,
}

fn augmented(model: &Model, noise: &NoiseModel, prior: &SignalPrior) -> Result<Augmented> {
    let (lead, b) = super::numerator_after_delay(model, "optimal compensator")?;
    // The model as a cascade of second-order sections (poles nearest the circle first, each
    // with its nearest zeros), each section in transposed direct form II: far better
    // conditioned than one companion form when poles crowd towards z = 1.
    let zpk = Zpk {
        zeros: poly::roots(b)?,
        poles: model.poles()?,
        gain: b.first().copied().unwrap_or(0.0),
    };
    let (cascade_gain, model_sections) = to_sections(&zpk);
    let nx = 2 * model_sections.len();
    let ar = noise.probe_ar_std > 0.0;
    let ramp = prior.increment_pole > 0.0;
    let n = nx + 1 + usize::from(ramp) + usize::from(ar);
    let iu = nx;
    let mut phi = Mat::<f64>::zeros(n, n);
    let mut h = vec![0.0; n];
    let mut q = vec![0.0; n];
    // The running signal as a row over the states plus a coefficient of u.
    let mut signal = vec![0.0; n];
    signal[iu] = cascade_gain;
    for (j, sec) in model_sections.iter().enumerate() {
        let [c0, c1, c2, a1, a2] = *sec;
        let (i1, i2) = (2 * j, 2 * j + 1);
        let mut out: Vec<f64> = signal.iter().map(|v| c0 * v).collect();
        out[i1] += 1.0;
        for k in 0..n {
            phi[(i1, k)] = c1 * signal[k] - a1 * out[k];
            phi[(i2, k)] = c2 * signal[k] - a2 * out[k];
        }
        phi[(i1, i2)] += 1.0;
        signal = out;
    }
    for (k, v) in signal.iter().enumerate() {
        h[k] = *v;
    }
    phi[(iu, iu)] = 1.0;
    if ramp {
        // u[k] = u[k-1] + v[k-1], v[k] = rho v[k-1] + w[k]: the same spectrum, with the
        // innovation on the increment alone (a diagonal process noise).
        let iv = iu + 1;
        phi[(iu, iv)] = 1.0;
        phi[(iv, iv)] = prior.increment_pole;
        q[iv] = prior.increment_std * prior.increment_std;
    } else {
        q[iu] = prior.increment_std * prior.increment_std;
    }
    if ar {
        let ic = iu + 1 + usize::from(ramp);
        let p = noise.probe_ar_pole;
        phi[(ic, ic)] = p;
        h[ic] = 1.0;
        q[ic] = noise.probe_ar_std * noise.probe_ar_std * (1.0 - p * p);
    }
    // A measurement without white noise makes the Riccati equation singular: keep a floor.
    let total = noise.probe_std().powi(2).max(1e-300);
    let r = (noise.probe_white_std * noise.probe_white_std).max(1e-6 * total);
    if !(prior.increment_std > 0.0 && r > 0.0 && q.iter().all(|v| v.is_finite())) {
        return Err(Error::Numerical {
            context: "optimal compensator".into(),
            message: format!(
                "the signal prior ({:.3e}) and the probe noise ({:.3e}) must be positive and finite",
                prior.increment_std,
                noise.probe_std()
            ),
        });
    }
    Ok(Augmented {
        phi,
        h,
        q,
        r,
        iu,
        delay: model.delay + lead,
    })
}

/// Steady-state a-priori covariance of the Kalman filter of `sys`: the doubling algorithm's
/// solution when its closed loop is stable, else (a solution that is not the stabilising one,
/// seen with nearly cancelling poles and zeros) the plain Riccati recursion from the prior.
fn riccati(sys: &Augmented) -> Result<Mat<f64>> {
    if let Ok(x) = riccati_doubling(sys) {
        if closed_loop_radius(sys, &x) < 1.0 {
            return Ok(x);
        }
    }
    riccati_recursion(sys)
}

/// The steady-state filter of `sys` for the a-priori covariance `p`: the innovation variance
/// `s = h P h' + r`, the predictor gain `Kp = Phi P h' / s` and the closed loop
/// `A_cl = Phi - Kp h`.
fn filter_of(sys: &Augmented, p: &Mat<f64>) -> (f64, Vec<f64>, Mat<f64>) {
    let n = sys.h.len();
    let ph: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| p[(i, j)] * sys.h[j]).sum())
        .collect();
    let s = sys.h.iter().zip(&ph).map(|(a, b)| a * b).sum::<f64>() + sys.r;
    let kp: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| sys.phi[(i, j)] * ph[j]).sum::<f64>() / s)
        .collect();
    let a_cl = Mat::<f64>::from_fn(n, n, |i, j| sys.phi[(i, j)] - kp[i] * sys.h[j]);
    (s, kp, a_cl)
}

/// Spectral radius of the filter's closed loop for the covariance `p`.
fn closed_loop_radius(sys: &Augmented, p: &Mat<f64>) -> f64 {
    filter_of(sys, p)
        .2
        .eigenvalues()
        .map_or(f64::INFINITY, |e| {
            e.iter().map(|v| v.norm()).fold(0.0, f64::max)
        })
}

/// The Riccati recursion `P <- Phi (P - P h' h P / s) Phi' + Q` from `P = Q + I * scale`,
/// which converges to the stabilising solution (slowly when the closed loop is slow).
fn riccati_recursion(sys: &Augmented) -> Result<Mat<f64>> {
    let n = sys.h.len();
    let scale = sys.q.iter().fold(sys.r, |m, v| m.max(*v)) * 1e3;
    let mut p = Mat::<f64>::from_fn(n, n, |i, j| if i == j { sys.q[i] + scale } else { 0.0 });
    for _ in 0..2_000_000 {
        let ph: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| p[(i, j)] * sys.h[j]).sum())
            .collect();
        let s = sys.h.iter().zip(&ph).map(|(a, b)| a * b).sum::<f64>() + sys.r;
        let filtered = Mat::<f64>::from_fn(n, n, |i, j| p[(i, j)] - ph[i] * ph[j] / s);
        let mut next = &sys.phi * &filtered * sys.phi.transpose();
        for i in 0..n {
            next[(i, i)] += sys.q[i];
        }
        let change = (&next - &p).norm_max();
        let size = next.norm_max();
        if !size.is_finite() {
            break;
        }
        p = next;
        if change <= 1e-10 * size {
            return Ok(p);
        }
    }
    Err(not_converged())
}

/// The error of a Riccati solution that did not converge.
fn not_converged() -> Error {
    Error::Numerical {
        context: "optimal compensator".into(),
        message: "the Kalman filter's Riccati equation did not converge (is the model stable and \
                  its DC gain non-zero?)"
            .into(),
    }
}

/// The structure-preserving doubling algorithm on the dual control Riccati equation
/// `X = A' X (I + G X)^-1 A + Q`, `A = Phi'`, `G = h' h / r`.
fn riccati_doubling(sys: &Augmented) -> Result<Mat<f64>> {
    let n = sys.h.len();
    let mut a = sys.phi.transpose().to_owned();
    let mut g = Mat::<f64>::from_fn(n, n, |i, j| sys.h[i] * sys.h[j] / sys.r);
    let mut x = Mat::<f64>::from_fn(n, n, |i, j| if i == j { sys.q[i] } else { 0.0 });
    let eye = Mat::<f64>::identity(n, n);
    for _ in 0..200 {
        let w = &eye + &g * &x;
        let lu = w.partial_piv_lu();
        let wa = lu.solve(&a);
        let wg = lu.solve(&g);
        let a_next = &a * &wa;
        let g_next = &g + &a * &wg * a.transpose();
        let x_next = &x + a.transpose() * &x * &wa;
        let change = (&x_next - &x).norm_max();
        let size = x_next.norm_max();
        if !size.is_finite() {
            break;
        }
        a = a_next;
        g = g_next;
        // Keep the iterate symmetric against round-off.
        x = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (x_next[(i, j)] + x_next[(j, i)]));
        if change <= 1e-14 * size {
            return Ok(x);
        }
    }
    Err(not_converged())
}

/// The steady-state fixed-lag smoother of a model under a noise model and a signal prior.
pub struct Smoother {
    /// Closed-loop (predictor) transition `Phi - Kp h`.
    a_cl: Mat<f64>,
    /// Predictor gain `Phi P h' / s`.
    kp: Vec<f64>,
    /// Measurement row.
    h: Vec<f64>,
    /// `e_u' P (A_cl')^i h' / s` for `i = 0, 1, ...` (grown on demand).
    gains: Vec<f64>,
    /// `(A_cl')^i h'`, the next column of the recursion.
    next: Vec<f64>,
    /// The pressure's row of `P`.
    p_u: Vec<f64>,
    /// Innovation variance.
    s: f64,
    /// Prediction error variance of the pressure.
    p_uu: f64,
    iu: usize,
    delay: usize,
}

impl Smoother {
    /// Solves the filter for `model`, `noise` and `prior`.
    ///
    /// # Errors
    /// [`Error::Numerical`] when the model has no numerator, the levels are not positive, or
    /// the Riccati equation does not converge.
    pub fn new(model: &Model, noise: &NoiseModel, prior: &SignalPrior) -> Result<Self> {
        let sys = augmented(model, noise, prior)?;
        let p = riccati(&sys)?;
        let n = sys.h.len();
        let (s, kp, a_cl) = filter_of(&sys, &p);
        Ok(Self {
            a_cl,
            kp,
            h: sys.h.clone(),
            gains: Vec::new(),
            next: sys.h.clone(),
            p_u: (0..n).map(|j| p[(sys.iu, j)]).collect(),
            s,
            p_uu: p[(sys.iu, sys.iu)],
            iu: sys.iu,
            delay: sys.delay,
        })
    }

    /// The model's delay (leading zeros of `b` included): the smoother's latency is this plus
    /// its lag.
    #[must_use]
    pub fn delay(&self) -> usize {
        self.delay
    }

    fn grow(&mut self, count: usize) {
        let n = self.h.len();
        while self.gains.len() < count {
            let g = self
                .p_u
                .iter()
                .zip(&self.next)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / self.s;
            self.gains.push(g);
            // next <- A_cl' next.
            let v: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| self.a_cl[(j, i)] * self.next[j]).sum())
                .collect();
            self.next = v;
        }
    }

    /// Standard deviation of the error of `u_hat[k - lag | k]` for `lag = 0..=max_lag`.
    pub fn error_std(&mut self, max_lag: usize) -> Vec<f64> {
        self.grow(max_lag + 1);
        let mut var = self.p_uu;
        self.gains
            .iter()
            .take(max_lag + 1)
            .map(|g| {
                var -= g * g * self.s;
                var.max(0.0).sqrt()
            })
            .collect()
    }

    /// Impulse response of the smoother at `lag`, from the probe sample to `u_hat[k - lag]`,
    /// `count` samples long.
    fn impulse(&mut self, lag: usize, count: usize) -> Vec<f64> {
        self.grow(lag + 1);
        let n = self.h.len();
        let mut x = vec![0.0; n];
        // Innovations and predicted pressure of the last lag + 1 samples (newest last).
        let mut innovations = vec![0.0; lag + 1];
        let mut predicted = vec![0.0; lag + 1];
        let mut out = Vec::with_capacity(count);
        for k in 0..count {
            let y = if k == 0 { 1.0 } else { 0.0 };
            let e = y - self.h.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
            innovations.rotate_left(1);
            predicted.rotate_left(1);
            if let Some(v) = innovations.last_mut() {
                *v = e;
            }
            if let Some(v) = predicted.last_mut() {
                *v = x.get(self.iu).copied().unwrap_or(0.0);
            }
            // u_hat[k-lag|k] = u_hat[k-lag|k-lag-1] + sum_i G_i e[k-lag+i].
            let smoothed: f64 = self
                .gains
                .iter()
                .zip(&innovations)
                .map(|(g, e)| g * e)
                .sum();
            out.push(predicted.first().copied().unwrap_or(0.0) + smoothed);
            let next: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| self.a_cl[(i, j)] * x[j]).sum::<f64>() + self.kp[i] * y)
                .collect();
            x = next;
        }
        out
    }

    /// The smoother at `lag` as a cascade `(gain, sections)` with the crate's sign convention.
    ///
    /// # Errors
    /// [`Error::Numerical`] when the eigenvalues or the numerator's roots cannot be found, or
    /// the sections do not reproduce the smoother's response to `1e-6`.
    pub fn realise(&mut self, lag: usize) -> Result<(f64, Vec<[f64; 5]>)> {
        let n = self.h.len();
        let poles = self.a_cl.eigenvalues().map_err(|e| Error::Numerical {
            context: "optimal compensator".into(),
            message: format!("eigenvalues of the Kalman filter did not converge: {e:?}"),
        })?;
        // Denominator prod (1 - p z^-1), real.
        let mut den = vec![Complex::new(1.0, 0.0)];
        for p in &poles {
            let mut next = den.clone();
            next.push(Complex::new(0.0, 0.0));
            for (i, d) in den.iter().enumerate() {
                if let Some(v) = next.get_mut(i + 1) {
                    *v -= *p * *d;
                }
            }
            den = next;
        }
        let den: Vec<f64> = den.iter().map(|c| c.re).collect();
        let degree = n + lag;
        let h = self.impulse(lag, degree + 1);
        let num: Vec<f64> = (0..=degree)
            .map(|k| {
                (0..=k)
                    .map(|i| {
                        h.get(i).copied().unwrap_or(0.0) * den.get(k - i).copied().unwrap_or(0.0)
                    })
                    .sum()
            })
            .collect();
        let big = num.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // Leading taps that vanish are a pure delay: at most one is expected (lag 0 with b0 = 0).
        let lead = num.iter().position(|v| v.abs() > 1e-13 * big).unwrap_or(0);
        let num_tail = num.get(lead..).unwrap_or(&[]);
        let zeros = poly::roots(num_tail)?;
        let zpk = Zpk {
            zeros,
            poles: poles.clone(),
            gain: num_tail.first().copied().unwrap_or(0.0),
        };
        let (gain, mut sections) = to_sections(&zpk);
        for _ in 0..lead {
            sections.push([0.0, 1.0, 0.0, 0.0, 0.0]);
        }
        // The sections must be the smoother: compare with the rational function N/D on a grid.
        for i in 1..64 {
            let w = PI * f64::from(i) / 64.0;
            let z = Complex::new(w.cos(), w.sin());
            let want = poly::eval(&num, z) / poly::eval(&den, z);
            let got = cascade_response(gain, &sections, z);
            if (want - got).norm() > 1e-6 * want.norm().max(1e-3 * big) {
                return Err(Error::Numerical {
                    context: "optimal compensator".into(),
                    message: format!(
                        "the sections do not reproduce the smoother at lag {lag} (|error| {:.2e} at {:.3} rad/sample): ask for a shorter latency",
                        (want - got).norm(),
                        w
                    ),
                });
            }
        }
        Ok((gain, sections))
    }
}

/// The non-causal optimum on a recorded run (host only, `unlag compensate --offline`):
/// `F = conj(G) S_u / (|G|^2 S_u + S_ny)` applied by FFT, the model's delay included in `G`, so
/// `u_hat` has no latency at all and the least error any linear filter can reach: the oracle a
/// causal compensator is measured against. The record is extended at both ends by its edge
/// values (a quarter of its length, at least 4096 samples) before the circular transform, so
/// that neither end wraps into the other.
///
/// # Errors
/// [`Error::Numerical`] when the record is too long for a power-of-two transform.
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
        .ok_or_else(|| Error::Numerical {
            context: "offline reconstruction".into(),
            message: format!("a record of {n} samples is too long"),
        })?;
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
    let (mut band, mut noise_var) = (0.0, 0.0);
    for (w, dw) in grid(6000) {
        let z = Complex::new(w.cos(), w.sin());
        let c = cascade_response(gain, sections, z);
        let g = model_response(model, z);
        let target = Complex::new((w * latency).cos(), -(w * latency).sin());
        band += (c * g - target).norm_sqr() * prior.psd(w) * dw;
        noise_var += c.norm_sqr() * noise.probe_psd(w) * dw;
    }
    // (1/2pi) over (-pi, pi] = (1/pi) over (0, pi].
    let band = (band / PI).sqrt();
    let noise_part = (noise_var / PI).sqrt();
    Budget {
        noise: noise_part,
        band_limit: band,
        total: band.hypot(noise_part),
        reference: noise.reference_std,
    }
}

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
    let score = |fc: f64| -> Option<(f64, super::Design, Budget)> {
        let d = super::design(model, fc, &inverse_options).ok()?;
        if d.latency_samples > max_latency || d.pole_margin < crate::compensator::MIN_POLE_MARGIN {
            return None;
        }
        let b = budget(model, d.gain, &d.sections, d.latency_samples, noise, prior);
        Some((b.total, d, b))
    };
    let (lo, hi) = (fs / 2000.0, 0.45 * fs);
    let n = 36;
    let grid: Vec<f64> = (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect();
    let mut best: Option<(f64, super::Design, Budget, usize)> = None;
    for (i, &fc) in grid.iter().enumerate() {
        if let Some((e, d, b)) = score(fc) {
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
        let s1 = score(x1.exp());
        let s2 = score(x2.exp());
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
    Some((d, b))
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
/// [`Error::Numerical`] as [`Smoother::new`] and [`Smoother::realise`].
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
    if pole_margin.is_nan() || pole_margin < crate::compensator::MIN_POLE_MARGIN {
        return Err(Error::Numerical {
            context: "optimal compensator".into(),
            message: format!(
                "the smoother's poles are {pole_margin:.2e} from the unit circle, less than the board's margin {:.0e}",
                crate::compensator::MIN_POLE_MARGIN
            ),
        });
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
    fn a_smooth_run_gives_back_its_increments_correlation() {
        // Increments AR(1) with pole 0.9 and innovation 0.01, through a noisy reference.
        let mut seed = 5u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut level, mut v) = (0.0, 0.0);
        let u: Vec<f64> = (0..200_000)
            .map(|_| {
                v = 0.9 * v + 0.01 * 12f64.sqrt() * uniform();
                level += v;
                level + 0.003 * 12f64.sqrt() * uniform()
            })
            .collect();
        let noise = NoiseModel {
            probe_white_std: 0.003,
            probe_ar_pole: 0.0,
            probe_ar_std: 0.0,
            reference_std: 0.003,
            source: NoiseSource::Given,
        };
        let p = prior_from_runs(&[(Some(&u), &u)], 1.0, &noise, 1);
        assert!((p.increment_pole - 0.9).abs() < 0.01, "{p:?}");
        assert!((p.increment_std / 0.01 - 1.0).abs() < 0.05, "{p:?}");
        // A step test's reference (one jump) stays a plain random walk.
        let step: Vec<f64> = (0..4000)
            .map(|k| if k < 1000 { 0.0 } else { 1.0 } + 0.003 * 12f64.sqrt() * uniform())
            .collect();
        let p = prior_from_runs(&[(Some(&step), &step)], 1.0, &noise, 1);
        assert!(p.increment_pole < 0.05, "{p:?}");
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

    #[test]
    fn a_recorded_run_gives_back_its_random_walk_level() {
        // A random walk of increment 0.01 (uniform increments of that standard deviation),
        // seen through a noisy probe of DC gain 2 and a noisy reference.
        let mut seed = 99u64;
        let mut uniform = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let step = 0.01 * 12f64.sqrt();
        let mut level = 0.0;
        let u: Vec<f64> = (0..100_000)
            .map(|_| {
                level += step * uniform();
                level
            })
            .collect();
        let noisy = |x: &[f64], g: f64, s: f64, r: &mut dyn FnMut() -> f64| -> Vec<f64> {
            x.iter().map(|v| g * v + s * 12f64.sqrt() * r()).collect()
        };
        let u_meas = noisy(&u, 1.0, 0.02, &mut uniform);
        let y_meas = noisy(&u, 2.0, 0.02, &mut uniform);
        let noise = NoiseModel {
            probe_white_std: 0.02,
            probe_ar_pole: 0.0,
            probe_ar_std: 0.0,
            reference_std: 0.02,
            source: NoiseSource::Given,
        };
        let from_u = prior_from_runs(&[(Some(&u_meas), &y_meas)], 2.0, &noise, 30);
        let from_y = prior_from_runs(&[(None, &y_meas)], 2.0, &noise, 30);
        for p in [from_u, from_y] {
            assert!((p.increment_std / 0.01 - 1.0).abs() < 0.1, "{p:?}");
            assert_eq!(p.source, PriorSource::Runs);
        }
    }

    #[test]
    fn quiet_noise_finds_an_ar1_part_and_a_white_one() {
        // AR(1) pole 0.9, std 3, plus white std 1, from a fixed LCG.
        let mut seed = 12345u64;
        let mut gauss = || {
            let mut s = 0.0;
            for _ in 0..12 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (seed >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        let mut c = 0.0;
        let innov = 3.0 * (1.0f64 - 0.81).sqrt();
        let y: Vec<f64> = (0..200_000)
            .map(|_| {
                c = 0.9 * c + innov * gauss();
                c + gauss()
            })
            .collect();
        let (w, (phi, s2)) = quiet_noise(&y);
        assert!((phi - 0.9).abs() < 0.02, "{phi}");
        assert!((s2.sqrt() - 3.0).abs() < 0.15, "{}", s2.sqrt());
        assert!((w.sqrt() - 1.0).abs() < 0.15, "{}", w.sqrt());
        // White noise alone: no AR part.
        let white: Vec<f64> = (0..20_000).map(|_| gauss()).collect();
        let (w, (phi, _)) = quiet_noise(&white);
        assert_eq!(phi, 0.0);
        assert!((w.sqrt() - 1.0).abs() < 0.05);
    }
}
