//! The HTML report: where the model and the measurement part, at a glance.
//!
//! This module owns the report's content and layout: one self-contained HTML file (inline SVG
//! and CSS, no script, no network, no font file; a generic font family) with, for a model file
//! and its step tests, the probe against the model with the residual beneath (whole record and
//! a zoom on the step), the compensated signal against the reference beside the raw probe, the
//! residual spectrum with its peaks labelled by the diagnosis, the residual autocorrelation and
//! input cross-correlation with their 99 % bands, the Bode plot of the model, the compensator
//! and their product (with the physical prediction when the model file has a `[probe]`
//! geometry), the pole-zero map, the modes table, the error history and the ranked candidates.
//! It presents; the numbers come from [`crate::modelling::evidence`], [`crate::modelling::diagnose`],
//! [`crate::fit::analysis`] and [`crate::design::inverse`]. The charts are in [`plot`].

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::SeriesLabelPosition;

use crate::error::Result;
use crate::file::{ModelFile, ProbeGeometry};
use crate::fit::analysis::{self, Analysis, ModeKind};
use crate::fit::Test;
use crate::modelling::diagnose::Candidate;
use crate::modelling::effects;
use crate::modelling::evidence::TestEvidence;
use crate::poly::Complex;

pub mod plot;

use plot::{colour, figure, Marker, Panel, Series, Style};

/// What a report is made of: the model file, its tests, and what `compare` and `diagnose`
/// measured on them (`evidence[i]` belongs to `tests[i]`).
#[derive(Debug, Clone, Copy)]
pub struct Inputs<'a> {
    /// The model file's name as given.
    pub model_name: &'a str,
    /// The model file.
    pub file: &'a ModelFile,
    /// The step tests; the first is the estimation test.
    pub tests: &'a [Test<'a>],
    /// The residual evidence per test ([`crate::modelling::diagnose::evidence`]).
    pub evidence: &'a [TestEvidence],
    /// The ranked candidates ([`crate::modelling::diagnose::diagnose`]).
    pub candidates: &'a [Candidate],
}

/// Identifiers of the plots a report holds (`<figure class="plot" id=...>`), in page order;
/// per-test plots end in `-N` (1-based test number).
#[must_use]
pub fn plot_ids(tests: usize, compensated: bool) -> Vec<String> {
    let mut ids = Vec::new();
    for i in 1..=tests {
        ids.push(format!("trace-{i}"));
        ids.push(format!("zoom-{i}"));
        if compensated {
            ids.push(format!("compensated-{i}"));
        }
        ids.push(format!("spectrum-{i}"));
        ids.push(format!("correlation-{i}"));
    }
    ids.extend(["bode", "pole-zero", "history"].map(String::from));
    ids
}

/// Writes the report atomically (a temporary file renamed into place); returns its size in
/// bytes.
///
/// # Errors
/// [`crate::Error::Plot`] when a chart cannot be drawn, [`crate::Error::Io`] when the file
/// cannot be written (nothing is left behind).
pub fn write(path: &Path, inputs: &Inputs<'_>) -> Result<usize> {
    let html = render(inputs)?;
    crate::file::write_atomically(path, html.as_bytes())?;
    Ok(html.len())
}

/// Escapes text for HTML.
#[must_use]
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            _ => out.push(c),
        }
    }
    out
}

/// Whether two names given on command lines are the same test file (the model file records
/// the names `unlag fit` was given; the report may be given the same files by other paths).
fn same_file(a: &str, b: &str) -> bool {
    a == b
        || (Path::new(a).file_name().is_some()
            && Path::new(a).file_name() == Path::new(b).file_name())
}

/// A number with four significant digits, without an exponent where one is not needed.
fn num(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-3..1e5).contains(&a) {
        format!("{x:.4}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{x:.3e}")
    }
}

/// A p-value: tiny ones as a bound.
fn p_value(p: f64) -> String {
    if p < 1e-16 {
        "&lt; 1e-16".into()
    } else {
        format!("{p:.2e}")
    }
}

/// A fraction as a percentage with three decimals, as the terminal prints it.
fn pct(x: f64) -> String {
    format!("{:.3} %", 100.0 * x)
}

