//! Naming the missing physical effect from the evidence.
//!
//! This module owns the catalogue's decision: for a model and its tests it ranks candidate
//! effects ([`Candidate`]), each with the numbers behind it, a physical reading, and the exact
//! change that adds it. Two kinds of evidence are combined:
//!
//! 1. the residual's signature on each test ([`crate::modelling::evidence`]): a narrow spectral peak for
//!    a mode, a level before the step for an offset, a ramp for a drift, a slow creep after
//!    the step for a leak, correlation in time without a cause in the input for coloured
//!    noise, a peak in the reference's own increments at the frequency where the probe's
//!    residual peaks for a sensor resonance (a line or cavity mode never shows in the
//!    reference, so a matched sensor resonance goes before `mode`), and natural frequencies of
//!    the tests fitted alone that all move by one common factor against the model's, with the
//!    damping about the same, for a temperature ([`temperature_evidence`]; both damping laws
//!    of [`crate::modelling::effects::TemperatureDamping`] are tried and the better offered, its `change`
//!    `--add temperature` or `--add temperature-viscous`); and across tests
//!    ([`amplitude_signature`]), a damping that rises with the step's amplitude and a residual
//!    that grows faster than the step, for nonlinear damping;
//! 2. a trial: the model is refitted on the estimation test with the effect added
//!    ([`crate::modelling::effects::fit_with`]) and judged on the held-out tests. A candidate whose
//!    signature is present but whose trial does not lower the held-out error is not offered.
//!
//! The score is `ln(error before / error after)` on the held-out tests (the estimation test
//! when there is none). `none` is the verdict when every test is at its noise floor with white
//! residuals, or when no candidate's trial helps.

use serde::Serialize;
use serde_json::{json, Value};

use crate::error::Result;
use crate::fit::model::{Model, Uncertainty};
use crate::fit::{Method, Options, Order, Test};
use crate::modelling::effects::{self, Effect, EffectKind, FitChanges};
use crate::modelling::evidence::TestEvidence;

/// A trial must lower the held-out error by at least this factor to be offered.
pub const MIN_IMPROVEMENT: f64 = 1.15;

/// A held-out error that falls this much in a trial overrules a noise floor that says nothing
/// is missing.
pub const FLOOR_OVERRULED: f64 = 1.4;

/// Score charged per parameter an effect adds: between two effects that explain the data
/// equally well, the simpler one ranks first (an offset before a drift, a leak before a mode).
pub const PARAMETER_PENALTY: f64 = 0.03;

/// What a diagnosis names: a missing effect, nothing missing, or something missing that no
/// effect of the catalogue explains. Its text is the candidate's `kind` in `--json`: the
/// effect's name, exactly what `unlag fit --add` takes ([`EffectKind`]), or `none`, or
/// `unexplained` (verdicts, not effects: there is nothing to add for them, so they are no
/// [`EffectKind`]).
///
/// ```
/// use unlag::modelling::diagnose::Finding;
/// use unlag::modelling::effects::EffectKind;
///
/// assert_eq!(Finding::Missing(EffectKind::Leak).to_string(), "leak");
/// assert_eq!(Finding::Nothing.to_string(), "none");
/// assert_eq!("unexplained".parse(), Ok(Finding::Unexplained));
/// assert_eq!(Finding::Missing(EffectKind::Mode).effect(), Some(EffectKind::Mode));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Finding {
    /// This effect is missing: `unlag fit --add` it.
    Missing(EffectKind),
    /// `none`: the residual is what the noise leaves; nothing to add.
    Nothing,
    /// `unexplained`: the residual is above the noise floor and no effect's trial lowers it.
    Unexplained,
}

impl Finding {
    /// The effect to add, when one is named.
    #[must_use]
    pub const fn effect(self) -> Option<EffectKind> {
        match self {
            Self::Missing(k) => Some(k),
            Self::Nothing | Self::Unexplained => None,
        }
    }

    /// Its text: the effect's name, `none` or `unexplained`.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::Missing(k) => k.as_str(),
            Self::Nothing => "none",
            Self::Unexplained => "unexplained",
        }
    }
}

impl core::fmt::Display for Finding {
    /// Its text ([`Finding::as_str`]), padded as the formatter asks.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.pad(self.as_str())
    }
}

impl core::str::FromStr for Finding {
    type Err = effects::UnknownKind;

    fn from_str(s: &str) -> core::result::Result<Self, Self::Err> {
        match s {
            "none" => Ok(Self::Nothing),
            "unexplained" => Ok(Self::Unexplained),
            _ => s.parse().map(Self::Missing),
        }
    }
}

impl Serialize for Finding {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> serde::Deserialize<'de> for Finding {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl PartialEq<EffectKind> for Finding {
    fn eq(&self, other: &EffectKind) -> bool {
        *self == Self::Missing(*other)
    }
}

/// One ranked candidate.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// What it names: an effect, exactly what `unlag fit --add` takes (`mode`, `leak`,
    /// `offset`, `drift`, `delay`, `coloured-noise`, `nonlinear-damping`, `sensor-resonance`,
    /// `temperature`, `temperature-viscous`), or `none` or `unexplained`.
    pub kind: Finding,
    /// `ln(error before / error after)` of the trial, less [`PARAMETER_PENALTY`] per parameter
    /// the effect adds; larger is stronger.
    pub score: f64,
    /// The numbers behind it.
    pub evidence: Value,
    /// What it means physically.
    pub reading: String,
    /// The exact change that adds it.
    pub change: String,
    /// Held-out error before the trial.
    pub nrmse_before: f64,
    /// Held-out error after the trial.
    pub nrmse_after: f64,
    /// How far ahead of the next candidate it is (score difference; the last one's score).
    pub margin: f64,
    /// When the next candidate is within [`CLOSE_MARGIN`]: the test that would tell the two
    /// apart.
    pub separated_by: Option<String>,
    /// The model's stated uncertainty before the trial (its fit report's), when it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty_before: Option<Uncertainty>,
    /// The trial refit's stated uncertainty, when it could say: with `coloured-noise` it is
    /// computed on the data its noise model whitens, so coloured noise is no longer counted
    /// as independent samples.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty_after: Option<Uncertainty>,
}

