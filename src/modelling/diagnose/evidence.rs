//! The numbers behind a candidate: one [`Evidence`] variant per kind of candidate, each with
//! named, typed fields. Serialised as a plain JSON object (no tag), its fields in alphabetical
//! order, as `unlag diagnose --json` has always written them.

use serde::ser::SerializeStruct;
use serde::{Serialize, Serializer};

use super::TemperatureRow;
use crate::effects::{rms, EffectKind, TemperatureDamping};

/// What a coloured-noise trial fits, and the error it then reports
/// ([`Evidence::ColouredNoise`]'s `fit`).
pub const COLOURED_NOISE_FIT: &str =
    "output error and an AR noise model; the error is the one-step-ahead prediction error";

/// What the transducers' modes do, and the other way ([`SensorResonance::remedy`]).
pub const SENSOR_RESONANCE_REMEDY: &str = "the transducers' modes in the model: two more poles \
     and zeros, fitted on the raw signals (sensor-resonance-prefilter: the paper's prefilter \
     instead)";

/// The numbers behind one candidate, by its kind.
///
/// ```
/// use unlag::modelling::diagnose::Evidence;
///
/// let e = Evidence::Leak {
///     dc_gain: 0.98,
///     late_residual_over_step: -0.01,
///     creep_in_standard_errors: -7.5,
///     creep_slope_kept: Some(0.04),
/// };
/// assert_eq!(
///     serde_json::to_string(&e).unwrap(),
///     r#"{"dc_gain":0.98,"late_residual_over_step":-0.01,"creep_in_standard_errors":-7.5,"creep_slope_kept":0.04}"#
/// );
/// ```
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
#[non_exhaustive]
pub enum Evidence {
    /// `mode`: where the spectra point at the unmodelled resonance.
    Mode(ModeEvidence),
    /// `offset`: a residual level before the step.
    Offset {
        /// The offset the trial fitted (probe units).
        offset: f64,
        /// The largest level before the step over the tests, in standard errors of its mean.
        pre_step_mean_in_standard_errors: f64,
    },
    /// `drift`: a ramp through the residual.
    Drift {
        /// Slope of the residual before the step (probe units per second), the tests'
        /// weighted by their standard errors.
        pre_step_slope_per_s: f64,
        /// Its standard error (infinite when no test has a segment before its step).
        pre_step_slope_se_per_s: f64,
        /// The largest ramp over the record, in standard errors of the mean.
        ramp_in_standard_errors: f64,
        /// The drift rate the trial fitted (probe units per second).
        rate_per_s: f64,
        /// How much of the line through the residual its level keeps at the end of the record,
        /// on the test of the largest ramp ([`super::ramp_kept`]): about 1 for a drift, which
        /// runs on; a hump that comes back is not offered as one.
        ramp_kept_at_end: Option<f64>,
    },
    /// `leak`: a slow creep after the step.
    Leak {
        /// The current model's DC gain.
        dc_gain: f64,
        /// The residual's level at the end of the record less its level before the step,
        /// over the step (the largest over the tests).
        late_residual_over_step: f64,
        /// The same difference in standard errors of the two levels' means under the noise
        /// both channels leave (the largest in size over the tests): a creep the noise could
        /// not make when it is large.
        creep_in_standard_errors: f64,
        /// How much of the slope of a line through the estimation test's residual its slope
        /// over the last 30 % of the record keeps ([`super::slope_kept`]): near 0 for a creep
        /// that settles, as a leak's does; about 1 or more for a drift, which runs on. `null`
        /// where the line is flat.
        creep_slope_kept: Option<f64>,
    },
    /// `sensor-resonance`: the reference rings where the probe's residual peaks.
    SensorResonance(SensorResonance),
    /// `temperature` or `temperature-viscous`: every natural frequency moved by one factor.
    Temperature(TemperatureShift),
    /// `delay`: the loss is lower at another delay.
    Delay {
        /// The delay a refit that searches it finds (samples).
        best_delay: usize,
        /// The current model's delay (samples).
        model_delay: usize,
        /// Lag of the peak of the residual's correlation with the input (samples).
        residual_input_xcorr_peak_lag: usize,
    },
    /// `nonlinear-damping`: across tests, damping that rises with the step.
    NonlinearDamping(NonlinearDamping),
    /// `coloured-noise`: a residual correlated in time with no cause in the input.
    ColouredNoise {
        /// What the trial fits ([`COLOURED_NOISE_FIT`]).
        fit: String,
        /// The first test's residual correlation at lag 1.
        lag1_autocorrelation: f64,
        /// The smallest Ljung-Box p-value over the tests.
        ljung_box_p: f64,
        /// How many times a one-step predictor lowers the probe's own noise before a step
        /// ([`crate::fit::noise::probe_predictability`]); `None` where no test has a quiet
        /// segment.
        #[serde(skip_serializing_if = "Option::is_none")]
        probe_noise_predictability: Option<f64>,
    },
    /// `unexplained`: above the noise floor, and no effect's trial lowers it.
    Unexplained {
        /// The mean noise floor over the tests (normalised RMS).
        noise_floor: f64,
        /// The held-out error (normalised RMS).
        nrmse: f64,
        /// Whether every test's residual is white (as the noise leaves it).
        white: bool,
        /// The largest error over noise floor over the tests.
        worst_over_floor: f64,
    },
    /// `none`: the residual is what the noise leaves.
    Nothing {
        /// The mean noise floor over the tests (normalised RMS).
        noise_floor: f64,
        /// The held-out error (normalised RMS).
        nrmse: f64,
        /// Whether every test's residual is white (as the noise leaves it).
        white: bool,
    },
}

