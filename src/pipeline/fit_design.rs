//! A fit and its compensator in one request: the effects a fit carries from the model file it
//! continues and those asked for, the probe's model fitted ([`super::fit_probe`]), and its
//! compensator designed on the same tests ([`super::design_compensator`]), the fit standing
//! without one when none can be designed ([`fit_and_design`]). `unlag fit` asks here.

use super::{
    add_effects, carried_effects, design_compensator, fit_probe, CompensatorRequest,
    CompensatorSpec, FitRequest, Roles,
};
use crate::effects::{Effect, EffectKind};
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit::{Options, Test};

/// The stages of a [`fit_and_design`], as [`FitDesignRequest::on_stage`] hears them, in this
/// order.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum FitStage {
    /// The fit continues a model file that has effects or error history: the effects it keeps
    /// ([`carried_effects`]), its rows of history, and the modes dropped because the order is
    /// given. Told before the effects asked for are added, and only for such a file.
    Continuing {
        /// The kinds of the effects kept, in the file's order.
        kept: Vec<EffectKind>,
        /// The rows of error history the fit continues.
        history_rows: usize,
        /// The mode effects dropped because the order is given.
        dropped_modes: usize,
    },
    /// Fitting the model: the orders on a window, then the whole record.
    Fitting,
    /// Designing the compensator.
    Designing,
}

/// A fit of the probe's model to its step tests and the compensator designed for it.
#[derive(Clone, Copy)]
pub struct FitDesignRequest<'a> {
    /// The tests: the estimation test first, then the held-out ones (as for [`FitRequest`]).
    pub tests: &'a [Test<'a>],
    /// How many of the tests, from the first, are estimation tests
    /// ([`FitRequest::estimation_tests`]).
    pub estimation_tests: usize,
    /// The SHA-256 of each test's file, in the same order.
    pub digests: &'a [String],
    /// Each test's sample rate (Hz), in the same order.
    pub sample_rates_hz: &'a [f64],
    /// Method, order and delay.
    pub options: Options,
    /// The model file this fit replaces, as it stands: unless [`Self::fresh`], the fit
    /// continues it (its effects, [`carried_effects`], and its error history carry over); its
    /// probe geometry, which describes the hardware and not the fit, is kept either way.
    /// `None` when there is none.
    pub previous: Option<&'a ModelFile>,
    /// Start afresh: of [`Self::previous`] only the probe's geometry is kept.
    pub fresh: bool,
    /// The effects to add, by name ([`add_effects`]).
    pub add: &'a [String],
    /// The estimation test's reference column in its file (1-based position, 0 when unknown,
    /// and name), which an [`Error::NoStep`] of the fit names: the tests here are samples,
    /// without their files' layout.
    pub reference_column: (usize, &'a str),
    /// The compensator asked for, given the fitted model's sample rate (Hz). Asked once the
    /// model is fitted, so that what the fit refuses is told before what the spec refuses.
    pub spec: &'a dyn Fn(f64) -> Result<CompensatorSpec>,
    /// Told as each stage starts (a front end's progress indication and notes).
    pub on_stage: &'a dyn Fn(FitStage),
}

impl core::fmt::Debug for FitDesignRequest<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FitDesignRequest")
            .field("tests", &self.tests.len())
            .field("options", &self.options)
            .field("previous", &self.previous.is_some())
            .field("fresh", &self.fresh)
            .field("add", &self.add)
            .field("reference_column", &self.reference_column)
            .finish_non_exhaustive()
    }
}

/// What a [`fit_and_design`] made.
#[derive(Debug)]
pub struct FitDesigned {
    /// The model file: the fitted model with its sources and history, and its compensator
    /// ([`ModelFile::inverse`]) when one could be designed.
    pub file: ModelFile,
    /// Why no compensator could be designed, when none could: the fit stands on its own.
    pub no_compensator: Option<Error>,
    /// The fixed-point plans that could not be made, and why: the f32 compensator does not
    /// depend on them.
    pub unplanned: Vec<Error>,
    /// The full scale the fixed-point plan was made for, and where it came from.
    pub full_scale: super::FullScale,
}

