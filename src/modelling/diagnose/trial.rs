//! The trials: the stretch of a long record a trial refits on, and the held-out error a model
//! with effects is judged by.

use super::mean;
use crate::fit::model::Model;
use crate::fit::Test;
use crate::modelling::effects::{self, Effect};
use crate::modelling::evidence::TestEvidence;

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
pub(super) fn trial_window<'a>(test: &Test<'a>) -> Test<'a> {
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

/// What a trial leaves: the held-out error ([`held_out`]), the effects it fitted, and every
/// test's error, the estimation test's first.
pub(super) struct Tried {
    pub after: f64,
    pub effects: Vec<Effect>,
    pub nrmse: Vec<f64>,
}

impl Tried {
    /// The trial of `model` with `effects` on `tests`.
    pub(super) fn of(model: &Model, effects: Vec<Effect>, tests: &[Test<'_>]) -> Self {
        let nrmse: Vec<f64> = tests
            .iter()
            .map(|t| effects::judged_nrmse(model, &effects, t.u, t.y))
            .collect();
        Self {
            after: mean(judged(&nrmse).iter().copied()),
            effects,
            nrmse,
        }
    }
}

/// The held-out error of a model with effects: mean nrmse over the validation tests, or the
/// estimation test's when there are none.
pub(super) fn held_out(model: &Model, effects: &[Effect], tests: &[Test<'_>]) -> f64 {
    mean(
        judged(tests)
            .iter()
            .map(|t| effects::judged_nrmse(model, effects, t.u, t.y)),
    )
}

/// The floor both channels' noise leaves on the held-out tests (the estimation test's when
/// there are none), as [`held_out`] averages them.
pub(super) fn held_out_floor(evidence: &[TestEvidence]) -> f64 {
    mean(judged(evidence).iter().map(TestEvidence::judged_floor))
}

/// What a held-out error is judged on: the validation tests (all after the first), or the
/// estimation test when there are none.
fn judged<T>(tests: &[T]) -> &[T] {
    tests.get(1..).filter(|v| !v.is_empty()).unwrap_or(tests)
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
