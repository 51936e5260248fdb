//! The guarantee: every compensator is checked on the tests against the raw probe before it is
//! stored; one that is not better falls back (a narrower band, then the delay alone), and the
//! record of what was tried travels with the design.
//!
//! "Better" means a lower error of `u_hat` against the recorded reference than the raw probe's,
//! both at their best time alignment ([`super::reconstruct_with`]), on every test given, by at
//! least [`MARGIN`] (a gain won within the scatter between two runs of the same kind is not
//! evidence). The caller gives the held-out tests, or the estimation test when it is alone.

use serde::{Deserialize, Serialize};

use super::optimal::{self, NoiseModel, OptimalOptions, SignalPrior};
use super::{design_auto_with, reconstruct_with, Design, Options, Reconstruction};
use crate::design::DesignError;
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::fit::Test;

/// A design is kept only when its error is below this fraction of the raw probe's on every
/// test; otherwise the probe passes unchanged. A gain of a few per cent on one run is within
/// the scatter between runs of the same kind: on the bench's drawn probes, given a held-out
/// run, designs that won by less than that on it lost on another run as often as they won
/// (BENCHMARKS.md).
pub const MARGIN: f64 = 0.95;

/// What the check found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// The design asked for is better than the raw probe on every test.
    Better,
    /// The design asked for was not; a narrower one is.
    FellBack,
    /// Nothing was better than the raw probe by the margin, the delay alone included: the
    /// probe passes unchanged, and `export` refuses it without `--force`.
    NotBetter,
    /// No test with a reference to check on.
    Unchecked,
}

/// The check's record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Check {
    /// The verdict.
    pub verdict: Verdict,
    /// Each design rejected before the one kept, with the numbers that rejected it.
    #[serde(default)]
    pub rejected: Vec<String>,
    /// Largest ratio of `u_hat`'s error to the raw probe's over the tests (below 1 is better).
    pub worst_ratio: f64,
}

/// Which design the user asked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// The noise-aware optimum ([`optimal::design`]); noise and prior measured on the tests
    /// unless given.
    Optimal {
        /// Latency cap and reduced-order family.
        options: OptimalOptions,
        /// The noise, when known (else measured on the tests).
        noise: Option<NoiseModel>,
        /// The prior, when known (else from the tests' references).
        prior: Option<SignalPrior>,
    },
    /// A stable inverse times a low-pass, its corner given or chosen on the tests.
    BandLimited(Options),
}

/// The design that only undoes the DC gain: `u_hat` is the probe signal over the model's DC
/// gain, as late as the probe follows a slow signal (its group delay at zero frequency, at
/// least the delay). The last fall-back.
///
/// # Errors
/// [`DesignError::DcGain`] when the model's DC gain is zero or not finite.
pub fn delay_only(model: &Model) -> Result<Design> {
    let dc = model.dc_gain();
    if !(dc.is_finite() && dc.abs() > 1e-12) {
        return Err(DesignError::DcGain { dc_gain: dc }.into());
    }
    let latency = model
        .dc_group_delay()
        .map_or(model.delay as f64, |t| t.max(model.delay as f64));
    Ok(Design {
        method: super::DesignMethod::of(super::MethodKind::DelayOnly),
        lowpass: super::LowpassKind::Bessel,
        lowpass_order: 1,
        lowpass_hz: 0.5 * model.fs,
        bandwidth_selection: "none".into(),
        gain: 1.0 / dc,
        sections: vec![[1.0, 0.0, 0.0, 0.0, 0.0]],
        latency_samples: latency,
        latency_s: latency / model.fs,
        corrected_bandwidth_hz: 0.0,
        noise_gain: 1.0 / dc.abs(),
        in_band_magnitude_error_db: 0.0,
        in_band_phase_error_deg: 0.0,
        pole_margin: 1.0,
        reflected_zeros: Vec::new(),
        pulled_zeros: Vec::new(),
        candidates: Vec::new(),
        reconstruction: Vec::new(),
        fixed: None,
        fixed_direct: None,
        noise: None,
        prior: None,
        budget: None,
        check: None,
        model_sha256: None,
    })
}

