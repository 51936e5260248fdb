//! The ranking: each candidate effect's signature read from the evidence and its trial run,
//! scored, and the verdict when none is offered (`none` or `unexplained`); their order is
//! [`super::order`]'s.

use super::temperature::{candidate, TrialAlone};
use super::trial::{adding, held_out, keep_delay_if_search_raises, options, trial_window, Tried};
use super::{
    amplitude_signature, creep_in_standard_errors, drift_before_step, joint_loss_evidence, mean,
    per_test, pre_step_slope, ramp_kept, ramp_returns, slope_kept, unseen_leak, AmplitudeSignature,
    Candidate, Current, Evidence, Finding, ModeEvidence, NonlinearDamping, Remedy, Spectrum,
    COLOURED_NOISE_FIT, CREEP_SETTLED_BELOW, LEAK_DC_GAIN_BELOW,
};
use crate::effects::{self, Effect, EffectKind, FitChanges};
use crate::error::Result;
use crate::evidence::TestEvidence;
use crate::fit::model::Uncertainty;
use crate::fit::{Method, Options, Test, TestRole};

/// A trial must lower the held-out error by at least this factor to be offered.
pub const MIN_IMPROVEMENT: f64 = 1.15;

/// A held-out error that falls this much in a trial overrules a noise floor that says nothing
/// is missing.
pub const FLOOR_OVERRULED: f64 = 1.4;

/// Score charged per parameter an effect adds: between two effects that explain the data
/// equally well, the simpler one ranks first (an offset before a drift, a leak before a mode).
pub const PARAMETER_PENALTY: f64 = 0.03;

/// Two peaks within this relative distance are at the same frequency.
pub const SAME_FREQUENCY: f64 = 0.15;

