//! The compensated signal of a test, its error against the reference beside the raw probe's,
//! and its figure.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::SeriesLabelPosition;

use super::plot::{colour, figure, Panel, Series};
use super::{escape, pct, points, push_figure, time_unit, Inputs};
use crate::error::Result;
use crate::fit::Test;

/// Whether two names given on command lines are the same test file (the model file records
/// the names `unlag fit` was given; the report may be given the same files by other paths).
fn same_file(a: &str, b: &str) -> bool {
    a == b
        || (Path::new(a).file_name().is_some()
            && Path::new(a).file_name() == Path::new(b).file_name())
}

/// The compensated signal of a test and its errors against the reference.
pub(super) struct Compensated {
    /// `u_hat` as the compensator gives it (lagging by `lag`).
    u_hat: Vec<f64>,
    /// Its lag behind the reference (samples).
    lag: usize,
    /// Which compensator.
    how: String,
    /// Error of `u_hat` against the reference at that lag (RMS / range).
    pub(super) error: f64,
    /// Error of the raw probe against the reference at its best alignment (as
    /// [`crate::design::inverse::reconstruct`] measures it).
    pub(super) raw_error: f64,
}

pub(super) fn compensated_signal(inputs: &Inputs<'_>, test: &Test<'_>) -> Option<Compensated> {
    let (u_hat, lag, how) = compensate(inputs, test)?;
    let (error, _) = crate::design::inverse::aligned_error(test.u, &u_hat, lag..=lag);
    let (raw_error, _) = crate::design::inverse::aligned_error(
        test.u,
        test.y,
        0..=inputs.file.model.delay + 4 * lag.max(10),
    );
    Some(Compensated {
        u_hat,
        lag,
        how,
        error,
        raw_error,
    })
}

/// `u_hat` aligned on the reference: `(estimate, lag, how)`.
fn compensate(inputs: &Inputs<'_>, test: &Test<'_>) -> Option<(Vec<f64>, usize, String)> {
    let file = inputs.file;
    if let Some(d) = &file.inverse {
        let u_hat = d.run::<f32>(test.y).ok()?;
        let lag = d
            .reconstruction
            .iter()
            .find(|r| same_file(&r.file, test.name))
            .map_or(d.latency_samples.round().max(0.0) as usize, |r| r.lag);
        let how = format!(
            "the board's compensator in f32 ({} sections, {}, corrected \
             bandwidth {:.0} Hz, noise gain {:.2}), advanced by its latency of {lag} samples",
            d.sections.len(),
            d.band_text(),
            d.corrected_bandwidth_hz,
            d.noise_gain
        );
        return Some((u_hat, lag, how));
    }
    let u_hat = file.model.compensate::<f32>(test.y).ok()?;
    Some((
        u_hat,
        file.model.delay,
        "the paper's direct inverse in f32 (the model file has no designed compensator)".into(),
    ))
}

pub(super) fn compensated(
    h: &mut String,
    inputs: &Inputs<'_>,
    number: usize,
    test: &Test<'_>,
    window: std::ops::Range<usize>,
) -> Result<()> {
    let fs = inputs.file.model.fs;
    let n = test.y.len().min(test.u.len());
    let Some(Compensated {
        u_hat,
        lag,
        how,
        error: e_hat,
        raw_error: e_raw,
    }) = compensated_signal(inputs, test)
    else {
        let _ = writeln!(
            h,
            "<p class=\"note\">No compensated signal: the model has no stable inverse and the \
             file no designed compensator (run <code>unlag invert</code>).</p>"
        );
        return Ok(());
    };
    let aligned = u_hat.get(lag..).unwrap_or_default();
    let (scale, t_label) = time_unit(n, fs);
    let panel = |range: std::ops::Range<usize>, what: &str| {
        let aligned_range = range.start..range.end.min(aligned.len());
        let mut p = Panel::new(
            what,
            t_label,
            "pressure (test units)",
            vec![
                Series::line(
                    "raw probe y",
                    &points(test.y, range.clone(), fs, scale),
                    colour::PROBE,
                    1,
                ),
                Series::line(
                    "reference u",
                    &points(test.u, range.clone(), fs, scale),
                    colour::REFERENCE,
                    2,
                ),
                Series::line(
                    "compensated u_hat",
                    &points(aligned, aligned_range, fs, scale),
                    colour::COMPENSATED,
                    2,
                ),
            ],
        );
        p.legend = SeriesLabelPosition::LowerRight;
        p
    };
    let svg = figure(
        &format!("compensated-{number}"),
        &[
            panel(0..n, "compensated against the reference"),
            panel(window, "zoom on the step"),
        ],
        340,
        2,
    )?;
    push_figure(
        h,
        &format!("compensated-{number}"),
        &svg,
        &format!(
            "Reconstructed reference u&#770; by {}. Error against the reference {} (raw probe at \
             its best alignment: {}).",
            escape(&how),
            pct(e_hat),
            pct(e_raw)
        ),
    );
    Ok(())
}
