//! Clipped ADC channels: a signal that sits flat at its largest or smallest value after a jump,
//! found over a whole record held in memory (the streamed passes find the same runs with
//! running figures, in [`stream`](super::stream)).

use std::path::Path;

use super::{Result, TraceError};

/// Shortest flat run at an extreme that counts as clipping.
pub const CLIP_MIN_RUN: usize = 5;

/// Shortest flat run at an extreme, lasting to the end of the record, that counts as clipping
/// when the rest of the record is noisy.
pub const CLIP_MIN_RUN_AT_END: usize = 20;

/// Fraction of the samples outside `start..end` that repeat their predecessor exactly.
fn repeat_fraction_outside(x: &[f64], start: usize, end: usize) -> f64 {
    let (mut repeats, mut pairs) = (0usize, 0usize);
    for (i, w) in x.windows(2).enumerate() {
        if (start.saturating_sub(1)..end).contains(&i) {
            continue;
        }
        pairs += 1;
        if let [a, b] = *w {
            if a == b {
                repeats += 1;
            }
        }
    }
    if pairs == 0 {
        1.0
    } else {
        repeats as f64 / pairs as f64
    }
}

/// Detects a saturated ADC: the signal sits flat at its largest (or smallest) value for at
/// least [`CLIP_MIN_RUN`] samples, and enters that run with a jump of more than 5 times the
/// typical sample-to-sample change. A settled, quantised signal also repeats its final value,
/// but it enters the plateau in steps of about one typical change, so it is not flagged.
pub(super) fn check_clipping(
    path: &Path,
    x: &[f64],
    lines: &[u64],
    column: usize,
    name: &str,
) -> Result<()> {
    if x.len() < 4 * CLIP_MIN_RUN {
        return Ok(());
    }
    let mut diffs: Vec<f64> = x
        .windows(2)
        .filter_map(|w| match *w {
            [a, b] if a != b => Some((b - a).abs()),
            _ => None,
        })
        .collect();
    if diffs.is_empty() {
        return Ok(());
    }
    let mid = diffs.len() / 2;
    diffs.select_nth_unstable_by(mid, f64::total_cmp);
    let typical = diffs.get(mid).copied().unwrap_or(0.0);
    let max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = x.iter().copied().fold(f64::INFINITY, f64::min);
    for (level, which) in [(max, "largest"), (min, "smallest")] {
        let mut k = 0;
        while k < x.len() {
            if x.get(k) == Some(&level) {
                let start = k;
                while x.get(k) == Some(&level) {
                    k += 1;
                }
                let run = k - start;
                let entry_jump = start
                    .checked_sub(1)
                    .and_then(|i| x.get(i))
                    .map_or(0.0, |prev| (level - prev).abs());
                // A run that lasts to the end of the record may be a noise-free step's
                // settled value; it is clipping when the rest of the record is noisy (its
                // samples rarely repeat) and the run is long.
                let clipped = if k < x.len() {
                    run >= CLIP_MIN_RUN
                } else {
                    run >= CLIP_MIN_RUN_AT_END && repeat_fraction_outside(x, start, k) < 0.2
                };
                if clipped && entry_jump > 5.0 * typical {
                    return Err(TraceError::Clipped {
                        path: path.to_path_buf(),
                        line: lines.get(start).copied().unwrap_or(0),
                        column,
                        name: name.to_string(),
                        run,
                        which,
                        value: level,
                    });
                }
            } else {
                k += 1;
            }
        }
    }
    Ok(())
}