const STYLE: &str = "
body { font-family: sans-serif; color: #222; max-width: 1060px; margin: 0 auto; padding: 1em 1.5em 4em; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 2px solid #0072b2; padding-bottom: 0.15em; margin-top: 2em; }
h3 { font-size: 1.05em; margin-top: 1.5em; }
.sub { color: #666; margin-top: 0; }
.verdict { background: #fff7e6; border-left: 5px solid #e69f00; padding: 0.6em 1em; margin: 1em 0; }
.verdict.ok { background: #e9f7f1; border-left-color: #009e73; }
figure.plot { margin: 0.8em 0 1.6em; }
figure.plot svg { width: 100%; height: auto; display: block; border: 1px solid #e4e4e4; }
figcaption { color: #555; font-size: 0.92em; margin-top: 0.3em; }
table { border-collapse: collapse; margin: 0.6em 0 1em; font-size: 0.93em; }
th, td { border-bottom: 1px solid #ddd; padding: 0.25em 0.7em; text-align: left; vertical-align: top; }
th { background: #f3f6f9; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
code { background: #f4f4f4; padding: 0 0.25em; font-size: 0.92em; }
nav a { margin-right: 1em; }
.note { color: #666; font-style: italic; }
";

/// Renders the whole page.
///
/// # Errors
/// [`crate::Error::Plot`] when a chart cannot be drawn.
pub fn render(inputs: &Inputs<'_>) -> Result<String> {
    let file = inputs.file;
    let model = &file.model;
    let mut h = String::new();
    let title = format!("unlag report: {}", inputs.model_name);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n",
        escape(&title)
    );
    let effects: Vec<&str> = file.effects.iter().map(|e| e.kind().as_str()).collect();
    let effects = if effects.is_empty() {
        "no effects added".to_string()
    } else {
        format!("effects: {}", effects.join(", "))
    };
    let _ = write!(
        h,
        "<h1>{}</h1>\n<p class=\"sub\">order {}, delay {} samples ({:.4} ms), fs {} Hz, DC gain {:.4}; \
         {}; {} test(s)</p>\n",
        escape(&title),
        model.order(),
        model.delay,
        1e3 * model.delay as f64 / model.fs,
        model.fs,
        model.dc_gain(),
        escape(&effects),
        inputs.tests.len()
    );
    verdict(&mut h, inputs);
    let _ = writeln!(
        h,
        "<nav><a href=\"#tests\">tests</a><a href=\"#frequency\">frequency response</a>\
         <a href=\"#poles\">poles and modes</a><a href=\"#loop\">error history and candidates</a></nav>"
    );
    summary_table(&mut h, inputs);

    h.push_str("<h2 id=\"tests\">The model against each test</h2>\n");
    for (i, (test, ev)) in inputs.tests.iter().zip(inputs.evidence).enumerate() {
        per_test(&mut h, inputs, i + 1, test, ev)?;
    }
    h.push_str("<h2 id=\"frequency\">Frequency response</h2>\n");
    bode(&mut h, inputs)?;
    h.push_str("<h2 id=\"poles\">Poles, zeros and modes</h2>\n");
    poles(&mut h, inputs)?;
    h.push_str("<h2 id=\"loop\">Error history and the missing effect</h2>\n");
    history(&mut h, inputs)?;
    candidates(&mut h, inputs);
    let _ = writeln!(
        h,
        "<p class=\"note\">Written by unlag {}. Self-contained: no script, no network.</p>\n</body>\n</html>",
        env!("CARGO_PKG_VERSION")
    );
    Ok(h)
}

fn top_effect<'a>(inputs: &Inputs<'a>) -> Option<&'a Candidate> {
    inputs.candidates.first()
}

fn verdict(h: &mut String, inputs: &Inputs<'_>) {
    match top_effect(inputs) {
        Some(c) if c.kind == crate::modelling::diagnose::Finding::Nothing => {
            let _ = writeln!(
                h,
                "<div class=\"verdict ok\"><b>Diagnosis: none.</b> {}</div>",
                escape(&c.reading)
            );
        }
        Some(c) => {
            let _ = writeln!(
                h,
                "<div class=\"verdict\"><b>Diagnosis: <span class=\"effect\">{}</span></b> \
                 (held-out error {} &rarr; {} in a trial refit). {}<br>Change: <code>{}</code></div>",
                escape(c.kind.as_str()),
                pct(c.nrmse_before),
                pct(c.nrmse_after),
                escape(&c.reading),
                escape(&c.change)
            );
        }
        None => {
            h.push_str("<div class=\"verdict\">No diagnosis was run.</div>\n");
        }
    }
}

/// The candidate's stated uncertainty before and after its trial, as HTML (empty when either
/// is missing).
fn stated_uncertainty(c: &Candidate) -> String {
    c.uncertainty_text()
        .map(|t| format!("<br><small>{}</small>", escape(&t)))
        .unwrap_or_default()
}

fn summary_table(h: &mut String, inputs: &Inputs<'_>) {
    h.push_str(
        "<p>The noise floor is what a correct model leaves: the probe's noise and the \
         reference's own noise through the model (both channels are sensors). Ljung-Box tests \
         the residual's correlation against that noise's, not against white noise.</p>\n",
    );
    h.push_str(
        "<table class=\"summary\"><tr><th>test</th><th>role</th><th>samples</th><th>fit %</th>\
         <th>error (nrmse)</th><th>noise floor</th><th>error / floor</th><th>Ljung-Box p</th>\
         <th>reconstruction u&#770; / raw probe</th></tr>\n",
    );
    for (e, test) in inputs.evidence.iter().zip(inputs.tests) {
        let rec = compensated_signal(inputs, test).map_or_else(
            || "&ndash;".to_string(),
            |c| format!("{} / {}", pct(c.error), pct(c.raw_error)),
        );
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{rec}</td></tr>",
            escape(&e.file),
            escape(&e.role),
            e.samples,
            e.fit_percent,
            pct(e.nrmse),
            pct(e.noise_floor),
            e.nrmse / e.noise_floor.max(1e-300),
            p_value(e.autocorrelation.p_value),
        );
    }
    h.push_str("</table>\n");
}

/// Time axis: milliseconds for records shorter than 2 s.
fn time_unit(samples: usize, fs: f64) -> (f64, &'static str) {
    if samples as f64 / fs < 2.0 {
        (1e3, "time (ms)")
    } else {
        (1.0, "time (s)")
    }
}

fn points(values: &[f64], range: std::ops::Range<usize>, fs: f64, scale: f64) -> Vec<(f64, f64)> {
    let v = values.get(range.clone()).unwrap_or(&[]);
    // Decimated here as the line series would be, so a long record is never copied whole.
    plot::decimated_indices(v.len(), plot::COLUMNS, |i| v.get(i).copied().unwrap_or(0.0))
        .into_iter()
        .filter_map(|i| Some((scale * (range.start + i) as f64 / fs, *v.get(i)?)))
        .collect()
}

fn push_figure(h: &mut String, id: &str, svg: &str, caption: &str) {
    let _ = writeln!(
        h,
        "<figure class=\"plot\" id=\"{id}\">\n{svg}\n<figcaption>{caption}</figcaption>\n</figure>"
    );
}

/// The samples around the step where the probe's answer happens: from a little before the
/// onset until the model has settled within 2 % of the step (at least 40 samples, at most a
/// quarter of the record).
fn step_window(ev: &TestEvidence, y_model: &[f64]) -> std::ops::Range<usize> {
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

fn per_test(
    h: &mut String,
    inputs: &Inputs<'_>,
    number: usize,
    test: &Test<'_>,
    ev: &TestEvidence,
) -> Result<()> {
    let file = inputs.file;
    let model = &file.model;
    let fs = model.fs;
    let n = test.y.len().min(test.u.len());
    let y_model = effects::predict(model, &file.effects, test.u, test.y);
    let residual: Vec<f64> = test.y.iter().zip(&y_model).map(|(a, b)| a - b).collect();
    let (scale, t_label) = time_unit(n, fs);
    let _ = writeln!(
        h,
        "<h3>Test {number}: {} ({}): error {} against a noise floor of {}</h3>",
        escape(&ev.file),
        escape(&ev.role),
        pct(ev.nrmse),
        pct(ev.noise_floor)
    );
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
    compensated(h, inputs, number, test, window)?;
    spectrum(h, inputs, number, ev)?;
    correlations(h, number, ev)?;
    Ok(())
}

/// The compensated signal of a test and its errors against the reference.
struct Compensated {
    /// `u_hat` as the compensator gives it (lagging by `lag`).
    u_hat: Vec<f64>,
    /// Its lag behind the reference (samples).
    lag: usize,
    /// Which compensator.
    how: String,
    /// Error of `u_hat` against the reference at that lag (RMS / range).
    error: f64,
    /// Error of the raw probe against the reference at its best alignment (as
    /// [`crate::design::inverse::reconstruct`] measures it).
    raw_error: f64,
}

fn compensated_signal(inputs: &Inputs<'_>, test: &Test<'_>) -> Option<Compensated> {
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

fn compensated(
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
    let (expected, significance) = (along(0.0), along(crate::modelling::evidence::PEAK_DB));
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
                &format!(
                    "significance: {} dB above it",
                    crate::modelling::evidence::PEAK_DB
                ),
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
            crate::modelling::evidence::PEAK_DB
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

/// Continuous phase along a grid, in degrees.
fn unwrap_deg(values: &[Complex]) -> Vec<f64> {
    let mut out = Vec::with_capacity(values.len());
    let mut previous: Option<f64> = None;
    for v in values {
        let mut p = v.arg();
        if let Some(q) = previous {
            let tau = 2.0 * std::f64::consts::PI;
            p += tau * ((q - p) / tau).round();
        }
        previous = Some(p);
        out.push(p.to_degrees());
    }
    out
}

fn db(m: f64) -> f64 {
    20.0 * m.max(1e-12).log10()
}

fn physics_response(g: &ProbeGeometry, freqs: &[f64]) -> Option<Vec<Complex>> {
    use crate::physics::gas::Gas;
    use crate::physics::line::Line;
    let gas = Gas::air(g.temperature_k, g.pressure_pa);
    gas.validate().ok()?;
    let line = g
        .lines
        .iter()
        .fold(Line::new(), |l, [length, diameter]| {
            l.tube(*length, diameter / 2.0)
        })
        .volume(g.volume_m3);
    line.validate().ok()?;
    let h: Vec<Complex> = freqs
        .iter()
        .map(|f| {
            let v = line.frequency_response(&gas, *f);
            Complex::new(v.re, v.im)
        })
        .collect();
    h.iter()
        .all(|v| v.re.is_finite() && v.im.is_finite())
        .then_some(h)
}

fn bode(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
    let file = inputs.file;
    let model = &file.model;
    let fs = model.fs;
    let (lo, hi) = (fs / 2.0 * 1e-3, fs / 2.0 * 0.995);
    let count = 400;
    let freqs: Vec<f64> = (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1) as f64))
        .collect();
    let unit = |f: f64| {
        let w = 2.0 * std::f64::consts::PI * f / fs;
        Complex::new(w.cos(), w.sin())
    };
    let hm: Vec<(f64, f64)> = analysis::frequency_response(model, &freqs);
    // Phase with the pure delays removed (they would swamp the dynamics with thousands of
    // degrees): the model's d samples; the design's latency is that of u_hat behind u, the
    // product's, of which the compensator adds latency - d.
    let delay = model.delay as f64;
    let latency = file.inverse.as_ref().map_or(0.0, |c| c.latency_samples);
    let turn = |f: f64, samples: f64| 360.0 * f * samples / fs;
    let mut mag = vec![Series::with(
        "model",
        freqs
            .iter()
            .zip(&hm)
            .map(|(f, (m, _))| (*f, db(*m)))
            .collect(),
        colour::MODEL,
        Style::Line(2),
    )];
    let mut phase = vec![Series::with(
        "model",
        freqs
            .iter()
            .zip(&hm)
            .map(|(f, (_, p))| (*f, p.to_degrees() + turn(*f, delay)))
            .collect(),
        colour::MODEL,
        Style::Line(2),
    )];
    let mut caption = String::from("Model H (the fitted probe, delay included)");
    if let Some(d) = &file.inverse {
        let c: Vec<Complex> = freqs
            .iter()
            .map(|f| crate::design::inverse::cascade_response(d.gain, &d.sections, unit(*f)))
            .collect();
        let product: Vec<Complex> = freqs
            .iter()
            .zip(&c)
            .map(|(f, c)| analysis::response(model, *f) * c)
            .collect();
        let (pc, pp) = (unwrap_deg(&c), unwrap_deg(&product));
        mag.push(Series::with(
            "compensator C",
            freqs
                .iter()
                .zip(&c)
                .map(|(f, v)| (*f, db(v.norm())))
                .collect(),
            colour::COMPENSATED,
            Style::Line(2),
        ));
        mag.push(Series::with(
            "corrected H C",
            freqs
                .iter()
                .zip(&product)
                .map(|(f, v)| (*f, db(v.norm())))
                .collect(),
            colour::PRODUCT,
            Style::Line(2),
        ));
        phase.push(Series::with(
            "compensator C",
            freqs
                .iter()
                .zip(pc)
                .map(|(f, p)| (*f, p + turn(*f, latency - delay)))
                .collect(),
            colour::COMPENSATED,
            Style::Line(2),
        ));
        phase.push(Series::with(
            "corrected H C",
            freqs
                .iter()
                .zip(pp)
                .map(|(f, p)| (*f, p + turn(*f, latency)))
                .collect(),
            colour::PRODUCT,
            Style::Line(2),
        ));
        let _ = write!(
            caption,
            ", the compensator C ({}) and the corrected response H C: flat \
             to {:.0} Hz within &plusmn;1 dB and &plusmn;5&deg;, latency {:.2} samples ({:.3} ms)",
            d.band_text(),
            d.corrected_bandwidth_hz,
            d.latency_samples,
            1e3 * d.latency_s
        );
    } else {
        caption.push_str(" (the model file has no designed compensator)");
    }
    match file
        .probe
        .as_ref()
        .map(|g| (g, physics_response(g, &freqs)))
    {
        Some((g, Some(p))) => {
            mag.push(Series::with(
                "physics prediction",
                freqs
                    .iter()
                    .zip(&p)
                    .map(|(f, v)| (*f, db(v.norm())))
                    .collect(),
                colour::PHYSICS,
                Style::Dashed,
            ));
            phase.push(Series::with(
                "physics prediction",
                freqs
                    .iter()
                    .zip(unwrap_deg(&p))
                    .map(|(f, p)| (*f, p + turn(*f, delay)))
                    .collect(),
                colour::PHYSICS,
                Style::Dashed,
            ));
            let lines: Vec<String> = g
                .lines
                .iter()
                .map(|[l, d]| format!("{l} m x {} mm", d * 1e3))
                .collect();
            let _ = write!(
                caption,
                "; dashed: the physical prediction (Bergh-Tijdeman) for the file's probe geometry, \
                 line {} into {:.3e} m^3 at {} K",
                lines.join(" + "),
                g.volume_m3,
                g.temperature_k
            );
        }
        Some((_, None)) => caption.push_str(
            "; the file's [probe] geometry is not valid, so no physical prediction is drawn",
        ),
        None => caption.push_str(
            "; no physical prediction: the model file names no probe geometry (add a [probe] \
             table with lines = [[length_m, diameter_m]] and volume_m3)",
        ),
    }
    let _ = write!(
        caption,
        ". Phase drawn with the pure delays taken out: the model's {} samples (from the \
         physical prediction likewise), the corrected response's latency of {latency:.2} samples, \
         and their difference from the compensator",
        model.delay
    );
    caption.push('.');
    // Magnitude from -60 dB up: the band that matters is near 0 dB.
    // (points beyond the view are left out: a line that ends is honest, one that runs flat
    // along the border is not).
    for x in &mut mag {
        x.points.retain(|p| (-60.0..=60.0).contains(&p.1));
    }
    let mut m = Panel::new("magnitude", "frequency (Hz)", "magnitude (dB)", mag);
    m.log_x = true;
    m.x = lo..hi;
    m.legend = SeriesLabelPosition::LowerLeft;
    for x in &mut phase {
        x.points.retain(|p| (-400.0..=400.0).contains(&p.1));
    }
    let mut p = Panel::new(
        "phase (pure delays removed)",
        "frequency (Hz)",
        "phase (degrees)",
        phase,
    );
    p.log_x = true;
    p.x = lo..hi;
    p.legend = SeriesLabelPosition::LowerLeft;
    let svg = figure("bode", &[m, p], 330, 1)?;
    push_figure(h, "bode", &svg, &caption);
    Ok(())
}

fn poles(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
    let model = &inputs.file.model;
    let a = match Analysis::new(model) {
        Ok(a) => a,
        Err(e) => {
            let _ = writeln!(
                h,
                "<p class=\"note\">No pole-zero analysis: {}</p>",
                escape(&e.to_string())
            );
            return Ok(());
        }
    };
    let view = 1.6f64;
    let inside = |r: &&analysis::Root| r.magnitude <= view;
    let circle: Vec<(f64, f64)> = (0..=240)
        .map(|i| {
            let t = 2.0 * std::f64::consts::PI * f64::from(i) / 240.0;
            (t.cos(), t.sin())
        })
        .collect();
    let series = vec![
        Series::with("unit circle", circle, colour::GUIDE, Style::Line(1)),
        Series::with(
            "poles",
            a.poles
                .iter()
                .filter(inside)
                .map(|r| (r.re, r.im))
                .collect(),
            colour::PROBE,
            Style::Crosses,
        ),
        Series::with(
            "zeros",
            a.zeros
                .iter()
                .filter(inside)
                .map(|r| (r.re, r.im))
                .collect(),
            colour::RESIDUAL,
            Style::Circles,
        ),
    ];
    let mut p = Panel::new(
        "pole-zero map of the model (z plane)",
        "real part",
        "imaginary part",
        series,
    );
    p.x = -view..view;
    p.y = -view..view;
    p.legend = SeriesLabelPosition::UpperLeft;
    // A square plot keeps the circle round: draw it in a square SVG.
    let svg = plot::figure_sized("pole-zero", &[p], (560, 540), 1)?;
    let svg = format!("<div style=\"max-width: 560px\">{svg}</div>");
    let outside: Vec<String> = a
        .zeros
        .iter()
        .filter(|r| r.magnitude > view)
        .map(|r| format!("{:.3}{:+.3}j", r.re, r.im))
        .collect();
    push_figure(
        h,
        "pole-zero",
        &svg,
        &format!(
            "Stable: {} (margin {:.4}). Minimum phase: {} (margin {:.4}){}.",
            a.stable,
            a.stability_margin,
            a.minimum_phase,
            a.minimum_phase_margin,
            if outside.is_empty() {
                String::new()
            } else {
                format!("; zeros outside the view: {}", outside.join(", "))
            }
        ),
    );
    h.push_str(
        "<table class=\"modes\"><tr><th>mode</th><th>natural frequency</th><th>damping ratio</th>\
         <th>time constant</th><th>pole</th></tr>\n",
    );
    for m in &a.modes {
        let what = match &m.kind {
            ModeKind::Resonance { .. } => "resonance (pole pair)",
            ModeKind::Real { .. } => "first-order lag (real pole)",
            ModeKind::Nyquist { .. } => "alternating (negative real pole)",
            ModeKind::Origin => "pole at the origin",
        };
        let (f, z, tau) = match &m.kind {
            ModeKind::Resonance {
                natural_frequency_hz,
                damping,
                ..
            } => (
                format!("{natural_frequency_hz:.1} Hz"),
                format!("{damping:.3}"),
                "&ndash;".to_string(),
            ),
            ModeKind::Real {
                time_constant_s, ..
            } => (
                "&ndash;".into(),
                "&ndash;".into(),
                time_constant_s.map_or("&infin;".into(), |t| format!("{:.4} ms", 1e3 * t)),
            ),
            ModeKind::Nyquist { frequency_hz, .. } => (
                format!("{frequency_hz:.1} Hz (Nyquist)"),
                "&ndash;".into(),
                "&ndash;".into(),
            ),
            ModeKind::Origin => ("&ndash;".into(), "&ndash;".into(), "&ndash;".into()),
        };
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"num\">{f}</td><td class=\"num\">{z}</td>\
             <td class=\"num\">{tau}</td><td class=\"num\">{:.4}{:+.4}j (|z| {:.4})</td></tr>",
            what, m.pole.re, m.pole.im, m.pole.magnitude
        );
    }
    h.push_str("</table>\n");
    Ok(())
}

fn history(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
    let file = inputs.file;
    let rows = &file.history;
    let step_name = |i: usize| {
        rows.get(i).map_or(String::new(), |r| {
            if r.effects.is_empty() {
                format!("{}. order {}", i + 1, r.order)
            } else {
                format!("{}. +{}", i + 1, r.effects.join("+"))
            }
        })
    };
    let mut files: Vec<&str> = Vec::new();
    for t in rows.iter().flat_map(|r| r.tests.iter()) {
        if !files.contains(&t.file.as_str()) {
            files.push(&t.file);
        }
    }
    let palette = [
        colour::PROBE,
        colour::MODEL,
        colour::COMPENSATED,
        colour::PHYSICS,
    ];
    let mut series: Vec<Series> = files
        .iter()
        .enumerate()
        .map(|(j, f)| {
            let pts: Vec<(f64, f64)> = rows
                .iter()
                .enumerate()
                .filter_map(|(i, r)| {
                    r.tests
                        .iter()
                        .find(|t| t.file == *f)
                        .map(|t| ((i + 1) as f64, 100.0 * t.nrmse))
                })
                .collect();
            let name = Path::new(f)
                .file_name()
                .map_or_else(|| (*f).to_string(), |n| n.to_string_lossy().into_owned());
            Series::with(
                &name,
                pts,
                palette[j % palette.len()],
                if rows.len() > 1 {
                    Style::Line(2)
                } else {
                    Style::Crosses
                },
            )
        })
        .collect();
    // Marks on every step (a line alone hides where the steps are).
    let marks: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .collect();
    series.push(Series::with("", marks, colour::REFERENCE, Style::Crosses));
    let floor = {
        let f: Vec<f64> = file.sources.iter().map(|s| s.noise_floor).collect();
        if f.is_empty() {
            None
        } else {
            Some(100.0 * f.iter().sum::<f64>() / f.len() as f64)
        }
    };
    if rows.is_empty() {
        h.push_str(
            "<p class=\"note\">The model file has no error history (it was not written by \
             <code>unlag fit</code>).</p>\n",
        );
    }
    let mut p = Panel::new(
        "error of each fit in this model file",
        "fit (effects added)",
        "error nrmse (%)",
        series,
    );
    if let Some(f) = floor {
        p = p.guides(vec![(f, "noise floor (mean)".into())]);
    }
    // From zero, with room above the highest point for its mark.
    let top = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|q| q.1))
        .chain(floor)
        .fold(0.0f64, f64::max);
    p.y = 0.0..(1.15 * top).max(1e-6);
    p.x = 0.5..(rows.len().max(1) as f64 + 0.5);
    p.x_names = (0..rows.len()).map(step_name).collect();
    let svg = figure("history", &[p], 320, 1)?;
    push_figure(
        h,
        "history",
        &svg,
        "Each point is one <code>unlag fit</code> into this file (x: the fit number and what \
         it added), its simulation error on each test; the error should fall towards the noise \
         floor as effects are added.",
    );
    h.push_str(
        "<table class=\"history\"><tr><th>fit</th><th>order</th><th>delay</th><th>effects</th>\
         <th>error per test</th></tr>\n",
    );
    for (i, r) in rows.iter().enumerate() {
        let errs: Vec<String> = r
            .tests
            .iter()
            .map(|t| {
                format!(
                    "{} ({}): {}",
                    escape(&t.file),
                    escape(&t.role),
                    pct(t.nrmse)
                )
            })
            .collect();
        let _ = writeln!(
            h,
            "<tr><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>\
             <td>[{}]</td><td>{}</td></tr>",
            i + 1,
            r.order,
            r.delay,
            escape(&r.effects.join(", ")),
            errs.join("<br>")
        );
    }
    h.push_str("</table>\n");
    Ok(())
}

/// The evidence's numbers to four significant digits (the full ones are in `--json`).
fn rounded(v: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if n.is_f64() && x != 0.0 && x.is_finite() => {
                let digits = 3 - x.abs().log10().floor() as i32;
                let scale = 10f64.powi(digits);
                serde_json::Number::from_f64((x * scale).round() / scale)
                    .map_or_else(|| v.clone(), Value::Number)
            }
            _ => v.clone(),
        },
        Value::Array(a) => Value::Array(a.iter().map(rounded).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, x)| (k.clone(), rounded(x))).collect()),
        _ => v.clone(),
    }
}

