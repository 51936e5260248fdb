//! The noise model beside the dynamics: an autoregressive model `D(q) v[k] = e[k]` of what the
//! dynamics leave, `v = y - G u`, with `e` white (a Box-Jenkins structure whose noise
//! numerator is 1). Owns its estimate (Levinson-Durbin on the residual's autocorrelation, the
//! order by Akaike's criterion) and the one-step-ahead prediction error it gives,
//! `eps = D(q) (y - G u)`: for white residuals `D = 1` and that error is the simulation
//! error; for coloured ones it is the part of the error no predictor can remove.

use serde::{Deserialize, Serialize};

use crate::fit::model::PredictionFloor;

/// Highest order tried for the AR model of a channel's own noise, read in its quiet segment.
pub const MAX_NOISE_ORDER: usize = 4;

/// Highest order tried for the noise model of what the dynamics leave, `v = y - G u`, that
/// the `coloured-noise` effect fits (the default fit's Box-Jenkins alternation keeps
/// [`MAX_NOISE_ORDER`]). With noise on the reference, `v` carries that noise through the
/// probe, and its spectrum `S_y + |G|^2 S_u` has a narrow peak at each of a resonant probe's
/// modes: whitening it takes an order of about twice the modes' count beside the probe
/// noise's own. Akaike's criterion picks the order below this. Over the coloured noises the
/// bench draws, an order of 4 left the one-step-ahead prediction error of 7 % of them 1.15x to
/// 1.67x above its floor; 32 leaves 5 % there, at most 1.48x.
pub const MAX_RESIDUAL_ORDER: usize = 32;

/// Highest order of the AR model of what colour a whitened residual keeps, for the
/// parameters' covariance ([`crate::fit::covariance::covariance_coloured`]): long enough for the
/// ringing that the reference's noise leaves through a resonant probe.
pub const MAX_COLOUR_ORDER: usize = 32;

/// An AR noise model: `v[k] + d1 v[k-1] + ... + dp v[k-p] = e[k]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ArNoise {
    /// `[d1..dp]` (empty: white).
    pub ar: Vec<f64>,
    /// Standard deviation of the white innovation `e`.
    pub innovation_std: f64,
    /// Standard deviation of `v` itself.
    pub std: f64,
}

