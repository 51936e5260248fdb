//! A mode beside the first change: where the model is short of its own estimation test as
//! well as of the effect the first candidate names, the change adds both in one fit
//! ([`Beside`], [`Remedy::AddBeside`]).
//!
//! A user starts from a low order (`unlag fit --order 2`). A pneumatic probe's line and
//! cavity have modes above the first, so that start leaves its own step test above the noise
//! floor, and a held-out test at another temperature, or with a leak, shows a second deficit on
//! top of it. The diagnosis names the second (the effect a test of another kind reveals), and
//! its change alone leaves the first: a temperature takes a wake traverse down by a third,
//! still far above its floor, and the estimation test stays near four times its own. The next
//! round of the loop names the mode. Where the mode's trial beside the first change shows
//! that already, the first change carries it, and says why.

use serde::Serialize;

use super::trial::{adding, options, trial_window, Tried};
use super::{Candidate, Current, Remedy, MIN_IMPROVEMENT};
use crate::effects::{self, Effect, EffectKind, FitChanges};
use crate::evidence::TestEvidence;
use crate::fit::error_rose;
use crate::fit::Test;

/// The effect added beside a candidate's own, with what its trial left.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Beside {
    /// The effect added beside (`mode`).
    pub kind: EffectKind,
    /// The held-out error with the candidate's effect alone, refitted as its change refits
    /// (the delay searched again unless the change keeps it).
    pub nrmse_alone: f64,
    /// The held-out error with both.
    pub nrmse_after: f64,
    /// The estimation test's error with the candidate's effect alone.
    pub estimation_alone: f64,
    /// The estimation test's error with both.
    pub estimation_after: f64,
    /// The estimation test's floor, what both channels' noise leaves on it.
    pub estimation_floor: f64,
}

impl Beside {
    /// Whether the figures call for the effect beside: the candidate's effect alone leaves
    /// the estimation test above its floor by [`MIN_IMPROVEMENT`] or more, and the effect
    /// beside lowers both that test's error and the held-out error by that factor.
    #[must_use]
    pub fn called_for(&self) -> bool {
        let falls =
            |before: f64, after: f64| after.is_finite() && before >= MIN_IMPROVEMENT * after;
        falls(self.estimation_alone, self.estimation_floor)
            && falls(self.estimation_alone, self.estimation_after)
            && falls(self.nrmse_alone, self.nrmse_after)
    }

    /// The sentence the reading of a candidate that adds `own` gains.
    fn reading(&self, own: EffectKind) -> String {
        format!(
            "the model is short of its own estimation test as well ({:.3} % with this effect \
             alone, against a floor of {:.3} %: the probe's own dynamics need a higher order than \
             the model's); with {} {} beside it the estimation test falls to {:.3} % and the \
             held-out error from {:.3} % to {:.3} %, so the change adds both",
            100.0 * self.estimation_alone,
            100.0 * self.estimation_floor,
            if own == self.kind { "a second" } else { "a" },
            self.kind,
            100.0 * self.estimation_after,
            100.0 * self.nrmse_alone,
            100.0 * self.nrmse_after,
        )
    }
}

