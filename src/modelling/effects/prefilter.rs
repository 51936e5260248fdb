//! The `sensor-resonance` prefilter: its corner, its sections, the signals through it, and
//! its place in front of a compensator.

use super::Effect;
use crate::error::Result;

/// Order of the sensor-resonance prefilter (Butterworth): -24 dB at the resonance when the
/// corner is at half of it.
pub const PREFILTER_ORDER: usize = 4;

/// The prefilter corner of `effects` (Hz), when they have a sensor resonance with a known
/// frequency.
#[must_use]
pub fn prefilter_hz(effects: &[Effect]) -> Option<f64> {
    effects.iter().find_map(|e| match e {
        Effect::SensorResonance { prefilter_hz, .. } if *prefilter_hz > 0.0 => Some(*prefilter_hz),
        _ => None,
    })
}

/// The prefilter as `(gain, sections [b0, b1, b2, a1, a2])` at sample rate `fs`: a Butterworth
/// low-pass of order [`PREFILTER_ORDER`] with unit DC gain.
///
/// # Errors
/// [`crate::error::Error::InvalidArgument`] when the corner is not below half the sample
/// rate.
pub fn prefilter_sections(corner_hz: f64, fs: f64) -> Result<(f64, Vec<[f64; 5]>)> {
    let zpk = crate::design::inverse::lowpass(
        crate::design::inverse::LowpassKind::Butterworth,
        PREFILTER_ORDER,
        corner_hz,
        fs,
    )?;
    Ok(crate::design::inverse::to_sections(&zpk))
}

/// `x` through the prefilter of `effects`, started in equilibrium with its resting level
/// ([`crate::fit::model::resting_level`]); `x` unchanged when there is none.
#[must_use]
pub fn prefiltered(effects: &[Effect], fs: f64, x: &[f64]) -> Vec<f64> {
    match prefilter_hz(effects).and_then(|fc| prefilter_sections(fc, fs).ok()) {
        Some((gain, sections)) => {
            let x0 = crate::fit::model::resting_level(x);
            let mut v: Vec<f64> = x.iter().map(|a| a - x0).collect();
            for s in &sections {
                v = crate::fit::model::filter(&s[..3], &s[3..], 0, &v);
            }
            v.iter().map(|a| gain * a + x0).collect()
        }
        None => x.to_vec(),
    }
}

/// The sensor-resonance prefilter's group delay at low frequency (samples), 0 without one.
#[must_use]
pub fn prefilter_delay(effects: &[Effect], fs: f64) -> f64 {
    let Some((gain, sections)) =
        prefilter_hz(effects).and_then(|fc| prefilter_sections(fc, fs).ok())
    else {
        return 0.0;
    };
    // From the phase at a low frequency (the prefilter's phase is linear there).
    let w: f64 = 1e-4;
    let h = crate::design::inverse::cascade_response(
        gain,
        &sections,
        crate::poly::Complex::new(w.cos(), w.sin()),
    );
    -h.im.atan2(h.re) / w
}

/// Puts the sensor-resonance prefilter of `effects` in front of a compensator designed for
/// the model (which was fitted on prefiltered signals): its sections run first on the board,
/// its gain multiplies the cascade's, its group delay at low frequency adds to the latency,
/// and the pole margin is the smaller of the two. Nothing happens without a prefilter.
///
/// # Errors
/// As [`prefilter_sections`].
pub fn with_prefilter(
    design: &mut crate::design::inverse::Design,
    effects: &[Effect],
    fs: f64,
) -> Result<()> {
    let Some(fc) = prefilter_hz(effects) else {
        return Ok(());
    };
    let (gain, sections) = prefilter_sections(fc, fs)?;
    let delay = prefilter_delay(effects, fs);
    let margin = sections
        .iter()
        .map(|s| {
            // |poles| of 1 + a1 z^-1 + a2 z^-2: sqrt(a2) for a complex pair.
            let (a1, a2) = (s[3], s[4]);
            let disc = a1 * a1 - 4.0 * a2;
            let r = if disc < 0.0 {
                a2.abs().sqrt()
            } else {
                0.5 * (a1.abs() + disc.sqrt())
            };
            1.0 - r
        })
        .fold(f64::INFINITY, f64::min);
    design.sections.splice(0..0, sections);
    design.gain *= gain;
    design.latency_samples += delay;
    design.latency_s = design.latency_samples / fs;
    design.pole_margin = design.pole_margin.min(margin);
    design.method = design.method.clone().after_prefilter(&format!(
        "sensor-resonance prefilter (Butterworth order {PREFILTER_ORDER} at {fc:.1} Hz)"
    ));
    Ok(())
}
