//! Fitting a model with effects: the effects' parameters resolved on the estimation test,
//! the fit with the order, delay, method and additive parts they impose, and the noise model
//! fitted beside it. The second looks the fit then takes at its own result are in
//! [`fallback`].

use super::additive::initial_drift;
use super::nonlinear::fit_nonlinear;
use super::predict::residual;
use super::{
    estimate_additive, prefilter_sections, prefiltered, scale_for, simulate_nonlinear, Additive,
    Effect, FitChanges, SensorRemedy,
};
use crate::effects::EffectError;
use crate::error::Result;
use crate::fit::model::Model;
use crate::fit::{Fitted, Options, Order, Test};

mod fallback;
pub use fallback::fit_with_also_reading_creep;

/// The effects with their frequency-domain parameters resolved on the estimation test: a
/// sensor resonance without a frequency takes the reference's ringing peak, and its prefilter
/// half of it.
///
/// # Errors
/// [`EffectError::NoSensorResonance`] when the reference shows no resonance to filter
/// below; [`crate::error::Error::InvalidArgument`] when the prefilter's corner is not below
/// half the sample rate.
pub fn resolve(effects: &[Effect], u: &[f64], fs: f64) -> Result<Vec<Effect>> {
    effects
        .iter()
        .map(|e| match e {
            Effect::SensorResonance {
                natural_frequency_hz,
                prefilter_hz,
                remedy,
            } => {
                let f = if *natural_frequency_hz > 0.0 {
                    *natural_frequency_hz
                } else {
                    crate::evidence::reference_ringing(u, fs)
                        .map(|p| p.frequency_hz)
                        .ok_or(EffectError::NoSensorResonance)?
                };
                if *remedy == SensorRemedy::Modes {
                    if f >= 0.5 * fs {
                        return Err(crate::error::Error::InvalidArgument {
                            what: "sensor-resonance",
                            message: format!(
                                "the transducer's natural frequency {f} Hz is not below half \
                                 the sample rate ({} Hz): the record cannot show it",
                                0.5 * fs
                            ),
                        });
                    }
                    return Ok(Effect::SensorResonance {
                        natural_frequency_hz: f,
                        prefilter_hz: 0.0,
                        remedy: *remedy,
                    });
                }
                let corner = if *prefilter_hz > 0.0 {
                    *prefilter_hz
                } else {
                    0.5 * f
                };
                prefilter_sections(corner, fs)?;
                Ok(Effect::SensorResonance {
                    natural_frequency_hz: f,
                    prefilter_hz: corner,
                    remedy: *remedy,
                })
            }
            Effect::Temperature { reference_k, .. } => {
                scale_for(*reference_k, *reference_k)?;
                Ok(e.clone())
            }
            other => Ok(other.clone()),
        })
        .collect()
}

/// Fits with `effects`: the order raised by the modes and leaks, the delay and method they
/// impose, and the drift removed before the dynamics are fitted (alternating three times).
/// With `nonlinear-damping` the linear part and the quadratic loss are fitted together (a
/// search over the loss, the linear part refitted at each; see `fit_nonlinear`).
/// Returns the fit and the effects with their fitted parameters (from the estimation test).
///
/// # Errors
/// As [`crate::fit::fit`].
pub fn fit_with(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    options: &Options,
    effects: &[Effect],
) -> Result<(Fitted, Vec<Effect>)> {
    fit_with_also(estimation, &[], validation, fs, options, effects)
}

