//! The continuous-time equivalent of a model, and its re-discretisation at another sample rate
//! (the paper's §2.2: the transfer function in `s` is the invariant, the `z` coefficients are
//! not).
//!
//! This module owns [`Continuous`] (`G(s) e^{-s tau}` with a fractional delay `tau`) and
//! [`Continuous::discretise`]. Both directions are **step invariant** (zero-order hold): the
//! continuous step response sampled at the model's rate is the model's step response, exactly,
//! and the re-discretised model's step response is the continuous step response sampled at the
//! new rate.
//!
//! # The mathematics
//!
//! For a model `H(z) = z^-d B(z^-1) / A(z^-1)` with distinct poles `p_i` (none at 0, none on the
//! negative real axis, all inside the unit circle), the unit step response is, for `k >= d`,
//!
//! `S_k = S_inf + sum_i c_i p_i^(k-d)`,  `c_i = B(p_i) / ((1 - 1/p_i) prod_{j != i} (1 - p_j/p_i))`
//!
//! (a partial-fraction expansion of `B / (A (1 - z^-1))`, checked against the model's own
//! recursion). With `s_i = fs ln p_i` the same formula extends to continuous time:
//! `F(t) = S_inf + sum_i c_i e^{s_i (t - d/fs)}`. The continuous step response is `S(t) = F(t)`
//! for `t >= tau` and 0 before, where `tau` in `((d-1)/fs, d/fs]` is where `F` crosses zero (the
//! fractional delay: `S` then starts without a jump). If `F` has no zero there, `tau` is where
//! `|F|` is smallest and the remaining jump `D = F(tau)` is a feedthrough. So
//!
//! `G(s) = D + sum_i r_i / (s - s_i)`,  `r_i = s_i c_i e^{s_i (tau - d/fs)}`,
//! `H(s) = G(s) e^{-s tau}`.
//!
//! At a new rate `fs2` the delay is `d2 = ceil(tau fs2)` whole samples, the poles are
//! `q_i = e^{s_i / fs2}` and `S2_k = S(k / fs2) = S_inf + sum_i C_i q_i^(k-d2)` for `k >= d2`,
//! with `C_i = (r_i / s_i) e^{s_i (d2/fs2 - tau)}`; hence
//! `H2(z) = z^-d2 [S_inf + sum_i C_i (1 - z^-1) / (1 - q_i z^-1)]`, put over the common
//! denominator `prod (1 - q_i z^-1)`: `m` real `a` and `m + 1` real `b` coefficients. The
//! fraction of a sample between `tau` and `d2 / fs2` is carried by the coefficients, not rounded
//! away.
//!
//! Repeated (or nearly repeated) poles have no such modal expansion and are refused.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fit::analysis::{self, Root, ORIGIN_RADIUS, REAL_AXIS_TOLERANCE};
use crate::fit::model::{filter, Model};
use crate::fit::{ContinuousError, FitError};
use crate::poly::{self, Complex};

/// Two poles closer than this (relative to the larger magnitude) are refused as repeated.
pub const REPEATED_POLE_TOLERANCE: f64 = 1e-6;

/// The modal expansion must reproduce the model's own step response to this (relative to the
/// largest value of the step response).
pub const EXPANSION_TOLERANCE: f64 = 1e-8;

/// Largest number of samples [`step_agreement`] simulates.
pub const MAX_AGREEMENT_SAMPLES: usize = 1_000_000;

/// How the fractional delay was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DelayFound {
    /// `F` crosses zero at `tau`: the step response starts there without a jump.
    ZeroCrossing,
    /// `F` has no zero in the interval; `tau` is where `|F|` is smallest and the rest is the
    /// feedthrough jump.
    MinimumOfResponse,
    /// The model has no delay (`d = 0`): `tau = 0`, and `D = b0`.
    NoDelay,
}

/// The continuous-time equivalent `H(s) = (D + sum_i r_i / (s - s_i)) e^{-s tau}` of a model
/// (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Continuous {
    /// The delay `tau` in seconds (fractional: not a multiple of the sample period).
    pub delay_s: f64,
    /// How `tau` was found.
    pub delay_found: DelayFound,
    /// The jump `D` of the step response at `tau` (the feedthrough of `G`).
    pub feedthrough: f64,
    /// Final value of the unit step response (the DC gain).
    pub dc_gain: f64,
    /// Continuous-time poles `s_i` in 1/s (real part) and rad/s (imaginary part).
    pub poles: Vec<Root>,
    /// Residues `r_i` of `G(s)` at each pole.
    pub residues: Vec<Root>,
    /// Sample rate of the model this came from, in Hz.
    pub source_sample_rate_hz: f64,
    /// Delay of the model this came from, in whole samples (after moving leading zeros of `b`
    /// into the delay).
    pub source_delay_samples: usize,
}

