//! Where a model fails on a test: the residual `y - y_model` and the evidence in it.
//!
//! This module owns [`TestEvidence`]: fit % and normalised RMS against the noise floor, the
//! residual's autocorrelation with its 99 % band and the Ljung-Box statistic, its
//! cross-correlation with the input's increments, its spectrum with the significant peaks, and
//! its level and trend before the step and at the end of the record. It measures; naming the
//! missing effect from these numbers is [`crate::modelling::diagnose`]'s job.
//!
//! Both channels are sensors: a correct model leaves the residual `n_y - G n_u`, the probe's
//! noise plus the reference's noise through the model, whose spectrum
//! `sigma_y^2 + |G|^2 sigma_u^2` is coloured below the probe's corner ([`ExpectedResidual`]).
//! The noise floor, the whiteness test and the bands are judged against that, not against
//! white noise.

use rustfft::num_complex::Complex64;
use rustfft::FftPlanner;
use serde::Serialize;

use crate::fit::model::{Model, PredictionFloor, TestRole};
use crate::fit::step;
use crate::fit::step::NoiseSource;

mod correlation;
pub use correlation::{autocorrelation, autocorrelation_against, chi2_survival, cross_correlation};

/// Lags of the residual autocorrelation examined (and degrees of freedom of Ljung-Box).
pub const ACF_LAGS: usize = 30;

/// Two-sided 99 % quantile of the normal distribution: the band `+-Z99 / sqrt(N)`.
pub const Z99: f64 = 2.575_829_303_548_901;

/// A spectral peak counts when it stands this far above the floor (dB).
pub const PEAK_DB: f64 = 10.0;

/// The residual's autocorrelation, against the one a correct model leaves.
#[derive(Debug, Clone, Serialize)]
pub struct Autocorrelation {
    /// `rho(k)` for `k = 1..=ACF_LAGS`.
    pub values: Vec<f64>,
    /// What a correct model leaves, `rho_0(k)` ([`ExpectedResidual::acf`]; zeros for white).
    pub expected: Vec<f64>,
    /// 99 % half-width of `rho(k) - rho_0(k)`: `Z99 sqrt(c / N)`, `c` the expected residual's
    /// Bartlett factor (1 for white noise).
    pub band: f64,
    /// How many lags fall outside the band around the expected values.
    pub outside: usize,
    /// Ljung-Box on the departures, `Q = N (N + 2) sum (rho(k) - rho_0(k))^2 / (N - k) / c`.
    pub ljung_box: f64,
    /// Its p-value when the residual is the expected noise (chi-square with `ACF_LAGS`
    /// degrees of freedom).
    pub p_value: f64,
}

/// The residual a correct model leaves on a test: `n_y - G n_u`, white probe noise plus the
/// reference's white noise through the model.
#[derive(Debug, Clone, Serialize)]
pub struct ExpectedResidual {
    /// The probe's noise (standard deviation).
    pub probe_std: f64,
    /// The reference's noise.
    pub reference_std: f64,
    /// Where both were measured: the quiet segment before the step, or the record's highest
    /// frequencies when it has none (a wake traverse).
    pub source: NoiseSource,
    /// RMS of `n_y - G n_u`: `sqrt(sigma_y^2 + sigma_u^2 sum g_k^2)`.
    pub std: f64,
    /// Its autocorrelation at lags `1..=ACF_LAGS`.
    pub acf: Vec<f64>,
    /// Bartlett's factor `sum_k rho_0(k)^2` over all lags: how much wider the scatter of a
    /// sample autocorrelation of this noise is than of white noise's.
    pub bartlett: f64,
    /// `1 + 2 sum_k rho_0(k)`: a mean of `m` samples of this noise scatters like one of
    /// `m / factor` white samples (at least 1).
    pub mean_factor: f64,
}

impl ExpectedResidual {
    /// Standard error of a mean of `samples` consecutive residual samples of this noise.
    #[must_use]
    pub fn mean_se(&self, samples: usize) -> f64 {
        self.std * (self.mean_factor / samples.max(1) as f64).min(1.0).sqrt()
    }

    /// Standard error (units per second) of the slope of a straight line fitted to `samples`
    /// consecutive residual samples of this noise at `fs`: `std sqrt(12 / (n (n^2 - 1))) fs`,
    /// widened as a mean is for correlated noise. Infinite below three samples.
    #[must_use]
    pub fn slope_se(&self, samples: usize, fs: f64) -> f64 {
        if samples < 3 {
            return f64::INFINITY;
        }
        let n = samples as f64;
        self.std * self.mean_factor.max(1.0).sqrt() * (12.0 / (n * (n * n - 1.0))).sqrt() * fs
    }
}

