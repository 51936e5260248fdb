//! The report's pole-zero map of the model and its table of modes.

use std::fmt::Write as _;

use plotters::prelude::SeriesLabelPosition;

use super::plot::{self, colour, Panel, Series, Style};
use super::{escape, push_figure, Inputs};
use crate::error::Result;
use crate::fit::analysis::{self, Analysis, ModeKind};
use crate::fit::model::{quoted, two_digits, ResonanceUncertainty, Uncertainty};

/// Between a value and its deviation.
const PLUS_MINUS: &str = " &plusmn; ";

pub(super) fn poles(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
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
    pole_zero_map(h, &a)?;
    let stated = inputs
        .file
        .fit
        .as_ref()
        .and_then(|f| f.uncertainty.as_ref());
    mode_table(h, &a, stated);
    Ok(())
}

/// The pole-zero map in the z plane, with the stability and minimum-phase margins.
fn pole_zero_map(h: &mut String, a: &Analysis) -> Result<()> {
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
    Ok(())
}

/// The table of the model's modes, each resonance with its stated deviations where the fit
/// states them.
fn mode_table(h: &mut String, a: &Analysis, stated: Option<&Uncertainty>) {
    // A resonance's stated deviations: the fit's entry at the same natural frequency.
    let deviation = |f_hz: f64| {
        stated?
            .resonances
            .iter()
            .find(|r| (r.natural_frequency_hz - f_hz).abs() <= 1e-6 * f_hz.abs().max(1.0))
    };
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
        let (f, z, tau) = mode_cells(&m.kind, deviation);
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"num\">{f}</td><td class=\"num\">{z}</td>\
             <td class=\"num\">{tau}</td><td class=\"num\">{:.4}{:+.4}j (|z| {:.4})</td></tr>",
            what, m.pole.re, m.pole.im, m.pole.magnitude
        );
    }
    h.push_str("</table>\n");
    if let Some(u) = stated {
        let _ = writeln!(
            h,
            "<p class=\"note\">&plusmn; one standard deviation as the fit states it, from {}; \
             DC gain &plusmn; {}. It covers the noise, not a wrong model structure.</p>",
            escape(&u.noise_text()),
            two_digits(u.dc_gain_std)
        );
    }
}

/// A mode's natural frequency, damping and time constant as the table prints them.
fn mode_cells<'a>(
    kind: &ModeKind,
    deviation: impl Fn(f64) -> Option<&'a ResonanceUncertainty>,
) -> (String, String, String) {
    match kind {
        ModeKind::Resonance {
            natural_frequency_hz,
            damping,
            ..
        } => {
            let (f, z) = match deviation(*natural_frequency_hz) {
                Some(d) => (
                    quoted(
                        *natural_frequency_hz,
                        d.natural_frequency_std_hz,
                        PLUS_MINUS,
                    ),
                    quoted(*damping, d.damping_std, PLUS_MINUS),
                ),
                None => (
                    format!("{natural_frequency_hz:.1}"),
                    format!("{damping:.3}"),
                ),
            };
            (format!("{f} Hz"), z, "&ndash;".to_string())
        }
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
    }
}
