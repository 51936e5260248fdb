//! Physical effects added to a model in the modelling loop, and what each changes.
//!
//! This module owns [`Effect`] (stored in the model file as `effects = [...]`), how a fit
//! honours each effect ([`FitChanges`]), and how the model's prediction and the compensator's
//! input are corrected for the additive ones ([`Additive`]). Finding which effect is missing is
//! [`crate::diagnose`]'s job; measuring the residual is [`crate::evidence`]'s.
//!
//! | kind | change to the model | on the board |
//! |---|---|---|
//! | `mode` | two more poles and zeros (a second-order section) | one more section |
//! | `leak` | one more pole and zero (the slow creep of a leaking cavity) | part of a section |
//! | `offset` | a constant added to the prediction | subtracted before compensation |
//! | `drift` | a ramp added to the prediction | subtracted (the board counts samples) |
//! | `delay` | the delay the evidence points to, instead of the fitted one | the delay |
//! | `coloured-noise` | output-error fit (the noise needs no model then) | nothing |
//! | `nonlinear-damping` | a quadratic loss `gain * \|dy/dt\| dy/dt` taken off the input the dynamics see (fitted by least squares, alternating with the linear part) | `gain * lowpass(\|dy\| dy)` added to the linear inverse ([`crate::compensator::NonlinearDampingCoefficients`]); f32 only, the fixed-point export refuses it |
//!
//! # Nonlinear damping
//!
//! Orifice and turbulent losses grow with the square of the flow: a probe obeys
//! `y'' + (2 zeta w + k |y'|) y' + w^2 y = w^2 u(t - tau)` rather than the linear equation.
//! Written as the input the linear dynamics see, `u(t - tau) - gain |y'| y'` with
//! `gain = k / w^2` (s^2 per probe unit), the model is
//!
//! ```text
//! A(q) y = B(q) ( q^-d u  -  gain * N ),    N[k] = fs^2 |y[k] - y[k-1]| (y[k] - y[k-1])
//! ```
//!
//! and its inverse is the linear one plus a correction from the probe signal alone:
//! `u[k-d] = (A/B) y + gain * N[k]`. The board adds `gain * lowpass(N)` (the design's own
//! low-pass) to the linear compensator's output; nothing else changes.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::fit::{Fitted, Method, Options, Order, Test};
use crate::model::Model;

/// One effect added to the model, with its parameters once fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Effect {
    /// An unmodelled resonance: a higher acoustic mode of the line, a cavity's Helmholtz
    /// resonance. Adds a second-order section.
    Mode {
        /// Frequency where the evidence put it (Hz), for the record.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        near_hz: Option<f64>,
    },
    /// A leaking cavity or side volume: a slow pole-zero pair (creep after the step).
    Leak,
    /// A zero offset of the probe against the reference.
    Offset {
        /// Offset in the probe's units (fitted).
        #[serde(default)]
        value: f64,
    },
    /// A slow drift of the probe in time (thermal drift of the sensor).
    Drift {
        /// Offset at the start of a test (fitted).
        #[serde(default)]
        value: f64,
        /// Drift rate in the probe's units per second (fitted).
        #[serde(default)]
        rate_per_s: f64,
    },
    /// The delay, corrected.
    Delay {
        /// Delay in samples.
        samples: usize,
    },
    /// Residuals correlated in time but not explained by the input: fit by output error.
    ColouredNoise,
    /// Amplitude-dependent (quadratic, orifice or turbulent) losses: the input the linear
    /// dynamics see is lowered by `gain * |dy/dt| dy/dt` (see the module docs).
    NonlinearDamping {
        /// Quadratic loss coefficient, s^2 per probe unit (fitted); the linear damping ratio
        /// rises by about `gain * w * |dy/dt| / 2` at the rate `dy/dt`.
        #[serde(default)]
        gain: f64,
    },
}

/// The machine-readable kinds, in catalogue order.
pub const KINDS: [&str; 7] = [
    "mode",
    "leak",
    "offset",
    "drift",
    "delay",
    "coloured-noise",
    "nonlinear-damping",
];

