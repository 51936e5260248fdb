//! The report's frequency response: the Bode plot of the model, the compensator and their
//! product, with the physical prediction for the model file's probe geometry.

use std::fmt::Write as _;

use plotters::prelude::SeriesLabelPosition;
use plotters::style::RGBColor;

use super::plot::{colour, figure, Panel, Series, Style};
use super::{push_figure, Inputs};
use crate::error::Result;
use crate::file::ProbeGeometry;
use crate::fit::analysis;
use crate::poly::Complex;

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

/// The two panels' curves on one frequency grid: magnitude (dB) and phase (degrees, with the
/// pure delays taken out).
struct Curves<'a> {
    freqs: &'a [f64],
    fs: f64,
    mag: Vec<Series>,
    phase: Vec<Series>,
}

impl Curves<'_> {
    /// Adds one response to both panels: its `magnitude` (linear) and its `phase` (degrees),
    /// with `samples` of pure delay taken out of the phase.
    fn add(
        &mut self,
        label: &str,
        (magnitude, phase): (&[f64], &[f64]),
        samples: f64,
        colour: RGBColor,
        style: Style,
    ) {
        let (freqs, fs) = (self.freqs, self.fs);
        let mag = freqs.iter().zip(magnitude).map(|(f, m)| (*f, db(*m)));
        self.mag
            .push(Series::with(label, mag.collect(), colour, style));
        let turned = freqs
            .iter()
            .zip(phase)
            .map(|(f, p)| (*f, p + 360.0 * f * samples / fs));
        self.phase
            .push(Series::with(label, turned.collect(), colour, style));
    }
}

/// A complex response's magnitudes and continuous phase (degrees).
fn polar(values: &[Complex]) -> (Vec<f64>, Vec<f64>) {
    (
        values.iter().map(|v| v.norm()).collect(),
        unwrap_deg(values),
    )
}

pub(super) fn bode(h: &mut String, inputs: &Inputs<'_>) -> Result<()> {
    let file = inputs.file;
    let model = &file.model;
    let fs = model.fs;
    let (lo, hi) = (fs / 2.0 * 1e-3, fs / 2.0 * 0.995);
    let count = 400;
    let freqs: Vec<f64> = (0..count)
        .map(|i| lo * (hi / lo).powf(i as f64 / (count - 1) as f64))
        .collect();
    let hm: Vec<(f64, f64)> = analysis::frequency_response(model, &freqs);
    // Phase with the pure delays removed (they would swamp the dynamics with thousands of
    // degrees): the model's d samples; the design's latency is that of u_hat behind u, the
    // product's, of which the compensator adds latency - d.
    let delay = model.delay as f64;
    let mut curves = Curves {
        freqs: &freqs,
        fs,
        mag: Vec::new(),
        phase: Vec::new(),
    };
    let (m, p): (Vec<f64>, Vec<f64>) = hm.iter().map(|(m, p)| (*m, p.to_degrees())).unzip();
    curves.add("model", (&m, &p), delay, colour::MODEL, Style::Line(2));
    let mut caption = String::from("Model H (the fitted probe, delay included)");
    caption.push_str(&compensator_curves(&mut curves, file));
    caption.push_str(&physics_curves(&mut curves, file, delay));
    let latency = file.inverse.as_ref().map_or(0.0, |c| c.latency_samples);
    let _ = write!(
        caption,
        ". Phase drawn with the pure delays taken out: the model's {} samples (from the \
         physical prediction likewise), the corrected response's latency of {latency:.2} samples, \
         and their difference from the compensator",
        model.delay
    );
    caption.push('.');
    let svg = panels(curves, lo..hi)?;
    push_figure(h, "bode", &svg, &caption);
    Ok(())
}

