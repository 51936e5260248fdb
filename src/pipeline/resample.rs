//! A model file at another sample rate: the model re-discretised step invariant through its
//! continuous-time equivalent (the delay included), its step response checked against the old
//! model's and the continuous one, and the file without the compensator designed at the old
//! rate.

use std::path::Path;

use crate::error::{Error, Parameter, Result};
use crate::file::ModelFile;
use crate::fit::continuous::{self, Agreement, Continuous, Discretised};

/// A model file to put at another sample rate.
#[derive(Debug, Clone, Copy)]
pub struct ResampleRequest<'a> {
    /// The model file.
    pub file: &'a ModelFile,
    /// Where the model file was read from, for messages.
    pub model_path: &'a Path,
    /// The new sample rate (Hz): [`check_sample_rate`].
    pub sample_rate_hz: f64,
}

/// A model file at another sample rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    /// The new model file: the model at the new rate, the fit report, sources, effects,
    /// history and probe geometry kept (they describe where the model came from), no
    /// compensator (its coefficients belong to the old rate).
    pub file: ModelFile,
    /// The old model's continuous-time equivalent, which the new one samples.
    pub continuous: Continuous,
    /// The new model and how its delay was split between whole samples and coefficients.
    pub discretised: Discretised,
    /// The step responses of the old and the new model at the instants both rates sample.
    pub agreement: Agreement,
    /// The largest difference of the new model's step response from the continuous one, as a
    /// fraction of the step's final value.
    pub max_error_vs_continuous: f64,
    /// The old file had a compensator, which was not carried over.
    pub dropped_inverse: bool,
}

/// Whether `sample_rate_hz` is a sample rate a model can be resampled to: above 0 and at most
/// [`crate::trace::MAX_SAMPLE_RATE_HZ`].
///
/// # Errors
/// [`Error::InvalidParameter`] ([`Parameter::SampleRate`]) when it is not.
pub fn check_sample_rate(sample_rate_hz: f64) -> Result<()> {
    if sample_rate_hz.is_finite()
        && sample_rate_hz > 0.0
        && sample_rate_hz <= crate::trace::MAX_SAMPLE_RATE_HZ
    {
        return Ok(());
    }
    Err(Error::InvalidParameter {
        parameter: Parameter::SampleRate,
        message: format!(
            "must be a sample rate in Hz above 0 and at most {:e}, not {:?}",
            crate::trace::MAX_SAMPLE_RATE_HZ,
            sample_rate_hz
        ),
    })
}

/// Re-discretises the model file's model at the new rate, step invariant, the delay included
/// ([`Continuous::discretise`]), and checks the new step response against the old model's
/// ([`continuous::step_agreement`]) and the continuous one.
///
/// # Errors
/// [`check_sample_rate`]'s; [`Error::Model`] (`cannot resample: ...`, naming the pole) for a
/// model without a continuous-time equivalent; the discretisation's.
pub fn resample(request: &ResampleRequest<'_>) -> Result<Resampled> {
    let ResampleRequest {
        file,
        model_path,
        sample_rate_hz: fs,
    } = *request;
    check_sample_rate(fs)?;
    let old = &file.model;
    let cannot = |reason: String| Error::Model {
        path: model_path.to_path_buf(),
        message: format!("cannot resample: {reason}"),
    };
    let ct = Continuous::from_model(old).map_err(|e| {
        if let Some(crate::fit::FitError::Continuous(reason)) = e.stage() {
            cannot(reason.to_string())
        } else if let Some(p) = e.stage::<crate::poly::PolyError>() {
            cannot(p.reason())
        } else {
            e
        }
    })?;
    let new = ct.discretise(fs)?;
    let agreement = continuous::step_agreement(old, &new.model);
    let max_error_vs_continuous = {
        let n = (agreement.instants.max(1) as f64 * (fs / old.fs).max(1.0)).ceil() as usize;
        let n = n.clamp(16, continuous::MAX_AGREEMENT_SAMPLES);
        let s = continuous::step_response(&new.model, n);
        let scale = ct.dc_gain.abs().max(f64::MIN_POSITIVE);
        s.iter()
            .enumerate()
            .map(|(k, v)| (v - ct.step(k as f64 / fs)).abs() / scale)
            .fold(0.0, f64::max)
    };
    let resampled = ModelFile {
        model: new.model.clone(),
        inverse: None,
        ..file.clone()
    };
    Ok(Resampled {
        file: resampled,
        continuous: ct,
        discretised: new,
        agreement,
        max_error_vs_continuous,
        dropped_inverse: file.inverse.is_some(),
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::probe;
    use super::*;
    use crate::fit::model::Model;
    use crate::testing::model_file;

    fn at(file: &ModelFile, fs: f64) -> Result<Resampled> {
        resample(&ResampleRequest {
            file,
            model_path: Path::new("probe.toml"),
            sample_rate_hz: fs,
        })
    }

    #[test]
    fn a_model_resampled_up_and_back_is_the_same_model() {
        let mut f = model_file(probe());
        let design = crate::design::inverse::design(
            &f.model,
            300.0,
            &crate::design::inverse::Options {
                bandwidth_hz: Some(300.0),
                ..Default::default()
            },
        )
        .unwrap();
        f.inverse = Some(design);
        let up = at(&f, 50_000.0).unwrap();
        assert!(up.dropped_inverse && up.file.inverse.is_none());
        assert_eq!(up.file.model, up.discretised.model);
        assert_eq!(up.file.model.fs, 50_000.0);
        assert!(up.agreement.max_error < 1e-6, "{:?}", up.agreement);
        assert!(
            up.max_error_vs_continuous < 1e-6,
            "{}",
            up.max_error_vs_continuous
        );
        let back = at(&up.file, 10_000.0).unwrap();
        assert!(!back.dropped_inverse);
        assert_eq!(back.file.model.delay, f.model.delay);
        for (a, b) in back.file.model.a.iter().zip(&f.model.a) {
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
        for (a, b) in back.file.model.b.iter().zip(&f.model.b) {
            assert!((a - b).abs() < 1e-9, "{a} {b}");
        }
    }

    #[test]
    fn a_bad_rate_and_a_model_without_a_continuous_equivalent_are_refused() {
        let f = model_file(probe());
        for fs in [0.0, -3.0, f64::NAN, f64::INFINITY, 1e300] {
            let e = at(&f, fs).unwrap_err();
            assert!(
                matches!(
                    e,
                    Error::InvalidParameter {
                        parameter: Parameter::SampleRate,
                        ..
                    }
                ),
                "{e:?}"
            );
            // The library names the parameter, not a command-line flag.
            assert!(!e.to_string().contains("--"), "{e}");
        }
        // A pole on the negative real axis has no continuous-time equivalent.
        let ringing = model_file(Model {
            fs: 10_000.0,
            delay: 1,
            a: vec![0.5],
            b: vec![1.5],
        });
        let e = at(&ringing, 20_000.0).unwrap_err();
        assert!(
            matches!(&e, Error::Model { path, message }
                if path == Path::new("probe.toml") && message.starts_with("cannot resample: ")),
            "{e:?}"
        );
    }
}
