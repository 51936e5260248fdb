//! The estimate's covariance: how far an output-error fit's parameters could move with the
//! noise of its residual, white, coloured, or a sum of independent coloured parts (the
//! probe's noise and the reference's through the model), as the sandwich `A^-1 B A^-1` from
//! triangles of the Jacobian, a long record never held.

use faer::Mat;

use super::arx::Data;
use super::oe::{each_row, triangle, Folder, Rows, BLOCK};

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

/// The asymptotic covariance of an output-error estimate `[a; b]` whose residual is not
/// white: `P(q) r = e`, `P = 1 + p1 q^-1 + ...` the AR model `colour = [p1..pp]` of the
/// residual (empty: white) and `e` white of variance `innovation_var`. The estimate's error
/// is `(J'J)^-1 J' r`, so its covariance is the sandwich `A^-1 B A^-1` with `A = J'J` and
/// `B = innovation_var Z'Z`, `Z = P^-T J` (each column of `J` filtered by `1/P` backwards in
/// time), both by their triangles; the rows are made twice, chunk by chunk, so a long record
/// is never held. With no colour it is [`covariance`] with the innovation's variance for the
/// residual's. `None` as [`covariance`].
#[must_use]
pub fn covariance_coloured(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    colour: &[f64],
    innovation_var: f64,
) -> Option<Mat<f64>> {
    covariance_of_parts(
        sets,
        (a, b),
        d,
        &[Colour {
            num: vec![1.0],
            den: colour.to_vec(),
            var: innovation_var,
        }],
    )
}

/// One independent part of a residual: white noise of variance `var` through the causal
/// filter `num(q) / (1 + den(q))` (`num = [n0 n1 ..]` in powers of `q^-1`, `den = [m1 m2 ..]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Colour {
    /// Numerator, from `q^0`.
    pub num: Vec<f64>,
    /// Denominator after its leading 1.
    pub den: Vec<f64>,
    /// Variance of the white noise that drives it.
    pub var: f64,
}

/// As [`covariance_coloured`], the residual a sum of independent [`Colour`]s (the probe's
/// noise and the reference's through the probe, each as measured): `B = sum var Z'Z`,
/// `Z = H^T J` for each part's filter `H`, run backwards in time.
#[must_use]
pub fn covariance_of_parts(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    parts: &[Colour],
) -> Option<Mat<f64>> {
    covariance_weighted(
        &[Weighted {
            sets,
            weight: 1.0,
            parts: parts.to_vec(),
            nuisances: Vec::new(),
        }],
        (a, b),
        d,
    )
}

/// One test of a fit on one or several: its records, the weight of its squared error in the
/// fit's loss, the independent parts of its residual ([`Colour`]), and the quantities the
/// fit took as known: each `(c, var)` a column `c` (one value per row of the test's records,
/// in order) of the residual's derivatives by such a quantity, whose error has variance
/// `var`, independent of the residual and of the others (a resting level read before the
/// step).
#[derive(Debug, Clone)]
pub struct Weighted<'a> {
    /// The test's records.
    pub sets: &'a [Data<'a>],
    /// The weight of its squared error.
    pub weight: f64,
    /// Its residual's parts.
    pub parts: Vec<Colour>,
    /// The quantities taken as known.
    pub nuisances: Vec<(Vec<f64>, f64)>,
}