/// A re-discretised model and what happened to the delay.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Discretised {
    /// The model at the new rate.
    pub model: Model,
    /// The continuous delay `tau` in seconds.
    pub delay_s: f64,
    /// `tau` in samples of the new rate (generally not an integer).
    pub delay_in_samples: f64,
    /// The whole-sample delay `d2 = ceil(tau fs2)`; the coefficients carry `d2 - tau fs2`.
    pub delay_samples: usize,
    /// One sentence saying how the delay was split between `d2` and the coefficients.
    pub delay_note: String,
    /// Anything the user should know (e.g. a resonance above the new Nyquist frequency).
    pub warnings: Vec<String>,
}

/// How well two models' step responses agree.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Agreement {
    /// Number of instants compared.
    pub instants: usize,
    /// Largest absolute difference, as a fraction of the step's final value.
    pub max_error: f64,
    /// RMS difference, as a fraction of the step's final value.
    pub rms_error: f64,
}

fn c(re: f64, im: f64) -> Complex {
    Complex::new(re, im)
}

fn to_complex(r: &Root) -> Complex {
    c(r.re, r.im)
}

fn continuous(reason: ContinuousError) -> Error {
    FitError::Continuous(reason).into()
}

/// The coefficient `c_i` of `p_i^n` in the step response of `b(z^-1) / a(z^-1)` (the delay
/// aside), for `a`'s distinct roots `poles`: `b(p_i) / ((1 - 1 / p_i) prod_(j != i) (1 - p_j /
/// p_i))`, the residues of `H(z) / (1 - z^-1)`.
#[must_use]
pub fn step_coefficients(b: &[f64], poles: &[Complex]) -> Vec<Complex> {
    let one = c(1.0, 0.0);
    poles
        .iter()
        .enumerate()
        .map(|(i, &pi)| {
            let others = poles
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .fold(one, |acc, (_, &pj)| acc * (one - pj / pi));
            poly::eval(b, pi) / ((one - one / pi) * others)
        })
        .collect()
}

impl Continuous {
    /// The continuous-time equivalent of `model` (step invariant).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an invalid model; [`FitError::Continuous`] naming the
    /// pole when a pole is at `z = 0`, on the negative real axis, on or outside the unit
    /// circle, or repeated; [`crate::poly::PolyError`] when the eigenvalue solver fails.
    pub fn from_model(model: &Model) -> Result<Self> {
        analysis::validate(model)?;
        let fs = model.fs;
        let shift = model
            .b
            .iter()
            .position(|&v| v != 0.0)
            .ok_or(FitError::Continuous(ContinuousError::ZeroNumerator))?;
        let b = model.b.get(shift..).unwrap_or(&[]);
        let d = model.delay + shift;
        let a_len = model.a.iter().rposition(|&v| v != 0.0).map_or(0, |i| i + 1);
        let a = model.a.get(..a_len).unwrap_or(&[]);
        if b.len() > a.len() + 1 {
            return Err(continuous(ContinuousError::FiniteImpulsePart {
                numerator: b.len(),
                denominator: a.len(),
            }));
        }
        let denominator: Vec<f64> = std::iter::once(1.0).chain(a.iter().copied()).collect();
        let p = poly::roots(&denominator)?;
        check_poles(&p)?;
        let s_inf: f64 = poly::eval(b, c(1.0, 0.0)).re / poly::eval(&denominator, c(1.0, 0.0)).re;
        let coefficients = step_coefficients(b, &p);
        // F(x) with x in samples: S_inf + Re sum c_i p_i^(x - d).
        let s: Vec<Complex> = p.iter().map(|&pi| pi.ln() * fs).collect();
        let f = |x: f64| -> f64 {
            s_inf
                + s.iter()
                    .zip(&coefficients)
                    .map(|(&si, &ci)| (ci * (si * ((x - d as f64) / fs)).exp()).re)
                    .sum::<f64>()
        };
        check_expansion(b, a, d, &f)?;
        let (x, delay_found) = if d == 0 {
            (0.0, DelayFound::NoDelay)
        } else {
            find_delay(&f, d as f64)
        };
        let tau = x / fs;
        let feedthrough = f(x);
        let residues = s
            .iter()
            .zip(&coefficients)
            .map(|(&si, &ci)| Root::from(si * ci * (si * (tau - d as f64 / fs)).exp()))
            .collect();
        Ok(Self {
            delay_s: tau,
            delay_found,
            feedthrough,
            dc_gain: s_inf,
            poles: s.into_iter().map(Root::from).collect(),
            residues,
            source_sample_rate_hz: fs,
            source_delay_samples: d,
        })
    }