/// Carries the effects of the model file the fit continues and adds those asked for, fits the
/// model to the tests, and designs its compensator on them (the held-out tests judge it, or
/// the estimation test when it is alone), telling each stage as it starts.
///
/// # Errors
/// [`add_effects`]'s for an effect that is not one; [`fit_probe`]'s (an
/// [`Error::NoStep`] naming [`FitDesignRequest::reference_column`]); the spec's; and
/// [`design_compensator`]'s for what is asked. A compensator that cannot be designed is no
/// error but [`FitDesigned::no_compensator`].
pub fn fit_and_design(request: &FitDesignRequest<'_>) -> Result<FitDesigned> {
    let on_stage = request.on_stage;
    // The probe's geometry describes the hardware, not the fit: kept even afresh.
    let probe = request.previous.and_then(|p| p.probe.clone());
    let previous = request.previous.filter(|_| !request.fresh);
    let (mut effects, dropped_modes) = carried_effects(
        previous.map_or(&[], |p| p.effects.as_slice()),
        request.options.order,
    );
    if let Some(p) = previous.filter(|p| !p.effects.is_empty() || !p.history.is_empty()) {
        on_stage(FitStage::Continuing {
            kept: effects.iter().map(Effect::kind).collect(),
            history_rows: p.history.len(),
            dropped_modes,
        });
    }
    let search_delay = add_effects(&mut effects, request.add)?;
    on_stage(FitStage::Fitting);
    let (column, name) = request.reference_column;
    let mut file = fit_probe(&FitRequest {
        tests: request.tests,
        estimation_tests: request.estimation_tests,
        digests: request.digests,
        sample_rates_hz: request.sample_rates_hz,
        options: request.options,
        effects,
        search_delay,
        history: previous.map(|p| p.history.clone()).unwrap_or_default(),
        probe,
    })
    .map_err(|e| match e {
        Error::NoStep { path, reason, .. } => Error::NoStep {
            column,
            name: name.to_string(),
            path,
            reason,
        },
        e => e,
    })?;
    on_stage(FitStage::Designing);
    let spec = (request.spec)(file.model.fs)?;
    let compensator = design_compensator(&CompensatorRequest {
        model: &file.model,
        effects: &file.effects,
        tests: request.tests,
        roles: Roles::Fit {
            estimation: request.estimation_tests,
        },
        stored: None,
        spec: &spec,
        exportable: false,
    })?;
    let no_compensator = match compensator.design {
        Ok(design) => {
            file.inverse = Some(design);
            None
        }
        Err(e) => Some(e),
    };
    Ok(FitDesigned {
        file,
        no_compensator,
        unplanned: compensator.unplanned,
        full_scale: compensator.full_scale,
    })
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use super::super::testing::{est_and_val, step_test};
    use super::super::Shape;
    use super::*;
    use crate::design::inverse::LowpassKind;
    use crate::design::quantise::FixedForm;
    use crate::fit::{Method, Order};

    fn spec(bandwidth_hz: f64) -> CompensatorSpec {
        CompensatorSpec {
            shape: Shape::BandLimited {
                bandwidth_hz: Some(bandwidth_hz),
                stabilise: true,
            },
            lowpass: LowpassKind::Bessel,
            lowpass_order: 4,
            signal: Vec::new(),
            fixed_form: FixedForm::Normal,
            full_scale: None,
        }
    }

    #[test]
    fn a_fit_comes_back_with_its_compensator_or_why_there_is_none() {
        let (est, val) = (step_test(1.0, 1), step_test(1.0, 2));
        let tests = est_and_val(&est, &val);
        let ((ue, _), (_, yv)) = (&est, &val);
        let digests = ["e".to_string(), "v".to_string()];
        let heard = RefCell::new(Vec::new());
        let rates_asked = RefCell::new(Vec::new());
        let on_stage = |s: FitStage| heard.borrow_mut().push(s);
        let band_200 = |fs: f64| {
            rates_asked.borrow_mut().push(fs);
            Ok(spec(200.0))
        };
        let request = FitDesignRequest {
            tests: &tests,
            estimation_tests: 1,
            digests: &digests,
            sample_rates_hz: &[10_000.0, 10_000.0],
            options: Options {
                method: Method::Oe,
                order: Order::Fixed(1),
                delay: Some(3),
            },
            previous: None,
            fresh: false,
            add: &[],
            reference_column: (2, "p_ref"),
            spec: &band_200,
            on_stage: &on_stage,
        };
        let done = fit_and_design(&request).unwrap();
        assert!(done.no_compensator.is_none(), "{:?}", done.no_compensator);
        assert!(done.file.inverse.is_some() && done.file.fit.is_some());
        assert_eq!(done.file.history.len(), 1);
        assert_eq!(*heard.borrow(), [FitStage::Fitting, FitStage::Designing]);
        assert_eq!(*rates_asked.borrow(), [10_000.0]);

        // Continuing that file with an order given: its mode is dropped, told before the fit;
        // the effect asked for is added, the history grows.
        heard.borrow_mut().clear();
        let mut previous = done.file.clone();
        previous.effects = vec![
            Effect::parse("mode").unwrap(),
            Effect::parse("offset").unwrap(),
        ];
        let continued = fit_and_design(&FitDesignRequest {
            previous: Some(&previous),
            add: &["drift".to_string()],
            ..request
        })
        .unwrap();
        assert_eq!(
            heard.borrow()[0],
            FitStage::Continuing {
                kept: vec![EffectKind::Offset],
                history_rows: 1,
                dropped_modes: 1,
            }
        );
        assert_eq!(heard.borrow().len(), 3);
        let kinds: Vec<EffectKind> = continued.file.effects.iter().map(Effect::kind).collect();
        assert_eq!(kinds, [EffectKind::Offset, EffectKind::Drift]);
        assert_eq!(continued.file.history.len(), 2);

        // Afresh from a file with the probe's geometry: nothing of the fit carries over but
        // the geometry.
        heard.borrow_mut().clear();
        let geometry = crate::file::ProbeGeometry {
            lines: vec![[0.6, 1.1e-3]],
            volume_m3: 20e-9,
            temperature_k: 293.15,
            pressure_pa: 101_325.0,
        };
        previous.probe = Some(geometry.clone());
        let fresh = fit_and_design(&FitDesignRequest {
            previous: Some(&previous),
            fresh: true,
            ..request
        })
        .unwrap();
        assert_eq!(*heard.borrow(), [FitStage::Fitting, FitStage::Designing]);
        assert!(fresh.file.effects.is_empty());
        assert_eq!(fresh.file.history.len(), 1);
        assert_eq!(fresh.file.probe, Some(geometry.clone()));
        let continued = fit_and_design(&FitDesignRequest {
            previous: Some(&previous),
            ..request
        })
        .unwrap();
        assert_eq!(continued.file.probe, Some(geometry));

        // A band above Nyquist: the fit stands, the design's failure comes back typed.
        let too_wide = |_: f64| Ok(spec(1e9));
        let undesigned = fit_and_design(&FitDesignRequest {
            spec: &too_wide,
            ..request
        })
        .unwrap();
        assert!(undesigned.file.inverse.is_none() && undesigned.file.fit.is_some());
        assert!(
            matches!(
                undesigned.no_compensator,
                Some(Error::InvalidParameter {
                    parameter: crate::error::Parameter::Bandwidth,
                    ..
                })
            ),
            "{:?}",
            undesigned.no_compensator
        );

        // A held-out test whose reference does not move: refused naming the reference column
        // given, before the spec is asked for.
        rates_asked.borrow_mut().clear();
        let flat = vec![1.0; ue.len()];
        let still = [
            tests[0],
            Test {
                name: "flat.csv",
                u: &flat,
                y: yv,
            },
        ];
        let refused = fit_and_design(&FitDesignRequest {
            tests: &still,
            ..request
        })
        .unwrap_err();
        assert!(
            matches!(&refused, Error::NoStep { column: 2, name, .. } if name == "p_ref"),
            "{refused:?}"
        );
        assert!(rates_asked.borrow().is_empty());

        // An effect that is not one: refused before the fit starts.
        heard.borrow_mut().clear();
        let unknown = fit_and_design(&FitDesignRequest {
            add: &["gremlins".to_string()],
            ..request
        });
        assert!(matches!(unknown, Err(Error::InvalidParameter { .. })));
        assert!(heard.borrow().is_empty());
    }
}