impl Candidate {
    /// The stated uncertainty before and after the trial in one sentence, when both are
    /// known; with a noise model added, which figure to quote.
    #[must_use]
    pub fn uncertainty_text(&self) -> Option<String> {
        let (b, a) = (
            self.uncertainty_before.as_ref()?,
            self.uncertainty_after.as_ref()?,
        );
        let quote = if !b.noise_model && a.noise_model {
            " (the white-noise figure counts correlated samples as independent: it understates; \
             the whitened one is the one to quote)"
        } else {
            ""
        };
        Some(format!(
            "stated uncertainty (1 sigma): before, from {}: {}; after, from {}: {}{quote}",
            b.noise_text(),
            b.summary(),
            a.noise_text(),
            a.summary()
        ))
    }
}

/// Two candidates closer than this in score are close: the diagnosis names the test that
/// would separate them.
pub const CLOSE_MARGIN: f64 = 0.3;

/// The test that tells what `a` names from what `b` names, by what each one's signature
/// depends on.
#[must_use]
pub fn separating_test(a: Finding, b: Finding) -> String {
    use EffectKind::{ColouredNoise, Drift, Leak, Mode, NonlinearDamping, Offset, SensorResonance};
    let pair = |x: EffectKind, y: EffectKind| (a == x && b == y) || (a == y && b == x);
    let temperature = |k: Finding| {
        k.effect()
            .is_some_and(|k| k.family() == EffectKind::Temperature)
    };
    if pair(Drift, Offset) || pair(Leak, Drift) {
        "a longer record after the step (a drift keeps growing, an offset stays, a leak settles)"
            .into()
    } else if pair(ColouredNoise, Drift) || pair(ColouredNoise, Offset) {
        "a record with no step, the pressure steady (the noise alone: it wanders both ways, a drift one way)".into()
    } else if temperature(a) || temperature(b) {
        "a test at another gas temperature, or the same temperature as the estimation test (a temperature moves every natural frequency by one factor)".into()
    } else if a == NonlinearDamping || b == NonlinearDamping {
        "steps of other sizes (amplitude-dependent losses change with the step, a linear effect does not)".into()
    } else if pair(Mode, SensorResonance) {
        "the reference transducer alone on a step (a diaphragm rings in it, a line mode does not)"
            .into()
    } else {
        "another step test of another size and direction, held out".into()
    }
}

/// The current state of a model file that a diagnosis starts from.
#[derive(Debug, Clone)]
pub struct Current<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its effects.
    pub effects: &'a [Effect],
    /// The method it was fitted with.
    pub method: Method,
    /// Its stated uncertainty (the fit report's), if any.
    pub uncertainty: Option<&'a Uncertainty>,
}

fn mean(x: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = x.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// A trial on a record longer than this refits on this many samples from just before the step
/// (the held-out error is still judged on the whole records): ranking the candidates needs
/// each effect's signature, which a quarter of a million samples show, not a shock-tube
/// record's full precision, and a trial on five million samples would cost a whole fit each.
pub const TRIAL_WINDOW: usize = 1 << 18;

/// Samples kept before the step in a trial's window.
const TRIAL_LEAD: usize = 200;

/// The stretch of `test` a trial refits on: all of it up to [`TRIAL_WINDOW`] samples, else
/// [`TRIAL_WINDOW`] samples from [`TRIAL_LEAD`] before the step (from the start when no step is
/// found).
fn trial_window<'a>(test: &Test<'a>) -> Test<'a> {
    let n = test.u.len().min(test.y.len());
    if n <= TRIAL_WINDOW {
        return *test;
    }
    let onset = crate::fit::step::find_step(test.u).map_or(0, |s| s.onset);
    let start = onset.saturating_sub(TRIAL_LEAD).min(n - TRIAL_WINDOW);
    let range = start..start + TRIAL_WINDOW;
    Test {
        name: test.name,
        u: test.u.get(range.clone()).unwrap_or(test.u),
        y: test.y.get(range).unwrap_or(test.y),
    }
}

