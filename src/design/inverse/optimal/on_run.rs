//! What a compensator is expected to do on a recorded run that has no reference: the run's own
//! probe spectrum, the pressure spectrum it implies through the model and the noise, and the
//! error a cascade (or the raw probe) leaves on that pressure.
//!
//! The probe gives `S_y = |G|^2 S_u + S_ny`, so the run's pressure spectrum is
//! `S_u = max(S_y - S_ny, 0) / |G|^2`, measured where the probe's signal stands above its noise
//! and zero where it does not. The error of a cascade `C` at latency `L` is then
//! `|C G - z^-L|^2 S_u + |C|^2 S_ny`, as in [`super::budget`] but with this run's spectrum in
//! place of the design's prior: a design made for steps and run on a slow balloon or wake is
//! judged on the slow run's spectrum, where its boost above the probe's corner only amplifies
//! noise.

use std::f64::consts::PI;
use std::ops::RangeInclusive;

use statrs::distribution::{ContinuousCDF, Gamma};

use super::NoiseModel;
use crate::design::inverse::{cascade_response, model_response};
use crate::fit::model::Model;
use crate::poly::Complex;

/// Longest stretch of the record transformed at once: a longer record is cut into equal parts
/// no longer than this, whose periodograms are averaged, so that memory stays bounded.
pub const SEGMENT: usize = 1 << 20;

/// Shortest record a spectrum is measured on.
pub const MIN_SAMPLES: usize = 256;

/// Independent periodogram values averaged into each bin's detection (about; at least).
pub const AVERAGED: f64 = 16.0;

/// The chance that the probe noise alone passes the detection threshold anywhere in the band
/// ([`RunSpectrum::pressure`]): each of the band's independent smoothed values is held to the
/// noise's quantile at `1 - FALSE_DETECTION / groups` (Bonferroni over the groups).
pub const FALSE_DETECTION: f64 = 0.05;

/// The factor over the noise density a smoothed bin must pass to count as the pressure's: the
/// quantile at `1 - FALSE_DETECTION / groups` of the noise's smoothed periodogram over its
/// density, a mean of `averaged` independent exponential values, so Gamma with shape and rate
/// `averaged`. Held bin by bin to a fixed number of standard deviations instead, noise alone
/// passes somewhere in a band of thousands of groups (the Gamma law's upper tail is long),
/// and a pass where the model's response is small is divided by it into a large pressure.
fn detection_threshold(averaged: f64, groups: f64) -> f64 {
    let shape = averaged.max(1.0);
    let p = 1.0 - FALSE_DETECTION / groups.max(1.0);
    Gamma::new(shape, shape)
        .ok()
        .map(|g| g.inverse_cdf(p))
        .filter(|t| t.is_finite() && *t > 1.0)
        // Where the quantile cannot be had: four standard deviations.
        .unwrap_or(1.0 + 4.0 / shape.sqrt())
}

/// A run's probe spectrum: the periodogram of the whole record (or of parts of at most
/// [`SEGMENT`] samples, averaged), each part closed by a raised-cosine bridge from its last
/// value back to its first so that the circular transform sees no jump, and the same smoothed
/// over enough neighbouring bins to tell the pressure from the noise. The densities are per
/// sample and two-sided (white noise of variance `s^2` reads `s^2` in every bin); the bins run
/// from DC to `pi` rad/sample.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpectrum {
    /// Bin frequencies, rad/sample, from 0 to `pi`.
    pub omega: Vec<f64>,
    /// Periodogram of the probe signal at each bin.
    pub psd: Vec<f64>,
    /// The same, smoothed over neighbouring bins.
    pub smoothed: Vec<f64>,
    /// Independent values averaged into a smoothed bin (about).
    pub averaged: f64,
    /// Neighbouring bins smoothed over: the band holds about `omega.len() / window`
    /// independent smoothed values.
    pub window: usize,
    /// Transform length: the sum over bins, weighted by [`RunSpectrum::weight`], over this is
    /// the mean square.
    pub size: usize,
}

impl RunSpectrum {
    /// The spectrum of `y`; `None` for a record shorter than [`MIN_SAMPLES`] or not finite.
    #[must_use]
    pub fn measure(y: &[f64]) -> Option<Self> {
        let mut streamed = SpectrumStream::new(y.len())?;
        for &v in y {
            streamed.push(v);
        }
        streamed.finish()
    }

    /// Weight of bin `k` in the mean square (the bins between DC and `pi` stand for two).
    #[must_use]
    pub fn weight(&self, k: usize) -> f64 {
        if k == 0 || k + 1 == self.omega.len() {
            1.0
        } else {
            2.0
        }
    }

