//! The residual's correlations: its autocorrelation against what a correct model leaves
//! (with the Ljung-Box statistic), and its cross-correlation with the input's increments
//! against Bartlett's band.

use super::{mean, Autocorrelation, CrossCorrelation, Z99};

/// Chi-square survival function by the Wilson-Hilferty cube-root normal approximation
/// (relative error below 1e-2 in the tail for 30 degrees of freedom: enough for a verdict).
#[must_use]
pub fn chi2_survival(q: f64, dof: usize) -> f64 {
    let k = dof as f64;
    let z = ((q / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    0.5 * libm::erfc(z / std::f64::consts::SQRT_2)
}

/// Autocorrelation of `r` at lags `1..=lags`, judged against white noise.
#[must_use]
pub fn autocorrelation(r: &[f64], lags: usize) -> Autocorrelation {
    autocorrelation_against(r, &vec![0.0; lags], 1.0)
}

/// Autocorrelation of `r` at lags `1..=expected.len()`, judged against the expected
/// autocorrelation `expected` of a noise whose Bartlett factor is `bartlett`.
#[must_use]
pub fn autocorrelation_against(r: &[f64], expected: &[f64], bartlett: f64) -> Autocorrelation {
    let lags = expected.len();
    let n = r.len();
    let m = mean(r);
    let c0: f64 = r.iter().map(|v| (v - m) * (v - m)).sum();
    let values: Vec<f64> = (1..=lags)
        .map(|k| {
            if k >= n || c0 == 0.0 {
                return 0.0;
            }
            r.iter()
                .zip(&r[k..])
                .map(|(a, b)| (a - m) * (b - m))
                .sum::<f64>()
                / c0
        })
        .collect();
    let nf = n as f64;
    let c = bartlett.max(1.0);
    let band = Z99 * (c / nf).sqrt();
    let ljung_box = nf
        * (nf + 2.0)
        * values
            .iter()
            .zip(expected)
            .enumerate()
            .map(|(i, (rho, e))| (rho - e).powi(2) / (nf - (i + 1) as f64).max(1.0))
            .sum::<f64>()
        / c;
    Autocorrelation {
        outside: values
            .iter()
            .zip(expected)
            .filter(|(v, e)| (*v - *e).abs() > band)
            .count(),
        p_value: chi2_survival(ljung_box, lags),
        values,
        expected: expected.to_vec(),
        band,
        ljung_box,
    }
}

/// Normalised cross-correlation of `r` with the increments of `u`, lags `0..lags`.
#[must_use]
pub fn cross_correlation(u: &[f64], r: &[f64], lags: usize) -> CrossCorrelation {
    let du: Vec<f64> = std::iter::once(0.0)
        .chain(u.windows(2).map(|w| w[1] - w[0]))
        .collect();
    let n = du.len().min(r.len());
    let (mu, mr) = (mean(&du[..n]), mean(&r[..n]));
    let su = du[..n].iter().map(|v| (v - mu).powi(2)).sum::<f64>().sqrt();
    let sr = r[..n].iter().map(|v| (v - mr).powi(2)).sum::<f64>().sqrt();
    let values: Vec<f64> = if su == 0.0 || sr == 0.0 {
        vec![0.0; lags.min(n)]
    } else {
        crate::fit::noise::lagged_products(&du[..n], &r[..n], (mu, mr), lags.min(n))
            .into_iter()
            .map(|v| v / (su * sr))
            .collect()
    };
    let (peak_lag, peak) = values
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |(bl, bv), (i, &v)| {
            if v.abs() > bv.abs() {
                (i, v)
            } else {
                (bl, bv)
            }
        });
    CrossCorrelation {
        band: Z99 * (bartlett_factor(&du[..n], &r[..n], lags.min(n)) / n as f64).sqrt(),
        values,
        peak_lag,
        peak,
    }
}

/// Bartlett's factor of the cross-correlation of two independent series, `1 + 2 sum_{j=1}^{M}
/// rho_a(j) rho_b(j)` over `M = lags` (their autocorrelations): the variance of the estimated
/// cross-correlation is this over `N`. Two white series give 1; a slowly varying input (a
/// traverse's wakes) and a coloured residual give more, and their cross-correlation strays
/// that much further from zero by chance. Never below 1: the band is not narrowed by
/// autocorrelations of opposite sign (the differenced noise of a step test).
fn bartlett_factor(a: &[f64], b: &[f64], lags: usize) -> f64 {
    let acf = |x: &[f64]| -> Vec<f64> {
        let m = mean(x);
        let p = crate::fit::noise::lagged_products(x, x, (m, m), lags + 1);
        let c0 = p.first().copied().unwrap_or(0.0);
        if c0 > 0.0 {
            p.iter().skip(1).map(|v| v / c0).collect()
        } else {
            Vec::new()
        }
    };
    let sum: f64 = acf(a).iter().zip(acf(b)).map(|(x, y)| x * y).sum();
    (1.0 + 2.0 * sum).max(1.0)
}