/// The residual `model` leaves on `(u, y)` when it is right: both channels' noise measured
/// ([`step::channel_noise`], the quiet segment ending at `quiet`), the reference's passed
/// through the model's impulse response.
#[must_use]
pub fn expected_residual(model: &Model, u: &[f64], y: &[f64], quiet: usize) -> ExpectedResidual {
    let (probe_std, ps) = step::channel_noise(y, quiet);
    let (reference_std, rs) = step::channel_noise(u, quiet);
    let source = if ps == NoiseSource::PreStep && rs == NoiseSource::PreStep {
        NoiseSource::PreStep
    } else {
        NoiseSource::HighFrequency
    };
    // The model's impulse response (the delay does not change an autocorrelation).
    let len = u.len().clamp(64, 1 << 16);
    let mut impulse = vec![0.0; len];
    impulse[1] = 1.0;
    let g = model.simulate_from(&impulse, 0.0);
    // sum_j g_j g_(j+k) for every k, by FFT.
    let nfft = (2 * g.len()).next_power_of_two();
    let mut buf: Vec<Complex64> = g.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    buf.resize(nfft, Complex64::new(0.0, 0.0));
    let mut planner = FftPlanner::new();
    planner.plan_fft_forward(nfft).process(&mut buf);
    buf.iter_mut()
        .for_each(|c| *c = Complex64::new(c.norm_sqr(), 0.0));
    planner.plan_fft_inverse(nfft).process(&mut buf);
    let (su2, sy2) = (reference_std * reference_std, probe_std * probe_std);
    let cov: Vec<f64> = buf[..g.len()]
        .iter()
        .enumerate()
        .map(|(k, c)| su2 * c.re / nfft as f64 + if k == 0 { sy2 } else { 0.0 })
        .collect();
    let c0 = cov.first().copied().unwrap_or(0.0);
    let rho: Vec<f64> = if c0 > 0.0 {
        cov.iter().map(|c| c / c0).collect()
    } else {
        vec![1.0]
    };
    let bartlett = 1.0 + 2.0 * rho.iter().skip(1).map(|r| r * r).sum::<f64>();
    let mean_factor = (1.0 + 2.0 * rho.iter().skip(1).sum::<f64>()).max(1.0);
    ExpectedResidual {
        probe_std,
        reference_std,
        source,
        std: c0.max(0.0).sqrt(),
        acf: (1..=ACF_LAGS)
            .map(|k| rho.get(k).copied().unwrap_or(0.0))
            .collect(),
        bartlett,
        mean_factor,
    }
}

/// The residual's cross-correlation with the input increments `u[k] - u[k-1]`.
#[derive(Debug, Clone, Serialize)]
pub struct CrossCorrelation {
    /// Normalised cross-correlation at lags `0..values.len()` (residual after input).
    pub values: Vec<f64>,
    /// 99 % band when the residual does not depend on the input: `Z99 sqrt(c / N)`, `c`
    /// Bartlett's factor of the two series' autocorrelations (1 when either is white).
    pub band: f64,
    /// Lag of the largest magnitude.
    pub peak_lag: usize,
    /// Its value.
    pub peak: f64,
}

/// A significant peak of the residual spectrum.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Peak {
    /// Frequency (Hz).
    pub frequency_hz: f64,
    /// Height above the floor (dB).
    pub above_floor_db: f64,
    /// Quality factor: frequency / width at half power.
    pub q: f64,
}

/// The residual's spectrum after the step.
#[derive(Debug, Clone, Serialize)]
pub struct Spectrum {
    /// Bin spacing (Hz).
    pub resolution_hz: f64,
    /// Power spectral density (dB, arbitrary reference), bins `0..`.
    pub psd_db: Vec<f64>,
    /// The floor: median of the density (dB), against the expected shape.
    pub floor_db: f64,
    /// What the noise a correct model leaves would give, bins `0..` (dB, the floor's level):
    /// flat for white noise, raised below the probe's corner by the reference's noise.
    pub expected_db: Vec<f64>,
    /// Significant peaks, highest first.
    pub peaks: Vec<Peak>,
}

/// The model-error spectrum `20 log10 |FFT(diff y)| / |FFT(diff y_model)|`: where the model's
/// frequency response departs from the measured one (a step's increments have a flat
/// spectrum, so this is the ratio of the two frequency responses). Only bins where the model's
/// response stands 10 dB above the noise are kept.
#[derive(Debug, Clone, Serialize)]
pub struct ModelError {
    /// Bin spacing (Hz).
    pub resolution_hz: f64,
    /// Highest frequency where the ratio is trusted (Hz).
    pub valid_to_hz: f64,
    /// The ratio in dB, bins `0..` up to `valid_to_hz`.
    pub db: Vec<f64>,
    /// Peaks of the ratio at least [`MODEL_ERROR_PEAK_DB`] above its median, highest first.
    pub peaks: Vec<Peak>,
}

