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
/// residual as its last column ([`each_row`]), reduced `BLOCK` rows at a time in `block`
/// (which must have `np + 1` columns and at least `np + 1 + BLOCK` rows, or all the rows there
/// are): a long record is never held.
fn triangle(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    block: &mut Mat<f64>,
) -> Mat<f64> {
    let width = a.len() + b.len() + 1;
    let step = BLOCK.min(block.nrows().saturating_sub(width).max(1));
    let mut folder = Folder::new(block, width, step);
    each_row(sets, (a, b), d, step, |row| folder.push(row));
    folder.finish()
}

/// Rows reduced to their triangle a block at a time ([`arx::fold`]): the triangle of all the
/// rows pushed, in one block's memory.
struct Folder<'m> {
    block: &'m mut Mat<f64>,
    r: Mat<f64>,
    width: usize,
    step: usize,
    filled: usize,
}

impl<'m> Folder<'m> {
    /// `block` has `width` columns and at least `width + step` rows.
    fn new(block: &'m mut Mat<f64>, width: usize, step: usize) -> Self {
        Self {
            block,
            r: Mat::<f64>::zeros(width, width),
            width,
            step: step.max(1),
            filled: 0,
        }
    }

    /// One more row (its first `width` values).
    fn push(&mut self, row: &[f64]) {
        for (c, v) in row.iter().take(self.width).enumerate() {
            self.block[(self.width + self.filled, c)] = *v;
        }
        self.filled += 1;
        if self.filled == self.step {
            self.r = arx::fold(self.block, &self.r, self.filled);
            self.filled = 0;
        }
    }

    /// The triangle of every row pushed.
    fn finish(mut self) -> Mat<f64> {
        if self.filled > 0 {
            self.r = arx::fold(self.block, &self.r, self.filled);
        }
        self.r
    }
}

/// Each row `[J_k r_k]` of the output-error Jacobian at `(a, b)` with the residual, in
/// order, set after set, given to `emit`. The three recursions the rows need (the simulation
/// `yh`, `u / A` and `yh / A`) run `step` samples at a time ([`chunk_rows`]) in buffers of
/// one step and its history (zeros before each record): a long record is never held three
/// times over.
fn each_row(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    step: usize,
    mut emit: impl FnMut(&[f64]),
) {
    let mut rows = Rows::new((a, b), d, step);
    for s in sets {
        rows.restart();
        let mut k0 = 0;
        while k0 < s.y.len() {
            let k1 = (k0 + rows.step).min(s.y.len());
            rows.chunk(s, (k0, k1), &mut emit);
            k0 = k1;
        }
    }
}

/// The recursions of the output-error Jacobian's rows, a chunk of samples at a time: the
/// simulation `yh = q^-d B/A u`, `w = u/A` and `vv = yh/A`, each in a buffer of one chunk
/// after the `h` samples of history before it.
struct Rows<'p> {
    a: &'p [f64],
    b: &'p [f64],
    d: usize,
    step: usize,
    h: usize,
    bufs: [Vec<f64>; 3],
    row: Vec<f64>,
}

impl<'p> Rows<'p> {
    fn new((a, b): (&'p [f64], &'p [f64]), d: usize, step: usize) -> Self {
        let step = step.max(1);
        // Lags read: yh and vv up to m, w up to d + nb - 1.
        let h = a.len().max(d + b.len());
        Self {
            a,
            b,
            d,
            step,
            h,
            bufs: [
                vec![0.0; h + step],
                vec![0.0; h + step],
                vec![0.0; h + step],
            ],
            row: vec![0.0; a.len() + b.len() + 1],
        }
    }

    /// Zero history: a record's start.
    fn restart(&mut self) {
        self.bufs.iter_mut().for_each(|t| t.fill(0.0));
    }

    /// The history before the next chunk, in `out` (`3 h` values).
    fn save(&self, out: &mut Vec<f64>) {
        for t in &self.bufs {
            out.extend(t.iter().take(self.h));
        }
    }

    /// Takes back a history [`Self::save`] gave.
    fn restore(&mut self, saved: &[f64]) {
        let h = self.h;
        for (i, t) in self.bufs.iter_mut().enumerate() {
            for (slot, v) in t.iter_mut().zip(saved.iter().skip(i * h).take(h)) {
                *slot = *v;
            }
        }
    }

