//! The `nonlinear-damping` effect: the quadratic rate term, the model's simulation with the
//! quadratic loss, and the fit of the loss together with the linear part.

use super::Effect;
use crate::error::Result;
use crate::fit::model::Model;
use crate::fit::{Fitted, Options, Test};

/// The quadratic damping gain of `effects` (s^2 per probe unit; 0 without the effect).
#[must_use]
pub fn nonlinear_gain(effects: &[Effect]) -> f64 {
    effects
        .iter()
        .map(|e| match e {
            Effect::NonlinearDamping { gain } => *gain,
            _ => 0.0,
        })
        .sum()
}

/// The quadratic rate term of the probe signal, `N[k] = fs^2 |y[k] - y[k-1]| (y[k] - y[k-1])`
/// (`N[0] = 0`): `|dy/dt| dy/dt` by the backward difference, what the board computes.
#[must_use]
pub fn quadratic_rate(y: &[f64], fs: f64) -> Vec<f64> {
    let mut prev = y.first().copied().unwrap_or(0.0);
    y.iter()
        .map(|&v| {
            let d = v - prev;
            prev = v;
            fs * fs * d.abs() * d
        })
        .collect()
}

/// The peak of the quadratic rate ([`quadratic_rate`]) of `model`'s simulation of `u`: the
/// probe's own peak rate, which a measurement's sample-to-sample differences overstate by its
/// noise times the sample rate on a slow probe sampled fast. What a loss's search is scaled by.
#[must_use]
pub(crate) fn peak_rate(model: &Model, u: &[f64]) -> f64 {
    quadratic_rate(&model.simulate(u), model.fs)
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
}

/// The model's output with quadratic damping `gain` (see the module docs), started in
/// equilibrium with its resting level ([`crate::fit::model::resting_level`]): `A y = B (q^-d u - gain N(y))`. The term of `b0`, which needs
/// `N[k]` of the sample being computed, is solved exactly (a quadratic in the step
/// `y[k] - y[k-1]`); with `gain = 0` this is [`Model::simulate`].
#[must_use]
pub fn simulate_nonlinear(model: &Model, gain: f64, u: &[f64]) -> Vec<f64> {
    let mut s = Stepper::new(model, gain, u);
    (0..u.len()).map(|k| s.next(u, k)).collect()
}

/// [`simulate_nonlinear`] one sample at a time, holding only the model's history: what a
/// fit over a long record runs block by block.
#[derive(Debug, Clone)]
pub(super) struct Stepper<'m> {
    model: &'m Model,
    gain: f64,
    /// The input's resting level and the output's, in equilibrium with it.
    u0: f64,
    y0: f64,
    fs2: f64,
    /// `y[k-1-i]` and `q[k-1-i]` (deviations from the resting level), newest first.
    y: Vec<f64>,
    q: Vec<f64>,
}

impl<'m> Stepper<'m> {
    /// At rest before the record `u`.
    pub(super) fn new(model: &'m Model, gain: f64, u: &[f64]) -> Self {
        let u0 = crate::fit::model::resting_level(u);
        let depth = model.a.len().max(model.b.len()) + 1;
        Self {
            model,
            gain,
            u0,
            y0: model.dc_gain() * u0,
            fs2: model.fs * model.fs,
            y: vec![0.0; depth],
            q: vec![0.0; depth],
        }
    }