/// The covariance of an output-error estimate `[a; b]` fitted on several tests, test `t`'s
/// squared error weighted by `w_t`: the sandwich `A^-1 B A^-1` with `A = sum w_t J_t'J_t` and
/// `B = sum w_t^2 sum_parts var Z'Z` (each part's `Z = H^T J_t`, see
/// [`covariance_of_parts`]), each test's triangles made alone and stacked.
/// Each quantity taken as known moves the estimate by `A^-1 w_t J_t' c` per unit of it, and
/// so adds `var (A^-1 w_t J_t'c)(A^-1 w_t J_t'c)'`. `None` when `J` is rank-deficient, a test
/// has no more rows than parameters, or a weight or a variance is negative or not a number.
#[must_use]
pub fn covariance_weighted(
    tests: &[Weighted<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
) -> Option<Mat<f64>> {
    let np = a.len() + b.len();
    let shares = tests
        .iter()
        .map(|t| {
            let (ra, rb) = triangles(t.sets, (a, b), d, &t.parts)?;
            Some(Share {
                ra,
                rb,
                weight: t.weight,
                moves: moved_by(t.sets, (a, b), d, &t.nuisances),
            })
        })
        .collect::<Option<Vec<Share>>>()?;
    combine(np, &shares)
}

/// One test's share of a weighted sandwich: the triangles of its `J'J` and of its `B` (at
/// least `np x np`, their leading blocks read), the weight of its squared error, and `J'c`
/// of each quantity it took as known, with that quantity's variance.
pub(crate) struct Share {
    /// Triangle of `J'J`.
    pub ra: Mat<f64>,
    /// Triangle of `B`.
    pub rb: Mat<f64>,
    /// Weight of the test's squared error.
    pub weight: f64,
    /// `J'c` and the variance of each quantity taken as known.
    pub moves: Vec<(Vec<f64>, f64)>,
}

/// The sandwich of the tests' shares: `A = sum w A_t`, `B = sum w^2 B_t`, by stacking their
/// triangles scaled and reducing them to one; the quantities taken as known added. `None`
/// when `A` is rank-deficient or a weight is negative or not a number.
pub(crate) fn combine(np: usize, shares: &[Share]) -> Option<Mat<f64>> {
    let rows = (shares.len() * np).max(1);
    let mut blocks = (
        Mat::<f64>::zeros(np + rows, np),
        Mat::<f64>::zeros(np + rows, np),
    );
    let mut fold_a = Folder::new(&mut blocks.0, np, rows);
    let mut fold_b = Folder::new(&mut blocks.1, np, rows);
    let mut moves = Vec::new();
    for t in shares {
        if t.weight.is_nan()
            || t.weight < 0.0
            || t.ra.nrows() < np
            || t.ra.ncols() < np
            || t.rb.nrows() < np
            || t.rb.ncols() < np
        {
            return None;
        }
        for i in 0..np {
            let row = |r: &Mat<f64>, scale: f64| -> Vec<f64> {
                (0..np).map(|c| scale * r[(i, c)]).collect()
            };
            fold_a.push(&row(&t.ra, t.weight.sqrt()));
            fold_b.push(&row(&t.rb, t.weight));
        }
        for (g, var) in &t.moves {
            moves.push((g.iter().map(|v| t.weight * v).collect::<Vec<f64>>(), *var));
        }
    }
    let (ra, rb) = (fold_a.finish(), fold_b.finish());
    let x = upper_inverse(&ra, np)?;
    let mut cov = sandwich(&x, &rb, np, 1.0);
    for (g, var) in &moves {
        // A^-1 g = X (X' g).
        let xtg: Vec<f64> = (0..np)
            .map(|i| {
                (0..np)
                    .map(|r| x[(r, i)] * g.get(r).copied().unwrap_or(0.0))
                    .sum()
            })
            .collect();
        let v: Vec<f64> = (0..np)
            .map(|r| (0..np).map(|i| x[(r, i)] * xtg[i]).sum())
            .collect();
        for r in 0..np {
            for c in 0..np {
                cov[(r, c)] += var * v[r] * v[c];
            }
        }
    }
    Some(cov)
}

/// A record's Jacobian rows, made chunk by chunk from its start, that can be made again from
/// a mark taken before a chunk: what running a filter backwards over them needs without
/// holding them.
pub(crate) trait Replay {
    /// What the rows' recursions hold before a chunk.
    type Mark;
    /// The state before the next chunk.
    fn mark(&self) -> Self::Mark;
    /// Takes back a state [`Replay::mark`] gave.
    fn resume(&mut self, mark: &Self::Mark);
    /// The rows of samples `k0..k1`, in order, each its `np` derivatives first.
    fn rows(&mut self, range: (usize, usize), emit: &mut dyn FnMut(&[f64]));
}

/// The output-error rows of one record.
struct OeReplay<'r, 'p, 'd> {
    rows: &'r mut Rows<'p>,
    data: &'r Data<'d>,
}

impl Replay for OeReplay<'_, '_, '_> {
    type Mark = Vec<f64>;
    fn mark(&self) -> Vec<f64> {
        let mut saved = Vec::new();
        self.rows.save(&mut saved);
        saved
    }
    fn resume(&mut self, mark: &Vec<f64>) {
        self.rows.restore(mark);
    }
    fn rows(&mut self, range: (usize, usize), emit: &mut dyn FnMut(&[f64])) {
        self.rows.chunk(self.data, range, &mut |r: &[f64]| emit(r));
    }
}

