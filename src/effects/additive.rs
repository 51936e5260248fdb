//! The `offset` and `drift` effects: the additive part of a prediction, and its estimates
//! from a test's residual and from the record's ends.

use super::{Effect, FitChanges};

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
/// least squares: an offset from the samples before `onset`, where the quiet segment before
/// the step ends ([`crate::fit::step::quiet_until`]; all of them without one, as in a
/// traverse, whose first samples are signal the model may not yet follow); an offset and a
/// rate from the whole record. They are nuisances of each record (a drift is not
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

/// A first drift estimate from the record's ends: the probe's slope over its last 30 % less
/// the reference's slope there scaled by the probe's step gain, and the level before the step.
pub(super) fn initial_drift(u: &[f64], y: &[f64], onset: usize, fs: f64) -> Additive {
    let slope = |x: &[f64]| -> (f64, f64) {
        let n = x.len() as f64;
        let tm = 0.5 * (n - 1.0);
        let m = x.iter().sum::<f64>() / n.max(1.0);
        let (mut num, mut den) = (0.0, 0.0);
        for (k, v) in x.iter().enumerate() {
            let t = k as f64 - tm;
            num += t * (v - m);
            den += t * t;
        }
        (m, if den > 0.0 { num / den } else { 0.0 })
    };
    let n = y.len().min(u.len());
    let tail = n - (3 * n / 10).max(2).min(n);
    let (Some(yt), Some(ut)) = (y.get(tail..n), u.get(tail..n)) else {
        return Additive::default();
    };
    let (y_tail, y_slope) = slope(yt);
    let (u_tail, u_slope) = slope(ut);
    let pre = onset.max(1).min(n);
    let y0 = y
        .get(..pre)
        .map_or(0.0, |x| x.iter().sum::<f64>() / x.len().max(1) as f64);
    let u0 = u
        .get(..pre)
        .map_or(0.0, |x| x.iter().sum::<f64>() / x.len().max(1) as f64);
    let gain = if (u_tail - u0).abs() > 0.0 {
        (y_tail - y0) / (u_tail - u0)
    } else {
        1.0
    };
    let rate_per_sample = y_slope - gain * u_slope;
    // The ramp passes through zero at the onset: the level before the step is the probe's.
    Additive {
        offset: -rate_per_sample * onset as f64,
        rate_per_s: rate_per_sample * fs,
    }
}

/// The drift rate among `effects` (0 without one).
pub(super) fn additive_rate(effects: &[Effect]) -> f64 {
    Additive::of(effects).rate_per_s
}
