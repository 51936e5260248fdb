//! The identified probe model and what the host computes from it.
//!
//! This module owns [`Model`] (sample rate, delay, `a`, `b` in the crate's one sign convention,
//! see [`crate::board::compensator`]), what can be computed from it on the host (simulation from the
//! reference, DC gain, poles and zeros, compensation through the board's code), and the fit's
//! report ([`FitReport`]) with its identification [`Method`]; the model file that stores them
//! is [`crate::file`].

use serde::{Deserialize, Serialize};

use crate::board::compensator::{Compensator, InverseCoefficients, Sample};
use crate::error::{Error, Result};
use crate::fit::FitError;
use crate::poly::{self, Complex};

mod report;
pub use report::{
    quoted, two_digits, DelayRow, FitReport, Method, NoiseOrigin, OrderRow, PredictionFloor,
    ResonanceUncertainty, Source, TestRole, Uncertainty,
};

/// Largest model order the host compensator handles.
pub const MAX_ORDER: usize = 16;

/// A mode's free response ends within a record when its motion falls below this share of its
/// start by the record's last sample (`e^-5`, five time constants): only such modes start a
/// record that does not start at rest ([`Model::fit_free_response`]).
pub const FREE_RESPONSE_ENDS: f64 = 6.737_946_999_085_467e-3;

/// A discrete probe model:
/// `y[k] = sum_{i=0..m} b[i] u[k-i-d] - sum_{i=1..m} a[i] y[k-i]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Sample rate in Hz the coefficients belong to.
    pub fs: f64,
    /// Delay `d` in samples.
    pub delay: usize,
    /// Denominator `[a1..am]` (no leading one).
    pub a: Vec<f64>,
    /// Numerator `[b0..bm]`.
    pub b: Vec<f64>,
}

impl Model {
    /// Model order `m`.
    #[must_use]
    pub fn order(&self) -> usize {
        self.a.len().max(self.b.len().saturating_sub(1))
    }

    /// SHA-256 of the model's numbers (`fs`, `delay`, `a`, `b`, each float by its IEEE bits),
    /// lower-case hex: what a stored compensator names as the model it was designed for, so
    /// that a model edited after its design is never exported with the old compensator.
    #[must_use]
    pub fn fingerprint(&self) -> String {
        use sha2::{Digest, Sha256};
        let mut h = Sha256::new();
        h.update(self.fs.to_bits().to_le_bytes());
        h.update((self.delay as u64).to_le_bytes());
        for c in [&self.a, &self.b] {
            h.update((c.len() as u64).to_le_bytes());
            for v in c {
                h.update(v.to_bits().to_le_bytes());
            }
        }
        h.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Steady-state gain `sum b / (1 + sum a)` (1 for a calibrated probe).
    #[must_use]
    pub fn dc_gain(&self) -> f64 {
        self.b.iter().sum::<f64>() / (1.0 + self.a.iter().sum::<f64>())
    }

    /// Group delay at zero frequency in samples, the delay included: `d + sum k b_k / sum b_k -
    /// sum k a_k / (1 + sum a_k)`, how late the probe follows a slow signal. `None` when the DC
    /// gain is zero or not finite.
    #[must_use]
    pub fn dc_group_delay(&self) -> Option<f64> {
        let moment = |p: &[f64]| p.iter().enumerate().map(|(k, c)| k as f64 * c).sum::<f64>();
        let sb = self.b.iter().sum::<f64>();
        let den = self.denominator();
        let sa = den.iter().sum::<f64>();
        let tau = self.delay as f64 + moment(&self.b) / sb - moment(&den) / sa;
        (sb.abs() > 1e-300 && sa.abs() > 1e-300 && tau.is_finite()).then_some(tau)
    }

    /// Denominator as a polynomial in `z^-1`: `[1, a1, ..., am]`.
    #[must_use]
    pub fn denominator(&self) -> Vec<f64> {
        std::iter::once(1.0).chain(self.a.iter().copied()).collect()
    }

    /// Poles (roots of `A`), largest magnitude first.
    ///
    /// # Errors
    /// [`crate::poly::PolyError`] if the eigenvalue solver fails.
    pub fn poles(&self) -> Result<Vec<Complex>> {
        poly::roots(&self.denominator())
    }

    /// Zeros (roots of `B`, without the delay's zeros at the origin), largest magnitude first.
    ///
    /// # Errors
    /// [`crate::poly::PolyError`] if the eigenvalue solver fails (or `b` is zero).
    pub fn zeros(&self) -> Result<Vec<Complex>> {
        poly::roots(&self.b)
    }

    /// Fails with [`Error::UnstableModel`] naming the pole when a pole is on or outside the
    /// unit circle.
    ///
    /// # Errors
    /// As described.
    pub fn check_stable(&self, context: &str) -> Result<()> {
        if let Some(p) = self.poles()?.first() {
            if p.norm() >= 1.0 {
                return Err(Error::UnstableModel {
                    context: context.to_string(),
                    pole: poly::format_root(*p),
                    radius: p.norm(),
                    note: String::new(),
                });
            }
        }
        Ok(())
    }

    /// Fails with [`Error::UnstableInverse`] naming the zero when a zero of `B` is on or outside
    /// the unit circle (the direct inverse would diverge).
    ///
    /// # Errors
    /// As described.
    pub fn check_invertible(&self, context: &str) -> Result<()> {
        if let Some(z) = self.zeros()?.first() {
            if z.norm() >= 1.0 {
                return Err(Error::UnstableInverse {
                    context: context.to_string(),
                    zero: poly::format_root(*z),
                    radius: z.norm(),
                });
            }
        }
        Ok(())
    }

    /// The model's output for the input `u`, starting in equilibrium with its resting level
    /// ([`resting_level`]: a step test starts from a steady state).
    #[must_use]
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        self.simulate_from(u, resting_level(u))
    }