/// The triangle of `B = sum var Z'Z` (`Z = H^T J` for each part's filter `H`) over the `n`
/// rows of `np` derivatives that `replay` makes from its start, `step` at a time: the rows
/// are made once forwards, marking each chunk's start, and again chunk by chunk from the
/// last, each part's filter run backwards over them. `None` when a part is malformed.
pub(crate) fn parts_triangle(
    replay: &mut impl Replay,
    (n, np, step): (usize, usize, usize),
    parts: &[Colour],
) -> Option<Mat<f64>> {
    let step = step.max(1);
    if malformed(parts) {
        return None;
    }
    let mut zblock = Mat::<f64>::zeros(np + step, np);
    let mut folder = Folder::new(&mut zblock, np, step);
    fold_parts(replay, (n, np, step), parts, &mut folder);
    Some(folder.finish())
}

/// A part with a variance negative or not a number, or no numerator.
fn malformed(parts: &[Colour]) -> bool {
    parts
        .iter()
        .any(|c| c.var.is_nan() || c.var < 0.0 || c.num.is_empty())
}

/// [`parts_triangle`]'s rows pushed to `folder`.
fn fold_parts(
    replay: &mut impl Replay,
    (n, np, step): (usize, usize, usize),
    parts: &[Colour],
    folder: &mut Folder<'_>,
) {
    let starts: Vec<usize> = (0..n).step_by(step.max(1)).collect();
    let mut marks = Vec::with_capacity(starts.len());
    for &k0 in &starts {
        marks.push(replay.mark());
        replay.rows((k0, (k0 + step).min(n)), &mut |_| {});
    }
    let mut chunk = vec![0.0; step * np];
    let mut scaled = vec![0.0; np];
    for part in parts {
        let scale = part.var.sqrt();
        // z_(i+1) .. z_(i+p) and J_(i+1) .. J_(i+q), nearest first, and one spare each.
        let mut later: Vec<Vec<f64>> = vec![vec![0.0; np]; part.den.len() + 1];
        let mut ahead: Vec<Vec<f64>> = vec![vec![0.0; np]; part.num.len()];
        for (&k0, mark) in starts.iter().zip(&marks).rev() {
            replay.resume(mark);
            let mut filled = 0;
            replay.rows((k0, (k0 + step).min(n)), &mut |row| {
                for (slot, v) in chunk.iter_mut().skip(filled * np).zip(row.iter().take(np)) {
                    *slot = *v;
                }
                filled += 1;
            });
            for i in (0..filled).rev() {
                // J_i joins the rows ahead: ahead = J_i, J_(i+1), ...
                let Some(mut j) = ahead.pop() else { break };
                for (cj, v) in j.iter_mut().zip(chunk.iter().skip(i * np).take(np)) {
                    *cj = *v;
                }
                ahead.insert(0, j);
                // z_i = sum_j n_j J_(i+j) - sum_j m_j z_(i+j): H run backwards.
                let Some(mut z) = later.pop() else { break };
                for (c, zc) in z.iter_mut().enumerate() {
                    let fir: f64 = part
                        .num
                        .iter()
                        .zip(&ahead)
                        .map(|(nj, jr)| nj * jr.get(c).copied().unwrap_or(0.0))
                        .sum();
                    let iir: f64 = part
                        .den
                        .iter()
                        .zip(&later)
                        .map(|(m, zl)| m * zl.get(c).copied().unwrap_or(0.0))
                        .sum();
                    *zc = fir - iir;
                }
                for (out, v) in scaled.iter_mut().zip(&z) {
                    *out = scale * v;
                }
                folder.push(&scaled);
                later.insert(0, z);
            }
        }
    }
}

/// The triangles of `A = J'J` and of `B = sum var Z'Z` over one test's records (see
/// [`covariance_of_parts`]). `None` when there are no more rows than parameters or a part is
/// malformed.
fn triangles(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    parts: &[Colour],
) -> Option<(Mat<f64>, Mat<f64>)> {
    let np = a.len() + b.len();
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    if rows <= np + 1 || malformed(parts) {
        return None;
    }
    let step = BLOCK.min(rows);
    let mut block = Mat::<f64>::zeros(np + 1 + step, np + 1);
    let ra = triangle(sets, (a, b), d, &mut block);
    let mut zblock = Mat::<f64>::zeros(np + step, np);
    let mut folder = Folder::new(&mut zblock, np, step);
    let mut rows_of = Rows::new((a, b), d, step);
    for data in sets {
        rows_of.restart();
        let mut replay = OeReplay {
            rows: &mut rows_of,
            data,
        };
        fold_parts(&mut replay, (data.y.len(), np, step), parts, &mut folder);
    }
    Some((ra, folder.finish()))
}

