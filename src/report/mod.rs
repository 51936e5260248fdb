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
//! It presents; the numbers come from [`crate::evidence`], [`crate::modelling::diagnose`],
//! [`crate::fit::analysis`], [`crate::design::inverse`] and [`crate::pipeline`] (the compensated
//! signal, as `unlag compensate` gives it). The charts are in [`plot`].

use std::fmt::Write as _;
use std::path::Path;

use crate::error::Result;
use crate::evidence::TestEvidence;
use crate::file::ModelFile;
use crate::fit::Test;
use crate::modelling::diagnose::{Candidate, Remedy};

mod compensated;
mod each_test;
mod frequency;
mod history;
pub mod plot;
mod poles;

use each_test::per_test;
use frequency::bode;
use history::{candidates, history};
use poles::poles;

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
    /// The residual evidence per test ([`crate::pipeline::diagnose()`]).
    pub evidence: &'a [TestEvidence],
    /// The ranked candidates ([`crate::pipeline::diagnose()`]).
    pub candidates: &'a [Candidate],
    /// How a candidate's change is worded: `|r| r.to_string()` for the library's words
    /// ([`Remedy`]'s `Display`), [`Remedy::command`] for the `unlag` command that makes it.
    pub change_text: fn(&Remedy) -> String,
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
    // Each test's section first, for the summary table above them: it holds the errors of
    // the compensated signals, made once (a shock-tube record is millions of samples).
    let mut sections = String::new();
    sections.push_str("<h2 id=\"tests\">The model against each test</h2>\n");
    let mut reconstructions = Vec::with_capacity(inputs.tests.len());
    for (i, (test, ev)) in inputs.tests.iter().zip(inputs.evidence).enumerate() {
        reconstructions.push(per_test(&mut sections, inputs, i + 1, test, ev)?);
    }
    summary_table(&mut h, inputs, &reconstructions);
    h.push_str(&sections);
    drop(sections);
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
                 ({} in a trial refit). {}<br>Change: <code>{}</code></div>",
                escape(c.kind.as_str()),
                escape(&c.error_change()).replace(" -> ", " &rarr; "),
                escape(&c.reading),
                escape(&(inputs.change_text)(&c.change))
            );
        }
        None => {
            h.push_str("<div class=\"verdict\">No diagnosis was run.</div>\n");
        }
    }
}

/// The table of the tests; `reconstructions[i]` is the compensated signal's errors on
/// `inputs.tests[i]`.
fn summary_table(
    h: &mut String,
    inputs: &Inputs<'_>,
    reconstructions: &[Option<crate::pipeline::ReferenceError>],
) {
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
    for (e, rec) in inputs.evidence.iter().zip(reconstructions) {
        let rec = rec.map_or_else(
            || "&ndash;".to_string(),
            |r| format!("{} / {}", pct(r.u_hat), pct(r.raw)),
        );
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{:.2}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{rec}</td></tr>",
            escape(&e.file),
            e.role,
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

#[cfg(test)]
mod tests {
    use super::each_test::step_window;
    use super::*;
    use crate::fit::model::{Model, TestRole};
    use crate::testing::model_file;

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
        let mut f = model_file(m.clone());
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
            TestRole::Estimation,
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
            change_text: |r| r.to_string(),
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
        let f = model_file(m.clone());
        let tests = [Test {
            name: "a<b>.csv",
            u: &u,
            y: &y,
        }];
        let ym = m.simulate(&u);
        let ev = [TestEvidence::measure(
            "a<b>.csv",
            TestRole::Estimation,
            &m,
            (&u, &y),
            &ym,
        )];
        let c = Candidate {
            margin: 0.5,
            ..Candidate::new(
                crate::modelling::diagnose::Finding::Missing(crate::effects::EffectKind::Leak),
                0.5,
                (
                    crate::modelling::diagnose::Evidence::Leak {
                        dc_gain: 0.5,
                        late_residual_over_step: 1.0,
                        creep_in_standard_errors: 40.0,
                        creep_slope_kept: Some(0.02),
                    },
                    "a slow creep & more".into(),
                ),
                Remedy::Add(crate::effects::Effect::Leak),
                (0.0123, 0.00456),
            )
        };
        let html = render(&Inputs {
            model_name: "m.toml",
            file: &f,
            tests: &tests,
            evidence: &ev,
            candidates: &[c],
            change_text: |r| r.to_string(),
        })
        .unwrap();
        assert!(html.contains("Diagnosis: <span class=\"effect\">leak</span>"));
        assert!(html.contains("1.230 %") && html.contains("0.456 %"));
        assert!(html.contains(&pct(ev[0].nrmse)));
        assert!(html.contains("a slow creep &amp; more"));
        assert!(html.contains("a&lt;b&gt;.csv") && !html.contains("a<b>.csv"));
        // The subtitle says what is there in words; the candidates' evidence is not JSON.
        assert!(html.contains("no effects added") && !html.contains("effects []"));
        assert!(
            html.contains(
                "<code>creep in standard errors: 40.0; creep slope kept: 0.02; dc gain: 0.5; \
                 late residual over step: 1.0</code>"
            ),
            "evidence as text"
        );
        // The change in the words it was given: here the library's.
        assert!(html.contains(
            "<code>add the leak effect   (model file: effects = [{ kind = &quot;leak&quot; }])</code>"
        ));
    }

    #[test]
    fn the_step_window_covers_the_answer() {
        let m = model();
        let (u, y) = step_test(5_000, &m);
        let ym = m.simulate(&u);
        let ev = TestEvidence::measure("t", TestRole::Estimation, &m, (&u, &y), &ym);
        let w = step_window(&ev, &ym);
        assert!(
            w.start < ev.step_onset && w.end > ev.step_onset + 40,
            "{w:?}"
        );
        assert!(w.end - w.start <= 5_000 / 4 + 40);
    }
}
