//! Noise-robust fits: Steiglitz-McBride iterations and the output-error (simulation-error)
//! refinement by Levenberg-Marquardt.
//!
//! Measurement noise on the probe biases the paper's equation-error fit because the noisy
//! output appears among the regressors. Both methods here compare the *simulated* output
//! `B/A u` with the measurement instead, so white measurement noise no longer biases the
//! estimate:
//!
//! * Steiglitz-McBride prefilters `u` and `y` by `1/A` of the previous iterate and solves the
//!   ARX problem on the filtered data; at convergence it minimises (nearly) the output error.
//! * Output error minimises `sum (y - q^-d B/A u)^2` directly by Levenberg-Marquardt. The
//!   Jacobian needs only two all-pole filterings per iteration
//!   (`d yhat / d b_i = q^(-d-i) u/A`, `d yhat / d a_i = -q^(-i) yhat/A`); each step is a
//!   column-pivoted QR solve of the damped, column-scaled Jacobian. Steps that would make `A`
//!   unstable are rejected.

use faer::Mat;

use super::arx::{self, Data, Params};
use crate::compensator::schur_stable;
use crate::error::Result;
use crate::fit::model::filter;

/// `x / A(q)` with zero initial conditions: [`filter`] with numerator 1 (the same arithmetic).
#[must_use]
pub fn allpole(a: &[f64], x: &[f64]) -> Vec<f64> {
    filter(&[1.0], a, 0, x)
}

/// Whether the denominator `1 + a1 z^-1 + ... + am z^-m` is stable (Schur).
pub(crate) fn stable(a: &[f64]) -> bool {
    let mut p = Vec::with_capacity(a.len() + 1);
    p.push(1.0);
    p.extend_from_slice(a);
    schur_stable(&p).is_ok()
}

/// A fall in the loss, in units of the residual variance, below which the iterations stop.
const NEGLIGIBLE: f64 = 1e-3;
/// The damping never falls below this (a guard; the undamped trial does the rest).
const LAMBDA_FLOOR: f64 = 1e-20;

/// Damping below which each iteration first tries the undamped step.
const UNDAMPED_BELOW: f64 = 1e-6;

/// Rows of the Jacobian reduced to its triangle at a time.
const BLOCK: usize = 8192;

