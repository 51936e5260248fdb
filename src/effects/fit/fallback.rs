//! The second looks a fit with effects takes at its own result, each tried by a refit and kept,
//! with a note, only where it explains the estimation test as well: a model that a
//! temperature cannot scale, a real pole slower than the record, an offset before the step,
//! and (for `unlag fit` alone) a pole on the unit circle.

use super::super::additive::additive_rate;
use super::super::{temperature_law, Additive, Effect};
use super::fit_with_also;
use crate::error::Result;
use crate::fit::continuous::Continuous;
use crate::fit::model::Model;
use crate::fit::{Fitted, Options, Order, Test};

/// [`fit_with_also`] as `unlag fit` makes it: a fit that leaves a pole on the unit circle at
/// every delay has taken a creep for an integrator, and is refused as unstable. Unless the
/// user asked for a leak or a drift, the drift is then read (as for a pole slower than the
/// record), else one order fewer is fitted, each with a note. (The diagnosis' trials do not
/// go past the refusal: a trial that cannot be fitted is not offered.)
///
/// # Errors
/// As [`super::fit_with`].
pub fn fit_with_also_reading_creep(
    estimation: &Test<'_>,
    also: &[Test<'_>],
    validation: &[Test<'_>],
    fs: f64,
    options: &Options,
    effects: &[Effect],
) -> Result<(Fitted, Vec<Effect>)> {
    let fitted = fit_with_also(estimation, also, validation, fs, options, effects);
    let Err(crate::error::Error::UnstableModel { pole, .. }) = &fitted else {
        return fitted;
    };
    // A drifting capillary's second-order fit can put a pole on z = 1, the drift taken for an
    // integrator, and the loop could not start; with the drift read it fits to its floor.
    if effects
        .iter()
        .any(|e| matches!(e, Effect::Leak | Effect::Drift { .. }))
    {
        return fitted;
    }
    let refit = |options: &Options, effects: &[Effect]| {
        fit_with_also_reading_creep(estimation, also, validation, fs, options, effects)
    };
    let mut with_drift = effects.to_vec();
    with_drift.push(Effect::Drift {
        value: 0.0,
        rate_per_s: 0.0,
    });
    // Kept only where the drift resolves the creep: a model that still has a pole slower than
    // the record has spent a pole-zero pair on it, whichever side of the circle rounding put
    // the pole, and goes one order down as such a pole does ([`second_looks`]).
    let onset = crate::fit::step::find_step(estimation.u).map_or(0, |s| s.onset);
    let after_step = estimation.y.len().saturating_sub(onset) as f64;
    if let Ok((mut f, fx)) = refit(options, &with_drift) {
        if slower_than(&f.model, after_step).is_none() {
            f.report.notes.push(format!(
                "the fit left a pole on the unit circle ({pole}): a creep the record cannot tell from an integrator, read as a drift of {:.4e} per second (a drift is removed before compensation, never inverted)",
                additive_rate(&fx)
            ));
            return Ok((f, fx));
        }
    }
    if let Order::Fixed(m) = options.order {
        if m > 1 {
            let o = Options {
                order: Order::Fixed(m - 1),
                ..*options
            };
            if let Ok((mut f, fx)) = refit(&o, effects) {
                f.report.notes.push(format!(
                    "order {m} left a pole on the unit circle ({pole}) at every delay, with a drift too; order {} was kept",
                    m - 1
                ));
                return Ok((f, fx));
            }
        }
    }
    fitted
}

/// A fit with effects as it first comes out, and what its second looks need.
pub(super) struct First<'a> {
    /// The fit.
    pub fitted: Fitted,
    /// The effects with their fitted parameters.
    pub out: Vec<Effect>,
    /// The effects asked for (resolved on the estimation test), which a refit is given.
    pub effects: &'a [Effect],
    /// The options as the user gave them: a refit changes one thing in them.
    pub options: &'a Options,
    /// The delay was searched: neither the user nor an effect gave it.
    pub delay_searched: bool,
    /// The order the effects add to the one asked for (a mode's two, a leak's one).
    pub extra_order: usize,
    /// The estimation test as fitted (prefiltered below a sensor resonance).
    pub estimation: Test<'a>,
    /// Its step onset.
    pub onset: usize,
    /// The sample rate in Hz.
    pub fs: f64,
}

/// The same fit with other options or effects, on the same tests.
pub(super) type Refit<'r> = &'r dyn Fn(&Options, &[Effect]) -> Result<(Fitted, Vec<Effect>)>;

/// `first`, or the refit one of its second looks keeps: a model a temperature can scale, a
/// slow pole read as a drift, an offset read before the step, or a slow pole's order one
/// fewer, tried in that order.
///
/// # Errors
/// None of its own: a refit that fails is not kept.
pub(super) fn second_looks(first: First<'_>, refit: Refit<'_>) -> Result<(Fitted, Vec<Effect>)> {
    let First {
        mut fitted,
        out,
        effects,
        options,
        delay_searched,
        extra_order,
        estimation,
        onset,
        fs,
    } = first;
    if temperature_law(&out).is_some() && delay_searched {
        if let Some(kept) = scalable(&mut fitted, effects, options, extra_order, refit) {
            return Ok(kept);
        }
    }
    // A real pole slower than the record is not resolved by it: a drift makes the same
    // creep, and a near-integrator pole-zero pair inverts it into a runaway. Unless the user
    // asked for a leak or a drift, try the drift and keep it when it explains the estimation
    // test as well (within 10 %) with the dynamics it leaves.
    let asked = effects
        .iter()
        .any(|e| matches!(e, Effect::Leak | Effect::Drift { .. }));
    let after_step = estimation.y.len().saturating_sub(onset) as f64;
    let slow = slower_than(&fitted.model, after_step).filter(|_| !asked);
    if let Some(tau) = slow {
        let mut with_drift = out.clone();
        with_drift.push(Effect::Drift {
            value: 0.0,
            rate_per_s: 0.0,
        });
        if let Ok((mut f, fx)) = refit(options, &with_drift) {
            let still_slow = slower_than(&f.model, after_step).is_some();
            if !still_slow && f.nrmse_estimation <= 1.1 * fitted.nrmse_estimation {
                f.report.notes.push(format!(
                    "a real pole with time constant {:.4} s, longer than the {:.4} s after the step, was read as a drift of {:.4e} per second (a drift is removed before compensation, never inverted): adding the `leak` effect keeps it as dynamics",
                    tau / fs,
                    after_step / fs,
                    additive_rate(&fx)
                ));
                return Ok((f, fx));
            }
        }
    }
    // An offset is the probe's, not the pressure's: unless the user asked for an additive
    // effect, one that the quiet segment before the step shows clearly is removed before the
    // fit and kept when the fit explains the test better without it.
    let additive_asked = effects
        .iter()
        .any(|e| matches!(e, Effect::Offset { .. } | Effect::Drift { .. }));
    if !additive_asked {
        if let Some(level) = pre_step_offset(&fitted.model, &estimation, onset) {
            let mut with_offset = out.clone();
            with_offset.push(Effect::Offset { value: 0.0 });
            if let Ok((mut f, fx)) = refit(options, &with_offset) {
                if f.nrmse_estimation <= OFFSET_GAIN * fitted.nrmse_estimation {
                    f.report.notes.push(format!(
                        "the probe read {level:.4e} off the model before the step: read as an offset of {:.4e} (the probe's, removed before compensation, never inverted), which brings the estimation error from {:.3} % to {:.3} %",
                        Additive::of(&fx).offset,
                        100.0 * fitted.nrmse_estimation,
                        100.0 * f.nrmse_estimation
                    ));
                    return Ok((f, fx));
                }
            }
        }
    }
    if let Some(tau) = slow {
        // The slow pole can be a spare one, all but cancelled by a zero beside it: a probe
        // whose record shows one corner after its delay spends its second pole on the creep
        // or the coloured noise, and the pair's DC gain is then theirs, not the probe's (a pole
        // and a zero a hair from z = 1 can set a DC gain of tens of thousands, which a held-out
        // test's level turns into an absurd error). One order fewer
        // (the delay searched again unless the user gave it), with the offset the fit reads
        // itself, is kept when it explains the estimation test as well, within 10 %, as the
        // order asked for with its own offset (which comes back here through the refit above).
        let fitted_order = fitted.model.order().saturating_sub(extra_order);
        if fitted_order > 1 {
            let o = Options {
                order: Order::Fixed(fitted_order - 1),
                ..*options
            };
            if let Ok((mut f, fx)) = refit(&o, effects) {
                if slower_than(&f.model, after_step).is_none()
                    && f.nrmse_estimation <= 1.1 * fitted.nrmse_estimation
                {
                    f.report.notes.push(format!(
                        "order {fitted_order} left a real pole with time constant {:.4} s, longer than the {:.4} s after the step, which the record cannot resolve (its DC gain was {:.4}); order {} explains the estimation test as well ({:.3} % against {:.3} %) and was kept",
                        tau / fs,
                        after_step / fs,
                        fitted.model.dc_gain(),
                        fitted_order - 1,
                        100.0 * f.nrmse_estimation,
                        100.0 * fitted.nrmse_estimation
                    ));
                    return Ok((f, fx));
                }
            }
        }
    }
    Ok((fitted, out))
}

/// A model that a temperature can scale, where `fitted`'s cannot: a pole on the negative real
/// axis has no continuous-time equivalent. Smaller delays, then lower orders, are tried; the
/// first that explains the estimation test as well is returned. Otherwise `fitted` gets a
/// note that the temperature cannot scale it.
fn scalable(
    fitted: &mut Fitted,
    effects: &[Effect],
    options: &Options,
    extra_order: usize,
    refit: Refit<'_>,
) -> Option<(Fitted, Vec<Effect>)> {
    // A temperature scales the model through its continuous-time equivalent, which a pole on
    // the negative real axis does not have: it rings at Nyquist, a sampling artefact where a
    // searched delay took one sample too many from a fast corner (on a capillary, neighbouring
    // delays can fit within a fraction of a percent, and the largest is taken). The next
    // smaller delays are tried, then lower orders (below), and the first whose model has one
    // is kept when it explains the estimation test as well (within 10 %); otherwise the fit
    // says that the temperature cannot scale it.
    if Continuous::from_model(&fitted.model).is_ok() {
        return None;
    }
    let d = fitted.model.delay;
    let lowest = d.saturating_sub(MAX_DELAY_BACKOFF);
    let delays = (lowest..d).rev().map(|fewer| {
        let o = Options {
            delay: Some(fewer),
            ..*options
        };
        let kept = format!(
            "the delay {d} the search found left a pole on the negative real axis, which a \
             temperature cannot scale (no continuous-time equivalent); delay {fewer}"
        );
        (o, kept)
    });
    // The pole on the negative real axis can be a spare one: an overdamped probe whose
    // record shows one corner (a capillary) spends the second pole on the noise, and the
    // lower order explains the estimation test just as well. One order fewer, the delay
    // searched again, then explains the test as well and can be scaled (and the held-out
    // error falls to its floor).
    let asked = fitted.model.order().saturating_sub(extra_order);
    let orders = (1..asked).rev().map(|fewer| {
        let o = Options {
            order: Order::Fixed(fewer),
            delay: None,
            ..*options
        };
        let kept = format!(
            "order {asked} left a pole on the negative real axis, which a temperature \
             cannot scale (no continuous-time equivalent), at every delay from {d} down to \
             {lowest}; order {fewer}"
        );
        (o, kept)
    });
    for (o, kept) in delays.chain(orders) {
        if let Ok((mut f, fx)) = refit(&o, effects) {
            if Continuous::from_model(&f.model).is_ok()
                && f.nrmse_estimation <= 1.1 * fitted.nrmse_estimation
            {
                f.report.notes.push(format!(
                    "{kept} explains the estimation test as well ({:.3} % against {:.3} %) \
                     and was kept",
                    100.0 * f.nrmse_estimation,
                    100.0 * fitted.nrmse_estimation
                ));
                return Some((f, fx));
            }
        }
    }
    fitted.report.notes.push(format!(
        "the temperature effect cannot scale this model: a pole on the negative real axis \
         has no continuous-time equivalent, and no smaller delay (down to {}) nor lower \
         order explains the estimation test as well without one; its predictions at other \
         temperatures are the reference's (refit with another --order or --delay)",
        lowest
    ));
    None
}

/// Most samples below a searched delay tried for a model that a temperature can scale.
const MAX_DELAY_BACKOFF: usize = 8;

/// The time constant, in samples, of `model`'s real pole slower than `samples` (a record
/// `samples` long cannot resolve it), if it has one.
fn slower_than(model: &Model, samples: f64) -> Option<f64> {
    model.poles().ok().and_then(|poles| {
        poles
            .iter()
            .filter(|p| p.im.abs() < 1e-9 && p.re > 0.0 && p.re < 1.0)
            .map(|p| -1.0 / p.re.ln())
            .find(|tau| *tau > samples)
    })
}

/// An offset found before the step is kept only when the fit without it explains the
/// estimation test at least this much better (its error over the error with it in).
const OFFSET_GAIN: f64 = 0.9;

/// The mean of what `model` leaves of the probe signal before the step, when the quiet
/// segment (at least [`crate::fit::step::MIN_QUIET`] samples) shows it clearly:
/// five standard errors from zero (its independent samples counted as a correlated noise
/// leaves them), and at least half the segment's noise.
fn pre_step_offset(model: &Model, test: &Test<'_>, onset: usize) -> Option<f64> {
    if onset < crate::fit::step::MIN_QUIET {
        return None;
    }
    let simulated = model.simulate(test.u.get(..onset)?);
    let r: Vec<f64> = test
        .y
        .get(..onset)?
        .iter()
        .zip(&simulated)
        .map(|(y, s)| y - s)
        .collect();
    let n = r.len() as f64;
    let mean = r.iter().sum::<f64>() / n;
    let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    // Correlated noise (a slow wander) moves a segment's mean further than white noise does:
    // its standard error counts the independent samples, n (1 - rho) / (1 + rho).
    let rho = if var > 0.0 {
        (r.iter()
            .zip(r.iter().skip(1))
            .map(|(a, b)| (a - mean) * (b - mean))
            .sum::<f64>()
            / ((n - 1.0) * var))
            .clamp(0.0, 0.999)
    } else {
        0.0
    };
    let independent = (n * (1.0 - rho) / (1.0 + rho)).max(1.0);
    let std = var.sqrt();
    (mean.abs() > 5.0 * std / independent.sqrt() && mean.abs() > 0.5 * std).then_some(mean)
}

#[cfg(test)]
mod tests {
    use super::super::fit_with;
    use super::super::tests::noisy_step;
    use super::*;

    #[test]
    fn a_pre_step_offset_must_stand_out_of_the_noise_as_it_is_correlated() {
        let model = Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.5],
            b: vec![0.5],
        };
        let u = vec![0.0; 400];
        let white = crate::testing::gaussian(400, 5);
        let test = |y: &[f64]| -> Option<f64> {
            pre_step_offset(
                &model,
                &Test {
                    name: "t",
                    u: &u,
                    y,
                },
                400,
            )
        };
        // White noise of 0.01 about 0.01: found.
        let shifted: Vec<f64> = white.iter().map(|n| 0.01 + 0.01 * n).collect();
        let found = test(&shifted).unwrap();
        assert!((found - 0.01).abs() < 0.002, "{found}");
        // The same noise about zero: nothing.
        let still: Vec<f64> = white.iter().map(|n| 0.01 * n).collect();
        assert_eq!(test(&still), None);
        // A slow wander (AR(1), pole 0.98) whose mean over the segment is off zero by a
        // fraction of its spread: a white-noise standard error would call it an offset.
        let mut v = 0.0;
        let wander: Vec<f64> = white
            .iter()
            .map(|n| {
                v = 0.98 * v + 0.01 * n;
                v
            })
            .collect();
        let mean = wander.iter().sum::<f64>() / 400.0;
        let std = (wander.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 399.0).sqrt();
        assert!(mean.abs() > 5.0 * std / 20.0, "{mean} {std}");
        assert_eq!(test(&wander), None);
    }

    #[test]
    fn a_spare_pole_on_the_negative_real_axis_steps_the_order_down_for_a_temperature() {
        // A one-corner probe (pole 0.99) behind a sample-rate wobble (a pole at -0.3, unit
        // static gain): at order 2 the fit finds the wobble, which has no continuous-time
        // equivalent, so no temperature can scale that model. The wobble is under the noise:
        // order 1 explains the step as well, can be scaled, and is kept with a note.
        let fs = 1000.0;
        let truth = Model {
            fs,
            delay: 2,
            a: vec![-0.99 + 0.3, -0.99 * 0.3],
            b: vec![0.01 * 1.3, 0.0, 0.0],
        };
        let (u, y) = noisy_step(&truth, 0.3, 11);
        let est = Test {
            name: "step.csv",
            u: &u,
            y: &y,
        };
        let options = Options {
            method: crate::fit::Method::Oe,
            order: Order::Fixed(2),
            delay: None,
        };
        let plain = crate::fit::fit(&est, &[], fs, &options).unwrap();
        assert!(
            Continuous::from_model(&plain.model).is_err(),
            "{:?}",
            plain.model.poles()
        );
        let warm = [Effect::Temperature {
            reference_k: 293.15,
            damping: crate::effects::TemperatureDamping::Diffusive,
        }];
        let (fitted, _) = fit_with(&est, &[], fs, &options, &warm).unwrap();
        assert_eq!(fitted.model.order(), 1);
        assert!(Continuous::from_model(&fitted.model).is_ok());
        assert!(fitted.nrmse_estimation <= 1.1 * plain.nrmse_estimation);
        assert!(
            fitted
                .report
                .notes
                .iter()
                .any(|n| n.contains("order 1 explains")),
            "{:?}",
            fitted.report.notes
        );
    }

    #[test]
    fn a_real_pole_is_slower_than_a_record_it_outlasts() {
        // Poles 0.999 (a time constant of 999.5 samples) and 0.5; a complex pair of radius
        // 0.9999 rings, it does not creep, and is never read as slow.
        let model = |a: Vec<f64>| Model {
            fs: 1000.0,
            delay: 0,
            b: vec![1.0 + a.iter().sum::<f64>()],
            a,
        };
        let real = model(vec![-1.499, 0.4995]);
        let tau = slower_than(&real, 500.0).expect("the slow pole");
        assert!((tau - 999.5).abs() < 0.5, "{tau}");
        assert_eq!(slower_than(&real, 2000.0), None);
        let r: f64 = 0.9999;
        let ringing = model(vec![-2.0 * r * 0.3f64.cos(), r * r]);
        assert_eq!(slower_than(&ringing, 500.0), None);
    }
}