    /// The model's output for the input `u`, starting in equilibrium with the input level
    /// `u0` (`u[0]` makes it the exact inverse of [`Model::compensate`], which starts in
    /// equilibrium with `y[0]`).
    #[must_use]
    pub fn simulate_from(&self, u: &[f64], u0: f64) -> Vec<f64> {
        let y0 = self.dc_gain() * u0;
        let dev: Vec<f64> = u.iter().map(|v| v - u0).collect();
        let mut y = filter(&self.b, &self.a, self.delay, &dev);
        for v in &mut y {
            *v += y0;
        }
        y
    }

    /// The model's output for `u` as it explains the probe's `y`: [`Model::simulate`] for a
    /// record that starts at rest (a quiet segment before its step); for one that does not
    /// (a traverse caught among its wakes: [`crate::fit::step::quiet_until`] finds no quiet
    /// segment), with the free response that best explains `y` added
    /// ([`Model::add_free_response`]). A simulation from rest cannot know where the probe was
    /// when such a record began: a slow probe misses its first tenths of a second by far more
    /// than its noise (a capillary caught mid-traverse can start hundreds of pascals off and
    /// come within its noise only after some tenths of a second). Estimating the initial
    /// state is what MATLAB's `compare` does by default.
    #[must_use]
    pub fn simulate_matched(&self, u: &[f64], y: &[f64]) -> Vec<f64> {
        self.simulate_matched_from(u, y, crate::fit::step::quiet_until(u) != 0)
    }

    /// As [`Model::simulate_matched`], told whether the record starts at rest
    /// (`quiet_until(u) != 0`): for a search that simulates one record under many models,
    /// which need not find its step again each time.
    #[must_use]
    pub fn simulate_matched_from(&self, u: &[f64], y: &[f64], at_rest: bool) -> Vec<f64> {
        let mut ym = self.simulate(u);
        if !at_rest {
            self.add_free_response(&mut ym, y);
        }
        ym
    }

    /// Adds to a simulation `ym` of the probe's `y` the model's free response (the motion of
    /// its poles from an initial state) that best explains what `ym` leaves of `y`
    /// ([`Model::fit_free_response`] with no other columns).
    pub fn add_free_response(&self, ym: &mut [f64], y: &[f64]) {
        let _ = self.fit_free_response(ym, y, &[]);
    }

