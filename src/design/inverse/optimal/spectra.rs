//! The spectra a design weighs: the noise of both channels ([`NoiseModel`]) and the prior for
//! the pressure ([`SignalPrior`]), and their measurement on step tests or recorded runs.

use serde::{Deserialize, Serialize};

use crate::fit::step::{self, detrend, NoiseSource};
use crate::fit::Test;

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

pub use crate::fit::step::MIN_QUIET;

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
/// little, less the noise's share `2 sigma_y^2`, as a plain random walk: the first estimate
/// that [`crate::design::inverse::check::prior_for_runs`] then judges on the runs' spectra.
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

#[cfg(test)]
mod tests {
    use super::*;

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
