//! A recording compensated with a model file: the board's compensator (or the paper's direct
//! inverse, or the offline optimum) run on the probe signal with the model's effects, and the
//! error of its output against the recorded reference beside the raw probe's.

use std::path::Path;

use crate::design::inverse::{self, Design};
use crate::design::quantise::{DirectPlan, FixedPlan, FixedRunner};
use crate::effects;
use crate::error::{Advice, Error, Result};
use crate::file::ModelFile;
use crate::fit;

/// Arithmetic of a compensator run on the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arithmetic {
    /// 32-bit float, as on a Cortex-M4F board.
    F32,
    /// 64-bit float.
    F64,
    /// 32-bit fixed point, bit for bit what a board without an FPU computes (the design's
    /// fixed-point plan).
    Fixed,
}

/// Which compensator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compensation {
    /// The model file's compensator as the board runs it (the paper's direct inverse when the
    /// file has none), whatever the run: what a board given the file computes.
    Designed(Arithmetic),
    /// The model file's compensator, unless the run's own probe spectrum predicts it not to
    /// beat the raw probe and another design (the delay alone, the probe passed through, the
    /// optimum under a quieter prior) to do better: then that one, in f64 on the host only. A
    /// board given the file computes the stored one.
    AdaptedToRun,
    /// The paper's direct inverse (eq. 7), even when the model file has a compensator.
    Direct(Arithmetic),
    /// The non-causal optimum on the whole record (no latency, the least error a linear
    /// filter can reach), from the noise and prior stored with the file's optimal design; in
    /// f64, on the host only.
    Offline,
}

/// A recording to compensate with a model file.
#[derive(Debug, Clone, Copy)]
pub struct CompensateRequest<'a> {
    /// The model file.
    pub file: &'a ModelFile,
    /// Where the model file was read from, for messages.
    pub model_path: &'a Path,
    /// The recording's probe signal.
    pub probe: &'a [f64],
    /// The recording's reference, when it has one (the error of `u_hat` is measured against
    /// it).
    pub reference: Option<&'a [f64]>,
    /// Which compensator.
    pub compensation: Compensation,
    /// The recording's gas temperature (K), for a model with a `temperature` effect: the model
    /// is scaled to it and its compensator designed anew ([`at_temperature`](super::at_temperature)),
    /// as a board given that temperature runs it; `None` runs the file as it is.
    pub temperature_k: Option<f64>,
}

/// The error of `u_hat` against the recorded reference, beside the raw probe's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceError {
    /// `u_hat`'s RMS error over the reference's range, at its best alignment.
    pub u_hat: f64,
    /// The raw probe's, at its best alignment.
    pub raw: f64,
    /// The lag of `u_hat` behind the reference at its best alignment (samples).
    pub lag: usize,
}

impl ReferenceError {
    /// Whether `u_hat` is not closer to the reference than the raw probe: a tie within f32
    /// rounding (the probe passed through) is not better, and a NaN counts as worse, so that
    /// neither passes silently.
    #[must_use]
    pub fn worse(&self) -> bool {
        self.u_hat.partial_cmp(&(self.raw * (1.0 - 1e-6))) != Some(std::cmp::Ordering::Less)
    }
}

/// What a fixed-point run clamped and saturated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedRunSummary {
    /// Samples of the probe signal outside the full scale, clamped.
    pub clamped_inputs: usize,
    /// The plan's full scale.
    pub full_scale: f64,
    /// A state or the output saturated (the overflow flag).
    pub overflowed: bool,
}

