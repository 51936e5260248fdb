//! The paper's direct least squares on the ARX equation (its eq. 1-5), solved by a
//! column-pivoted QR factorisation (faer), never by forming and inverting the normal equations.
//!
//! Equation error: `y[k] + sum a[i] y[k-i] = sum b[i] u[k-d-i] + e[k]`. Unbiased only when the
//! noise is white *in the equation*, which measurement noise is not: with noise on `y` and
//! `fs >> fn` the estimate is strongly biased (see the tests in `host-tests/fit.rs`). That is
//! why it is not the default; it is also the starting point of the noise-robust methods.

use faer::linalg::solvers::SolveLstsq;
use faer::Mat;

use crate::error::Result;
use crate::fit::FitError;

/// One data set for a regression: input and output deviations, zero before the first sample.
#[derive(Debug, Clone, Copy)]
pub struct Data<'a> {
    /// Input (reference) deviations.
    pub u: &'a [f64],
    /// Output (probe) deviations.
    pub y: &'a [f64],
}

/// Parameters `(a, b)` in the crate's convention.
pub type Params = (Vec<f64>, Vec<f64>);

/// Solves `min || X theta - t ||` by column-pivoted QR and checks the rank.
///
/// # Errors
/// [`FitError::TooFewEquations`] when `X` has fewer rows than columns,
/// [`FitError::RankDeficient`] when it is rank deficient (the data do not determine the
/// parameters), [`FitError::NonFiniteSolution`] when the solution is not finite.
pub fn lstsq(x: &Mat<f64>, t: &Mat<f64>, context: &str) -> Result<Vec<f64>> {
    if x.nrows() < x.ncols() {
        return Err(FitError::TooFewEquations {
            context: context.into(),
            equations: x.nrows(),
            unknowns: x.ncols(),
        }
        .into());
    }
    let qr = x.col_piv_qr();
    let r = qr.thin_R();
    let n = r.ncols().min(r.nrows());
    let d0 = if n > 0 { r[(0, 0)].abs() } else { 0.0 };
    let dn = if n > 0 { r[(n - 1, n - 1)].abs() } else { 0.0 };
    if d0.is_nan() || d0 <= 0.0 || dn.is_nan() || dn <= d0 * 1e-14 {
        return Err(FitError::RankDeficient {
            context: context.into(),
        }
        .into());
    }
    let sol = qr.solve_lstsq(t);
    let theta: Vec<f64> = (0..x.ncols()).map(|i| sol[(i, 0)]).collect();
    if theta.iter().any(|v| !v.is_finite()) {
        return Err(FitError::NonFiniteSolution {
            context: context.into(),
        }
        .into());
    }
    Ok(theta)
}

