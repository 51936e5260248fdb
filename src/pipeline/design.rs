//! The compensator's design: what is asked ([`CompensatorSpec`]), which tests it learns from and
//! is judged on ([`Roles`]), and the one sequence every compensator goes through (the design,
//! the sensor-resonance prefilter in front, the fixed-point plans), for a design on tests
//! ([`design_compensator`]) and for a stored design redone on a rescaled model ([`retarget`]).

use crate::design::inverse::check::{self, Request};
use crate::design::inverse::optimal::{self, NoiseModel, OptimalOptions, SignalPrior};
use crate::design::inverse::{self, Design, LowpassKind};
use crate::design::quantise::{DirectPlan, FixedForm, FixedPlan};
use crate::effects::{self, Effect};
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit::model::Model;
use crate::fit::{self, Test};
use crate::trace::Trace;

/// The shape of compensator asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// The noise-aware optimum ([`optimal::design`]), from the noise measured on the tests and
    /// the signal prior learnt from them (or from [`CompensatorSpec::signal`]).
    Optimal {
        /// Longest latency of `u_hat` behind the true pressure, in samples (the model's delay
        /// included).
        max_latency_samples: Option<usize>,
        /// Largest -3 dB band (Hz).
        max_band_hz: Option<f64>,
    },
    /// A stable (or, without `stabilise`, the paper's direct) inverse times a low-pass.
    BandLimited {
        /// The low-pass corner (Hz); `None` chooses the one that reconstructs the tests'
        /// references best.
        bandwidth_hz: Option<f64>,
        /// Reflect the unstable zeros instead of inverting them as they are.
        stabilise: bool,
    },
}

/// What the user asks of a compensator designed on tests (`unlag fit`, `unlag invert`).
#[derive(Debug, Clone)]
pub struct CompensatorSpec {
    /// Optimum or band-limited inverse.
    pub shape: Shape,
    /// The low-pass family of the band limit.
    pub lowpass: LowpassKind,
    /// Its order.
    pub lowpass_order: usize,
    /// The user's own recorded runs to learn the optimum's signal prior from, instead of the
    /// tests (`--signal`).
    pub signal: Vec<Trace>,
    /// The fixed-point form to plan.
    pub fixed_form: FixedForm,
    /// The ADC's full scale in the probe's units; `None` takes [`default_full_scale`] of the
    /// tests the design is judged on.
    pub full_scale: Option<f64>,
}

/// Which tests a design learns from and which it is judged on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Roles {
    /// A fit's tests, its `estimation` tests first (the model was fitted on them): the noise
    /// and the prior are learnt from them and from the held-out tests that are clean steps (a
    /// quiet segment before the step); the check judges on the held-out tests, or on the
    /// estimation tests when there are none. A held-out run of another kind (a balloon, a
    /// traverse) is judged on, not learnt from: a compensator learnt from the very run it is
    /// checked on passes its own check.
    Fit {
        /// How many of the tests, from the first, the model was fitted on (at least 1).
        estimation: usize,
    },
    /// Every test alike, learnt from and judged on (`unlag invert`).
    Alike,
}

/// A compensator for a model, designed on tests.
#[derive(Debug, Clone, Copy)]
pub struct CompensatorRequest<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its effects: a sensor resonance's prefilter runs in front of the compensator (and the
    /// design is made and judged on prefiltered tests), a nonlinear damping's correction is
    /// judged with it, a noise model colours the measured noise.
    pub effects: &'a [Effect],
    /// The tests with a reference, as recorded (not prefiltered).
    pub tests: &'a [Test<'a>],
    /// What the tests are to the design.
    pub roles: Roles,
    /// The model file's stored design, whose noise and prior stand in where there are no
    /// tests to measure them on.
    pub stored: Option<&'a Design>,
    /// What is asked.
    pub spec: &'a CompensatorSpec,
    /// Refuse, before planning it in fixed point, a design the board cannot run
    /// ([`Design::check_exportable`]).
    pub exportable: bool,
}

/// A designed compensator, and what could not be made of it.
#[derive(Debug)]
pub struct Compensator {
    /// The design, with the prefilter in front and its fixed-point plan; or why none could be
    /// made (a fit stands without one, `unlag invert` fails).
    pub design: Result<Design>,
    /// The fixed-point plans that could not be made, and why: the f32 compensator does not
    /// depend on them.
    pub unplanned: Vec<Error>,
    /// The full scale the fixed-point plan was made for, and where it came from.
    pub full_scale: FullScale,
}