    fn modes(&self) -> impl Iterator<Item = (Complex, Complex)> + '_ {
        self.poles
            .iter()
            .zip(&self.residues)
            .map(|(s, r)| (to_complex(s), to_complex(r)))
    }

    /// The unit step response `S(t)`: 0 before the delay, then
    /// `D + sum_i (r_i / s_i)(e^{s_i (t - tau)} - 1)`.
    #[must_use]
    pub fn step(&self, t: f64) -> f64 {
        // Sample instants computed in floating point may land a rounding error before tau.
        let slack = 1e-9 / self.source_sample_rate_hz;
        if t < self.delay_s - slack {
            return 0.0;
        }
        self.after_delay(t - self.delay_s)
    }

    /// `F(tau + t')`: the step response's formula, also for `t'` a rounding error below 0.
    fn after_delay(&self, t: f64) -> f64 {
        self.feedthrough
            + self
                .modes()
                .map(|(s, r)| (r / s * ((s * t).exp() - c(1.0, 0.0))).re)
                .sum::<f64>()
    }

    /// `H(j 2 pi f) = (D + sum_i r_i / (j 2 pi f - s_i)) e^{-j 2 pi f tau}`.
    #[must_use]
    pub fn response(&self, f_hz: f64) -> Complex {
        let jw = c(0.0, 2.0 * std::f64::consts::PI * f_hz);
        let g = self
            .modes()
            .fold(c(self.feedthrough, 0.0), |acc, (s, r)| acc + r / (jw - s));
        g * (-jw * self.delay_s).exp()
    }

    /// Magnitude and phase (radians) at each frequency: the delay's `-2 pi f tau` exactly, the
    /// rest unwrapped along the grid (give the grid in increasing order).
    #[must_use]
    pub fn frequency_response(&self, freqs_hz: &[f64]) -> Vec<(f64, f64)> {
        let tau2 = 2.0 * std::f64::consts::PI;
        let mut previous: Option<f64> = None;
        freqs_hz
            .iter()
            .map(|&f| {
                let w = tau2 * f;
                let g = self.response(f) * c(0.0, w * self.delay_s).exp();
                let principal = g.arg();
                let phase = previous.map_or(principal, |p| {
                    principal + tau2 * ((p - principal) / tau2).round()
                });
                previous = Some(phase);
                (g.norm(), phase - w * self.delay_s)
            })
            .collect()
    }

    /// The step-invariant discrete model at `sample_rate_hz` (see the module documentation).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a non-positive or non-finite rate;
    /// [`FitError::Continuous`] if the combined coefficients come out complex (which only round-off on ill-conditioned
    /// poles can cause).
    pub fn discretise(&self, sample_rate_hz: f64) -> Result<Discretised> {
        let fs2 = sample_rate_hz;
        if !(fs2.is_finite() && fs2 > 0.0) {
            return Err(Error::InvalidArgument {
                what: "sample rate",
                message: format!("must be a positive number of Hz, not {fs2}"),
            });
        }
        let x = self.delay_s * fs2;
        // A delay that lands on a sample instant (up to round-off) is that many samples.
        let d2 = (x - 1e-9).ceil().max(0.0) as usize;
        let t0 = d2 as f64 / fs2 - self.delay_s;
        let mut den = vec![c(1.0, 0.0)];
        let mut terms: Vec<(Complex, Complex)> = Vec::new();
        let mut s_inf = self.feedthrough;
        for (s, r) in self.modes() {
            let q = (s / fs2).exp();
            s_inf -= (r / s).re;
            terms.push((q, r / s * (s * t0).exp()));
            den = multiply(&den, &[c(1.0, 0.0), -q]);
        }
        // num = S_inf den + sum_i C_i (1 - z^-1) prod_{j != i} (1 - q_j z^-1)
        let mut num: Vec<Complex> = den.iter().map(|&v| v * s_inf).collect();
        for (i, &(_, ci)) in terms.iter().enumerate() {
            let mut part = vec![ci, -ci];
            for (j, &(qj, _)) in terms.iter().enumerate() {
                if j != i {
                    part = multiply(&part, &[c(1.0, 0.0), -qj]);
                }
            }
            for (n, p) in num.iter_mut().zip(&part) {
                *n += *p;
            }
        }
        let scale = num
            .iter()
            .chain(&den)
            .map(|v| v.norm())
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let worst_im = num
            .iter()
            .chain(&den)
            .map(|v| v.im.abs())
            .fold(0.0, f64::max);
        if worst_im > 1e-9 * scale {
            return Err(continuous(ContinuousError::ComplexCoefficients {
                imaginary: worst_im,
                scale,
                rate_hz: fs2,
            }));
        }
        let model = Model {
            fs: fs2,
            delay: d2,
            a: den.iter().skip(1).map(|v| v.re).collect(),
            b: num.iter().map(|v| v.re).collect(),
        };
        let carried = d2 as f64 - x;
        let delay_note = format!(
            "delay {:.9} s = {x:.6} samples at {fs2} Hz: {d2} whole samples of delay, the \
             coefficients carry the remaining {:.6} of a sample (step response starts {:.6} samples \
             before sample {d2}); nothing is rounded away",
            self.delay_s,
            (x - (d2 as f64 - 1.0)).clamp(0.0, 1.0),
            carried.max(0.0)
        );
        let nyquist = std::f64::consts::PI * fs2;
        let warnings = self
            .poles
            .iter()
            .filter(|s| s.im > nyquist)
            .map(|s| {
                format!(
                    "the pole s = {:.3}{:+.3}j (ringing at {:.3} Hz) is above the Nyquist frequency {:.3} Hz of the new rate: it aliases",
                    s.re,
                    s.im,
                    s.im / (2.0 * std::f64::consts::PI),
                    fs2 / 2.0
                )
            })
            .collect();
        Ok(Discretised {
            model,
            delay_s: self.delay_s,
            delay_in_samples: x,
            delay_samples: d2,
            delay_note,
            warnings,
        })
    }
}