/// Sum of squared simulation errors over all data sets.
#[must_use]
pub fn loss(sets: &[Data<'_>], (a, b): (&[f64], &[f64]), d: usize) -> f64 {
    sets.iter()
        .map(|s| {
            let yh = filter(b, a, d, s.u);
            s.y.iter()
                .zip(&yh)
                .map(|(y, h)| (y - h) * (y - h))
                .sum::<f64>()
        })
        .sum()
}

/// Steiglitz-McBride: `iterations` rounds of prefiltered least squares, started from ARX.
/// Returns the iterate with the lowest simulation loss among the stable ones (ARX included).
///
/// # Errors
/// As [`arx::fit`].
pub fn steiglitz_mcbride(
    sets: &[Data<'_>],
    m: usize,
    d: usize,
    iterations: usize,
) -> Result<Params> {
    steiglitz_mcbride_nb(sets, m, m + 1, d, iterations)
}

/// Steiglitz-McBride with `nb` numerator coefficients.
///
/// # Errors
/// As [`arx::fit`].
pub fn steiglitz_mcbride_nb(
    sets: &[Data<'_>],
    m: usize,
    nb: usize,
    d: usize,
    iterations: usize,
) -> Result<Params> {
    let mut best = arx::fit_nb(sets, m, nb, d)?;
    let mut best_loss = if stable(&best.0) {
        loss(sets, (&best.0, &best.1), d)
    } else {
        f64::INFINITY
    };
    let mut current = best.clone();
    for _ in 0..iterations {
        if !stable(&current.0) {
            break;
        }
        let filtered: Vec<(Vec<f64>, Vec<f64>)> = sets
            .iter()
            .map(|s| (allpole(&current.0, s.u), allpole(&current.0, s.y)))
            .collect();
        let fsets: Vec<Data<'_>> = filtered.iter().map(|(u, y)| Data { u, y }).collect();
        let Ok(next) = arx::fit_nb(&fsets, m, nb, d) else {
            break;
        };
        if stable(&next.0) {
            let l = loss(sets, (&next.0, &next.1), d);
            if l < best_loss {
                best_loss = l;
                best = next.clone();
            }
        }
        let change: f64 = next
            .0
            .iter()
            .chain(&next.1)
            .zip(current.0.iter().chain(&current.1))
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        current = next;
        if change < 1e-12 {
            break;
        }
    }
    Ok(best)
}

/// The triangular factor `R` of `[J r]`, the output-error Jacobian at `(a, b)` with the
/// residual as its last column, reduced `BLOCK` rows at a time in `block` (which must have
/// `np + 1` columns and at least `np + 1 + BLOCK` rows, or all the rows there are). The three
/// recursions the rows need (the simulation `yh`, `u / A` and `yh / A`) run block by block in
/// buffers of one block and its history (zeros before the record), the recursions of
/// [`filter`] and [`allpole`] (to rounding: they sum in another order): a long record is never
/// held three times over.
fn triangle(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    block: &mut Mat<f64>,
) -> Mat<f64> {
    let (m, np) = (a.len(), a.len() + b.len());
    let width = np + 1;
    // Lags read: yh and vv up to m, w up to d + nb - 1.
    let h = m.max(d + b.len());
    let step = BLOCK.min(block.nrows().saturating_sub(width).max(1));
    let mut r_aug = Mat::<f64>::zeros(width, width);
    // yh = q^-d B/A u, w = u/A, vv = yh/A; local index h + (k - k0) is sample k.
    let (mut yh, mut w, mut vv) = (
        vec![0.0; h + step],
        vec![0.0; h + step],
        vec![0.0; h + step],
    );
    for s in sets {
        let n = s.y.len();
        for t in [&mut yh, &mut w, &mut vv] {
            t.fill(0.0);
        }
        let mut k0 = 0;
        while k0 < n {
            let k1 = (k0 + step).min(n);
            // Rows: the triangle so far (put by `arx::fold`), then samples k0..k1.
            for k in k0..k1 {
                let p = h + k - k0;
                let mut acc = 0.0;
                for (i, bi) in b.iter().enumerate() {
                    if let Some(j) = k.checked_sub(i + d) {
                        acc += bi * s.u.get(j).copied().unwrap_or(0.0);
                    }
                }
                for (i, ai) in a.iter().enumerate() {
                    acc -= ai * yh[p - i - 1];
                }
                let mut acc_w = s.u.get(k).copied().unwrap_or(0.0);
                let mut acc_v = acc;
                for (i, ai) in a.iter().enumerate() {
                    acc_w -= ai * w[p - i - 1];
                    acc_v -= ai * vv[p - i - 1];
                }
                yh[p] = acc;
                w[p] = acc_w;
                vv[p] = acc_v;
                let row = width + k - k0;
                for i in 0..m {
                    block[(row, i)] = if k > i { -vv[p - i - 1] } else { 0.0 };
                }
                for i in 0..np - m {
                    block[(row, m + i)] = w[p - d - i];
                }
                block[(row, np)] = s.y.get(k).copied().unwrap_or(0.0) - acc;
            }
            r_aug = arx::fold(block, &r_aug, k1 - k0);
            // The last h samples become the next block's history.
            let filled = h + k1 - k0;
            for t in [&mut yh, &mut w, &mut vv] {
                t.copy_within(filled - h..filled, 0);
            }
            k0 = k1;
        }
    }
    r_aug
}

/// The small problem each damped step solves, from the triangle `R` of `[J r]` (`np`
/// parameters): `J`'s column norms (those of `R`, as `Q` is orthogonal), the `2 np x np`
/// matrix `[R; 0]` whose lower half takes the damping rows, and its target `[Q^T r; 0]`.
pub(crate) fn damped_problem(r_aug: &Mat<f64>, np: usize) -> (Vec<f64>, Mat<f64>, Mat<f64>) {
    let norms: Vec<f64> = (0..np)
        .map(|c| {
            (0..=c)
                .map(|r| r_aug[(r, c)] * r_aug[(r, c)])
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let mut small = Mat::<f64>::zeros(2 * np, np);
    let mut target = Mat::<f64>::zeros(2 * np, 1);
    for r in 0..np {
        for c in r..np {
            small[(r, c)] = r_aug[(r, c)];
        }
        target[(r, 0)] = r_aug[(r, np)];
    }
    (norms, small, target)
}

/// The asymptotic covariance of an output-error estimate `[a; b]`: `s^2 (J^T J)^-1` with
/// `s^2` the residual variance, as `s^2 R^-1 R^-T` from the Jacobian's triangular factor (back
/// substitution on `R`, never the normal equations). Valid for white residuals: give the data
/// whitened by the noise model when there is one. `None` when the Jacobian is rank-deficient
/// or there are no more rows than parameters.
#[must_use]
pub fn covariance(sets: &[Data<'_>], (a, b): (&[f64], &[f64]), d: usize) -> Option<Mat<f64>> {
    let np = a.len() + b.len();
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    if rows <= np + 1 {
        return None;
    }
    let mut block = Mat::<f64>::zeros(np + 1 + BLOCK.min(rows), np + 1);
    let r_aug = triangle(sets, (a, b), d, &mut block);
    covariance_of(&r_aug, np, rows)
}

/// The parameters' covariance `s^2 (R^T R)^-1` from the triangle `R` of `[J r]` over `rows`
/// residuals and `np` parameters (`s^2` the residual variance), by inverting the triangle
/// alone. `None` when a parameter is not identified (a diagonal element of `R` negligible).
#[must_use]
fn covariance_of(r_aug: &Mat<f64>, np: usize, rows: usize) -> Option<Mat<f64>> {
    if rows <= np + 1 || r_aug.nrows() <= np || r_aug.ncols() <= np {
        return None;
    }
    // The last diagonal element of R of [J r] is the norm of the residual J cannot explain.
    let rss = r_aug[(np, np)] * r_aug[(np, np)];
    let s2 = rss / (rows - np) as f64;
    let x = upper_inverse(r_aug, np)?;
    let mut cov = Mat::<f64>::zeros(np, np);
    for i in 0..np {
        for j in 0..np {
            cov[(i, j)] = s2 * (0..np).map(|k| x[(i, k)] * x[(j, k)]).sum::<f64>();
        }
    }
    Some(cov)
}

/// The inverse of the leading `np x np` block of the upper triangle `r`, by back
/// substitution column by column. `None` when a diagonal element is negligible (a parameter
/// not identified) or the triangle is smaller.
#[must_use]
pub(crate) fn upper_inverse(r: &Mat<f64>, np: usize) -> Option<Mat<f64>> {
    if r.nrows() < np || r.ncols() < np {
        return None;
    }
    let scale = (0..np).map(|i| r[(i, i)].abs()).fold(0.0, f64::max);
    if (0..np).any(|i| r[(i, i)].abs() <= 1e-12 * scale || r[(i, i)].is_nan()) {
        return None;
    }
    let mut x = Mat::<f64>::zeros(np, np);
    for c in 0..np {
        for row in (0..=c).rev() {
            let mut acc = if row == c { 1.0 } else { 0.0 };
            for k in row + 1..=c {
                acc -= r[(row, k)] * x[(k, c)];
            }
            x[(row, c)] = acc / r[(row, row)];
        }
    }
    Some(x)
}

/// Output-error refinement by Levenberg-Marquardt from `init` (which should be stable).
/// Never returns a worse or unstable model than `init` when `init` is stable.
///
/// # Errors
/// As [`arx::lstsq`].
pub fn output_error(
    sets: &[Data<'_>],
    init: Params,
    d: usize,
    max_iterations: usize,
) -> Result<Params> {
    output_error_from(sets, init, d, max_iterations, FRESH_DAMPING)
}

/// The first damping of a fit from an initial guess (Steiglitz-McBride's).
pub const FRESH_DAMPING: f64 = 1e-4;

/// The first damping of a refinement from an optimum of nearby data (the window's fit on the
/// whole record, a Box-Jenkins round after the first): small enough that the first trial is
/// the undamped step.
pub const WARM_DAMPING: f64 = UNDAMPED_BELOW;

/// [`output_error`] with the first damping `lambda`.
///
/// # Errors
/// As [`arx::lstsq`].
pub fn output_error_from(
    sets: &[Data<'_>],
    init: Params,
    d: usize,
    max_iterations: usize,
    lambda: f64,
) -> Result<Params> {
    let m = init.0.len();
    let np = m + init.1.len();
    let (mut a, mut b) = init;
    let mut v = loss(sets, (&a, &b), d);
    if !stable(&a) || !v.is_finite() {
        return Ok((a, b));
    }
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    let mut lambda = lambda;
    // The Jacobian with the residual as its last column, reduced to its triangular factor R
    // block by block (R of [R_prev; next rows] is R of all rows so far): one QR pass per
    // iteration over a buffer of `BLOCK` rows, whatever the record's length. R gives the column
    // norms and Q^T r at once; each damping trial then solves the small problem
    // [R; sqrt(lambda) D] delta = [Q^T r; 0], the same least-squares solution as the full
    // damped system, at the cost of np rows.
    if rows <= np {
        return Ok((a, b));
    }
    let width = np + 1;
    let mut block = Mat::<f64>::zeros(width + BLOCK.min(rows), width);
    for _ in 0..max_iterations {
        let r_aug = triangle(sets, (&a, &b), d, &mut block);
        let (norms, mut small, target) = damped_problem(&r_aug, np);
        let mut improved = false;
        // Once the damping has fallen to `UNDAMPED_BELOW` (the iterate is near an optimum),
        // the first trial is the undamped Gauss-Newton step: it converges quadratically where
        // any damping slows the weakly determined directions (a polynomial's coefficients are
        // ill-conditioned at high sample rates) to a crawl. Further away the damped steps keep
        // the iterate in its basin.
        let first = usize::from(lambda > UNDAMPED_BELOW);
        for trial in first..13 {
            let damping = if trial == 0 { 0.0 } else { lambda };
            // Damping rows: sqrt(damping) * diag(column norms).
            for (c, nrm) in norms.iter().enumerate() {
                small[(np + c, c)] = damping.sqrt() * nrm.max(1e-300);
            }
            let Ok(delta) = arx::lstsq(&small, &target, "output error") else {
                if trial > 0 {
                    lambda *= 10.0;
                }
                continue;
            };
            let a_new: Vec<f64> = a.iter().zip(&delta[..m]).map(|(x, dx)| x + dx).collect();
            let b_new: Vec<f64> = b.iter().zip(&delta[m..]).map(|(x, dx)| x + dx).collect();
            if stable(&a_new) {
                let v_new = loss(sets, (&a_new, &b_new), d);
                if v_new.is_finite() && v_new < v {
                    let rel = (v - v_new) / v.max(1e-300);
                    a = a_new;
                    b = b_new;
                    v = v_new;
                    lambda = (lambda / 10.0).max(LAMBDA_FLOOR);
                    // Stop once a step no longer matters statistically: its fall in the
                    // loss, in units of the residual variance `v / rows`, is below
                    // `NEGLIGIBLE` (the parameters then move far less than their
                    // standard errors).
                    improved = rel * rows as f64 > NEGLIGIBLE;
                    break;
                }
            }
            if trial == 0 {
                continue;
            }
            lambda *= 10.0;
            if lambda > 1e8 {
                break;
            }
        }
        if !improved || v == 0.0 {
            break;
        }
    }
    Ok((a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allpole_inverts_fir() {
        let a = [-0.5, 0.2];
        let x: Vec<f64> = (0..50).map(|k| (k as f64 * 0.3).sin()).collect();
        let y = allpole(&a, &x);
        let back = filter(&[1.0, -0.5, 0.2], &[], 0, &y);
        for (p, q) in back.iter().zip(&x) {
            assert!((p - q).abs() < 1e-12);
        }
    }
}