/// Swings of the tests' probe signal, beyond their largest `|y|`, that the default full scale
/// leaves room for ([`default_full_scale`]).
pub const DEFAULT_FULL_SCALE_SWINGS: f64 = 3.0;

/// The full scale a fixed-point plan was made for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullScale {
    /// In the probe's units: readings within `+-value` are never clamped.
    pub value: f64,
    /// Stated by the user (the ADC's range), rather than [`default_full_scale`].
    pub stated: bool,
    /// The largest `|y|` of the tests it was chosen on (0 without tests).
    pub tests_peak: f64,
}

impl FullScale {
    /// The bits of the fixed-point input range the tests leave unused: `log2(value /
    /// tests_peak)`, the resolution the room above them costs (0 when no test moved).
    #[must_use]
    pub fn unused_bits(&self) -> f64 {
        if self.tests_peak > 0.0 {
            (self.value / self.tests_peak).log2().max(0.0)
        } else {
            0.0
        }
    }
}

/// The full scale a design takes when the ADC's range is not stated: the tests' largest `|y|`
/// plus [`DEFAULT_FULL_SCALE_SWINGS`] times their swing (largest minus smallest `y`), rounded
/// up to 1, 2 or 5 times a power of ten; 1 when the tests do not move.
///
/// The room is for the runs made after a step-test calibration, which a step test does not
/// show: a shock tube's reflected shock brings the pressure to 2 to 2.6 times the incident
/// step, a burst balloon overshoots, a turbulent run wanders above its mean, and a ringing
/// probe overshoots each of them by as much as it overshot the step. Three swings above the
/// tests' peak hold a reflected shock of 2.6 times the step with 15 % more overshoot than the
/// step showed, and a step of twice the size and the opposite sign. What it costs is
/// resolution, [`FullScale::unused_bits`] of the 31 (2 to 3 bits for a step from zero): the
/// fixed-point compensator's rounding is a fixed fraction of the full scale.
#[must_use]
pub fn default_full_scale<'a>(tests_y: impl IntoIterator<Item = &'a [f64]>) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in tests_y.into_iter().flatten().filter(|v| v.is_finite()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if lo > hi {
        return 1.0;
    }
    let peak = lo.abs().max(hi.abs());
    let wanted = peak + DEFAULT_FULL_SCALE_SWINGS * (hi - lo);
    if !(wanted > 0.0 && wanted.is_finite()) {
        return 1.0;
    }
    round_up_125(wanted)
}

/// The smallest of 1, 2, 5 times a power of ten at or above `v > 0`.
fn round_up_125(v: f64) -> f64 {
    let decade = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&c| c >= v * (1.0 - 1e-12))
        .unwrap_or(10.0 * decade)
}