/// Convenience: the continuous-time equivalent of `model` and its re-discretisation at
/// `sample_rate_hz`.
///
/// # Errors
/// As [`Continuous::from_model`] and [`Continuous::discretise`].
pub fn resample(model: &Model, sample_rate_hz: f64) -> Result<(Continuous, Discretised)> {
    let ct = Continuous::from_model(model)?;
    let d = ct.discretise(sample_rate_hz)?;
    Ok((ct, d))
}

/// The model's unit step response (`u_k = 1` for `k >= 0`, at rest before), `n` samples.
#[must_use]
pub fn step_response(model: &Model, n: usize) -> Vec<f64> {
    filter(&model.b, &model.a, model.delay, &vec![1.0; n])
}

/// Compares the step responses of `old` and `new` at the instants both sample (`k / fs_old =
/// j / fs_new`), over the time `old` takes to settle (from its slowest pole), as a fraction of
/// `old`'s final value.
#[must_use]
pub fn step_agreement(old: &Model, new: &Model) -> Agreement {
    let slowest = old
        .poles()
        .ok()
        .and_then(|p| p.first().map(|p| p.norm()))
        .unwrap_or(0.0);
    let settle = if slowest < 1.0 {
        // 30 time constants of the slowest pole: e^-30 of its amplitude is left.
        30.0 / (1.0 - slowest).max(1e-12)
    } else {
        1000.0
    };
    let n_old =
        ((old.delay + old.order() + 16) as f64 + settle).min(MAX_AGREEMENT_SAMPLES as f64) as usize;
    let ratio = new.fs / old.fs;
    let n_new = ((n_old as f64 * ratio).ceil() as usize)
        .saturating_add(1)
        .min(MAX_AGREEMENT_SAMPLES);
    let s_old = step_response(old, n_old);
    let s_new = step_response(new, n_new);
    let scale = {
        let g = old.dc_gain().abs();
        if g > 0.0 {
            g
        } else {
            s_old
                .iter()
                .fold(0.0, |m: f64, v| m.max(v.abs()))
                .max(f64::MIN_POSITIVE)
        }
    };
    let (mut count, mut worst, mut sum2) = (0usize, 0.0f64, 0.0f64);
    for (k, so) in s_old.iter().enumerate() {
        let j = k as f64 * ratio;
        let jr = j.round();
        if (j - jr).abs() > 1e-6 {
            continue;
        }
        let Some(sn) = s_new.get(jr as usize) else {
            break;
        };
        let e = (so - sn).abs() / scale;
        count += 1;
        worst = worst.max(e);
        sum2 += e * e;
    }
    Agreement {
        instants: count,
        max_error: worst,
        rms_error: if count > 0 {
            (sum2 / count as f64).sqrt()
        } else {
            0.0
        },
    }
}

