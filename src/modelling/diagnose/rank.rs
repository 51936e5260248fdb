//! The ranking: each candidate effect's signature read from the evidence and its trial run,
//! scored, and the verdict when none is offered (`none` or `unexplained`); their order is
//! [`super::order`]'s.
//!
//! [`rank_at`] runs the candidates in a fixed sequence on one [`Ranking`]: each reads its
//! signature and runs its trial ([`candidates`]), and what passes [`MIN_IMPROVEMENT`] is
//! offered with its score; then the order, and the verdicts ([`verdict`]).

use std::cell::{OnceCell, RefCell};

use super::temperature::{candidate, Offer, TrialAlone};
use super::trial::{
    adding, held_out, judged, keep_delay_if_search_raises, options, trial_window, Tried,
};
use super::{mean, per_test, Candidate, Current, Evidence, Finding, PerTest, Remedy};
use crate::effects::{self, Effect, FitChanges};
use crate::error::Result;
use crate::evidence::TestEvidence;
use crate::fit::model::Uncertainty;
use crate::fit::{Options, Test};

mod candidates;
mod verdict;

/// A trial must lower the held-out error by at least this factor to be offered.
pub const MIN_IMPROVEMENT: f64 = 1.15;

/// A held-out error that falls this much in a trial overrules a noise floor that says nothing
/// is missing.
pub const FLOOR_OVERRULED: f64 = 1.4;

/// The score charged per parameter an effect adds, from the held-out tests' `evidence`: BIC's
/// charge of `ln(n) / 2` per parameter against the Gaussian log-likelihood gain
/// `n ln(before / after)`, both per sample, `ln(n) / (2 n)`, with `n` the held-out tests'
/// effective samples ([`effective_samples`]). Between two effects that explain the data
/// equally well the simpler one ranks first (an offset before a drift, a leak before a
/// mode); the charge a parameter needs to earn falls as the record grows. About 0.03 for a
/// step test of a few thousand samples with a slow residual.
#[must_use]
pub fn parameter_penalty(evidence: &[TestEvidence]) -> f64 {
    let n = evidence
        .iter()
        .map(effective_samples)
        .sum::<f64>()
        .max(core::f64::consts::E);
    n.ln() / (2.0 * n)
}

/// A test's effective samples for its residual: `N / (1 + 2 sum rho(k))` over the
/// autocorrelation's lags (Bartlett's estimate, the sum truncated at
/// [`crate::evidence::ACF_LAGS`]), at most `N`. A model error is slow: its residual's
/// neighbouring samples say one thing, and `N` of them weigh as `N / 61` at the most
/// correlated.
#[must_use]
pub fn effective_samples(evidence: &TestEvidence) -> f64 {
    let correlated = 1.0 + 2.0 * evidence.autocorrelation.values.iter().sum::<f64>();
    evidence.samples as f64 / correlated.max(1.0)
}

/// Two peaks within this relative distance are at the same frequency.
pub const SAME_FREQUENCY: f64 = 0.15;

/// One ranking: the model and its tests, the trials' options and the error they are judged
/// against, and the candidates offered so far.
struct Ranking<'r> {
    current: &'r Current<'r>,
    /// Every test, the estimation test first.
    tests: &'r [Test<'r>],
    evidence: &'r [TestEvidence],
    /// The estimation test and the held-out ones, each cut to the trial's window.
    estimation: Test<'r>,
    validation: Vec<Test<'r>>,
    /// The options every trial starts from: the current model's method and order, at the
    /// delay asked for.
    base: Options,
    /// The current model's held-out error.
    before: f64,
    /// What the current effects already change in a fit.
    have: FitChanges,
    /// Every test at its noise floor.
    at_floor: bool,
    /// The tests' mean noise floor, as each is judged.
    floor: f64,
    /// Every test's residual white (Ljung-Box p above 0.01).
    white: bool,
    /// The score charged per parameter an effect adds ([`parameter_penalty`]).
    penalty: f64,
    /// The current structure fitted to each test alone ([`per_test`]), once, for the
    /// candidates that read it.
    across: OnceCell<Vec<PerTest>>,
    /// Each trial's held-out error and stated uncertainty, for the candidate it becomes.
    stated: RefCell<Vec<(f64, Option<Uncertainty>)>>,
    /// The candidates offered, in the order they were.
    out: Vec<Candidate>,
}