/// The design that leaves the probe signal as it is (gain 1, the probe's own latency): the
/// last fall-back when not even undoing the DC gain beats the raw probe on the tests.
///
/// # Errors
/// As [`delay_only`].
pub fn pass_through(model: &Model) -> Result<Design> {
    let mut d = delay_only(model)?;
    d.method = super::DesignMethod::of(super::MethodKind::PassThrough);
    d.gain = 1.0;
    d.noise_gain = 1.0;
    Ok(d)
}

/// What a run's own probe spectrum predicts for a design and for the raw probe, when the run
/// has no reference to judge on ([`optimal::RunPressure::predicted`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunCheck {
    /// The design's predicted error (RMS, pressure units) at its best latency.
    pub design: f64,
    /// The raw probe's, at its best alignment.
    pub raw: f64,
}

impl RunCheck {
    /// The design's predicted error over the raw probe's (below 1 is better).
    #[must_use]
    pub fn ratio(&self) -> f64 {
        self.design / self.raw
    }
}

/// A design's run check keeps it when its predicted error is below this fraction of the raw
/// probe's; otherwise [`on_run`] looks for one that is.
pub const RUN_MARGIN: f64 = 0.95;

/// A run's probe spectrum through the model and the noise a design was made for: what
/// [`on_run`] judges designs with.
struct RunJudge<'a> {
    model: &'a Model,
    pressure: optimal::RunPressure,
    raw: f64,
}

impl<'a> RunJudge<'a> {
    fn new(
        design: &Design,
        model: &'a Model,
        spectrum: impl FnOnce() -> Option<optimal::RunSpectrum>,
    ) -> Option<Self> {
        let noise = design.noise.as_ref()?;
        Self::with_spectrum(model, noise, &spectrum()?, design.latency_samples)
    }

    /// The run `y` through `model` and `noise`, the raw probe aligned within the lags a design
    /// of `latency` samples is compared on.
    fn with_noise(model: &'a Model, noise: &NoiseModel, y: &[f64], latency: f64) -> Option<Self> {
        Self::with_spectrum(model, noise, &optimal::RunSpectrum::measure(y)?, latency)
    }

    /// [`RunJudge::with_noise`] from the run's spectrum.
    fn with_spectrum(
        model: &'a Model,
        noise: &NoiseModel,
        spectrum: &optimal::RunSpectrum,
        latency: f64,
    ) -> Option<Self> {
        let pressure = spectrum.pressure(model, noise);
        let latency = latency.round().max(0.0) as usize;
        let (_, raw_lags) = super::comparison_lags(None, latency, latency, model.delay);
        let raw = pressure.predicted(1.0, &[], raw_lags);
        Some(Self {
            model,
            pressure,
            raw,
        })
    }

    fn judge(&self, d: &Design) -> RunCheck {
        let latency = d.latency_samples.round().max(0.0) as usize;
        let (lags, _) = super::comparison_lags(Some(d), latency, latency, self.model.delay);
        RunCheck {
            design: self.pressure.predicted(d.gain, &d.sections, lags),
            raw: self.raw,
        }
    }
}

/// Levels of the signal prior tried for `--signal` runs recorded by the probe alone, in
/// decades of the increments' variance around the level their increments give: a hundred
/// times louder to ten thousand times quieter, in half decades.
pub const RUN_PRIOR_DECADES: [f64; 13] = [
    2.0, 1.5, 1.0, 0.5, 0.0, -0.5, -1.0, -1.5, -2.0, -2.5, -3.0, -3.5, -4.0,
];

