//! The fixed-lag Kalman smoother: the model's state space with the signal and noise states,
//! the steady-state Riccati solution, the smoother's gains and error for every lag, and its
//! realisation as second-order sections.

use std::f64::consts::PI;

use faer::linalg::solvers::Solve;
use faer::Mat;

use super::{NoiseModel, SignalPrior};
use crate::design::inverse::{cascade_response, numerator_after_delay, to_sections, Zpk};
use crate::design::DesignError;
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::poly::{self, Complex};

/// The delay-free model's state space with the signal and noise states appended.
struct Augmented {
    /// Transition.
    phi: Mat<f64>,
    /// Measurement row.
    h: Vec<f64>,
    /// Process noise covariance (diagonal).
    q: Vec<f64>,
    /// White measurement noise variance.
    r: f64,
    /// Index of the pressure state.
    iu: usize,
    /// Delay in samples of the model, leading zero coefficients of `b` included.
    delay: usize,
}

fn augmented(model: &Model, noise: &NoiseModel, prior: &SignalPrior) -> Result<Augmented> {
    let (lead, b) = numerator_after_delay(model, "optimal compensator")?;
    // The model as a cascade of second-order sections (poles nearest the circle first, each
    // with its nearest zeros), each section in transposed direct form II: far better
    // conditioned than one companion form when poles crowd towards z = 1.
    let zpk = Zpk {
        zeros: poly::roots(b)?,
        poles: model.poles()?,
        gain: b.first().copied().unwrap_or(0.0),
    };
    let (cascade_gain, model_sections) = to_sections(&zpk);
    let nx = 2 * model_sections.len();
    let ar = noise.probe_ar_std > 0.0;
    let ramp = prior.increment_pole > 0.0;
    let n = nx + 1 + usize::from(ramp) + usize::from(ar);
    let iu = nx;
    let mut phi = Mat::<f64>::zeros(n, n);
    let mut h = vec![0.0; n];
    let mut q = vec![0.0; n];
    // The running signal as a row over the states plus a coefficient of u.
    let mut signal = vec![0.0; n];
    signal[iu] = cascade_gain;
    for (j, sec) in model_sections.iter().enumerate() {
        let [c0, c1, c2, a1, a2] = *sec;
        let (i1, i2) = (2 * j, 2 * j + 1);
        let mut out: Vec<f64> = signal.iter().map(|v| c0 * v).collect();
        out[i1] += 1.0;
        for k in 0..n {
            phi[(i1, k)] = c1 * signal[k] - a1 * out[k];
            phi[(i2, k)] = c2 * signal[k] - a2 * out[k];
        }
        phi[(i1, i2)] += 1.0;
        signal = out;
    }
    for (k, v) in signal.iter().enumerate() {
        h[k] = *v;
    }
    phi[(iu, iu)] = 1.0;
    if ramp {
        // u[k] = u[k-1] + v[k-1], v[k] = rho v[k-1] + w[k]: the same spectrum, with the
        // innovation on the increment alone (a diagonal process noise).
        let iv = iu + 1;
        phi[(iu, iv)] = 1.0;
        phi[(iv, iv)] = prior.increment_pole;
        q[iv] = prior.increment_std * prior.increment_std;
    } else {
        q[iu] = prior.increment_std * prior.increment_std;
    }
    if ar {
        let ic = iu + 1 + usize::from(ramp);
        let p = noise.probe_ar_pole;
        phi[(ic, ic)] = p;
        h[ic] = 1.0;
        q[ic] = noise.probe_ar_std * noise.probe_ar_std * (1.0 - p * p);
    }
    // A measurement without white noise makes the Riccati equation singular: keep a floor.
    let total = noise.probe_std().powi(2).max(1e-300);
    let r = (noise.probe_white_std * noise.probe_white_std).max(1e-6 * total);
    if !(prior.increment_std > 0.0 && r > 0.0 && q.iter().all(|v| v.is_finite())) {
        return Err(DesignError::NoiseLevels {
            prior_std: prior.increment_std,
            probe_std: noise.probe_std(),
        }
        .into());
    }
    Ok(Augmented {
        phi,
        h,
        q,
        r,
        iu,
        delay: model.delay + lead,
    })
}