/// A model-error peak counts from this height (dB) above the ratio's median.
pub const MODEL_ERROR_PEAK_DB: f64 = 2.0;

/// Longest segment one spectrum transforms at once: a longer record is cut into equal segments
/// no longer than this, whose periodograms are averaged (Bartlett's method). Up to this length
/// the spectrum is the record's own; beyond it memory stays bounded and the resolution is that of
/// a record of this length, while a transient keeps its ratio to the noise (both fall with the
/// record's length as they would in one long transform).
pub const SPECTRUM_SEGMENT: usize = 1 << 20;

/// How a record of `n` samples is cut for its spectrum.
#[derive(Debug, Clone, Copy)]
struct Segments {
    /// Samples per segment (the last may be shorter).
    len: usize,
    /// Number of segments, as the averaging divisor.
    count: f64,
    /// Transform length: twice the segment, to a power of two (zero padding).
    nfft: usize,
}

impl Segments {
    fn of(n: usize) -> Self {
        let count = n.div_ceil(SPECTRUM_SEGMENT).max(1);
        let len = n.div_ceil(count).max(1);
        Self {
            len,
            count: n.div_ceil(len).max(1) as f64,
            nfft: (2 * len).next_power_of_two(),
        }
    }
}

/// The model-error spectrum of a test (see [`ModelError`]).
#[must_use]
pub fn model_error(y: &[f64], y_model: &[f64], noise_std: f64, fs: f64) -> ModelError {
    let n = y.len().min(y_model.len()).max(2);
    let plan = Segments::of(n);
    let nfft = plan.nfft;
    // The increments' powers, both signals in one transform (y real, the model imaginary):
    // for a real pair, Y_k = (Z_k + conj Z_(N-k)) / 2 and M_k = (Z_k - conj Z_(N-k)) / 2i.
    let increment = |x: &[f64], i: usize| match i {
        0 => 0.0,
        _ => x.get(i).copied().unwrap_or(0.0) - x.get(i - 1).copied().unwrap_or(0.0),
    };
    let half = nfft / 2;
    let (mut fy, mut fm) = (vec![0.0; half + 1], vec![0.0; half + 1]);
    let mut buf = vec![Complex64::new(0.0, 0.0); nfft];
    let fft = FftPlanner::new().plan_fft_forward(nfft);
    for start in (0..n).step_by(plan.len) {
        let end = (start + plan.len).min(n);
        buf.iter_mut().enumerate().for_each(|(j, c)| {
            *c = if start + j < end {
                Complex64::new(increment(y, start + j), increment(y_model, start + j))
            } else {
                Complex64::new(0.0, 0.0)
            };
        });
        fft.process(&mut buf);
        for k in 0..=half {
            let (z, zc) = (buf[k], buf[(nfft - k) % nfft].conj());
            fy[k] += ((z + zc) * 0.5).norm_sqr() / plan.count;
            fm[k] += ((z - zc) * 0.5).norm_sqr() / plan.count;
        }
    }
    drop(buf);
    let resolution_hz = fs / nfft as f64;
    // Power averaged over 9 neighbouring bins (the zero padding correlates pairs of them):
    // the ratio's scatter from noise falls to a fraction of a dB where the model stands
    // 10 dB above the noise.
    let smooth = |p: &[f64]| -> Vec<f64> {
        (0..p.len())
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(4), (i + 5).min(p.len()));
                p[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
            })
            .collect()
    };
    let (py, pm) = (smooth(&fy), smooth(&fm));
    // White noise of std s gives increments of std s sqrt 2, and FFT powers near 2 n s^2 (n
    // the segment's length).
    let noise_power = 2.0 * plan.len as f64 * noise_std * noise_std;
    let valid = (1..pm.len())
        .take_while(|&i| pm[i] > 10.0 * noise_power)
        .last()
        .unwrap_or(0);
    let db: Vec<f64> = (0..=valid)
        .map(|i| {
            if i == 0 {
                0.0
            } else {
                10.0 * (py[i] / pm[i]).log10()
            }
        })
        .collect();
    let mut sorted: Vec<f64> = db.iter().skip(1).copied().collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let k = 6;
    let mut peaks: Vec<Peak> = (k..db.len().saturating_sub(k))
        .filter(|&i| {
            let v = db[i];
            v - median > MODEL_ERROR_PEAK_DB && (i - k..=i + k).all(|j| j == i || db[j] < v)
        })
        .map(|i| {
            let half = db[i] - 3.0;
            let lo = (0..i).rev().find(|&j| db[j] < half).unwrap_or(0);
            let hi = (i..db.len())
                .find(|&j| db[j] < half)
                .unwrap_or(db.len() - 1);
            let f = i as f64 * resolution_hz;
            Peak {
                frequency_hz: f,
                above_floor_db: db[i] - median,
                q: f / (((hi - lo) as f64) * resolution_hz).max(resolution_hz),
            }
        })
        .collect();
    peaks.sort_by(|a, b| b.above_floor_db.total_cmp(&a.above_floor_db));
    peaks.truncate(8);
    ModelError {
        resolution_hz,
        valid_to_hz: valid as f64 * resolution_hz,
        db,
        peaks,
    }
}