impl Effect {
    /// Its machine-readable kind.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Mode { .. } => "mode",
            Self::Leak => "leak",
            Self::Offset { .. } => "offset",
            Self::Drift { .. } => "drift",
            Self::Delay { .. } => "delay",
            Self::ColouredNoise => "coloured-noise",
            Self::NonlinearDamping { .. } => "nonlinear-damping",
        }
    }

    /// A fresh effect of `kind` (parameters to be fitted), or `None` for an unknown kind.
    #[must_use]
    pub fn parse(kind: &str) -> Option<Self> {
        Some(match kind {
            "mode" => Self::Mode { near_hz: None },
            "leak" => Self::Leak,
            "offset" => Self::Offset { value: 0.0 },
            "drift" => Self::Drift {
                value: 0.0,
                rate_per_s: 0.0,
            },
            "coloured-noise" => Self::ColouredNoise,
            "nonlinear-damping" => Self::NonlinearDamping { gain: 0.0 },
            _ => {
                let d = kind.strip_prefix("delay=")?.parse().ok()?;
                Self::Delay { samples: d }
            }
        })
    }
}

/// What a list of effects changes in a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FitChanges {
    /// Poles to add to the order the user asked for.
    pub extra_order: usize,
    /// The delay to use instead of searching.
    pub delay: Option<usize>,
    /// The method to use instead of the user's.
    pub method: Option<Method>,
    /// Whether an offset is fitted.
    pub offset: bool,
    /// Whether a drift is fitted.
    pub drift: bool,
    /// Whether a quadratic damping term is fitted.
    pub nonlinear: bool,
}

impl FitChanges {
    /// Collects the changes of `effects`.
    #[must_use]
    pub fn of(effects: &[Effect]) -> Self {
        let mut c = Self::default();
        for e in effects {
            match e {
                Effect::Mode { .. } => c.extra_order += 2,
                Effect::Leak => c.extra_order += 1,
                Effect::Offset { .. } => c.offset = true,
                Effect::Drift { .. } => c.drift = true,
                Effect::Delay { samples } => c.delay = Some(*samples),
                Effect::ColouredNoise => c.method = Some(Method::Oe),
                Effect::NonlinearDamping { .. } => c.nonlinear = true,
            }
        }
        c
    }
}

/// The additive part of a model's effects: `offset + rate * t` (t from the test's start).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Additive {
    /// Constant, probe units.
    pub offset: f64,
    /// Rate, probe units per second.
    pub rate_per_s: f64,
}

impl Additive {
    /// The additive part of `effects`.
    #[must_use]
    pub fn of(effects: &[Effect]) -> Self {
        let mut a = Self::default();
        for e in effects {
            match e {
                Effect::Offset { value } => a.offset += value,
                Effect::Drift { value, rate_per_s } => {
                    a.offset += value;
                    a.rate_per_s += rate_per_s;
                }
                _ => {}
            }
        }
        a
    }

    /// The value at sample `k` of a test sampled at `fs`.
    #[must_use]
    pub fn at(&self, k: usize, fs: f64) -> f64 {
        self.offset + self.rate_per_s * k as f64 / fs
    }

    /// Adds itself to a prediction.
    pub fn add_to(&self, y: &mut [f64], fs: f64) {
        for (k, v) in y.iter_mut().enumerate() {
            *v += self.at(k, fs);
        }
    }

    /// The probe signal with the additive effects removed (what the compensator is given).
    #[must_use]
    pub fn removed_from(&self, y: &[f64], fs: f64) -> Vec<f64> {
        y.iter()
            .enumerate()
            .map(|(k, v)| v - self.at(k, fs))
            .collect()
    }
}

/// The additive effects of one test, estimated from its residual `r = y - y_dynamics` by
/// least squares: an offset from the samples before the step (or all, without a step), an
/// offset and a rate from the whole record. They are nuisances of each record (a drift is not
/// the same in two tests), so each test gets its own.
#[must_use]
pub fn estimate_additive(changes: &FitChanges, r: &[f64], onset: usize, fs: f64) -> Additive {
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len().max(1) as f64;
    if changes.drift {
        let n = r.len() as f64;
        let tm = (n - 1.0) / 2.0;
        let rm = mean(r);
        let (mut num, mut den) = (0.0, 0.0);
        for (i, v) in r.iter().enumerate() {
            let t = i as f64 - tm;
            num += t * (v - rm);
            den += t * t;
        }
        let per_sample = if den > 0.0 { num / den } else { 0.0 };
        Additive {
            offset: rm - per_sample * tm,
            rate_per_s: per_sample * fs,
        }
    } else if changes.offset {
        let pre = if onset >= 20 { &r[..onset] } else { r };
        Additive {
            offset: mean(pre),
            rate_per_s: 0.0,
        }
    } else {
        Additive::default()
    }
}

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

