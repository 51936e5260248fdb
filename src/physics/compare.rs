//! Physical prediction of a probe ([`predict`]: exact first modes, front delay, lumped
//! approximation) and how a fitted discrete model disagrees with it ([`compare`]: natural
//! frequency ratio, damping ratio, delay difference), for the modelling loop.
//!
//! A fitted model's modes come from its poles: `s = f_s ln z` (the step-invariant map, exact
//! for the poles of a sampled continuous system), `ω_n = |s|`, `ζ = −Re s/|s|`. Negative real
//! poles (ringing at the Nyquist frequency) have no continuous counterpart and are skipped. The
//! fitted mode compared is the one nearest the predicted first mode in log-frequency.

use serde::Serialize;

use super::gas::Gas;
use super::line::Line;
use super::lumped::{lumped, Lumped, POISEUILLE_INERTANCE};
use super::modes::{find_modes, Mode};
use super::PhysicsError;
use crate::error::Result;
use crate::fit::model::Model;

/// Womersley number below which the lumped approximation is trusted (README 1.3).
pub const LUMPED_WOMERSLEY_LIMIT: f64 = 2.0;

/// One mode as it is reported and compared.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModeSummary {
    /// Natural frequency \[Hz\].
    pub natural_frequency_hz: f64,
    /// Damping ratio [-].
    pub damping: f64,
}

impl From<&Mode> for ModeSummary {
    fn from(m: &Mode) -> Self {
        Self {
            natural_frequency_hz: m.natural_frequency_hz,
            damping: m.damping,
        }
    }
}

/// What the physics predicts for a probe.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    /// Exact modes (poles of the Bergh-Tijdeman response), slowest first.
    pub modes: Vec<Mode>,
    /// Real poles found, `−σ` [rad/s], slowest first: slow creeps (lines in series, a leak)
    /// that shape the step response as much as the modes.
    pub real_poles_rad_s: Vec<f64>,
    /// How far along the negative real axis they were searched [rad/s]
    /// ([`super::modes::ModeAnalysis::real_search_limit_rad_s`]).
    pub real_search_limit_rad_s: f64,
    /// Front delay `ΣL/a` \[s\].
    pub delay_s: f64,
    /// The lumped second-order approximation, if the line has one.
    pub lumped: Option<Lumped>,
    /// Static gain `H(0)` [-].
    pub dc_gain: f64,
}

impl Prediction {
    /// `true` when the lumped approximation is within its validity (Womersley below
    /// [`LUMPED_WOMERSLEY_LIMIT`]).
    #[must_use]
    pub fn lumped_valid(&self) -> bool {
        self.lumped
            .is_some_and(|l| l.womersley < LUMPED_WOMERSLEY_LIMIT)
    }
}

/// Most exact modes [`predict`] reports.
pub const MAX_MODES: usize = 20;

/// Checks that `count` exact modes can be reported (`1..=`[`MAX_MODES`]), as [`predict`] does
/// first; for a front end that tells a wrong count before building the probe.
///
/// # Errors
/// [`PhysicsError::ModeCount`].
pub fn check_mode_count(count: usize) -> core::result::Result<(), PhysicsError> {
    if (1..=MAX_MODES).contains(&count) {
        Ok(())
    } else {
        Err(PhysicsError::ModeCount { count })
    }
}

/// Predicts the first `count` exact modes, the front delay and the lumped approximation.
///
/// # Errors
/// [`PhysicsError::ModeCount`] for a `count` outside `1..=`[`MAX_MODES`]; errors of
/// [`find_modes`].
pub fn predict(line: &Line, gas: &Gas, count: usize) -> Result<Prediction> {
    check_mode_count(count)?;
    let analysis = find_modes(line, gas, count)?;
    Ok(Prediction {
        modes: analysis.modes,
        real_poles_rad_s: analysis.real_poles_rad_s,
        real_search_limit_rad_s: analysis.real_search_limit_rad_s,
        delay_s: analysis.delay_s,
        lumped: lumped(line, gas, POISEUILLE_INERTANCE).ok(),
        dc_gain: line.dc_gain(gas),
    })
}