/// A candidate's evidence as a reader reads it: `name value` pairs, nested names joined by
/// dots, long lists cut to their first values.
fn evidence_text(v: &serde_json::Value) -> String {
    use serde_json::Value;
    fn scalar(v: &Value) -> String {
        match v {
            Value::String(s) => s.clone(),
            Value::Array(a) => {
                let mut items: Vec<String> = a.iter().take(6).map(scalar).collect();
                if a.len() > 6 {
                    items.push(format!("... {} in all", a.len()));
                }
                items.join(", ")
            }
            Value::Null => "none".into(),
            other => other.to_string(),
        }
    }
    fn walk(prefix: &str, v: &Value, out: &mut Vec<String>) {
        match v {
            Value::Object(o) => {
                for (k, x) in o {
                    let name = if prefix.is_empty() {
                        k.replace('_', " ")
                    } else {
                        format!("{prefix} {}", k.replace('_', " "))
                    };
                    walk(&name, x, out);
                }
            }
            other if prefix.is_empty() => out.push(scalar(other)),
            other => out.push(format!("{prefix}: {}", scalar(other))),
        }
    }
    let mut out = Vec::new();
    walk("", v, &mut out);
    out.join("; ")
}

fn candidates(h: &mut String, inputs: &Inputs<'_>) {
    h.push_str(
        "<h3>Candidates for the missing effect, best first</h3>\n\
         <table class=\"candidates\"><tr><th>#</th><th>effect</th><th>score</th>\
         <th>held-out error</th><th>reading and evidence</th><th>change</th></tr>\n",
    );
    for (i, c) in inputs.candidates.iter().enumerate() {
        let evidence = evidence_text(&rounded(&c.evidence));
        let _ = writeln!(
            h,
            "<tr><td class=\"num\">{}</td><td><b>{}</b></td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{} &rarr; {}</td><td>{}{}<br><small><code>{}</code></small></td>\
             <td><code>{}</code></td></tr>",
            i + 1,
            escape(c.kind.as_str()),
            c.score,
            pct(c.nrmse_before),
            pct(c.nrmse_after),
            escape(&c.reading),
            stated_uncertainty(c),
            escape(&evidence),
            escape(&c.change)
        );
    }
    h.push_str("</table>\n<p class=\"sub\">Score: ln of the held-out error's fall in a trial refit, less a small charge per parameter.</p>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::model::Model;

    fn file(model: Model) -> ModelFile {
        ModelFile {
            format_version: crate::file::FORMAT_VERSION,
            model,
            fit: None,
            sources: Vec::new(),
            inverse: None,
            effects: Vec::new(),
            history: Vec::new(),
            probe: None,
        }
    }

    fn step_test(n: usize, model: &Model) -> (Vec<f64>, Vec<f64>) {
        let u: Vec<f64> = (0..n).map(|k| if k < n / 10 { 0.0 } else { 1.0 }).collect();
        let mut y = model.simulate(&u);
        // Deterministic noise and a one-sample glitch the report must not hide.
        let mut s = 12_345u64;
        for v in &mut y {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            *v += 1e-3 * ((s >> 33) as f64 / (1u64 << 31) as f64 - 0.5);
        }
        (u, y)
    }

    fn model() -> Model {
        Model {
            fs: 10_000.0,
            delay: 5,
            a: vec![-1.8, 0.85],
            b: vec![0.025, 0.025],
        }
    }

    #[test]
    fn a_100_000_sample_report_stays_under_2_mb() {
        let m = model();
        let (u, y) = step_test(100_000, &m);
        let mut f = file(m.clone());
        let options = crate::design::inverse::Options {
            bandwidth_hz: Some(500.0),
            lowpass: crate::design::inverse::LowpassKind::Bessel,
            lowpass_order: 4,
            stabilise: true,
        };
        f.inverse = Some(crate::design::inverse::design(&m, 500.0, &options).unwrap());
        let tests = [Test {
            name: "long.csv",
            u: &u,
            y: &y,
        }];
        let ym = m.simulate(&u);
        let ev = [TestEvidence::measure(
            "long.csv",
            "estimation",
            &m,
            (&u, &y),
            &ym,
        )];
        let html = render(&Inputs {
            model_name: "m.toml",
            file: &f,
            tests: &tests,
            evidence: &ev,
            candidates: &[],
        })
        .unwrap();
        eprintln!("report of a 100 000-sample test: {} bytes", html.len());
        assert!(html.len() < 2_000_000, "{} bytes", html.len());
        // And it is the whole report, not a truncated one.
        for id in plot_ids(1, true) {
            assert!(html.contains(&format!("id=\"{id}\"")), "{id} missing");
        }
        assert!(!html.contains("<script") && !html.contains("<link"));
    }

    #[test]
    fn the_page_names_the_diagnosis_and_the_errors() {
        let m = model();
        let (u, y) = step_test(2_000, &m);
        let f = file(m.clone());
        let tests = [Test {
            name: "a<b>.csv",
            u: &u,
            y: &y,
        }];
        let ym = m.simulate(&u);
        let ev = [TestEvidence::measure(
            "a<b>.csv",
            "estimation",
            &m,
            (&u, &y),
            &ym,
        )];
        let c = Candidate {
            kind: crate::modelling::diagnose::Finding::Missing(
                crate::modelling::effects::EffectKind::Leak,
            ),
            score: 0.5,
            evidence: serde_json::json!({"x": 1}),
            reading: "a slow creep & more".into(),
            change: "unlag fit ... --add leak".into(),
            nrmse_before: 0.0123,
            nrmse_after: 0.00456,
            margin: 0.5,
            separated_by: None,
            uncertainty_before: None,
            uncertainty_after: None,
        };
        let html = render(&Inputs {
            model_name: "m.toml",
            file: &f,
            tests: &tests,
            evidence: &ev,
            candidates: &[c],
        })
        .unwrap();
        assert!(html.contains("Diagnosis: <span class=\"effect\">leak</span>"));
        assert!(html.contains("1.230 %") && html.contains("0.456 %"));
        assert!(html.contains(&pct(ev[0].nrmse)));
        assert!(html.contains("a slow creep &amp; more"));
        assert!(html.contains("a&lt;b&gt;.csv") && !html.contains("a<b>.csv"));
        // The subtitle says what is there in words; the candidates' evidence is not JSON.
        assert!(html.contains("no effects added") && !html.contains("effects []"));
        assert!(html.contains("<code>x: 1</code>"), "evidence as text");
    }

    #[test]
    fn evidence_reads_as_names_and_values_not_json() {
        let v = serde_json::json!({"peak_hz": 120.5, "band": {"low_db": -3.0}, "tests": [1, 2], "why": "a mode"});
        let t = evidence_text(&v);
        assert!(!t.contains('{') && !t.contains('"'), "{t}");
        assert!(t.contains("peak hz: 120.5"), "{t}");
        assert!(t.contains("band low db: -3.0"), "{t}");
        assert!(t.contains("tests: 1, 2"), "{t}");
        assert!(t.contains("why: a mode"), "{t}");
    }

    #[test]
    fn evidence_numbers_are_shortened_not_changed() {
        let v = serde_json::json!({"a": 0.000_716_295_602_505_328_9, "b": [303.955_078_125, 7],
                                   "c": "x", "d": -2.526_434_974_417_220_8});
        let r = rounded(&v);
        assert_eq!(r["a"].as_f64(), Some(0.000_716_3));
        assert_eq!(r["b"][0].as_f64(), Some(304.0));
        assert_eq!(r["b"][1].as_u64(), Some(7));
        assert_eq!(r["c"], "x");
        assert_eq!(r["d"].as_f64(), Some(-2.526));
    }

    #[test]
    fn the_step_window_covers_the_answer() {
        let m = model();
        let (u, y) = step_test(5_000, &m);
        let ym = m.simulate(&u);
        let ev = TestEvidence::measure("t", "estimation", &m, (&u, &y), &ym);
        let w = step_window(&ev, &ym);
        assert!(
            w.start < ev.step_onset && w.end > ev.step_onset + 40,
            "{w:?}"
        );
        assert!(w.end - w.start <= 5_000 / 4 + 40);
    }

    #[test]
    fn a_probe_geometry_gives_a_physical_prediction() {
        let g = ProbeGeometry {
            lines: vec![[0.6, 1.1e-3]],
            volume_m3: 20e-9,
            temperature_k: 293.15,
            pressure_pa: 101_325.0,
        };
        let h = physics_response(&g, &[1.0, 100.0]).unwrap();
        assert!((h[0].norm() - 1.0).abs() < 0.01, "{:?}", h[0]);
        let bad = ProbeGeometry {
            volume_m3: -1.0,
            ..g
        };
        assert!(physics_response(&bad, &[1.0]).is_none());
    }
}