/// The signal prior for runs the probe recorded alone (`runs`, probe signals): among the
/// `levels` (the level the runs' increments give, and the step tests' own) each scaled by
/// [`RUN_PRIOR_DECADES`], the one whose optimum for `noise` and `options` has the least
/// predicted mean-square error on the runs' own spectra, each relative to the raw probe's on
/// the same run and averaged over the runs. A random walk's level read from the increments
/// misjudges a run whose spectrum is not a random walk's (turbulence that ends at a band
/// limit, a train of wakes), and says nothing when the increments do not rise above the
/// probe's noise (a level of zero: only a bound); the error the runs' spectra predict judges
/// the compensator itself, whichever level it starts from. The first level with a positive
/// increment when no run is long enough for a spectrum or no level gives a design.
#[must_use]
pub fn prior_for_runs(
    model: &Model,
    noise: &NoiseModel,
    levels: &[SignalPrior],
    options: &OptimalOptions,
    runs: &[&[f64]],
) -> SignalPrior {
    let Some(&estimate) = levels
        .iter()
        .find(|p| p.increment_std > 0.0 && p.increment_std.is_finite())
        .or(levels.first())
    else {
        return SignalPrior {
            increment_std: 0.0,
            increment_pole: 0.0,
            source: optimal::PriorSource::Runs,
        };
    };
    let candidates: Vec<(SignalPrior, Design)> = levels
        .iter()
        .filter(|level| level.increment_std > 0.0)
        .flat_map(|level| {
            RUN_PRIOR_DECADES
                .iter()
                .map(move |decades| (level, decades))
        })
        .filter_map(|(level, decades)| {
            let p = SignalPrior {
                increment_std: level.increment_std * 10f64.powf(0.5 * decades),
                source: optimal::PriorSource::Runs,
                ..*level
            };
            optimal::design(model, noise, &p, options)
                .ok()
                .map(|d| (p, d))
        })
        .collect();
    // Every candidate judged against the same raw error on each run: aligned within the
    // widest candidate's lags.
    let widest = candidates
        .iter()
        .map(|(_, d)| d.latency_samples)
        .fold(0.0, f64::max);
    let judges: Vec<RunJudge<'_>> = runs
        .iter()
        .filter_map(|y| RunJudge::with_noise(model, noise, y, widest))
        .filter(|j| j.raw > 0.0)
        .collect();
    if judges.is_empty() {
        return estimate;
    }
    candidates
        .into_iter()
        .map(|(p, d)| {
            let relative = judges
                .iter()
                .map(|j| j.judge(&d).ratio().powi(2))
                .sum::<f64>()
                / judges.len() as f64;
            (relative, p)
        })
        .filter(|(r, _)| r.is_finite())
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(estimate, |(_, p)| p)
}

/// Which designs the run check may run instead of the stored one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunCandidates {
    /// None: the stored design is only judged.
    JudgeOnly,
    /// The delay alone and the raw probe (no redesign: fixed point has no plan for one).
    Calibration,
    /// Those, and the stored optimum under a prior ten to ten thousand times quieter.
    Redesigns,
}

/// A compensator chosen for a run on which the stored one is predicted not to beat the raw
/// probe.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFallBack {
    /// The design run instead.
    pub design: Design,
    /// It, in words: `the optimum under a prior 100 times quieter (-3 dB band 12000 Hz)`, `the
    /// delay alone`, `the probe passed through`.
    pub what: String,
    /// Its prediction on the run.
    pub chosen: RunCheck,
}

/// What the run check found on a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunJudgement {
    /// The stored design's prediction on the run, beside the raw probe's.
    pub stored: RunCheck,
    /// The design run instead, when the stored one is not predicted to beat the raw probe by
    /// [`RUN_MARGIN`] and another is predicted to do better than it.
    pub fall_back: Option<RunFallBack>,
}

/// Judges the stored `design` on the probe signal `y` of a run, from the run's own spectrum
/// and the design's stored noise ([`optimal::RunPressure`]), beside the raw probe; when it is
/// not predicted to beat the raw probe by [`RUN_MARGIN`], chooses among `candidates` the design
/// of least predicted error, if that is less than the stored one's. `None` for a design
/// without a noise model, one that passes the probe on, or a record too short for a spectrum.
#[must_use]
pub fn on_run(
    design: &Design,
    model: &Model,
    y: &[f64],
    candidates: RunCandidates,
) -> Option<RunJudgement> {
    on_run_measured(
        design,
        model,
        || optimal::RunSpectrum::measure(y),
        candidates,
    )
}