/// Level and trend of the residual before the step and at the end of the record.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Trend {
    /// Mean of the quiet segment before the step (NaN, `null` in JSON, for a record without
    /// one, such as a traverse).
    pub pre_mean: f64,
    /// Slope before the step (units per second).
    pub pre_slope_per_s: f64,
    /// Its standard error under the noise both channels leave (infinite without a segment
    /// before the step).
    pub pre_slope_se_per_s: f64,
    /// Mean of the last 30 % of the record.
    pub late_mean: f64,
    /// Slope over the last 30 % of the record (units per second).
    pub late_slope_per_s: f64,
    /// Slope of a straight line through the whole residual (units per second).
    pub slope_per_s: f64,
    /// Standard error of a mean of the noise over the pre-step segment (infinite without one).
    pub pre_mean_se: f64,
    /// Standard error of a mean of the noise over the late segment.
    pub late_mean_se: f64,
}

/// The one-step-ahead prediction error of a model with a noise model on a test, over its
/// range, and the floor of that error: what a noise model can be judged against, since the
/// simulation error it leaves is the noise itself.
#[derive(Debug, Clone, Serialize)]
pub struct PredictionError {
    /// RMS of `D(q) (y - G u)` / range(y).
    pub nrmse: f64,
    /// The innovation of both channels' noise through the model over range(y).
    pub floor: PredictionFloor,
}

/// Everything measured on one test.
#[derive(Debug, Clone, Serialize)]
pub struct TestEvidence {
    /// The test's file name.
    pub file: String,
    /// What the test was used for, written `estimation` or `validation`.
    pub role: TestRole,
    /// Samples.
    pub samples: usize,
    /// `100 (1 - |y - y_model| / |y - mean(y)|)`.
    pub fit_percent: f64,
    /// `RMS(y - y_model) / range(y)`.
    pub nrmse: f64,
    /// What a correct model leaves, RMS / range(y): both channels' noise
    /// ([`ExpectedResidual::std`]).
    pub noise_floor: f64,
    /// With a noise model, the error the model is judged by, the one-step-ahead prediction
    /// error, and its floor ([`TestEvidence::with_prediction`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prediction: Option<PredictionError>,
    /// Step onset (sample).
    pub step_onset: usize,
    /// Signed step size of the reference.
    pub step_size: f64,
    /// Probe noise standard deviation ([`ExpectedResidual::probe_std`]).
    pub noise_std: f64,
    /// The residual a correct model leaves, both channels' noise.
    pub expected: ExpectedResidual,
    /// Residual RMS over the record.
    pub residual_rms: f64,
    /// Residual autocorrelation.
    pub autocorrelation: Autocorrelation,
    /// Residual against the input.
    pub cross_correlation: CrossCorrelation,
    /// Residual spectrum after the step.
    pub spectrum: Spectrum,
    /// Model-error spectrum.
    pub model_error: ModelError,
    /// Residual level and trend.
    pub trend: Trend,
    /// The reference's own ringing after the step ([`reference_ringing`]), if any.
    pub reference_ringing: Option<Peak>,
}

/// A spectral peak at least this sharp (centre frequency over its -3 dB width) is a resonance:
/// a mode of damping below 0.25. A slow creep or a drift leaves a broad low-frequency hump
/// (Q about 1 or below) that can stand as far out of the floor.
pub const NARROW_PEAK_Q: f64 = 2.0;

/// The reference channel's own ringing: the highest narrow peak (Q at least [`NARROW_PEAK_Q`]) of the spectrum
/// of its increments from the step on. A clean step's increments are an impulse with a flat
/// spectrum; a transducer's diaphragm ringing in the reference makes a peak at its natural
/// frequency. A line or cavity mode of the probe never shows here. `None` for a record that
/// is not a step test ([`step::Step::is_clean`]).
#[must_use]
pub fn reference_ringing(u: &[f64], fs: f64) -> Option<Peak> {
    ringing_after(u, step::find_step(u).ok().as_ref(), fs)
}

/// [`reference_ringing`] with the reference's step already found.
fn ringing_after(u: &[f64], found: Option<&step::Step>, fs: f64) -> Option<Peak> {
    // Only after a step: the periodic content of a traverse is the flow's, not a diaphragm's.
    let onset = found.filter(|s| s.is_clean())?.onset;
    let du: Vec<f64> = u
        .get(onset.saturating_sub(2)..)?
        .windows(2)
        .map(|w| w[1] - w[0])
        .collect();
    if du.len() < 32 {
        return None;
    }
    spectrum(&du, fs)
        .peaks
        .into_iter()
        .find(|p| p.q >= NARROW_PEAK_Q)
}

fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// Slope of the least-squares line through `x` (per sample).
fn slope(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    if x.len() < 3 {
        return 0.0;
    }
    let tm = (n - 1.0) / 2.0;
    let xm = mean(x);
    let (mut num, mut den) = (0.0, 0.0);
    for (i, v) in x.iter().enumerate() {
        let t = i as f64 - tm;
        num += t * (v - xm);
        den += t * t;
    }
    num / den
}

/// Periodogram of `x` (mean removed, no taper), zero-padded to a power of two of at least
/// `2 len`, smoothed over 9 bins; the floor is the median bin; peaks are local maxima
/// [`PEAK_DB`] above it.
#[must_use]
pub fn spectrum(x: &[f64], fs: f64) -> Spectrum {
    spectrum_against(x, fs, |_| 1.0)
}

/// As [`spectrum`], judged against the expected noise density `shape(omega)` (any scale,
/// `omega` in rad/sample): the floor is the median of the density over the shape, and a peak
/// stands [`PEAK_DB`] above the shape at the floor's level.
#[must_use]
pub fn spectrum_against(x: &[f64], fs: f64, shape: impl Fn(f64) -> f64) -> Spectrum {
    let plan = Segments::of(x.len().max(2));
    let nfft = plan.nfft;
    let m = mean(x);
    let half = nfft / 2;
    // No taper: the residual of a step test is a transient that starts with the segment, and a
    // window would erase it.
    let mut raw = vec![0.0; half + 1];
    let mut buf = vec![Complex64::new(0.0, 0.0); nfft];
    let fft = FftPlanner::new().plan_fft_forward(nfft);
    for chunk in x.chunks(plan.len) {
        buf.iter_mut().enumerate().for_each(|(j, c)| {
            *c = Complex64::new(chunk.get(j).map_or(0.0, |v| v - m), 0.0);
        });
        fft.process(&mut buf);
        raw.iter_mut()
            .zip(&buf)
            .for_each(|(p, c)| *p += c.norm_sqr() / plan.count);
    }
    drop(buf);
    raw.iter_mut().for_each(|p| *p = p.max(1e-300));
    // A periodogram bin scatters like chi-square with 2 degrees of freedom (10 dB above the
    // median once in a thousand bins); averaging 9 neighbours makes a 10 dB excursion of noise
    // practically impossible while a resonance, wider than that, stays.
    let psd: Vec<f64> = (0..raw.len())
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(4), (i + 5).min(raw.len()));
            raw[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect();
    let psd_db: Vec<f64> = psd.iter().map(|p| 10.0 * p.log10()).collect();
    let shape_db: Vec<f64> = (0..psd_db.len())
        .map(|i| {
            10.0 * shape(2.0 * std::f64::consts::PI * i as f64 / nfft as f64)
                .max(1e-300)
                .log10()
        })
        .collect();
    let relative: Vec<f64> = psd_db.iter().zip(&shape_db).map(|(p, e)| p - e).collect();
    let mut sorted = relative.clone();
    sorted.sort_by(f64::total_cmp);
    let floor_db = sorted[sorted.len() / 2];
    let resolution_hz = fs / nfft as f64;
    // Zero padding by 2 makes neighbouring bins correlated: a peak must beat 3 bins each side.
    let mut peaks: Vec<Peak> = (4..psd_db.len().saturating_sub(4))
        .filter(|&i| {
            let v = relative[i];
            v - floor_db > PEAK_DB && (i - 3..=i + 3).all(|j| j == i || relative[j] < v)
        })
        .map(|i| {
            let half_power = psd[i] / 2.0;
            let lo = (0..i).rev().find(|&j| psd[j] < half_power).unwrap_or(0);
            let hi = (i..psd.len())
                .find(|&j| psd[j] < half_power)
                .unwrap_or(psd.len() - 1);
            let width = ((hi - lo) as f64 * resolution_hz).max(resolution_hz);
            let f = i as f64 * resolution_hz;
            Peak {
                frequency_hz: f,
                above_floor_db: relative[i] - floor_db,
                q: f / width,
            }
        })
        .collect();
    peaks.sort_by(|a, b| b.above_floor_db.total_cmp(&a.above_floor_db));
    peaks.truncate(8);
    // The floor drawn where the shape puts it: its level at the median.
    let mut shape_sorted = shape_db.clone();
    shape_sorted.sort_by(f64::total_cmp);
    let level = floor_db + shape_sorted[shape_sorted.len() / 2];
    Spectrum {
        resolution_hz,
        expected_db: shape_db.iter().map(|e| e + floor_db).collect(),
        psd_db,
        floor_db: level,
        peaks,
    }
}

