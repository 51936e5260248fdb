//! Scoring a signal against a pressure: the RMS error at the best whole-sample alignment
//! within a window of lags, over the run after a settling margin, every lag judged on the
//! same samples.

use std::ops::RangeInclusive;

/// RMS of `signal[k] - truth[k - lag]` over `k` from `from` (or the window's largest lag,
/// if later) to the end of the shorter record, at the lag of `lags` that makes it least:
/// `(rms, lag)` [units of the signals, samples]. Every lag is judged on the same samples. No
/// sample to compare, or a signal that is not finite there at any lag, gives
/// `(f64::INFINITY, first lag)`: counted as worse than anything.
pub fn aligned_rms(
    truth: &[f64],
    signal: &[f64],
    lags: RangeInclusive<usize>,
    from: usize,
) -> (f64, usize) {
    let n = truth.len().min(signal.len());
    let (lo, hi) = (*lags.start(), *lags.end());
    let start = from.max(hi);
    let mut best = (f64::INFINITY, lo);
    if start >= n || lo > hi {
        return best;
    }
    let count = (n - start) as f64;
    for lag in lags {
        let sse: f64 = signal[start..n]
            .iter()
            .zip(&truth[start - lag..n - lag])
            .map(|(s, t)| (s - t) * (s - t))
            .sum();
        let rms = (sse / count).sqrt();
        if rms < best.0 {
            best = (rms, lag);
        }
    }
    best
}

/// The lags a compensator's output is searched over: its stated latency rounded, plus or
/// minus half of it (at least 4 samples), since a model's delay may be off the probe's by a
/// few samples.
pub fn output_lags(latency_samples: f64) -> RangeInclusive<usize> {
    let l = latency_samples.round().max(0.0) as usize;
    let w = (l / 2).max(4);
    l.saturating_sub(w)..=l + w
}

/// The lags the raw probe is searched over: from 0 to four times its low-frequency lag
/// behind the pressure plus 40 samples, at most a quarter of the record.
pub fn raw_lags(lag_samples: f64, n: usize) -> RangeInclusive<usize> {
    0..=((4.0 * lag_samples).ceil() as usize + 40).min(n / 4)
}

/// The samples left out at the start of a run: a tenth of it (the compensator starts from
/// equilibrium on the run's first sample, and settles).
pub fn settling(n: usize) -> usize {
    n / 10
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_best_lag_and_its_rms_by_hand() {
        // Lag 0 misses by 1 on four of the five samples compared (k = 1..5), lag 1 on one.
        let truth = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let signal = [0.0, 0.0, 1.0, 2.0, 3.0, 5.0];
        let (rms, lag) = aligned_rms(&truth, &signal, 0..=1, 0);
        assert_eq!(lag, 1);
        assert!((rms - (1.0f64 / 5.0).sqrt()).abs() < 1e-12, "{rms}");
        // Lag 0 alone: sqrt(4/5) on the same five samples.
        let (rms, lag) = aligned_rms(&truth, &signal, 0..=0, 1);
        assert_eq!(lag, 0);
        assert!((rms - (4.0f64 / 5.0).sqrt()).abs() < 1e-12, "{rms}");
    }

    #[test]
    fn a_delayed_copy_with_an_offset_is_found_at_its_delay() {
        let truth: Vec<f64> = (0..2000)
            .map(|k| (0.01 * k as f64).sin() + 0.3 * (0.137 * k as f64).cos())
            .collect();
        let delay = 7;
        let mut signal: Vec<f64> = (0..truth.len())
            .map(|k| truth[k.saturating_sub(delay)] + 0.25)
            .collect();
        // A start-up transient inside the settling margin is not counted.
        signal.iter_mut().take(100).for_each(|v| *v += 50.0);
        let (rms, lag) = aligned_rms(&truth, &signal, 0..=20, 200);
        assert_eq!(lag, delay);
        assert!((rms - 0.25).abs() < 1e-12, "{rms}");
        // Counted from 0, the transient shows.
        assert!(aligned_rms(&truth, &signal, 0..=20, 0).0 > 5.0);
        // A window that stops short of the delay gives its nearest lag and a larger error.
        let (short, lag) = aligned_rms(&truth, &signal, 0..=5, 200);
        assert_eq!(lag, 5);
        // (The two-sample difference adds sqrt(0.0819^2 + 0.02^2) / sqrt(2) in quadrature.)
        assert!(short > 0.255, "{short}");
        // The window around a stated latency of 7 holds it.
        assert!(output_lags(7.0).contains(&delay));
        assert_eq!(output_lags(0.0), 0..=4);
        assert_eq!(output_lags(40.0), 20..=60);
    }

    #[test]
    fn nothing_to_compare_or_a_nan_is_worse_than_anything() {
        let truth = [1.0; 50];
        let mut signal = [1.0; 50];
        signal[30] = f64::NAN;
        assert_eq!(aligned_rms(&truth, &signal, 0..=3, 10).0, f64::INFINITY);
        assert_eq!(aligned_rms(&truth, &truth, 0..=60, 0).0, f64::INFINITY);
        assert_eq!(aligned_rms(&truth, &truth, 0..=3, 0), (0.0, 0));
        assert_eq!(raw_lags(0.0, 1000), 0..=40);
        assert_eq!(raw_lags(100.0, 1000), 0..=250);
    }
}