/// Fits an AR model of order `0..=max_order` to `v` (its mean removed), the order chosen by
/// Akaike's criterion `N ln(sigma_p^2) + 2p`.
#[must_use]
pub fn fit(v: &[f64], max_order: usize) -> ArNoise {
    let n = v.len();
    if n < 4 * (max_order + 1) {
        return ArNoise {
            ar: Vec::new(),
            innovation_std: rms(v),
            std: rms(v),
        };
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    let x: Vec<f64> = v.iter().map(|a| a - mean).collect();
    // Biased autocorrelation: its Toeplitz matrix is positive definite, so Levinson-Durbin
    // gives a stable model at every order.
    let r: Vec<f64> = (0..=max_order)
        .map(|lag| {
            x.iter()
                .zip(x.iter().skip(lag))
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / n as f64
        })
        .collect();
    let r0 = r.first().copied().unwrap_or(0.0);
    if r0 <= 0.0 {
        return ArNoise {
            ar: Vec::new(),
            innovation_std: 0.0,
            std: 0.0,
        };
    }
    let mut best = (n as f64 * r0.ln(), Vec::new(), r0);
    let mut a: Vec<f64> = Vec::new();
    let mut power = r0;
    for p in 1..=max_order {
        // Reflection coefficient of order p.
        let acc = r.get(p).copied().unwrap_or(0.0)
            + a.iter()
                .enumerate()
                .map(|(i, ai)| ai * r.get(p - 1 - i).copied().unwrap_or(0.0))
                .sum::<f64>();
        let k = -acc / power;
        if !k.is_finite() || k.abs() >= 1.0 {
            break;
        }
        let previous = a.clone();
        a.push(k);
        for (i, ai) in a.iter_mut().enumerate().take(p - 1) {
            *ai += k * previous.get(p - 2 - i).copied().unwrap_or(0.0);
        }
        power *= 1.0 - k * k;
        let aic = n as f64 * power.ln() + 2.0 * p as f64;
        if aic < best.0 {
            best = (aic, a.clone(), power);
        }
    }
    ArNoise {
        ar: best.1,
        innovation_std: best.2.max(0.0).sqrt(),
        std: r0.sqrt(),
    }
}

/// The variance of the mean of `x`, its samples correlated as the AR model of order up to
/// [`MAX_NOISE_ORDER`] fitted to them says: the spectral density at zero frequency over the
/// length, `sigma_e^2 / (n D(1)^2)`, which is `var / n` for white samples and larger for
/// low-frequency noise (an AR(1) of pole 0.9 gives 19 times `var / n`). Never more than the
/// samples' own variance; 0 for fewer than two samples.
#[must_use]
pub fn variance_of_mean(x: &[f64]) -> f64 {
    if x.len() < 2 {
        return 0.0;
    }
    let n = x.len() as f64;
    let model = fit(x, MAX_NOISE_ORDER);
    let var = model.std * model.std;
    let d1 = 1.0 + model.ar.iter().sum::<f64>();
    let at_zero = model.innovation_std * model.innovation_std / (d1 * d1).max(1e-12);
    (at_zero / n).min(var)
}

/// The part of a channel's noise no predictor removes: the innovation standard deviation of
/// the AR model fitted to its quiet segment (the first `quiet` samples, detrended; pass
/// [`crate::fit::step::quiet_until`] of the reference). This is the floor of a one-step-ahead
/// prediction error, as the noise's standard deviation is the floor of a simulation error:
/// `exp` of the mean log spectrum (Kolmogorov-Szego), which an AR model of rising order
/// approaches from above. For white noise it is the standard deviation; for a slow AR(1) of
/// pole 0.9 and ten times the white level it is 4.6 times the white level where the spectrum's
/// highest frequencies say 2.5 and the standard deviation 10. `None` without a quiet segment
/// of 64 samples (a traverse).
#[must_use]
pub fn innovation_floor(x: &[f64], quiet: usize) -> Option<f64> {
    of_quiet_segment(x, quiet).map(|m| m.innovation_std)
}

/// The AR model (order up to [`MAX_NOISE_ORDER`]) of a channel's quiet segment, the first
/// `quiet` samples detrended: its noise alone, the signal still. `None` below
/// [`crate::fit::step::MIN_QUIET`] samples (a traverse).
#[must_use]
pub fn of_quiet_segment(x: &[f64], quiet: usize) -> Option<ArNoise> {
    let pre = x
        .get(..quiet)
        .filter(|p| p.len() >= crate::fit::step::MIN_QUIET)?;
    Some(fit(&crate::fit::step::detrend(pre), MAX_NOISE_ORDER))
}

/// How much of a channel's noise a predictor removes: the standard deviation of its quiet
/// segment (the first `quiet` samples, detrended) over the innovation's of its AR model
/// ([`innovation_floor`]). About 1 for white noise (1.00 to 1.05 on 200 samples); an AR(1) of
/// pole 0.9 gives 2.3. `None` without a quiet segment of 64 samples.
#[must_use]
pub fn predictability(x: &[f64], quiet: usize) -> Option<f64> {
    let model = of_quiet_segment(x, quiet)?;
    (model.innovation_std > 0.0).then(|| model.std / model.innovation_std)
}

/// The probe's [`predictability`] before the step of the first test that has a quiet
/// segment (the estimation test first: one probe, one noise); `None` where none has one.
#[must_use]
pub fn probe_predictability(tests: &[crate::fit::Test<'_>]) -> Option<f64> {
    tests
        .iter()
        .find_map(|t| predictability(t.y, crate::fit::step::quiet_until(t.u)))
}

impl ArNoise {
    /// Its power spectral density at `w` radians per sample, in units where white noise of
    /// variance `v` has `v` at every frequency: `innovation_std^2 / |D(e^jw)|^2`.
    #[must_use]
    pub fn spectrum(&self, w: f64) -> f64 {
        // D(z) = 1 + z^-1 (d1 + d2 z^-1 + ...), without building [1, d1, ...] at each w.
        let z = crate::poly::Complex::new(w.cos(), w.sin());
        let one = crate::poly::Complex::new(1.0, 0.0);
        let den = (one + crate::poly::eval(&self.ar, z) / z).norm_sqr();
        self.innovation_std * self.innovation_std / den.max(1e-300)
    }
}

/// Frequencies a floor's spectrum is averaged over (midpoints on `(0, pi)`).
const FLOOR_GRID: usize = 2048;

/// The part of what a correct model leaves, `y - G u = n_y - G n_u`, that no predictor
/// removes, where both channels are noisy: the probe's noise `probe` and the reference's
/// `reference` through the model (errors in variables). By Kolmogorov and Szego, the
/// innovation variance of a noise of spectrum `S` is `exp` of the mean of `ln S` over the
/// frequencies, here `S = S_probe + |G|^2 S_reference`. Without the reference's noise it is
/// the probe's innovation ([`innovation_floor`]); a flush probe (`|G|` near 1 over the band)
/// with white noise of equal level on both channels has `sqrt(2)` times it.
#[must_use]
pub fn both_channels_innovation(
    probe: &ArNoise,
    reference: Option<&ArNoise>,
    model: &crate::fit::Model,
) -> f64 {
    let Some(reference) = reference.filter(|r| r.innovation_std > 0.0) else {
        return probe.innovation_std;
    };
    let mean_log = (0..FLOOR_GRID)
        .map(|i| {
            let w = std::f64::consts::PI * (i as f64 + 0.5) / FLOOR_GRID as f64;
            let g = crate::fit::analysis::response(model, w * model.fs / std::f64::consts::TAU);
            (probe.spectrum(w) + g.norm_sqr() * reference.spectrum(w))
                .max(1e-300)
                .ln()
        })
        .sum::<f64>()
        / FLOOR_GRID as f64;
    let floor = (0.5 * mean_log).exp();
    if floor.is_finite() {
        floor.max(probe.innovation_std)
    } else {
        probe.innovation_std
    }
}

/// Each test's [`PredictionFloor`] under `model`: the part of both channels' noise no
/// predictor removes ([`both_channels_innovation`]), each channel's noise read in the test's
/// own quiet segment, else in the first test's that has one (the same sensors), over the
/// test's range; `None` where no test has a quiet segment or the probe does not move.
#[must_use]
pub fn prediction_floors(
    tests: &[crate::fit::Test<'_>],
    model: &crate::fit::Model,
) -> Vec<Option<PredictionFloor>> {
    let own: Vec<Option<f64>> = tests
        .iter()
        .map(|t| {
            let quiet = crate::fit::step::quiet_until(t.u);
            let probe = of_quiet_segment(t.y, quiet)?;
            let reference = of_quiet_segment(t.u, quiet);
            Some(both_channels_innovation(&probe, reference.as_ref(), model))
        })
        .collect();
    let borrowed = tests
        .iter()
        .zip(&own)
        .find_map(|(t, f)| f.map(|f| (t.name, f)));
    tests
        .iter()
        .zip(&own)
        .map(|(t, f)| {
            let (from, pa) = f.map(|f| (t.name, f)).or(borrowed)?;
            let range = crate::fit::range(t.y);
            (range > 0.0).then(|| PredictionFloor {
                value: pa / range,
                from: from.to_string(),
            })
        })
        .collect()
}

/// `D(q) x`: the one-step-ahead prediction error of `x` under the noise model (the first `p`
/// samples use the samples there are).
#[must_use]
pub fn whiten(ar: &[f64], x: &[f64]) -> Vec<f64> {
    let d: Vec<f64> = std::iter::once(1.0).chain(ar.iter().copied()).collect();
    crate::fit::model::filter(&d, &[], 0, x)
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|a| a * a).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// `Σ_i (a[i] − ma)(b[i+k] − mb)` over `i < a.len()`, `i + k < b.len()` for `k` in `0..lags`
/// (for signals of one length `n`: over `i + k < n`), by FFT block by
/// block (overlap-save): each block of `a` against the stretch of `b` it reaches, in one
/// transform size, so the work is `O(n log lags)` and the memory `O(lags)` beside the signals,
/// not `O(n lags)` as the direct sums are.
pub(crate) fn lagged_products(a: &[f64], b: &[f64], (ma, mb): (f64, f64), lags: usize) -> Vec<f64> {
    // `a` is taken whole, `b` as far as it goes (the sum stops at `i + k < b.len()`).
    let (n, nb) = (a.len(), b.len());
    let mut out = vec![0.0; lags];
    if lags == 0 || n == 0 {
        return out;
    }
    let nfft = (4 * lags).max(4096).next_power_of_two();
    let block = nfft - lags;
    let mut planner = rustfft::FftPlanner::new();
    let (forward, inverse) = (
        planner.plan_fft_forward(nfft),
        planner.plan_fft_inverse(nfft),
    );
    let mut x = vec![rustfft::num_complex::Complex64::new(0.0, 0.0); nfft];
    let mut spectrum = vec![rustfft::num_complex::Complex64::new(0.0, 0.0); nfft];
    let mut start = 0;
    while start < n {
        let end = (start + block).min(n);
        let reach = (start + nfft).min(nb);
        // a's block in the real part, b's stretch in the imaginary part: one transform.
        for (j, v) in x.iter_mut().enumerate() {
            let i = start + j;
            let re = if i < end { a[i] - ma } else { 0.0 };
            let im = if i < reach { b[i] - mb } else { 0.0 };
            *v = rustfft::num_complex::Complex64::new(re, im);
        }
        forward.process(&mut x);
        // A = (X_k + conj X_{-k})/2, B = (X_k − conj X_{-k})/(2i); conj(A)·B.
        for (k, s) in spectrum.iter_mut().enumerate() {
            let (xk, xm) = (x[k], x[(nfft - k) % nfft].conj());
            let fa = 0.5 * (xk + xm);
            let fb = rustfft::num_complex::Complex64::new(0.0, -0.5) * (xk - xm);
            *s = fa.conj() * fb;
        }
        inverse.process(&mut spectrum);
        let scale = 1.0 / nfft as f64;
        for (o, c) in out.iter_mut().zip(&spectrum) {
            *o += c.re * scale;
        }
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_of_correlated_noise_is_less_sure_than_of_white() {
        // AR(1) of pole 0.9: the variance of the mean of n samples is about
        // var (1 + 0.9) / (1 - 0.9) / n, nineteen times the white formula.
        let n = 20_000;
        let e = crate::testing::gaussian(n, 5);
        let mut v = Vec::with_capacity(n);
        let mut s = 0.0;
        for x in &e {
            s = 0.9 * s + x;
            v.push(s);
        }
        let var = v.iter().map(|x| x * x).sum::<f64>() / n as f64;
        let ratio = variance_of_mean(&v) / (var / n as f64);
        assert!((ratio / 19.0 - 1.0).abs() < 0.2, "{ratio}");
        let white = variance_of_mean(&e) / (1.0 / n as f64);
        assert!((white - 1.0).abs() < 0.1, "{white}");
        assert_eq!(variance_of_mean(&[1.0]), 0.0);
    }

    #[test]
    fn lagged_products_by_blocks_are_the_direct_sums() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (n, lags) in [(50_001usize, 2000usize), (9_000, 7), (100, 100), (3, 1)] {
            let a: Vec<f64> = (0..n).map(|_| next()).collect();
            let b: Vec<f64> = (0..n)
                .map(|i| next() + 0.3 * a[i.saturating_sub(5)])
                .collect();
            let (ma, mb) = (0.01, -0.02);
            let fast = lagged_products(&a, &b, (ma, mb), lags);
            assert_eq!(fast.len(), lags);
            for (k, f) in fast.iter().enumerate() {
                let direct: f64 = (0..n - k).map(|i| (a[i] - ma) * (b[i + k] - mb)).sum();
                assert!(
                    (f - direct).abs() < 1e-9 * (n as f64),
                    "n {n} lag {k}: {f} against {direct}"
                );
            }
        }
    }

    fn white(n: usize, seed: u64) -> Vec<f64> {
        crate::testing::gaussian(n, seed)
    }

    /// A model of order 1 at 10 kHz: `G = b0 / (1 - p q^-1)`, unit DC gain.
    fn lowpass(p: f64) -> crate::fit::Model {
        crate::fit::Model {
            fs: 10_000.0,
            delay: 3,
            a: vec![-p],
            b: vec![1.0 - p, 0.0],
        }
    }

    #[test]
    fn both_channels_noise_raises_the_prediction_floor_as_the_spectra_say() {
        let white_noise = |std: f64| ArNoise {
            ar: Vec::new(),
            innovation_std: std,
            std,
        };
        let probe = white_noise(1.0);
        // No reference noise: the probe's innovation.
        assert_eq!(both_channels_innovation(&probe, None, &lowpass(0.5)), 1.0);
        // A flush probe (G = 1, its delay aside) with equal white noise on both channels: the
        // sum is white of twice the variance.
        let flush = lowpass(0.0);
        let f = both_channels_innovation(&probe, Some(&white_noise(1.0)), &flush);
        assert!((f - 2f64.sqrt()).abs() < 1e-9, "{f}");
        // A slow probe passes the reference's noise at low frequencies only: the floor is
        // exp of the mean log of 1 + |G|^2, integrated here on a fine grid.
        let p = 0.9;
        let grid = 200_000;
        let mean_log = (0..grid)
            .map(|i| {
                let w = std::f64::consts::PI * (i as f64 + 0.5) / grid as f64;
                let g2 = (1.0 - p) * (1.0 - p) / (1.0 - 2.0 * p * w.cos() + p * p);
                (1.0 + g2).ln()
            })
            .sum::<f64>()
            / grid as f64;
        let truth = (0.5 * mean_log).exp();
        let f = both_channels_innovation(&probe, Some(&white_noise(1.0)), &lowpass(p));
        assert!((f / truth - 1.0).abs() < 1e-4, "{f} against {truth}");
        assert!(f > 1.0 && f < 2f64.sqrt(), "{f}");
        // A predictable (coloured) probe noise: its innovation, raised by the reference's.
        let coloured = ArNoise {
            ar: vec![-0.9],
            innovation_std: 0.5,
            std: 0.5 / (1.0f64 - 0.81).sqrt(),
        };
        let alone = both_channels_innovation(&coloured, None, &flush);
        let with = both_channels_innovation(&coloured, Some(&white_noise(0.5)), &flush);
        assert_eq!(alone, 0.5);
        assert!(with > alone && with < coloured.std, "{with}");
    }

    #[test]
    fn the_prediction_floor_reads_both_channels_before_the_step() {
        // A flush probe, white noise of 1 on the probe and 1 on the reference before a step of
        // 1000 at sample 3000: the floor is about sqrt(2) over the range.
        let n = 3_000;
        let (ny, nu) = (white(n, 31), white(n, 32));
        let mut u: Vec<f64> = nu.clone();
        u.extend(std::iter::repeat_n(1000.0, 2_000));
        let mut y: Vec<f64> = ny.clone();
        y.extend(std::iter::repeat_n(1000.0, 2_000));
        let test = crate::fit::Test {
            name: "step.csv",
            u: &u,
            y: &y,
        };
        let range = crate::fit::range(&y);
        let both = prediction_floors(&[test], &lowpass(0.0));
        let Some(Some(floor)) = both.first() else {
            panic!("{both:?}")
        };
        assert_eq!(floor.from, "step.csv");
        let ratio = floor.value * range / 2f64.sqrt();
        assert!((ratio - 1.0).abs() < 0.06, "{ratio}");
        // The reference's quiet: the probe's alone.
        let still: Vec<f64> = std::iter::repeat_n(0.0, n)
            .chain(std::iter::repeat_n(1000.0, 2_000))
            .collect();
        let test = crate::fit::Test { u: &still, ..test };
        let alone = prediction_floors(&[test], &lowpass(0.0));
        let value = alone.first().cloned().flatten().map_or(0.0, |f| f.value);
        assert!((value * range - 1.0).abs() < 0.06, "{value}");
    }

    /// What the dynamics leave behind a probe of three modes (0.5, 1.4 and 2.3 kHz, damping
    /// 0.01, at 10 kHz) with white noise on the reference and a slow AR(1) noise on the probe:
    /// the residual noise model whitens it to its floor (1.00x here), which a model of the
    /// order of a channel's own noise cannot (1.56x).
    #[test]
    fn the_residual_noise_model_whitens_a_noisy_reference_through_a_resonant_probe() {
        use crate::poly::times;
        let mut g = crate::testing::second_order(500.0, 0.01, 10_000.0, 2).0;
        for f in [1_400.0, 2_300.0] {
            let m = crate::testing::second_order(f, 0.01, 10_000.0, 0).0;
            let a = times(&[&[1.0][..], &g.a].concat(), &[1.0, m.a[0], m.a[1]]);
            g.a = a[1..].to_vec();
            g.b = times(&g.b, &m.b);
        }
        let n = 40_000;
        let reference_noise = white(n, 41);
        let through = g.simulate(&reference_noise);
        let mut s = 0.0;
        let v: Vec<f64> = white(n, 42)
            .iter()
            .zip(&through)
            .map(|(e, t)| {
                s = 0.95 * s + 0.2 * e;
                s - t
            })
            .collect();
        let probe = ArNoise {
            ar: vec![-0.95],
            innovation_std: 0.2,
            std: 0.2 / (1.0f64 - 0.95 * 0.95).sqrt(),
        };
        let reference = ArNoise {
            ar: Vec::new(),
            innovation_std: 1.0,
            std: 1.0,
        };
        let floor = both_channels_innovation(&probe, Some(&reference), &g);
        let residual = fit(&v, MAX_RESIDUAL_ORDER);
        let own = fit(&v, MAX_NOISE_ORDER);
        let (got, short) = (residual.innovation_std / floor, own.innovation_std / floor);
        assert!(got < 1.1 && got > 0.9, "{got}, order {}", residual.ar.len());
        assert!(short > 1.3, "{short} {got}");
    }

    #[test]
    fn an_ar2_process_is_recovered() {
        // v[k] = 1.5 v[k-1] - 0.7 v[k-2] + e[k]: D = [-1.5, 0.7].
        let e = white(20_000, 3);
        let mut v = vec![0.0; e.len()];
        for k in 0..e.len() {
            let v1 = if k >= 1 { v[k - 1] } else { 0.0 };
            let v2 = if k >= 2 { v[k - 2] } else { 0.0 };
            v[k] = 1.5 * v1 - 0.7 * v2 + e[k];
        }
        let m = fit(&v, MAX_NOISE_ORDER);
        assert!(m.ar.len() >= 2, "{m:?}");
        assert!(
            (m.ar[0] + 1.5).abs() < 0.03 && (m.ar[1] - 0.7).abs() < 0.03,
            "{m:?}"
        );
        assert!((m.innovation_std - 1.0).abs() < 0.03, "{m:?}");
        // Whitening gives back the innovation.
        let w = whiten(&m.ar, &v);
        assert!((rms(&w[10..]) - 1.0).abs() < 0.03);
    }

    #[test]
    fn white_noise_gets_no_model() {
        let m = fit(&white(5_000, 9), MAX_NOISE_ORDER);
        assert!(m.ar.len() <= 1, "{m:?}");
        assert!(m.ar.iter().all(|d| d.abs() < 0.05), "{m:?}");
        assert!((m.innovation_std / m.std - 1.0).abs() < 0.01);
    }

    #[test]
    fn the_innovation_floor_is_what_the_spectrum_leaves_a_predictor() {
        // White noise of std 1 plus an AR(1) of pole 0.9 whose own std is 10, before a step
        // at sample 4000: the floor is exp(mean ln S) ^ 1/2 of the spectrum
        // S(w) = 1 + 100 (1 - 0.81) / |1 - 0.9 e^-iw|^2, integrated here on a grid.
        let (rho, ratio, n) = (0.9f64, 10.0f64, 4_000);
        let grid = 100_000;
        let mean_log = (0..grid)
            .map(|i| {
                let w = std::f64::consts::PI * (i as f64 + 0.5) / grid as f64;
                let den = 1.0 - 2.0 * rho * w.cos() + rho * rho;
                (1.0 + ratio * ratio * (1.0 - rho * rho) / den).ln()
            })
            .sum::<f64>()
            / grid as f64;
        let truth = (0.5 * mean_log).exp();
        let (w, e) = (white(n, 21), white(n, 22));
        let mut ar = 0.0;
        let mut x: Vec<f64> = w
            .iter()
            .zip(&e)
            .map(|(w, e)| {
                ar = rho * ar + ratio * (1.0 - rho * rho).sqrt() * e;
                w + ar
            })
            .collect();
        x.extend(std::iter::repeat_n(1000.0, 500));
        let floor = innovation_floor(&x, n).unwrap_or(0.0);
        assert!(
            (floor / truth - 1.0).abs() < 0.08,
            "{floor} against {truth}"
        );
        // Far from the white level the spectrum's top shows, and from the std.
        assert!(floor > 1.5 * 2.5 && floor < 0.6 * ratio, "{floor}");
        // White noise: its std; no quiet segment: none.
        let white_floor = innovation_floor(&w, n).unwrap_or(0.0);
        assert!((white_floor - 1.0).abs() < 0.05, "{white_floor}");
        assert_eq!(innovation_floor(&x, 63), None);
    }

    #[test]
    fn white_noise_is_not_predictable_and_a_slow_noise_is() {
        // An AR(1) of pole 0.9: its std over its innovation's is 1 / sqrt(1 - 0.81) = 2.29.
        let e = white(4_000, 31);
        let mut s = 0.0;
        let slow: Vec<f64> = e
            .iter()
            .map(|x| {
                s = 0.9 * s + x;
                s
            })
            .collect();
        let p = predictability(&slow, slow.len()).unwrap_or(0.0);
        assert!((p / 2.29 - 1.0).abs() < 0.05, "{p}");
        // White noise on the 200 samples a quiet segment often has: below the diagnosis'
        // threshold of 1.15 for every draw, as a white probe noise is (1.00 to 1.05).
        for seed in 0..40 {
            let w = white(200, 100 + seed);
            let p = predictability(&w, w.len()).unwrap_or(f64::INFINITY);
            assert!(p < 1.1, "seed {seed}: {p}");
        }
        // No quiet segment of 64 samples: unknown.
        assert_eq!(predictability(&slow, 63), None);
    }
}