/// Whether [`on_run`] looks at the run's spectrum for `design`: not for a design without a
/// noise model or one that passes the probe on (a streamed run then needs no spectrum).
#[must_use]
pub fn judges_runs(design: &Design) -> bool {
    !design.passes_probe() && design.noise.is_some()
}

/// [`on_run`] with the run's spectrum measured by `spectrum` (a run streamed from its file:
/// [`optimal::on_run::SpectrumStream`]), called only when [`judges_runs`].
#[must_use]
pub fn on_run_measured(
    design: &Design,
    model: &Model,
    spectrum: impl FnOnce() -> Option<optimal::RunSpectrum>,
    candidates: RunCandidates,
) -> Option<RunJudgement> {
    if design.passes_probe() {
        return None;
    }
    let judge = RunJudge::new(design, model, spectrum)?;
    let stored = judge.judge(design);
    if stored.ratio() < RUN_MARGIN || candidates == RunCandidates::JudgeOnly {
        return Some(RunJudgement {
            stored,
            fall_back: None,
        });
    }
    let redesign = candidates == RunCandidates::Redesigns;
    let mut candidates: Vec<(String, Design)> = Vec::new();
    if let (true, Some(prior), Some(noise)) = (redesign, design.prior, design.noise) {
        let options = OptimalOptions {
            max_latency_samples: Some(design.latency_samples.round().max(0.0) as usize),
            lowpass: design.lowpass,
            lowpass_order: design.lowpass_order,
            ..OptimalOptions::default()
        };
        for quieter in [10.0, 100.0, 1e3, 1e4] {
            let p = SignalPrior {
                increment_std: prior.increment_std / f64::sqrt(quieter),
                ..prior
            };
            if let Ok(d) = optimal::design(model, &noise, &p, &options) {
                let what = format!(
                    "the optimum under a prior {quieter} times quieter (-3 dB band {:.0} Hz)",
                    d.lowpass_hz
                );
                candidates.push((what, d));
            }
        }
    }
    candidates.extend(delay_only(model).ok().map(|d| {
        (
            "the delay alone (the probe over its DC gain)".to_string(),
            d,
        )
    }));
    candidates.extend(
        pass_through(model)
            .ok()
            .map(|d| ("the probe passed through".to_string(), d)),
    );
    // The stored design stays unless another is predicted to do better on this run.
    let fall_back = candidates
        .into_iter()
        .map(|(what, d)| (judge.judge(&d), what, d))
        .filter(|(c, _, _)| c.design < stored.design)
        .min_by(|a, b| a.0.design.total_cmp(&b.0.design))
        .map(|(chosen, what, design)| RunFallBack {
            design,
            what,
            chosen,
        });
    Some(RunJudgement { stored, fall_back })
}