fn multiply(p: &[Complex], q: &[Complex]) -> Vec<Complex> {
    let mut out = vec![c(0.0, 0.0); p.len() + q.len() - 1];
    for (i, &pi) in p.iter().enumerate() {
        for (j, &qj) in q.iter().enumerate() {
            if let Some(o) = out.get_mut(i + j) {
                *o += pi * qj;
            }
        }
    }
    out
}

fn check_poles(p: &[Complex]) -> Result<()> {
    for &pi in p {
        let r = pi.norm();
        if r < ORIGIN_RADIUS {
            return Err(continuous(ContinuousError::PoleAtOrigin { pole: pi }));
        }
        if r >= 1.0 {
            return Err(continuous(ContinuousError::UnstablePole {
                pole: pi,
                radius: r,
            }));
        }
        if pi.im.abs() <= REAL_AXIS_TOLERANCE * r && pi.re < 0.0 {
            return Err(continuous(ContinuousError::NegativeRealPole { pole: pi }));
        }
    }
    for (i, &pi) in p.iter().enumerate() {
        for &pj in p.iter().skip(i + 1) {
            if (pi - pj).norm() < REPEATED_POLE_TOLERANCE * pi.norm().max(pj.norm()) {
                return Err(continuous(ContinuousError::RepeatedPoles {
                    first: pi,
                    second: pj,
                }));
            }
        }
    }
    Ok(())
}

/// The modal expansion must reproduce the model's step response (it does unless poles are
/// nearly repeated and the coefficients cancel).
fn check_expansion(b: &[f64], a: &[f64], d: usize, f: &dyn Fn(f64) -> f64) -> Result<()> {
    let n = d + 4 * a.len().max(1) + 16;
    let s = filter(b, a, d, &vec![1.0; n]);
    let scale = s
        .iter()
        .fold(0.0, |m: f64, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let worst = s
        .iter()
        .enumerate()
        .skip(d)
        .map(|(k, v)| (f(k as f64) - v).abs())
        .fold(0.0, f64::max);
    if worst > EXPANSION_TOLERANCE * scale {
        return Err(continuous(ContinuousError::ExpansionMismatch {
            relative: worst / scale,
        }));
    }
    Ok(())
}

/// `tau` (in samples) in `(d-1, d]`: the latest zero crossing of `F`, else the minimum of `|F|`.
fn find_delay(f: &dyn Fn(f64) -> f64, d: f64) -> (f64, DelayFound) {
    const GRID: usize = 64;
    let lo = d - 1.0;
    let xs: Vec<f64> = (0..=GRID).map(|j| lo + j as f64 / GRID as f64).collect();
    let fx: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
    // Latest sign change.
    for j in (0..GRID).rev() {
        let (x0, x1) = (xs[j], xs[j + 1]);
        let (f0, f1) = (fx[j], fx[j + 1]);
        if f1 == 0.0 && j + 1 < GRID {
            return (x1, DelayFound::ZeroCrossing);
        }
        if f0 * f1 < 0.0 {
            let (mut a, mut b, mut fa) = (x0, x1, f0);
            for _ in 0..200 {
                let m = 0.5 * (a + b);
                if m <= a || m >= b {
                    break;
                }
                let fm = f(m);
                if fm == 0.0 {
                    a = m;
                    b = m;
                    break;
                }
                if (fa < 0.0) == (fm < 0.0) {
                    a = m;
                    fa = fm;
                } else {
                    b = m;
                }
            }
            let x = 0.5 * (a + b);
            return (clamp_open(x, lo, d), DelayFound::ZeroCrossing);
        }
    }
    // No crossing: the minimum of |F|, preferring the later point on ties.
    let mut best = GRID;
    for j in (0..GRID).rev() {
        if fx[j].abs() < fx[best].abs() {
            best = j;
        }
    }
    let (mut a, mut b) = (
        xs[best.saturating_sub(1)],
        xs.get(best + 1).copied().unwrap_or(d),
    );
    let g = |x: f64| f(x).abs();
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - phi * (b - a), a + phi * (b - a));
    let (mut g1, mut g2) = (g(x1), g(x2));
    for _ in 0..200 {
        if b - a < 1e-14 {
            break;
        }
        if g1 < g2 {
            b = x2;
            x2 = x1;
            g2 = g1;
            x1 = b - phi * (b - a);
            g1 = g(x1);
        } else {
            a = x1;
            x1 = x2;
            g1 = g2;
            x2 = a + phi * (b - a);
            g2 = g(x2);
        }
    }
    let mut x = 0.5 * (a + b);
    // Keep the grid's answer if the search made it worse (flat |F|, e.g. a pure gain).
    if g(xs[best]) <= g(x) {
        x = xs[best];
    }
    (clamp_open(x, lo, d), DelayFound::MinimumOfResponse)
}