    /// The poles whose free response ends within `n` samples (below [`FREE_RESPONSE_ENDS`] of
    /// its start), one of each complex pair: what starts a record that is not at rest. `None`
    /// for a model with a pole on or outside the unit circle.
    #[must_use]
    pub fn ending_poles(&self, n: usize) -> Option<Vec<Complex>> {
        let poles = self.poles().ok()?;
        let ends = |p: &Complex| (n as f64) * p.norm().ln() < FREE_RESPONSE_ENDS.ln();
        (!poles.iter().any(|p| p.norm().is_nan() || p.norm() >= 1.0)).then(|| {
            poles
                .into_iter()
                .filter(|p| p.im >= 0.0 && ends(p))
                .collect()
        })
    }

    /// Fits to what the simulation `ym` leaves of the probe's `y` the model's free response
    /// and the `extra` columns (each a function of the sample index: a level, a ramp) together,
    /// by least squares (column-pivoted QR); adds the free response to `ym` and returns the
    /// extra columns' coefficients. Fitted together, a slow free response does not take part
    /// of a level it cannot hold to the end of the record.
    ///
    /// The free response is that of the modes that end within the record (a pole whose motion
    /// falls below [`FREE_RESPONSE_ENDS`] of its start by the last sample; a complex pair
    /// gives two columns): a mode slower than that is, over the record, a level or a ramp, and
    /// would take a drift or an offset as its initial state (a capillary's slowest pole can
    /// take a traverse's drift off it). `None`, with `ym` as it was, for a model with a pole
    /// on or outside the unit circle, or a record that does not determine the fit.
    pub fn fit_free_response(
        &self,
        ym: &mut [f64],
        y: &[f64],
        extra: &[&dyn Fn(usize) -> f64],
    ) -> Option<Vec<f64>> {
        let n = ym.len().min(y.len());
        let ending = self.ending_poles(n)?;
        let columns = ending
            .iter()
            .map(|p| if p.im > 1e-12 { 2 } else { 1 })
            .sum::<usize>();
        if columns + extra.len() == 0 || n < 4 * (columns + extra.len()) {
            return None;
        }
        let mut x = faer::Mat::<f64>::zeros(n, columns + extra.len());
        let mut j = 0;
        for p in &ending {
            let mut z = Complex::new(1.0, 0.0);
            for k in 0..n {
                x[(k, j)] = z.re;
                if p.im > 1e-12 {
                    x[(k, j + 1)] = z.im;
                }
                z *= *p;
            }
            j += if p.im > 1e-12 { 2 } else { 1 };
        }
        for (i, column) in extra.iter().enumerate() {
            for k in 0..n {
                x[(k, columns + i)] = column(k);
            }
        }
        let t = faer::Mat::<f64>::from_fn(n, 1, |k, _| y[k] - ym[k]);
        let c = crate::fit::arx::lstsq(&x, &t, "the free response").ok()?;
        for (k, v) in ym.iter_mut().take(n).enumerate() {
            *v += (0..columns).map(|j| c[j] * x[(k, j)]).sum::<f64>();
        }
        Some(c[columns..].to_vec())
    }

    /// Reconstructs the reference from the probe's `y` with the board's compensator in
    /// arithmetic `T`; sample `k` of the result estimates `u[k - d]`. Starts in equilibrium
    /// with `y[0]`.
    ///
    /// # Errors
    /// [`Error::UnstableInverse`] naming the zero when `B` has a zero on or outside the unit
    /// circle, or [`Error::InvalidArgument`] when the order exceeds [`MAX_ORDER`].
    pub fn compensate<T: Sample>(&self, y: &[f64]) -> Result<Vec<f64>> {
        self.check_invertible("compensate")?;
        match self.order() {
            0..=2 => self.compensate_with::<T, 2>(y),
            3..=4 => self.compensate_with::<T, 4>(y),
            5..=8 => self.compensate_with::<T, 8>(y),
            9..=MAX_ORDER => self.compensate_with::<T, MAX_ORDER>(y),
            m => Err(Self::too_high(m)),
        }
    }

    /// The whole record through one compensator, without a call through a pointer per sample.
    fn compensate_with<T: Sample, const M: usize>(&self, y: &[f64]) -> Result<Vec<f64>> {
        let mut c = self.started::<T, M>(y.first().copied().unwrap_or(0.0))?;
        Ok(y.iter().map(|&v| c.push(T::from_f64(v)).to_f64()).collect())
    }