/// A compensated recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Compensated {
    /// The reconstructed reference, one sample per sample of the recording.
    pub u_hat: Vec<f64>,
    /// Its latency behind the true pressure (samples).
    pub latency_samples: f64,
    /// Which compensator ran, in words.
    pub compensator: &'static str,
    /// Whether it was the model file's design (or the offline optimum from it) rather than
    /// the direct inverse.
    pub designed: bool,
    /// The error against the recorded reference: `None` without a reference, or with one
    /// that does not move above its noise ([`Compensated::still_reference`]).
    pub error: Option<ReferenceError>,
    /// The reference does not move above its noise: it says nothing about `u_hat`.
    pub still_reference: bool,
    /// The fixed-point run's clamps and saturation, when the fixed-point compensator ran.
    pub fixed: Option<FixedRunSummary>,
    /// What the run's own probe spectrum predicts for the model file's compensator and the raw
    /// probe ([`inverse::check::on_run`]).
    pub predicted: Option<inverse::check::RunCheck>,
    /// The compensator that ran instead of the model file's, predicted not to beat the raw
    /// probe on this run.
    pub fall_back: Option<inverse::check::RunFallBack>,
    /// The model file's design (at the request's temperature) was asked for and its stored
    /// check found no design better than the raw probe on the fit's tests: its method.
    pub stored_not_better: Option<inverse::DesignMethod>,
    /// `u_hat` is not what a board given the model file computes: the offline optimum, or a
    /// compensator chosen for the run ([`Compensation::AdaptedToRun`]).
    pub host_only: bool,
}

/// Compensates the recording: the model's offset and drift removed from the probe signal
/// first (they are the probe's, not the pressure's), the compensator asked for run on it, a
/// nonlinear damping's correction added; then the error against the recorded reference at the
/// best alignment near the latency (with a sensor resonance, the reference below it: the
/// compensator does not and should not reproduce the reference transducer's own ringing).
///
/// With a gas temperature, the model file is first put at it
/// ([`at_temperature`](super::at_temperature)).
///
/// # Errors
/// [`Error::InvalidArgument`] for the offline optimum without a stored optimal design, or
/// fixed point without a plan or for the direct inverse; [`Error::UnsupportedOnBoard`] for
/// fixed point with nonlinear damping; the model's and the compensator's refusals (a
/// non-invertible model, a design the board cannot run); with a temperature,
/// [`at_temperature`](super::at_temperature)'s.
pub fn compensate(request: &CompensateRequest<'_>) -> Result<Compensated> {
    let at_temperature = match request.temperature_k {
        Some(t) => Some(super::at_temperature(request.file, t)?),
        None => None,
    };
    let file = at_temperature.as_ref().unwrap_or(request.file);
    let CompensateRequest {
        model_path,
        probe,
        reference,
        compensation,
        ..
    } = *request;
    let m = &file.model;
    let additive = effects::Additive::of(&file.effects);
    let y_probe = additive.removed_from(probe, m.fs);
    let (design, arithmetic, offline) = match compensation {
        Compensation::Designed(a) => (file.inverse.as_ref(), a, false),
        Compensation::AdaptedToRun => (file.inverse.as_ref(), Arithmetic::F64, false),
        Compensation::Direct(a) => (None, a, false),
        Compensation::Offline => (file.inverse.as_ref(), Arithmetic::F64, true),
    };
    let adapt = compensation == Compensation::AdaptedToRun;
    // Quadratic losses: the board adds gain * lowpass(|dy| dy) to the linear inverse.
    let nonlinear = effects::nonlinear_gain(&file.effects);
    if offline && design.is_none() {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::Offline,
            message: format!(
                "{} has no compensator design to take the noise and prior from",
                model_path.display()
            ),
        }
        .advised(Advice::DesignCompensator));
    }
    // The stored design judged on the run's own probe spectrum (said when it is predicted not
    // to beat the raw probe); only when asked, the one of least predicted error runs instead,
    // on the host.
    let judgement = design.filter(|_| !offline).and_then(|d| {
        let candidates = if adapt && nonlinear == 0.0 {
            inverse::check::RunCandidates::Redesigns
        } else {
            // The board adds a nonlinear correction to the stored design's output.
            inverse::check::RunCandidates::JudgeOnly
        };
        inverse::check::on_run(d, m, &y_probe, candidates)
    });
    let predicted = judgement.as_ref().map(|j| j.stored);
    let fall_back = judgement.and_then(|j| j.fall_back);
    let stored_not_better = design
        .and_then(|d| d.check.as_ref().map(|c| (d, c)))
        .filter(|(_, c)| c.verdict == inverse::check::Verdict::NotBetter)
        .map(|(d, _)| d.method.clone());
    let design = fall_back.as_ref().map(|f| &f.design).or(design);
    let mut fixed = None;
    let (u_hat, latency, compensator) = match design {
        Some(d) if offline => (
            run_offline(d, file, model_path, &y_probe)?,
            effects::prefilter_delay(&file.effects, m.fs),
            "the non-causal optimum (offline, host only)",
        ),
        Some(d) => {
            let (u_hat, summary) = run_designed(d, file, model_path, arithmetic, &y_probe)?;
            fixed = summary;
            let what = if fall_back.is_some() {
                "a compensator chosen for this run (host only: a board runs the model file's)"
            } else {
                "the model file's compensator"
            };
            (u_hat, d.latency_samples, what)
        }
        None => (
            run_direct(file, model_path, arithmetic, &y_probe)?,
            m.delay as f64,
            "the paper's direct inverse (eq. 7)",
        ),
    };
    // A reference that does not move above its noise says nothing about u_hat: no error, no
    // verdict (a run without a step is compensated all the same).
    let still_reference = reference
        .filter(|u| fit::step::excitation(u) < fit::step::MIN_EXCITATION)
        .is_some();
    let error = reference
        .filter(|_| !still_reference)
        .map(|u| reference_error(file, design, latency, u, probe, &u_hat));
    Ok(Compensated {
        host_only: offline || fall_back.is_some(),
        predicted,
        fall_back: fall_back.clone(),
        stored_not_better,
        u_hat,
        latency_samples: latency,
        compensator,
        designed: design.is_some(),
        error,
        still_reference,
        fixed,
    })
}

