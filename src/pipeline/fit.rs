//! The fit of the probe's model in the modelling loop: the tests a fit accepts (a reference
//! that moves, one sample rate), the effects a refit carries and adds, and the model file a
//! fit makes (sources, error history).

use std::path::Path;

use crate::effects::{self, Effect, EffectKind};
use crate::error::{Error, Result};
use crate::file::{HistoryRow, HistoryTest, ModelFile, ProbeGeometry, FORMAT_VERSION};
use crate::fit::model::Source;
use crate::fit::{self, step, Options, Order, Test, TestRole};

/// A fit of the probe's model to its step tests (`unlag fit`).
#[derive(Debug, Clone)]
pub struct FitRequest<'a> {
    /// The tests: the estimation test first, then the held-out ones (which choose the order
    /// and are reported). Their names are the files the model file records.
    pub tests: &'a [Test<'a>],
    /// How many of [`Self::tests`], from the first, are estimation tests: 1, or more fitted
    /// together for a quadratic loss that one test cannot identify (`nonlinear-damping`,
    /// [`effects::fit_with_also_reading_creep`]); the rest are held out.
    pub estimation_tests: usize,
    /// The SHA-256 of each test's file, in the same order.
    pub digests: &'a [String],
    /// Each test's sample rate (Hz), in the same order: the estimation test's is the model's,
    /// and the held-out tests must share it ([`check_same_rate`]).
    pub sample_rates_hz: &'a [f64],
    /// Method, order and delay.
    pub options: Options,
    /// The effects to fit with ([`carried_effects`], [`add_effects`]).
    pub effects: Vec<Effect>,
    /// Search the delay again and keep it as the model's from then on (`--add delay`); without
    /// effect when `effects` fix the delay already.
    pub search_delay: bool,
    /// The error history of the model this fit continues (empty for a fresh one).
    pub history: Vec<HistoryRow>,
    /// The probe's geometry, which describes the hardware and is kept whatever the fit.
    pub probe: Option<ProbeGeometry>,
}

/// Fits the model, with its effects, to the tests: the model file with its sources (errors
/// with the effects included, noise floors), one more row of error history, and no
/// compensator yet ([`super::design_compensator`] designs it).
///
/// # Errors
/// [`Error::InvalidParameter`] without a test; [`Error::InvalidArgument`] with a digest or a
/// sample rate missing; [`check_excitation`]'s for a test whose reference does not move,
/// [`check_same_rate`]'s for a held-out test at another rate; the fit's errors
/// ([`effects::fit_with`]).
pub fn fit_probe(request: &FitRequest<'_>) -> Result<ModelFile> {
    let Some((estimation, rest)) = request.tests.split_first() else {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::Tests,
            message: "give at least one step test".into(),
        });
    };
    let joint = request.estimation_tests.max(1);
    let (also, validation) = rest.split_at((joint - 1).min(rest.len()));
    if request.digests.len() != request.tests.len() {
        return Err(Error::InvalidArgument {
            what: "digests",
            message: format!(
                "{} file digests for {} tests",
                request.digests.len(),
                request.tests.len()
            ),
        });
    }
    if request.sample_rates_hz.len() != request.tests.len() {
        return Err(Error::InvalidArgument {
            what: "sample rates",
            message: format!(
                "{} sample rates for {} tests",
                request.sample_rates_hz.len(),
                request.tests.len()
            ),
        });
    }
    for test in request.tests {
        check_excitation(Path::new(test.name), test.u)?;
    }
    let rated: Vec<(&str, f64)> = request
        .tests
        .iter()
        .map(|t| t.name)
        .zip(request.sample_rates_hz.iter().copied())
        .collect();
    check_same_rate(&rated)?;
    let fs = request.sample_rates_hz[0];
    let search_delay = request.search_delay
        && !request
            .effects
            .iter()
            .any(|e| e.kind() == EffectKind::Delay);
    let (fitted, mut effects) = effects::fit_with_also_reading_creep(
        estimation,
        also,
        validation,
        fs,
        &request.options,
        &request.effects,
    )?;
    if search_delay {
        effects.push(Effect::Delay {
            samples: fitted.model.delay,
        });
    }
    // Errors with the effects included (an offset or a drift is estimated on each test).
    let floors = if effects::noise_model(&effects).is_some() {
        fit::noise::prediction_floors(request.tests, &fitted.model)
    } else {
        Vec::new()
    };
    let sources: Vec<Source> = request
        .tests
        .iter()
        .zip(request.digests)
        .enumerate()
        .map(|(i, (test, digest))| Source {
            file: test.name.to_string(),
            sha256: digest.clone(),
            role: if i < joint {
                TestRole::Estimation
            } else {
                TestRole::Validation
            },
            // With a noise model, the one-step-ahead prediction error (said when printed).
            nrmse: effects::judged_nrmse(&fitted.model, &effects, test.u, test.y),
            noise_floor: fit::noise_floor(test.y, fit::step::quiet_until(test.u)),
            prediction_floor: floors.get(i).cloned().flatten(),
        })
        .collect();
    let mut history = request.history.clone();
    history.push(HistoryRow {
        effects: effects.iter().map(|e| e.kind()).collect(),
        order: fitted.model.order(),
        delay: fitted.model.delay,
        tests: sources
            .iter()
            .map(|s| HistoryTest {
                file: s.file.clone(),
                role: s.role,
                nrmse: s.nrmse,
            })
            .collect(),
    });
    Ok(ModelFile {
        format_version: FORMAT_VERSION,
        model: fitted.model,
        fit: Some(fitted.report),
        sources,
        inverse: None,
        effects,
        history,
        probe: request.probe.clone(),
        board: Default::default(),
    })
}

