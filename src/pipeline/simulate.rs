//! A model file's probe output from a recording's reference, the effects included (an offset
//! or drift estimated on the recording, the time scale of a temperature), and its error
//! against the recorded probe.

use crate::effects;
use crate::error::{Advice, Error, Parameter, Result};
use crate::file::ModelFile;

/// A recording to simulate a model file on.
#[derive(Debug, Clone, Copy)]
pub struct SimulateRequest<'a> {
    /// The model file.
    pub file: &'a ModelFile,
    /// The recording's reference (the input), at the model's sample rate.
    pub u: &'a [f64],
    /// The recorded probe, as long as `u`: what the effects are estimated on and the
    /// simulation is measured against.
    pub y: &'a [f64],
    /// The recording's gas temperature (K), for a model with a `temperature` effect; `None`
    /// estimates the time-scale factor from the recording.
    pub temperature_k: Option<f64>,
}

/// The model's probe output and its error.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulated {
    /// The simulated probe, one sample per sample of the reference.
    pub y_model: Vec<f64>,
    /// Its normalised RMS error against the recorded probe (as the effects observe it).
    pub nrmse: f64,
}

/// Simulates the whole model of `request.file` (dynamics plus effects) on the recording.
///
/// # Errors
/// [`Error::InvalidParameter`] ([`Parameter::Temperature`], advised to add the temperature
/// effect) when a temperature is given and the model has no `temperature` effect;
/// [`effects::scale_for`]'s for a temperature that is not a positive number of kelvin. The
/// scale at that temperature follows the effect's law ([`effects::TemperatureDamping::scale`]).
pub fn simulate(request: &SimulateRequest<'_>) -> Result<Simulated> {
    let SimulateRequest {
        file,
        u,
        y,
        temperature_k,
    } = *request;
    let scale = match (temperature_k, effects::temperature_law(&file.effects)) {
        (Some(t), Some((reference, law))) => Some(law.scale(t, reference)?),
        (Some(_), None) => {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Temperature,
                message: "the model file has no temperature effect, so no reference temperature"
                    .into(),
            }
            .advised(Advice::AddTemperature { by_hand: false }))
        }
        (None, _) => None,
    };
    let y_model = effects::predict_with(&file.model, &file.effects, u, y, scale);
    let observed = effects::observed(&file.effects, file.model.fs, y);
    let nrmse = crate::fit::nrmse_of(&observed, &y_model);
    Ok(Simulated { y_model, nrmse })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> ModelFile {
        crate::testing::model_file(super::super::testing::probe())
    }

    /// The model's own answer to a step is simulated with no error, and a temperature is
    /// refused for a model with no temperature law.
    #[test]
    fn a_model_simulates_its_own_answer_and_refuses_a_temperature_it_has_no_law_for() {
        let file = file();
        let u: Vec<f64> = (0..2000).map(|k| f64::from(u8::from(k >= 500))).collect();
        let y = file.model.simulate(&u);
        let request = SimulateRequest {
            file: &file,
            u: &u,
            y: &y,
            temperature_k: None,
        };
        let s = simulate(&request).unwrap();
        assert_eq!(s.y_model.len(), u.len());
        assert!(s.nrmse < 1e-12, "{}", s.nrmse);
        let e = simulate(&SimulateRequest {
            temperature_k: Some(300.0),
            ..request
        })
        .unwrap_err();
        assert!(
            matches!(
                e,
                Error::Advised {
                    advice: Advice::AddTemperature { by_hand: false },
                    ..
                }
            ),
            "{e}"
        );
        assert!(!e.to_string().contains("--"), "{e}");
    }
}
