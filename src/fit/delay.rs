//! The delay search: for each candidate delay a model is fitted on the step's window and its
//! simulation error measured, and the delay is the largest whose error is the lowest within
//! that error's statistical spread. A long range of candidates is searched coarse to fine.

use super::arx::Data;
use super::model::DelayRow;
use super::{oe, step, FitError};
use crate::error::Result;
use std::collections::BTreeSet;

/// Longest stretch of samples the delay search looks at.
const WINDOW: usize = 20_000;

/// Up to this many candidate delays are each tried. A longer range (a slow probe sampled
/// fast: 1209 candidates for a capillary's half-rise at 9.4 kHz, each a fit on the step's
/// window) is tried first on a grid of about this many, then at every delay between the grid
/// points next to one near the grid's best.
const DENSE: usize = 64;

/// A grid delay whose error is within this fraction of the grid's best has the delays on
/// either side of it, up to the next grid points, tried too. The error over delays is smooth
/// on the scale of a grid step (the model's poles and zeros move with the delay), and the
/// delays the choice can take are within a fraction of a per cent of the best.
const NEAR_BEST: f64 = 0.02;

/// The delay for order `m` on a test (`u` and `y` as deviations from their levels before the
/// step, which starts at `onset`), and the candidates tried with their errors, by delay. With
/// `spread`, the candidates of each pass are fitted on the cores there are (the fit of one
/// order: with several, the orders already are); the result is the same.
///
/// # Errors
/// [`FitError::NoUsableDelay`] when no candidate delay gives a model.
pub(super) fn search(
    u: &[f64],
    y: &[f64],
    onset: usize,
    m: usize,
    spread: bool,
) -> Result<(usize, Vec<DelayRow>)> {
    // The probe cannot answer later than where it has made half its step.
    let n = y.len().min(u.len());
    let tail = y.get(n - n / 10..n).unwrap_or_default();
    let yfinal = step::mean_std(tail).0;
    let after = y.get(onset..n).unwrap_or_default();
    let half = after
        .iter()
        .position(|v| (v / yfinal) > 0.5)
        .unwrap_or(after.len());
    let hi = (half + 2).min(n / 4);
    let start = onset.saturating_sub(200);
    let end = (onset + WINDOW).min(n);
    let (Some(u), Some(y)) = (u.get(start..end), y.get(start..end)) else {
        return Err(FitError::NoUsableDelay.into());
    };
    let sets = [Data { u, y }];
    let energy: f64 = y.iter().map(|v| v * v).sum();
    let loss = |&d: &usize| {
        let (a, b) = oe::steiglitz_mcbride_nb(&sets, m, m, d, 8).ok()?;
        let l = oe::loss(&sets, (&a, &b), d);
        l.is_finite().then(|| DelayRow {
            delay: d,
            nrmse: (l / energy.max(1e-300)).sqrt(),
        })
    };
    let rows = candidates(hi, |delays: &[usize]| {
        if spread {
            super::in_parallel(delays, loss)
        } else {
            delays.iter().map(loss).collect()
        }
    });
    let best = rows.iter().map(|r| r.nrmse).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return Err(FitError::NoUsableDelay.into());
    }
    // Candidates whose residual sum of squares is within 2 noise variances of the best are
    // statistically indistinguishable from it (a likelihood-ratio margin); among those the
    // largest delay is the one for which the probe has not yet answered.
    let samples = (end - start) as f64;
    let tol = best * best * (1.0 + 2.0 / samples);
    let d = rows
        .iter()
        .filter(|r| r.nrmse * r.nrmse <= tol)
        .map(|r| r.delay)
        .max()
        .unwrap_or(0);
    Ok((d, rows))
}

/// How the delay was chosen, for the model file: the rule, the order, and the candidates
/// tried (a search that went coarse to fine says so, with the range it covered).
pub(super) fn selection(m: usize, rows: &[DelayRow]) -> String {
    let top = rows.last().map_or(0, |r| r.delay);
    let tried = if top > DENSE {
        format!("{} candidates from 0 to {top}, coarse to fine", rows.len())
    } else {
        format!("{} candidates", rows.len())
    };
    format!("largest delay with the lowest simulation loss (order {m}, {tried})")
}