/// Ranks the candidates, best first, with every trial at `delay` (searched in each trial
/// when `None`); `none` alone when nothing is missing, `unexplained` when the residual is
/// above the floor and no trial lowers it. A temperature read from its trial alone needs a
/// model resonance short of critical damping unless `any_damping`
/// ([`super::TRIAL_ALONE_DAMPING_BELOW`]).
///
/// # Errors
/// Only when the current model cannot be evaluated; a trial that fails is simply not
/// offered.
pub(super) fn rank_at(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
    delay: Option<usize>,
    any_damping: bool,
) -> Result<Vec<Candidate>> {
    let fs = current.model.fs;
    let before = held_out(current.model, current.effects, tests);
    let have = FitChanges::of(current.effects);
    let base = options(current, delay);
    let Some((estimation, validation)) = tests.split_first() else {
        return Ok(Vec::new());
    };
    let estimation = &trial_window(estimation);
    let validation: &[Test<'_>] = &validation.iter().map(trial_window).collect::<Vec<_>>();
    // Each trial's held-out error and stated uncertainty, for the candidate it becomes.
    let stated: std::cell::RefCell<Vec<(f64, Option<Uncertainty>)>> = Default::default();
    // The current effects with `added` added as `unlag fit --add` adds it.
    let adding = |added: &Effect| adding(current.effects, added);
    let trial = |added: Effect, options: &Options| -> Option<Tried> {
        let with = adding(&added);
        let (fitted, fx) = effects::fit_with(estimation, validation, fs, options, &with).ok()?;
        fitted.model.check_stable("trial").ok()?;
        let tried = Tried::of(&fitted.model, fx, tests);
        stated
            .borrow_mut()
            .push((tried.after, fitted.report.uncertainty.clone()));
        Some(tried)
    };
    let floor = mean(evidence.iter().map(TestEvidence::judged_floor));
    let white = evidence.iter().all(|e| e.autocorrelation.p_value > 0.01);
    let at_floor = evidence.iter().all(TestEvidence::at_noise_floor);
    let mut out: Vec<Candidate> = Vec::new();
    // Candidates offered so far (`out` is borrowed by `offer` until the last offer).
    let offered = std::cell::Cell::new(0usize);
    let mut offer =
        |kind: EffectKind, after: f64, evidence: Evidence, reading: String, change: Remedy| {
            let ratio = before / after;
            if after.is_finite() && ratio >= MIN_IMPROVEMENT {
                offered.set(offered.get() + 1);
                out.push(Candidate {
                    uncertainty_before: current.uncertainty.cloned(),
                    uncertainty_after: stated
                        .borrow()
                        .iter()
                        .rev()
                        .find(|(e, _)| e.to_bits() == after.to_bits())
                        .and_then(|(_, u)| u.clone()),
                    ..Candidate::new(
                        Finding::Missing(kind),
                        ratio.ln() - PARAMETER_PENALTY * kind.parameters() as f64,
                        (evidence, reading),
                        change,
                        (before, after),
                    )
                });
            }
        };

    // mode: the trial (two more poles and zeros), read with the highest peak of the
    // model-error spectrum (where the measured response rises above the model's), or its rise
    // at the top of the band the noise leaves, or a residual spectrum peak.
    let peak = evidence
        .iter()
        .flat_map(|e| e.model_error.peaks.iter().map(move |p| (e, p)))
        .max_by(|a, b| a.1.above_floor_db.total_cmp(&b.1.above_floor_db));
    let edge = evidence
        .iter()
        .filter_map(|e| {
            let last = e.model_error.db.last().copied()?;
            (last > crate::evidence::MODEL_ERROR_PEAK_DB).then_some((e, last))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let residual_peak = evidence
        .iter()
        .flat_map(|e| e.spectrum.peaks.iter().map(move |p| (e, p)))
        .max_by(|a, b| a.1.above_floor_db.total_cmp(&b.1.above_floor_db));
    if let Some(Tried {
        after, effects: fx, ..
    }) = trial(Effect::Mode { near_hz: None }, &base)
    {
        let (near, ev, reading) = if let Some((e, p)) = peak {
            (
                Some(p.frequency_hz),
                Evidence::Mode(ModeEvidence::Peak {
                    spectrum: Spectrum::ModelError,
                    frequency_hz: p.frequency_hz,
                    above_floor_db: p.above_floor_db,
                    q: p.q,
                    test: e.file.clone(),
                }),
                format!(
                    "the measured response rises {:.1} dB above the model's at {:.0} Hz (Q about \
                     {:.0}): an unmodelled acoustic mode of the line or a cavity resonance",
                    p.above_floor_db, p.frequency_hz, p.q
                ),
            )
        } else if let Some((e, db)) = edge {
            let f = e.model_error.valid_to_hz;
            (
                Some(f),
                Evidence::Mode(ModeEvidence::BandEdge {
                    rise_db: db,
                    up_to_hz: f,
                    test: e.file.clone(),
                }),
                format!(
                    "the measured response rises {db:.1} dB above the model's towards {f:.0} Hz, \
                     where the noise takes over: an unmodelled mode at or above it (a higher \
                     acoustic mode of the line or a cavity resonance)"
                ),
            )
        } else if let Some((e, p)) = residual_peak {
            (
                Some(p.frequency_hz),
                Evidence::Mode(ModeEvidence::Peak {
                    spectrum: Spectrum::Residual,
                    frequency_hz: p.frequency_hz,
                    above_floor_db: p.above_floor_db,
                    q: p.q,
                    test: e.file.clone(),
                }),
                format!(
                    "a narrow residual peak at {:.0} Hz, {:.0} dB above the floor, Q about {:.0}: \
                     an unmodelled acoustic mode of the line or a cavity resonance",
                    p.frequency_hz, p.above_floor_db, p.q
                ),
            )
        } else {
            (
                None,
                Evidence::Mode(ModeEvidence::TrialOnly),
                "two more poles and zeros lower the held-out error, without a spectral peak to \
                 point at: a heavily damped extra mode"
                    .to_string(),
            )
        };
        let _ = fx;
        offer(
            EffectKind::Mode,
            after,
            ev,
            reading,
            Remedy::Add(Effect::Mode { near_hz: near }),
        );
    }

    // offset: a residual level before the step, the same after it.
    let offset = evidence
        .iter()
        .map(|e| e.trend.pre_mean / e.trend.pre_mean_se.max(1e-300))
        .fold(0.0f64, |m, z| if z.abs() > m.abs() { z } else { m });
    if offset.abs() > 5.0 && !have.offset {
        if let Some(Tried {
            after, effects: fx, ..
        }) = trial(Effect::Offset { value: 0.0 }, &base)
        {
            let value = effects::Additive::of(&fx).offset;
            offer(
                EffectKind::Offset,
                after,
                Evidence::Offset {
                    offset: value,
                    pre_step_mean_in_standard_errors: offset,
                },
                format!(
                    "the residual sits {offset:.0} standard errors off zero before the step: a zero \
                     offset of the probe against the reference ({value:.4e})"
                ),
                Remedy::Add(Effect::Offset { value: 0.0 }),
            );
        }
    }

    // drift: a ramp through the residual that runs on to the end of the record. A ramp whose
    // level comes back by then is a hump the dynamics leave after the step (a capillary's
    // slow tail after a valve step of another size: low a tenth of a second after the step,
    // back to its level before it at the end), which a line only halves: it is not offered.
    let (drift, strongest) = evidence
        .iter()
        .map(|e| {
            let t = e.samples as f64 / fs;
            let z =
                (e.trend.slope_per_s * t) / (e.noise_std / (e.samples as f64).sqrt()).max(1e-300);
            (z, Some(e))
        })
        .fold(
            (0.0f64, None),
            |m, z| if z.0.abs() > m.0.abs() { z } else { m },
        );
    let kept = strongest.and_then(|e| ramp_kept(&e.trend, e.samples, e.step_onset, fs));
    if drift.abs() > 10.0 && !have.drift && !ramp_returns(kept) {
        if let Some(Tried {
            after, effects: fx, ..
        }) = trial(
            Effect::Drift {
                value: 0.0,
                rate_per_s: 0.0,
            },
            &base,
        ) {
            let rate = effects::Additive::of(&fx).rate_per_s;
            let (pre, pre_se) = pre_step_slope(evidence);
            let before = drift_before_step(pre, pre_se, rate);
            offer(
                EffectKind::Drift,
                after,
                Evidence::Drift {
                    pre_step_slope_per_s: pre,
                    pre_step_slope_se_per_s: pre_se,
                    ramp_in_standard_errors: drift,
                    rate_per_s: rate,
                    ramp_kept_at_end: kept.map(|k| k.0),
                },
                format!("a ramp through the whole residual ({rate:.3e} per second), {before}"),
                Remedy::Add(Effect::Drift {
                    value: 0.0,
                    rate_per_s: 0.0,
                }),
            );
        }
    }

    // leak: a slow creep after the step (one more slow pole and zero).
    let creep = evidence
        .iter()
        .map(|e| (e.trend.late_mean - e.trend.pre_mean) / e.step_size.abs().max(1e-300))
        .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
    let creep_z = creep_in_standard_errors(evidence);
    // Whether it settles: read on the estimation test, a step; a held-out test of another
    // excitation (a traverse, a balloon) has no creep's shape to keep.
    let creep_slope_kept = evidence
        .iter()
        .find(|e| e.role == TestRole::Estimation)
        .and_then(|e| slope_kept(&e.trend, e.samples as f64 / fs));
    if let Some(Tried { after, .. }) = trial(Effect::Leak, &base) {
        offer(
            EffectKind::Leak,
            after,
            Evidence::Leak {
                dc_gain: current.model.dc_gain(),
                late_residual_over_step: creep,
                creep_in_standard_errors: creep_z,
                creep_slope_kept,
            },
            format!(
                "after the step the residual creeps slowly ({:+.2} % of the step at the end of the \
                 record, {creep_z:+.1} standard errors of the noise{}) and the model's DC gain is \
                 {:.4}{}: a leaking cavity or side volume, a second, slow time scale",
                100.0 * creep,
                match creep_slope_kept {
                    Some(k) if k.abs() < CREEP_SETTLED_BELOW => format!(
                        "; settled at the end, its slope there {:.2} of a line's through it",
                        k
                    ),
                    Some(k) => format!(
                        "; still running at the end, its slope there {k:.2} of a line's through \
                         it, as a sensor's drift does"
                    ),
                    None => String::new(),
                },
                current.model.dc_gain(),
                if current.model.dc_gain() < LEAK_DC_GAIN_BELOW {
                    ""
                } else {
                    " (not below 1, as a leaking volume's is: a thermal creep, or the trial \
                     fitting something else)"
                }
            ),
            Remedy::Add(Effect::Leak),
        );
    }

    // sensor-resonance: the reference rings too (a line or cavity mode never shows in the
    // reference): the transducers' own diaphragm, in both channels ([`super::sensor`]).
    let signature = super::sensor::signature(evidence);
    if let (Some(sig), None) = (signature, effects::prefilter_hz(current.effects)) {
        let added = Effect::SensorResonance {
            natural_frequency_hz: sig.reference.frequency_hz,
            prefilter_hz: 0.0,
            remedy: effects::SensorRemedy::Modes,
        };
        // The transducers' modes move the step's apparent onset: a second-order model has
        // taken its delay short to meet their rise (well short of the probe's), so the trial
        // searches the delay again as well and keeps the better of the two.
        let searched = Options {
            delay: None,
            ..base
        };
        let best = [trial(added.clone(), &base), trial(added.clone(), &searched)]
            .into_iter()
            .flatten()
            .min_by(|a, b| a.after.total_cmp(&b.after));
        if let Some(Tried { after, .. }) = best {
            offer(
                EffectKind::SensorResonance,
                after,
                Evidence::SensorResonance(sig.evidence()),
                sig.reading(),
                Remedy::Add(added),
            );
        }
    }

    // delay: a refit that searches the delay.
    let xc = evidence.first().map_or(0, |e| e.cross_correlation.peak_lag);
    let search = Options {
        delay: None,
        ..base
    };
    if have.delay.is_none() {
        if let Ok(f) = crate::fit::fit(estimation, validation, fs, &search) {
            let d = f.model.delay;
            if d != current.model.delay {
                if let Some(Tried { after, .. }) = trial(Effect::Delay { samples: d }, &base) {
                    offer(
                        EffectKind::Delay,
                        after,
                        Evidence::Delay {
                            best_delay: d,
                            model_delay: current.model.delay,
                            residual_input_xcorr_peak_lag: xc,
                        },
                        format!(
                            "the model answers {} samples {} the probe does (loss lowest at d = {d}, \
                             not {}); the residual against the input peaks at lag {xc}",
                            current.model.delay.abs_diff(d),
                            if d > current.model.delay { "before" } else { "after" },
                            current.model.delay
                        ),
                        Remedy::SetDelay { samples: d },
                    );
                }
            }
        }
    }

    // nonlinear damping: across tests, the damping rises with the step and the residual of
    // each test's own linear fit grows faster than the step.
    let mut nonlinear_tried = false;
    if !have.nonlinear && tests.len() > 1 {
        let across = per_test(current, tests, evidence);
        if let Some(sig) =
            amplitude_signature(&across).filter(AmplitudeSignature::nonlinear_damping)
        {
            nonlinear_tried = true;
            if let Some(Tried {
                after, effects: fx, ..
            }) = trial(Effect::NonlinearDamping { gain: 0.0 }, &base)
            {
                let gain = effects::nonlinear_gain(&fx);
                offer(
                    EffectKind::NonlinearDamping,
                    after,
                    Evidence::NonlinearDamping(NonlinearDamping::of(Some(&sig), true, gain, None)),
                    sig.reading(gain),
                    Remedy::Add(Effect::NonlinearDamping { gain: 0.0 }),
                );
            }
        }
    }

    // nonlinear damping from the tests fitted together: one model with a quadratic loss
    // explains tests of different sizes where no single linear model does. One step cannot
    // identify the loss (a capillary's step is explained as well with it or without, where
    // a traverse is missed by several percent), so its remedy fits on the tests together.
    let joint_from = offered.get();
    if !at_floor && !have.nonlinear && !nonlinear_tried {
        let trials: Vec<Test<'_>> = std::iter::once(*estimation)
            .chain(validation.iter().copied())
            .collect();
        let now = effects::rms(&Tried::of(current.model, current.effects.to_vec(), &trials).nrmse);
        if let Some(joint) =
            joint_loss_evidence(current, &trials).filter(|j| j.offered_against(now))
        {
            nonlinear_tried = true;
            let sig = amplitude_signature(&per_test(current, tests, evidence));
            let also = joint.tests.iter().skip(1).cloned().collect();
            offer(
                EffectKind::NonlinearDamping,
                before / joint.fall,
                Evidence::NonlinearDamping(NonlinearDamping::of(
                    sig.as_ref(),
                    false,
                    joint.gain_s2_per_unit,
                    Some(joint.clone()),
                )),
                joint.reading(),
                Remedy::AddJointly {
                    effect: Effect::NonlinearDamping { gain: 0.0 },
                    also,
                },
            );
        }
    }

    // temperature: every natural frequency of the per-test fits moves by one common factor
    // against the model's (the speed of sound, and the kinematic viscosity, changed), or,
    // where no test fitted alone can show it, the trial alone held to the floor; on any model
    // beside a loss fitted on the tests together, which it is then set against.
    let alone = match (any_damping, offered.get() > joint_from) {
        (true, _) => TrialAlone::AnyModel,
        (false, true) => TrialAlone::BesideJointLoss,
        (false, false) => TrialAlone::Resonant,
    };
    let t = candidate(
        current,
        tests,
        evidence,
        &trial,
        (&base, alone),
        before,
        at_floor,
    );
    if let Some(t) = t {
        offer(t.kind, t.after, t.evidence, t.reading, t.change);
    }

    // coloured noise: the probe's own noise coloured before a step, or correlated residuals
    // with no cause in the input.
    let p = evidence
        .iter()
        .map(|e| e.autocorrelation.p_value)
        .fold(1.0f64, f64::min);
    let input_explains = evidence
        .iter()
        .any(|e| e.cross_correlation.peak.abs() > 2.0 * e.cross_correlation.band);
    // With least squares (ARX, SM) an output-error refit is the trial, whatever the residual
    // correlates with: noise biases least squares. With output error already, the probe's own
    // noise before a step decides where a test has one: white there, the residual's colour is
    // the reference's noise through the model (errors in variables); coloured, it scatters the
    // residual's correlation with the input beyond the white band, and is itself the
    // evidence, at the floor of a simulation error too (a noise model lowers the error it
    // reports, the prediction error, and states the uncertainty right). Without one, the
    // signature must be clean (no cause in the input).
    let own = crate::fit::noise::probe_predictability(tests);
    let seen = own.is_some_and(|c| c >= MIN_IMPROVEMENT);
    let least_squares = !matches!(current.method, Method::Oe | Method::Bj);
    if seen && effects::noise_model(current.effects).is_none()
        || p < 1e-3 && (least_squares || own.is_none() && !input_explains)
    {
        let added = Effect::ColouredNoise {
            ar: Vec::new(),
            innovation_std: 0.0,
        };
        let after = trial(added, &base).map_or(f64::NAN, |t| t.after);
        let how = COLOURED_NOISE_FIT;
        let rho1 = evidence
            .first()
            .and_then(|e| e.autocorrelation.values.first().copied())
            .unwrap_or(0.0);
        offer(
            EffectKind::ColouredNoise,
            after,
            Evidence::ColouredNoise {
                fit: how.into(),
                lag1_autocorrelation: rho1,
                ljung_box_p: p,
                probe_noise_predictability: own,
            },
            format!(
                "{}{}: coloured measurement noise. The remedy is a noise model beside the \
                 dynamics ({how}: what a predictor of the probe one sample ahead cannot remove, \
                 against the simulation error before)",
                if p < 1e-3 {
                    format!(
                        "the residual is correlated in time beyond what both channels' noise \
                         through the model explains (Ljung-Box p = {p:.1e}, lag-1 correlation \
                         {rho1:.2})"
                    )
                } else {
                    "the residual is within what both channels' noise leaves".into()
                },
                own.map_or(String::new(), |c| format!(
                    ", and a predictor lowers the probe's own noise before the step {c:.2} times"
                )),
            ),
            Remedy::Add(Effect::ColouredNoise {
                ar: Vec::new(),
                innovation_std: 0.0,
            }),
        );
    }

    // nonlinear damping without its signature: when the residual is above the floor, the
    // tests may simply not show the signature (one step and an excitation that is not a step,
    // such as a traverse or a balloon). The trial alone then competes, and the reading says
    // which test would confirm it.
    if !at_floor && !have.nonlinear && !nonlinear_tried && tests.len() > 1 {
        let alone = offered.get() == 0;
        if let Some(Tried {
            after, effects: fx, ..
        }) = trial(Effect::NonlinearDamping { gain: 0.0 }, &base)
        {
            let gain = effects::nonlinear_gain(&fx);
            let sig = amplitude_signature(&per_test(current, tests, evidence));
            offer(
                EffectKind::NonlinearDamping,
                after,
                Evidence::NonlinearDamping(NonlinearDamping::of(sig.as_ref(), false, gain, None)),
                format!(
                    "{} ({:.3} % -> {:.3} %, quadratic loss {gain:.3e} s^2 per unit): \
                     amplitude-dependent losses, read from the trial alone, for these tests do \
                     not show their signature (the damping rising with the step and a linear \
                     fit's residual growing faster than it); steps of two or more sizes would \
                     confirm it",
                    if alone {
                        "no effect above lowers the held-out error, but quadratic losses do"
                    } else {
                        "quadratic losses lower the held-out error"
                    },
                    100.0 * before,
                    100.0 * after
                ),
                Remedy::Add(Effect::NonlinearDamping { gain: 0.0 }),
            );
        }
    }

    // A temperature offered beside a loss fitted on the tests together is fitted on them
    // together too (one model, each test its own time scale), so that the order can set the
    // two on one footing: the loss's dynamics are refitted on every test, the trial's are
    // the estimation test's.
    let joint_loss = out
        .iter()
        .any(|c| matches!(&c.evidence, Evidence::NonlinearDamping(n) if n.joint.is_some()));
    if joint_loss {
        for c in &mut out {
            if let (Evidence::Temperature(t), Remedy::Add(added)) = (&mut c.evidence, &c.change) {
                let with = adding(added);
                t.joint_nrmse =
                    effects::fit_with_also(estimation, validation, &[], fs, &base, &with)
                        .ok()
                        .map(|(fitted, fx)| Tried::of(&fitted.model, fx, tests).nrmse);
            }
        }
    }
    super::order::order(
        &mut out,
        current.model.dc_gain(),
        super::order::slowest_pole_hz(current.model),
    );
    // The first change as the user will make it: `unlag fit --add KIND` searches the delay
    // again; where that would raise the held-out error, the change keeps the delay.
    if have.delay.is_none() && delay.is_some() {
        if let Some(first) = out.first_mut() {
            keep_delay_if_search_raises(first, current.model.delay, |added, searched| {
                trial(
                    added.clone(),
                    &if searched {
                        Options {
                            delay: None,
                            ..base
                        }
                    } else {
                        base
                    },
                )
            });
        }
    }
    // Nothing is missing when the residual is what both channels' noise leaves (at the floor,
    // correlated only as that noise is), or at the floor with no effect's trial lowering it.
    // A residual above the floor that no effect's trial lowers is not "none": something
    // outside the catalogue is missing, and the diagnosis says so.
    //
    // A leak with neither of its signatures (the DC gain at 1, no creep after the step) that
    // nothing yields to ([`super::order`]) is no leak: its pole and zero stand for dynamics the
    // model lacks, and the diagnosis says so before it (a probe with no hidden effect whose
    // own dynamics beyond second order leave the tests above what its true model leaves is
    // otherwise named `leak` alone).
    let lone_leak = out
        .first()
        .filter(|c| unseen_leak(c, current.model.dc_gain()))
        .map(|c| (c.nrmse_before / c.nrmse_after, out.len() == 1));
    if !at_floor && (out.is_empty() || lone_leak.is_some()) {
        let worst = evidence
            .iter()
            .map(|e| e.judged_nrmse() / e.judged_floor().max(f64::MIN_POSITIVE))
            .fold(0.0f64, f64::max);
        let reading = format!(
            "the residual is up to {worst:.2}x what both channels' noise leaves{}, but {}: \
             something outside the catalogue is missing (a higher order, or physics the effects \
             do not describe); the model is not at its noise floor",
            if white {
                ""
            } else {
                " and correlated beyond that noise"
            },
            lone_leak.map_or_else(
                || format!("no effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x"),
                |(fall, alone)| format!(
                    "the {} effect whose trial lowers the held-out error ({fall:.2}x) is a \
                     leak with neither of its signatures: the DC gain is 1 and no creep stands \
                     out of the noise after the step, so its pole and zero stand for dynamics \
                     the model lacks",
                    if alone { "only" } else { "first" }
                )
            ),
        );
        let unexplained = Evidence::Unexplained {
            noise_floor: floor,
            nrmse: before,
            white,
            worst_over_floor: worst,
        };
        out.insert(
            0,
            Candidate {
                uncertainty_before: current.uncertainty.cloned(),
                ..Candidate::new(
                    Finding::Unexplained,
                    0.0,
                    (unexplained, reading),
                    Remedy::RaiseOrder,
                    (before, before),
                )
            },
        );
    }
    // A trial that cuts the error by FLOOR_OVERRULED or more shows the floor was measured too
    // high (a noisy pre-step segment): the candidates then stand.
    let best_fall = out
        .iter()
        .map(|c| c.nrmse_before / c.nrmse_after)
        .fold(0.0f64, f64::max);
    if at_floor && ((white && best_fall < FLOOR_OVERRULED) || out.is_empty()) {
        let reading = format!(
            "the residuals are consistent with noise ({}error {:.3} % against a floor of {:.3} \
             %{}); no effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x",
            if evidence.iter().any(|e| e.prediction.is_some()) {
                "one-step-ahead prediction "
            } else {
                ""
            },
            100.0 * before,
            100.0 * floor,
            if white { ", white" } else { "" }
        );
        let nothing = Evidence::Nothing {
            noise_floor: floor,
            nrmse: before,
            white,
        };
        let none = Candidate {
            uncertainty_before: current.uncertainty.cloned(),
            ..Candidate::new(
                Finding::Nothing,
                0.0,
                (nothing, reading),
                Remedy::Nothing,
                (before, before),
            )
        };
        out.insert(0, none);
    }
    super::order::set_margins(&mut out);
    Ok(out)
}
