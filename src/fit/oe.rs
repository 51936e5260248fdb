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
use crate::board::compensator::schur_stable;
use crate::error::Result;
use crate::fit::model::{allpole_pair, filter};

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
pub(super) const BLOCK: usize = 8192;

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
            .map(|s| allpole_pair(&current.0, s.u, s.y))
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
pub(super) fn triangle(
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
pub(super) struct Folder<'m> {
    block: &'m mut Mat<f64>,
    r: Mat<f64>,
    width: usize,
    step: usize,
    filled: usize,
}

impl<'m> Folder<'m> {
    /// `block` has `width` columns and at least `width + step` rows.
    pub(super) fn new(block: &'m mut Mat<f64>, width: usize, step: usize) -> Self {
        Self {
            block,
            r: Mat::<f64>::zeros(width, width),
            width,
            step: step.max(1),
            filled: 0,
        }
    }

    /// One more row (its first `width` values).
    pub(super) fn push(&mut self, row: &[f64]) {
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
    pub(super) fn finish(mut self) -> Mat<f64> {
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
pub(super) fn each_row(
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
pub(super) struct Rows<'p> {
    a: &'p [f64],
    b: &'p [f64],
    d: usize,
    step: usize,
    h: usize,
    bufs: [Vec<f64>; 3],
    row: Vec<f64>,
}

impl<'p> Rows<'p> {
    pub(super) fn new((a, b): (&'p [f64], &'p [f64]), d: usize, step: usize) -> Self {
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
    pub(super) fn restart(&mut self) {
        self.bufs.iter_mut().for_each(|t| t.fill(0.0));
    }

    /// The history before the next chunk, in `out` (`3 h` values).
    pub(super) fn save(&self, out: &mut Vec<f64>) {
        for t in &self.bufs {
            out.extend(t.iter().take(self.h));
        }
    }

    /// Takes back a history [`Self::save`] gave.
    pub(super) fn restore(&mut self, saved: &[f64]) {
        let h = self.h;
        for (i, t) in self.bufs.iter_mut().enumerate() {
            for (slot, v) in t.iter_mut().zip(saved.iter().skip(i * h).take(h)) {
                *slot = *v;
            }
        }
    }

    /// The rows of samples `k0..k1` of `s` (at most one step), given to `emit`; the last `h`
    /// samples then become the history before `k1`.
    pub(super) fn chunk(
        &mut self,
        s: &Data<'_>,
        (k0, k1): (usize, usize),
        emit: &mut impl FnMut(&[f64]),
    ) {
        let (a, b, d, h) = (self.a, self.b, self.d, self.h);
        let (m, np) = (a.len(), a.len() + b.len());
        let [yh, w, vv] = &mut self.bufs;
        let row = &mut self.row;
        for k in k0..k1 {
            let p = h + k - k0;
            let mut acc = 0.0;
            // Past the record's first `nb + d - 1` samples every input term exists: the same
            // sum over a slice.
            match k.checked_sub(d).and_then(|last| {
                (last + 1)
                    .checked_sub(b.len())
                    .and_then(|first| s.u.get(first..=last))
            }) {
                Some(us) => {
                    for (bi, uj) in b.iter().zip(us.iter().rev()) {
                        acc += bi * uj;
                    }
                }
                None => {
                    for (i, bi) in b.iter().enumerate() {
                        if let Some(j) = k.checked_sub(i + d) {
                            acc += bi * s.u.get(j).copied().unwrap_or(0.0);
                        }
                    }
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