/// Clamps into `(lo, hi]`: sample `d - 1` must stay before the delay.
fn clamp_open(x: f64, lo: f64, hi: f64) -> f64 {
    x.clamp(lo + 1e-6, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Independent ZOH discretisation of `wn^2 / (s^2 + 2 zeta wn s + wn^2)` delayed by
    /// `t_delay`: the closed-form step response sampled at `k / fs`, turned into `b` by
    /// `b = A * diff(S)` (the first `m + 1` terms).
    fn zoh_second_order(fs: f64, fn_hz: f64, zeta: f64, t_delay: f64) -> Model {
        let wn = 2.0 * PI * fn_hz;
        let sigma = zeta * wn;
        let wd = wn * (1.0 - zeta * zeta).sqrt();
        let sc = |t: f64| {
            if t <= 0.0 {
                0.0
            } else {
                1.0 - (-sigma * t).exp() * ((wd * t).cos() + sigma / wd * (wd * t).sin())
            }
        };
        let h = 1.0 / fs;
        let r = (-sigma * h).exp();
        let a = vec![-2.0 * r * (wd * h).cos(), r * r];
        let d = (t_delay * fs).ceil() as usize;
        let s: Vec<f64> = (0..d + 3).map(|k| sc(k as f64 * h - t_delay)).collect();
        let imp: Vec<f64> = (d..d + 3)
            .map(|k| s[k] - if k > 0 { s[k - 1] } else { 0.0 })
            .collect();
        let b = vec![
            imp[0],
            imp[1] + a[0] * imp[0],
            imp[2] + a[0] * imp[1] + a[1] * imp[0],
        ];
        Model { fs, delay: d, a, b }
    }

    fn section(fs: f64, fn_hz: f64, zeta: f64) -> [f64; 2] {
        let wn = 2.0 * PI * fn_hz;
        let p = (c(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt()) / fs).exp();
        [-2.0 * p.re, p.norm_sqr()]
    }

    /// Fitted-looking models: arbitrary (not ZOH-exact) numerators, unit-ish DC gain.
    fn fitted_second() -> Model {
        let [a1, a2] = section(10_000.0, 95.0, 0.12);
        let g = 1.0 + a1 + a2;
        Model {
            fs: 10_000.0,
            delay: 3,
            a: vec![a1, a2],
            b: vec![0.21 * g, 0.5 * g, 0.29 * g],
        }
    }

    fn fitted_fourth() -> Model {
        let fs = 10_000.0;
        let [a1, a2] = section(fs, 180.0, 0.3);
        let [c1, c2] = section(fs, 850.0, 0.05);
        let a = vec![a1 + c1, a2 + a1 * c1 + c2, a1 * c2 + a2 * c1, a2 * c2];
        let g: f64 = 1.0 + a.iter().sum::<f64>();
        let w = [0.05, 0.3, 0.35, 0.2, 0.1];
        Model {
            fs,
            delay: 18,
            a,
            b: w.iter().map(|v| v * g).collect(),
        }
    }

    #[test]
    fn continuous_poles_of_a_zoh_system_are_exact() {
        let fs = 10_000.0;
        let t_delay = 2.37e-4;
        let m = zoh_second_order(fs, 95.0, 0.12, t_delay);
        assert_eq!(m.delay, 3);
        let ct = Continuous::from_model(&m).unwrap();
        for s in &ct.poles {
            let wn = s.magnitude;
            assert!((wn / (2.0 * PI) - 95.0).abs() < 1e-9, "{}", wn / (2.0 * PI));
            assert!((-s.re / wn - 0.12).abs() < 1e-9);
        }
        // The relative degree is 2: F touches zero at the true delay without crossing.
        assert!((ct.delay_s - t_delay).abs() * fs < 1e-5, "{}", ct.delay_s);
        assert!(ct.feedthrough.abs() < 1e-9, "{}", ct.feedthrough);
        // The continuous step response is the true one.
        let wn = 2.0 * PI * 95.0;
        let (sigma, wd) = (0.12 * wn, wn * (1.0f64 - 0.0144).sqrt());
        for k in 0..400 {
            let t = k as f64 * 1.3e-5;
            let tt = t - t_delay;
            let truth = if tt <= 0.0 {
                0.0
            } else {
                1.0 - (-sigma * tt).exp() * ((wd * tt).cos() + sigma / wd * (wd * tt).sin())
            };
            assert!(
                (ct.step(t) - truth).abs() < 1e-8,
                "t = {t}: {} vs {truth}",
                ct.step(t)
            );
        }
        // And so is the analysis of the discrete model.
        let an = crate::fit::analysis::Analysis::new(&m).unwrap();
        let crate::fit::analysis::ModeKind::Resonance {
            natural_frequency_hz,
            damping,
            ..
        } = an.modes[0].kind
        else {
            panic!()
        };
        assert!((natural_frequency_hz - 95.0).abs() < 1e-9);
        assert!((damping - 0.12).abs() < 1e-9);
    }

    #[test]
    fn a_first_order_lag_crosses_zero_at_its_delay() {
        // ZOH of 1/(1 + s T) delayed by 4.6 samples: F crosses zero exactly there.
        let fs = 1000.0;
        let (tc, td): (f64, f64) = (0.01, 4.6e-3);
        let p = (-1.0 / (tc * fs)).exp();
        let sc = |t: f64| if t <= 0.0 { 0.0 } else { 1.0 - (-t / tc).exp() };
        let s5 = sc(5e-3 - td);
        let s6 = sc(6e-3 - td);
        let m = Model {
            fs,
            delay: 5,
            a: vec![-p],
            b: vec![s5, (s6 - s5) - p * s5],
        };
        let ct = Continuous::from_model(&m).unwrap();
        assert_eq!(ct.delay_found, DelayFound::ZeroCrossing);
        assert!((ct.delay_s - td).abs() < 1e-12, "{}", ct.delay_s);
        assert!((ct.poles[0].re + 1.0 / tc).abs() < 1e-9);
        assert!((ct.response(1e-9).norm() - m.dc_gain()).abs() < 1e-9);
    }

    #[test]
    fn continuous_step_reproduces_the_discrete_step() {
        for m in [fitted_second(), fitted_fourth()] {
            let ct = Continuous::from_model(&m).unwrap();
            let s = step_response(&m, 3000);
            for (k, v) in s.iter().enumerate() {
                assert!((ct.step(k as f64 / m.fs) - v).abs() < 1e-9, "k = {k}");
            }
            // DC: the continuous model's gain near 0 Hz is the discrete DC gain.
            let h0 = ct.response(1e-6);
            assert!((h0.re - m.dc_gain()).abs() < 1e-9 && h0.im.abs() < 1e-6);
            assert!((ct.dc_gain - m.dc_gain()).abs() < 1e-12);
            let fr = ct.frequency_response(&[0.0, 1.0]);
            assert!((fr[0].0 - m.dc_gain().abs()).abs() < 1e-9);
            assert!(
                ct.delay_s > (m.delay as f64 - 1.0) / m.fs && ct.delay_s <= m.delay as f64 / m.fs
            );
        }
    }

    #[test]
    fn resampled_step_matches_the_continuous_step() {
        for m in [fitted_second(), fitted_fourth()] {
            let (ct, up) = resample(&m, 50_000.0).unwrap();
            assert_eq!(up.model.a.len(), m.a.len());
            assert_eq!(up.model.b.len(), m.a.len() + 1);
            assert!(up.delay_samples as f64 >= up.delay_in_samples - 1e-9);
            assert!((up.delay_samples as f64) < up.delay_in_samples + 1.0);
            let s = step_response(&up.model, 15_000);
            let worst = s
                .iter()
                .enumerate()
                .map(|(k, v)| (ct.step(k as f64 / 50_000.0) - v).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "order {}: {worst:e}", m.order());
            assert!((up.model.dc_gain() - m.dc_gain()).abs() < 1e-9);
        }
    }

    #[test]
    fn round_trip_10k_50k_10k_reproduces_the_step() {
        for m in [fitted_second(), fitted_fourth()] {
            let (_, up) = resample(&m, 50_000.0).unwrap();
            let (_, back) = resample(&up.model, 10_000.0).unwrap();
            assert_eq!(back.model.delay, m.delay);
            let agreement = step_agreement(&m, &back.model);
            // The criterion is 0.5 % of the step; the step-invariant round trip is exact
            // up to round-off.
            assert!(
                agreement.max_error < 1e-8,
                "order {}: {agreement:?}",
                m.order()
            );
            assert!(agreement.instants > 100);
            let there = step_agreement(&m, &up.model);
            assert!(there.max_error < 1e-9, "{there:?}");
            // The coefficients themselves come back to ~1e-6 relative for the 4th order (its
            // poles sit near z = 1); the step response, which is what matters, to ~1e-10.
        }
    }

    #[test]
    fn odd_rates_and_downsampling() {
        let m = fitted_fourth();
        let (ct, r) = resample(&m, 12_345.0).unwrap();
        let s = step_response(&r.model, 5000);
        for (k, v) in s.iter().enumerate() {
            assert!((ct.step(k as f64 / 12_345.0) - v).abs() < 1e-9);
        }
        // At 1 kHz the 850 Hz resonance is above Nyquist: still step invariant, but warned.
        let (_, low) = resample(&m, 1000.0).unwrap();
        assert!(!low.warnings.is_empty());
        assert!(low.delay_note.contains("samples"));
    }

    #[test]
    fn models_without_an_equivalent_are_refused_clearly() {
        let neg = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![0.6],
            b: vec![1.6],
        };
        let e = Continuous::from_model(&neg).unwrap_err().to_string();
        assert!(e.contains("negative real axis"), "{e}");
        let unstable = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-1.1],
            b: vec![0.1],
        };
        let e = Continuous::from_model(&unstable).unwrap_err().to_string();
        assert!(e.contains("unstable"), "{e}");
        let repeated = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-1.8, 0.81],
            b: vec![0.01],
        };
        let e = Continuous::from_model(&repeated).unwrap_err().to_string();
        assert!(e.contains("repeated"), "{e}");
        let fir = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-0.5],
            b: vec![0.1, 0.2, 0.2],
        };
        let e = Continuous::from_model(&fir).unwrap_err().to_string();
        assert!(e.contains("z = 0"), "{e}");
        assert!(fitted_second_discretise_rejects_bad_rate());
    }

    fn fitted_second_discretise_rejects_bad_rate() -> bool {
        let ct = Continuous::from_model(&fitted_second()).unwrap();
        ct.discretise(0.0).is_err() && ct.discretise(f64::NAN).is_err()
    }

    #[test]
    fn a_pure_delay_and_a_leading_zero() {
        let m = Model {
            fs: 1000.0,
            delay: 2,
            a: vec![],
            b: vec![0.0, 0.8],
        };
        let ct = Continuous::from_model(&m).unwrap();
        assert!((ct.delay_s - 3e-3).abs() < 1e-15);
        assert!((ct.feedthrough - 0.8).abs() < 1e-15);
        let r = ct.discretise(4000.0).unwrap();
        assert_eq!(r.delay_samples, 12);
        assert_eq!(r.model.b, vec![0.8]);
    }

    /// The fit room's typed errors keep their words ("continuous-time equivalent: ...") and
    /// the stable kind "numerical".
    #[test]
    fn models_without_an_equivalent_are_refused_by_name() {
        let model = |a: Vec<f64>, b: Vec<f64>| Model {
            fs: 1000.0,
            delay: 1,
            a,
            b,
        };
        let e = Continuous::from_model(&model(vec![0.5], vec![0.5])).unwrap_err();
        assert!(
            matches!(
                e.stage(),
                Some(FitError::Continuous(
                    ContinuousError::NegativeRealPole { .. }
                ))
            ),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "continuous-time equivalent: pole -0.500000 is on the negative real axis: it \
             oscillates at Nyquist and has no continuous-time equivalent (s = fs ln p is not real)"
        );
        assert_eq!(e.kind(), "numerical");
        assert_eq!(e.location(), (None, None, None));
        let e = Continuous::from_model(&model(vec![-1.5], vec![0.5])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "continuous-time equivalent: pole 1.500000 has |z| = 1.500000 >= 1: an unstable \
             model has no step-invariant continuous-time equivalent"
        );
        let e = Continuous::from_model(&model(vec![-0.5], vec![0.1, 0.2, 0.3])).unwrap_err();
        assert!(
            matches!(
                e.stage(),
                Some(FitError::Continuous(ContinuousError::FiniteImpulsePart {
                    numerator: 3,
                    denominator: 1
                }))
            ),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "continuous-time equivalent: b has 3 coefficients after the delay but a only 1: the \
             model has poles at z = 0 (a finite-impulse-response part), which have no \
             continuous-time equivalent"
        );
        let e = Continuous::from_model(&model(vec![-0.5], vec![0.0, 0.0])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "continuous-time equivalent: b is all zeros: the model's output is always zero"
        );
    }
}
