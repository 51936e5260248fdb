//! Finding the step in a step test: where the reference rises (or falls), by how much, and how
//! noisy each channel is before it.
//!
//! The step is located as the best two-level split of the reference (least squares over all
//! split points, `O(n)` with prefix sums), which is robust to noise and to a finite rise time.
//! The onset is then walked back from the split to the first sample that leaves the pre-step
//! level by more than the noise allows.

use serde::{Deserialize, Serialize};

/// A located step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// First sample that belongs to the step (the reference has started to move).
    pub onset: usize,
    /// Sample where the two-level split falls (the middle of the rise).
    pub split: usize,
    /// Level before the step (mean of the samples before the onset).
    pub before: f64,
    /// Level after the step (mean of the samples after the split).
    pub after: f64,
    /// Noise standard deviation of the reference before the step.
    pub noise: f64,
    /// Share of the reference's variance the two levels explain: near 1 for a step (a shock
    /// tube, a balloon, a valve), far below for a traverse whose largest change is one of many.
    pub explained: f64,
}

/// A step whose two levels explain at least this share of the reference's variance is a step
/// test's: its reference's own ringing can be read after it.
pub const CLEAN_STEP: f64 = 0.9;

impl Step {
    /// The record is a step test: two levels explain [`CLEAN_STEP`] of its variance.
    #[must_use]
    pub fn is_clean(&self) -> bool {
        self.explained >= CLEAN_STEP
    }
}

impl Step {
    /// Signed step size.
    #[must_use]
    pub fn size(&self) -> f64 {
        self.after - self.before
    }
}

/// Where a noise level was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseSource {
    /// The quiet segment before the step.
    PreStep,
    /// First differences of the whole record (no quiet segment long enough).
    HighFrequency,
    /// Given by the caller (an oracle, a test).
    Given,
}

/// Noise of one channel and where it was measured: the quiet segment before `quiet` (at least
/// 64 samples, detrended; pass [`quiet_until`] of the reference: a step test's pressure is
/// steady before its step, so whatever moves there is noise, white or coloured); otherwise
/// the whole record's third differences (a smooth signal barely reaches them: 150 Hz at 10 kHz
/// keeps 8e-4 of its amplitude), by their median absolute value.
#[must_use]
pub fn channel_noise(x: &[f64], quiet: usize) -> (f64, NoiseSource) {
    match x.get(..quiet).filter(|p| p.len() >= 64) {
        Some(pre) => (detrended_std(pre), NoiseSource::PreStep),
        None => (high_frequency_std(x), NoiseSource::HighFrequency),
    }
}

/// Fewest quiet samples before a step that the noise is measured on; a test with fewer (a
/// traverse, a balloon burst at once) gives its noise from its highest frequencies.
pub const MIN_QUIET: usize = 64;

/// Where a record's quiet segment ends: the onset of its step when it is a step test
/// ([`Step::is_clean`]), else 0 (a traverse has none: its first samples are signal).
#[must_use]
pub fn quiet_until(u: &[f64]) -> usize {
    quiet_end(find_step(u).ok())
}

/// [`quiet_until`] of a reference whose step is already found (`None`: no step).
#[must_use]
pub fn quiet_end(found: Option<Step>) -> usize {
    found.filter(Step::is_clean).map_or(0, |s| s.onset)
}