/// Gives the first candidate a mode beside its effect where [`Beside::called_for`]: its
/// change then adds both ([`Remedy::AddBeside`]) and its reading says why. Only a candidate
/// that adds one effect other than a delay, without `--also`, to a model with no mode yet,
/// and only with a held-out test: on the estimation test alone, more poles always fit better.
/// A mode gets a second mode beside it the same way: a probe whose line and cavity have two
/// modes above the model's (one mode leaves the estimation test well above its floor, and a
/// second lowers the held-out error further).
pub(super) fn mode_beside(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
    candidates: &mut [Candidate],
) {
    let Some(first) = candidates.first_mut() else {
        return;
    };
    let (added, kept_delay) = match &first.change {
        Remedy::Add(e) => (e, None),
        Remedy::AddKeepingDelay { effect, samples } => (effect, Some(*samples)),
        _ => return,
    };
    if matches!(added, Effect::Delay { .. })
        || current.effects.iter().any(|e| e.kind() == EffectKind::Mode)
    {
        return;
    }
    let Some((estimation, validation)) = tests.split_first() else {
        return;
    };
    if validation.is_empty() {
        return;
    }
    // Both trials as the change's fit makes them: the user's order, the delay searched again
    // unless the model file or the change fixes it.
    let estimation = trial_window(estimation);
    let validation: Vec<Test<'_>> = validation.iter().map(trial_window).collect();
    let options = options(current, None);
    let trial = |beside: Option<Effect>, kept_delay: Option<usize>| -> Option<Tried> {
        let mut with = adding(current.effects, added);
        with.extend(beside);
        if let Some(samples) = kept_delay {
            with = adding(&with, &Effect::Delay { samples });
        }
        let (fitted, fx) =
            effects::fit_with(&estimation, &validation, current.model.fs, &options, &with).ok()?;
        fitted.model.check_stable("trial").ok()?;
        Some(Tried::of(&fitted.model, fx, tests))
    };
    let mode = Effect::Mode { near_hz: None };
    let Some(alone) = trial(None, kept_delay) else {
        return;
    };
    let Some(mut both) = trial(Some(mode.clone()), kept_delay) else {
        return;
    };
    // As the first change does ([`super::trial::keep_delay_if_search_raises`]): where the
    // delay searched again moves and raises the held-out error, the change keeps the model's.
    let delay = current.model.delay;
    let mut change = first.change.clone();
    let delay_fixed = FitChanges::of(current.effects).delay.is_some();
    if kept_delay.is_none() && !delay_fixed && both.delay != delay {
        if let Some(kept) = trial(Some(mode.clone()), Some(delay)) {
            if error_rose(kept.after, both.after) {
                both = kept;
                change = Remedy::AddKeepingDelay {
                    effect: added.clone(),
                    samples: delay,
                };
            }
        }
    }
    // The estimation test's floor on the footing its error is judged: with a noise model
    // fitted, the one-step-ahead prediction error's.
    let floor = if effects::noise_model(&alone.effects).is_some() {
        crate::fit::noise::prediction_floors(tests.get(..1).unwrap_or_default(), current.model)
            .into_iter()
            .flatten()
            .next()
            .map(|f| f.value)
    } else {
        evidence.first().map(TestEvidence::judged_floor)
    };
    let Some(floor) = floor else {
        return;
    };
    let beside = Beside {
        kind: EffectKind::Mode,
        nrmse_alone: alone.after,
        nrmse_after: both.after,
        estimation_alone: alone.nrmse.first().copied().unwrap_or(f64::NAN),
        estimation_after: both.nrmse.first().copied().unwrap_or(f64::NAN),
        estimation_floor: floor,
    };
    // The change with the mode must also do better than the candidate says its own does.
    if !beside.called_for() || beside.nrmse_after * MIN_IMPROVEMENT > first.nrmse_after {
        return;
    }
    first.reading.push_str("; ");
    first.reading.push_str(&beside.reading(added.kind()));
    first.change = Remedy::AddBeside {
        change: Box::new(change),
        beside: mode,
    };
    first.beside = Some(beside);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A temperature beside a mode: a temperature alone leaves the estimation test at
    /// 3.8x its floor; a mode beside it takes that test to 0.300 % and the traverse from
    /// 4.172 % to 1.653 %.
    fn case_089() -> Beside {
        Beside {
            kind: EffectKind::Mode,
            nrmse_alone: 0.04172,
            nrmse_after: 0.01653,
            estimation_alone: 0.00932,
            estimation_after: 0.00300,
            estimation_floor: 0.00247,
        }
    }

    #[test]
    fn a_mode_goes_beside_only_where_the_estimation_test_is_short_and_both_errors_fall() {
        assert!(case_089().called_for());
        let with = |f: fn(&mut Beside)| {
            let mut b = case_089();
            f(&mut b);
            b.called_for()
        };
        // The estimation test at its floor with the effect alone: nothing short there.
        assert!(!with(|b| b.estimation_alone = 1.1 * b.estimation_floor));
        // The mode lowers the estimation test (in-sample, more poles always do) by less than
        // the threshold.
        assert!(!with(|b| b.estimation_after = b.estimation_alone / 1.1));
        // The held-out error does not fall by the threshold.
        assert!(!with(|b| b.nrmse_after = b.nrmse_alone / 1.1));
        // A trial that failed.
        assert!(!with(|b| b.nrmse_after = f64::NAN));
        // Just past every threshold.
        assert!(with(|b| {
            b.estimation_alone = 1.16 * b.estimation_floor;
            b.estimation_after = b.estimation_alone / 1.16;
            b.nrmse_after = b.nrmse_alone / 1.16;
        }));
    }

    #[test]
    fn its_reading_gives_the_figures_behind_it() {
        let r = case_089().reading(EffectKind::Temperature);
        assert!(r.contains("with a mode beside it"), "{r}");
        let second = case_089().reading(EffectKind::Mode);
        assert!(second.contains("with a second mode beside it"), "{second}");
        for figure in ["0.932 %", "0.247 %", "0.300 %", "4.172 %", "1.653 %"] {
            assert!(r.contains(figure), "{figure}: {r}");
        }
    }
}
