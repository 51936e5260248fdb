//! The compensated signal of a test as `unlag compensate` gives it (the library's pipeline, in
//! f32), its error against the reference beside the raw probe's, and its figure.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::SeriesLabelPosition;

use super::plot::{colour, figure, Panel, Series};
use super::{escape, pct, points, push_figure, time_unit, Inputs};
use crate::effects;
use crate::error::{Error, Result};
use crate::fit::Test;
use crate::pipeline::{
    self, Arithmetic, CompensateRequest, Compensated, Compensation, ReferenceError,
};

/// The test compensated as `unlag compensate MODEL TEST -o ...` compensates it: the model
/// file's offset and drift removed from the probe signal, the model file's compensator (the
/// paper's direct inverse when it has none) run in f32 with the nonlinear damping's
/// correction, as a board given the file computes it, judged beforehand on the test's own
/// probe spectrum ([`Compensated::predicted`]); its error against the reference at the best
/// alignment beside the raw probe's ([`Compensated::error`]).
///
/// # Errors
/// What [`pipeline::compensate`] refuses: a model without a stable inverse and a file without
/// a designed compensator, a design the board cannot run.
fn compensated_signal(inputs: &Inputs<'_>, test: &Test<'_>) -> Result<Compensated> {
    pipeline::compensate(&CompensateRequest {
        file: inputs.file,
        model_path: Path::new(inputs.model_name),
        probe: test.y,
        reference: Some(test.u),
        compensation: Compensation::Designed(Arithmetic::F32),
        temperature_k: None,
    })
}

/// Which compensator ran on the test and how, in words (HTML-escaped).
fn how(inputs: &Inputs<'_>, c: &Compensated) -> String {
    let file = inputs.file;
    let mut how = format!("{} in f32", c.compensator);
    let ran = c
        .fall_back
        .as_ref()
        .map(|f| &f.design)
        .or(file.inverse.as_ref())
        .filter(|_| c.designed);
    if let Some(d) = ran {
        let _ = write!(
            how,
            " ({} sections, {}, corrected bandwidth {:.0} Hz, noise gain {:.2})",
            d.sections.len(),
            d.band_text(),
            d.corrected_bandwidth_hz,
            d.noise_gain
        );
    } else if file.inverse.is_none() {
        how.push_str(" (the model file has no designed compensator)");
    }
    if let Some(stored) = c
        .predicted
        .filter(|p| p.ratio() >= crate::design::inverse::check::RUN_MARGIN)
    {
        let _ = write!(
            how,
            "; the run check predicts it to leave {:.2}x the raw probe's error on this test \
             (from its own probe spectrum): for runs like this one, design with them \
             (`unlag invert MODEL TEST.csv --signal RUN.csv`)",
            stored.ratio()
        );
    }
    if effects::Additive::of(&file.effects) != effects::Additive::default() {
        how.push_str(", on the probe signal less the model's offset and drift");
    }
    if effects::nonlinear_gain(&file.effects) != 0.0 {
        how.push_str(", with the nonlinear damping's correction");
    }
    escape(&how)
}

