//! The report's section for each test: the probe against the model with the residual (whole
//! record and a zoom on the step), then the compensated signal, the residual spectrum and the
//! residual's correlations.

use std::fmt::Write as _;

use plotters::prelude::SeriesLabelPosition;

use super::compensated::compensated;
use super::plot::{colour, figure, Marker, Panel, Series, Style};
use super::{escape, num, p_value, pct, points, push_figure, time_unit, top_effect, Inputs};
use crate::effects;
use crate::error::Result;
use crate::evidence::TestEvidence;
use crate::fit::Test;
use crate::pipeline::ReferenceError;

/// The samples around the step where the probe's answer happens: from a little before the
/// onset until the model has settled within 2 % of the step (at least 40 samples, at most a
/// quarter of the record).
pub(super) fn step_window(ev: &TestEvidence, y_model: &[f64]) -> std::ops::Range<usize> {
    let n = y_model.len();
    let onset = ev.step_onset.min(n);
    let last = y_model.last().copied().unwrap_or(0.0);
    let tol = 0.02 * ev.step_size.abs().max(1e-300);
    let settled = y_model
        .iter()
        .rposition(|v| (v - last).abs() > tol)
        .unwrap_or(onset)
        .max(onset);
    let span = ((settled - onset) * 3 / 2).clamp(40, (n / 4).max(40));
    let lo = onset.saturating_sub(span / 5);
    lo..(onset + span).min(n)
}

/// The section of test `number`; the compensated signal's errors against the reference (as
/// `unlag compensate` gives them), when there is one, for the summary table.
pub(super) fn per_test(
    h: &mut String,
    inputs: &Inputs<'_>,
    number: usize,
    test: &Test<'_>,
    ev: &TestEvidence,
) -> Result<Option<ReferenceError>> {
    let file = inputs.file;
    let model = &file.model;
    let fs = model.fs;
    let n = test.y.len().min(test.u.len());
    let y_model = effects::predict(model, &file.effects, test.u, test.y);
    let residual: Vec<f64> = test.y.iter().zip(&y_model).map(|(a, b)| a - b).collect();
    let (scale, t_label) = time_unit(n, fs);
    heading(h, number, ev);
    // Probe against model, residual beneath on the same time axis.
    // The band a correct model's residual stays in: both channels' noise through it.
    let band = 2.0 * ev.expected.std;
    let traces = |range: std::ops::Range<usize>, what: &str| -> [Panel; 2] {
        let top = Panel::new(
            &format!("{what}: measured probe against the model"),
            t_label,
            "pressure (test units)",
            vec![
                Series::line(
                    "reference u",
                    &points(test.u, range.clone(), fs, scale),
                    colour::REFERENCE,
                    1,
                ),
                // The measured probe wide beneath, the model dashed on top: where they
                // agree both stay visible.
                Series::line(
                    "probe y (measured)",
                    &points(test.y, range.clone(), fs, scale),
                    colour::PROBE,
                    4,
                ),
                Series {
                    style: Style::Dashed,
                    ..Series::line(
                        "model (dashed)",
                        &points(&y_model, range.clone(), fs, scale),
                        colour::MODEL,
                        2,
                    )
                },
            ],
        );
        let mut top = top;
        top.legend = SeriesLabelPosition::LowerRight;
        let mut bottom = Panel::new(
            "residual y - model",
            t_label,
            "residual (test units)",
            vec![Series::line(
                "residual",
                &points(&residual, range.clone(), fs, scale),
                colour::RESIDUAL,
                1,
            )],
        )
        .guides(vec![(band, "+-2 noise std".into()), (-band, String::new())]);
        // Same time axis as the panel above.
        bottom.x = top.x.clone();
        [top, bottom]
    };
    let svg = figure(
        &format!("trace-{number}"),
        &traces(0..n, "whole record"),
        300,
        1,
    )?;
    push_figure(
        h,
        &format!("trace-{number}"),
        &svg,
        &format!(
            "Whole record. Residual RMS {}; the grey lines are twice the probe's noise \
             standard deviation ({}) measured before the step. Fit {:.2} %.",
            num(ev.residual_rms),
            num(ev.noise_std),
            ev.fit_percent
        ),
    );
    let window = step_window(ev, &y_model);
    let svg = figure(
        &format!("zoom-{number}"),
        &traces(window.clone(), "zoom on the step"),
        300,
        1,
    )?;
    push_figure(
        h,
        &format!("zoom-{number}"),
        &svg,
        &format!(
            "The first {:.2} ms after the step at t = {:.3} ms (sample {}): where probes fail.",
            1e3 * (window.end.saturating_sub(ev.step_onset)) as f64 / fs,
            1e3 * ev.step_onset as f64 / fs,
            ev.step_onset
        ),
    );
    // The model's response and residual are drawn: free them before the compensated signal
    // is made (a shock-tube record is millions of samples).
    drop(residual);
    drop(y_model);
    let reconstruction = compensated(h, inputs, number, test, window)?;
    spectrum(h, inputs, number, ev)?;
    correlations(h, number, ev)?;
    Ok(reconstruction)
}

/// A test's heading: its error against its noise floor, and with a noise model its
/// one-step-ahead prediction error against that error's floor.
fn heading(h: &mut String, number: usize, ev: &TestEvidence) {
    let _ = writeln!(
        h,
        "<h3>Test {number}: {} ({}): error {} against a noise floor of {}</h3>",
        escape(&ev.file),
        ev.role,
        pct(ev.nrmse),
        pct(ev.noise_floor)
    );
    if let Some(p) = &ev.prediction {
        let _ = writeln!(
            h,
            "<p>With its noise model the model is judged by its one-step-ahead prediction \
             error: {} against that error's floor of {} ({}).</p>",
            pct(p.nrmse),
            pct(p.floor.value),
            escape(&p.floor.origin())
        );
    }
}

