//! Each candidate effect: its signature read from the evidence, its trial run, and what is
//! offered ([`Offer`]) when the signature gates it in; [`super::Ranking::offer`] keeps it when
//! the trial lowers the held-out error enough.

use super::super::temperature::Offer;
use super::super::trial::Tried;
use super::super::{
    amplitude_signature, creep_in_standard_errors, drift_before_step, joint_loss_evidence,
    leak_shown, pre_step_slope, ramp_kept, ramp_returns, slope_kept, AmplitudeSignature, Evidence,
    ModeEvidence, NonlinearDamping, Remedy, Spectrum, COLOURED_NOISE_FIT, CREEP_SETTLED_BELOW,
    LEAK_DC_GAIN_BELOW,
};
use super::{Ranking, MIN_IMPROVEMENT};
use crate::effects::{self, Effect, EffectKind};
use crate::fit::{Method, Options, Test, TestRole};

/// What a candidate offers.
fn offer(
    kind: EffectKind,
    after: f64,
    evidence: Evidence,
    reading: String,
    change: Remedy,
) -> Option<Offer> {
    Some(Offer {
        kind,
        after,
        evidence,
        reading,
        change,
    })
}

impl Ranking<'_> {
    /// A mode: the trial (two more poles and zeros), read with the highest peak of the model-error
    /// spectrum (where the measured response rises above the model's), or its rise at the top of
    /// the band the noise leaves, or a residual spectrum peak.
    pub(super) fn mode(&self) -> Option<Offer> {
        let evidence = self.evidence;
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
        if let Some(Tried { after, .. }) = self.trial(Effect::Mode { near_hz: None }, &self.base) {
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
            return offer(
                EffectKind::Mode,
                after,
                ev,
                reading,
                Remedy::Add(Effect::Mode { near_hz: near }),
            );
        }
        None
    }

    /// An offset: a residual level before the step, the same after it.
    pub(super) fn offset(&self) -> Option<Offer> {
        let evidence = self.evidence;
        let have = self.have;
        let offset = evidence
            .iter()
            .map(|e| e.trend.pre_mean / e.trend.pre_mean_se.max(1e-300))
            .fold(0.0f64, |m, z| if z.abs() > m.abs() { z } else { m });
        if offset.abs() > 5.0 && !have.offset {
            if let Some(Tried {
                after, effects: fx, ..
            }) = self.trial(Effect::Offset { value: 0.0 }, &self.base)
            {
                let value = effects::Additive::of(&fx).offset;
                return offer(
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
        None
    }

    /// A drift: a ramp through the residual that runs on to the end of the record. A ramp whose
    /// level comes back by then is a hump the dynamics leave after the step (a capillary's slow
    /// tail after a valve step of another size: low a tenth of a second after the step, back to
    /// its level before it at the end), which a line only halves: it is not offered.
    pub(super) fn drift(&self) -> Option<Offer> {
        let (evidence, fs, have) = (self.evidence, self.fs(), self.have);
        let (drift, strongest) = evidence
            .iter()
            .map(|e| {
                let t = e.samples as f64 / fs;
                let z = (e.trend.slope_per_s * t)
                    / (e.noise_std / (e.samples as f64).sqrt()).max(1e-300);
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
            }) = self.trial(
                Effect::Drift {
                    value: 0.0,
                    rate_per_s: 0.0,
                },
                &self.base,
            ) {
                let rate = effects::Additive::of(&fx).rate_per_s;
                let (pre, pre_se) = pre_step_slope(evidence);
                let before = drift_before_step(pre, pre_se, rate);
                return offer(
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
        None
    }

    /// A leak: a slow creep after the step (one more slow pole and zero).
    pub(super) fn leak(&self) -> Option<Offer> {
        let (current, evidence, fs) = (self.current, self.evidence, self.fs());
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
        if !leak_shown(current.model.dc_gain(), creep_z, creep_slope_kept) {
            return None;
        }
        if let Some(Tried { after, .. }) = self.trial(Effect::Leak, &self.base) {
            return offer(
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
                        " (not below 1, as a leaking volume's is: a thermal creep, which settles)"
                    }
                ),
                Remedy::Add(Effect::Leak),
            );
        }
        None
    }

    /// A sensor resonance: the reference rings too (a line or cavity mode never shows in the
    /// reference): the transducers' own diaphragm, in both channels ([`super::super::sensor`]).
    pub(super) fn sensor_resonance(&self) -> Option<Offer> {
        let (current, evidence) = (self.current, self.evidence);
        let signature = super::super::sensor::signature(evidence);
        if let (Some(sig), None) = (signature, effects::prefilter_hz(current.effects)) {
            let added = Effect::SensorResonance {
                natural_frequency_hz: sig.reference.frequency_hz,
                prefilter_hz: 0.0,
                remedy: effects::SensorRemedy::Modes,
            };
            // The transducers' modes move the step's apparent onset: a second-order model has
            // taken its delay short to meet their rise (well short of the probe's), so the trial
            // searches the delay again as well and keeps the better of the two.
            let best = [
                self.trial_searching(added.clone(), false),
                self.trial_searching(added.clone(), true),
            ]
            .into_iter()
            .flatten()
            .min_by(|a, b| a.after.total_cmp(&b.after));
            if let Some(Tried { after, .. }) = best {
                return offer(
                    EffectKind::SensorResonance,
                    after,
                    Evidence::SensorResonance(sig.evidence()),
                    sig.reading(),
                    Remedy::Add(added),
                );
            }
        }
        None
    }

    /// The delay: a refit that searches the delay.
    pub(super) fn delay(&self) -> Option<Offer> {
        let (current, evidence, fs, have) = (self.current, self.evidence, self.fs(), self.have);
        let (estimation, validation) = (&self.estimation, &self.validation[..]);
        let xc = evidence.first().map_or(0, |e| e.cross_correlation.peak_lag);
        let search = Options {
            delay: None,
            ..self.base
        };
        if have.delay.is_none() {
            if let Ok(f) = crate::fit::fit(estimation, validation, fs, &search) {
                let d = f.model.delay;
                if d != current.model.delay {
                    if let Some(Tried { after, .. }) =
                        self.trial(Effect::Delay { samples: d }, &self.base)
                    {
                        return offer(
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
        None
    }

    /// Coloured noise: the probe's own noise coloured before a step, or correlated residuals with
    /// no cause in the input.
    pub(super) fn coloured_noise(&self) -> Option<Offer> {
        let (current, tests, evidence) = (self.current, self.tests, self.evidence);
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
            let after = self.trial(added, &self.base).map_or(f64::NAN, |t| t.after);
            let how = COLOURED_NOISE_FIT;
            let rho1 = evidence
                .first()
                .and_then(|e| e.autocorrelation.values.first().copied())
                .unwrap_or(0.0);
            return offer(
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
        None
    }

    /// Nonlinear damping: across tests, the damping rises with the step and the residual of
    /// each test's own linear fit grows faster than the step; and whether its trial was run.
    pub(super) fn nonlinear_damping_by_amplitude(&self) -> (Option<Offer>, bool) {
        if self.have.nonlinear || self.tests.len() <= 1 {
            return (None, false);
        }
        let Some(sig) =
            amplitude_signature(self.per_test()).filter(AmplitudeSignature::nonlinear_damping)
        else {
            return (None, false);
        };
        let found = self
            .trial(Effect::NonlinearDamping { gain: 0.0 }, &self.base)
            .and_then(
                |Tried {
                     effects: fx, after, ..
                 }| {
                    let gain = effects::nonlinear_gain(&fx);
                    offer(
                        EffectKind::NonlinearDamping,
                        after,
                        Evidence::NonlinearDamping(NonlinearDamping::of(
                            Some(&sig),
                            true,
                            gain,
                            None,
                        )),
                        sig.reading(gain),
                        Remedy::Add(Effect::NonlinearDamping { gain: 0.0 }),
                    )
                },
            );
        (found, true)
    }

    /// Nonlinear damping from the tests fitted together: one model with a quadratic loss
    /// explains tests of different sizes where no single linear model does. One step cannot
    /// identify the loss (a capillary's step is explained as well with it or without, where a
    /// traverse is missed by several percent), so its remedy fits on the tests together. Also
    /// whether such a loss was found.
    pub(super) fn nonlinear_damping_jointly(&self) -> (Option<Offer>, bool) {
        let current = self.current;
        if self.at_floor || self.have.nonlinear {
            return (None, false);
        }
        let trials: Vec<Test<'_>> = std::iter::once(self.estimation)
            .chain(self.validation.iter().copied())
            .collect();
        let now = effects::rms(&Tried::of(current.model, current.effects.to_vec(), &trials).nrmse);
        let Some(joint) = joint_loss_evidence(current, &trials).filter(|j| j.offered_against(now))
        else {
            return (None, false);
        };
        let sig = amplitude_signature(self.per_test());
        let also = joint.tests.iter().skip(1).cloned().collect();
        let found = offer(
            EffectKind::NonlinearDamping,
            self.before / joint.fall,
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
        (found, true)
    }

    /// Nonlinear damping without its signature: when the residual is above the floor, the
    /// tests may simply not show the signature (one step and an excitation that is not a step,
    /// such as a traverse or a balloon). The trial alone then competes, and the reading says
    /// which test would confirm it.
    pub(super) fn nonlinear_damping_from_trial_alone(&self) -> Option<Offer> {
        let before = self.before;
        if self.at_floor || self.have.nonlinear || self.tests.len() <= 1 {
            return None;
        }
        let alone = self.offered() == 0;
        let Tried {
            after, effects: fx, ..
        } = self.trial(Effect::NonlinearDamping { gain: 0.0 }, &self.base)?;
        let gain = effects::nonlinear_gain(&fx);
        let sig = amplitude_signature(self.per_test());
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
        )
    }
}