    /// The output at sample `k` of `u`; the samples must come in order from 0.
    pub(super) fn next(&mut self, u: &[f64], k: usize) -> f64 {
        let (model, gain) = (self.model, self.gain);
        let mut acc = 0.0;
        for (i, bi) in model.b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + model.delay) {
                acc += bi * (u.get(j).copied().unwrap_or(self.u0) - self.u0);
            }
            if i > 0 && k >= i {
                acc -= gain * bi * self.q.get(i - 1).copied().unwrap_or(0.0);
            }
        }
        for (i, ai) in model.a.iter().enumerate() {
            if k > i {
                acc -= ai * self.y.get(i).copied().unwrap_or(0.0);
            }
        }
        // y[k] = acc - gain b0 fs^2 |D| D with D = y[k] - y[k-1]: D = c - beta |D| D.
        let b0 = model.b.first().copied().unwrap_or(0.0);
        let prev = if k > 0 {
            self.y.first().copied().unwrap_or(0.0)
        } else {
            0.0
        };
        let c = acc - prev;
        let beta = gain * b0 * self.fs2;
        let disc = 1.0 + 4.0 * beta * c.abs();
        let d = if beta == 0.0 {
            c
        } else if disc >= 0.0 {
            c.signum() * 2.0 * c.abs() / (1.0 + disc.sqrt())
        } else {
            // No solution of the implicit step (a negative b0 and a large step): the term of
            // b0 is taken from the previous sample instead.
            let q_prev = if k > 0 {
                self.q.first().copied().unwrap_or(0.0)
            } else {
                0.0
            };
            c - beta * q_prev / self.fs2
        };
        let y = prev + d;
        push_front(&mut self.y, y);
        push_front(&mut self.q, self.fs2 * d.abs() * d);
        y + self.y0
    }
}

/// Shifts the history `v` (newest first) by one sample and puts `x` in front, the oldest
/// falling off: a loop the compiler keeps in registers for the few samples a model's order
/// needs, where `rotate_right` called the C library's `memmove` once a sample (a fit's
/// simulation makes millions of steps).
fn push_front(v: &mut [f64], x: f64) {
    let mut carry = x;
    for slot in v.iter_mut() {
        carry = core::mem::replace(slot, carry);
    }
}

/// Points of the coarse grid over the quadratic loss before the golden-section refinement.
pub const NONLINEAR_GRID: usize = 9;

/// Golden-section steps refining the quadratic loss between the grid's neighbours.
pub const NONLINEAR_REFINE: usize = 10;