/// Designs the compensator asked for on the tests and checks it against the raw probe
/// ([`check::design_checked`]), puts the sensor-resonance prefilter in front, and plans its
/// fixed-point form for the full scale.
///
/// # Errors
/// [`Error::InvalidArgument`] for an optimum without tests and without a stored noise and
/// prior, or a full scale that is not a positive number. A design that cannot be made is no
/// error here but [`Compensator::design`]; a fixed-point plan that cannot be made is in
/// [`Compensator::unplanned`].
pub fn design_compensator(request: &CompensatorRequest<'_>) -> Result<Compensator> {
    let CompensatorRequest {
        model,
        effects,
        tests,
        roles,
        stored,
        spec,
        exportable,
    } = *request;
    let fs = model.fs;
    // Each test through the prefilter once (unchanged without one).
    let filtered: Vec<(Vec<f64>, Vec<f64>)> = tests
        .iter()
        .map(|t| {
            (
                effects::prefiltered(effects, fs, t.u),
                effects::prefiltered(effects, fs, t.y),
            )
        })
        .collect();
    let filtered: Vec<Test<'_>> = filtered
        .iter()
        .zip(tests)
        .map(|((u, y), t)| Test { name: t.name, u, y })
        .collect();
    // The probe noise is measured on the raw tests (a sensor resonance's prefilter would hide
    // its level in band), the prior on the prefiltered ones.
    let (judge, raw, learnt) = match roles {
        Roles::Fit { estimation } => {
            let fitted_on = estimation.max(1);
            let (estimation, held_out) = filtered.split_at(fitted_on.min(filtered.len()));
            let is_step: Vec<bool> = tests
                .iter()
                .enumerate()
                .map(|(i, t)| i < fitted_on || fit::step::quiet_until(t.u) >= optimal::MIN_QUIET)
                .collect();
            (
                if held_out.is_empty() {
                    estimation
                } else {
                    held_out
                },
                kept(tests, &is_step),
                kept(&filtered, &is_step),
            )
        }
        Roles::Alike => (filtered.as_slice(), tests.to_vec(), filtered.clone()),
    };
    let asked = asked_request(model, effects, spec, &raw, &learnt, stored)?;
    let tests_peak = judge
        .iter()
        .flat_map(|t| t.y.iter())
        .filter(|v| v.is_finite())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let full_scale = FullScale {
        value: spec
            .full_scale
            .unwrap_or_else(|| default_full_scale(judge.iter().map(|t| t.y))),
        stated: spec.full_scale.is_some(),
        tests_peak,
    };
    let mut made = compensator(
        model,
        effects,
        Step::Checked {
            request: asked,
            judge,
            nonlinear_gain: effects::nonlinear_gain(effects),
        },
        exportable,
        &[(spec.fixed_form, full_scale.value)],
        false,
    )?;
    made.full_scale = full_scale;
    Ok(made)
}

/// The tests whose `keep` flag is set.
fn kept<'t>(tests: &[Test<'t>], keep: &[bool]) -> Vec<Test<'t>> {
    tests
        .iter()
        .zip(keep)
        .filter_map(|(t, k)| k.then_some(*t))
        .collect()
}