/// How far a channel moves beyond its own noise: its standard deviation over the white noise
/// its third differences show. About 1 for noise alone; a step test gives tens to thousands,
/// a traverse with wakes tens.
#[must_use]
pub fn excitation(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let std = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    let noise = high_frequency_std(x);
    if noise > 0.0 {
        std / noise
    } else if std > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// [`excitation`] of a channel streamed twice (a run read in passes from its file): the mean
/// and the third differences' median counted in the first pass, the spread about the mean and
/// the median's second look in the second. The same figure as [`excitation`] (the median as
/// [`crate::trace::stream::Median`] finds it).
#[derive(Debug, Clone, Default)]
pub struct ExcitationStream {
    n: usize,
    sum: f64,
    mean: f64,
    squares: f64,
    last: [f64; 3],
    seen: usize,
    d3: crate::trace::stream::Median,
}

impl ExcitationStream {
    /// Nothing yet.
    #[must_use]
    pub fn new() -> Self {
        Self {
            sum: -0.0,
            squares: -0.0,
            ..Self::default()
        }
    }

    /// The next third difference's magnitude, once three samples came before `v`.
    fn d3(&mut self, v: f64) -> Option<f64> {
        let [a, b, c] = self.last;
        let d = (self.seen >= 3).then(|| (v - 3.0 * c + 3.0 * b - a).abs());
        self.last = [b, c, v];
        self.seen += 1;
        d
    }

    /// A sample of the first pass.
    pub fn first(&mut self, v: f64) {
        self.n += 1;
        self.sum += v;
        if let Some(d) = self.d3(v) {
            self.d3.first(d);
        }
    }

    /// Ends the first pass.
    pub fn end_first(&mut self) {
        self.mean = self.sum / self.n.max(1) as f64;
        self.seen = 0;
        self.d3.end_first();
    }

    /// A sample of the second pass.
    pub fn second(&mut self, v: f64) {
        self.squares += (v - self.mean).powi(2);
        if let Some(d) = self.d3(v) {
            self.d3.second(d);
        }
    }

    /// The excitation, after the second pass.
    #[must_use]
    pub fn value(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let std = (self.squares / self.n as f64).sqrt();
        let noise = self
            .d3
            .value()
            .map_or(0.0, |m| m / (0.674_489_75 * 20f64.sqrt()));
        if noise > 0.0 {
            std / noise
        } else if std > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }
}

/// Least [`excitation`] of a test's reference: below it the test carries no step or other
/// change above its noise and tells nothing about the probe.
pub const MIN_EXCITATION: f64 = 3.0;

/// White-noise standard deviation from third differences: `d3 = x[k+3] - 3x[k+2] + 3x[k+1]
/// - x[k]` has variance `20 sigma^2`, and the median of `|d3|` is `0.6745 sqrt(20) sigma`.
fn high_frequency_std(x: &[f64]) -> f64 {
    let mut d: Vec<f64> = x
        .windows(4)
        .map(|w| (w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]).abs())
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid] / (0.674_489_75 * 20f64.sqrt())
}

/// `x` less its least-squares line.
#[must_use]
pub fn detrend(x: &[f64]) -> Vec<f64> {
    let n = x.len() as f64;
    if x.len() < 3 {
        return x.to_vec();
    }
    let tm = 0.5 * (n - 1.0);
    let xm = x.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let t = k as f64 - tm;
        sxy += t * (v - xm);
        sxx += t * t;
    }
    let slope = sxy / sxx;
    x.iter()
        .enumerate()
        .map(|(k, v)| v - xm - slope * (k as f64 - tm))
        .collect()
}

/// Standard deviation of `x` about its least-squares line.
fn detrended_std(x: &[f64]) -> f64 {
    let d = detrend(x);
    (d.iter().map(|v| v * v).sum::<f64>() / d.len().max(1) as f64).sqrt()
}

/// Robust noise standard deviation from first differences (median absolute difference / 0.954,
/// the normal-distribution factor for differences of independent samples).
#[must_use]
pub fn noise_std(x: &[f64]) -> f64 {
    let mut d: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if d.is_empty() {
        return 0.0;
    }
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    // MAD of a N(0, 2 s^2) variable = 0.6745 * sqrt(2) s = 0.954 s.
    d[mid] / 0.954
}

/// Mean and standard deviation.
#[must_use]
pub fn mean_std(x: &[f64]) -> (f64, f64) {
    if x.is_empty() {
        return (0.0, 0.0);
    }
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / n;
    (m, v.sqrt())
}