/// The continuous-time modes of a fitted discrete model, slowest first. Complex pole pairs give
/// one mode each; if there is none, the two slowest positive real poles give an equivalent
/// overdamped pair (`ω_n = √(σ₁σ₂)`, `ζ = (σ₁+σ₂)/(2ω_n)`).
///
/// # Errors
/// Errors of [`Model::poles`].
pub fn model_modes(model: &Model) -> Result<Vec<ModeSummary>> {
    let fs = model.fs;
    let poles = model.poles()?;
    let mut modes = Vec::new();
    let mut reals = Vec::new();
    for z in &poles {
        let r = z.norm();
        if !(r > 0.0 && r.is_finite()) {
            continue;
        }
        let is_real = z.im.abs() <= 1e-9 * r;
        if is_real {
            if z.re > 0.0 {
                reals.push(-fs * r.ln()); // σ > 0 for a stable pole
            }
            continue;
        }
        if z.im < 0.0 {
            continue;
        }
        let s_re = fs * r.ln();
        let s_im = fs * z.im.atan2(z.re);
        let wn = s_re.hypot(s_im);
        modes.push(ModeSummary {
            natural_frequency_hz: wn / (2.0 * core::f64::consts::PI),
            damping: -s_re / wn,
        });
    }
    if modes.is_empty() {
        reals.sort_by(f64::total_cmp);
        if let [s1, s2, ..] = reals.as_slice() {
            let (s1, s2) = (*s1, *s2);
            if s1 > 0.0 && s2 > 0.0 {
                let wn = (s1 * s2).sqrt();
                modes.push(ModeSummary {
                    natural_frequency_hz: wn / (2.0 * core::f64::consts::PI),
                    damping: (s1 + s2) / (2.0 * wn),
                });
            }
        }
    }
    modes.sort_by(|a, b| a.natural_frequency_hz.total_cmp(&b.natural_frequency_hz));
    Ok(modes)
}

/// How a fitted model and a physical prediction disagree.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// The fitted mode compared (nearest the predicted first mode).
    pub fitted: ModeSummary,
    /// The predicted (exact) first mode.
    pub predicted: ModeSummary,
    /// `f_n,fitted / f_n,predicted` [-].
    pub natural_frequency_ratio: f64,
    /// `ζ_fitted / ζ_predicted` [-].
    pub damping_ratio: f64,
    /// The fitted model's delay `d/f_s` \[s\].
    pub fitted_delay_s: f64,
    /// The predicted front delay `ΣL/a` \[s\].
    pub predicted_delay_s: f64,
    /// `fitted − predicted` delay \[s\].
    pub delay_difference_s: f64,
    /// The fitted model's DC gain [-] against the predicted one.
    pub dc_gain_ratio: f64,
    /// One line per disagreement beyond the tolerances (5 % in frequency, 15 % in damping,
    /// one sample in delay, 1 % in DC gain), with the physical effects that leave that
    /// signature (README section 3). Empty when model and physics agree.
    pub findings: Vec<String>,
}

/// Compares a fitted model with a prediction.
///
/// # Errors
/// [`PhysicsError::NoPredictedMode`] when the prediction has no mode,
/// [`PhysicsError::NoFittedMode`] when the model has no oscillatory or overdamped mode; errors
/// of [`model_modes`].
pub fn compare(model: &Model, prediction: &Prediction) -> Result<Comparison> {
    let predicted = prediction
        .modes
        .first()
        .map(ModeSummary::from)
        .ok_or(PhysicsError::NoPredictedMode)?;
    let fitted = model_modes(model)?
        .into_iter()
        .min_by(|a, b| {
            let da = (a.natural_frequency_hz / predicted.natural_frequency_hz)
                .ln()
                .abs();
            let db = (b.natural_frequency_hz / predicted.natural_frequency_hz)
                .ln()
                .abs();
            da.total_cmp(&db)
        })
        .ok_or(PhysicsError::NoFittedMode)?;
    let fr = fitted.natural_frequency_hz / predicted.natural_frequency_hz;
    let zr = fitted.damping / predicted.damping;
    let fitted_delay_s = model.delay as f64 / model.fs;
    let dd = fitted_delay_s - prediction.delay_s;
    let dcr = model.dc_gain() / prediction.dc_gain;
    let mut findings = Vec::new();
    if (fr - 1.0).abs() > 0.05 {
        findings.push(format!(
            "natural frequency {:+.1} % against the prediction: {}",
            100.0 * (fr - 1.0),
            if fr < 1.0 {
                "more volume than modelled (diaphragm compliance, fittings, a larger cavity), a longer or narrower path, or a colder gas"
            } else {
                "less volume or a shorter path than modelled, or a warmer gas"
            }
        ));
    }
    if (zr - 1.0).abs() > 0.15 {
        findings.push(format!(
            "damping {:+.1} % against the prediction: {}",
            100.0 * (zr - 1.0),
            if zr > 1.0 {
                "extra losses (minor/orifice losses that grow with step amplitude, a restriction, a lower mean pressure)"
            } else {
                "less loss than the viscothermal model (a higher mean pressure or temperature than assumed, or a lumped model used beyond its Womersley limit)"
            }
        ));
    }
    if dd.abs() > 1.0 / model.fs {
        findings.push(format!(
            "delay {:+.3} ms against the front delay: {}",
            1e3 * dd,
            if dd > 0.0 {
                "channel timing skew, an anti-alias filter on the probe channel, or a longer line"
            } else {
                "the fitted delay is shorter than the front (a low-order model starting early)"
            }
        ));
    }
    if (dcr - 1.0).abs() > 0.01 {
        findings.push(format!(
            "DC gain {:+.2} % against the prediction: {}",
            100.0 * (dcr - 1.0),
            if dcr < 1.0 {
                "a leak from the cavity, or a static calibration error"
            } else {
                "a static calibration error or zero drift"
            }
        ));
    }
    Ok(Comparison {
        fitted,
        predicted,
        natural_frequency_ratio: fr,
        damping_ratio: zr,
        fitted_delay_s,
        predicted_delay_s: prediction.delay_s,
        delay_difference_s: dd,
        dc_gain_ratio: dcr,
        findings,
    })
}

