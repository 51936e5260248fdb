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

/// [`prefiltered`] one sample at a time, for a run streamed from its file: the same numbers.
/// The resting level is taken from the signal's first samples (`head`, at least the first 64
/// when the signal has them), as [`prefiltered`] takes it.
#[derive(Debug, Clone)]
pub struct PrefilterStream {
    /// `(gain, sections, resting level)`; `None`: no prefilter, samples pass unchanged.
    filter: Option<(f64, Vec<[f64; 5]>, f64)>,
    /// Per section: its last two inputs and outputs.
    state: Vec<[f64; 4]>,
    k: usize,
}

impl PrefilterStream {
    /// The prefilter of `effects` at `fs` for a signal starting with `head`.
    #[must_use]
    pub fn new(effects: &[Effect], fs: f64, head: &[f64]) -> Self {
        let filter = prefilter_hz(effects)
            .and_then(|fc| prefilter_sections(fc, fs).ok())
            .map(|(gain, sections)| (gain, sections, crate::fit::model::resting_level(head)));
        let state = vec![[0.0; 4]; filter.as_ref().map_or(0, |f| f.1.len())];
        Self {
            filter,
            state,
            k: 0,
        }
    }

    /// The next sample through the prefilter.
    pub fn step(&mut self, x: f64) -> f64 {
        let Some((gain, sections, x0)) = &self.filter else {
            return x;
        };
        let k = self.k;
        self.k += 1;
        let mut v = x - x0;
        for (s, st) in sections.iter().zip(&mut self.state) {
            let [x1, x2, y1, y2] = *st;
            // As `filter` sums them: every term from the third sample on, the ones that exist
            // before it.
            let y = if k >= 3 {
                let fir = 0.0 + s[0] * v + s[1] * x1 + s[2] * x2;
                let tail = 0.0 + s[4] * y2;
                (fir - tail) - s[3] * y1
            } else {
                let mut acc = 0.0;
                acc += s[0] * v;
                if k >= 1 {
                    acc += s[1] * x1;
                }
                if k >= 2 {
                    acc += s[2] * x2;
                }
                if k >= 1 {
                    acc -= s[3] * y1;
                }
                if k >= 2 {
                    acc -= s[4] * y2;
                }
                acc
            };
            *st = [v, x1, y, y1];
            v = y;
        }
        gain * v + x0
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_streamed_prefilter_gives_the_same_numbers() {
        let effects = [Effect::parse("sensor-resonance-prefilter=2000").unwrap()];
        assert!(prefilter_hz(&effects).is_some());
        let x: Vec<f64> = crate::testing::gaussian(500, 4)
            .iter()
            .enumerate()
            .map(|(k, n)| if k > 100 { 1.0 } else { 0.0 } + 1e-3 * n)
            .collect();
        let batch = prefiltered(&effects, 10_000.0, &x);
        let mut s = PrefilterStream::new(&effects, 10_000.0, &x[..64]);
        let streamed: Vec<f64> = x.iter().map(|&v| s.step(v)).collect();
        assert_eq!(streamed, batch);
        assert_ne!(batch, x);
    }
}