/// Which spectrum of the probe's residual a peak was read in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spectrum {
    /// The model-error spectrum `|FFT(dy)| / |FFT(dy_model)|`: `model-error spectrum`.
    ModelError,
    /// The residual's spectrum after the step: `residual spectrum`.
    Residual,
}

impl Spectrum {
    /// Its text: `model-error spectrum` or `residual spectrum`.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::ModelError => "model-error spectrum",
            Self::Residual => "residual spectrum",
        }
    }
}

impl core::fmt::Display for Spectrum {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.pad(self.as_str())
    }
}

impl Serialize for Spectrum {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// What points at an unmodelled mode; each serialises with its `source` in words.
#[derive(Debug, Clone, PartialEq)]
pub enum ModeEvidence {
    /// A peak of a spectrum (`source`: the spectrum's name).
    Peak {
        /// The spectrum it is in.
        spectrum: Spectrum,
        /// Its frequency (Hz).
        frequency_hz: f64,
        /// Its height above the floor (dB).
        above_floor_db: f64,
        /// Its quality factor.
        q: f64,
        /// The test it is on.
        test: String,
    },
    /// The model-error spectrum rising at the top of the band the noise leaves (`source`:
    /// `model-error spectrum, top of the band`).
    BandEdge {
        /// The rise at the top of the band (dB).
        rise_db: f64,
        /// The top of the band (Hz).
        up_to_hz: f64,
        /// The test it is on.
        test: String,
    },
    /// No peak: only the trial says it (`source`: `trial only`).
    TrialOnly,
}

impl Serialize for ModeEvidence {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Self::Peak {
                spectrum,
                frequency_hz,
                above_floor_db,
                q,
                test,
            } => {
                let mut m = s.serialize_struct("ModeEvidence", 5)?;
                m.serialize_field("above_floor_db", above_floor_db)?;
                m.serialize_field("frequency_hz", frequency_hz)?;
                m.serialize_field("q", q)?;
                m.serialize_field("source", spectrum)?;
                m.serialize_field("test", test)?;
                m.end()
            }
            Self::BandEdge {
                rise_db,
                up_to_hz,
                test,
            } => {
                let mut m = s.serialize_struct("ModeEvidence", 4)?;
                m.serialize_field("rise_db", rise_db)?;
                m.serialize_field("source", "model-error spectrum, top of the band")?;
                m.serialize_field("test", test)?;
                m.serialize_field("up_to_hz", up_to_hz)?;
                m.end()
            }
            Self::TrialOnly => {
                let mut m = s.serialize_struct("ModeEvidence", 1)?;
                m.serialize_field("source", "trial only")?;
                m.end()
            }
        }
    }
}

/// The evidence of a sensor resonance: the reference's own ringing and the probe's peak
/// beside it, where the probe shows one.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensorResonance {
    /// The probe's peak near the reference's ringing; `None` where the probe shows none (the
    /// line before its transducer filters the diaphragm's ringing out) and the reference's
    /// ringing in every step test is the evidence.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub probe: Option<ProbePeak>,
    /// The reference's ringing's height above the floor of its increments (dB).
    pub reference_above_floor_db: f64,
    /// The reference's ringing frequency (Hz).
    pub reference_peak_hz: f64,
    /// The reference's ringing's quality factor.
    pub reference_q: f64,
    /// The test whose reference rings most.
    pub reference_test: String,
    /// What the remedy does ([`SENSOR_RESONANCE_REMEDY`]).
    pub remedy: String,
}