/// Fits the linear part and the quadratic loss together on one test: for each trial loss the
/// linear part is fitted (by the user's method, delay fixed by a plain fit first) to the input
/// less the loss times the quadratic rate of the (lightly smoothed, centred) measurement, and
/// the loss is chosen where the whole model's simulation error is lowest: a grid from zero to
/// the loss that would take twice the step off the input at the plain model's peak rate,
/// refined by golden section. Returns the fit and the loss.
pub(super) fn fit_nonlinear(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    opts: &Options,
) -> Result<(Fitted, f64)> {
    let plain = crate::fit::fit(estimation, validation, fs, opts)?;
    let opts = Options {
        delay: Some(plain.model.delay),
        ..*opts
    };
    let d = plain.model.delay;
    // Centred 5-point mean: the rate's noise is much reduced, its timing kept.
    let n = estimation.y.len();
    let smooth: Vec<f64> = (0..n)
        .map(|k| {
            let lo = k.saturating_sub(2);
            let hi = (k + 3).min(n);
            estimation.y[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect();
    let q = quadratic_rate(&smooth, fs);
    let last = q.last().copied().unwrap_or(0.0);
    let advanced: Vec<f64> = (0..n)
        .map(|k| q.get(k + d).copied().unwrap_or(last))
        .collect();
    let (lo, hi) = estimation
        .u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    // The peak rate is the plain model's, as the joint fit's: the measurement's carries its
    // noise ([`super::joint::joint_loss`]).
    let q_max = peak_rate(&plain.model, estimation.u);
    if !(q_max > 0.0 && hi > lo) {
        return Ok((plain, 0.0));
    }
    let g_max = 2.0 * (hi - lo) / q_max;
    let trial = |g: f64| -> Option<(f64, Fitted)> {
        let u: Vec<f64> = estimation
            .u
            .iter()
            .zip(&advanced)
            .map(|(u, q)| u - g * q)
            .collect();
        let t = Test {
            name: estimation.name,
            u: &u,
            y: estimation.y,
        };
        let f = crate::fit::fit(&t, validation, fs, &opts).ok()?;
        let e = crate::fit::nrmse_of(estimation.y, &simulate_nonlinear(&f.model, g, estimation.u));
        e.is_finite().then_some((e, f))
    };
    let step = g_max / (NONLINEAR_GRID - 1) as f64;
    let mut best: Option<(f64, f64, Fitted)> = None;
    let consider = |g: f64, best: &mut Option<(f64, f64, Fitted)>| -> f64 {
        match trial(g) {
            Some((e, f)) => {
                if best.as_ref().is_none_or(|b| e < b.0) {
                    *best = Some((e, g, f));
                }
                e
            }
            None => f64::INFINITY,
        }
    };
    for i in 0..NONLINEAR_GRID {
        consider(step * i as f64, &mut best);
    }
    let centre = best.as_ref().map_or(0.0, |b| b.1);
    let (mut a, mut b) = ((centre - step).max(0.0), centre + step);
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = b - ratio * (b - a);
    let mut x2 = a + ratio * (b - a);
    let mut e1 = consider(x1, &mut best);
    let mut e2 = consider(x2, &mut best);
    for _ in 0..NONLINEAR_REFINE {
        if e1 <= e2 {
            b = x2;
            x2 = x1;
            e2 = e1;
            x1 = b - ratio * (b - a);
            e1 = consider(x1, &mut best);
        } else {
            a = x1;
            x1 = x2;
            e1 = e2;
            x2 = a + ratio * (b - a);
            e2 = consider(x2, &mut best);
        }
    }
    Ok(best.map_or((plain, 0.0), |(_, g, f)| (f, g)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_history_takes_the_newest_sample_in_front_and_drops_the_oldest() {
        let mut v = vec![3.0, 2.0, 1.0];
        push_front(&mut v, 4.0);
        assert_eq!(v, [4.0, 3.0, 2.0]);
        push_front(&mut v, 5.0);
        assert_eq!(v, [5.0, 4.0, 3.0]);
        let mut empty: Vec<f64> = Vec::new();
        push_front(&mut empty, 1.0);
        assert!(empty.is_empty());
    }

    #[test]
    fn quadratic_losses_obey_the_model_equation_and_invert_exactly() {
        // DC gain 1, zeros of B at |z|^2 = 0.2 (invertible), delay 3.
        let model = Model {
            fs: 1000.0,
            delay: 3,
            a: vec![-1.6, 0.7],
            b: vec![0.05, 0.04, 0.01],
        };
        let u: Vec<f64> = (0..400)
            .map(|k| match k {
                0..20 => 0.0,
                20..150 => 1.0,
                _ => 0.2,
            })
            .collect();
        // Without the loss it is the linear model (to rounding: the sums run in another order).
        let linear = model.simulate(&u);
        for (x, l) in simulate_nonlinear(&model, 0.0, &u).iter().zip(&linear) {
            assert!((x - l).abs() < 1e-12, "{x} vs {l}");
        }
        let g = 2e-5;
        let y = simulate_nonlinear(&model, g, &u);
        let n = quadratic_rate(&y, model.fs);
        // The loss is a real part of the response (peak |g N| well above rounding) ...
        let peak = n.iter().fold(0.0f64, |m, v| m.max((g * v).abs()));
        assert!(peak > 0.05, "{peak}");
        // ... and every sample satisfies A y = B (q^-d u - g N), the b0 term included.
        for k in 5..u.len() {
            let mut e = y[k] + model.a[0] * y[k - 1] + model.a[1] * y[k - 2];
            for (i, bi) in model.b.iter().enumerate() {
                e -= bi * (u[k - i - 3] - g * n[k - i]);
            }
            assert!(e.abs() < 1e-12, "sample {k}: {e}");
        }
        // The inverse is the linear one plus g N: the reference comes back, d samples late.
        let linear = model.compensate::<f64>(&y).unwrap();
        for k in 3..u.len() {
            let u_hat = linear[k] + g * n[k];
            assert!((u_hat - u[k - 3]).abs() < 1e-9, "sample {k}: {u_hat}");
        }
        // Without the correction it does not.
        let worst = (3..u.len())
            .map(|k| (linear[k] - u[k - 3]).abs())
            .fold(0.0, f64::max);
        assert!(worst > 0.05, "{worst}");
    }
}