/// The offline optimum of design `d`'s stored noise and prior on the probe signal `y_probe`
/// (prefiltered as the model's effects say), on the host.
fn run_offline(
    d: &Design,
    file: &ModelFile,
    model_path: &Path,
    y_probe: &[f64],
) -> Result<Vec<f64>> {
    let (Some(noise), Some(prior)) = (&d.noise, &d.prior) else {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::Offline,
            message: format!("{} has no stored noise and prior", model_path.display()),
        }
        .advised(Advice::DesignOptimal));
    };
    let m = &file.model;
    let y_in = effects::prefiltered(&file.effects, m.fs, y_probe);
    inverse::optimal::offline(m, noise, prior, &y_in)
}

/// The designed compensator `d` on `y_probe` as the board runs it in `arithmetic`, with the
/// nonlinear damping's correction added (f32 or f64 only), and the fixed-point run's clamps.
fn run_designed(
    d: &Design,
    file: &ModelFile,
    model_path: &Path,
    arithmetic: Arithmetic,
    y_probe: &[f64],
) -> Result<(Vec<f64>, Option<FixedRunSummary>)> {
    d.check_exportable()?;
    let m = &file.model;
    // Quadratic losses: the board adds gain * lowpass(|dy| dy) to the linear inverse.
    let nonlinear = effects::nonlinear_gain(&file.effects);
    let mut fixed = None;
    let mut u_hat = match arithmetic {
        Arithmetic::F32 => d.run::<f32>(y_probe)?,
        Arithmetic::F64 => d.run::<f64>(y_probe)?,
        Arithmetic::Fixed if nonlinear != 0.0 => {
            return Err(Error::UnsupportedOnBoard {
                path: model_path.to_path_buf(),
                effect: "nonlinear damping",
                arithmetic: "fixed-point",
            }
            .advised(Advice::UseF32))
        }
        Arithmetic::Fixed => {
            let (u_hat, summary) = run_fixed(d, file.board.full_scale, model_path, y_probe)?;
            fixed = Some(summary);
            u_hat
        }
    };
    if nonlinear != 0.0 {
        let correction = match arithmetic {
            Arithmetic::F64 => d.run_nonlinear_correction::<f64>(m.fs, nonlinear, y_probe)?,
            _ => d.run_nonlinear_correction::<f32>(m.fs, nonlinear, y_probe)?,
        };
        for (u, c) in u_hat.iter_mut().zip(correction) {
            *u += c;
        }
    }
    Ok((u_hat, fixed))
}