/// `J'c` for each quantity taken as known, in one pass over the rows, with its variance.
fn moved_by(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    nuisances: &[(Vec<f64>, f64)],
) -> Vec<(Vec<f64>, f64)> {
    let np = a.len() + b.len();
    if nuisances.is_empty() {
        return Vec::new();
    }
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    let mut jc = vec![vec![0.0; np]; nuisances.len()];
    let mut k = 0;
    each_row(sets, (a, b), d, BLOCK.min(rows.max(1)), |row| {
        for (acc, (c, _)) in jc.iter_mut().zip(nuisances) {
            let ck = c.get(k).copied().unwrap_or(0.0);
            for (s, j) in acc.iter_mut().zip(row) {
                *s += j * ck;
            }
        }
        k += 1;
    });
    jc.into_iter()
        .zip(nuisances.iter().map(|(_, v)| *v))
        .collect()
}

/// `s2 (R_b X X')' (R_b X X')`: the covariance `A^-1 B A^-1` with `A^-1 = X X'` (`X` the
/// inverse of `A`'s triangle) and `B = s2 R_b' R_b` (`R_b` upper triangular), by products of
/// `np x np` matrices alone.
#[must_use]
pub(crate) fn sandwich(x: &Mat<f64>, rb: &Mat<f64>, np: usize, s2: f64) -> Mat<f64> {
    let xxt = Mat::<f64>::from_fn(np, np, |i, j| (0..np).map(|k| x[(i, k)] * x[(j, k)]).sum());
    let c = Mat::<f64>::from_fn(np, np, |i, j| {
        (i..np).map(|k| rb[(i, k)] * xxt[(k, j)]).sum()
    });
    Mat::<f64>::from_fn(np, np, |i, j| {
        s2 * (0..np).map(|k| c[(k, i)] * c[(k, j)]).sum::<f64>()
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::model::filter;

    /// The sandwich of a coloured residual, made twice in chunks backwards, is the one built
    /// from the whole Jacobian and the AR residual's covariance `s2 P^-1 P^-T` as matrices;
    /// with no colour it is `s2 (J'J)^-1`.
    #[test]
    fn the_coloured_covariance_is_the_sandwich_of_the_whole_jacobian() {
        let (a, b, d) = (vec![-1.6, 0.7], vec![0.05, 0.05], 1);
        let n = 300;
        let u: Vec<f64> = (0..n).map(|k| if k < 40 { 0.0 } else { 1.0 }).collect();
        let y: Vec<f64> = crate::testing::with_noise(&filter(&b, &a, d, &u), 0.01, 3);
        let sets = [Data { u: &u, y: &y }];
        let np = 4;
        let mut j = Mat::<f64>::zeros(n, np);
        let mut k = 0;
        each_row(&sets, (&a, &b), d, 7, |row| {
            for c in 0..np {
                j[(k, c)] = row[c];
            }
            k += 1;
        });
        let (colour, s2) = (vec![-0.8, 0.15], 2.0);
        // P as a lower-triangular matrix, and P^-1 by forward substitution on the identity.
        let p = Mat::<f64>::from_fn(n, n, |r, c| match r.checked_sub(c) {
            Some(0) => 1.0,
            Some(l) => colour.get(l - 1).copied().unwrap_or(0.0),
            None => 0.0,
        });
        // Z = P^-T J: back substitution on the dense upper triangle P^T, row by row from the
        // last.
        let pt = p.transpose().to_owned();
        let mut z = Mat::<f64>::zeros(n, np);
        for r in (0..n).rev() {
            for c in 0..np {
                let later: f64 = (r + 1..n).map(|q| pt[(r, q)] * z[(q, c)]).sum();
                z[(r, c)] = (j[(r, c)] - later) / pt[(r, r)];
            }
        }
        let bm = s2 * (z.transpose() * &z);
        use faer::linalg::solvers::SolveLstsq;
        let a_inv = (j.transpose() * &j)
            .col_piv_qr()
            .solve_lstsq(Mat::<f64>::identity(np, np));
        let expected = &a_inv * &bm * &a_inv;
        // Chunks of 7 rows: the buffers cross chunk borders many times.
        let got = covariance_coloured(&sets, (&a, &b), d, &colour, s2).unwrap();
        for r in 0..np {
            for c in 0..np {
                let (g, e) = (got[(r, c)], expected[(r, c)]);
                assert!(
                    (g - e).abs() <= 1e-6 * e.abs().max(expected[(r, r)].abs()),
                    "{r} {c}: {g} {e}"
                );
            }
        }
        let white = covariance_coloured(&sets, (&a, &b), d, &[], s2).unwrap();
        let plain = covariance(&sets, (&a, &b), d).unwrap();
        let r_aug = triangle(&sets, (&a, &b), d, &mut Mat::<f64>::zeros(n + 5, 5));
        let s2_plain = r_aug[(np, np)].powi(2) / (n - np) as f64;
        for r in 0..np {
            let ratio = white[(r, r)] / plain[(r, r)] * s2_plain / s2;
            assert!((ratio - 1.0).abs() < 1e-6, "{ratio}");
        }
    }
}

#[cfg(test)]
mod both_channels {
    use super::*;
    use crate::fit::model::filter;

    /// The two parts (the probe's white noise, and the reference's white noise through the
    /// model from rest) give the dense sandwich with the true residual covariance
    /// `sy^2 I + su^2 G G'`, and the residual's own AR colour comes near it.
    #[test]
    fn the_parts_are_the_sandwich_with_the_true_residual_covariance() {
        let fs = 7078.0;
        let (truth, _) = crate::testing::second_order(40.28488, 0.1529161, fs, 27);
        let n = 2000;
        let u: Vec<f64> = (0..n).map(|k| if k < 300 { 0.0 } else { 1051.0 }).collect();
        let y0 = truth.simulate(&u);
        let (su, sy) = (3.8, 2.62);
        let nu = crate::testing::with_noise(&vec![0.0; n], su, 1000);
        let gn = truth.simulate(&nu);
        let y: Vec<f64> = y0.iter().zip(&gn).map(|(a, b)| a - b).collect();
        let y = crate::testing::with_noise(&y, sy, 2000);
        let sets = [Data { u: &u, y: &y }];
        let (a, b, d) = (truth.a.clone(), truth.b.clone(), truth.delay);
        let np = a.len() + b.len();
        let mut j = Mat::<f64>::zeros(n, np);
        let mut res = vec![0.0; n];
        let mut k = 0;
        each_row(&sets, (&a, &b), d, 512, |row| {
            for c in 0..np {
                j[(k, c)] = row[c];
            }
            res[k] = row[np];
            k += 1;
        });
        // The true residual covariance: sy^2 I + su^2 G G' (G the probe's impulse response
        // as a lower-triangular Toeplitz matrix, the reference noise from rest).
        let mut imp = vec![0.0; n];
        imp[0] = 1.0;
        let g = filter(&truth.b, &truth.a, truth.delay, &imp);
        let gm = Mat::<f64>::from_fn(n, n, |r, c| if r >= c { g[r - c] } else { 0.0 });
        let gj = gm.transpose() * &j;
        let bm = sy * sy * (j.transpose() * &j) + su * su * (gj.transpose() * &gj);
        use faer::linalg::solvers::SolveLstsq;
        let a_inv = (j.transpose() * &j)
            .col_piv_qr()
            .solve_lstsq(Mat::<f64>::identity(np, np));
        let exact = &a_inv * &bm * &a_inv;
        let colour = crate::fit::noise::fit(&res, crate::fit::noise::MAX_COLOUR_ORDER);
        let est = covariance_coloured(
            &sets,
            (&a, &b),
            d,
            &colour.ar,
            colour.innovation_std.powi(2),
        )
        .unwrap();
        let plain = covariance(&sets, (&a, &b), d).unwrap();
        let mut gnum = vec![0.0; d];
        gnum.extend(&b);
        let parts = covariance_of_parts(
            &sets,
            (&a, &b),
            d,
            &[
                Colour {
                    num: vec![1.0],
                    den: vec![],
                    var: sy * sy,
                },
                Colour {
                    num: gnum,
                    den: a.clone(),
                    var: su * su,
                },
            ],
        )
        .unwrap();
        for i in 0..np {
            let exact_over_parts = exact[(i, i)] / parts[(i, i)];
            assert!(
                (exact_over_parts - 1.0).abs() < 1e-3,
                "parameter {i}: the dense sandwich is {exact_over_parts} times the parts'"
            );
            // The fallback without a quiet segment, the AR colour of the residual, comes
            // nearer the truth than the covariance of white noise, on every parameter.
            let (ar, white) = (exact[(i, i)] / est[(i, i)], exact[(i, i)] / plain[(i, i)]);
            assert!(
                ar > 0.5 && ar < white,
                "parameter {i}: the AR colour's variance is {ar} of the truth, white noise's {white}"
            );
        }
        let worst_white = (0..np)
            .map(|i| exact[(i, i)] / plain[(i, i)])
            .fold(0.0f64, f64::max);
        assert!(worst_white > 4.0, "white noise was right ({worst_white})");
    }
}