fn spectrum(h: &mut String, inputs: &Inputs<'_>, number: usize, ev: &TestEvidence) -> Result<()> {
    let s = &ev.spectrum;
    let pts: Vec<(f64, f64)> = s
        .psd_db
        .iter()
        .enumerate()
        .skip(1)
        .map(|(i, v)| (i as f64 * s.resolution_hz, *v))
        .collect();
    let along = |shift: f64| -> Vec<(f64, f64)> {
        s.expected_db
            .iter()
            .enumerate()
            .skip(1)
            .map(|(i, v)| (i as f64 * s.resolution_hz, v + shift))
            .collect()
    };
    let (expected, significance) = (along(0.0), along(crate::evidence::PEAK_DB));
    let top = top_effect(inputs).map(|c| c.kind);
    let effect = top.map_or("not diagnosed", crate::modelling::diagnose::Finding::as_str);
    let label_of = |f: f64| {
        if top == Some(crate::modelling::diagnose::Finding::Nothing) {
            format!("{f:.0} Hz")
        } else {
            format!("{f:.0} Hz: {effect}")
        }
    };
    let mut p = Panel::new(
        "residual spectrum after the step",
        "frequency (Hz)",
        "power density (dB)",
        vec![
            Series::line("residual", &pts, colour::RESIDUAL, 1),
            Series::line(
                "what the noise leaves (probe's, and the reference's through the model)",
                &expected,
                colour::MODEL,
                1,
            ),
            Series::line(
                &format!("significance: {} dB above it", crate::evidence::PEAK_DB),
                &significance,
                colour::GUIDE,
                1,
            ),
        ],
    );
    // Peaks highest first; a label only where it does not run into one already placed.
    let span = p.x.end - p.x.start;
    let mut labelled: Vec<f64> = Vec::new();
    p.markers = s
        .peaks
        .iter()
        .take(5)
        .filter_map(|pk| {
            let i = (pk.frequency_hz / s.resolution_hz).round() as usize;
            let crowded = labelled
                .iter()
                .any(|f| (f - pk.frequency_hz).abs() < 0.12 * span);
            if !crowded {
                labelled.push(pk.frequency_hz);
            }
            s.psd_db.get(i).map(|v| Marker {
                at: (pk.frequency_hz, *v),
                label: if crowded {
                    String::new()
                } else {
                    label_of(pk.frequency_hz)
                },
            })
        })
        .collect();
    // Room above the highest peak for its label.
    p.y.end += 0.08 * (p.y.end - p.y.start);
    let svg = figure(&format!("spectrum-{number}"), &[p], 330, 1)?;
    let peaks = if s.peaks.is_empty() {
        format!(
            "no peak stands {} dB above the floor",
            crate::evidence::PEAK_DB
        )
    } else {
        s.peaks
            .iter()
            .take(5)
            .map(|p| {
                format!(
                    "{:.0} Hz (+{:.0} dB, Q {:.0})",
                    p.frequency_hz, p.above_floor_db, p.q
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    push_figure(
        h,
        &format!("spectrum-{number}"),
        &svg,
        &format!(
            "Significant peaks (circled, labelled with the diagnosed effect \
             <b>{}</b>): {}. Resolution {:.2} Hz.",
            escape(effect),
            escape(&peaks),
            s.resolution_hz
        ),
    );
    Ok(())
}

fn correlations(h: &mut String, number: usize, ev: &TestEvidence) -> Result<()> {
    let a = &ev.autocorrelation;
    let x = &ev.cross_correlation;
    let acf: Vec<(f64, f64)> = a
        .values
        .iter()
        .enumerate()
        .map(|(k, v)| ((k + 1) as f64, *v))
        .collect();
    let xcf: Vec<(f64, f64)> = x
        .values
        .iter()
        .enumerate()
        .map(|(k, v)| (k as f64, *v))
        .collect();
    let mut left = Panel::new(
        "residual autocorrelation",
        "lag (samples)",
        "correlation",
        vec![Series::with("rho(k)", acf, colour::PROBE, Style::Stems)],
    )
    .guides(vec![(a.band, "99 % band".into()), (-a.band, String::new())]);
    left.x = 0.0..(a.values.len() as f64 + 1.0);
    let mut right = Panel::new(
        "residual against the input increments",
        "lag (samples)",
        "correlation",
        vec![Series::with(
            "cross-corr.",
            xcf,
            colour::RESIDUAL,
            Style::Stems,
        )],
    )
    .guides(vec![(x.band, "99 % band".into()), (-x.band, String::new())]);
    right.x = -1.0..(x.values.len() as f64);
    let svg = figure(&format!("correlation-{number}"), &[left, right], 300, 2)?;
    push_figure(
        h,
        &format!("correlation-{number}"),
        &svg,
        &format!(
            "Left: {} of {} lags outside the 99 % band &plusmn;{:.3}; Ljung-Box Q = {:.1}, p {} \
             (white residuals give p &gt; 0.01). Right: peak {:+.3} at lag {} (band &plusmn;{:.3}); \
             a peak outside the band means the model misses part of the answer to the input.",
            a.outside,
            a.values.len(),
            a.band,
            a.ljung_box,
            if a.p_value < 1e-16 { p_value(a.p_value) } else { format!("= {}", p_value(a.p_value)) },
            x.peak,
            x.peak_lag,
            x.band
        ),
    );
    Ok(())
}