    /// The board's compensator for this model, started in equilibrium with `first`.
    fn started<T: Sample, const M: usize>(&self, first: f64) -> Result<Compensator<T, M>> {
        let coefficients = InverseCoefficients::<T, M>::new(&self.b, &self.a)
            .map_err(|error| FitError::Compensator { error })?;
        Ok(Compensator::from_coefficients(
            coefficients,
            T::from_f64(first),
        ))
    }

    fn too_high(m: usize) -> Error {
        Error::InvalidArgument {
            what: "model order",
            message: format!("order {m} exceeds the largest supported order {MAX_ORDER}"),
        }
    }

    /// [`Model::compensate`] one sample at a time, started in equilibrium with `first`.
    ///
    /// # Errors
    /// As [`Model::compensate`].
    pub fn compensator<T: Sample + 'static>(
        &self,
        first: f64,
    ) -> Result<Box<dyn FnMut(f64) -> f64>> {
        self.check_invertible("compensate")?;
        match self.order() {
            0..=2 => self.compensator_with::<T, 2>(first),
            3..=4 => self.compensator_with::<T, 4>(first),
            5..=8 => self.compensator_with::<T, 8>(first),
            9..=MAX_ORDER => self.compensator_with::<T, MAX_ORDER>(first),
            m => Err(Self::too_high(m)),
        }
    }

    fn compensator_with<T: Sample + 'static, const M: usize>(
        &self,
        first: f64,
    ) -> Result<Box<dyn FnMut(f64) -> f64>> {
        let mut c = self.started::<T, M>(first)?;
        Ok(Box::new(move |v| c.push(T::from_f64(v)).to_f64()))
    }
}

/// `y = q^-d B/A x` with zero initial conditions (direct form I, f64).
#[must_use]
pub fn filter(b: &[f64], a: &[f64], delay: usize, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    // From `warm` on every term exists: the same sums in the same order, without the tests.
    let warm = (b.len() + delay).max(a.len()).max(1).min(x.len());
    for k in 0..warm {
        let mut acc = 0.0;
        for (i, bi) in b.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + delay) {
                acc += bi * x[j];
            }
        }
        for (i, ai) in a.iter().enumerate() {
            if let Some(j) = k.checked_sub(i + 1) {
                acc -= ai * y[j];
            }
        }
        y[k] = acc;
    }
    // The recursion's critical path is the newest output alone: the numerator's sum and the
    // older outputs' terms do not wait for it.
    steady(b, a, delay, x, &mut y, warm);
    y
}

/// The steady part of [`filter`], from sample `warm` on (where every term exists), with the
/// orders the fits use unrolled (the same sums in the same order).
fn steady(b: &[f64], a: &[f64], delay: usize, x: &[f64], y: &mut [f64], warm: usize) {
    macro_rules! fixed {
        ($($m:literal),*) => {
            match (b.len(), a.len()) {
                $(
                    (nb, $m) if nb == $m => {
                        if let (Ok(b), Ok(a)) = (<&[f64; $m]>::try_from(b), <&[f64; $m]>::try_from(a)) {
                            return steady_fixed(b, a, delay, x, y, warm);
                        }
                    }
                    (nb, $m) if nb == $m + 1 => {
                        if let (Ok(b), Ok(a)) = (<&[f64; $m + 1]>::try_from(b), <&[f64; $m]>::try_from(a)) {
                            return steady_fixed(b, a, delay, x, y, warm);
                        }
                    }
                    (1, $m) => {
                        if let (Ok(b), Ok(a)) = (<&[f64; 1]>::try_from(b), <&[f64; $m]>::try_from(a)) {
                            return steady_fixed(b, a, delay, x, y, warm);
                        }
                    }
                )*
                _ => {}
            }
        };
    }
    fixed!(1, 2, 3, 4, 5, 6, 7, 8);
    let (a0, older) = a.split_first().map_or((0.0, &[][..]), |(a0, r)| (*a0, r));
    for k in warm..x.len() {
        let mut fir = 0.0;
        for (bi, xj) in b.iter().zip(x[..=k - delay].iter().rev()) {
            fir += bi * xj;
        }
        let mut tail = 0.0;
        for (ai, yj) in older.iter().zip(y[..k - 1].iter().rev()) {
            tail += ai * yj;
        }
        y[k] = (fir - tail) - a0 * y[k - 1];
    }
}