/// Steady-state a-priori covariance of the Kalman filter of `sys`: the doubling algorithm's
/// solution when its closed loop is stable, else (a solution that is not the stabilising one,
/// seen with nearly cancelling poles and zeros) the plain Riccati recursion from the prior.
fn riccati(sys: &Augmented) -> Result<Mat<f64>> {
    if let Ok(x) = riccati_doubling(sys) {
        if closed_loop_radius(sys, &x) < 1.0 {
            return Ok(x);
        }
    }
    riccati_recursion(sys)
}

/// The steady-state filter of `sys` for the a-priori covariance `p`: the innovation variance
/// `s = h P h' + r`, the predictor gain `Kp = Phi P h' / s` and the closed loop
/// `A_cl = Phi - Kp h`.
fn filter_of(sys: &Augmented, p: &Mat<f64>) -> (f64, Vec<f64>, Mat<f64>) {
    let n = sys.h.len();
    let ph: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| p[(i, j)] * sys.h[j]).sum())
        .collect();
    let s = sys.h.iter().zip(&ph).map(|(a, b)| a * b).sum::<f64>() + sys.r;
    let kp: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|j| sys.phi[(i, j)] * ph[j]).sum::<f64>() / s)
        .collect();
    let a_cl = Mat::<f64>::from_fn(n, n, |i, j| sys.phi[(i, j)] - kp[i] * sys.h[j]);
    (s, kp, a_cl)
}

/// Spectral radius of the filter's closed loop for the covariance `p`.
fn closed_loop_radius(sys: &Augmented, p: &Mat<f64>) -> f64 {
    filter_of(sys, p)
        .2
        .eigenvalues()
        .map_or(f64::INFINITY, |e| {
            e.iter().map(|v| v.norm()).fold(0.0, f64::max)
        })
}

/// The Riccati recursion `P <- Phi (P - P h' h P / s) Phi' + Q` from `P = Q + I * scale`,
/// which converges to the stabilising solution (slowly when the closed loop is slow).
fn riccati_recursion(sys: &Augmented) -> Result<Mat<f64>> {
    let n = sys.h.len();
    let scale = sys.q.iter().fold(sys.r, |m, v| m.max(*v)) * 1e3;
    let mut p = Mat::<f64>::from_fn(n, n, |i, j| if i == j { sys.q[i] + scale } else { 0.0 });
    for _ in 0..2_000_000 {
        let ph: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| p[(i, j)] * sys.h[j]).sum())
            .collect();
        let s = sys.h.iter().zip(&ph).map(|(a, b)| a * b).sum::<f64>() + sys.r;
        let filtered = Mat::<f64>::from_fn(n, n, |i, j| p[(i, j)] - ph[i] * ph[j] / s);
        let mut next = &sys.phi * &filtered * sys.phi.transpose();
        for i in 0..n {
            next[(i, i)] += sys.q[i];
        }
        let change = (&next - &p).norm_max();
        let size = next.norm_max();
        if !size.is_finite() {
            break;
        }
        p = next;
        if change <= 1e-10 * size {
            return Ok(p);
        }
    }
    Err(not_converged())
}

/// The error of a Riccati solution that did not converge.
fn not_converged() -> Error {
    DesignError::RiccatiNotConverged.into()
}