    /// The pressure spectrum the run implies through `model` at each bin, beside the probe
    /// noise's density and the model's response there. The noise is the stored model's shape at the run's own
    /// level (the median over the top quarter of the band, where no probe passes pressure
    /// above its noise), since a run's noise need not be the step test's; a bin is the
    /// pressure's only where its smoothed density passes that noise's quantile
    /// ([`FALSE_DETECTION`]) over the band's independent groups,
    /// noise, and is then `(S_y - S_ny) / |G|^2`.
    #[must_use]
    pub fn pressure(&self, model: &Model, noise: &NoiseModel) -> RunPressure {
        let shape: Vec<f64> = self.omega.iter().map(|&w| noise.probe_psd(w)).collect();
        let mut top: Vec<f64> = self
            .omega
            .iter()
            .zip(self.smoothed.iter().zip(&shape))
            .filter(|(w, _)| **w > 0.75 * PI)
            .map(|(_, (p, s))| p / s)
            .filter(|r| r.is_finite())
            .collect();
        top.sort_by(f64::total_cmp);
        let level = top.get(top.len() / 2).copied().unwrap_or(1.0);
        let groups = self.omega.len() as f64 / self.window.max(1) as f64;
        let threshold = detection_threshold(self.averaged, groups);
        let bins = self
            .omega
            .iter()
            .enumerate()
            .map(|(k, &w)| {
                let z = Complex::new(w.cos(), w.sin());
                let g = model_response(model, z);
                let sn = level * shape.get(k).copied().unwrap_or(0.0);
                let (p, smooth) = (
                    self.psd.get(k).copied().unwrap_or(0.0),
                    self.smoothed.get(k).copied().unwrap_or(0.0),
                );
                let su = if smooth > threshold * sn {
                    (p - sn).max(0.0) / g.norm_sqr().max(1e-300)
                } else {
                    0.0
                };
                Bin {
                    z,
                    g,
                    su,
                    sn,
                    weight: self.weight(k),
                }
            })
            .collect();
        RunPressure {
            bins,
            size: self.size,
        }
    }
}

/// [`RunSpectrum::measure`] on a run streamed one sample at a time, its length `n` known
/// beforehand (the first pass over its file): the parts are transformed as they fill, so that
/// memory holds one part (at most [`SEGMENT`] samples) whatever the run's length. The same
/// figures as [`RunSpectrum::measure`] on the whole record, which is this over a slice.
pub struct SpectrumStream {
    fft: std::sync::Arc<dyn rustfft::Fft<f64>>,
    buf: Vec<Complex>,
    /// Samples a part has (the last may have fewer).
    len: usize,
    size: usize,
    psd: Vec<f64>,
    /// Samples of the current part so far, and their sum.
    filled: usize,
    sum: f64,
    mean_square_level: f64,
    count: usize,
    finite: bool,
    pushed: usize,
    n: usize,
}

impl SpectrumStream {
    /// A spectrum of a run of `n` samples; `None` when shorter than [`MIN_SAMPLES`].
    #[must_use]
    pub fn new(n: usize) -> Option<Self> {
        Self::with_segment(n, SEGMENT)
    }

    /// [`SpectrumStream::new`] with parts of at most `segment` samples.
    fn with_segment(n: usize, segment: usize) -> Option<Self> {
        if n < MIN_SAMPLES {
            return None;
        }
        let parts = n.div_ceil(segment);
        let len = n.div_ceil(parts);
        // The bridge: long enough that its bend leaks nothing into the band, short enough that
        // it adds little power of its own; rustfft takes any length.
        let size = (len + (len / 32).max(64)).next_multiple_of(64);
        let fft = rustfft::FftPlanner::<f64>::new().plan_fft_forward(size);
        Some(Self {
            fft,
            buf: vec![Complex::new(0.0, 0.0); size],
            len,
            size,
            psd: vec![0.0; size / 2 + 1],
            filled: 0,
            sum: -0.0,
            mean_square_level: 0.0,
            count: 0,
            finite: true,
            pushed: 0,
            n,
        })
    }

    /// The next sample of the run.
    pub fn push(&mut self, v: f64) {
        self.finite &= v.is_finite();
        self.pushed += 1;
        if let Some(c) = self.buf.get_mut(self.filled) {
            *c = Complex::new(v, 0.0);
        }
        self.filled += 1;
        self.sum += v;
        if self.filled == self.len {
            self.part();
        }
    }