/// The refusal of the paper's direct inverse in fixed point, which runs designed sections only.
pub(super) fn direct_not_in_fixed_point() -> Error {
    Error::InvalidParameter {
        parameter: crate::error::Parameter::Arithmetic,
        message: "fixed point runs the designed compensator in sections, not the paper's \
                  direct inverse"
            .into(),
    }
    .advised(Advice::DesignSections)
}

/// The nonlinear damping's correction beside the direct inverse, of gain `nonlinear` at
/// `fs`: unfiltered, as the direct inverse has no band limit.
pub(super) fn unfiltered_correction(
    nonlinear: f64,
    fs: f64,
) -> Result<crate::board::compensator::NonlinearDampingCoefficients<f64, 1>> {
    crate::board::compensator::NonlinearDampingCoefficients::<f64, 1>::new(
        nonlinear * fs * fs,
        1.0,
        &[],
    )
    .map_err(|e| Error::BoardRefused {
        during: "nonlinear-damping correction",
        refusal: e.into(),
    })
}

/// The paper's direct inverse of the model on `y_probe` (prefiltered for a model fitted below
/// a sensor resonance), with the nonlinear damping's correction unfiltered (the direct
/// inverse has no band limit); not in fixed point.
fn run_direct(
    file: &ModelFile,
    model_path: &Path,
    arithmetic: Arithmetic,
    y_probe: &[f64],
) -> Result<Vec<f64>> {
    let m = &file.model;
    m.check_invertible(&model_path.display().to_string())?;
    let y_in = effects::prefiltered(&file.effects, m.fs, y_probe);
    let mut u_hat = match arithmetic {
        Arithmetic::F32 => m.compensate::<f32>(&y_in)?,
        Arithmetic::F64 => m.compensate::<f64>(&y_in)?,
        Arithmetic::Fixed => return Err(direct_not_in_fixed_point()),
    };
    let nonlinear = effects::nonlinear_gain(&file.effects);
    if nonlinear != 0.0 {
        let c = unfiltered_correction(nonlinear, m.fs)?;
        let mut st = c.equilibrium(y_probe.first().copied().unwrap_or(0.0));
        for (u, y) in u_hat.iter_mut().zip(y_probe) {
            *u += c.process(&mut st, *y);
        }
    }
    Ok(u_hat)
}

/// The error of `u_hat` (from `design`, or the direct inverse without one, `latency` samples
/// late) against the recorded reference `u`, beside the raw `probe`'s, each at its best
/// alignment.
fn reference_error(
    file: &ModelFile,
    design: Option<&Design>,
    latency: f64,
    u: &[f64],
    probe: &[f64],
    u_hat: &[f64],
) -> ReferenceError {
    let m = &file.model;
    let u = &effects::observed(&file.effects, m.fs, u);
    let prefilter = if design.is_some() {
        effects::prefilter_delay(&file.effects, m.fs)
    } else {
        0.0
    };
    let nominal = (latency - prefilter).round().max(0.0) as usize;
    // The raw probe is searched over the same lags whatever the compensator's latency
    // (the offline optimum has none), so that its error does not depend on it.
    let causal = design
        .map_or(latency, |d| d.latency_samples)
        .round()
        .max(0.0) as usize;
    let (lags, raw_lags) = inverse::comparison_lags(design, nominal, causal, m.delay);
    let (e, lag) = inverse::aligned_error(u, u_hat, lags);
    let (raw, _) = inverse::aligned_error(u, probe, raw_lags);
    ReferenceError { u_hat: e, raw, lag }
}

/// The fixed-point compensator (the direct form's plan if the design has one, else the normal
/// form's) on the probe signal `y`; planned anew for the board's `stated` full scale when the
/// stored plan was made for another (a `[board]` range written by hand).
fn run_fixed(
    d: &Design,
    stated: Option<f64>,
    model: &Path,
    y: &[f64],
) -> Result<(Vec<f64>, FixedRunSummary)> {
    let (mut runner, full_scale) =
        fixed_runner(d, stated, model, y.first().copied().unwrap_or(0.0))?;
    let u_hat = y.iter().map(|&v| runner.step(v)).collect();
    let summary = FixedRunSummary {
        clamped_inputs: runner.clipped_inputs(),
        full_scale,
        overflowed: runner.overflowed(),
    };
    Ok((u_hat, summary))
}