/// The held-out error of a model with effects: mean nrmse over the validation tests, or the
/// estimation test's when there are none.
fn held_out(model: &Model, effects: &[Effect], tests: &[Test<'_>]) -> f64 {
    let judged = if tests.len() > 1 { &tests[1..] } else { tests };
    mean(
        judged
            .iter()
            .map(|t| effects::judged_nrmse(model, effects, t.u, t.y)),
    )
}

/// One test seen on its own: the same model structure fitted to it alone, and how big its
/// residual is for its step. Across tests this shows what one model hides: natural
/// frequencies that move together (temperature), damping that changes with the step's
/// amplitude or direction (amplitude-dependent losses), a residual that grows faster than
/// the step.
#[derive(Debug, Clone, Serialize)]
pub struct PerTest {
    /// The test's file name.
    pub file: String,
    /// Signed step size of the reference.
    pub step_size: f64,
    /// The shared model's residual RMS over `|step|`.
    pub residual_per_step: f64,
    /// Each resonance of the test's own fit: `(natural frequency in Hz, damping)`, lowest
    /// first.
    pub resonances: Vec<(f64, f64)>,
    /// What the test's own (linear) fit leaves above the noise, RMS over `|step|`:
    /// `sqrt(max(rms^2 - noise^2, (noise / 10)^2)) / |step|`. A linear probe leaves the same
    /// share of every step; amplitude-dependent losses leave more of a larger one.
    pub own_residual_per_step: f64,
}

/// Lowest relative rise of the damping over the tests' amplitudes for the nonlinear-damping
/// signature.
pub const MIN_DAMPING_RISE: f64 = 0.1;

/// Lowest exponent of the own-fit residual against the step's amplitude for the
/// nonlinear-damping signature (1 for a linear probe).
pub const MIN_RESIDUAL_EXPONENT: f64 = 1.3;

/// Smallest ratio of the largest to the smallest step for an amplitude signature.
pub const MIN_AMPLITUDE_RATIO: f64 = 1.3;

/// Residual against amplitude across tests: how the fitted damping and what a linear fit
/// cannot explain change with the step's size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AmplitudeSignature {
    /// `|step|` of each test, smallest first.
    pub amplitudes: Vec<f64>,
    /// Damping of the lowest resonance of each test's own fit, in the same order.
    pub damping: Vec<f64>,
    /// Own-fit residual per unit step ([`PerTest::own_residual_per_step`]), same order.
    pub residual_per_step: Vec<f64>,
    /// Least-squares slope of the damping against `|step|` (per probe unit).
    pub damping_slope: f64,
    /// Damping at the largest step over the damping at the smallest, less one.
    pub damping_rise: f64,
    /// Exponent `p` of the own-fit residual against amplitude, `residual ~ |step|^p` (least
    /// squares on the logarithms): 1 for a linear probe, 2 for quadratic losses.
    pub residual_exponent: f64,
}

impl AmplitudeSignature {
    /// Whether it is the signature of amplitude-dependent losses: the damping rises by
    /// [`MIN_DAMPING_RISE`] and the residual grows as `|step|^p`, `p >=`
    /// [`MIN_RESIDUAL_EXPONENT`].
    #[must_use]
    pub fn nonlinear_damping(&self) -> bool {
        self.damping_rise >= MIN_DAMPING_RISE && self.residual_exponent >= MIN_RESIDUAL_EXPONENT
    }
}