/// The probe's peak beside the reference's ringing ([`SensorResonance::probe`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbePeak {
    /// The probe's peak's height above its floor (dB).
    #[serde(rename = "probe_above_floor_db")]
    pub above_floor_db: f64,
    /// The probe's peak's frequency (Hz).
    #[serde(rename = "probe_peak_hz")]
    pub frequency_hz: f64,
    /// The spectrum the probe's peak is in.
    #[serde(rename = "probe_source")]
    pub source: Spectrum,
}

/// The evidence of a temperature change: the natural frequencies of the tests fitted alone
/// against the model's, and the scale a trial estimates for each test.
#[derive(Debug, Clone, Serialize)]
pub struct TemperatureShift {
    /// The kind offered (`temperature` or `temperature-viscous`: the damping law is part of it).
    pub add: EffectKind,
    /// The strongest test's common frequency ratio.
    pub common_ratio: f64,
    /// The damping law the trial used.
    pub damping: TemperatureDamping,
    /// The strongest test's damping ratio (test over model).
    pub damping_ratio: f64,
    /// Per test, the scale the trial's model estimates.
    pub estimated_scale: Vec<ScaleEstimate>,
    /// Per test, its resonances against the model's (empty when no test fitted alone showed
    /// the shift: `signature` false).
    pub per_test: Vec<TemperatureRow>,
    /// The model's reference temperature (K).
    pub reference_k: f64,
    /// `T / T_ref` that `common_ratio` implies under the law offered: its square for the speed
    /// of sound's (`temperature`, `temperature-viscous`), through the viscosity for
    /// `temperature-diffusive`.
    pub temperature_ratio: f64,
    /// Whether the tests fitted alone showed every natural frequency moved by one factor;
    /// `false`: the trial alone named it, `common_ratio` is then the scale it fitted to
    /// `test` and `damping_ratio` the law's factor at that scale.
    pub signature: bool,
    /// The strongest test.
    pub test: String,
    /// Each test's error after the trial, the estimation test's first: set beside a loss
    /// fitted on the tests together ([`JointLoss::nrmse`]), what each leaves on every test.
    pub trial_nrmse: Vec<f64>,
    /// Each test's error, the estimation test's first, with one model fitted to all the
    /// tests and each test's own time scale (`fit --also`, as a loss is fitted on them):
    /// reckoned where a nonlinear damping fitted on the tests together is offered beside it,
    /// to set the two on one footing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint_nrmse: Option<Vec<f64>>,
    /// The damping factor the viscous law gives for `common_ratio`.
    pub viscous_damping_ratio: f64,
}

/// The time-scale factor a temperature trial estimates for one test.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScaleEstimate {
    /// The damping factor at that scale.
    pub damping_factor: f64,
    /// The scale `k = sqrt(T / T_ref)`.
    pub scale: f64,
    /// The gas temperature it means (K).
    pub temperature_k: f64,
    /// The test.
    pub test: String,
}

/// The evidence of amplitude-dependent damping, across tests of different step sizes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NonlinearDamping {
    /// Whether the tests showed the amplitude signature (the damping rising with the step);
    /// `false`: the trial alone named it, and the fields of the signature are what the tests
    /// gave (empty or NaN where they gave nothing).
    pub amplitude_signature: bool,
    /// The tests' step amplitudes, smallest first.
    pub amplitudes: Vec<f64>,
    /// The damping of each test fitted alone.
    pub damping: Vec<f64>,
    /// Relative rise of the damping from the smallest step to the largest.
    pub damping_rise: f64,
    /// Slope of the damping against the step.
    pub damping_slope_per_unit_step: f64,
    /// The quadratic loss the trial fitted (s^2 per probe unit).
    pub gain_s2_per_unit: f64,
    /// Exponent `p` of the own-fit residual growing as `|step|^p`.
    pub residual_exponent: f64,
    /// Each test's own-fit residual over its step.
    pub residual_per_step: Vec<f64>,
    /// One model fitted to all the tests together, with the loss and without: what tests of
    /// different sizes show where one step cannot (`None` when not tried).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<JointLoss>,
}