/// [`run_fixed`]'s compensator, to run one sample at a time from `first` on; with its full
/// scale.
pub(super) fn fixed_runner(
    d: &Design,
    stated: Option<f64>,
    model: &Path,
    first: f64,
) -> Result<(FixedRunner, f64)> {
    let other = |planned: f64| stated.filter(|&s| s != planned);
    Ok(match (&d.fixed_direct, &d.fixed, stated) {
        (Some(plan), _, _) => match other(plan.full_scale) {
            Some(fs) => (DirectPlan::new(d, fs)?.runner(first)?, fs),
            None => (plan.runner(first)?, plan.full_scale),
        },
        (None, Some(plan), _) => match other(plan.full_scale) {
            Some(fs) => (FixedPlan::new(d, fs)?.runner(first)?, fs),
            None => (plan.runner(first)?, plan.full_scale),
        },
        // No plan stored, a range stated: planned for it, as the export plans it.
        (None, None, Some(fs)) => (FixedPlan::new(d, fs)?.runner(first)?, fs),
        (None, None, None) => {
            return Err(Error::InvalidParameter {
                parameter: crate::error::Parameter::Arithmetic,
                message: format!("{} has no fixed-point plan", model.display()),
            }
            .advised(Advice::PlanFixedPoint {
                model: model.to_path_buf(),
            }))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{probe, step_test};
    use super::*;
    use crate::effects::Effect;
    use crate::file::FORMAT_VERSION;
    use crate::trace::{Columns, Trace};

    /// A recording of `u` and `y` at 10 kHz, as read from a CSV file.
    fn trace(u: &[f64], y: &[f64]) -> Trace {
        let mut csv = String::from("t,u,y\n");
        for (k, (u, y)) in u.iter().zip(y).enumerate() {
            csv.push_str(&format!("{:.6},{u:e},{y:e}\n", k as f64 / 10_000.0));
        }
        let columns = Columns {
            time: "t".into(),
            input: "u".into(),
            output: "y".into(),
            sample_rate_hz: None,
            require_input: false,
            ..Columns::default()
        };
        Trace::parse(Path::new("run.csv"), csv.as_bytes(), &columns).unwrap()
    }

    /// The probe's model file with a band-limited compensator at 300 Hz, planned in fixed
    /// point for inputs within +-`full_scale`.
    fn file(full_scale: f64) -> ModelFile {
        let m = probe();
        let options = inverse::Options {
            bandwidth_hz: Some(300.0),
            ..inverse::Options::default()
        };
        let mut d = inverse::design(&m, 300.0, &options).unwrap();
        d.fixed = Some(FixedPlan::new(&d, full_scale).unwrap());
        ModelFile {
            format_version: FORMAT_VERSION,
            model: m,
            fit: None,
            sources: Vec::new(),
            inverse: Some(d),
            effects: Vec::new(),
            history: Vec::new(),
            probe: None,
            board: Default::default(),
        }
    }

    fn run(file: &ModelFile, trace: &Trace, compensation: Compensation) -> Result<Compensated> {
        compensate(&CompensateRequest {
            file,
            model_path: Path::new("probe.toml"),
            probe: &trace.y,
            reference: trace.u.as_deref(),
            compensation,
            temperature_k: None,
        })
    }

    #[test]
    fn the_compensator_beats_the_raw_probe_and_fixed_point_tells_its_clamps() {
        let (u, y) = step_test(1.0, 7);
        let t = trace(&u, &y);
        let f = file(2.0);
        let c = run(&f, &t, Compensation::Designed(Arithmetic::F64)).unwrap();
        assert_eq!(c.u_hat.len(), y.len());
        assert!(c.designed && c.fixed.is_none() && !c.still_reference);
        let e = c.error.unwrap();
        assert!(e.u_hat < 0.7 * e.raw, "{e:?}");
        assert!(!e.worse());
        let latency = f.inverse.as_ref().unwrap().latency_samples;
        assert_eq!(c.latency_samples, latency);
        assert!(
            e.lag.abs_diff(latency.round() as usize) <= 4,
            "{e:?} {latency}"
        );

        let fixed = run(&f, &t, Compensation::Designed(Arithmetic::Fixed)).unwrap();
        assert_eq!(
            fixed.fixed,
            Some(FixedRunSummary {
                clamped_inputs: 0,
                full_scale: 2.0,
                overflowed: false
            })
        );
        // Within a few codes of the f64 run.
        let worst = fixed
            .u_hat
            .iter()
            .zip(&c.u_hat)
            .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(worst < 1e-4, "{worst}");
        // A full scale below the step: the samples above it are clamped, and said to be.
        let clamped = run(&file(0.5), &t, Compensation::Designed(Arithmetic::Fixed)).unwrap();
        let above = y.iter().filter(|v| v.abs() > 0.5).count();
        let summary = clamped.fixed.unwrap();
        assert!(
            summary.clamped_inputs > 0 && summary.clamped_inputs.abs_diff(above) <= 1,
            "{summary:?} against {above}"
        );
    }

    #[test]
    fn the_direct_inverse_the_offline_optimum_and_a_still_reference() {
        let (u, y) = step_test(1.0, 8);
        let t = trace(&u, &y);
        let f = file(2.0);
        let direct = run(&f, &t, Compensation::Direct(Arithmetic::F64)).unwrap();
        assert!(!direct.designed);
        assert_eq!(direct.latency_samples, 3.0);
        assert_eq!(direct.compensator, "the paper's direct inverse (eq. 7)");
        assert!(matches!(
            run(&f, &t, Compensation::Direct(Arithmetic::Fixed))
                .as_ref()
                .map_err(Error::unadvised),
            Err(Error::InvalidParameter {
                parameter: crate::error::Parameter::Arithmetic,
                ..
            })
        ));
        // The band-limited design has no noise and prior for the offline optimum.
        assert!(matches!(
            run(&f, &t, Compensation::Offline)
                .as_ref()
                .map_err(Error::unadvised),
            Err(Error::InvalidParameter {
                parameter: crate::error::Parameter::Offline,
                ..
            })
        ));
        // A reference that does not move: compensated, but no error against it.
        let flat = vec![0.0; u.len()];
        let quiet = run(
            &f,
            &trace(&flat, &y),
            Compensation::Designed(Arithmetic::F32),
        )
        .unwrap();
        assert!(quiet.still_reference && quiet.error.is_none());
    }

    #[test]
    fn a_design_for_steps_gives_way_on_a_slow_run_it_would_make_worse() {
        // A second-order probe at 1.5 kHz behind a sample of delay; noise 1e-3 on the probe.
        let (m, _) = crate::testing::second_order(1500.0, 0.3, 10_000.0, 1);
        let noisy = |u: &[f64], seed: u64| -> Vec<f64> {
            let n = crate::testing::gaussian(u.len(), seed);
            m.simulate(u)
                .iter()
                .zip(n)
                .map(|(y, n)| y + 1e-3 * n)
                .collect()
        };
        // The optimum for steps, from a step test.
        let step: Vec<f64> = (0..4000)
            .map(|k| if k < 1000 { 0.0 } else { 1.0 })
            .collect();
        let y_step = noisy(&step, 21);
        let tests = [crate::fit::Test {
            name: "step",
            u: &step,
            y: &y_step,
        }];
        let noise = inverse::optimal::estimate_noise(&tests);
        let prior = inverse::optimal::estimate_prior(&tests, &noise);
        let d = inverse::optimal::design(&m, &noise, &prior, &Default::default()).unwrap();
        let mut f = file(2.0);
        f.model = m.clone();
        f.inverse = Some(d.clone());
        // A slow run (a 3 Hz swing), where the step design's boost above 1.5 kHz only adds
        // noise.
        let slow: Vec<f64> = (0..40_000)
            .map(|k| (2.0 * std::f64::consts::PI * 3.0 * k as f64 / 10_000.0).sin())
            .collect();
        let y_slow = noisy(&slow, 22);
        let t = trace(&slow, &y_slow);
        // The stored design alone is worse than the raw probe there.
        let stored = d.run::<f64>(&y_slow).unwrap();
        let latency = d.latency_samples.round() as usize;
        let (stored_error, _) = inverse::aligned_error(&slow, &stored, latency - 2..=latency + 2);
        let (raw_error, _) = inverse::aligned_error(&slow, &y_slow, 0..=60);
        assert!(stored_error > raw_error, "{stored_error} {raw_error}");
        // compensate sees it from the probe signal alone, and runs the board's all the same.
        let board = run(&f, &t, Compensation::Designed(Arithmetic::F64)).unwrap();
        assert!(board.fall_back.is_none() && !board.host_only);
        assert!(board.predicted.unwrap().ratio() >= inverse::check::RUN_MARGIN);
        assert!(board.error.unwrap().worse(), "{:?}", board.error);
        // Asked to, it runs one that is not worse, on the host only.
        let c = run(&f, &t, Compensation::AdaptedToRun).unwrap();
        assert!(c.host_only);
        let fell = c.fall_back.as_ref().expect("a fall-back");
        assert!(
            c.predicted.unwrap().ratio() >= inverse::check::RUN_MARGIN,
            "{:?}",
            c.predicted
        );
        assert!(fell.chosen.ratio() < 1.0, "{fell:?}");
        let e = c.error.unwrap();
        assert!(e.u_hat < e.raw, "{e:?}");
        assert_eq!(
            c.compensator,
            "a compensator chosen for this run (host only: a board runs the model file's)"
        );
        // On a step like its own the stored design stays, asked to adapt or not.
        let again = noisy(&step, 23);
        let kept = run(&f, &trace(&step, &again), Compensation::AdaptedToRun).unwrap();
        assert!(
            kept.fall_back.is_none() && !kept.host_only,
            "{:?}",
            kept.fall_back
        );
        assert!(kept.predicted.unwrap().ratio() < inverse::check::RUN_MARGIN);
        assert!(!kept.error.unwrap().worse());
    }

    /// A gas temperature puts the model file at it before the run, as
    /// [`at_temperature`](super::super::at_temperature) does; a model without a temperature
    /// law refuses one.
    #[test]
    fn a_temperature_retargets_the_file_before_the_run() {
        let (u, y) = step_test(1.0, 10);
        let t = trace(&u, &y);
        let mut warm = file(2.0);
        warm.effects = vec![Effect::parse("temperature=293.15").unwrap()];
        let request = CompensateRequest {
            file: &warm,
            model_path: Path::new("probe.toml"),
            probe: &t.y,
            reference: t.u.as_deref(),
            compensation: Compensation::Designed(Arithmetic::F64),
            temperature_k: Some(343.15),
        };
        let hot = compensate(&request).unwrap();
        let retargeted = super::super::at_temperature(&warm, 343.15).unwrap();
        let by_hand = compensate(&CompensateRequest {
            file: &retargeted,
            temperature_k: None,
            ..request
        })
        .unwrap();
        assert_eq!(hot, by_hand);
        let as_stored = compensate(&CompensateRequest {
            temperature_k: None,
            ..request
        })
        .unwrap();
        assert_ne!(hot.u_hat, as_stored.u_hat);
        assert!(compensate(&CompensateRequest {
            file: &file(2.0),
            ..request
        })
        .is_err());
    }

    #[test]
    fn the_probes_offset_is_removed_before_the_compensator() {
        let (u, y) = step_test(1.0, 9);
        let shifted: Vec<f64> = y.iter().map(|v| v + 0.25).collect();
        let plain = run(
            &file(2.0),
            &trace(&u, &y),
            Compensation::Designed(Arithmetic::F64),
        )
        .unwrap();
        let mut with_offset = file(2.0);
        with_offset.effects = vec![Effect::Offset { value: 0.25 }];
        let removed = run(
            &with_offset,
            &trace(&u, &shifted),
            Compensation::Designed(Arithmetic::F64),
        )
        .unwrap();
        let worst = plain
            .u_hat
            .iter()
            .zip(&removed.u_hat)
            .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
        assert!(worst < 1e-9, "{worst}");
        let (a, b) = (plain.error.unwrap(), removed.error.unwrap());
        assert!((a.u_hat - b.u_hat).abs() < 1e-12, "{a:?} {b:?}");
    }
}
