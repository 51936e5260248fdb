//! The sensor-resonance signature: the reference transducer's own ringing after a step, and
//! the probe's peak beside it where the probe shows one.

use super::{ProbePeak, SensorResonance, Spectrum, SAME_FREQUENCY, SENSOR_RESONANCE_REMEDY};
use crate::evidence::{Peak, TestEvidence};

/// What says the transducers ring: the reference's ringing, the test it rings most in, and
/// the probe's peak near it, if any.
#[derive(Debug, Clone)]
pub(super) struct Signature {
    /// The reference's ringing.
    pub reference: Peak,
    /// The test whose reference rings most.
    pub test: String,
    /// The probe's highest peak near it (residual or model-error spectrum).
    pub probe: Option<ProbePeak>,
}

/// The signature on these tests (the first is the estimation test), if there is one.
///
/// The estimation step's reference must ring: a step is the sharpest edge a transducer meets,
/// and its diaphragm rings in it. A reference that rings only in another test rings with the
/// pressure itself (a valve's chamber), which the probe's model must follow: such ringing
/// hides no sensor resonance, and taken for one it named a drift, validated on a valve whose
/// chamber rings at a few hundred Hz, a sensor resonance.
///
/// Then, as a line or cavity mode never shows in the reference, that ringing is the
/// transducers' where either the probe peaks near it in some test, or, where the probe shows
/// no peak there (the line before its transducer filters its diaphragm out), every other test
/// whose reference rings does so at the same frequency: one transducer, one diaphragm (the
/// reference ringing at one kHz frequency in both tests, the probe showing nothing there).
pub(super) fn signature(evidence: &[TestEvidence]) -> Option<Signature> {
    let step = evidence.first()?.reference_ringing?;
    let near_step = |f: f64| (f / step.frequency_hz - 1.0).abs() < SAME_FREQUENCY;
    let (e, rp) = evidence
        .iter()
        .filter_map(|e| e.reference_ringing.map(|p| (e, p)))
        .filter(|(_, p)| near_step(p.frequency_hz))
        .max_by(|a, b| a.1.above_floor_db.total_cmp(&b.1.above_floor_db))?;
    let near = |f: f64| (f / rp.frequency_hz - 1.0).abs() < SAME_FREQUENCY;
    let probe = evidence
        .iter()
        .flat_map(|e| {
            let residual = e.spectrum.peaks.iter().map(|p| (p, Spectrum::Residual));
            let model = e
                .model_error
                .peaks
                .iter()
                .map(|p| (p, Spectrum::ModelError));
            residual.chain(model)
        })
        .filter(|(p, _)| near(p.frequency_hz))
        .max_by(|a, b| a.0.above_floor_db.total_cmp(&b.0.above_floor_db))
        .map(|(p, source)| ProbePeak {
            above_floor_db: p.above_floor_db,
            frequency_hz: p.frequency_hz,
            source,
        });
    let every_step = evidence
        .iter()
        .filter_map(|e| e.reference_ringing)
        .all(|p| near(p.frequency_hz));
    (probe.is_some() || every_step).then(|| Signature {
        reference: rp,
        test: e.file.clone(),
        probe,
    })
}

impl Signature {
    /// The evidence a candidate carries.
    pub fn evidence(&self) -> SensorResonance {
        SensorResonance {
            probe: self.probe.clone(),
            reference_above_floor_db: self.reference.above_floor_db,
            reference_peak_hz: self.reference.frequency_hz,
            reference_q: self.reference.q,
            reference_test: self.test.clone(),
            remedy: SENSOR_RESONANCE_REMEDY.into(),
        }
    }

    /// The candidate's reading.
    pub fn reading(&self) -> String {
        let r = &self.reference;
        let probe = match &self.probe {
            Some(p) => format!("the probe's {} peaks at {:.0} Hz", p.source, p.frequency_hz),
            None => "the probe shows no peak there (the line before its transducer filters \
                     the diaphragm's ringing out), yet modelling it lowers the held-out error"
                .into(),
        };
        format!(
            "the reference itself rings at {:.0} Hz ({:.0} dB above the floor of its \
             increments, Q about {:.0}) and {probe}: the transducers' own diaphragm resonance, \
             in both channels, not the line's; model the transducers' modes (two more poles \
             and zeros, on the raw signals), or, as the paper does, fit below it with both \
             channels prefiltered at {:.0} Hz (sensor-resonance-prefilter)",
            r.frequency_hz,
            r.above_floor_db,
            r.q,
            0.5 * r.frequency_hz
        )
    }
}