/// A probe to predict, and the fitted model to compare with the prediction, if any.
#[derive(Debug, Clone, Copy)]
pub struct PredictRequest<'a> {
    /// The probe's line.
    pub line: &'a Line,
    /// The gas in it.
    pub gas: &'a Gas,
    /// How many exact modes to report (`1..=`[`MAX_MODES`]).
    pub modes: usize,
    /// A fitted model to compare with the prediction.
    pub model: Option<&'a Model>,
}

/// A probe's prediction and, when a model was given, how it disagrees with it.
#[derive(Debug, Clone, PartialEq)]
pub struct Predicted {
    /// The prediction ([`predict`]).
    pub prediction: Prediction,
    /// The fitted model against it ([`compare`]), when a model was given.
    pub comparison: Option<Comparison>,
}

/// Predicts the probe of `request` and compares the fitted model with it, if one is given.
///
/// # Errors
/// Errors of [`predict`] and [`compare`].
pub fn predict_and_compare(request: &PredictRequest<'_>) -> Result<Predicted> {
    let prediction = predict(request.line, request.gas, request.modes)?;
    let comparison = match request.model {
        Some(m) => Some(compare(m, &prediction)?),
        None => None,
    };
    Ok(Predicted {
        prediction,
        comparison,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sampled second-order system `ω²/(s² + 2ζωs + ω²)` (poles `e^{s T}`) has the same mode.
    #[test]
    fn model_modes_invert_the_pole_map() {
        let fs = 10_000.0;
        let (f, zeta) = (120.0, 0.3);
        let w = 2.0 * core::f64::consts::PI * f;
        let s = num_complex::Complex64::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt());
        let z = (s / fs).exp();
        let a = vec![-2.0 * z.re, z.norm_sqr()];
        let gain = 1.0 + a[0] + a[1];
        let model = Model {
            fs,
            delay: 3,
            a,
            b: vec![gain],
        };
        let m = model_modes(&model).expect("modes");
        assert_eq!(m.len(), 1);
        assert!((m[0].natural_frequency_hz / f - 1.0).abs() < 1e-9);
        assert!((m[0].damping / zeta - 1.0).abs() < 1e-9);
    }

    /// A fitted second-order model of the line's own first mode and delay agrees with the
    /// prediction; without a model there is no comparison; a mode count outside
    /// `1..=MAX_MODES` is refused before any search.
    #[test]
    fn a_probe_is_predicted_compared_and_its_mode_count_bounded() {
        let gas = Gas::air(293.15, 101_325.0);
        let line = Line::new().tube(0.6, 1.1e-3).volume(20e-9);
        let request = PredictRequest {
            line: &line,
            gas: &gas,
            modes: 2,
            model: None,
        };
        let alone = predict_and_compare(&request).unwrap();
        assert_eq!(alone.prediction.modes.len(), 2);
        assert!(alone.comparison.is_none());
        let first = ModeSummary::from(&alone.prediction.modes[0]);
        let fs = 50_000.0;
        let w = 2.0 * core::f64::consts::PI * first.natural_frequency_hz;
        let zeta = first.damping.min(0.9);
        let s = num_complex::Complex64::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt());
        let z = (s / fs).exp();
        let a = vec![-2.0 * z.re, z.norm_sqr()];
        let model = Model {
            fs,
            delay: (alone.prediction.delay_s * fs).round() as usize,
            b: vec![1.0 + a[0] + a[1]],
            a,
        };
        let both = predict_and_compare(&PredictRequest {
            model: Some(&model),
            ..request
        })
        .unwrap();
        assert_eq!(both.prediction, alone.prediction);
        let c = both.comparison.unwrap();
        assert!((c.natural_frequency_ratio - 1.0).abs() < 1e-6, "{c:?}");
        assert!(check_mode_count(1).is_ok() && check_mode_count(MAX_MODES).is_ok());
        for count in [0, MAX_MODES + 1] {
            assert!(check_mode_count(count).is_err());
            let e = predict_and_compare(&PredictRequest {
                modes: count,
                ..request
            })
            .unwrap_err();
            assert!(
                matches!(e.stage(), Some(PhysicsError::ModeCount { count: c }) if *c == count),
                "{e}"
            );
        }
    }
}
