//! The noise model beside the dynamics: an autoregressive model `D(q) v[k] = e[k]` of what the
//! dynamics leave, `v = y - G u`, with `e` white (a Box-Jenkins structure whose noise
//! numerator is 1). Owns its estimate (Levinson-Durbin on the residual's autocorrelation, the
//! order by Akaike's criterion) and the one-step-ahead prediction error it gives,
//! `eps = D(q) (y - G u)`: for white residuals `D = 1` and that error is the simulation
//! error; for coloured ones it is the part of the error no predictor can remove.

use serde::{Deserialize, Serialize};

/// Highest order tried for the noise model.
pub const MAX_NOISE_ORDER: usize = 4;

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

/// `D(q) x`: the one-step-ahead prediction error of `x` under the noise model (the first `p`
/// samples use the samples there are).
#[must_use]
pub fn whiten(ar: &[f64], x: &[f64]) -> Vec<f64> {
    let d: Vec<f64> = std::iter::once(1.0).chain(ar.iter().copied()).collect();
    crate::model::filter(&d, &[], 0, x)
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|a| a * a).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn white(n: usize, seed: u64) -> Vec<f64> {
        crate::testing::gaussian(n, seed)
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
}