/// [`steady`] for `NB` numerator and `M >= 1` denominator coefficients.
fn steady_fixed<const NB: usize, const M: usize>(
    b: &[f64; NB],
    a: &[f64; M],
    delay: usize,
    x: &[f64],
    y: &mut [f64],
    warm: usize,
) {
    // From `warm` on, `k >= NB + delay` and `k >= M`: every index below is in range.
    for k in warm..x.len() {
        let Some(xs) = x.get(k + 1 - NB - delay..=k - delay) else {
            return;
        };
        let Some(ys) = y.get(k - M..k) else {
            return;
        };
        let mut fir = 0.0;
        for (bi, xj) in b.iter().zip(xs.iter().rev()) {
            fir += bi * xj;
        }
        let mut tail = 0.0;
        for (ai, yj) in a[1..].iter().zip(ys[..M - 1].iter().rev()) {
            tail += ai * yj;
        }
        y[k] = (fir - tail) - a[0] * ys[M - 1];
    }
}

/// [`filter`] of two signals by the same all-pole `1 / A` (numerator 1, no delay), the two
/// recursions interleaved in one loop: the same numbers as two calls, in about the time of one
/// (each recursion waits on its newest output; the other fills the wait).
#[must_use]
pub fn allpole_pair(a: &[f64], x1: &[f64], x2: &[f64]) -> (Vec<f64>, Vec<f64>) {
    macro_rules! fixed {
        ($($m:literal),*) => {
            $(
                if let Ok(a) = <&[f64; $m]>::try_from(a) {
                    if x1.len() == x2.len() && x1.len() > $m {
                        return allpole_pair_fixed(a, x1, x2);
                    }
                }
            )*
        };
    }
    fixed!(1, 2, 3, 4, 5, 6, 7, 8);
    (filter(&[1.0], a, 0, x1), filter(&[1.0], a, 0, x2))
}

/// [`allpole_pair`] for `M` coefficients and two signals of the same length, longer than `M`.
fn allpole_pair_fixed<const M: usize>(
    a: &[f64; M],
    x1: &[f64],
    x2: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let n = x1.len();
    // The first `M` samples as `filter` makes them (not every term exists yet).
    let mut y1 = vec![0.0; n];
    let mut y2 = vec![0.0; n];
    for (x, y) in [(x1, &mut y1), (x2, &mut y2)] {
        for k in 0..M.min(n) {
            let mut acc = 0.0;
            acc += 1.0 * x[k];
            for (i, ai) in a.iter().enumerate() {
                if let Some(j) = k.checked_sub(i + 1) {
                    acc -= ai * y[j];
                }
            }
            y[k] = acc;
        }
    }
    for k in M..n {
        let (Some(p1), Some(p2)) = (y1.get(k - M..k), y2.get(k - M..k)) else {
            break;
        };
        let fir1 = 0.0 + 1.0 * x1[k];
        let fir2 = 0.0 + 1.0 * x2[k];
        let (mut t1, mut t2) = (0.0, 0.0);
        for ((ai, q1), q2) in a[1..]
            .iter()
            .zip(p1[..M - 1].iter().rev())
            .zip(p2[..M - 1].iter().rev())
        {
            t1 += ai * q1;
            t2 += ai * q2;
        }
        let v1 = (fir1 - t1) - a[0] * p1[M - 1];
        let v2 = (fir2 - t2) - a[0] * p2[M - 1];
        y1[k] = v1;
        y2[k] = v2;
    }
    (y1, y2)
}

