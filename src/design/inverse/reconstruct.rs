//! What a design does on a test: the reconstruction of the reference, and its error at the
//! best alignment (searched directly or by FFT on long records).

use super::{Design, Reconstruction};
use crate::error::Result;
use crate::fit::model::Model;
use crate::fit::Test;

/// The lags at which a compensator's output and the raw probe are compared with the
/// reference, `(output's, raw probe's)`. The raw probe: from 0 to the delay plus four times the
/// compensator's causal latency (at least 40 samples), whatever the compensator. The output:
/// its stated latency `nominal` plus or minus 4 samples, or plus or minus the part of the
/// latency beyond the delay when that is larger; a design that passes the probe on
/// ([`Design::passes_probe`]) is the raw probe, and is searched over the raw probe's lags.
#[must_use]
pub fn comparison_lags(
    design: Option<&Design>,
    nominal: usize,
    causal: usize,
    delay: usize,
) -> (
    std::ops::RangeInclusive<usize>,
    std::ops::RangeInclusive<usize>,
) {
    let raw = 0..=delay + 4 * causal.max(10);
    if design.is_some_and(Design::passes_probe) {
        return (raw.clone(), raw);
    }
    let w = nominal.saturating_sub(delay).max(4);
    (nominal.saturating_sub(w)..=nominal + w, raw)
}

/// Error of an estimate against a reference when the estimate lags by `lag` samples, searched
/// over `lags` for the best alignment: `(nrmse, lag)`, RMS over the range of the reference.
/// All lags are compared on the same samples.
#[must_use]
pub fn aligned_error(
    reference: &[f64],
    estimate: &[f64],
    lags: std::ops::RangeInclusive<usize>,
) -> (f64, usize) {
    let n = reference.len().min(estimate.len());
    let hi = (*lags.end()).min(n.saturating_sub(2));
    let (lo_v, hi_v) = reference
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let range = hi_v - lo_v;
    let lo = *lags.start();
    let count = n.saturating_sub(hi);
    if lo < hi && count > 0 && (hi - lo + 1).saturating_mul(count) > FFT_ALIGNMENT_WORK {
        return aligned_error_by_fft(reference, estimate, lo..=hi, range);
    }
    let mut best = (f64::INFINITY, 0);
    for lag in lo..=hi {
        let count = n - hi;
        let sse: f64 = (hi..n)
            .map(|k| {
                let e = estimate[k] - reference[k - lag];
                e * e
            })
            .sum();
        let e = (sse / count as f64).sqrt() / range;
        if e < best.0 {
            best = (e, lag);
        }
    }
    best
}

/// [`aligned_error`] on a run streamed one sample at a time, its length `n` and its
/// reference's range known beforehand (earlier passes over its file): each lag's sum of
/// squares kept as the samples pass, the reference's last samples in a ring as long as the
/// largest lag. The same sums in the same order as [`aligned_error`]'s direct search, so the
/// same figures; on a long record where [`aligned_error`] searches by FFT, the same figure
/// unless two lags tie within its rounding. Work: lags times samples.
#[derive(Debug, Clone)]
pub struct AlignedErrorStream {
    lo: usize,
    hi: usize,
    n: usize,
    range: f64,
    sse: Vec<f64>,
    ring: Vec<f64>,
    k: usize,
}

impl AlignedErrorStream {
    /// The search over `lags` on a run of `n` samples whose reference spans `range`.
    #[must_use]
    pub fn new(n: usize, lags: std::ops::RangeInclusive<usize>, range: f64) -> Self {
        let hi = (*lags.end()).min(n.saturating_sub(2));
        let lo = *lags.start();
        let count = if lo <= hi { hi - lo + 1 } else { 0 };
        Self {
            lo,
            hi,
            n,
            range,
            sse: vec![-0.0; count],
            ring: vec![0.0; 2 * (hi + 1)],
            k: 0,
        }
    }

    /// The next sample of the reference and of the estimate.
    pub fn push(&mut self, reference: f64, estimate: f64) {
        let k = self.k;
        self.k += 1;
        // Each value is kept twice, `cap` apart, so that the last `cap` values always lie in
        // one slice, oldest first: the reference `lag` samples back is at `pos + cap - lag`.
        let cap = self.hi + 1;
        let pos = k % cap;
        for at in [pos, pos + cap] {
            if let Some(r) = self.ring.get_mut(at) {
                *r = reference;
            }
        }
        if k < self.hi || k >= self.n || self.sse.is_empty() {
            return;
        }
        let Some(window) = self.ring.get(pos + cap - self.hi..=pos + cap - self.lo) else {
            return;
        };
        for (sse, r) in self.sse.iter_mut().zip(window.iter().rev()) {
            let e = estimate - r;
            *sse += e * e;
        }
    }

    /// `(nrmse, lag)` at the best alignment, as [`aligned_error`] gives it.
    #[must_use]
    pub fn finish(&self) -> (f64, usize) {
        let count = self.n - self.hi;
        let mut best = (f64::INFINITY, 0);
        for (i, sse) in self.sse.iter().enumerate() {
            let e = (sse / count as f64).sqrt() / self.range;
            if e < best.0 {
                best = (e, self.lo + i);
            }
        }
        best
    }
}

/// Above this many multiply-adds (lags times samples) [`aligned_error`] finds the best lag by
/// FFT cross-correlation; below it, by direct sums.
pub(crate) const FFT_ALIGNMENT_WORK: usize = 1 << 24;