/// The structure-preserving doubling algorithm on the dual control Riccati equation
/// `X = A' X (I + G X)^-1 A + Q`, `A = Phi'`, `G = h' h / r`.
fn riccati_doubling(sys: &Augmented) -> Result<Mat<f64>> {
    let n = sys.h.len();
    let mut a = sys.phi.transpose().to_owned();
    let mut g = Mat::<f64>::from_fn(n, n, |i, j| sys.h[i] * sys.h[j] / sys.r);
    let mut x = Mat::<f64>::from_fn(n, n, |i, j| if i == j { sys.q[i] } else { 0.0 });
    let eye = Mat::<f64>::identity(n, n);
    for _ in 0..200 {
        let w = &eye + &g * &x;
        let lu = w.partial_piv_lu();
        let wa = lu.solve(&a);
        let wg = lu.solve(&g);
        let a_next = &a * &wa;
        let g_next = &g + &a * &wg * a.transpose();
        let x_next = &x + a.transpose() * &x * &wa;
        let change = (&x_next - &x).norm_max();
        let size = x_next.norm_max();
        if !size.is_finite() {
            break;
        }
        a = a_next;
        g = g_next;
        // Keep the iterate symmetric against round-off.
        x = Mat::<f64>::from_fn(n, n, |i, j| 0.5 * (x_next[(i, j)] + x_next[(j, i)]));
        if change <= 1e-14 * size {
            return Ok(x);
        }
    }
    Err(not_converged())
}

/// The steady-state fixed-lag smoother of a model under a noise model and a signal prior.
pub struct Smoother {
    /// Closed-loop (predictor) transition `Phi - Kp h`.
    a_cl: Mat<f64>,
    /// Predictor gain `Phi P h' / s`.
    kp: Vec<f64>,
    /// Measurement row.
    pub(super) h: Vec<f64>,
    /// `e_u' P (A_cl')^i h' / s` for `i = 0, 1, ...` (grown on demand).
    gains: Vec<f64>,
    /// `(A_cl')^i h'`, the next column of the recursion.
    next: Vec<f64>,
    /// The pressure's row of `P`.
    p_u: Vec<f64>,
    /// Innovation variance.
    s: f64,
    /// Prediction error variance of the pressure.
    p_uu: f64,
    iu: usize,
    delay: usize,
}

impl Smoother {
    /// Solves the filter for `model`, `noise` and `prior`.
    ///
    /// # Errors
    /// [`DesignError::ZeroNumerator`] when the model has no numerator,
    /// [`DesignError::NoiseLevels`] when the levels are not positive,
    /// [`DesignError::RiccatiNotConverged`] when the Riccati equation does not converge.
    pub fn new(model: &Model, noise: &NoiseModel, prior: &SignalPrior) -> Result<Self> {
        let sys = augmented(model, noise, prior)?;
        let p = riccati(&sys)?;
        let n = sys.h.len();
        let (s, kp, a_cl) = filter_of(&sys, &p);
        Ok(Self {
            a_cl,
            kp,
            h: sys.h.clone(),
            gains: Vec::new(),
            next: sys.h.clone(),
            p_u: (0..n).map(|j| p[(sys.iu, j)]).collect(),
            s,
            p_uu: p[(sys.iu, sys.iu)],
            iu: sys.iu,
            delay: sys.delay,
        })
    }

    /// The model's delay (leading zeros of `b` included): the smoother's latency is this plus
    /// its lag.
    #[must_use]
    pub fn delay(&self) -> usize {
        self.delay
    }