fn slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len()) as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut num, mut den) = (0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        num += (a - mx) * (b - my);
        den += (a - mx) * (a - mx);
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// The residual-against-amplitude signature across tests, or `None` with fewer than two
/// tests with a resonance, or steps too alike in size (ratio under [`MIN_AMPLITUDE_RATIO`]).
#[must_use]
pub fn amplitude_signature(per_test: &[PerTest]) -> Option<AmplitudeSignature> {
    let mut points: Vec<(f64, f64, f64)> = per_test
        .iter()
        .filter_map(|p| {
            let a = p.step_size.abs();
            let z = p.resonances.first()?.1;
            (a > 0.0 && a.is_finite() && p.own_residual_per_step > 0.0).then_some((
                a,
                z,
                p.own_residual_per_step,
            ))
        })
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (first, last) = (points.first()?, points.last()?);
    if points.len() < 2 || last.0 < MIN_AMPLITUDE_RATIO * first.0 {
        return None;
    }
    let amplitudes: Vec<f64> = points.iter().map(|p| p.0).collect();
    let damping: Vec<f64> = points.iter().map(|p| p.1).collect();
    let residual_per_step: Vec<f64> = points.iter().map(|p| p.2).collect();
    let ln_a: Vec<f64> = amplitudes.iter().map(|a| a.ln()).collect();
    let ln_r: Vec<f64> = points.iter().map(|p| (p.2 * p.0).ln()).collect();
    Some(AmplitudeSignature {
        damping_slope: slope(&amplitudes, &damping),
        damping_rise: last.1 / first.1 - 1.0,
        residual_exponent: slope(&ln_a, &ln_r),
        amplitudes,
        damping,
        residual_per_step,
    })
}

/// Two peaks within this relative distance are at the same frequency.
pub const SAME_FREQUENCY: f64 = 0.15;

/// A test's natural frequencies must move by at least this factor (3 %) together to point at
/// a temperature.
pub const MIN_FREQUENCY_SHIFT: f64 = 1.03;

/// The per-test evidence of a temperature change.
#[derive(Debug, Clone, Serialize)]
pub struct TemperatureRow {
    /// The test.
    pub file: String,
    /// Each resonance of its own fit against the model's nearest: `(test Hz, model Hz, ratio)`.
    pub modes: Vec<(f64, f64, f64)>,
    /// The common ratio (geometric mean over the modes).
    pub ratio: f64,
    /// Largest relative departure of a mode's ratio from the common one.
    pub spread: f64,
    /// Geometric mean of the damping ratios (test over model).
    pub damping_ratio: f64,
}

/// What [`temperature_evidence`] found.
#[derive(Debug, Clone)]
pub struct TemperatureEvidence {
    /// One row per test.
    pub rows: Vec<TemperatureRow>,
    /// Spread of the strongest test.
    pub spread: f64,
    /// Damping ratio of the strongest test.
    pub damping_ratio: f64,
}

impl TemperatureEvidence {
    /// The test whose frequencies moved most, and its common ratio.
    #[must_use]
    pub fn strongest(&self) -> (String, f64) {
        self.rows
            .iter()
            .max_by(|a, b| a.ratio.ln().abs().total_cmp(&b.ratio.ln().abs()))
            .map_or((String::new(), 1.0), |r| (r.file.clone(), r.ratio))
    }
}

/// The natural frequencies of each test fitted alone against the model's: present when a test's
/// frequencies all move by one common factor of at least [`MIN_FREQUENCY_SHIFT`] (spread
/// across modes under a third of the shift) while its damping stays about the same (a change
/// of damping much larger than of frequency is an amplitude effect, not temperature).
#[must_use]
pub fn temperature_evidence(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
) -> Option<TemperatureEvidence> {
    let model_modes = crate::fit::analysis::Analysis::new(current.model)
        .ok()?
        .resonance_pairs();
    if model_modes.is_empty() {
        return None;
    }
    let rows: Vec<TemperatureRow> = per_test(current, tests, evidence)
        .into_iter()
        .filter(|p| !p.resonances.is_empty())
        .map(|p| {
            let pairs: Vec<((f64, f64), (f64, f64))> = p
                .resonances
                .iter()
                .filter_map(|&(f, z)| {
                    model_modes
                        .iter()
                        .min_by(|a, b| (a.0 / f).ln().abs().total_cmp(&(b.0 / f).ln().abs()))
                        .map(|&m| ((f, z), m))
                })
                .collect();
            let n = pairs.len().max(1) as f64;
            let ln_ratio = pairs
                .iter()
                .map(|((f, _), (g, _))| (f / g).ln())
                .sum::<f64>()
                / n;
            let spread = pairs
                .iter()
                .map(|((f, _), (g, _))| ((f / g).ln() - ln_ratio).abs())
                .fold(0.0, f64::max);
            let ln_damping = pairs
                .iter()
                .map(|((_, z), (_, w))| (z.max(1e-6) / w.max(1e-6)).ln())
                .sum::<f64>()
                / n;
            TemperatureRow {
                file: p.file,
                modes: pairs
                    .iter()
                    .map(|((f, _), (g, _))| (*f, *g, f / g))
                    .collect(),
                ratio: ln_ratio.exp(),
                spread,
                damping_ratio: ln_damping.exp(),
            }
        })
        .collect();
    let strongest = rows
        .iter()
        .max_by(|a, b| a.ratio.ln().abs().total_cmp(&b.ratio.ln().abs()))?;
    let shift = strongest.ratio.ln().abs();
    let ok = shift >= MIN_FREQUENCY_SHIFT.ln()
        && strongest.spread <= shift / 3.0 + 0.005
        && strongest.damping_ratio.ln().abs() <= 2.0 * shift + 0.1;
    ok.then(|| TemperatureEvidence {
        spread: strongest.spread,
        damping_ratio: strongest.damping_ratio,
        rows: rows.clone(),
    })
}

/// Fits the current model's structure (order without effects, delay, method) to each test
/// alone.
#[must_use]
pub fn per_test(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
) -> Vec<PerTest> {
    let have = FitChanges::of(current.effects);
    let order = current
        .model
        .order()
        .saturating_sub(have.extra_order)
        .max(1);
    let options = Options {
        method: current.method,
        order: Order::Fixed(order),
        delay: Some(current.model.delay),
    };
    tests
        .iter()
        .zip(evidence)
        .map(|(t, e)| {
            let own = crate::fit::fit(t, &[], current.model.fs, &options).ok();
            let own_rms = own.as_ref().map_or(f64::NAN, |f| {
                let ym = f.model.simulate(t.u);
                let n = t.y.len().min(ym.len()).max(1) as f64;
                (t.y.iter()
                    .zip(&ym)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    / n)
                    .sqrt()
            });
            let noise2 = e.noise_std * e.noise_std;
            let excess = (own_rms * own_rms - noise2).max(0.01 * noise2).sqrt();
            let mut resonances: Vec<(f64, f64)> = own
                .as_ref()
                .and_then(|f| crate::fit::analysis::Analysis::new(&f.model).ok())
                .map(|a| a.resonance_pairs())
                .unwrap_or_default();
            resonances.sort_by(|a, b| a.0.total_cmp(&b.0));
            PerTest {
                file: e.file.clone(),
                step_size: e.step_size,
                residual_per_step: e.residual_rms / e.step_size.abs().max(1e-300),
                resonances,
                own_residual_per_step: excess / e.step_size.abs().max(1e-300),
            }
        })
        .collect()
}

/// Measures the evidence on every test (the first is the estimation test).
#[must_use]
pub fn evidence(current: &Current<'_>, tests: &[Test<'_>]) -> Vec<TestEvidence> {
    tests
        .iter()
        .enumerate()
        .map(|(i, t)| {
            // With a sensor resonance the model is judged below it: on the prefiltered signals.
            let fs = current.model.fs;
            let ym = effects::predict(current.model, current.effects, t.u, t.y);
            TestEvidence::measure(
                t.name,
                if i == 0 { "estimation" } else { "validation" },
                current.model,
                (
                    &effects::observed(current.effects, fs, t.u),
                    &effects::observed(current.effects, fs, t.y),
                ),
                &ym,
            )
        })
        .collect()
}