/// The model's output with quadratic damping `gain` (see the module docs), started in
/// equilibrium with `u[0]`: `A y = B (q^-d u - gain N(y))`. The term of `b0`, which needs
/// `N[k]` of the sample being computed, is solved exactly (a quadratic in the step
/// `y[k] - y[k-1]`); with `gain = 0` this is [`Model::simulate`].
#[must_use]
pub fn simulate_nonlinear(model: &Model, gain: f64, u: &[f64]) -> Vec<f64> {
    let u0 = u.first().copied().unwrap_or(0.0);
    let y0 = model.dc_gain() * u0;
    let fs2 = model.fs * model.fs;
    let n = u.len();
    let mut y = vec![0.0; n];
    let mut q = vec![0.0; n];
    let b0 = model.b.first().copied().unwrap_or(0.0);
    for k in 0..n {
        let mut acc = 0.0;
        for (i, bi) in model.b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + model.delay) {
                acc += bi * (u[j] - u0);
            }
            if i > 0 {
                if let Some(j) = k.checked_sub(i) {
                    acc -= gain * bi * q[j];
                }
            }
        }
        for (i, ai) in model.a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                acc -= ai * y[j];
            }
        }
        // y[k] = acc - gain b0 fs^2 |D| D with D = y[k] - y[k-1]: D = c - beta |D| D.
        let prev = if k > 0 { y[k - 1] } else { 0.0 };
        let c = acc - prev;
        let beta = gain * b0 * fs2;
        let disc = 1.0 + 4.0 * beta * c.abs();
        let d = if beta == 0.0 {
            c
        } else if disc >= 0.0 {
            c.signum() * 2.0 * c.abs() / (1.0 + disc.sqrt())
        } else {
            // No solution of the implicit step (a negative b0 and a large step): the term of
            // b0 is taken from the previous sample instead.
            c - beta * if k > 0 { q[k - 1] / fs2 } else { 0.0 }
        };
        y[k] = prev + d;
        q[k] = fs2 * d.abs() * d;
    }
    for v in &mut y {
        *v += y0;
    }
    y
}

/// The model's full prediction for a test: the dynamics (with their quadratic damping, if
/// any) started in equilibrium with `u[0]`, plus the additive effects estimated on this test.
#[must_use]
pub fn predict(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    let gain = nonlinear_gain(effects);
    let mut ym = if gain == 0.0 {
        model.simulate(u)
    } else {
        simulate_nonlinear(model, gain, u)
    };
    let changes = FitChanges::of(effects);
    if changes.offset || changes.drift {
        let onset = crate::fit::step::find_step(u).map_or(0, |s| s.onset);
        let r: Vec<f64> = y.iter().zip(&ym).map(|(a, b)| a - b).collect();
        estimate_additive(&changes, &r, onset, model.fs).add_to(&mut ym, model.fs);
    }
    ym
}

/// Points of the coarse grid over the quadratic loss before the golden-section refinement.
pub const NONLINEAR_GRID: usize = 9;

/// Golden-section steps refining the quadratic loss between the grid's neighbours.
pub const NONLINEAR_REFINE: usize = 10;

