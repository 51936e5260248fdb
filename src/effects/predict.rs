//! What a model with effects predicts of a test, what the prediction is compared with, and
//! the error the model is judged by (one step ahead with a `coloured-noise` noise model).

use super::{
    estimate_additive, estimate_scale_with, nonlinear_gain, prefilter_hz, prefiltered, scaled_with,
    simulate_nonlinear, temperature_law, Additive, Effect, FitChanges,
};
#[cfg(doc)]
use super::{estimate_scale, TemperatureDamping};
use crate::fit::model::Model;

/// The model's full prediction for a test: the dynamics (with their quadratic damping, if
/// any) started in equilibrium with `u[0]`, plus the additive effects estimated on this test. With a `sensor-resonance` it predicts
/// the prefiltered probe signal ([`observed`]); with a `temperature` the model is scaled by
/// the factor estimated on this test ([`estimate_scale`]).
#[must_use]
pub fn predict(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    predict_with(model, effects, u, y, None)
}

/// As [`predict`], with the time-scale factor `k = sqrt(T / reference_k)` given instead of
/// estimated (`None`: estimated when the effects have a `temperature`); the damping follows
/// the `temperature`'s law ([`TemperatureDamping`]).
#[must_use]
pub fn predict_with(
    model: &Model,
    effects: &[Effect],
    u: &[f64],
    y: &[f64],
    scale: Option<f64>,
) -> Vec<f64> {
    let fs = model.fs;
    let (u, y) = (prefiltered(effects, fs, u), prefiltered(effects, fs, y));
    let law = temperature_law(effects);
    let k = match (scale, law) {
        (Some(k), _) => k,
        (None, Some((reference, damping))) => {
            estimate_scale_with(model, damping, reference, &u, &y)
        }
        (None, None) => 1.0,
    };
    let rescaled = if (k - 1.0).abs() > 1e-12 {
        let factor = law.map_or(1.0, |(reference, damping)| damping.factor(k, reference));
        scaled_with(model, k, factor).ok()
    } else {
        None
    };
    let model = rescaled.as_ref().unwrap_or(model);
    let gain = nonlinear_gain(effects);
    let mut ym = if gain == 0.0 {
        model.simulate(&u)
    } else {
        simulate_nonlinear(model, gain, &u)
    };
    let changes = FitChanges::of(effects);
    // A record that does not start at rest (a traverse) starts from the state that best
    // explains it ([`Model::simulate_matched`]), fitted together with its offset or drift,
    // which are then its whole record's.
    let onset = crate::fit::step::quiet_until(&u);
    if onset == 0 {
        let level = |_: usize| 1.0;
        let ramp = |k: usize| k as f64 / fs;
        let extra: &[&dyn Fn(usize) -> f64] = match (changes.drift, changes.offset) {
            (true, _) => &[&level, &ramp],
            (false, true) => &[&level],
            (false, false) => &[],
        };
        if let Some(c) = model.fit_free_response(&mut ym, &y, extra) {
            let additive = Additive {
                offset: c.first().copied().unwrap_or(0.0),
                rate_per_s: c.get(1).copied().unwrap_or(0.0),
            };
            additive.add_to(&mut ym, fs);
            return ym;
        }
    }
    if changes.offset || changes.drift {
        let r: Vec<f64> = y.iter().zip(&ym).map(|(a, b)| a - b).collect();
        estimate_additive(&changes, &r, onset, fs).add_to(&mut ym, fs);
    }
    ym
}

/// What a prediction of [`predict`] is compared with: the probe signal, prefiltered when the
/// effects have a `sensor-resonance`.
#[must_use]
pub fn observed<'a>(effects: &[Effect], fs: f64, y: &'a [f64]) -> std::borrow::Cow<'a, [f64]> {
    match prefilter_hz(effects) {
        Some(_) => std::borrow::Cow::Owned(prefiltered(effects, fs, y)),
        None => std::borrow::Cow::Borrowed(y),
    }
}

/// What a model with effects cannot predict of a test one step ahead: `y - G u` (effects
/// included) whitened by the `coloured-noise` effect's noise model; without one it is the
/// simulation error `y - G u` itself.
#[must_use]
pub fn prediction_error(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    let v = residual(model, effects, u, y);
    match noise_model(effects) {
        Some(ar) => crate::fit::noise::whiten(ar, &v),
        None => v,
    }
}

/// What the model with its effects leaves of a test: the observed probe signal less
/// [`predict`].
pub(super) fn residual(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> Vec<f64> {
    let ym = predict(model, effects, u, y);
    observed(effects, model.fs, y)
        .iter()
        .zip(&ym)
        .map(|(a, b)| a - b)
        .collect()
}

/// The fitted AR noise model of a `coloured-noise` effect, if any.
#[must_use]
pub fn noise_model(effects: &[Effect]) -> Option<&[f64]> {
    effects.iter().find_map(|e| match e {
        Effect::ColouredNoise { ar, .. } if !ar.is_empty() => Some(ar.as_slice()),
        _ => None,
    })
}

/// The innovation standard deviation of a `coloured-noise` effect's noise model (0 without).
#[must_use]
pub fn innovation_std(effects: &[Effect]) -> f64 {
    effects
        .iter()
        .find_map(|e| match e {
            Effect::ColouredNoise { innovation_std, .. } => Some(*innovation_std),
            _ => None,
        })
        .unwrap_or(0.0)
}

/// The normalised RMS error a model with effects is judged by on a test: the one-step-ahead
/// prediction error when it has a noise model, else the simulation error (the same thing for
/// white residuals); over the range of the observed probe signal.
#[must_use]
pub fn judged_nrmse(model: &Model, effects: &[Effect], u: &[f64], y: &[f64]) -> f64 {
    crate::fit::nrmse_of_error(
        &observed(effects, model.fs, y),
        prediction_error(model, effects, u, y),
    )
}