/// Reconstructions of every test, and the worst error ratio against the raw probe.
fn judge(
    design: &Design,
    model: &Model,
    tests: &[Test<'_>],
    nonlinear_gain: f64,
) -> (Vec<Reconstruction>, f64) {
    let mut out = Vec::with_capacity(tests.len());
    let mut worst = 0.0f64;
    for t in tests {
        // A design the board's code refuses to run loses against the raw probe.
        let r = match reconstruct_with(design, model, t, nonlinear_gain) {
            Ok(r) => r,
            Err(_) => Reconstruction {
                file: t.name.to_string(),
                nrmse_u_hat: f64::INFINITY,
                nrmse_raw: f64::NAN,
                lag: 0,
                range: None,
                model_part: None,
            },
        };
        let ratio = r.nrmse_u_hat / r.nrmse_raw;
        worst = worst.max(if ratio.is_nan() { f64::INFINITY } else { ratio });
        out.push(r);
    }
    (out, worst)
}

/// Designs the compensator asked for and checks it on `tests` against the raw probe; when it
/// is not better on every test, tries narrower designs (the optimum with a prior ten and a
/// hundred times quieter, or the band-limited inverse at a half and a quarter of its corner),
/// then the delay alone. The kept design carries the [`Check`] and its reconstructions.
///
/// # Errors
/// As the designs; a design that fails to build is skipped in favour of the next.
pub fn design_checked(
    model: &Model,
    tests: &[Test<'_>],
    request: &Request,
    nonlinear_gain: f64,
) -> Result<Design> {
    let mut candidates: Vec<Result<Design>> = Vec::new();
    match request {
        Request::Optimal {
            options,
            noise,
            prior,
        } => {
            let noise = noise.unwrap_or_else(|| optimal::estimate_noise(tests));
            let prior = prior.unwrap_or_else(|| optimal::estimate_prior(tests, &noise));
            for quieter in [1.0, 0.1, 0.01] {
                let p = SignalPrior {
                    increment_std: prior.increment_std * f64::sqrt(quieter),
                    ..prior
                };
                candidates.push(optimal::design(model, &noise, &p, options));
                // Nothing narrower is tried when the first is refused for a reason of its own
                // (a latency cap below the delay).
                if matches!(
                    candidates.first(),
                    Some(Err(
                        Error::InvalidArgument { .. } | Error::InvalidParameter { .. }
                    ))
                ) {
                    break;
                }
            }
        }
        Request::BandLimited(options) => {
            let first = design_auto_with(model, tests, options, nonlinear_gain);
            let corner = first.as_ref().map(|d| d.lowpass_hz).ok();
            candidates.push(first);
            if let Some(fc) = corner {
                for factor in [0.5, 0.25] {
                    let narrower = Options {
                        bandwidth_hz: Some(fc * factor),
                        ..*options
                    };
                    candidates.push(super::design(model, fc * factor, &narrower));
                }
            }
        }
    }
    let mut rejected = Vec::new();
    let mut first_error = None;
    for (i, candidate) in candidates.into_iter().enumerate() {
        let mut d = match candidate {
            Ok(d) => d,
            Err(e) if e.is_the_callers() => return Err(e),
            Err(e) => {
                rejected.push(format!("design {} failed: {e}", i + 1));
                first_error.get_or_insert(e);
                continue;
            }
        };
        if tests.is_empty() {
            d.check = Some(Check {
                verdict: Verdict::Unchecked,
                rejected,
                worst_ratio: f64::NAN,
            });
            return Ok(d);
        }
        let (recon, worst) = judge(&d, model, tests, nonlinear_gain);
        if worst < MARGIN {
            d.reconstruction = recon;
            d.check = Some(Check {
                verdict: if i == 0 && rejected.is_empty() {
                    Verdict::Better
                } else {
                    Verdict::FellBack
                },
                rejected,
                worst_ratio: worst,
            });
            return Ok(d);
        }
        rejected.push(describe(&d, &recon));
    }
    // The delay alone: the raw probe, calibrated; when that does not win by the margin either
    // (a DC gain within the scatter of 1, or fitted a little off), the raw probe as it is.
    let mut d = delay_only(model).map_err(|e| first_error.unwrap_or(e))?;
    let (mut recon, mut worst) = judge(&d, model, tests, 0.0);
    if worst >= MARGIN {
        rejected.push(describe(&d, &recon));
        d = pass_through(model)?;
        (recon, worst) = judge(&d, model, tests, 0.0);
    }
    d.reconstruction = recon;
    d.check = Some(Check {
        verdict: if worst < MARGIN {
            Verdict::FellBack
        } else {
            Verdict::NotBetter
        },
        rejected,
        worst_ratio: worst,
    });
    Ok(d)
}

/// One line on a rejected design: what it was and the test it lost on.
fn describe(d: &Design, recon: &[Reconstruction]) -> String {
    let worst = recon
        .iter()
        .max_by(|a, b| (a.nrmse_u_hat / a.nrmse_raw).total_cmp(&(b.nrmse_u_hat / b.nrmse_raw)));
    match worst {
        Some(r) => format!(
            "{} (-3 dB band {:.1} Hz): u_hat {:.3} % against the raw probe's {:.3} % on {}",
            d.method.short(),
            d.lowpass_hz,
            100.0 * r.nrmse_u_hat,
            100.0 * r.nrmse_raw,
            r.file
        ),
        None => d.method.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn leaky_line() -> Model {
        // A first-order lag (pole 0.9) behind a leak (pole 0.9995, zero 0.99995), DC gain 0.95.
        Model {
            fs: 10_000.0,
            delay: 3,
            a: vec![-(0.9 + 0.9995), 0.9 * 0.9995],
            b: vec![0.95, -0.95 * 0.99995],
        }
    }

    /// A unit step at sample 500 of 2000.
    fn step() -> Vec<f64> {
        (0..2000).map(|k| if k < 500 { 0.0 } else { 1.0 }).collect()
    }

    /// The band-limited inverse at 200 Hz of `m`, checked on the one test `(u, y)`.
    fn checked_on(m: &Model, u: &[f64], y: &[f64]) -> Design {
        let tests = [Test { name: "t", u, y }];
        let request = Request::BandLimited(Options {
            bandwidth_hz: Some(200.0),
            ..Options::default()
        });
        design_checked(m, &tests, &request, 0.0).unwrap()
    }

    #[test]
    fn runs_inside_the_probes_band_get_a_quieter_prior_and_a_smaller_error() {
        // A first-order probe (time constant 20 samples: a band of 80 Hz at 10 kHz).
        let m = Model {
            fs: 10_000.0,
            delay: 2,
            a: vec![-0.95],
            b: vec![0.05],
        };
        let noise = optimal::NoiseModel {
            probe_white_std: 2e-3,
            probe_ar_pole: 0.0,
            probe_ar_std: 0.0,
            reference_std: 0.0,
            source: crate::fit::step::NoiseSource::PreStep,
        };
        let n = 16_000;
        // Slow fluctuations (5 to 20 Hz, far inside the band) and a train of unit steps, each
        // with the probe's noise.
        let slow: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / m.fs;
                0.2 * (2.0 * PI * 5.0 * t).sin()
                    + 0.1 * (2.0 * PI * 13.0 * t + 1.0).sin()
                    + 0.05 * (2.0 * PI * 20.0 * t + 2.0).sin()
            })
            .collect();
        let steps: Vec<f64> = (0..n).map(|k| ((k / 1500) % 2) as f64).collect();
        let recorded = |u: &[f64], seed| crate::testing::with_noise(&m.simulate(u), 2e-3, seed);
        let (y_slow, y_steps) = (recorded(&slow, 5), recorded(&steps, 6));
        // The level a step in 2000 samples gives.
        let estimate = SignalPrior {
            increment_std: (1.0f64 / 2000.0).sqrt(),
            increment_pole: 0.0,
            source: optimal::PriorSource::Runs,
        };
        let options = OptimalOptions::default();
        let for_slow = prior_for_runs(&m, &noise, &[estimate], &options, &[&y_slow]);
        let for_steps = prior_for_runs(&m, &noise, &[estimate], &options, &[&y_steps]);
        assert!(
            for_slow.increment_std < 0.1 * for_steps.increment_std,
            "{for_slow:?} {for_steps:?}"
        );
        // On the slow run, the chosen prior's optimum beats the estimate's, measured against
        // the true pressure at each one's latency.
        let error = |p: &SignalPrior| {
            let d = optimal::design(&m, &noise, p, &options).unwrap();
            let u_hat = d.run::<f64>(&y_slow).unwrap();
            let lag = d.latency_samples.round() as usize;
            let sse: f64 = (2000..n).map(|k| (u_hat[k] - slow[k - lag]).powi(2)).sum();
            (sse / (n - 2000) as f64).sqrt()
        };
        let (chosen, assumed) = (error(&for_slow), error(&estimate));
        assert!(chosen < 0.7 * assumed, "{chosen} {assumed}");
        // No run long enough for a spectrum: the estimate stands.
        assert_eq!(
            prior_for_runs(&m, &noise, &[estimate], &options, &[&y_slow[..50]]),
            estimate
        );
        // Increments that do not rise above the noise give a level of zero, which is only a
        // bound: the search starts from the next level (the step tests'), judged on the run as
        // before, and ends at the same prior the slow run chose from the estimate.
        let silent = SignalPrior {
            increment_std: 0.0,
            ..estimate
        };
        let from_steps = prior_for_runs(&m, &noise, &[silent, estimate], &options, &[&y_slow]);
        assert_eq!(from_steps, for_slow);
        // Two levels: the search covers both, so it predicts no more error than from either.
        let predicted = |p: &SignalPrior| {
            let d = optimal::design(&m, &noise, p, &options).unwrap();
            RunJudge::with_noise(&m, &noise, &y_slow, d.latency_samples)
                .unwrap()
                .judge(&d)
                .ratio()
        };
        let loud = SignalPrior {
            increment_std: 1e3 * estimate.increment_std,
            ..estimate
        };
        let both = prior_for_runs(&m, &noise, &[loud, estimate], &options, &[&y_slow]);
        let alone = prior_for_runs(&m, &noise, &[loud], &options, &[&y_slow]);
        assert!(
            predicted(&both) <= predicted(&alone) * (1.0 + 1e-9),
            "{both:?} {alone:?}"
        );
    }

    #[test]
    fn delay_only_passes_the_probe_over_its_dc_gain() {
        let m = leaky_line();
        let d = delay_only(&m).unwrap();
        let y = vec![0.5; 10];
        let u = d.run::<f64>(&y).unwrap();
        assert!((u[9] - 0.5 / m.dc_gain()).abs() < 1e-12);
    }

    #[test]
    fn a_compensator_worse_than_the_raw_probe_is_never_kept_silently() {
        // A first-order probe; the tests' reference is the probe signal itself (a probe with
        // no lag): any compensation can only lose against the raw probe.
        let m = Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.9],
            b: vec![0.1],
        };
        let u = step();
        let d = checked_on(&m, &u, &u);
        let check = d.check.unwrap();
        assert_ne!(check.verdict, Verdict::Better);
        assert!(!check.rejected.is_empty());
        assert_eq!(
            d.method.kind(),
            crate::design::inverse::MethodKind::PassThrough,
            "{}",
            d.method
        );
    }

    #[test]
    fn when_undoing_the_dc_gain_loses_the_probe_passes_unchanged() {
        // A model whose DC gain (0.8) the tests do not bear out: the reference is the probe
        // signal itself, so dividing by 0.8 only adds error and the raw probe is kept as is.
        let m = Model {
            fs: 1000.0,
            delay: 0,
            a: vec![-0.9],
            b: vec![0.08],
        };
        let u = step();
        // A little deterministic noise on the probe, so that the raw probe's error is not 0.
        let y: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(k, v)| v + 1e-3 * ((k * 7919 % 13) as f64 - 6.0))
            .collect();
        let d = checked_on(&m, &u, &y);
        assert_eq!(
            d.method.kind(),
            crate::design::inverse::MethodKind::PassThrough,
            "{}",
            d.method
        );
        assert_eq!(d.gain, 1.0);
        let check = d.check.unwrap();
        assert_eq!(check.verdict, Verdict::NotBetter);
        assert!(
            check.rejected.iter().any(|r| r.starts_with("delay only")),
            "{:?}",
            check.rejected
        );
        // The raw probe as it is: its error is the raw probe's.
        assert!(
            (check.worst_ratio - 1.0).abs() < 1e-12,
            "{}",
            check.worst_ratio
        );
    }

    #[test]
    fn delay_only_needs_a_dc_gain() {
        let model = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-0.5],
            b: vec![0.0],
        };
        let e = delay_only(&model).unwrap_err();
        assert!(
            matches!(e.stage(), Some(DesignError::DcGain { dc_gain }) if *dc_gain == 0.0),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "delay-only compensator: the model's DC gain is 0"
        );
    }
}