/// The compensated-signal figure of test `number` (the whole record and the zoom on the step
/// `window`), or a note saying why there is none; the errors against the reference it shows,
/// for the summary table.
pub(super) fn compensated(
    h: &mut String,
    inputs: &Inputs<'_>,
    number: usize,
    test: &Test<'_>,
    window: std::ops::Range<usize>,
) -> Result<Option<ReferenceError>> {
    let fs = inputs.file.model.fs;
    let n = test.y.len().min(test.u.len());
    let c = match compensated_signal(inputs, test) {
        Ok(c) => c,
        Err(e)
            if inputs.file.inverse.is_none()
                && matches!(e.unadvised(), Error::UnstableInverse { .. }) =>
        {
            let _ = writeln!(
                h,
                "<p class=\"note\">No compensated signal: the model has no stable inverse and the \
                 file no designed compensator (run <code>unlag invert</code>).</p>"
            );
            return Ok(None);
        }
        Err(e) => {
            let _ = writeln!(
                h,
                "<p class=\"note\">No compensated signal: <code>unlag compensate</code> refuses \
                 this test: {}</p>",
                escape(&e.to_string())
            );
            return Ok(None);
        }
    };
    // Advanced by its best alignment on the reference, where the error is measured.
    let lag = c
        .error
        .map_or(c.latency_samples.round().max(0.0) as usize, |e| e.lag);
    let aligned = c.u_hat.get(lag..).unwrap_or_default();
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
    let errors = match c.error {
        Some(e) => format!(
            "Error against the reference {} (raw probe at its best alignment: {}).",
            pct(e.u_hat),
            pct(e.raw)
        ),
        None => "The reference does not move above its noise: no error against it.".into(),
    };
    push_figure(
        h,
        &format!("compensated-{number}"),
        &svg,
        &format!(
            "Reconstructed reference u&#770; by {}, as <code>unlag compensate</code> runs it; \
             advanced by {lag} samples, its best alignment (latency {:.2} samples). {errors}",
            how(inputs, &c),
            c.latency_samples
        ),
    );
    Ok(c.error)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::inverse;
    use crate::effects::Effect;
    use crate::file::{ModelFile, FORMAT_VERSION};
    use crate::fit::model::Model;

    /// `model` observed with noise 1e-3 (seeded) and `offset` added.
    fn probe_signal(model: &Model, u: &[f64], seed: u64, offset: f64) -> Vec<f64> {
        let noise = crate::testing::gaussian(u.len(), seed);
        model
            .simulate(u)
            .iter()
            .zip(noise)
            .map(|(y, n)| y + 1e-3 * n + offset)
            .collect()
    }

    /// A step from 0 to 1 at a quarter of `n` samples.
    fn step(n: usize) -> Vec<f64> {
        (0..n).map(|k| if k < n / 4 { 0.0 } else { 1.0 }).collect()
    }

    /// `model`'s file with the optimal compensator designed from a step test of it, and
    /// `effects`.
    fn file(model: &Model, effects: Vec<Effect>) -> ModelFile {
        let u = step(4000);
        let y = probe_signal(model, &u, 21, 0.0);
        let tests = [Test {
            name: "step",
            u: &u,
            y: &y,
        }];
        let noise = inverse::optimal::estimate_noise(&tests);
        let prior = inverse::optimal::estimate_prior(&tests, &noise);
        let d = inverse::optimal::design(model, &noise, &prior, &Default::default()).unwrap();
        ModelFile {
            format_version: FORMAT_VERSION,
            model: model.clone(),
            fit: None,
            sources: Vec::new(),
            inverse: Some(d),
            effects,
            history: Vec::new(),
            probe: None,
            board: Default::default(),
        }
    }

    fn inputs<'a>(file: &'a ModelFile, tests: &'a [Test<'a>]) -> Inputs<'a> {
        Inputs {
            model_name: "probe.toml",
            file,
            tests,
            evidence: &[],
            candidates: &[],
            change_text: |r| r.to_string(),
        }
    }

    /// What `unlag compensate probe.toml TEST -o ...` computes: the request it builds for a
    /// plain run.
    fn as_the_command_line(file: &ModelFile, u: &[f64], y: &[f64]) -> Compensated {
        pipeline::compensate(&CompensateRequest {
            file,
            model_path: Path::new("probe.toml"),
            probe: y,
            reference: Some(u),
            compensation: Compensation::Designed(Arithmetic::F32),
            temperature_k: None,
        })
        .unwrap()
    }

    /// The report's compensated signal and errors are `unlag compensate`'s: with an offset on
    /// the probe, which the compensator alone would pass on as a step at the record's start.
    #[test]
    fn the_report_compensates_the_test_as_unlag_compensate_does() {
        let (m, _) = crate::testing::second_order(1500.0, 0.3, 10_000.0, 1);
        let f = file(&m, vec![Effect::Offset { value: 0.25 }]);
        let u = step(4000);
        let y = probe_signal(&m, &u, 22, 0.25);
        let tests = [Test {
            name: "offset.csv",
            u: &u,
            y: &y,
        }];
        let inputs = inputs(&f, &tests);
        let expected = as_the_command_line(&f, &u, &y);
        let got = compensated_signal(&inputs, &tests[0]).unwrap();
        assert_eq!(got, expected);
        // The offset matters here: the design run on the probe signal as it is gives another
        // signal, and a worse error.
        let plain = f.inverse.as_ref().unwrap().run::<f32>(&y).unwrap();
        let apart = plain
            .iter()
            .zip(&expected.u_hat)
            .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(apart > 0.1, "{apart}");
        // The figure and the summary table show those errors.
        let e = expected.error.unwrap();
        let mut h = String::new();
        let shown = compensated(&mut h, &inputs, 1, &tests[0], 900..1400).unwrap();
        assert_eq!(shown, Some(e));
        assert!(
            h.contains(&format!(
                "Error against the reference {} (raw probe at its best alignment: {})",
                pct(e.u_hat),
                pct(e.raw)
            )),
            "{}",
            &h[h.find("<figcaption>").unwrap()..]
        );
        assert!(h.contains(&format!("advanced by {} samples", e.lag)));
        assert!(h.contains("less the model's offset and drift"));
    }

    /// A run the model file's compensator is predicted to make worse still shows what the
    /// board computes, and the caption says what the run check predicts and the remedy.
    #[test]
    fn the_caption_says_when_the_board_compensator_is_predicted_worse() {
        let (m, _) = crate::testing::second_order(1500.0, 0.3, 10_000.0, 1);
        let f = file(&m, Vec::new());
        // A slow run (a 3 Hz swing), where the step design's boost above 1.5 kHz only adds
        // noise.
        let u: Vec<f64> = (0..40_000)
            .map(|k| (2.0 * std::f64::consts::PI * 3.0 * k as f64 / 10_000.0).sin())
            .collect();
        let y = probe_signal(&m, &u, 23, 0.0);
        let tests = [Test {
            name: "slow.csv",
            u: &u,
            y: &y,
        }];
        let inputs = inputs(&f, &tests);
        let expected = as_the_command_line(&f, &u, &y);
        assert!(expected.fall_back.is_none(), "{:?}", expected.fall_back);
        let mut h = String::new();
        let shown = compensated(&mut h, &inputs, 1, &tests[0], 0..4000).unwrap();
        assert_eq!(shown, expected.error);
        let caption = &h[h.find("<figcaption>").unwrap()..];
        assert!(
            caption.contains("the model file's compensator in f32")
                && caption.contains("--signal RUN.csv"),
            "{caption}"
        );
        let ratio = expected.predicted.unwrap().ratio();
        assert!(
            ratio >= crate::design::inverse::check::RUN_MARGIN,
            "{ratio}"
        );
        assert!(
            caption.contains(&format!("{ratio:.2}x the raw probe")),
            "{caption}"
        );
    }

    /// A model without a stable inverse and a file without a compensator: a note, no figure.
    #[test]
    fn no_stable_inverse_and_no_compensator_is_a_note() {
        let m = Model {
            fs: 10_000.0,
            delay: 1,
            a: vec![-0.9],
            b: vec![0.02, 0.08],
        };
        let f = crate::testing::model_file(m);
        let u = step(2000);
        let y = f.model.simulate(&u);
        let tests = [Test {
            name: "t.csv",
            u: &u,
            y: &y,
        }];
        let mut h = String::new();
        let shown = compensated(&mut h, &inputs(&f, &tests), 1, &tests[0], 0..400).unwrap();
        assert_eq!(shown, None);
        assert!(
            h.contains("No compensated signal: the model has no stable inverse"),
            "{h}"
        );
        assert!(!h.contains("<figure"));
    }
}