    /// The rows of samples `k0..k1` of `s` (at most one step), given to `emit`; the last `h`
    /// samples then become the history before `k1`.
    fn chunk(&mut self, s: &Data<'_>, (k0, k1): (usize, usize), emit: &mut impl FnMut(&[f64])) {
        let (a, b, d, h) = (self.a, self.b, self.d, self.h);
        let (m, np) = (a.len(), a.len() + b.len());
        let [yh, w, vv] = &mut self.bufs;
        let row = &mut self.row;
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
            for i in 0..m {
                row[i] = if k > i { -vv[p - i - 1] } else { 0.0 };
            }
            for i in 0..np - m {
                row[m + i] = w[p - d - i];
            }
            row[np] = s.y.get(k).copied().unwrap_or(0.0) - acc;
            emit(row);
        }
        let filled = h + k1 - k0;
        for t in [yh, w, vv] {
            t.copy_within(filled - h..filled, 0);
        }
    }
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
    let np = a.len() + b.len();
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    if rows <= np + 1
        || parts
            .iter()
            .any(|c| c.var.is_nan() || c.var < 0.0 || c.num.is_empty())
    {
        return None;
    }
    let step = BLOCK.min(rows);
    let mut block = Mat::<f64>::zeros(np + 1 + step, np + 1);
    let ra = triangle(sets, (a, b), d, &mut block);
    let mut zblock = Mat::<f64>::zeros(np + step, np);
    let mut folder = Folder::new(&mut zblock, np, step);
    // z runs backwards in time: each record's rows are made again chunk by chunk from the
    // last, from the recursions' history saved at each chunk's start on a first pass.
    let mut rows_of = Rows::new((a, b), d, step);
    let mut saved = Vec::new();
    let mut chunk = vec![0.0; step * np];
    for part in parts {
        let scale = part.var.sqrt();
        // z_(i+1) .. z_(i+p) and J_(i+1) .. J_(i+q), nearest first, and one spare each.
        let mut later: Vec<Vec<f64>> = vec![vec![0.0; np]; part.den.len() + 1];
        let mut ahead: Vec<Vec<f64>> = vec![vec![0.0; np]; part.num.len()];
        for s in sets {
            let n = s.y.len();
            let starts: Vec<usize> = (0..n).step_by(step).collect();
            saved.clear();
            rows_of.restart();
            for &k0 in &starts {
                rows_of.save(&mut saved);
                rows_of.chunk(s, (k0, (k0 + step).min(n)), &mut |_| {});
            }
            later.iter_mut().for_each(|z| z.fill(0.0));
            ahead.iter_mut().for_each(|z| z.fill(0.0));
            let width = saved.len() / starts.len().max(1);
            for (c, &k0) in starts.iter().enumerate().rev() {
                rows_of.restore(saved.get(c * width..(c + 1) * width).unwrap_or(&[]));
                let mut filled = 0;
                rows_of.chunk(s, (k0, (k0 + step).min(n)), &mut |row| {
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
                    let scaled: Vec<f64> = z.iter().map(|v| scale * v).collect();
                    folder.push(&scaled);
                    later.insert(0, z);
                }
            }
        }
    }
    let rb = folder.finish();
    let x = upper_inverse(&ra, np)?;
    Some(sandwich(&x, &rb, np, 1.0))
}

/// `cov` with the error of quantities the fit took as known added: each `(c, var)` a column
/// `c` (one value per row of the sets, in order) of the residual's derivatives by such a
/// quantity, whose error has variance `var`, independent of the residual and of the others.
/// The estimate moves by `(J'J)^-1 J' c` per unit of it, so each adds
/// `var (A^-1 J'c)(A^-1 J'c)'`. `None` when `J` is rank-deficient.
#[must_use]
pub fn with_nuisances(
    mut cov: Mat<f64>,
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
    nuisances: &[(Vec<f64>, f64)],
) -> Option<Mat<f64>> {
    let np = a.len() + b.len();
    if nuisances.is_empty() {
        return Some(cov);
    }
    let rows: usize = sets.iter().map(|s| s.y.len()).sum();
    let step = BLOCK.min(rows.max(1));
    let mut block = Mat::<f64>::zeros(np + 1 + step, np + 1);
    let ra = triangle(sets, (a, b), d, &mut block);
    let x = upper_inverse(&ra, np)?;
    // J'c for every nuisance, in one pass over the rows.
    let mut jc = vec![vec![0.0; np]; nuisances.len()];
    let mut k = 0;
    each_row(sets, (a, b), d, step, |row| {
        for (acc, (c, _)) in jc.iter_mut().zip(nuisances) {
            let ck = c.get(k).copied().unwrap_or(0.0);
            for (s, j) in acc.iter_mut().zip(row) {
                *s += j * ck;
            }
        }
        k += 1;
    });
    for (g, (_, var)) in jc.iter().zip(nuisances) {
        // A^-1 g = X (X' g).
        let xtg: Vec<f64> = (0..np)
            .map(|i| (0..np).map(|r| x[(r, i)] * g[r]).sum())
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

#[cfg(test)]
mod both_channels {
    use super::*;

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