impl<'r> Ranking<'r> {
    /// `None` without a test.
    fn new(
        current: &'r Current<'r>,
        tests: &'r [Test<'r>],
        evidence: &'r [TestEvidence],
        delay: Option<usize>,
    ) -> Option<Self> {
        let (estimation, validation) = tests.split_first()?;
        Some(Self {
            current,
            tests,
            evidence,
            estimation: trial_window(estimation),
            validation: validation.iter().map(trial_window).collect(),
            base: options(current, delay),
            before: held_out(current.model, current.effects, tests),
            have: FitChanges::of(current.effects),
            at_floor: evidence.iter().all(TestEvidence::at_noise_floor),
            floor: mean(evidence.iter().map(TestEvidence::judged_floor)),
            white: evidence.iter().all(|e| e.autocorrelation.p_value > 0.01),
            penalty: parameter_penalty(judged(evidence)),
            across: OnceCell::new(),
            stated: RefCell::default(),
            out: Vec::new(),
        })
    }

    fn fs(&self) -> f64 {
        self.current.model.fs
    }

    /// The current effects with `added` added as `unlag fit --add` adds it.
    fn adding(&self, added: &Effect) -> Vec<Effect> {
        adding(self.current.effects, added)
    }

    /// The trial of `added`: refitted on the estimation test with `options`, judged on every
    /// test; `None` where the fit fails or is unstable.
    fn trial(&self, added: Effect, options: &Options) -> Option<Tried> {
        let with = self.adding(&added);
        let (fitted, fx) = effects::fit_with(
            &self.estimation,
            &self.validation,
            self.fs(),
            options,
            &with,
        )
        .ok()?;
        fitted.model.check_stable("trial").ok()?;
        let tried = Tried::of(&fitted.model, fx, self.tests);
        self.stated
            .borrow_mut()
            .push((tried.after, fitted.report.uncertainty.clone()));
        Some(tried)
    }

    /// The trial of `added` at the base options, or with the delay searched too.
    fn trial_searching(&self, added: Effect, searched: bool) -> Option<Tried> {
        let options = if searched {
            Options {
                delay: None,
                ..self.base
            }
        } else {
            self.base
        };
        self.trial(added, &options)
    }

    /// The current structure fitted to each test alone, fitted on the first call.
    fn per_test(&self) -> &[PerTest] {
        self.across
            .get_or_init(|| per_test(self.current, self.tests, self.evidence))
    }

    /// How many candidates were offered so far.
    fn offered(&self) -> usize {
        self.out.len()
    }

    /// Offers `o` when its trial lowers the held-out error by [`MIN_IMPROVEMENT`] or more,
    /// scored `ln(before / after)` less [`parameter_penalty`] per parameter it adds.
    fn offer(&mut self, o: Option<Offer>) {
        let Some(o) = o else { return };
        let ratio = self.before / o.after;
        if !(o.after.is_finite() && ratio >= MIN_IMPROVEMENT) {
            return;
        }
        let uncertainty_after = self
            .stated
            .borrow()
            .iter()
            .rev()
            .find(|(e, _)| e.to_bits() == o.after.to_bits())
            .and_then(|(_, u)| u.clone());
        self.out.push(Candidate {
            uncertainty_before: self.current.uncertainty.cloned(),
            uncertainty_after,
            ..Candidate::new(
                Finding::Missing(o.kind),
                ratio.ln() - self.penalty * o.kind.parameters() as f64,
                (o.evidence, o.reading),
                o.change,
                (self.before, o.after),
            )
        });
    }

    /// A temperature offered beside a loss fitted on the tests together is fitted on them
    /// together too (one model, each test its own time scale), so that the order can set the
    /// two on one footing: the loss's dynamics are refitted on every test, the trial's are
    /// the estimation test's.
    fn temperature_beside_joint_loss(&mut self) {
        let joint_loss = self
            .out
            .iter()
            .any(|c| matches!(&c.evidence, Evidence::NonlinearDamping(n) if n.joint.is_some()));
        if !joint_loss {
            return;
        }
        let (estimation, validation, fs, base) =
            (&self.estimation, &self.validation, self.fs(), &self.base);
        let (effects, tests) = (self.current.effects, self.tests);
        for c in &mut self.out {
            if let (Evidence::Temperature(t), Remedy::Add(added)) = (&mut c.evidence, &c.change) {
                let with = adding(effects, added);
                t.joint_nrmse =
                    effects::fit_with_also(estimation, validation, &[], fs, base, &with)
                        .ok()
                        .map(|(fitted, fx)| Tried::of(&fitted.model, fx, tests).nrmse);
            }
        }
    }
}

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
    let Some(mut r) = Ranking::new(current, tests, evidence, delay) else {
        return Ok(Vec::new());
    };
    let signatures: [fn(&Ranking<'_>) -> Option<Offer>; 6] = [
        |r| r.mode(),
        |r| r.offset(),
        |r| r.drift(),
        |r| r.leak(),
        |r| r.sensor_resonance(),
        |r| r.delay(),
    ];
    for candidate in signatures {
        let offer = candidate(&r);
        r.offer(offer);
    }
    let (offer, mut nonlinear_tried) = r.nonlinear_damping_by_amplitude();
    r.offer(offer);
    let joint_from = r.offered();
    if !nonlinear_tried {
        let (offer, tried) = r.nonlinear_damping_jointly();
        nonlinear_tried = tried;
        r.offer(offer);
    }
    // temperature: every natural frequency of the per-test fits moves by one common factor
    // against the model's (the speed of sound, and the kinematic viscosity, changed), or,
    // where no test fitted alone can show it, the trial alone held to the floor; on any model
    // beside a loss fitted on the tests together, which it is then set against.
    let alone = match (any_damping, r.offered() > joint_from) {
        (true, _) => TrialAlone::AnyModel,
        (false, true) => TrialAlone::BesideJointLoss,
        (false, false) => TrialAlone::Resonant,
    };
    let offer = candidate(
        r.current,
        r.tests,
        r.evidence,
        &|added, options: &Options| r.trial(added, options),
        (&r.base, alone),
        r.before,
        r.at_floor,
    );
    r.offer(offer);
    let offer = r.coloured_noise();
    r.offer(offer);
    if !nonlinear_tried {
        let offer = r.nonlinear_damping_from_trial_alone();
        r.offer(offer);
    }
    r.temperature_beside_joint_loss();
    let mut out = std::mem::take(&mut r.out);
    super::order::order(&mut out);
    // The first change as the user will make it: `unlag fit --add KIND` searches the delay
    // again; where that would raise the held-out error, the change keeps the delay.
    if r.have.delay.is_none() && delay.is_some() {
        if let Some(first) = out.first_mut() {
            keep_delay_if_search_raises(first, current.model.delay, |added, searched| {
                r.trial_searching(added.clone(), searched)
            });
        }
    }
    verdict::unexplained(&mut out, &r);
    verdict::nothing(&mut out, &r);
    super::order::set_margins(&mut out);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A capillary's probe after a step at sample 500 of `n`, `extra` added to its output.
    fn evidence(n: usize, extra: impl Fn(f64) -> f64) -> TestEvidence {
        crate::testing::capillary_evidence(n, 500, extra)
    }

    /// A white residual counts every sample; a slow model error counts its samples as few,
    /// at most `ACF_LAGS` times two plus one to a sample; the charge per parameter is BIC's,
    /// larger for the slow residual and falling as the record grows.
    #[test]
    fn the_charge_per_parameter_is_bics_over_the_residuals_independent_samples() {
        let white = evidence(8000, |_| 0.0);
        let slow = evidence(8000, |t| {
            40.0 * (2.0 * std::f64::consts::PI * 3.0 * t).sin()
        });
        let (nw, ns) = (effective_samples(&white), effective_samples(&slow));
        assert!(nw > 0.7 * 8000.0 && nw <= 8000.0, "{nw}");
        let most = 8000.0 / (2.0 * crate::evidence::ACF_LAGS as f64 + 1.0);
        assert!(ns < 2.0 * most && ns >= most * (1.0 - 1e-9), "{ns}");
        let penalty = |n: f64| n.ln() / (2.0 * n);
        let once = parameter_penalty(std::slice::from_ref(&slow));
        assert!((once - penalty(ns)).abs() < 1e-12);
        assert!(once > 5.0 * parameter_penalty(&[white]));
        let longer = evidence(32_000, |t| {
            40.0 * (2.0 * std::f64::consts::PI * 3.0 * t).sin()
        });
        assert!(parameter_penalty(&[longer]) < once);
    }
}