/// The level a record starts from: the mean of its leading samples up to the first that
/// leaves the start's scatter (at most 64), not the first sample alone, whose noise a slow
/// model would carry as a transient through the record. The start is the median of the first
/// 9 samples, the scatter 5x the noise its first differences show.
#[must_use]
pub fn resting_level(x: &[f64]) -> f64 {
    let head = x.get(..x.len().min(64)).unwrap_or(x);
    let Some(&first) = head.first() else {
        return 0.0;
    };
    let mut start: Vec<f64> = head.iter().take(9).copied().collect();
    start.sort_by(f64::total_cmp);
    let median = start.get(start.len() / 2).copied().unwrap_or(first);
    let mut d: Vec<f64> = head.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    d.sort_by(f64::total_cmp);
    // Median |difference| of white noise is 0.954 sigma.
    let sigma = d.get(d.len() / 2).copied().unwrap_or(0.0) / 0.954;
    let limit = 5.0 * sigma;
    let quiet: Vec<f64> = head
        .iter()
        .copied()
        .take_while(|v| (v - median).abs() <= limit)
        .collect();
    if quiet.is_empty() {
        first
    } else {
        quiet.iter().sum::<f64>() / quiet.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recursion as it was written before the unrolled orders: every term tested.
    fn filter_by_definition(b: &[f64], a: &[f64], delay: usize, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        let warm = (b.len() + delay).max(a.len()).max(1).min(x.len());
        let (a0, older) = a.split_first().map_or((0.0, &[][..]), |(a0, r)| (*a0, r));
        for k in 0..x.len() {
            if k < warm {
                let mut acc = 0.0;
                for (i, bi) in b.iter().enumerate() {
                    if let Some(j) = k.checked_sub(i + delay) {
                        acc += bi * x[j];
                    }
                }
                for (i, ai) in a.iter().enumerate() {
                    if let Some(j) = k.checked_sub(i + 1) {
                        acc -= ai * y[j];
                    }
                }
                y[k] = acc;
            } else {
                let mut fir = 0.0;
                for (bi, xj) in b.iter().zip(x[..=k - delay].iter().rev()) {
                    fir += bi * xj;
                }
                let mut tail = 0.0;
                for (ai, yj) in older.iter().zip(y[..k - 1].iter().rev()) {
                    tail += ai * yj;
                }
                y[k] = (fir - tail) - a0 * y[k - 1];
            }
        }
        y
    }

    /// A stable denominator of order `m` (poles at 0.9, 0.8, ... alternating in sign) and a
    /// signal with every kind of sample.
    fn case(m: usize) -> (Vec<f64>, Vec<f64>) {
        let mut a = vec![1.0];
        for i in 0..m {
            let p = (0.9 - 0.07 * i as f64) * if i % 2 == 0 { 1.0 } else { -1.0 };
            let mut next = vec![0.0; a.len() + 1];
            for (j, c) in a.iter().enumerate() {
                next[j] += c;
                next[j + 1] -= p * c;
            }
            a = next;
        }
        let x = (0..500)
            .map(|k| ((k * 7919) % 101) as f64 / 13.0 - 3.0 + if k > 40 { 1.0 } else { 0.0 })
            .collect();
        (a[1..].to_vec(), x)
    }

    #[test]
    fn the_unrolled_orders_are_the_same_sums_to_the_bit() {
        for m in 0..=9 {
            let (a, x) = case(m);
            for nb in [1, m, m + 1, m + 2] {
                let b: Vec<f64> = (0..nb).map(|i| 0.3 / (i as f64 + 1.5)).collect();
                for delay in [0, 1, 7] {
                    for len in [0, 1, m + delay, 500] {
                        let x = &x[..len];
                        let fast = filter(&b, &a, delay, x);
                        let slow = filter_by_definition(&b, &a, delay, x);
                        assert!(
                            fast.iter()
                                .map(|v| v.to_bits())
                                .eq(slow.iter().map(|v| v.to_bits())),
                            "m {m} nb {nb} delay {delay} len {len}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn allpole_pair_is_two_filters_to_the_bit() {
        for m in 0..=9 {
            let (a, x1) = case(m);
            let x2: Vec<f64> = x1.iter().rev().map(|v| 2.0 * v - 0.5).collect();
            for len in [0, 1, m, m + 1, 500] {
                let (y1, y2) = allpole_pair(&a, &x1[..len], &x2[..len]);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&y1), bits(&filter(&[1.0], &a, 0, &x1[..len])), "m {m}");
                assert_eq!(bits(&y2), bits(&filter(&[1.0], &a, 0, &x2[..len])), "m {m}");
            }
        }
    }

    #[test]
    fn a_record_that_does_not_start_at_rest_is_simulated_from_the_state_that_explains_it() {
        // A capillary (corners 3 and 50 Hz, 10 kHz) under a traverse: a tunnel's oscillation
        // and three wakes, recorded from the middle of it.
        let fs = 10_000.0;
        let m = crate::testing::overdamped(3.0, 50.0, fs, 17);
        let before = 2013;
        let whole = crate::testing::traverse(fs, 7.0, before, 6000);
        let u = &whole[before..];
        assert_eq!(crate::fit::step::quiet_until(u), 0);
        let y = crate::testing::with_noise(&m.simulate(&whole)[before..], 0.001, 3);
        // From rest the model misses the record's first tenth of a second by far more than the
        // noise; from the state that explains the record it leaves the noise (the error of
        // the true probe's own output against the record).
        let from_rest = crate::fit::nrmse_of(&y, &m.simulate(u));
        let matched = crate::fit::nrmse_of(&y, &m.simulate_matched(u, &y));
        let clean = &m.simulate(&whole)[before..];
        let noise = crate::fit::nrmse_of(&y, clean);
        assert!(from_rest > 5.0 * noise, "{from_rest}");
        assert!(matched < 1.2 * noise, "{matched}");
        // A mode slower than the record is a level or a ramp over it: its free response is not
        // fitted, and a drift on the probe stays in what the model leaves (with that mode's
        // free response it would go: 0.9999^k is a ramp over 6000 samples).
        let creeping = Model {
            a: vec![-(0.9999 + 0.98), 0.9999 * 0.98],
            b: vec![0.0, 0.6 * 0.0001 * 0.02, 0.4 * 0.0001 * 0.02],
            ..m.clone()
        };
        let drifting: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(k, v)| v + 1e-5 * k as f64)
            .collect();
        let taken: Vec<f64> = creeping
            .simulate_matched(u, &drifting)
            .iter()
            .zip(creeping.simulate_matched(u, &y))
            .map(|(a, b)| a - b)
            .collect();
        let end = taken.last().copied().unwrap_or(f64::NAN);
        assert!(end.abs() < 0.1 * 1e-5 * 6000.0, "{end}");
        // A step test starts at rest: simulated from rest, as it always was.
        let step: Vec<f64> = (0..4000).map(|k| f64::from(u8::from(k >= 500))).collect();
        let y = crate::testing::with_noise(&m.simulate(&step), 0.001, 4);
        assert_eq!(m.simulate_matched(&step, &y), m.simulate(&step));
        // An unstable model's free response is not fitted.
        let unstable = Model {
            a: vec![-2.1, 1.1],
            ..m.clone()
        };
        assert_eq!(
            unstable.simulate_matched(u, &y[..u.len().min(y.len())]),
            unstable.simulate(u)
        );
    }

    #[test]
    fn a_deviation_has_two_significant_digits_and_the_value_its_decimal_place() {
        assert_eq!(quoted(112.6312, 0.0312, " +/- "), "112.631 +/- 0.031");
        assert_eq!(quoted(0.32004, 0.00041, " +/- "), "0.32004 +/- 0.00041");
        assert_eq!(quoted(1523.4, 27.0, " +/- "), "1523 +/- 27");
        assert_eq!(quoted(0.5, 0.0, " +/- "), "0.5000");
        assert_eq!(quoted(0.5, f64::NAN, " +/- "), "0.5000");
        assert_eq!(two_digits(0.004489), "0.0045");
    }

    /// A role is stored as the same word it always was, both ways, in JSON and in a model
    /// file; another word is refused with the words there are.
    #[test]
    fn a_test_role_round_trips_by_its_name_and_an_unknown_one_is_refused() {
        #[derive(Debug, PartialEq, Serialize, Deserialize)]
        struct Row {
            role: TestRole,
        }
        for (role, name) in [
            (TestRole::Estimation, "estimation"),
            (TestRole::Validation, "validation"),
        ] {
            assert_eq!(role.as_str(), name);
            assert_eq!(role.to_string(), name);
            assert_eq!(format!("{role:<11}|"), format!("{name:<11}|"));
            let json = serde_json::to_string(&role).unwrap();
            assert_eq!(json, format!("\"{name}\""));
            assert_eq!(serde_json::from_str::<TestRole>(&json).unwrap(), role);
            let toml_text = toml::to_string(&Row { role }).unwrap();
            assert_eq!(toml_text, format!("role = \"{name}\"\n"));
            assert_eq!(toml::from_str::<Row>(&toml_text).unwrap(), Row { role });
        }
        assert_eq!(TestRole::of_index(0), TestRole::Estimation);
        assert_eq!(TestRole::of_index(1), TestRole::Validation);
        assert_eq!(TestRole::of_index(7), TestRole::Validation);
        let err = serde_json::from_str::<TestRole>("\"training\"").unwrap_err();
        assert!(
            err.to_string()
                .contains("unknown test role `training`: one of estimation, validation"),
            "{err}"
        );
        assert!(toml::from_str::<Row>("role = \"Estimation\"\n").is_err());
    }

    fn m2() -> Model {
        Model {
            fs: 1000.0,
            delay: 3,
            a: vec![-1.5, 0.7],
            b: vec![0.1, 0.08, 0.02],
        }
    }

    #[test]
    fn dc_group_delay_is_how_late_a_slow_ramp_is_followed() {
        // One pole at 0.9 behind one sample of delay: 1 + 0.9 / 0.1 = 10 samples.
        let m = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-0.9],
            b: vec![0.1],
        };
        let tau = m.dc_group_delay().unwrap();
        assert!((tau - 10.0).abs() < 1e-12, "{tau}");
        // The simulated response to a ramp settles `tau` samples behind it.
        let u: Vec<f64> = (0..400).map(f64::from).collect();
        let y = filter(&m.b, &m.a, m.delay, &u);
        assert!((u[399] - y[399] - tau).abs() < 1e-6);
        // The same for the second-order model, measured the same way.
        let m = m2();
        let y = filter(&m.b, &m.a, m.delay, &u);
        let lag = u[399] - y[399] / m.dc_gain();
        assert!((lag - m.dc_group_delay().unwrap()).abs() < 1e-6, "{lag}");
    }

    #[test]
    fn the_resting_level_is_the_quiet_start_not_its_first_sample() {
        // Noise of std 0.05 about 2 (uniform, scaled), its first sample 3 levels off, then a
        // step to 5 after 40 samples.
        let mut state = 7u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05 * 12f64.sqrt()
        };
        let mut x: Vec<f64> = (0..80)
            .map(|k| if k < 40 { 2.0 } else { 5.0 } + noise())
            .collect();
        x[0] = 2.15;
        let level = resting_level(&x);
        let quiet = x[..40].iter().sum::<f64>() / 40.0;
        assert!((level - quiet).abs() < 1e-12, "{level} vs {quiet}");
        assert!((level - 2.0).abs() < 0.03, "{level}");
        // A step at the very start leaves the first sample.
        assert_eq!(
            resting_level(&[1.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0]),
            1.0
        );
        assert_eq!(resting_level(&[]), 0.0);
    }

    #[test]
    fn simulate_starts_in_equilibrium_and_delays() {
        let m = m2();
        let g = m.dc_gain();
        let u = [2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0, 3.0];
        let y = m.simulate(&u);
        // Flat until the step has travelled the delay.
        for v in &y[..6] {
            assert!((v - 2.0 * g).abs() < 1e-12);
        }
        assert!((y[6] - (2.0 * g + 0.1)).abs() < 1e-12);
    }

    #[test]
    fn compensate_inverts_simulate() {
        let m = m2();
        let u: Vec<f64> = (0..200).map(|k| ((k as f64) * 0.07).sin() + 1.0).collect();
        let y = m.simulate(&u);
        let uh = m.compensate::<f64>(&y).unwrap();
        for k in m.delay..u.len() {
            assert!((uh[k] - u[k - m.delay]).abs() < 1e-9);
        }
    }

    #[test]
    fn unstable_model_is_named() {
        let m = Model {
            fs: 1.0,
            delay: 0,
            a: vec![-2.1],
            b: vec![1.0],
        };
        let e = m.check_stable("x").unwrap_err().to_string();
        assert!(e.contains("2.1") && e.contains("unstable"), "{e}");
        let m = Model {
            fs: 1.0,
            delay: 0,
            a: vec![-0.5],
            b: vec![1.0, -2.1],
        };
        let e = m.check_invertible("x").unwrap_err().to_string();
        assert!(e.contains("zero 2.1"), "{e}");
    }
}