/// The ARX regression matrix (rows `k >= m + d`, the paper's eq. 4) stacked over data sets:
/// columns `-y[k-1..k-m]`, then `u[k-d..k-d-nb+1]`; target `y[k]`. The paper has `nb = m + 1`.
#[must_use]
pub fn regression(sets: &[Data<'_>], m: usize, nb: usize, d: usize) -> (Mat<f64>, Mat<f64>) {
    let start = m.max(nb.saturating_sub(1)) + d;
    let lens: Vec<usize> = sets
        .iter()
        .map(|data| data.y.len().min(data.u.len()).saturating_sub(start))
        .collect();
    let n_rows: usize = lens.iter().sum();
    let cols = m + nb;
    // Column by column, each a run of contiguous copies: the matrix is column major.
    let mut x = Mat::<f64>::zeros(n_rows, cols);
    let mut t = Mat::<f64>::zeros(n_rows, 1);
    // `first` is where the column starts in each set's signal; `y` or `u`; negated or not.
    let fill = |col: &mut [f64], first: usize, from_y: bool, negate: bool| {
        let mut r = 0;
        for (data, &len) in sets.iter().zip(&lens) {
            let signal = if from_y { data.y } else { data.u };
            let src = &signal[first..first + len];
            let dst = &mut col[r..r + len];
            if negate {
                dst.iter_mut().zip(src).for_each(|(o, v)| *o = -v);
            } else {
                dst.copy_from_slice(src);
            }
            r += len;
        }
    };
    for c in 0..cols {
        if let Some(col) = x.col_mut(c).try_as_col_major_mut() {
            if c < m {
                fill(col.as_slice_mut(), start - 1 - c, true, true);
            } else {
                fill(col.as_slice_mut(), start - d - (c - m), false, false);
            }
        }
    }
    if let Some(col) = t.col_mut(0).try_as_col_major_mut() {
        fill(col.as_slice_mut(), start, true, false);
    }
    (x, t)
}

/// Direct least squares of order `m` with delay `d` (the paper's eq. 5, by QR).
///
/// # Errors
/// [`FitError`] when the data are too short or do not determine the parameters.
pub fn fit(sets: &[Data<'_>], m: usize, d: usize) -> Result<Params> {
    fit_nb(sets, m, m + 1, d)
}

/// Direct least squares with `nb` numerator coefficients `b0..b(nb-1)`.
///
/// # Errors
/// As [`fit`].
pub fn fit_nb(sets: &[Data<'_>], m: usize, nb: usize, d: usize) -> Result<Params> {
    let cols = m + nb;
    let (r, rows) = triangle(sets, m, nb, d);
    if rows < cols {
        return Err(FitError::TooFewEquations {
            context: "arx".into(),
            equations: rows,
            unknowns: cols,
        }
        .into());
    }
    // R's columns have X's norms and R^T R = X^T X, so the pivoted QR of R sees the same
    // rank and gives the same solution as that of X.
    let x = r.as_ref().submatrix(0, 0, cols, cols).to_owned();
    let t = r.as_ref().submatrix(0, cols, cols, 1).to_owned();
    let theta = lstsq(&x, &t, "arx")?;
    Ok(split(&theta, m))
}

/// One step of a blockwise QR: `R` of the triangle so far, `r_aug`, stacked on the `rows`
/// rows of `block` below its first `r_aug.nrows()` (which it neither reads nor writes; the
/// rows below are overwritten): `R` of all the rows so far, whatever their number, in one
/// block's memory.
///
/// Householder reflections, one per column, with the triangle's structure used: reflection
/// `j` touches row `j` of the triangle and the block's rows only, so a step costs
/// `2 rows width^2` flops and no more, each reflection a pass of sums over contiguous columns
/// (the block is column major). A general QR of the stacked matrix spends most of its time
/// on packing and on the norm's scaling at these shapes (a few to twenty columns); the norm
/// is scaled here only where its plain sum of squares would overflow or underflow.
pub(crate) fn fold(block: &mut Mat<f64>, r_aug: &Mat<f64>, rows: usize) -> Mat<f64> {
    let width = r_aug.nrows();
    let mut r = Mat::<f64>::zeros(width, width);
    for c in 0..width {
        for i in 0..=c {
            r[(i, c)] = r_aug[(i, c)];
        }
    }
    let rows = rows.min(block.nrows().saturating_sub(width));
    let mut v = vec![0.0; rows];
    for j in 0..width {
        let Some(col) = block.col_mut(j).try_as_col_major_mut() else {
            continue;
        };
        let Some(xj) = col.as_slice_mut().get(width..width + rows) else {
            continue;
        };
        let below = norm(xj);
        if below == 0.0 {
            // Nothing below the diagonal: the column is already reduced.
            continue;
        }
        let alpha = r[(j, j)];
        let norm = alpha.hypot(below);
        let beta = if alpha > 0.0 { -norm } else { norm };
        // The reflection `I - tau w w^T`, `w = [1; x_j / (alpha - beta)]`.
        let scale = 1.0 / (alpha - beta);
        v.iter_mut()
            .zip(xj.iter())
            .for_each(|(o, x)| *o = x * scale);
        let tau = (beta - alpha) / beta;
        r[(j, j)] = beta;
        for c in j + 1..width {
            let Some(col) = block.col_mut(c).try_as_col_major_mut() else {
                continue;
            };
            let Some(xc) = col.as_slice_mut().get_mut(width..width + rows) else {
                continue;
            };
            let s = (r[(j, c)] + dot(&v, xc)) * tau;
            r[(j, c)] -= s;
            xc.iter_mut().zip(&v).for_each(|(x, w)| *x -= s * w);
        }
    }
    r
}

/// `sqrt(sum x[i]^2)`: the plain sum where it can neither overflow nor lose precision to
/// underflow, else scaled by the largest magnitude.
fn norm(x: &[f64]) -> f64 {
    let sigma = dot(x, x);
    if sigma.is_finite() && sigma > 1e-250 {
        return sigma.sqrt();
    }
    let largest = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if largest == 0.0 || !largest.is_finite() {
        return largest;
    }
    let scaled: f64 = x.iter().map(|v| (v / largest).powi(2)).sum();
    largest * scaled.sqrt()
}

/// `sum a[i] b[i]` in eight interleaved partial sums (independent chains the processor
/// overlaps and vectorises).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for ((s, p), q) in acc.iter_mut().zip(x).zip(y) {
            *s += p * q;
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// Rows of the regression reduced at a time: a block and the triangle so far stay in cache.
const BLOCK_ROWS: usize = 2048;

/// The triangular factor `R` of `[X t]`, the regression of [`regression`] with its target as
/// the last column, reduced block by block (`R` of `[R_so_far; next rows]` is `R` of all rows
/// so far), and the number of rows: the same least-squares problem in `(m + nb + 1)^2`
/// numbers, without the whole matrix.
#[must_use]
pub fn triangle(sets: &[Data<'_>], m: usize, nb: usize, d: usize) -> (Mat<f64>, usize) {
    let start = m.max(nb.saturating_sub(1)) + d;
    let cols = m + nb;
    let width = cols + 1;
    let mut r_aug = Mat::<f64>::zeros(width, width);
    let mut block = Mat::<f64>::zeros(width + BLOCK_ROWS, width);
    let mut rows = 0;
    for data in sets {
        let len = data.y.len().min(data.u.len());
        let mut k0 = start;
        while k0 < len {
            let k1 = (k0 + BLOCK_ROWS).min(len);
            let n = k1 - k0;
            for c in 0..width {
                let Some(col) = block.col_mut(c).try_as_col_major_mut() else {
                    continue;
                };
                let col = col.as_slice_mut();
                // The block's rows below its first `width`, which `fold` leaves alone.
                let dst = &mut col[width..width + n];
                if c < m {
                    let src = &data.y[k0 - 1 - c..k1 - 1 - c];
                    dst.iter_mut().zip(src).for_each(|(o, v)| *o = -v);
                } else if c < cols {
                    let lag = d + c - m;
                    dst.copy_from_slice(&data.u[k0 - lag..k1 - lag]);
                } else {
                    dst.copy_from_slice(&data.y[k0..k1]);
                }
            }
            r_aug = fold(&mut block, &r_aug, n);
            rows += n;
            k0 = k1;
        }
    }
    (r_aug, rows)
}

/// Splits `[a1..am, b0..bm]`.
#[must_use]
pub fn split(theta: &[f64], m: usize) -> Params {
    (theta[..m].to_vec(), theta[m..].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::model::filter;

    #[test]
    fn recovers_a_noise_free_model_exactly() {
        let (a, b) = (vec![-1.6, 0.7], vec![0.05, 0.03, 0.02]);
        let u: Vec<f64> = (0..300).map(|k| if k >= 20 { 1.0 } else { 0.0 }).collect();
        let y = filter(&b, &a, 4, &u);
        let (ah, bh) = fit(&[Data { u: &u, y: &y }], 2, 4).unwrap();
        for (x, t) in ah.iter().chain(&bh).zip(a.iter().chain(&b)) {
            assert!((x - t).abs() < 1e-10 * t.abs(), "{x} vs {t}");
        }
    }

    /// The blockwise reduction gives the triangle of faer's QR of the whole regression
    /// matrix, up to the signs of its rows and rounding, over several blocks and two data
    /// sets; and the same least squares as the pivoted QR of the whole matrix.
    #[test]
    fn the_blockwise_reduction_gives_the_whole_matrix_triangle() {
        let (a, b) = (vec![-1.6, 0.7], vec![0.05, 0.03, 0.02]);
        let u: Vec<f64> = (0..5000)
            .map(|k| f64::from(u8::from(k >= 20)) + ((k * 7919) % 97) as f64 * 1e-3)
            .collect();
        let clean = filter(&b, &a, 4, &u);
        let y: Vec<f64> = clean
            .iter()
            .enumerate()
            .map(|(k, v)| v + ((k * 104_729) % 89) as f64 * 1e-4)
            .collect();
        let sets = [
            Data { u: &u, y: &y },
            Data {
                u: &u[..3000],
                y: &y[..3000],
            },
        ];
        for (m, nb, d) in [(2, 3, 4), (4, 4, 0), (1, 1, 9)] {
            let (x, t) = regression(&sets, m, nb, d);
            let w = m + nb + 1;
            let mut whole = Mat::<f64>::zeros(x.nrows(), w);
            for r in 0..x.nrows() {
                for c in 0..w - 1 {
                    whole[(r, c)] = x[(r, c)];
                }
                whole[(r, w - 1)] = t[(r, 0)];
            }
            let general = whole.qr().thin_R().to_owned();
            let (blockwise, rows) = triangle(&sets, m, nb, d);
            assert_eq!(rows, x.nrows());
            for i in 0..w {
                let sign = general[(i, i)].signum() * blockwise[(i, i)].signum();
                for c in 0..w {
                    let (g, s) = (general[(i, c)], sign * blockwise[(i, c)]);
                    let scale = general[(c, c)].abs().max(general[(i, i)].abs());
                    assert!((g - s).abs() <= 1e-10 * scale, "({i}, {c}): {g} vs {s}");
                }
            }
            let whole_fit = lstsq(&x, &t, "whole").unwrap();
            let blockwise = fit_nb(&sets, m, nb, d).unwrap();
            for (p, q) in blockwise.0.iter().chain(&blockwise.1).zip(&whole_fit) {
                assert!((p - q).abs() <= 1e-9 * q.abs().max(1e-3), "{p} vs {q}");
            }
        }
    }

    /// Data whose sums of squares overflow (or underflow) give the triangle of the same data
    /// scaled into range, scaled back.
    #[test]
    fn the_reduction_keeps_data_whose_squares_overflow_or_underflow() {
        let u: Vec<f64> = (0..3000)
            .map(|k| f64::from(u8::from(k >= 20)) + ((k * 7919) % 97) as f64 * 1e-3)
            .collect();
        let y = filter(&[0.2], &[-0.8], 2, &u);
        let (plain, _) = triangle(&[Data { u: &u, y: &y }], 1, 1, 2);
        for factor in [1e200, 1e-200] {
            let (us, ys): (Vec<f64>, Vec<f64>) = u
                .iter()
                .zip(&y)
                .map(|(a, b)| (a * factor, b * factor))
                .unzip();
            let (scaled, _) = triangle(&[Data { u: &us, y: &ys }], 1, 1, 2);
            for i in 0..3 {
                for c in i..3 {
                    let (p, s) = (plain[(i, c)], scaled[(i, c)] / factor);
                    assert!(
                        (p - s).abs() <= 1e-12 * plain[(0, 0)].abs(),
                        "{factor}: {p} vs {s}"
                    );
                }
            }
        }
    }

    #[test]
    fn refuses_data_without_excitation() {
        let u = vec![0.0; 100];
        let y = vec![0.0; 100];
        assert!(fit(&[Data { u: &u, y: &y }], 2, 0).is_err());
    }

    /// Too little data and data without excitation are told apart, in the fit's words.
    #[test]
    fn short_and_unexciting_data_are_refused_by_name() {
        let u = vec![1.0; 3];
        let y = vec![0.5; 3];
        let e = fit(&[Data { u: &u, y: &y }], 2, 0).unwrap_err();
        assert!(
            matches!(
                e.stage(),
                Some(FitError::TooFewEquations {
                    equations: 1,
                    unknowns: 5,
                    ..
                })
            ),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "arx: 1 equations for 5 unknowns: the data are too short"
        );
        assert_eq!(e.kind(), "numerical");
        let x = Mat::<f64>::zeros(4, 2);
        let t = Mat::<f64>::zeros(4, 1);
        let e = lstsq(&x, &t, "output error").unwrap_err();
        assert!(
            matches!(e.stage(), Some(FitError::RankDeficient { .. })),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "output error: the regression is rank deficient: the data do not excite the model \
             (is there a step?)"
        );
    }
}