/// Refuses a test whose reference (`u`, of the test at `path`) does not move above its noise
/// (a step, or another change): a record with no excitation tells nothing about the probe
/// and would only mislead the order and band choices.
///
/// # Errors
/// [`Error::NoStep`] for a reference without excitation, its column unknown here (0, no
/// name: the caller that read the file knows them).
pub fn check_excitation(path: &Path, u: &[f64]) -> Result<()> {
    let e = step::excitation(u);
    if e < step::MIN_EXCITATION {
        return Err(Error::NoStep {
            path: path.to_path_buf(),
            column: 0,
            name: String::new(),
            reason: format!(
                "the reference does not move above its noise (its spread is {e:.2} times \
                 the noise; at least {} is needed): a test without a step or other change \
                 tells nothing about the probe",
                step::MIN_EXCITATION
            ),
        });
    }
    Ok(())
}

/// Refuses held-out tests sampled at another rate than the estimation test (the first), each
/// given as its name and its sample rate (Hz), beyond the jitter a clock has
/// ([`crate::trace::rate_differs`]).
///
/// # Errors
/// [`Error::Mismatch`] naming the first test at another rate.
pub fn check_same_rate(tests: &[(&str, f64)]) -> Result<()> {
    let Some(((est, est_hz), val)) = tests.split_first() else {
        return Ok(());
    };
    for (name, hz) in val {
        if crate::trace::rate_differs(*hz, *est_hz) {
            return Err(Error::Mismatch {
                path: name.into(),
                message: format!(
                    "sampled at {hz:.6} Hz but the estimation test {est} at {est_hz:.6} Hz: \
                     resample one of them"
                ),
            });
        }
    }
    Ok(())
}

/// Refuses a record sampled at another rate than the model file's, beyond the jitter a clock
/// has ([`crate::trace::rate_differs`]).
///
/// # Errors
/// [`Error::Mismatch`] naming the record at `path`.
pub fn check_model_rate(file: &ModelFile, path: &Path, rate_hz: f64) -> Result<()> {
    if crate::trace::rate_differs(rate_hz, file.model.fs) {
        return Err(Error::Mismatch {
            path: path.to_path_buf(),
            message: format!(
                "sampled at {rate_hz:.6} Hz but the model is for {:.6} Hz",
                file.model.fs
            ),
        });
    }
    Ok(())
}