/// The request [`check::design_checked`] takes for `spec`: the optimum's noise from the `raw`
/// tests and prior from the `learnt` ones (or the `--signal` runs); without tests, those
/// `stored` with the model's last design.
fn asked_request(
    model: &Model,
    effects: &[Effect],
    spec: &CompensatorSpec,
    raw: &[Test<'_>],
    learnt: &[Test<'_>],
    stored: Option<&Design>,
) -> Result<Request> {
    let (max_latency_samples, max_band_hz) = match spec.shape {
        Shape::BandLimited {
            bandwidth_hz,
            stabilise,
        } => {
            return Ok(Request::BandLimited(inverse::Options {
                bandwidth_hz,
                lowpass: spec.lowpass,
                lowpass_order: spec.lowpass_order,
                stabilise,
            }))
        }
        Shape::Optimal {
            max_latency_samples,
            max_band_hz,
        } => (max_latency_samples, max_band_hz),
    };
    let (mut noise, mut prior, steps_prior) = noise_and_prior(model, spec, raw, learnt, stored)?;
    // A record with no quiet segment shows no coloured probe noise by itself: the noise model
    // fitted beside the dynamics (`coloured-noise`) supplies it.
    if noise.probe_ar_std == 0.0 {
        if let Some(ar) = effects::noise_model(effects) {
            noise.take_ar_part(ar, effects::innovation_std(effects));
        }
    }
    let options = OptimalOptions {
        max_band_hz,
        max_latency_samples,
        lowpass: spec.lowpass,
        lowpass_order: spec.lowpass_order,
    };
    // Runs the probe recorded alone: the level whose optimum their spectra predict least
    // error for, searched around the level their increments give and the step tests' own.
    if spec.signal.iter().any(|r| r.u.is_none()) {
        let runs: Vec<&[f64]> = spec.signal.iter().map(|r| r.y.as_slice()).collect();
        let levels: Vec<SignalPrior> = std::iter::once(prior).chain(steps_prior).collect();
        prior = check::prior_for_runs(model, &noise, &levels, &options, &runs);
    }
    Ok(Request::Optimal {
        options,
        noise: Some(noise),
        prior: Some(prior),
    })
}

/// The probe noise, measured on the `raw` tests, and the signal prior, from the `--signal`
/// runs or the `learnt` tests; without tests, those `stored` with the model's last design.
/// With `--signal` runs, also the prior the step tests alone give (the `learnt` tests', or
/// the stored one), when there is one.
fn noise_and_prior(
    model: &Model,
    spec: &CompensatorSpec,
    raw: &[Test<'_>],
    learnt: &[Test<'_>],
    stored: Option<&Design>,
) -> Result<(NoiseModel, SignalPrior, Option<SignalPrior>)> {
    let stored = stored.and_then(|d| d.noise.zip(d.prior));
    let noise = match (raw.is_empty(), stored) {
        (true, Some((noise, _))) => noise,
        (true, None) => {
            return Err(Error::InvalidParameter {
                parameter: crate::error::Parameter::Tests,
                message: "the optimal compensator needs a step test to measure the noise on \
                          (or a model file designed from one)"
                    .into(),
            }
            .advised(crate::error::Advice::GiveTestOrBandwidth))
        }
        _ => optimal::estimate_noise(raw),
    };
    let steps_prior = match (learnt.is_empty(), stored) {
        (true, Some((_, prior))) => Some(prior),
        (true, None) => None,
        (false, _) => Some(optimal::estimate_prior(
            learnt,
            &optimal::estimate_noise(learnt),
        )),
    };
    let prior = if spec.signal.is_empty() {
        match steps_prior {
            Some(prior) => prior,
            None => optimal::estimate_prior(learnt, &optimal::estimate_noise(learnt)),
        }
    } else {
        let pairs: Vec<(Option<&[f64]>, &[f64])> = spec
            .signal
            .iter()
            .map(|r| (r.u.as_deref(), r.y.as_slice()))
            .collect();
        // The probe's response time: the slowest pole's time constant, at least 8 samples.
        let scale = model
            .poles()
            .ok()
            .and_then(|p| {
                p.first()
                    .map(|p| (1.0 / (1.0 - p.norm()).max(1e-6)).min(1e5))
            })
            .unwrap_or(8.0) as usize;
        optimal::prior_from_runs(&pairs, model.dc_gain(), &noise, scale.max(8))
    };
    Ok((
        noise,
        prior,
        steps_prior.filter(|_| !spec.signal.is_empty()),
    ))
}

/// The stored compensator `stored` designed anew for `model`, its model rescaled in time by
/// `k` (a gas temperature's `sqrt(T / T_ref)`): the optimum from its stored noise and prior, or
/// the band-limited inverse of the same family and order with its corner scaled by `k` (at
/// most 0.45 fs); the sensor-resonance prefilter of `effects` in front, and its fixed-point
/// plans redone for their full scales. A design after a prefilter is redesigned as a
/// band-limited inverse.
///
/// # Errors
/// The design's, the prefilter's and the fixed-point plans' errors: the board given this set
/// needs every plan the stored one had.
pub fn retarget(stored: &Design, model: &Model, effects: &[Effect], k: f64) -> Result<Design> {
    let corner_hz = (stored.lowpass_hz * k).min(0.45 * model.fs);
    let options = inverse::Options {
        bandwidth_hz: Some(corner_hz),
        lowpass: stored.lowpass,
        lowpass_order: stored.lowpass_order,
        stabilise: stored.method.kind() != inverse::MethodKind::DirectInverse,
    };
    let step = match (&stored.noise, &stored.prior) {
        (Some(noise), Some(prior))
            if !stored.method.is_prefiltered() && stored.method.kind().is_optimal() =>
        {
            Step::Optimal {
                noise: *noise,
                prior: *prior,
                options: OptimalOptions {
                    max_latency_samples: None,
                    max_band_hz: None,
                    lowpass: stored.lowpass,
                    lowpass_order: stored.lowpass_order,
                },
            }
        }
        _ => Step::BandLimited { corner_hz, options },
    };
    let plans: Vec<(FixedForm, f64)> = stored
        .fixed
        .iter()
        .map(|p| (FixedForm::Normal, p.full_scale))
        .chain(
            stored
                .fixed_direct
                .iter()
                .map(|p| (FixedForm::Direct, p.full_scale)),
        )
        .collect();
    compensator(model, effects, step, false, &plans, true)?.design
}

/// How the design of [`compensator`] is made.
enum Step<'a> {
    /// Designed as asked and checked on `judge` against the raw probe, falling back to
    /// narrower designs ([`check::design_checked`]).
    Checked {
        request: Request,
        judge: &'a [Test<'a>],
        nonlinear_gain: f64,
    },
    /// The optimum for a known noise and prior, unchecked.
    Optimal {
        noise: NoiseModel,
        prior: SignalPrior,
        options: OptimalOptions,
    },
    /// The band-limited inverse at a known corner, unchecked.
    BandLimited {
        corner_hz: f64,
        options: inverse::Options,
    },
}

/// The one sequence every compensator goes through: the design, the sensor-resonance prefilter
/// of `effects` in front of it, the board's check when `exportable`, then a fixed-point plan
/// for each `(form, full scale)` of `plans`. A full scale that is not a positive number is an
/// error; another plan that cannot be made is an error when `plans_required`, else left out.
fn compensator(
    model: &Model,
    effects: &[Effect],
    step: Step<'_>,
    exportable: bool,
    plans: &[(FixedForm, f64)],
    plans_required: bool,
) -> Result<Compensator> {
    let designed = match step {
        Step::Checked {
            request,
            judge,
            nonlinear_gain,
        } => check::design_checked(model, judge, &request, nonlinear_gain),
        Step::Optimal {
            noise,
            prior,
            options,
        } => optimal::design(model, &noise, &prior, &options),
        Step::BandLimited { corner_hz, options } => inverse::design(model, corner_hz, &options),
    }
    .and_then(|mut d| {
        effects::with_prefilter(&mut d, effects, model.fs)?;
        if exportable {
            d.check_exportable()?;
        }
        Ok(d)
    });
    // The plans' full scale as given (the callers that choose it say where it came from).
    let full_scale = FullScale {
        value: plans.first().map_or(1.0, |p| p.1),
        stated: true,
        tests_peak: 0.0,
    };
    let mut design = match designed {
        Ok(d) => d,
        Err(e) => {
            return Ok(Compensator {
                design: Err(e),
                unplanned: Vec::new(),
                full_scale,
            })
        }
    };
    let mut unplanned = Vec::new();
    for &(form, full_scale) in plans {
        let planned = match form {
            FixedForm::Normal => {
                FixedPlan::new(&design, full_scale).map(|p| design.fixed = Some(p))
            }
            FixedForm::Direct => {
                DirectPlan::new(&design, full_scale).map(|p| design.fixed_direct = Some(p))
            }
        };
        match planned {
            Ok(()) => {}
            // A full scale that makes no sense is the caller's error.
            Err(e) if e.is_the_callers() => return Err(e),
            Err(e) if plans_required => return Err(e),
            Err(e) => unplanned.push(e),
        }
    }
    Ok(Compensator {
        design: Ok(design),
        unplanned,
        full_scale,
    })
}

/// The model file at gas temperature `temperature_k`: the model scaled by
/// `sqrt(T / reference_k)`, its damping by the effect's law ([`effects::scaled_with`]), its compensator designed anew for it (same low-pass
/// family and order, corner scaled by the same factor, the sensor prefilter kept, the
/// fixed-point plan redone for the same full scale), and its `temperature` effect now at `T`.
/// This is the coefficient set a board is given for that temperature.
///
/// # Errors
/// [`crate::error::Error::InvalidParameter`] when the file has no `temperature` effect (no
/// reference temperature) or `T` is not a positive number of kelvin; the scaling's and the
/// design's errors.
pub fn at_temperature(file: &ModelFile, temperature_k: f64) -> Result<ModelFile> {
    let (reference, damping) = effects::temperature_law(&file.effects).ok_or_else(|| {
        crate::error::Error::InvalidParameter {
            parameter: crate::error::Parameter::Temperature,
            message: "the model file has no temperature effect, so no reference temperature".into(),
        }
        .advised(crate::error::Advice::AddTemperature { by_hand: true })
    })?;
    let k = damping.scale(temperature_k, reference)?;
    let model = effects::scaled_with(&file.model, k, damping.factor(k, reference))?;
    let inverse = match &file.inverse {
        Some(d) => {
            let mut nd = retarget(d, &model, &file.effects, k)?;
            nd.bandwidth_selection = format!(
                "{} at the reference temperature, scaled by {k:.4} to {temperature_k} K",
                d.bandwidth_selection
            );
            Some(nd)
        }
        None => None,
    };
    let effects = file
        .effects
        .iter()
        .map(|e| match e {
            Effect::Temperature { damping, .. } => Effect::Temperature {
                reference_k: temperature_k,
                damping: *damping,
            },
            other => other.clone(),
        })
        .collect();
    Ok(ModelFile {
        model,
        inverse,
        effects,
        ..file.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{probe, step_test};
    use super::*;
    use crate::testing::second_order;

    #[test]
    fn the_default_full_scale_holds_a_reflected_shock_and_a_reversed_step() {
        // A step from 0 to 1000 Pa, read by a probe that overshoots by 30 %.
        let step: Vec<f64> = (0..400)
            .map(|k| match k {
                0..=99 => 0.0,
                100..=119 => 1300.0,
                _ => 1000.0,
            })
            .collect();
        let fs = default_full_scale([step.as_slice()]);
        // 1300 + 3 * 1300 = 5200, rounded up on the 1-2-5 series.
        assert_eq!(fs, 10_000.0);
        // A reflected shock of 2.6 times the step with the same overshoot, and a step of twice
        // the size and the other sign, stay inside.
        assert!(2.6 * 1300.0 < fs);
        // Above a baseline (absolute pressure), the room is for the swing, not the baseline.
        let absolute: Vec<f64> = step.iter().map(|v| 100_000.0 + v).collect();
        assert_eq!(default_full_scale([absolute.as_slice()]), 200_000.0);
        // Nothing moves, or nothing finite: 1.
        assert_eq!(default_full_scale([[0.0; 8].as_slice()]), 1.0);
        assert_eq!(default_full_scale([[f64::NAN; 3].as_slice()]), 1.0);
        assert_eq!(default_full_scale(std::iter::empty::<&[f64]>()), 1.0);
        // The rounding: the smallest 1, 2 or 5 times a power of ten at or above.
        for (v, up) in [
            (1.0, 1.0),
            (1.01, 2.0),
            (2.0, 2.0),
            (4.9, 5.0),
            (5.2, 10.0),
            (0.03, 0.05),
        ] {
            assert_eq!(round_up_125(v), up, "{v}");
        }
        let chosen = FullScale {
            value: 4000.0,
            stated: false,
            tests_peak: 1000.0,
        };
        assert!((chosen.unused_bits() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_coefficient_set_for_a_temperature_follows_the_damping_law() {
        let fs = 10_000.0;
        let (m, s) = second_order(95.0, 0.3, fs, 17);
        let design =
            crate::design::inverse::design(&m, 800.0, &crate::design::inverse::Options::default())
                .unwrap();
        let file = |spelling: &str| crate::file::ModelFile {
            format_version: crate::file::FORMAT_VERSION,
            model: m.clone(),
            fit: None,
            sources: Vec::new(),
            inverse: Some(design.clone()),
            effects: vec![Effect::parse(spelling).unwrap()],
            history: Vec::new(),
            probe: None,
            board: Default::default(),
        };
        let (k, f) = (
            (343.15f64 / 293.15).sqrt(),
            effects::viscous_damping_factor(343.15, 293.15).unwrap(),
        );
        let w = s.norm();
        let pole_at = |zeta: f64| {
            (crate::poly::Complex::new(-zeta * k * w, k * w * (1.0 - zeta * zeta).sqrt()) / fs)
                .exp()
        };
        for (spelling, zeta, law) in [
            ("temperature", 0.3, effects::TemperatureDamping::Constant),
            (
                "temperature-viscous",
                0.3 * f,
                effects::TemperatureDamping::Viscous,
            ),
        ] {
            let hot = at_temperature(&file(spelling), 343.15).unwrap();
            let want = pole_at(zeta);
            let poles = hot.model.poles().unwrap();
            assert!(
                poles.iter().any(|p| (*p - want).norm() < 1e-9),
                "{spelling}: {poles:?} against {want:?}"
            );
            assert_eq!(effects::temperature_law(&hot.effects), Some((343.15, law)));
            assert!(hot.inverse.is_some());
            // Back to the reference from the new file: the law composes.
            let back = at_temperature(&hot, 293.15).unwrap();
            let worst = crate::fit::continuous::step_response(&m, 600)
                .iter()
                .zip(crate::fit::continuous::step_response(&back.model, 600))
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-6, "{spelling}: {worst}");
        }
    }

    #[test]
    fn a_capillarys_coefficient_set_for_a_hotter_gas_is_slower() {
        // An overdamped probe: corners 4 Hz and 100 Hz.
        let m = crate::testing::overdamped(4.0, 100.0, 3000.0, 12);
        let mut file = crate::testing::model_file(m.clone());
        file.effects = vec![Effect::parse("temperature-diffusive").unwrap()];
        let hot = at_temperature(&file, 343.15).unwrap();
        let mu = crate::physics::gas::sutherland_viscosity;
        let k = mu(293.15) / mu(343.15);
        let corners = |m: &crate::fit::Model| {
            let mut c: Vec<f64> = m.poles().unwrap().iter().map(|p| -p.re.ln()).collect();
            c.sort_by(f64::total_cmp);
            c
        };
        for (old, new) in corners(&m).iter().zip(corners(&hot.model)) {
            assert!((new / old / k - 1.0).abs() < 1e-9, "{old} -> {new}");
        }
        // Slower: the step response lags the reference's more.
        assert!(hot.model.dc_group_delay().unwrap() > 1.1 * m.dc_group_delay().unwrap());
        assert_eq!(
            effects::temperature_law(&hot.effects),
            Some((343.15, effects::TemperatureDamping::Diffusive))
        );
    }

    fn spec(shape: Shape, full_scale: Option<f64>) -> CompensatorSpec {
        CompensatorSpec {
            shape,
            lowpass: LowpassKind::Bessel,
            lowpass_order: 4,
            signal: Vec::new(),
            fixed_form: FixedForm::Normal,
            full_scale,
        }
    }

    const BAND_200: Shape = Shape::BandLimited {
        bandwidth_hz: Some(200.0),
        stabilise: true,
    };

    #[test]
    fn a_fits_compensator_is_judged_on_the_held_out_test_and_planned_for_its_peak() {
        let m = probe();
        let ((ue, ye), (uv, yv)) = (step_test(1.0, 3), step_test(2.0, 4));
        let tests = [
            Test {
                name: "est",
                u: &ue,
                y: &ye,
            },
            Test {
                name: "val",
                u: &uv,
                y: &yv,
            },
        ];
        let peak = |y: &[f64]| y.iter().fold(0.0f64, |p, v| p.max(v.abs()));
        let asked = spec(BAND_200, None);
        let request = CompensatorRequest {
            model: &m,
            effects: &[],
            tests: &tests,
            roles: Roles::Fit { estimation: 1 },
            stored: None,
            spec: &asked,
            exportable: true,
        };
        let c = design_compensator(&request).unwrap();
        assert!(c.unplanned.is_empty(), "{:?}", c.unplanned);
        let d = c.design.unwrap();
        assert_eq!(d.lowpass_hz, 200.0);
        let judged: Vec<&str> = d.reconstruction.iter().map(|r| r.file.as_str()).collect();
        assert_eq!(judged, ["val"]);
        // Unstated, the full scale leaves room above the judged test for the runs after it.
        let full_scale = d.fixed.unwrap().full_scale;
        let swing = yv.iter().fold(f64::NEG_INFINITY, |m, v| m.max(*v))
            - yv.iter().fold(f64::INFINITY, |m, v| m.min(*v));
        assert!(full_scale >= peak(&yv) + 3.0 * swing, "{full_scale}");
        assert!(
            full_scale <= 2.5 * (peak(&yv) + 3.0 * swing),
            "{full_scale}"
        );
        assert!(d.fixed_direct.is_none());

        // `invert`: every test judged on; the direct form planned for the full scale given.
        let direct = CompensatorSpec {
            fixed_form: FixedForm::Direct,
            ..spec(BAND_200, Some(3.0))
        };
        let d = design_compensator(&CompensatorRequest {
            roles: Roles::Alike,
            spec: &direct,
            ..request
        })
        .unwrap()
        .design
        .unwrap();
        let judged: Vec<&str> = d.reconstruction.iter().map(|r| r.file.as_str()).collect();
        assert_eq!(judged, ["est", "val"]);
        assert!(d.fixed.is_none());
        assert_eq!(d.fixed_direct.unwrap().full_scale, 3.0);

        // A full scale that is no number is the caller's error, once there is a design.
        let nonsense = spec(BAND_200, Some(-1.0));
        let refused = design_compensator(&CompensatorRequest {
            spec: &nonsense,
            ..request
        });
        assert!(
            matches!(
                refused,
                Err(Error::InvalidParameter {
                    parameter: crate::error::Parameter::FullScale,
                    ..
                })
            ),
            "{refused:?}"
        );
        // A design that cannot be made (a latency below the delay) is told, not an error.
        let too_soon = spec(
            Shape::Optimal {
                max_latency_samples: Some(1),
                max_band_hz: None,
            },
            Some(-1.0),
        );
        let c = design_compensator(&CompensatorRequest {
            spec: &too_soon,
            ..request
        })
        .unwrap();
        assert!(
            matches!(
                c.design,
                Err(Error::InvalidArgument {
                    what: "latency",
                    ..
                })
            ),
            "{:?}",
            c.design
        );
        // The optimum needs a test, or a stored design, to measure the noise on.
        let optimum = spec(
            Shape::Optimal {
                max_latency_samples: None,
                max_band_hz: None,
            },
            None,
        );
        let without = design_compensator(&CompensatorRequest {
            tests: &[],
            spec: &optimum,
            ..request
        });
        assert!(
            matches!(
                without.as_ref().map_err(Error::unadvised),
                Err(Error::InvalidParameter {
                    parameter: crate::error::Parameter::Tests,
                    ..
                })
            ),
            "{without:?}"
        );
    }

    #[test]
    fn a_retargeted_compensator_keeps_its_shape_prefilter_and_plans() {
        let m = probe();
        let options = inverse::Options {
            bandwidth_hz: Some(200.0),
            ..inverse::Options::default()
        };
        let mut stored = inverse::design(&m, 200.0, &options).unwrap();
        stored.fixed = Some(FixedPlan::new(&stored, 2.0).unwrap());
        stored.fixed_direct = Some(DirectPlan::new(&stored, 3.0).unwrap());
        let prefilter = [Effect::parse("sensor-resonance-prefilter=3000").unwrap()];
        let hot = retarget(&stored, &m, &prefilter, 1.5).unwrap();
        assert_eq!(hot.lowpass_hz, 300.0);
        assert_eq!((hot.lowpass, hot.lowpass_order), (stored.lowpass, 4));
        assert_eq!(hot.fixed.as_ref().unwrap().full_scale, 2.0);
        assert_eq!(hot.fixed_direct.as_ref().unwrap().full_scale, 3.0);
        // The prefilter's sections run first, and its delay adds to the latency.
        let plain = retarget(&stored, &m, &[], 1.5).unwrap();
        assert!(hot.method.is_prefiltered(), "{}", hot.method);
        assert_eq!(
            hot.sections.len(),
            plain.sections.len() + effects::PREFILTER_ORDER / 2
        );
        assert_eq!(
            hot.sections[effects::PREFILTER_ORDER / 2..],
            plain.sections[..]
        );
        assert!(hot.latency_samples > plain.latency_samples + 1.0);
        // The corner stays below the Nyquist frequency however far it is scaled.
        let far = retarget(&stored, &m, &[], 1e3).unwrap();
        assert_eq!(far.lowpass_hz, 0.45 * m.fs);
        assert!(!far.method.is_prefiltered());

        // The optimum is designed anew from its stored noise and prior.
        let ((u, y), name) = (step_test(1.0, 5), "t");
        let tests = [Test { name, u: &u, y: &y }];
        let optimum = spec(
            Shape::Optimal {
                max_latency_samples: None,
                max_band_hz: None,
            },
            None,
        );
        let designed = design_compensator(&CompensatorRequest {
            model: &m,
            effects: &[],
            tests: &tests,
            roles: Roles::Alike,
            stored: None,
            spec: &optimum,
            exportable: false,
        })
        .unwrap()
        .design
        .unwrap();
        assert!(designed.method.kind().is_optimal(), "{}", designed.method);
        let again = retarget(&designed, &m, &[], 1.0).unwrap();
        assert!(again.method.kind().is_optimal(), "{}", again.method);
        assert_eq!((again.noise, again.prior), (designed.noise, designed.prior));
        assert_eq!(
            again.fixed.map(|p| p.full_scale),
            designed.fixed.map(|p| p.full_scale)
        );
    }
}