/// [`fit_with`], with more estimation tests (`also`) fitted together with the first: one
/// model for all of them ([`super::joint_linear`]), from the first test's fit, so that
/// several runs of the same probe (shots of a shock tube, steps of a valve) pin it down
/// better than one. With `nonlinear-damping` the linear part and the quadratic loss are fitted
/// on all of them at once ([`super::joint_loss`]), which one test cannot do (a linear model
/// with more damping explains one step as well). An offset or a drift is each test's own,
/// estimated on each; the tests share one gas temperature. The fit's note gives each test's
/// error.
///
/// # Errors
/// As [`fit_with`].
pub fn fit_with_also(
    estimation: &Test<'_>,
    also: &[Test<'_>],
    validation: &[Test<'_>],
    fs: f64,
    options: &Options,
    effects: &[Effect],
) -> Result<(Fitted, Vec<Effect>)> {
    let estimation_raw = estimation;
    // The same fit with other options or effects, on the tests as given.
    let refit = |options: &Options, effects: &[Effect]| {
        fit_with_also(estimation, also, validation, fs, options, effects)
    };
    let changes = FitChanges::of(effects);
    let opts = changed_options(&changes, options);
    // A sensor resonance: both channels of every test prefiltered below it.
    let effects = resolve(effects, estimation.u, fs)?;
    let filtered: Vec<(Vec<f64>, Vec<f64>)> = std::iter::once(estimation)
        .chain(also)
        .chain(validation)
        .map(|t| {
            (
                prefiltered(&effects, fs, t.u),
                prefiltered(&effects, fs, t.y),
            )
        })
        .collect();
    let mut tests = filtered
        .iter()
        .zip(std::iter::once(estimation).chain(also).chain(validation))
        .map(|((u, y), t)| Test { name: t.name, u, y });
    let Some(estimation) = tests.next() else {
        return Err(EffectError::NoEstimationTest.into());
    };
    let also: Vec<Test<'_>> = tests.by_ref().take(also.len()).collect();
    let validation: Vec<Test<'_>> = tests.collect();
    let validation = validation.as_slice();
    // Each test fitted has its own step, and its own offset or drift (a probe's, which the
    // next run need not share): estimated on each from what the dynamics leave it.
    let fitted_tests: Vec<Test<'_>> = std::iter::once(estimation)
        .chain(also.iter().copied())
        .collect();
    let onsets: Vec<usize> = fitted_tests
        .iter()
        .map(|t| crate::fit::step::quiet_until(t.u))
        .collect();
    let onset = onsets.first().copied().unwrap_or(0);
    let (fitted, additive, gain) =
        alternate(&changes, &fitted_tests, &onsets, validation, fs, &opts)?;
    let additive = additive.first().copied().unwrap_or_default();
    let out = with_noise_model(
        &fitted.model,
        with_fitted_values(&effects, additive, gain),
        estimation_raw,
    );
    fallback::second_looks(
        fallback::First {
            fitted,
            out,
            effects: &effects,
            options,
            delay_searched: opts.delay.is_none(),
            extra_order: changes.extra_order,
            estimation,
            onset,
            fs,
        },
        &refit,
    )
}

/// The dynamics fitted on `fitted_tests` (steps at `onsets`) with each test's offset or
/// drift estimated from what they leave and removed, alternately (once without either): the
/// fit, each test's offset or drift, and the nonlinear gain.
fn alternate(
    changes: &FitChanges,
    fitted_tests: &[Test<'_>],
    onsets: &[usize],
    validation: &[Test<'_>],
    fs: f64,
    opts: &Options,
) -> Result<(Fitted, Vec<Additive>, f64)> {
    // A drift starts from the record's ends, so that the first fit does not take it into
    // the dynamics (from which the residual could no longer separate it).
    let mut additive: Vec<Additive> = fitted_tests
        .iter()
        .zip(onsets)
        .map(|(t, &o)| {
            if changes.drift {
                initial_drift(t.u, t.y, o, fs)
            } else {
                Additive::default()
            }
        })
        .collect();
    // An offset or a drift is estimated from what the dynamics leave and the dynamics fitted
    // again without it, a few times, so that the dynamics do not take it in.
    let rounds = if changes.drift {
        4
    } else if changes.offset {
        3
    } else {
        1
    };
    let mut gain = 0.0;
    let mut fitted = None;
    for _ in 0..rounds {
        let ys: Vec<Vec<f64>> = fitted_tests
            .iter()
            .zip(&additive)
            .map(|(t, a)| a.removed_from(t.y, fs))
            .collect();
        let cleaned: Vec<Test<'_>> = fitted_tests
            .iter()
            .zip(&ys)
            .map(|(t, y)| Test {
                name: t.name,
                u: t.u,
                y,
            })
            .collect();
        let (f, g) = fit_dynamics(changes, &cleaned, validation, fs, opts)?;
        gain = g;
        // Only an offset or a drift is estimated from what the dynamics leave.
        if changes.offset || changes.drift {
            additive = fitted_tests
                .iter()
                .zip(onsets)
                .map(|(t, &o)| {
                    let r: Vec<f64> =
                        t.y.iter()
                            .zip(simulate_nonlinear(&f.model, gain, t.u))
                            .map(|(a, b)| a - b)
                            .collect();
                    estimate_additive(changes, &r, o, fs)
                })
                .collect();
        }
        fitted = Some(f);
    }
    Ok((fitted.ok_or(EffectError::NoFit)?, additive, gain))
}

/// The options a fit with `changes` runs with: the order raised by the modes and leaks, the
/// method and delay they impose.
fn changed_options(changes: &FitChanges, options: &Options) -> Options {
    let order = match options.order {
        Order::Fixed(m) => Order::Fixed(m + changes.extra_order),
        Order::Auto { max } => Order::Auto {
            max: max + changes.extra_order,
        },
    };
    Options {
        method: changes.method.unwrap_or(options.method),
        order,
        delay: changes.delay.or(options.delay),
    }
}

/// One fit of the dynamics to the `cleaned` tests (their offset or drift removed; the first is
/// the estimation test, any others are fitted together with it): with a quadratic loss, the
/// linear part and the loss together, else the linear model (keeping the static gain found
/// for a leak, which lowers it). Returns the fit and the loss's gain (0 without one).
fn fit_dynamics(
    changes: &FitChanges,
    cleaned: &[Test<'_>],
    validation: &[Test<'_>],
    fs: f64,
    opts: &Options,
) -> Result<(Fitted, f64)> {
    let Some(est) = cleaned.first().copied() else {
        return Err(EffectError::NoEstimationTest.into());
    };
    let together = cleaned.len() > 1;
    if changes.nonlinear {
        let (mut f, mut gain) = fit_nonlinear(&est, validation, fs, opts)?;
        if together {
            gain = fit_loss_jointly(&mut f, gain, cleaned);
        }
        Ok((f, gain))
    } else {
        // A leak lowers the static gain: its model keeps the gain found.
        let mut f = if changes.leak {
            fit_with_leak(&est, validation, fs, opts)?
        } else {
            crate::fit::fit(&est, validation, fs, opts)?
        };
        if together {
            fit_linear_jointly(&mut f, cleaned, validation, !changes.leak);
        }
        Ok((f, 0.0))
    }
}

/// The `effects` with the values the fit found: the estimation test's offset or drift and the
/// loss's gain.
fn with_fitted_values(effects: &[Effect], additive: Additive, gain: f64) -> Vec<Effect> {
    effects
        .iter()
        .map(|e| match e {
            Effect::Offset { .. } => Effect::Offset {
                value: additive.offset,
            },
            Effect::Drift { .. } => Effect::Drift {
                value: additive.offset,
                rate_per_s: additive.rate_per_s,
            },
            Effect::NonlinearDamping { .. } => Effect::NonlinearDamping { gain },
            other => other.clone(),
        })
        .collect()
}

/// The tests' names, `a.csv and b.csv`, for a note.
fn listed(tests: &[Test<'_>]) -> String {
    tests
        .iter()
        .map(|t| t.name)
        .collect::<Vec<_>>()
        .join(" and ")
}

/// Errors as a note gives them: `0.184 %, 0.189 %`.
fn percents(v: &[f64]) -> String {
    v.iter()
        .map(|e| format!("{:.3} %", 100.0 * e))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The linear part and the quadratic loss of `fitted` (loss `gain`, from the estimation test
/// alone) fitted again on `tests` together, the estimation test first ([`super::joint_loss`]); the note
/// gives each test's error with the loss and with the best single linear model. Returns the
/// loss (`gain` unchanged when the joint fit cannot be made).
fn fit_loss_jointly(fitted: &mut Fitted, gain: f64, tests: &[Test<'_>]) -> f64 {
    let names = listed(tests);
    let Some((linear, joint)) = super::joint_loss(&fitted.model, tests) else {
        fitted.report.notes.push(format!(
            "the loss could not be fitted on {} together (no stable start): it is the \
             estimation test's alone",
            names
        ));
        return gain;
    };
    fitted.report.notes.push(format!(
        "the linear part and the quadratic loss were fitted on {} together (one step cannot \
         tell a quadratic loss from a linear damping): errors {} with a loss of {:.3e}{} s^2 \
         per unit, where the best single linear model leaves {}{}",
        names,
        percents(&joint.nrmse),
        joint.gain,
        joint
            .uncertainty
            .as_ref()
            .map_or_else(String::new, |(_, s)| format!(" +/- {s:.1e}")),
        percents(&linear.nrmse),
        super::rises_with_loss(
            &tests.iter().map(|t| t.name).collect::<Vec<_>>(),
            &linear.nrmse,
            &joint.nrmse
        )
        .map_or_else(String::new, |r| format!(
            "; {r}, so judge it on a further test before using it"
        ))
    ));
    fitted.nrmse_estimation = joint.nrmse.first().copied().unwrap_or(f64::NAN);
    fitted.model = joint.model;
    // The one-test fit's standard deviations are not this model's: the joint fit's, from all
    // the tests, replace them.
    fitted.report.uncertainty = joint.uncertainty.map(|(u, _)| u);
    joint.gain
}

/// The fit of a model with a leak, whose static gain the leak lowers: the DC gain found is
/// kept ([`crate::fit::fit_as_found`]) where [`crate::fit::fit`] would take it as 1, and the note
/// says so. A leak that lowers the gain by a few percent, its gain taken as 1, leaves the
/// step off by about as much, several times what the fit leaves.
fn fit_with_leak(
    est: &Test<'_>,
    validation: &[Test<'_>],
    fs: f64,
    opts: &Options,
) -> Result<Fitted> {
    let mut fitted = crate::fit::fit_as_found(est, validation, fs, opts)?;
    if crate::fit::calibration::would_calibrate(&fitted) {
        fitted.report.notes.push(format!(
            "the fitted DC gain {:.6} is kept, though the fit cannot tell it from 1: a \
             leak lowers the static gain",
            fitted.model.dc_gain()
        ));
    }
    Ok(fitted)
}

/// The model of `fitted` (from the estimation test alone) fitted again on `tests` together,
/// the estimation test first ([`super::joint_linear`]), its DC gain judged against 1 by the tests
/// together when `calibrated` (not with a leak), and its errors and uncertainty replaced by
/// the joint fit's; the note gives each test's error with the joint model and with the first
/// test's own.
fn fit_linear_jointly(
    fitted: &mut Fitted,
    tests: &[Test<'_>],
    validation: &[Test<'_>],
    calibrated: bool,
) {
    let names = listed(tests);
    let Some(joint) = super::joint_linear(&fitted.model, tests) else {
        fitted.report.notes.push(format!(
            "one model could not be fitted to {} together (no stable start): it is the \
             estimation test's alone",
            names
        ));
        return;
    };
    let alone: Vec<f64> = tests
        .iter()
        .map(|t| crate::fit::nrmse(&fitted.model, t.u, t.y))
        .collect();
    let mut model = joint.model;
    let uncertainty = joint.uncertainty.map(|(u, _)| u);
    let fitted_dc = model.dc_gain();
    let calibration = uncertainty
        .as_ref()
        .filter(|_| calibrated)
        .and_then(|u| crate::fit::calibration::calibrate(&mut model, u.dc_gain_std));
    let joint_errors: Vec<f64> = tests
        .iter()
        .map(|t| crate::fit::nrmse(&model, t.u, t.y))
        .collect();
    fitted.report.notes.push(format!(
        "one model was fitted to {} together (each test's simulation error over its range \
         counted alike): errors {}, where the estimation test's own model leaves {}",
        names,
        percents(&joint_errors),
        percents(&alone)
    ));
    match calibration {
        Some(note) => {
            fitted
                .report
                .notes
                .push(format!("with the tests together, {note}"));
            fitted.report.calibrated_from = Some(fitted_dc);
        }
        None if fitted.report.calibrated_from.is_some() => {
            fitted.report.notes.push(format!(
                "with the tests together the DC gain {fitted_dc:.6} is kept (the tests tell it \
                 from 1, or do not determine it)"
            ));
            fitted.report.calibrated_from = None;
        }
        None => {}
    }
    fitted.nrmse_estimation = joint_errors.first().copied().unwrap_or(f64::NAN);
    fitted.nrmse_validation = validation
        .iter()
        .map(|t| crate::fit::nrmse(&model, t.u, t.y))
        .collect();
    fitted.model = model;
    // The one-test fit's standard deviations are not this model's: the joint fit's, from all
    // the tests, replace them.
    fitted.report.uncertainty = uncertainty;
}

/// Fits the `coloured-noise` effect's AR model, if `effects` has one, to what the model and
/// the other effects leave on the estimation test.
fn with_noise_model(model: &Model, effects: Vec<Effect>, estimation: &Test<'_>) -> Vec<Effect> {
    if !effects
        .iter()
        .any(|e| matches!(e, Effect::ColouredNoise { .. }))
    {
        return effects;
    }
    let v = residual(model, &effects, estimation.u, estimation.y);
    let noise = crate::fit::noise::fit(&v, crate::fit::noise::MAX_RESIDUAL_ORDER);
    effects
        .into_iter()
        .map(|e| match e {
            Effect::ColouredNoise { .. } => Effect::ColouredNoise {
                ar: noise.ar.clone(),
                innovation_std: noise.innovation_std,
            },
            other => other,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step of 100 at sample 300 of 3000 and `truth`'s response to it with white noise of
    /// standard deviation `sd` (seed `seed`).
    pub(super) fn noisy_step(truth: &Model, sd: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let u: Vec<f64> = (0..3000)
            .map(|k| if k < 300 { 0.0 } else { 100.0 })
            .collect();
        let y = crate::testing::with_noise(&truth.simulate(&u), sd, seed);
        (u, y)
    }

    #[test]
    fn a_leak_keeps_the_dc_gain_the_fit_found_where_calibration_takes_it_as_one() {
        // A probe whose leak leaves 0.997 of the step, in noise (3 % of the step) through which
        // the fit cannot tell that gain from 1: the plain fit takes it as 1, the leak's keeps
        // the gain found.
        let (mut truth, _) = crate::testing::second_order(200.0, 0.3, 10_000.0, 1);
        truth.b.iter_mut().for_each(|b| *b *= 0.997);
        let (u, y) = noisy_step(&truth, 3.0, 7);
        let est = Test {
            name: "step.csv",
            u: &u,
            y: &y,
        };
        let options = Options {
            method: crate::fit::Method::Oe,
            order: Order::Fixed(2),
            delay: Some(1),
        };
        let plain = crate::fit::fit(&est, &[], 10_000.0, &options).unwrap();
        let found = plain.report.calibrated_from.unwrap();
        assert!((plain.model.dc_gain() - 1.0).abs() < 1e-12);
        let leak = fit_with_leak(&est, &[], 10_000.0, &options).unwrap();
        assert!((leak.model.dc_gain() - found).abs() < 1e-12);
        assert_eq!(leak.report.calibrated_from, None);
        assert!(leak.nrmse_estimation < plain.nrmse_estimation);
        assert!(
            leak.report.notes.iter().any(|n| n.contains("is kept"))
                && !leak.report.notes.iter().any(|n| n.contains("taken as 1")),
            "{:?}",
            leak.report.notes
        );
    }

    /// Two steps of different sizes through a probe with a quadratic loss: fitted on the first
    /// alone the loss is not identified (a linear damping explains the step), fitted on both
    /// together it is, and the fit says so.
    #[test]
    fn a_second_estimation_test_identifies_the_loss_and_needs_it() {
        let (truth, u_big, u_small, gain) = crate::testing::two_step_sizes();
        let noisy = |x: Vec<f64>, seed: u64| crate::testing::with_noise(&x, 0.5, seed);
        let y_big = noisy(simulate_nonlinear(&truth, gain, &u_big), 1);
        let y_small = noisy(simulate_nonlinear(&truth, gain, &u_small), 2);
        let big = Test {
            name: "big.csv",
            u: &u_big,
            y: &y_big,
        };
        let small = Test {
            name: "small.csv",
            u: &u_small,
            y: &y_small,
        };
        let options = Options {
            method: crate::fit::Method::Oe,
            order: Order::Fixed(2),
            delay: Some(2),
        };
        let loss = [Effect::NonlinearDamping { gain: 0.0 }];
        let fitted_gain = |fx: &[Effect]| super::super::nonlinear_gain(fx);
        let (f, fx) = fit_with_also(&big, &[small], &[], truth.fs, &options, &loss).unwrap();
        assert!(
            (fitted_gain(&fx) / gain - 1.0).abs() < 0.1,
            "{} vs {gain}",
            fitted_gain(&fx)
        );
        assert!(
            f.report
                .notes
                .iter()
                .any(|n| n.contains("big.csv and small.csv together")),
            "{:?}",
            f.report.notes
        );
        // The small step is explained to its noise (0.5 over 150) with the loss found so.
        let e = crate::fit::nrmse_of(
            &y_small,
            &simulate_nonlinear(&f.model, fitted_gain(&fx), &u_small),
        );
        assert!(e < 1.2 * 0.5 / 150.0, "{e}");
    }

    /// Two runs of the same linear probe (steps of 1000, each with its own noise): one model
    /// fitted to both finds the resonance closer to the truth than either run's own fit does,
    /// over eight noise draws, and states a smaller standard deviation for it; a second run
    /// with its own offset, fitted with the `offset` effect, is taken as it is (the offset
    /// removed from that run alone) and leaves the frequency where it was.
    #[test]
    fn runs_fitted_together_pin_the_model_down_better_than_either_alone() {
        let (truth, u, _, _) = crate::testing::two_step_sizes();
        let clean = truth.simulate(&u);
        let f0 = crate::fit::uncertainty::features(&truth).unwrap().1[0].0;
        let options = Options {
            method: crate::fit::Method::Oe,
            order: Order::Fixed(2),
            delay: Some(2),
        };
        let frequency = |f: &Fitted| {
            let r = f.report.uncertainty.as_ref().unwrap().resonances[0];
            (r.natural_frequency_hz, r.natural_frequency_std_hz)
        };
        let (mut alone, mut together, mut stated_alone, mut stated_together) = (0.0, 0.0, 0.0, 0.0);
        for seed in 0..8u64 {
            let y1 = crate::testing::with_noise(&clean, 2.0, 300 + seed);
            let y2 = crate::testing::with_noise(&clean, 2.0, 400 + seed);
            let run = |name, y| Test { name, u: &u, y };
            let (first, second) = (run("first.csv", &y1), run("second.csv", &y2));
            let (f1, _) = fit_with(&first, &[], truth.fs, &options, &[]).unwrap();
            let (f2, _) = fit_with(&second, &[], truth.fs, &options, &[]).unwrap();
            let (fj, _) = fit_with_also(&first, &[second], &[], truth.fs, &options, &[]).unwrap();
            assert!(
                fj.report
                    .notes
                    .iter()
                    .any(|n| n.contains("first.csv and second.csv together")),
                "{:?}",
                fj.report.notes
            );
            for f in [&f1, &f2] {
                alone += (frequency(f).0 - f0).powi(2) / 2.0;
                stated_alone += frequency(f).1 / 2.0;
            }
            together += (frequency(&fj).0 - f0).powi(2);
            stated_together += frequency(&fj).1;
            if seed == 0 {
                // The second run read 30 units high (its own offset): with the effect, the
                // frequency and its deviation are the ones without the offset (the offset
                // left in that run would double the deviation).
                let shifted: Vec<f64> = y2.iter().map(|v| v + 30.0).collect();
                let second = run("second.csv", &shifted);
                let offset = [Effect::Offset { value: 0.0 }];
                let (fo, _) =
                    fit_with_also(&first, &[second], &[], truth.fs, &options, &offset).unwrap();
                let (f, s) = frequency(&fj);
                let (fo, so) = frequency(&fo);
                assert!(
                    (fo - f).abs() < 0.1 * s && so < 1.1 * s,
                    "{fo} {so}, {f} {s}"
                );
            }
        }
        // Two runs halve the variance: the error and the stated deviation fall by about
        // sqrt(2), and at least by 1.2 here.
        let ratio = (alone / together).sqrt();
        assert!(ratio > 1.2, "rms error alone / together {ratio}");
        let stated = stated_alone / stated_together;
        assert!(
            (1.2..1.7).contains(&stated),
            "stated alone / together {stated}"
        );
    }
}