    fn grow(&mut self, count: usize) {
        let n = self.h.len();
        while self.gains.len() < count {
            let g = self
                .p_u
                .iter()
                .zip(&self.next)
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / self.s;
            self.gains.push(g);
            // next <- A_cl' next.
            let v: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| self.a_cl[(j, i)] * self.next[j]).sum())
                .collect();
            self.next = v;
        }
    }

    /// Standard deviation of the error of `u_hat[k - lag | k]` for `lag = 0..=max_lag`.
    pub fn error_std(&mut self, max_lag: usize) -> Vec<f64> {
        self.grow(max_lag + 1);
        let mut var = self.p_uu;
        self.gains
            .iter()
            .take(max_lag + 1)
            .map(|g| {
                var -= g * g * self.s;
                var.max(0.0).sqrt()
            })
            .collect()
    }

    /// Impulse response of the smoother at `lag`, from the probe sample to `u_hat[k - lag]`,
    /// `count` samples long.
    fn impulse(&mut self, lag: usize, count: usize) -> Vec<f64> {
        self.grow(lag + 1);
        let n = self.h.len();
        let mut x = vec![0.0; n];
        // Innovations and predicted pressure of the last lag + 1 samples (newest last).
        let mut innovations = vec![0.0; lag + 1];
        let mut predicted = vec![0.0; lag + 1];
        let mut out = Vec::with_capacity(count);
        for k in 0..count {
            let y = if k == 0 { 1.0 } else { 0.0 };
            let e = y - self.h.iter().zip(&x).map(|(a, b)| a * b).sum::<f64>();
            innovations.rotate_left(1);
            predicted.rotate_left(1);
            if let Some(v) = innovations.last_mut() {
                *v = e;
            }
            if let Some(v) = predicted.last_mut() {
                *v = x.get(self.iu).copied().unwrap_or(0.0);
            }
            // u_hat[k-lag|k] = u_hat[k-lag|k-lag-1] + sum_i G_i e[k-lag+i].
            let smoothed: f64 = self
                .gains
                .iter()
                .zip(&innovations)
                .map(|(g, e)| g * e)
                .sum();
            out.push(predicted.first().copied().unwrap_or(0.0) + smoothed);
            let next: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| self.a_cl[(i, j)] * x[j]).sum::<f64>() + self.kp[i] * y)
                .collect();
            x = next;
        }
        out
    }

    /// The smoother at `lag` as a cascade `(gain, sections)` with the crate's sign convention.
    ///
    /// # Errors
    /// [`DesignError::KalmanEigenvalues`] or [`crate::poly::PolyError`] when the eigenvalues or
    /// the numerator's roots cannot be found, [`DesignError::SmootherSections`] when the
    /// sections do not reproduce the smoother's response to `1e-6`.
    pub fn realise(&mut self, lag: usize) -> Result<(f64, Vec<[f64; 5]>)> {
        let n = self.h.len();
        let poles = self
            .a_cl
            .eigenvalues()
            .map_err(|error| DesignError::KalmanEigenvalues { error })?;
        // Denominator prod (1 - p z^-1), real.
        let mut den = vec![Complex::new(1.0, 0.0)];
        for p in &poles {
            let mut next = den.clone();
            next.push(Complex::new(0.0, 0.0));
            for (i, d) in den.iter().enumerate() {
                if let Some(v) = next.get_mut(i + 1) {
                    *v -= *p * *d;
                }
            }
            den = next;
        }
        let den: Vec<f64> = den.iter().map(|c| c.re).collect();
        let degree = n + lag;
        let h = self.impulse(lag, degree + 1);
        let num: Vec<f64> = (0..=degree)
            .map(|k| {
                (0..=k)
                    .map(|i| {
                        h.get(i).copied().unwrap_or(0.0) * den.get(k - i).copied().unwrap_or(0.0)
                    })
                    .sum()
            })
            .collect();
        let big = num.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // Leading taps that vanish are a pure delay: at most one is expected (lag 0 with b0 = 0).
        let lead = num.iter().position(|v| v.abs() > 1e-13 * big).unwrap_or(0);
        let num_tail = num.get(lead..).unwrap_or(&[]);
        let zeros = poly::roots(num_tail)?;
        let zpk = Zpk {
            zeros,
            poles: poles.clone(),
            gain: num_tail.first().copied().unwrap_or(0.0),
        };
        let (gain, mut sections) = to_sections(&zpk);
        for _ in 0..lead {
            sections.push([0.0, 1.0, 0.0, 0.0, 0.0]);
        }
        // The sections must be the smoother: compare with the rational function N/D on a grid.
        for i in 1..64 {
            let w = PI * f64::from(i) / 64.0;
            let z = Complex::new(w.cos(), w.sin());
            let want = poly::eval(&num, z) / poly::eval(&den, z);
            let got = cascade_response(gain, &sections, z);
            if (want - got).norm() > 1e-6 * want.norm().max(1e-3 * big) {
                return Err(DesignError::SmootherSections {
                    lag,
                    error: (want - got).norm(),
                    frequency: w,
                }
                .into());
            }
        }
        Ok((gain, sections))
    }
}
