//! Finding the step in a step test: where the reference rises (or falls), by how much, and how
//! noisy each channel is before it.
//!
//! The step is located as the best two-level split of the reference (least squares over all
//! split points, `O(n)` with prefix sums), which is robust to noise and to a finite rise time.
//! The onset is then walked back from the split to the first sample that leaves the pre-step
//! level by more than the noise allows.

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
}

impl Step {
    /// Signed step size.
    #[must_use]
    pub fn size(&self) -> f64 {
        self.after - self.before
    }
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