/// Locates the step in `u`.
///
/// # Errors
/// A sentence saying why no step was found: the trace is too short, or the largest level
/// change is not clearly above the noise.
pub fn find_step(u: &[f64]) -> Result<Step, String> {
    let n = u.len();
    if n < 8 {
        return Err(format!("{n} samples are too few to hold a step"));
    }
    // Best split into two constant levels: minimise SSE(0..k) + SSE(k..n), equivalently
    // maximise k (n-k) (mean_left - mean_right)^2.
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    let mut s = 0.0;
    for v in u {
        s += v;
        prefix.push(s);
    }
    let total = s;
    let mut best = (0.0, 0usize);
    for (k, &pk) in prefix.iter().enumerate().take(n - 1).skip(2) {
        let left = pk / k as f64;
        let right = (total - pk) / (n - k) as f64;
        let score = (k as f64) * ((n - k) as f64) * (left - right) * (left - right);
        if score > best.0 {
            best = (score, k);
        }
    }
    let split = best.1;
    if split == 0 {
        return Err("the reference is constant".into());
    }
    // Between-levels sum of squares over the total: best.0 / n is the former.
    let mean = total / n as f64;
    let total_ss = u.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>();
    let explained = if total_ss > 0.0 {
        (best.0 / n as f64 / total_ss).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let left = &u[..split];
    let right = &u[split..];
    let noise = noise_std(left).max(noise_std(right));
    let (lvl_before, _) = mean_std(left);
    let (after, _) = mean_std(right);
    let size = after - lvl_before;
    if size.is_nan() || size.abs() <= 10.0 * noise || size == 0.0 {
        return Err(format!(
            "the largest level change ({size:.4e}) is not clearly above the noise ({noise:.4e}); a step test needs a step at least 10 times the noise"
        ));
    }
    // Walk back from the split to where u leaves the pre-step level.
    let thr = (5.0 * noise).max(0.01 * size.abs());
    // Reference level before: robust, from the first half of the left part.
    let head = &u[..split.div_ceil(2).max(1)];
    let (base, _) = mean_std(head);
    let mut onset = split;
    while onset > 0 && (u[onset - 1] - base).abs() > thr {
        onset -= 1;
    }
    let (before, _) = if onset > 0 {
        mean_std(&u[..onset])
    } else {
        (u[0], 0.0)
    };
    Ok(Step {
        onset,
        split,
        before,
        after,
        noise,
        explained,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_clean_step_and_its_onset() {
        let u: Vec<f64> = (0..100).map(|k| if k >= 40 { 3.0 } else { 1.0 }).collect();
        let s = find_step(&u).unwrap();
        assert_eq!(s.onset, 40);
        assert!((s.size() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn finds_the_start_of_a_ramp_and_a_falling_step() {
        // Ramp from 30 to 40, then flat; falling.
        let u: Vec<f64> = (0..200)
            .map(|k| {
                let k = k as f64;
                if k < 30.0 {
                    5.0
                } else if k < 40.0 {
                    5.0 - (k - 29.0) * 0.4
                } else {
                    1.0
                }
            })
            .collect();
        let s = find_step(&u).unwrap();
        assert_eq!(s.onset, 30);
        assert!(s.size() < 0.0);
    }

    #[test]
    fn no_step_in_noise() {
        // Deterministic pseudo-noise.
        let mut x = 12345u64;
        let u: Vec<f64> = (0..500)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect();
        assert!(find_step(&u).is_err());
    }

    #[test]
    fn noise_std_of_gaussian_like_noise() {
        let mut x = 99u64;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        // Box-Muller.
        let v: Vec<f64> = (0..20000)
            .map(|_| {
                let (a, b) = (next().max(1e-300), next());
                (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos() * 0.3
            })
            .collect();
        let s = noise_std(&v);
        assert!((s - 0.3).abs() < 0.02, "{s}");
    }
}