    /// Transforms the part in the buffer.
    fn part(&mut self) {
        let m = self.filled;
        let (Some(first), Some(last)) = (
            self.buf.first(),
            m.checked_sub(1).and_then(|i| self.buf.get(i)),
        ) else {
            return;
        };
        let (first, last) = (first.re, last.re);
        // The level apart: its square is the DC bin's, and the bridge carries only the ends'
        // departures from it.
        let n = m as f64;
        let level = self.sum / n;
        let bridge = (self.size - m) as f64 + 1.0;
        for (i, c) in self.buf.iter_mut().enumerate() {
            let v = if i < m {
                c.re
            } else {
                let t = (i + 1 - m) as f64 / bridge;
                last + (first - last) * 0.5 * (1.0 - (PI * t).cos())
            };
            *c = Complex::new(v - level, 0.0);
        }
        self.fft.process(&mut self.buf);
        for (p, c) in self.psd.iter_mut().zip(&self.buf) {
            *p += c.norm_sqr() / n;
        }
        self.mean_square_level += level * level;
        self.count += 1;
        self.filled = 0;
        self.sum = -0.0;
    }

    /// The spectrum; `None` when a sample was not finite or the run had fewer samples than
    /// announced.
    #[must_use]
    pub fn finish(mut self) -> Option<RunSpectrum> {
        if self.filled > 0 {
            self.part();
        }
        if !self.finite || self.pushed != self.n {
            return None;
        }
        let (size, len) = (self.size, self.len);
        let mut psd = self.psd;
        let parts = self.count.max(1) as f64;
        psd.iter_mut().for_each(|p| *p /= parts);
        // The DC bin holds the level, so that it weighs in the mean square as it does in the
        // record (a DC gain's error on a run's level is most of a leak's).
        if let Some(dc) = psd.first_mut() {
            *dc = size as f64 * self.mean_square_level / parts;
        }
        // Zero padding makes neighbouring bins alike: smooth over enough of them to average
        // about AVERAGED independent values.
        let oversampling = size as f64 / len as f64;
        let width = ((0.5 * AVERAGED * oversampling / parts).ceil() as usize).max(1);
        let mut smoothed = moving_average(psd.get(1..).unwrap_or(&[]), width);
        smoothed.insert(0, psd.first().copied().unwrap_or(0.0));
        let averaged = (2 * width + 1) as f64 / oversampling * parts;
        let omega = (0..=size / 2)
            .map(|k| 2.0 * PI * k as f64 / size as f64)
            .collect();
        Some(RunSpectrum {
            omega,
            psd,
            smoothed,
            averaged,
            window: 2 * width + 1,
            size,
        })
    }
}