impl NonlinearDamping {
    /// The evidence from the tests' amplitude signature (`sig`, what the tests gave of it;
    /// `seen`: whether it is the signature of amplitude-dependent losses), the loss a trial
    /// fitted, and the fit of the tests together when made.
    #[must_use]
    pub fn of(
        sig: Option<&super::AmplitudeSignature>,
        seen: bool,
        gain: f64,
        joint: Option<JointLoss>,
    ) -> Self {
        Self {
            amplitude_signature: seen,
            amplitudes: sig.map(|s| s.amplitudes.clone()).unwrap_or_default(),
            damping: sig.map(|s| s.damping.clone()).unwrap_or_default(),
            damping_rise: sig.map_or(f64::NAN, |s| s.damping_rise),
            damping_slope_per_unit_step: sig.map_or(f64::NAN, |s| s.damping_slope),
            gain_s2_per_unit: gain,
            residual_exponent: sig.map_or(f64::NAN, |s| s.residual_exponent),
            residual_per_step: sig.map(|s| s.residual_per_step.clone()).unwrap_or_default(),
            joint,
        }
    }
}

/// One model fitted to all the tests at once, with a quadratic loss and without
/// ([`crate::effects::joint_loss`]): one step cannot tell the loss from a linear
/// damping, but no single linear model explains steps of different sizes when the probe has
/// it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointLoss {
    /// The tests, in the order of the errors.
    pub tests: Vec<String>,
    /// Each test's error left by the best single linear model.
    pub linear_nrmse: Vec<f64>,
    /// Each test's error left by the model with the loss.
    pub nrmse: Vec<f64>,
    /// The loss (s^2 per probe unit).
    pub gain_s2_per_unit: f64,
    /// The fall of the tests' RMS error the loss brings (linear over with the loss).
    pub fall: f64,
}

impl JointLoss {
    /// The root mean square of the tests' errors with the loss: what the joint fit minimises.
    #[must_use]
    pub fn rms(&self) -> f64 {
        rms(&self.nrmse)
    }

    /// Whether the loss is offered: it lowers the tests' RMS error by
    /// [`MIN_IMPROVEMENT`](super::MIN_IMPROVEMENT) against the best single linear model, and
    /// leaves less over them than the current model does (`now`, its RMS error over the same
    /// tests). A joint linear fit that broke down lends any loss a fall: on a drifting
    /// capillary it can leave a traverse far worse than the plain model does, and a loss
    /// well below it still leave both tests worse than the plain model.
    #[must_use]
    pub fn offered_against(&self, now: f64) -> bool {
        self.fall >= super::MIN_IMPROVEMENT && self.rms() < now
    }
}