/// [`aligned_error`] for long records: the squared error at each lag is `Σ e² + Σ r² − 2 Σ e r`,
/// its cross term for every lag at once by FFT blocks and the reference's energy by a running
/// sum; the best lag's error is then summed directly, so the figure is exact.
fn aligned_error_by_fft(
    reference: &[f64],
    estimate: &[f64],
    lags: std::ops::RangeInclusive<usize>,
    range: f64,
) -> (f64, usize) {
    let (lo, hi) = (*lags.start(), *lags.end());
    let n = reference.len().min(estimate.len());
    let (Some(e), Some(r)) = (estimate.get(hi..n), reference.get(..n - lo)) else {
        return (f64::INFINITY, lo);
    };
    // Σ_j e[j] r[s + j] for s = hi − lag, s in 0..=hi − lo.
    let cross = crate::fit::noise::lagged_products(e, r, (0.0, 0.0), hi - lo + 1);
    let ee: f64 = e.iter().map(|v| v * v).sum();
    // Σ r[s..s + len]² for s = 0, 1, ...: a sliding window.
    let len = e.len();
    let mut rr: f64 = r.iter().take(len).map(|v| v * v).sum();
    let mut sse = Vec::with_capacity(cross.len());
    for (s, c) in cross.iter().enumerate() {
        if s > 0 {
            let (out, inn) = (r.get(s - 1), r.get(s + len - 1));
            rr += inn.map_or(0.0, |v| v * v) - out.map_or(0.0, |v| v * v);
        }
        sse.push((ee + rr - 2.0 * c).max(0.0));
    }
    // The smallest lag among equals, as the direct search takes it.
    let (_, lag) = (lo..=hi).fold((f64::INFINITY, lo), |best, lag| match sse.get(hi - lag) {
        Some(&e) if e < best.0 => (e, lag),
        _ => best,
    });
    let sse: f64 = (hi..n)
        .map(|k| {
            let d = estimate[k] - reference[k - lag];
            d * d
        })
        .sum();
    ((sse / len as f64).sqrt() / range, lag)
}

/// Reconstruction error of `design` on one test (f64 arithmetic), against the raw probe.
///
/// # Errors
/// As [`Design::run`].
pub fn reconstruct(design: &Design, model: &Model, test: &Test<'_>) -> Result<Reconstruction> {
    reconstruct_with(design, model, test, 0.0)
}

/// [`reconstruct`] for a model with the `nonlinear-damping` effect: the compensator's output
/// plus the board's correction for the quadratic loss `nonlinear_gain` (s^2 per probe unit,
/// see [`crate::effects`]); with `nonlinear_gain = 0` exactly [`reconstruct`].
///
/// # Errors
/// As [`Design::run`] and [`Design::run_nonlinear_correction`].
pub fn reconstruct_with(
    design: &Design,
    model: &Model,
    test: &Test<'_>,
    nonlinear_gain: f64,
) -> Result<Reconstruction> {
    let mut u_hat = design.run::<f64>(test.y)?;
    if nonlinear_gain != 0.0 {
        let c = design.run_nonlinear_correction::<f64>(model.fs, nonlinear_gain, test.y)?;
        for (u, c) in u_hat.iter_mut().zip(c) {
            *u += c;
        }
    }
    let nominal = design.latency_samples.round().max(0.0) as usize;
    let (lags, raw_lags) = comparison_lags(Some(design), nominal, nominal, model.delay);
    let (e, lag) = aligned_error(test.u, &u_hat, lags);
    let (raw, _) = aligned_error(test.u, test.y, raw_lags);
    let range = test.u.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
        - test.u.iter().fold(f64::INFINITY, |m, v| m.min(*v));
    let model_part = design.budget.map(|b| {
        let explained = (b.total * b.total + b.reference * b.reference) / (range * range);
        (e * e - explained).max(0.0).sqrt()
    });
    Ok(Reconstruction {
        file: test.name.to_string(),
        nrmse_u_hat: e,
        nrmse_raw: raw,
        lag,
        range: Some(range),
        model_part,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ops::RangeInclusive;

    /// Streamed, the search gives the direct search's figure and lag, bit for bit, over lag
    /// ranges that start at 0 or later, are cut by the record's length, or are empty.
    #[test]
    fn the_streamed_search_is_the_direct_one() {
        let n = 3000;
        let noise = crate::testing::gaussian(n, 6);
        let reference: Vec<f64> = (0..n)
            .map(|k| if (k / 700) % 2 == 0 { 0.0 } else { 1.0 } + 0.01 * noise[k])
            .collect();
        // The reference 7 samples late, smoothed a little, with its own noise.
        let estimate: Vec<f64> = (0..n)
            .map(|k| {
                let r = |j: usize| reference.get(j).copied().unwrap_or(0.0);
                let k = k.saturating_sub(7);
                0.5 * r(k) + 0.25 * (r(k.saturating_sub(1)) + r(k + 1)) + 0.02 * noise[n - 1 - k]
            })
            .collect();
        let (lo, hi) = reference
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        for lags in [
            0..=40,
            3..=11,
            5..=5,
            2990..=3100,
            RangeInclusive::new(12, 4),
        ] {
            let direct = aligned_error(&reference, &estimate, lags.clone());
            let mut s = AlignedErrorStream::new(n, lags.clone(), hi - lo);
            for (r, e) in reference.iter().zip(&estimate) {
                s.push(*r, *e);
            }
            assert_eq!(s.finish(), direct, "{lags:?}");
        }
        assert_eq!(aligned_error(&reference, &estimate, 0..=40).1, 7);
    }
}