/// Mean of `x` over `i - width ..= i + width` (fewer at the ends).
fn moving_average(x: &[f64], width: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(x.len() + 1);
    prefix.push(0.0);
    let mut sum = 0.0;
    for v in x {
        sum += v;
        prefix.push(sum);
    }
    (0..x.len())
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(width), (i + width + 1).min(x.len()));
            (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// One bin of a run: its point on the unit circle, the model's response, the implied pressure
/// and probe noise densities, and its weight in the mean square.
#[derive(Debug, Clone)]
struct Bin {
    z: Complex,
    g: Complex,
    su: f64,
    sn: f64,
    weight: f64,
}

/// What a run implies through a model: the pressure's and the probe noise's densities at each
/// bin of its spectrum ([`RunSpectrum::pressure`]), from which any compensator's error follows.
#[derive(Debug, Clone)]
pub struct RunPressure {
    bins: Vec<Bin>,
    size: usize,
}

impl RunPressure {
    /// The error a cascade `(gain, sections)` run on the probe signal is expected to leave on
    /// the run (RMS, pressure units), at its best latency in `lags`: the pressure part it does
    /// not restore and the probe noise it passes, the reference channel's own noise left out.
    /// The raw probe is the cascade `(1, [])`.
    #[must_use]
    pub fn predicted(&self, gain: f64, sections: &[[f64; 5]], lags: RangeInclusive<usize>) -> f64 {
        let mut noise_part = 0.0;
        // Where the run has pressure: C G, the weighted density and the frequency.
        let mut signal: Vec<(Complex, f64, f64)> = Vec::new();
        for b in &self.bins {
            let c = cascade_response(gain, sections, b.z);
            noise_part += b.weight * c.norm_sqr() * b.sn;
            if b.su > 0.0 {
                signal.push((c * b.g, b.weight * b.su, b.z.im.atan2(b.z.re)));
            }
        }
        let band_part = lags
            .map(|lag| {
                let l = lag as f64;
                signal
                    .iter()
                    .map(|(cg, su, w)| {
                        (*cg - Complex::new((w * l).cos(), -(w * l).sin())).norm_sqr() * su
                    })
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min);
        ((band_part + noise_part) / self.size.max(1) as f64).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::step::NoiseSource;

    fn white(std: f64) -> NoiseModel {
        NoiseModel {
            probe_white_std: std,
            probe_ar_pole: 0.0,
            probe_ar_std: 0.0,
            reference_std: 0.0,
            source: NoiseSource::PreStep,
        }
    }

    /// The spectrum as it was measured on a whole record held in memory, parts of at most
    /// `segment` samples: the reference the streamed one is held to.
    fn measured_whole(y: &[f64], segment: usize) -> RunSpectrum {
        let parts = y.len().div_ceil(segment);
        let len = y.len().div_ceil(parts);
        let size = (len + (len / 32).max(64)).next_multiple_of(64);
        let fft = rustfft::FftPlanner::<f64>::new().plan_fft_forward(size);
        let mut buf = vec![Complex::new(0.0, 0.0); size];
        let half = size / 2;
        let mut psd = vec![0.0; half + 1];
        let mut mean_square_level = 0.0;
        let mut count = 0usize;
        for part in y.chunks(len) {
            let (first, last) = (part[0], part[part.len() - 1]);
            let n = part.len() as f64;
            let level = part.iter().sum::<f64>() / n;
            let bridge = (size - part.len()) as f64 + 1.0;
            for (i, c) in buf.iter_mut().enumerate() {
                let v = match part.get(i) {
                    Some(v) => *v,
                    None => {
                        let t = (i + 1 - part.len()) as f64 / bridge;
                        last + (first - last) * 0.5 * (1.0 - (PI * t).cos())
                    }
                };
                *c = Complex::new(v - level, 0.0);
            }
            fft.process(&mut buf);
            for (p, c) in psd.iter_mut().zip(&buf) {
                *p += c.norm_sqr() / n;
            }
            mean_square_level += level * level;
            count += 1;
        }
        let parts = count as f64;
        psd.iter_mut().for_each(|p| *p /= parts);
        psd[0] = size as f64 * mean_square_level / parts;
        let oversampling = size as f64 / len as f64;
        let width = ((0.5 * AVERAGED * oversampling / parts).ceil() as usize).max(1);
        let mut smoothed = moving_average(&psd[1..], width);
        smoothed.insert(0, psd[0]);
        RunSpectrum {
            omega: (0..=half)
                .map(|k| 2.0 * PI * k as f64 / size as f64)
                .collect(),
            psd,
            smoothed,
            averaged: (2 * width + 1) as f64 / oversampling * parts,
            window: 2 * width + 1,
            size,
        }
    }

    /// Streamed in parts (one, three of equal length, a shorter last one), the spectrum is
    /// the one measured on the whole record, bit for bit.
    #[test]
    fn the_streamed_spectrum_is_the_whole_records() {
        let y: Vec<f64> = crate::testing::gaussian(2000, 9)
            .iter()
            .enumerate()
            .map(|(k, n)| 0.3 + (k as f64 * 0.01).sin() + 0.05 * n)
            .collect();
        for (n, segment) in [(1000, SEGMENT), (1500, 500), (1999, 700), (2000, 256)] {
            let mut s = SpectrumStream::with_segment(n, segment).unwrap();
            y[..n].iter().for_each(|&v| s.push(v));
            let streamed = s.finish().unwrap();
            assert_eq!(streamed, measured_whole(&y[..n], segment), "{n} {segment}");
        }
        // Fewer samples than announced, or one not finite: no spectrum.
        let mut short = SpectrumStream::new(1000).unwrap();
        y[..999].iter().for_each(|&v| short.push(v));
        assert!(short.finish().is_none());
        assert!(SpectrumStream::new(MIN_SAMPLES - 1).is_none());
    }

    #[test]
    fn white_noise_reads_its_variance_in_every_bin() {
        let std = 0.01;
        // Longer than a segment: two parts, averaged.
        let y: Vec<f64> = crate::testing::gaussian(SEGMENT + SEGMENT / 2, 3)
            .iter()
            .map(|n| std * n)
            .collect();
        let s = RunSpectrum::measure(&y).unwrap();
        let mean_square = s
            .psd
            .iter()
            .enumerate()
            .map(|(k, p)| s.weight(k) * p)
            .sum::<f64>()
            / s.size as f64;
        // The level (about 0) adds nothing; the bridge adds a little of its own.
        assert!(
            (mean_square / (std * std) - 1.0).abs() < 0.04,
            "{mean_square}"
        );
        let level = s.smoothed.iter().sum::<f64>() / s.smoothed.len() as f64;
        assert!((level / (std * std) - 1.0).abs() < 0.04, "{level}");
        assert!(s.averaged >= AVERAGED, "{}", s.averaged);
        assert!(RunSpectrum::measure(&y[..100]).is_none());
        let mut bad = y.clone();
        bad[7] = f64::NAN;
        assert!(RunSpectrum::measure(&bad).is_none());
    }

    /// On records of white probe noise alone, a bin above the lowest hundred (where the
    /// bridge closing the record adds a little of its own) counts as the pressure's in about
    /// [`FALSE_DETECTION`] of them (here at most 5 of 40, 2 expected); four standard
    /// deviations bin by bin passed somewhere in most.
    #[test]
    fn noise_alone_is_taken_for_pressure_in_few_records() {
        let m = Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.9],
            b: vec![0.1],
        };
        let noise = white(1e-3);
        let (mut now, mut bin_by_bin) = (0, 0);
        for seed in 0..40 {
            let y: Vec<f64> = crate::testing::gaussian(20_000, 500 + seed)
                .iter()
                .map(|n| 1e-3 * n)
                .collect();
            let s = RunSpectrum::measure(&y).unwrap();
            let p = s.pressure(&m, &noise);
            let band = || p.bins.iter().zip(&s.smoothed).skip(100);
            now += usize::from(band().any(|(b, _)| b.su > 0.0));
            let four_sigma = 1.0 + 4.0 / s.averaged.sqrt();
            bin_by_bin += usize::from(band().any(|(b, &sm)| sm > four_sigma * b.sn));
        }
        assert!(now <= 5, "{now} of 40");
        assert!(bin_by_bin >= 20, "{bin_by_bin} of 40");
    }

    #[test]
    fn a_boost_loses_on_a_slow_run_and_wins_on_a_fast_one() {
        // A first-order probe (pole 0.9) and its inverse, which boosts the band above the
        // corner tenfold; white probe noise of 1e-3.
        let m = Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.9],
            b: vec![0.1],
        };
        let inverse = [[1.0, -0.9, 0.0, 0.0, 0.0]];
        let noise = white(1e-3);
        let probe = |u: &[f64], seed: u64| -> Vec<f64> {
            let mut state = u.first().copied().unwrap_or(0.0);
            u.iter()
                .zip(crate::testing::gaussian(u.len(), seed))
                .map(|(v, n)| {
                    state = 0.9 * state + 0.1 * v;
                    state + 1e-3 * n
                })
                .collect()
        };
        // Slow: a sine at 0.5 Hz. Fast: a square wave at 20 Hz.
        let slow: Vec<f64> = (0..100_000)
            .map(|k| (2.0 * PI * 0.5 * k as f64 / 1000.0).sin())
            .collect();
        let fast: Vec<f64> = (0..100_000)
            .map(|k| if (k / 25) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        for (u, inverse_wins, seed) in [(slow, false, 11), (fast, true, 12)] {
            let y = probe(&u, seed);
            let s = RunSpectrum::measure(&y).unwrap();
            let pressure = s.pressure(&m, &noise);
            let comp = pressure.predicted(10.0, &inverse, 0..=2);
            let raw = pressure.predicted(1.0, &[], 0..=40);
            assert_eq!(comp < raw, inverse_wins, "comp {comp} raw {raw}");
            // The measured errors agree on the verdict.
            let mut u_hat = Vec::with_capacity(y.len());
            let mut prev = y[0];
            for v in &y {
                u_hat.push(10.0 * v - 9.0 * prev);
                prev = *v;
            }
            let rms = |e: &[f64], lag: usize| -> f64 {
                (e.iter()
                    .skip(1000)
                    .zip(u.iter().skip(1000 - lag))
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    / (e.len() - 1000) as f64)
                    .sqrt()
            };
            let measured_comp = rms(&u_hat, 0);
            let measured_raw = (0..=40).map(|l| rms(&y, l)).fold(f64::INFINITY, f64::min);
            assert_eq!(measured_comp < measured_raw, inverse_wins);
            // And the prediction is near the measurement.
            assert!(
                (comp / measured_comp - 1.0).abs() < 0.25,
                "{comp} {measured_comp}"
            );
        }
    }
}