impl TestEvidence {
    /// Measures the residual of `model`'s prediction `y_model` (its effects included) against
    /// a test.
    #[must_use]
    pub fn measure(
        file: &str,
        role: TestRole,
        model: &Model,
        (u, y): (&[f64], &[f64]),
        y_model: &[f64],
    ) -> Self {
        let fs = model.fs;
        let n = y.len().min(y_model.len()).min(u.len());
        let r: Vec<f64> = y[..n]
            .iter()
            .zip(&y_model[..n])
            .map(|(a, b)| a - b)
            .collect();
        // The reference's step, found once: its onset, its size, where the quiet segment ends
        // (only a clean step has one) and whether the reference's ringing can be read.
        let found = step::find_step(&u[..n]).ok();
        let (onset, step_size) = found.map_or((0, 0.0), |s| (s.onset, s.size()));
        let quiet = step::quiet_end(found);
        let ym = mean(&y[..n]);
        let dev = y[..n].iter().map(|v| (v - ym).powi(2)).sum::<f64>().sqrt();
        let res = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        let expected = expected_residual(model, &u[..n], &y[..n], quiet);
        let noise_std = expected.probe_std;
        let (lo, hi) = y[..n]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        let range = (hi - lo).max(f64::MIN_POSITIVE);
        let late = &r[n - (3 * n / 10).max(1)..];
        // Only a step test has a level before its step: a traverse's first samples are signal,
        // where the model's free response was fitted ([`Model::simulate_matched`]).
        let pre = &r[..quiet];
        Self {
            file: file.to_string(),
            role,
            samples: n,
            fit_percent: 100.0 * (1.0 - res / dev),
            nrmse: crate::fit::nrmse_of(&y[..n], &y_model[..n]),
            noise_floor: expected.std / range,
            prediction: None,
            step_onset: onset,
            step_size,
            noise_std,
            residual_rms: res / (n as f64).sqrt(),
            autocorrelation: autocorrelation_against(&r, &expected.acf, expected.bartlett),
            cross_correlation: cross_correlation(&u[..n], &r, (n / 4).min(2000)),
            spectrum: spectrum_against(&r[onset.min(n)..], fs, |w| {
                let g = crate::design::inverse::model_response(
                    model,
                    crate::poly::Complex::new(w.cos(), w.sin()),
                );
                expected.probe_std.powi(2) + expected.reference_std.powi(2) * g.norm_sqr()
            }),
            model_error: model_error(&y[..n], &y_model[..n], noise_std, fs),
            trend: Trend {
                pre_mean: if pre.is_empty() { f64::NAN } else { mean(pre) },
                pre_slope_per_s: slope(pre) * fs,
                pre_slope_se_per_s: expected.slope_se(pre.len(), fs),
                late_mean: mean(late),
                late_slope_per_s: slope(late) * fs,
                slope_per_s: slope(&r) * fs,
                pre_mean_se: if pre.is_empty() {
                    f64::INFINITY
                } else {
                    expected.mean_se(pre.len())
                },
                late_mean_se: expected.mean_se(late.len()),
            },
            reference_ringing: ringing_after(&u[..n], found.as_ref(), fs),
            expected,
        }
    }

    /// The residual is at the floor: no structure left to explain. With a noise model, its
    /// one-step-ahead prediction error at that error's floor.
    #[must_use]
    pub fn at_noise_floor(&self) -> bool {
        self.judged_nrmse() <= 1.2 * self.judged_floor()
    }

    /// Adds the one-step-ahead prediction error of a model with a noise model and its floor.
    #[must_use]
    pub fn with_prediction(mut self, nrmse: f64, floor: Option<PredictionFloor>) -> Self {
        self.prediction = floor.map(|floor| PredictionError { nrmse, floor });
        self
    }

    /// The error the model is judged by: the prediction error with a noise model, else the
    /// simulation error.
    #[must_use]
    pub fn judged_nrmse(&self) -> f64 {
        self.prediction.as_ref().map_or(self.nrmse, |p| p.nrmse)
    }