/// The rows `losses` gives for the delays `0..=hi` (those it can fit), by delay: every delay up
/// to [`DENSE`] of them; otherwise a grid `hi / DENSE` apart (rounded up, `hi` included), and
/// then every delay between the grid points next to one within [`NEAR_BEST`] of the grid's
/// best. `losses` takes the delays of one pass and gives each one's row, in their order.
fn candidates(hi: usize, losses: impl Fn(&[usize]) -> Vec<Option<DelayRow>>) -> Vec<DelayRow> {
    let tried = |delays: &[usize]| losses(delays).into_iter().flatten().collect::<Vec<_>>();
    if hi <= DENSE {
        return tried(&(0..=hi).collect::<Vec<_>>());
    }
    let stride = hi.div_ceil(DENSE);
    let mut grid: Vec<usize> = (0..=hi).step_by(stride).collect();
    if grid.last() != Some(&hi) {
        grid.push(hi);
    }
    let mut rows = tried(&grid);
    let best = rows.iter().map(|r| r.nrmse).fold(f64::INFINITY, f64::min);
    let near: BTreeSet<usize> = rows
        .iter()
        .filter(|r| r.nrmse <= best * (1.0 + NEAR_BEST))
        .map(|r| r.delay)
        .collect();
    let mut fine = BTreeSet::new();
    for (i, d) in grid.iter().enumerate() {
        if near.contains(d) {
            let from = i
                .checked_sub(1)
                .and_then(|j| grid.get(j))
                .map_or(0, |p| p + 1);
            let to = grid.get(i + 1).map_or(hi, |q| q.saturating_sub(1));
            fine.extend(from..=to);
        }
    }
    let fine: Vec<usize> = fine
        .into_iter()
        .filter(|d| grid.binary_search(d).is_err())
        .collect();
    rows.extend(tried(&fine));
    rows.sort_by_key(|r| r.delay);
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows of an error curve `f` over delays (`None` where a delay gives no model), and
    /// how many delays were tried.
    fn tried(hi: usize, f: impl Fn(usize) -> Option<f64>) -> (Vec<DelayRow>, usize) {
        let count = std::cell::Cell::new(0);
        let rows = candidates(hi, |delays| {
            count.set(count.get() + delays.len());
            delays
                .iter()
                .map(|&d| f(d).map(|nrmse| DelayRow { delay: d, nrmse }))
                .collect()
        });
        (rows, count.get())
    }

    #[test]
    fn a_short_range_is_tried_at_every_delay() {
        let (rows, count) = tried(DENSE, |d| Some(1.0 + (d as f64 - 20.0).powi(2)));
        assert_eq!(count, DENSE + 1);
        assert!(rows.iter().map(|r| r.delay).eq(0..=DENSE));
    }

    #[test]
    fn a_long_range_finds_the_best_and_the_edge_of_a_flat_valley_from_a_grid() {
        // The shape of a slow capillary's curve (1209 candidates,
        // 0.462 % at delay 0, flat at 0.438 % from 55 to 73, rising to 0.51 % by 150 and on):
        // a valley whose floor is flat within a part in 1e4 over 19 delays.
        let hi = 1209;
        let f = |d: usize| {
            let x = d as f64;
            let off = (x - 55.0).max(0.0) - (x - 73.0).max(0.0);
            let dist = if x < 55.0 {
                55.0 - x
            } else {
                (x - 73.0).max(0.0)
            };
            0.438 + 1e-6 * off + 4e-6 * dist * dist
        };
        let (rows, count) = tried(hi, |d| Some(f(d)));
        assert!(count < hi / 4, "{count} of {hi} delays tried");
        // Every delay from 40 to 90 (both sides of the valley, to the next grid points) is
        // tried, and so the choice (the largest within the tolerance of the best) is the
        // same as trying them all.
        for d in 40..=90 {
            assert!(rows.iter().any(|r| r.delay == d), "delay {d} not tried");
        }
        let best = |rows: &[DelayRow]| rows.iter().map(|r| r.nrmse).fold(f64::INFINITY, f64::min);
        let all: Vec<DelayRow> = (0..=hi)
            .map(|d| DelayRow {
                delay: d,
                nrmse: f(d),
            })
            .collect();
        assert_eq!(best(&rows), best(&all));
        assert!(rows.windows(2).all(|w| w[0].delay < w[1].delay));
    }

    #[test]
    fn the_grid_keeps_the_last_delay_and_skips_what_cannot_be_fitted() {
        // Best at the top of the range; the odd delays give no model.
        let hi = 301;
        let (rows, count) = tried(hi, |d| {
            (d % 2 == 0 || d == hi).then(|| 1.0 + (hi - d) as f64)
        });
        assert_eq!(rows.last().map(|r| r.delay), Some(hi));
        assert!(rows.iter().all(|r| r.delay % 2 == 0 || r.delay == hi));
        assert!(count < hi / 2);
    }
}