/// Ranks the candidates, best first; `none` alone when nothing is missing.
///
/// # Errors
/// Only when the current model cannot be evaluated; a trial that fails is simply not
/// offered.
pub fn diagnose(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
) -> Result<Vec<Candidate>> {
    let fs = current.model.fs;
    let before = held_out(current.model, current.effects, tests);
    let have = FitChanges::of(current.effects);
    let base_order = current
        .model
        .order()
        .saturating_sub(have.extra_order)
        .max(1);
    let base = Options {
        method: current.method,
        order: Order::Fixed(base_order),
        delay: Some(current.model.delay),
    };
    let Some((estimation, validation)) = tests.split_first() else {
        return Ok(Vec::new());
    };
    let estimation = &trial_window(estimation);
    let validation: &[Test<'_>] = &validation.iter().map(trial_window).collect::<Vec<_>>();
    // Each trial's held-out error and stated uncertainty, for the candidate it becomes.
    let stated: std::cell::RefCell<Vec<(f64, Option<Uncertainty>)>> = Default::default();
    let trial = |added: Effect, options: &Options| -> Option<(f64, Vec<Effect>)> {
        let mut with = current.effects.to_vec();
        with.retain(|e| e.kind() != added.kind());
        with.push(added);
        let (fitted, fx) = effects::fit_with(estimation, validation, fs, options, &with).ok()?;
        fitted.model.check_stable("trial").ok()?;
        let after = held_out(&fitted.model, &fx, tests);
        stated
            .borrow_mut()
            .push((after, fitted.report.uncertainty.clone()));
        Some((after, fx))
    };
    let floor = mean(evidence.iter().map(|e| e.noise_floor));
    let white = evidence.iter().all(|e| e.autocorrelation.p_value > 0.01);
    let at_floor = evidence.iter().all(TestEvidence::at_noise_floor);
    let mut out: Vec<Candidate> = Vec::new();
    let mut offer =
        |kind: EffectKind, after: f64, evidence: Value, reading: String, change: String| {
            let ratio = before / after;
            if after.is_finite() && ratio >= MIN_IMPROVEMENT {
                out.push(Candidate {
                    kind: Finding::Missing(kind),
                    score: ratio.ln() - PARAMETER_PENALTY * kind.parameters() as f64,
                    evidence,
                    reading,
                    change,
                    nrmse_before: before,
                    nrmse_after: after,
                    margin: 0.0,
                    separated_by: None,
                    uncertainty_before: current.uncertainty.cloned(),
                    uncertainty_after: stated
                        .borrow()
                        .iter()
                        .rev()
                        .find(|(e, _)| e.to_bits() == after.to_bits())
                        .and_then(|(_, u)| u.clone()),
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
            (last > crate::modelling::evidence::MODEL_ERROR_PEAK_DB).then_some((e, last))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let residual_peak = evidence
        .iter()
        .flat_map(|e| e.spectrum.peaks.iter().map(move |p| (e, p)))
        .max_by(|a, b| a.1.above_floor_db.total_cmp(&b.1.above_floor_db));
    if let Some((after, fx)) = trial(Effect::Mode { near_hz: None }, &base) {
        let (near, ev, reading) = if let Some((e, p)) = peak {
            (
                Some(p.frequency_hz),
                json!({"frequency_hz": p.frequency_hz, "above_floor_db": p.above_floor_db,
                       "q": p.q, "test": e.file, "source": "model-error spectrum"}),
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
                json!({"rise_db": db, "up_to_hz": f, "test": e.file,
                       "source": "model-error spectrum, top of the band"}),
                format!(
                    "the measured response rises {db:.1} dB above the model's towards {f:.0} Hz, \
                     where the noise takes over: an unmodelled mode at or above it (a higher \
                     acoustic mode of the line or a cavity resonance)"
                ),
            )
        } else if let Some((e, p)) = residual_peak {
            (
                Some(p.frequency_hz),
                json!({"frequency_hz": p.frequency_hz, "above_floor_db": p.above_floor_db,
                       "q": p.q, "test": e.file, "source": "residual spectrum"}),
                format!(
                    "a narrow residual peak at {:.0} Hz, {:.0} dB above the floor, Q about {:.0}: \
                     an unmodelled acoustic mode of the line or a cavity resonance",
                    p.frequency_hz, p.above_floor_db, p.q
                ),
            )
        } else {
            (
                None,
                json!({"source": "trial only"}),
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
            match near {
                Some(f) => format!(
                    "unlag fit ... --add mode   (model file: effects = [{{ kind = \"mode\", near_hz = {f:.0} }}])"
                ),
                None => "unlag fit ... --add mode   (model file: effects = [{ kind = \"mode\" }])"
                    .into(),
            },
        );
    }

    // offset: a residual level before the step, the same after it.
    let offset = evidence
        .iter()
        .map(|e| e.trend.pre_mean / e.trend.pre_mean_se.max(1e-300))
        .fold(0.0f64, |m, z| if z.abs() > m.abs() { z } else { m });
    if offset.abs() > 5.0 && !have.offset {
        if let Some((after, fx)) = trial(Effect::Offset { value: 0.0 }, &base) {
            let value = effects::Additive::of(&fx).offset;
            offer(
                EffectKind::Offset,
                after,
                json!({"pre_step_mean_in_standard_errors": offset, "offset": value}),
                format!(
                    "the residual sits {offset:.0} standard errors off zero before the step: a zero \
                     offset of the probe against the reference ({value:.4e})"
                ),
                "unlag fit ... --add offset   (model file: effects = [{ kind = \"offset\" }])"
                    .into(),
            );
        }
    }

    // drift: a ramp through the residual.
    let drift = evidence
        .iter()
        .map(|e| {
            let t = e.samples as f64 / fs;
            (e.trend.slope_per_s * t) / (e.noise_std / (e.samples as f64).sqrt()).max(1e-300)
        })
        .fold(0.0f64, |m, z| if z.abs() > m.abs() { z } else { m });
    if drift.abs() > 10.0 && !have.drift {
        if let Some((after, fx)) = trial(
            Effect::Drift {
                value: 0.0,
                rate_per_s: 0.0,
            },
            &base,
        ) {
            let rate = effects::Additive::of(&fx).rate_per_s;
            let pre = mean(evidence.iter().map(|e| e.trend.pre_slope_per_s));
            offer(
                EffectKind::Drift,
                after,
                json!({"ramp_in_standard_errors": drift, "rate_per_s": rate,
                       "pre_step_slope_per_s": pre}),
                format!(
                    "a ramp through the whole residual ({rate:.3e} per second, already before the \
                     step): the sensor drifts in time (thermal drift)"
                ),
                "unlag fit ... --add drift   (model file: effects = [{ kind = \"drift\" }])".into(),
            );
        }
    }

    // leak: a slow creep after the step (one more slow pole and zero).
    let creep = evidence
        .iter()
        .map(|e| (e.trend.late_mean - e.trend.pre_mean) / e.step_size.abs().max(1e-300))
        .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m });
    if let Some((after, _)) = trial(Effect::Leak, &base) {
        offer(
            EffectKind::Leak,
            after,
            json!({"late_residual_over_step": creep, "dc_gain": current.model.dc_gain()}),
            format!(
                "after the step the residual creeps slowly ({:+.2} % of the step at the end of the \
                 record) and the model's DC gain is {:.4}: a leaking cavity or side volume, a \
                 second, slow time scale",
                100.0 * creep,
                current.model.dc_gain()
            ),
            "unlag fit ... --add leak   (model file: effects = [{ kind = \"leak\" }])".into(),
        );
    }

    // sensor-resonance: the reference rings too, at the frequency where the probe's residual
    // or model error peaks: the transducers' own diaphragm, in both channels. A line or cavity
    // mode never shows in the reference.
    let ringing = evidence
        .iter()
        .filter_map(|e| e.reference_ringing.map(|p| (e, p)))
        .max_by(|a, b| a.1.above_floor_db.total_cmp(&b.1.above_floor_db));
    let mut sensor_matched = false;
    if let (Some((e, rp)), None) = (ringing, effects::prefilter_hz(current.effects)) {
        let near = |f: f64| (f / rp.frequency_hz - 1.0).abs() < SAME_FREQUENCY;
        let probe = evidence
            .iter()
            .flat_map(|e| {
                e.spectrum
                    .peaks
                    .iter()
                    .map(|p| (p, "residual spectrum"))
                    .chain(
                        e.model_error
                            .peaks
                            .iter()
                            .map(|p| (p, "model-error spectrum")),
                    )
            })
            .filter(|(p, _)| near(p.frequency_hz))
            .max_by(|a, b| a.0.above_floor_db.total_cmp(&b.0.above_floor_db));
        if let Some((pp, source)) = probe {
            let f = rp.frequency_hz;
            let added = Effect::SensorResonance {
                natural_frequency_hz: f,
                prefilter_hz: 0.0,
                remedy: effects::SensorRemedy::Modes,
            };
            if let Some((after, _)) = trial(added, &base) {
                sensor_matched = true;
                offer(
                    EffectKind::SensorResonance,
                    after,
                    json!({"reference_peak_hz": f, "reference_above_floor_db": rp.above_floor_db,
                           "reference_q": rp.q, "reference_test": e.file,
                           "probe_peak_hz": pp.frequency_hz, "probe_above_floor_db": pp.above_floor_db,
                           "probe_source": source,
                           "remedy": "the transducers' modes in the model: two more poles and zeros, fitted on the raw signals (sensor-resonance-prefilter: the paper's prefilter instead)"}),
                    format!(
                        "the reference itself rings at {f:.0} Hz ({:.0} dB above the floor of its \
                         increments, Q about {:.0}) and the probe's {source} peaks at {:.0} Hz: the \
                         transducers' own diaphragm resonance, in both channels, not the line's; \
                         model the transducers' modes (two more poles and zeros, on the raw \
                         signals), or, as the paper does, fit below it with both channels \
                         prefiltered at {:.0} Hz (sensor-resonance-prefilter)",
                        rp.above_floor_db,
                        rp.q,
                        pp.frequency_hz,
                        0.5 * f
                    ),
                    format!(
                        "unlag fit ... --add sensor-resonance={f:.0}   (model file: effects = [{{ kind = \"sensor-resonance\", natural_frequency_hz = {f:.0}, remedy = \"modes\" }}])"
                    ),
                );
            }
        }
    }

    // temperature: every natural frequency of the per-test fits moves by one common factor
    // against the model's, with the damping about the same or moving as the viscous law says:
    // the speed of sound (and the kinematic viscosity) changed. Both damping laws are tried;
    // the one that lowers the held-out error more is offered.
    if tests.len() >= 2 && effects::reference_k(current.effects).is_none() {
        if let Some(t) = temperature_evidence(current, tests, evidence) {
            let best = [
                effects::TemperatureDamping::Constant,
                effects::TemperatureDamping::Viscous,
            ]
            .into_iter()
            .filter_map(|damping| {
                let added = Effect::Temperature {
                    reference_k: effects::DEFAULT_REFERENCE_K,
                    damping,
                };
                trial(added, &base).map(|(after, fx)| (after, fx, damping))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((after, fx, damping)) = best {
                let reference_k = effects::reference_k(&fx).unwrap_or(effects::DEFAULT_REFERENCE_K);
                let estimated: Vec<Value> = tests
                    .iter()
                    .map(|t| {
                        let k = effects::estimate_scale_with(
                            current.model,
                            damping,
                            reference_k,
                            t.u,
                            t.y,
                        );
                        json!({"test": t.name, "scale": k,
                               "temperature_k": reference_k * k * k,
                               "damping_factor": damping.factor(k, reference_k)})
                    })
                    .collect();
                let (file, ratio) = t.strongest();
                let viscous = effects::TemperatureDamping::Viscous.factor(ratio, reference_k);
                let spelling = damping.spelling();
                let law = match damping {
                    effects::TemperatureDamping::Constant => "damping kept".to_string(),
                    effects::TemperatureDamping::Viscous => format!(
                        "damping x{viscous:.2} by the viscous law nu(T)/nu(T_ref)/k of a \
                         tube-volume system"
                    ),
                };
                // The kind is what `--add` takes: the damping law is part of it.
                offer(
                    spelling,
                    after,
                    json!({"per_test": t.rows, "common_ratio": ratio, "test": file,
                           "temperature_ratio": ratio * ratio,
                           "damping_ratio": t.damping_ratio,
                           "viscous_damping_ratio": viscous,
                           "damping": damping, "add": spelling,
                           "estimated_scale": estimated, "reference_k": reference_k}),
                    format!(
                        "every natural frequency of {file} fitted alone is {ratio:.3} times the \
                         model's (spread across modes {:.1} %, damping x{:.2}): the same probe at \
                         another gas temperature, T/T_ref = {:.3} (speed of sound goes as the root \
                         of temperature); {law}",
                        100.0 * t.spread,
                        t.damping_ratio,
                        ratio * ratio
                    ),
                    match damping {
                        effects::TemperatureDamping::Constant => format!(
                            "unlag fit ... --add {spelling}   (model file: effects = [{{ kind = \"temperature\", reference_k = 293.15 }}]; the estimation test's temperature)"
                        ),
                        effects::TemperatureDamping::Viscous => format!(
                            "unlag fit ... --add {spelling}   (model file: effects = [{{ kind = \"temperature\", reference_k = 293.15, damping = \"viscous\" }}]; the estimation test's temperature)"
                        ),
                    },
                );
            }
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
                if let Some((after, _)) = trial(Effect::Delay { samples: d }, &base) {
                    offer(
                        EffectKind::Delay,
                        after,
                        json!({"model_delay": current.model.delay, "best_delay": d,
                               "residual_input_xcorr_peak_lag": xc}),
                        format!(
                            "the model answers {} samples {} the probe does (loss lowest at d = {d}, \
                             not {}); the residual against the input peaks at lag {xc}",
                            current.model.delay.abs_diff(d),
                            if d > current.model.delay { "before" } else { "after" },
                            current.model.delay
                        ),
                        format!("unlag fit ... --delay {d}   (model file: effects = [{{ kind = \"delay\", samples = {d} }}])"),
                    );
                }
            }
        }
    }

    // nonlinear damping: across tests, the damping rises with the step and the residual of
    // each test's own linear fit grows faster than the step.
    if !have.nonlinear && tests.len() > 1 {
        let across = per_test(current, tests, evidence);
        if let Some(sig) =
            amplitude_signature(&across).filter(AmplitudeSignature::nonlinear_damping)
        {
            if let Some((after, fx)) = trial(Effect::NonlinearDamping { gain: 0.0 }, &base) {
                let gain = effects::nonlinear_gain(&fx);
                let (a0, a1) = (
                    sig.amplitudes.first().copied().unwrap_or(0.0),
                    sig.amplitudes.last().copied().unwrap_or(0.0),
                );
                let (z0, z1) = (
                    sig.damping.first().copied().unwrap_or(0.0),
                    sig.damping.last().copied().unwrap_or(0.0),
                );
                offer(
                    EffectKind::NonlinearDamping,
                    after,
                    json!({"amplitudes": sig.amplitudes, "damping": sig.damping,
                           "residual_per_step": sig.residual_per_step,
                           "damping_slope_per_unit_step": sig.damping_slope,
                           "damping_rise": sig.damping_rise,
                           "residual_exponent": sig.residual_exponent,
                           "gain_s2_per_unit": gain}),
                    format!(
                        "the damping fitted to each test alone rises from {z0:.3} at a step of                          {a0:.3} to {z1:.3} at {a1:.3} ({:+.3} per unit step), and what a linear                          fit leaves grows as |step|^{:.2} (a linear probe: 1): amplitude-dependent                          losses, orifice or turbulent flow at large steps (quadratic loss                          {gain:.3e} s^2 per unit)",
                        sig.damping_slope, sig.residual_exponent
                    ),
                    "unlag fit ... --add nonlinear-damping   (model file: effects = [{ kind = \"nonlinear-damping\" }])"
                        .into(),
                );
            }
        }
    }

    // coloured noise: correlated residuals with no cause in the input and no peak.
    let p = evidence
        .iter()
        .map(|e| e.autocorrelation.p_value)
        .fold(1.0f64, f64::min);
    let input_explains = evidence
        .iter()
        .any(|e| e.cross_correlation.peak.abs() > 2.0 * e.cross_correlation.band);
    // With least squares (ARX, SM) an output-error refit is the trial, whatever the residual
    // correlates with: noise biases least squares; with output error already, the signature
    // must be clean (no cause in the input).
    if p < 1e-3 && (!matches!(current.method, Method::Oe | Method::Bj) || !input_explains) {
        let added = Effect::ColouredNoise {
            ar: Vec::new(),
            innovation_std: 0.0,
        };
        let after = trial(added, &base).map_or(f64::NAN, |t| t.0);
        let how =
            "output error and an AR noise model; the error is the one-step-ahead prediction error";
        let rho1 = evidence
            .first()
            .and_then(|e| e.autocorrelation.values.first().copied())
            .unwrap_or(0.0);
        offer(
            EffectKind::ColouredNoise,
            after,
            json!({"ljung_box_p": p, "lag1_autocorrelation": rho1, "fit": how}),
            format!(
                "the residual is correlated in time beyond what both channels' noise through \
                 the model explains (Ljung-Box p = {p:.1e}, lag-1 correlation {rho1:.2}): \
                 coloured measurement noise. The remedy is a noise model beside the dynamics \
                 ({how}: what a predictor of the probe one sample ahead cannot remove, against \
                 the simulation error before)"
            ),
            "unlag fit ... --add coloured-noise   (model file: effects = [{ kind = \"coloured-noise\" }])"
                .into(),
        );
    }

    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    // A resonance that shows in the reference as well is the transducers', not the line's:
    // the sensor resonance goes before a mode that would only model it.
    if sensor_matched {
        let s = out
            .iter()
            .position(|c| c.kind == EffectKind::SensorResonance);
        let m = out.iter().position(|c| c.kind == EffectKind::Mode);
        if let (Some(s), Some(m)) = (s, m) {
            if m < s {
                let c = out.remove(s);
                out.insert(m, c);
            }
        }
    }
    // A noise model lowers the one-step-ahead error of any smooth residual, a missing creep's
    // too: when an effect in the dynamics scores within CLOSE_MARGIN of it, the physics goes
    // first and the noise model is the last resort.
    if out
        .first()
        .is_some_and(|c| c.kind == EffectKind::ColouredNoise)
    {
        let top = out.first().map_or(0.0, |c| c.score);
        if let Some(i) = out
            .iter()
            .position(|c| c.kind != EffectKind::ColouredNoise && c.score >= top - CLOSE_MARGIN)
        {
            let c = out.remove(0);
            out.insert(i, c);
        }
    }
    // Nothing is missing when the residual is what both channels' noise leaves (at the floor,
    // correlated only as that noise is), or at the floor with no effect's trial lowering it.
    // A residual above the floor that no effect's trial lowers is not "none": something
    // outside the catalogue is missing, and the diagnosis says so.
    if !at_floor && out.is_empty() {
        let worst = evidence
            .iter()
            .map(|e| e.nrmse / e.noise_floor.max(f64::MIN_POSITIVE))
            .fold(0.0f64, f64::max);
        out.push(Candidate {
            kind: Finding::Unexplained,
            score: 0.0,
            evidence: json!({"nrmse": before, "noise_floor": floor, "white": white,
                             "worst_over_floor": worst}),
            reading: format!(
                "the residual is up to {worst:.1}x what both channels' noise leaves{}, but no \
                 effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x: something \
                 outside the catalogue is missing (a higher order, or physics the effects do not \
                 describe); the model is not at its noise floor",
                if white {
                    ""
                } else {
                    " and correlated beyond that noise"
                }
            ),
            change: "unlag fit ... --order auto   (or a higher --order N)".into(),
            nrmse_before: before,
            nrmse_after: before,
            margin: 0.0,
            separated_by: None,
            uncertainty_before: current.uncertainty.cloned(),
            uncertainty_after: None,
        });
    }
    // A trial that cuts the error by FLOOR_OVERRULED or more shows the floor was measured too
    // high (a noisy pre-step segment): the candidates then stand.
    let best_fall = out
        .iter()
        .map(|c| c.nrmse_before / c.nrmse_after)
        .fold(0.0f64, f64::max);
    if at_floor && ((white && best_fall < FLOOR_OVERRULED) || out.is_empty()) {
        let none = Candidate {
            kind: Finding::Nothing,
            score: 0.0,
            evidence: json!({"nrmse": before, "noise_floor": floor, "white": white}),
            reading: format!(
                "the residuals are consistent with noise (error {:.3} % against a floor of {:.3} %{}); \
                 no effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x",
                100.0 * before,
                100.0 * floor,
                if white { ", white" } else { "" }
            ),
            change: "none".into(),
            nrmse_before: before,
            nrmse_after: before,
            margin: 0.0,
            separated_by: None,
            uncertainty_before: current.uncertainty.cloned(),
            uncertainty_after: None,
        };
        out.insert(0, none);
    }
    let scores: Vec<(f64, Finding)> = out.iter().map(|c| (c.score, c.kind)).collect();
    for (i, c) in out.iter_mut().enumerate() {
        let next = scores.get(i + 1);
        c.margin = c.score - next.map_or(0.0, |n| n.0);
        c.separated_by = next
            .filter(|_| c.margin < CLOSE_MARGIN)
            .map(|n| separating_test(c.kind, n.1));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record of `n` samples at 0, stepping to 1 at `onset`, with a small ripple so that
    /// the step finder has noise to measure.
    fn step(n: usize, onset: usize) -> Vec<f64> {
        (0..n)
            .map(|k| f64::from(u8::from(k >= onset)) + 1e-4 * ((k % 7) as f64 - 3.0))
            .collect()
    }

    #[test]
    fn a_trial_refits_a_long_record_on_the_window_from_its_step() {
        let n = TRIAL_WINDOW + 100_000;
        let onset = 30_000;
        let u = step(n, onset);
        let y: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let t = Test {
            name: "long",
            u: &u,
            y: &y,
        };
        let w = trial_window(&t);
        assert_eq!(w.u.len(), TRIAL_WINDOW);
        assert_eq!(w.y.len(), TRIAL_WINDOW);
        // y[k] = k: the window's first sample is TRIAL_LEAD before the onset the finder saw.
        let start = w.y[0] as usize;
        let found = crate::fit::step::find_step(&u)
            .map(|s| s.onset)
            .unwrap_or(0);
        assert!(found.abs_diff(onset) <= 2, "onset {found}");
        assert_eq!(start, found - TRIAL_LEAD);
        assert_eq!(w.u[0], u[start]);
        // A step near the end: the window ends with the record.
        let late = step(n, n - 1000);
        let t = Test {
            name: "late",
            u: &late,
            y: &y,
        };
        let w = trial_window(&t);
        assert_eq!(w.y.len(), TRIAL_WINDOW);
        assert_eq!(w.y[TRIAL_WINDOW - 1] as usize, n - 1);
    }

    #[test]
    fn a_record_up_to_the_window_is_refitted_whole() {
        let u = step(TRIAL_WINDOW, 5000);
        let y = u.clone();
        let t = Test {
            name: "short",
            u: &u,
            y: &y,
        };
        let w = trial_window(&t);
        assert_eq!(w.u.len(), TRIAL_WINDOW);
        assert!(std::ptr::eq(w.u.as_ptr(), u.as_ptr()));
    }
}