/// The compensator's curves and the corrected response's (the model times the compensator),
/// and what the caption says of them.
fn compensator_curves(curves: &mut Curves<'_>, file: &crate::file::ModelFile) -> String {
    let Some(d) = &file.inverse else {
        return " (the model file has no designed compensator)".into();
    };
    let model = &file.model;
    let (fs, delay) = (model.fs, model.delay as f64);
    let unit = |f: f64| {
        let w = 2.0 * std::f64::consts::PI * f / fs;
        Complex::new(w.cos(), w.sin())
    };
    let c: Vec<Complex> = curves
        .freqs
        .iter()
        .map(|f| crate::design::inverse::cascade_response(d.gain, &d.sections, unit(*f)))
        .collect();
    let product: Vec<Complex> = curves
        .freqs
        .iter()
        .zip(&c)
        .map(|(f, c)| analysis::response(model, *f) * c)
        .collect();
    let ((cm, cp), (pm, pp)) = (polar(&c), polar(&product));
    let latency = d.latency_samples;
    let line = Style::Line(2);
    curves.add(
        "compensator C",
        (&cm, &cp),
        latency - delay,
        colour::COMPENSATED,
        line,
    );
    curves.add("corrected H C", (&pm, &pp), latency, colour::PRODUCT, line);
    format!(
        ", the compensator C ({}) and the corrected response H C: flat \
         to {:.0} Hz within &plusmn;1 dB and &plusmn;5&deg;, latency {:.2} samples ({:.3} ms)",
        d.band_text(),
        d.corrected_bandwidth_hz,
        d.latency_samples,
        1e3 * d.latency_s
    )
}

/// The physical prediction's curves for the model file's probe geometry, dashed, and what the
/// caption says of them (or why there are none).
fn physics_curves(curves: &mut Curves<'_>, file: &crate::file::ModelFile, delay: f64) -> String {
    match file
        .probe
        .as_ref()
        .map(|g| (g, physics_response(g, curves.freqs)))
    {
        Some((g, Some(p))) => {
            let (m, p) = polar(&p);
            let dashed = Style::Dashed;
            curves.add(
                "physics prediction",
                (&m, &p),
                delay,
                colour::PHYSICS,
                dashed,
            );
            let lines: Vec<String> = g
                .lines
                .iter()
                .map(|[l, d]| format!("{l} m x {} mm", d * 1e3))
                .collect();
            format!(
                "; dashed: the physical prediction (Bergh-Tijdeman) for the file's probe geometry, \
                 line {} into {:.3e} m^3 at {} K",
                lines.join(" + "),
                g.volume_m3,
                g.temperature_k
            )
        }
        Some((_, None)) => {
            "; the file's [probe] geometry is not valid, so no physical prediction is drawn".into()
        }
        None => "; no physical prediction: the model file names no probe geometry (add a [probe] \
                 table with lines = [[length_m, diameter_m]] and volume_m3)"
            .into(),
    }
}

/// The magnitude and phase panels over `x` (Hz, log scale), as one SVG figure.
fn panels(curves: Curves<'_>, x: std::ops::Range<f64>) -> Result<String> {
    let Curves {
        mut mag, mut phase, ..
    } = curves;
    // Magnitude from -60 dB up: the band that matters is near 0 dB.
    // (points beyond the view are left out: a line that ends is honest, one that runs flat
    // along the border is not).
    for s in &mut mag {
        s.points.retain(|p| (-60.0..=60.0).contains(&p.1));
    }
    let mut m = Panel::new("magnitude", "frequency (Hz)", "magnitude (dB)", mag);
    m.log_x = true;
    m.x = x.clone();
    m.legend = SeriesLabelPosition::LowerLeft;
    for s in &mut phase {
        s.points.retain(|p| (-400.0..=400.0).contains(&p.1));
    }
    let mut p = Panel::new(
        "phase (pure delays removed)",
        "frequency (Hz)",
        "phase (degrees)",
        phase,
    );
    p.log_x = true;
    p.x = x;
    p.legend = SeriesLabelPosition::LowerLeft;
    figure("bode", &[m, p], 330, 1)
}

#[cfg(test)]
mod tests {
    use super::*;

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