impl TemperatureShift {
    /// The least root mean square of the tests' errors a temperature model leaves, the trial's
    /// or one model fitted to all the tests with each test's own time scale, on the footing
    /// of [`JointLoss::rms`]; `None` until the latter was reckoned.
    #[must_use]
    pub fn joint_rms(&self) -> Option<f64> {
        let joint = rms(self.joint_nrmse.as_deref()?);
        Some(if self.trial_nrmse.is_empty() {
            joint
        } else {
            joint.min(rms(&self.trial_nrmse))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn joint(linear: [f64; 2], nrmse: [f64; 2]) -> JointLoss {
        JointLoss {
            tests: vec!["est.csv".into(), "val.csv".into()],
            linear_nrmse: linear.to_vec(),
            nrmse: nrmse.to_vec(),
            gain_s2_per_unit: 1e-8,
            fall: rms(&linear) / rms(&nrmse),
        }
    }

    #[test]
    fn a_joint_loss_is_offered_only_where_it_beats_the_linear_fit_and_the_current_model() {
        // A sound loss: 1.63x below the linear fit, and far below the current
        // model, which leaves 0.317 % and 2.544 %.
        let healthy = joint([0.00882, 0.00596], [0.00454, 0.00468]);
        assert!(healthy.offered_against(rms(&[0.00317, 0.02544])));
        // A loss 5.8x below a linear fit that broke down, but worse than the
        // current model on both tests (0.352 % and 10.441 %).
        let broken = joint([0.30836, 0.88875], [0.03456, 0.15737]);
        assert!(broken.fall > 5.0);
        assert!(!broken.offered_against(rms(&[0.00352, 0.10441])));
        // Below the current model, but not 1.15x below the linear fit.
        let small = joint([0.0050, 0.0060], [0.0048, 0.0057]);
        assert!(!small.offered_against(rms(&[0.0050, 0.0200])));
    }

    fn value(e: &Evidence) -> serde_json::Value {
        serde_json::to_value(e).unwrap()
    }

    #[test]
    fn each_kind_serialises_as_the_object_it_always_was() {
        let peak = Evidence::Mode(ModeEvidence::Peak {
            spectrum: Spectrum::ModelError,
            frequency_hz: 303.9,
            above_floor_db: 2.5,
            q: 12.0,
            test: "a.csv".into(),
        });
        assert_eq!(
            serde_json::to_string(&peak).unwrap(),
            r#"{"above_floor_db":2.5,"frequency_hz":303.9,"q":12.0,"source":"model-error spectrum","test":"a.csv"}"#
        );
        let edge = Evidence::Mode(ModeEvidence::BandEdge {
            rise_db: 3.0,
            up_to_hz: 400.0,
            test: "b.csv".into(),
        });
        assert_eq!(
            value(&edge),
            json!({"rise_db": 3.0, "up_to_hz": 400.0, "test": "b.csv",
                   "source": "model-error spectrum, top of the band"})
        );
        assert_eq!(
            serde_json::to_string(&Evidence::Mode(ModeEvidence::TrialOnly)).unwrap(),
            r#"{"source":"trial only"}"#
        );
        assert_eq!(
            value(&Evidence::Delay {
                best_delay: 27,
                model_delay: 30,
                residual_input_xcorr_peak_lag: 2
            }),
            json!({"model_delay": 30, "best_delay": 27, "residual_input_xcorr_peak_lag": 2})
        );
        assert_eq!(
            serde_json::to_string(&Evidence::ColouredNoise {
                fit: COLOURED_NOISE_FIT.into(),
                lag1_autocorrelation: 0.5,
                ljung_box_p: 1e-9,
                probe_noise_predictability: None,
            })
            .unwrap(),
            format!(
                r#"{{"fit":"{COLOURED_NOISE_FIT}","lag1_autocorrelation":0.5,"ljung_box_p":1e-9}}"#
            )
        );
        assert_eq!(
            serde_json::to_string(&Evidence::Nothing {
                noise_floor: 0.001,
                nrmse: 0.002,
                white: true
            })
            .unwrap(),
            r#"{"noise_floor":0.001,"nrmse":0.002,"white":true}"#
        );
        let sensor = Evidence::SensorResonance(SensorResonance {
            probe: Some(ProbePeak {
                above_floor_db: 20.0,
                frequency_hz: 2990.0,
                source: Spectrum::Residual,
            }),
            reference_above_floor_db: 30.0,
            reference_peak_hz: 2998.0,
            reference_q: 25.0,
            reference_test: "s1.csv".into(),
            remedy: SENSOR_RESONANCE_REMEDY.into(),
        });
        assert_eq!(
            value(&sensor),
            json!({"reference_peak_hz": 2998.0, "reference_above_floor_db": 30.0,
                   "reference_q": 25.0, "reference_test": "s1.csv",
                   "probe_peak_hz": 2990.0, "probe_above_floor_db": 20.0,
                   "probe_source": "residual spectrum",
                   "remedy": "the transducers' modes in the model: two more poles and zeros, fitted on the raw signals (sensor-resonance-prefilter: the paper's prefilter instead)"})
        );
        let t = Evidence::Temperature(TemperatureShift {
            add: EffectKind::TemperatureViscous,
            common_ratio: 1.05,
            damping: TemperatureDamping::Viscous,
            damping_ratio: 1.1,
            estimated_scale: vec![ScaleEstimate {
                damping_factor: 1.0,
                scale: 1.0,
                temperature_k: 293.15,
                test: "t1.csv".into(),
            }],
            per_test: vec![TemperatureRow {
                file: "t2.csv".into(),
                modes: vec![(105.0, 100.0, 1.05)],
                ratio: 1.05,
                spread: 0.0,
                damping_ratio: 1.1,
            }],
            reference_k: 293.15,
            temperature_ratio: 1.1025,
            signature: true,
            test: "t2.csv".into(),
            trial_nrmse: vec![0.002, 0.003],
            joint_nrmse: None,
            viscous_damping_ratio: 1.2,
        });
        assert_eq!(
            value(&t),
            json!({"per_test": [{"file": "t2.csv", "modes": [[105.0, 100.0, 1.05]],
                                 "ratio": 1.05, "spread": 0.0, "damping_ratio": 1.1}],
                   "common_ratio": 1.05, "test": "t2.csv", "temperature_ratio": 1.1025,
                   "signature": true, "trial_nrmse": [0.002, 0.003],
                   "damping_ratio": 1.1, "viscous_damping_ratio": 1.2,
                   "damping": "viscous", "add": "temperature-viscous",
                   "estimated_scale": [{"test": "t1.csv", "scale": 1.0, "temperature_k": 293.15,
                                        "damping_factor": 1.0}],
                   "reference_k": 293.15})
        );
        // A number that is not finite is null, as `json!` wrote it.
        assert_eq!(
            value(&Evidence::Offset {
                offset: f64::NAN,
                pre_step_mean_in_standard_errors: 6.0
            }),
            json!({"offset": null, "pre_step_mean_in_standard_errors": 6.0})
        );
    }
}