    /// That error's floor.
    #[must_use]
    pub fn judged_floor(&self) -> f64 {
        self.prediction
            .as_ref()
            .map_or(self.noise_floor, |p| p.floor.value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize, seed: u64) -> Vec<f64> {
        crate::testing::gaussian(n, seed)
    }

    #[test]
    fn white_noise_passes_and_coloured_noise_fails_ljung_box() {
        let w = noise(4000, 1);
        let a = autocorrelation(&w, ACF_LAGS);
        assert!(a.p_value > 0.01, "{}", a.p_value);
        let mut c = vec![0.0; w.len()];
        for k in 1..w.len() {
            c[k] = 0.8 * c[k - 1] + w[k];
        }
        let a = autocorrelation(&c, ACF_LAGS);
        assert!(a.p_value < 1e-6 && (a.values[0] - 0.8).abs() < 0.05);
    }

    #[test]
    fn the_cross_correlation_band_widens_for_two_slow_independent_series() {
        // Independent AR(1) series of pole 0.95: Bartlett's factor (1 + phi^2)/(1 - phi^2)
        // is about 19.5. The input's increments are what is correlated, so the input is the
        // running sum of an AR(1) series.
        let n = 40_000;
        let ar = |w: Vec<f64>| {
            let mut x = w;
            for k in 1..x.len() {
                x[k] += 0.95 * x[k - 1];
            }
            x
        };
        let du = ar(noise(n, 11));
        let u: Vec<f64> = du
            .iter()
            .scan(0.0, |s, d| {
                *s += d;
                Some(*s)
            })
            .collect();
        let r = ar(noise(n, 12));
        let lags = 400;
        let c = cross_correlation(&u, &r, lags);
        let factor = (c.band / Z99).powi(2) * n as f64;
        assert!((12.0..30.0).contains(&factor), "{factor}");
        // Against the widened band they look independent; against the white band they do not.
        let outside = |band: f64| c.values.iter().filter(|v| v.abs() > band).count();
        assert!(outside(c.band) <= lags / 20, "{}", outside(c.band));
        assert!(outside(Z99 / (n as f64).sqrt()) > lags / 10);
        // White against white keeps the white band.
        let w = cross_correlation(&noise(n, 13), &noise(n, 14), lags);
        assert!(
            (w.band * (n as f64).sqrt() / Z99 - 1.0).abs() < 0.2,
            "{}",
            w.band
        );
    }

    /// A slow first-order probe, `y = 0.05 u[k-1] + 0.95 y[k-1]` at 1 kHz.
    fn slow_probe() -> Model {
        Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.95],
            b: vec![0.0, 0.05],
        }
    }

    /// A step test with white noise on both channels: `(u, y, noise-free y)`.
    fn noisy_step(n: usize, su: f64, sy: f64) -> (Vec<f64>, Vec<f64>) {
        let m = slow_probe();
        let clean: Vec<f64> = (0..n).map(|k| if k < n / 4 { 0.0 } else { 1.0 }).collect();
        let (wu, wy) = (noise(n, 11), noise(n, 12));
        let u: Vec<f64> = clean.iter().zip(&wu).map(|(c, w)| c + su * w).collect();
        // The probe sees the true pressure; the reference records it with its own noise.
        let y: Vec<f64> = m
            .simulate_from(&clean, 0.0)
            .iter()
            .zip(&wy)
            .map(|(c, w)| c + sy * w)
            .collect();
        (u, y)
    }

    #[test]
    fn reference_noise_through_the_model_is_expected_not_flagged() {
        // The reference's noise 4x the probe's: y - G u is coloured below the probe's corner.
        let m = slow_probe();
        let (u, y) = noisy_step(8000, 0.02, 0.005);
        let ym = m.simulate(&u);
        let e = TestEvidence::measure("t", TestRole::Estimation, &m, (&u, &y), &ym);
        let r: Vec<f64> = y.iter().zip(&ym).map(|(a, b)| a - b).collect();
        // Judged against white noise the correct model fails...
        assert!(autocorrelation(&r, ACF_LAGS).p_value < 1e-6);
        // ...against what both channels' noise leaves it passes, and the floor includes it.
        assert!(e.autocorrelation.p_value > 0.01, "{:?}", e.autocorrelation);
        let expected_rho1 = e.expected.acf[0];
        assert!((e.autocorrelation.values[0] - expected_rho1).abs() < 0.05);
        // sigma^2 = sy^2 + su^2 sum g^2, sum g^2 = 0.05^2 / (1 - 0.95^2).
        let predicted = (0.005f64.powi(2) + 0.02f64.powi(2) * 0.0025 / (1.0 - 0.9025)).sqrt();
        assert!(
            (e.expected.std / predicted - 1.0).abs() < 0.1,
            "{} vs {predicted}",
            e.expected.std
        );
        assert!(e.at_noise_floor());
        assert_eq!(e.expected.source, NoiseSource::PreStep);
    }

    #[test]
    fn a_wrong_model_still_fails_against_the_expected_noise() {
        let m = slow_probe();
        let wrong = Model {
            a: vec![-0.9],
            b: vec![0.0, 0.1],
            ..m.clone()
        };
        let (u, y) = noisy_step(8000, 0.02, 0.005);
        let ym = wrong.simulate(&u);
        let e = TestEvidence::measure("t", TestRole::Estimation, &wrong, (&u, &y), &ym);
        assert!(e.autocorrelation.p_value < 1e-6, "{:?}", e.autocorrelation);
        assert!(!e.at_noise_floor());
    }

    #[test]
    fn a_record_without_a_quiet_segment_takes_its_noise_from_the_highest_frequencies() {
        // A slow traverse from the first sample: the "pre-step" part is signal, not noise.
        let w = noise(6000, 5);
        let x: Vec<f64> = (0..6000)
            .map(|k| (2.0 * std::f64::consts::PI * k as f64 / 700.0).sin() + 0.01 * w[k])
            .collect();
        assert_eq!(step::quiet_until(&x), 0);
        let (sigma, source) = step::channel_noise(&x, step::quiet_until(&x));
        assert_eq!(source, NoiseSource::HighFrequency);
        assert!((sigma / 0.01 - 1.0).abs() < 0.1, "{sigma}");
        // A step test's segment before the step is quiet: measured there.
        let stepped: Vec<f64> = w
            .iter()
            .enumerate()
            .map(|(k, v)| if k < 1500 { 0.0 } else { 1.0 } + 0.01 * v)
            .collect();
        let quiet = step::quiet_until(&stepped);
        assert!((1495..=1500).contains(&quiet), "{quiet}");
        let (sigma, source) = step::channel_noise(&stepped, quiet);
        assert_eq!(source, NoiseSource::PreStep);
        assert!((sigma / 0.01 - 1.0).abs() < 0.1, "{sigma}");
    }

    #[test]
    fn chi2_tail_matches_tabulated_quantiles() {
        // chi-square quantiles for 30 degrees of freedom: 0.99 -> 50.892, 0.95 -> 43.773.
        assert!((chi2_survival(50.892, 30) - 0.01).abs() < 5e-4);
        assert!((chi2_survival(43.773, 30) - 0.05).abs() < 1e-3);
    }

    #[test]
    fn a_decaying_oscillation_gives_a_peak_at_its_frequency() {
        let fs = 10_000.0;
        let w = noise(4000, 2);
        let x: Vec<f64> = (0..4000)
            .map(|k| {
                let t = k as f64 / fs;
                20.0 * (-2.0 * std::f64::consts::PI * 362.0 * 0.05 * t).exp()
                    * (2.0 * std::f64::consts::PI * 362.0 * t).sin()
                    + 0.1 * w[k]
            })
            .collect();
        let s = spectrum(&x, fs);
        let p = s.peaks.first().expect("a peak");
        assert!((p.frequency_hz - 362.0).abs() < 5.0, "{p:?}");
        assert!(p.q > 3.0 && p.q < 30.0, "{p:?}");
        assert!(spectrum(&w, fs).peaks.is_empty());
    }

    /// A record longer than [`SPECTRUM_SEGMENT`] is averaged over segments: the transform stays
    /// the segment's size, a resonance in the residual is still found where it is, and noise
    /// alone gives no peak.
    #[test]
    fn long_records_are_averaged_over_segments_and_keep_their_peaks() {
        let fs = 1e6;
        let n = 3 * SPECTRUM_SEGMENT + 12_345;
        let w = noise(n, 7);
        let f0 = 41_000.0;
        let x: Vec<f64> = w
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.05 * (2.0 * std::f64::consts::PI * f0 * k as f64 / fs).sin())
            .collect();
        let s = spectrum(&x, fs);
        // Four segments of at most 2^20 samples, each padded to 2^21.
        assert_eq!(s.psd_db.len(), (1 << 20) + 1);
        assert!((s.resolution_hz - fs / f64::from(1 << 21)).abs() < 1e-12);
        let top = s.peaks.first().expect("the sinusoid is a peak");
        assert!((top.frequency_hz - f0).abs() < 3.0, "{top:?}");
        // White noise alone: no peak.
        let plain = spectrum(&w, fs);
        assert!(plain.peaks.is_empty(), "{:?}", plain.peaks);
    }

    /// Up to one segment the spectrum is the record's own: the same bins as one transform of
    /// the whole record, and the model-error ratio of a signal with itself is 0 dB.
    #[test]
    fn short_records_are_one_segment_and_model_error_of_itself_is_flat() {
        let n = 5000;
        let x = noise(n, 3);
        let s = spectrum(&x, 1000.0);
        assert_eq!(s.psd_db.len(), (2 * n).next_power_of_two() / 2 + 1);
        let steps: Vec<f64> = (0..n).map(|k| f64::from(u8::from(k >= 100))).collect();
        let e = model_error(&steps, &steps, 1e-6, 1000.0);
        assert!(e.db.len() > 10);
        assert!(e.db.iter().all(|v| v.abs() < 1e-9), "{:?}", &e.db[..5]);
        assert!(e.peaks.is_empty());
    }
}