/// Fits the linear part and the quadratic loss together on one test: for each trial loss the
/// linear part is fitted (by the user's method, delay fixed by a plain fit first) to the input
/// less the loss times the quadratic rate of the (lightly smoothed, centred) measurement, and
/// the loss is chosen where the whole model's simulation error is lowest: a grid from zero to
/// the loss that would take twice the step off the input at the peak rate, refined by golden
/// section. Returns the fit and the loss.
fn fit_nonlinear(
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
    let q_max = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
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

/// Fits with `effects`: the order raised by the modes and leaks, the delay and method they
/// impose, and the drift removed before the dynamics are fitted (alternating three times).
/// With `nonlinear-damping` the linear part and the quadratic loss are fitted together (a
/// search over the loss, the linear part refitted at each; see `fit_nonlinear`).
/// Returns the fit and the effects with their fitted parameters (from the estimation test).
///
/// # Errors
/// As [`crate::fit::fit`].
pub fn fit_with(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    options: &Options,
    effects: &[Effect],
) -> Result<(Fitted, Vec<Effect>)> {
    let changes = FitChanges::of(effects);
    let order = match options.order {
        Order::Fixed(m) => Order::Fixed(m + changes.extra_order),
        Order::Auto { max } => Order::Auto {
            max: max + changes.extra_order,
        },
    };
    let opts = Options {
        method: changes.method.unwrap_or(options.method),
        order,
        delay: changes.delay.or(options.delay),
    };
    let onset = crate::fit::step::find_step(estimation.u).map_or(0, |s| s.onset);
    let mut additive = Additive::default();
    let rounds = if changes.drift { 3 } else { 1 };
    let mut gain = 0.0;
    let mut fitted = None;
    for _ in 0..rounds {
        let y = additive.removed_from(estimation.y, fs);
        let est = Test {
            name: estimation.name,
            u: estimation.u,
            y: &y,
        };
        let f = if changes.nonlinear {
            let (f, g) = fit_nonlinear(&est, validation, fs, &opts)?;
            gain = g;
            f
        } else {
            crate::fit::fit(&est, validation, fs, &opts)?
        };
        let r: Vec<f64> = estimation
            .y
            .iter()
            .zip(simulate_nonlinear(&f.model, gain, estimation.u))
            .map(|(a, b)| a - b)
            .collect();
        additive = estimate_additive(&changes, &r, onset, fs);
        fitted = Some(f);
    }
    let fitted = fitted.ok_or_else(|| crate::error::Error::Numerical {
        context: "fit".into(),
        message: "no fit".into(),
    })?;
    let out = effects
        .iter()
        .map(|e| match e {
            Effect::Offset { .. } => Effect::Offset {
                value: additive.offset,
            },
            Effect::Drift { .. } => Effect::Drift {
                value: additive.offset,
                rate_per_s: additive.rate_per_s,
            },
            Effect::NonlinearDamping { .. } => Effect::NonlinearDamping { gain },
            other => other.clone(),
        })
        .collect();
    Ok((fitted, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_round_trip_through_toml() {
        #[derive(Serialize, Deserialize)]
        struct W {
            effects: Vec<Effect>,
        }
        let w = W {
            effects: vec![
                Effect::Mode {
                    near_hz: Some(410.0),
                },
                Effect::Leak,
                Effect::Drift {
                    value: 0.1,
                    rate_per_s: -0.5,
                },
                Effect::Delay { samples: 17 },
                Effect::ColouredNoise,
                Effect::NonlinearDamping { gain: 1.25e-6 },
            ],
        };
        let text = toml::to_string(&w).unwrap();
        assert!(text.contains("kind = \"coloured-noise\""), "{text}");
        assert!(text.contains("kind = \"nonlinear-damping\""), "{text}");
        let back: W = toml::from_str(&text).unwrap();
        assert_eq!(back.effects, w.effects);
        for k in KINDS {
            let e = if k == "delay" {
                Effect::parse("delay=3")
            } else {
                Effect::parse(k)
            };
            assert_eq!(e.map(|e| e.kind()), Some(k));
        }
        assert!(Effect::parse("gremlins").is_none());
    }

    #[test]
    fn changes_and_additive_parts() {
        let e = [
            Effect::Mode { near_hz: None },
            Effect::Leak,
            Effect::Offset { value: 2.0 },
            Effect::Drift {
                value: 1.0,
                rate_per_s: 10.0,
            },
        ];
        let c = FitChanges::of(&e);
        assert_eq!(c.extra_order, 3);
        assert!(c.offset && c.drift);
        let a = Additive::of(&e);
        assert_eq!(a.at(0, 100.0), 3.0);
        assert_eq!(a.at(100, 100.0), 13.0);
        assert_eq!(a.removed_from(&[3.0, 3.1], 100.0), vec![0.0, 0.0]);
        // Estimated back from a residual that is exactly a ramp.
        let r: Vec<f64> = (0..1000).map(|k| 0.5 + 2.0 * k as f64 / 1000.0).collect();
        let est = estimate_additive(&c, &r, 100, 1000.0);
        assert!((est.offset - 0.5).abs() < 1e-9 && (est.rate_per_s - 2.0).abs() < 1e-9);
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
        assert_eq!(simulate_nonlinear(&model, 0.0, &u), model.simulate(&u));
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