/// The effects a refit starts from: those of the model it continues, less its modes when the
/// order is given (a mode is two more poles, which would override the order asked for); and
/// how many modes were dropped.
#[must_use]
pub fn carried_effects(previous: &[Effect], order: Order) -> (Vec<Effect>, usize) {
    let mut effects = previous.to_vec();
    if matches!(order, Order::Fixed(_)) {
        effects.retain(|e| e.kind() != EffectKind::Mode);
    }
    let dropped = previous.len() - effects.len();
    (effects, dropped)
}

/// Adds the effects named by `kinds` (`unlag fit --add KIND`, [`Effect::parse`]) to
/// `effects`: each replaces one of its kind, but modes add up. A bare `delay` (what a
/// diagnosis names) removes the delay effect instead; returns whether one was named, for
/// [`FitRequest::search_delay`].
///
/// # Errors
/// [`Error::InvalidParameter`] for a kind that is not an effect, naming the kinds there are.
pub fn add_effects(effects: &mut Vec<Effect>, kinds: &[String]) -> Result<bool> {
    let mut search_delay = false;
    for kind in kinds {
        if kind.parse() == Ok(EffectKind::Delay) {
            effects.retain(|x| x.kind() != EffectKind::Delay);
            search_delay = true;
            continue;
        }
        let e = Effect::parse(kind).ok_or_else(|| Error::InvalidParameter {
            parameter: crate::error::Parameter::Effect,
            message: format!(
                "unknown effect '{kind}': one of {}, or delay=N, sensor-resonance=HZ, sensor-resonance-prefilter[=HZ], temperature=K, temperature-viscous[=K], temperature-diffusive[=K]",
                effects::KINDS
                    .iter()
                    .map(|k| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
        effects::add(effects, e);
    }
    Ok(search_delay)
}

#[cfg(test)]
mod tests {
    use super::super::testing::{est_and_val, step_test};
    use super::*;
    use crate::fit::Method;

    #[test]
    fn a_fit_records_each_test_with_its_role_digest_and_a_history_row() {
        let (est, val) = (step_test(1.0, 1), step_test(1.0, 2));
        let tests = est_and_val(&est, &val);
        let ((ue, ye), (_, yv)) = (&est, &val);
        let digests = ["e".to_string(), "v".to_string()];
        let earlier = HistoryRow {
            effects: Vec::new(),
            order: 2,
            delay: 1,
            tests: Vec::new(),
        };
        let request = FitRequest {
            tests: &tests,
            estimation_tests: 1,
            digests: &digests,
            sample_rates_hz: &[10_000.0, 10_000.0],
            options: Options {
                method: Method::Oe,
                order: Order::Fixed(1),
                delay: Some(3),
            },
            effects: Vec::new(),
            search_delay: false,
            history: vec![earlier.clone()],
            probe: None,
        };
        let file = fit_probe(&request).unwrap();
        assert_eq!((file.model.order(), file.model.delay), (1, 3));
        assert!((file.model.a[0] + 0.95).abs() < 0.01, "{:?}", file.model.a);
        assert!(file.inverse.is_none() && file.fit.is_some());
        let roles: Vec<(&str, &str, &str)> = file
            .sources
            .iter()
            .map(|s| (s.file.as_str(), s.sha256.as_str(), s.role.as_str()))
            .collect();
        assert_eq!(
            roles,
            [
                ("est.csv", "e", "estimation"),
                ("val.csv", "v", "validation")
            ]
        );
        // Noise of 1e-3 on a unit step: errors at that level, floors measured before the step.
        for s in &file.sources {
            assert!(s.nrmse < 3e-3, "{s:?}");
            assert!(s.noise_floor > 3e-4 && s.noise_floor < 3e-3, "{s:?}");
        }
        assert_eq!(file.history.len(), 2);
        assert_eq!(file.history[0], earlier);
        let row = &file.history[1];
        assert_eq!((row.order, row.delay), (1, 3));
        assert_eq!(row.tests.len(), 2);
        assert_eq!(row.tests[1].nrmse, file.sources[1].nrmse);

        // `--add delay`: the delay found is kept as an effect; not when one is given.
        let searched = fit_probe(&FitRequest {
            search_delay: true,
            ..request.clone()
        })
        .unwrap();
        assert_eq!(searched.effects, [Effect::Delay { samples: 3 }]);
        assert_eq!(searched.history[1].effects, [EffectKind::Delay]);
        let given = fit_probe(&FitRequest {
            search_delay: true,
            effects: vec![Effect::Delay { samples: 4 }],
            ..request.clone()
        })
        .unwrap();
        assert_eq!(given.model.delay, 4);
        assert_eq!(given.effects, [Effect::Delay { samples: 4 }]);

        // A library caller gets the command line's checks on the tests: one sample rate, and
        // a reference that moves.
        let other_rate = fit_probe(&FitRequest {
            sample_rates_hz: &[10_000.0, 5_000.0],
            ..request.clone()
        })
        .unwrap_err();
        assert_eq!(
            other_rate.to_string(),
            "val.csv: sampled at 5000.000000 Hz but the estimation test est.csv at \
             10000.000000 Hz: resample one of them"
        );
        let flat = vec![1.0; ue.len()];
        let still = [
            Test {
                name: "est.csv",
                u: ue,
                y: ye,
            },
            Test {
                name: "flat.csv",
                u: &flat,
                y: yv,
            },
        ];
        let no_step = fit_probe(&FitRequest {
            tests: &still,
            estimation_tests: 1,
            ..request.clone()
        })
        .unwrap_err();
        assert!(
            matches!(&no_step, Error::NoStep { path, .. } if path.as_path() == Path::new("flat.csv")),
            "{no_step}"
        );
        assert!(matches!(
            fit_probe(&FitRequest {
                digests: &digests[..1],
                ..request.clone()
            }),
            Err(Error::InvalidArgument {
                what: "digests",
                ..
            })
        ));
        assert!(matches!(
            fit_probe(&FitRequest {
                tests: &[],
                estimation_tests: 1,
                digests: &[],
                ..request
            }),
            Err(Error::InvalidParameter {
                parameter: crate::error::Parameter::Tests,
                ..
            })
        ));
    }

    #[test]
    fn a_refit_drops_carried_modes_only_for_an_order_given() {
        let previous = [
            Effect::parse("mode").unwrap(),
            Effect::parse("leak").unwrap(),
            Effect::parse("mode").unwrap(),
        ];
        let (auto, dropped) = carried_effects(&previous, Order::Auto { max: 6 });
        assert_eq!((auto.as_slice(), dropped), (&previous[..], 0));
        let (fixed, dropped) = carried_effects(&previous, Order::Fixed(2));
        assert_eq!((fixed.as_slice(), dropped), (&previous[1..2], 2));
    }

    #[test]
    fn added_effects_replace_their_kind_but_modes_add_up() {
        let mut effects = vec![
            Effect::parse("delay=5").unwrap(),
            Effect::parse("mode").unwrap(),
            Effect::parse("temperature=300").unwrap(),
        ];
        let kinds = ["mode", "temperature=320", "offset"].map(String::from);
        assert!(!add_effects(&mut effects, &kinds).unwrap());
        let spelt: Vec<String> = effects.iter().map(|e| e.kind().to_string()).collect();
        assert_eq!(spelt, ["delay", "mode", "mode", "temperature", "offset"]);
        assert_eq!(effects::reference_k(&effects), Some(320.0));
        // A bare `delay` asks for the search: the delay effect goes.
        assert!(add_effects(&mut effects, &["delay".to_string()]).unwrap());
        assert!(effects.iter().all(|e| e.kind() != EffectKind::Delay));
        let unknown = add_effects(&mut effects, &["modes".to_string()]);
        assert!(
            matches!(&unknown, Err(Error::InvalidParameter { parameter: crate::error::Parameter::Effect, message }) if message.contains("one of mode, leak")),
            "{unknown:?}"
        );
    }
}
