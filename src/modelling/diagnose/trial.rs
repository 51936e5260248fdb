//! The trials: the stretch of a long record a trial refits on, the held-out error a model
//! with effects is judged by, and the first change made as the user's fit will make it.

use super::{mean, Candidate, Current, Remedy};
use crate::effects::{self, Effect, FitChanges};
use crate::evidence::TestEvidence;
use crate::fit::error_rose;
use crate::fit::model::Model;
use crate::fit::{Options, Order, Test};

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

/// The options a trial refits with: the model's method, the order the user asked for (the
/// model's, less the poles its effects add) and `delay` (searched when `None`, unless an effect
/// fixes it), as `unlag fit --add` refits.
pub(super) fn options(current: &Current<'_>, delay: Option<usize>) -> Options {
    let extra = FitChanges::of(current.effects).extra_order;
    Options {
        method: current.method,
        order: Order::Fixed(current.model.order().saturating_sub(extra).max(1)),
        delay,
    }
}

/// `effects` with `added` added as `unlag fit --add` adds it ([`effects::add`]): in place of
/// any of its kind, but a mode beside the modes there.
pub(super) fn adding(effects: &[Effect], added: &Effect) -> Vec<Effect> {
    let mut with = effects.to_vec();
    effects::add(&mut with, added.clone());
    with
}

/// What a trial leaves: the held-out error ([`held_out`]), the effects it fitted, every
/// test's error (the estimation test's first), and the delay it fitted at.
pub(super) struct Tried {
    pub after: f64,
    pub effects: Vec<Effect>,
    pub nrmse: Vec<f64>,
    pub delay: usize,
    /// The model the trial fitted (its order can be lower than the one it started from:
    /// [`crate::effects::fit_with`] steps down where a temperature cannot scale it).
    pub model: Model,
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
            delay: model.delay,
            model: model.clone(),
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
pub(super) fn judged<T>(tests: &[T]) -> &[T] {
    tests.get(1..).filter(|v| !v.is_empty()).unwrap_or(tests)
}

/// The first change as the user will make it. `unlag fit --add KIND` searches the delay
/// again, which the trials did not (bar a sensor resonance's): a leak's trial at the model's
/// delay can lower the held-out error where, searched again, the slow pole trades with the
/// delay, which moves, and the error rises above the plain model's.
///
/// Where the first candidate adds an effect whose refit with the delay searched again moves
/// the delay and raises the held-out error over what the candidate says ([`error_rose`]), and
/// the trial at `delay` does better than that refit, makes its change keep `delay`
/// ([`Remedy::AddKeepingDelay`]) and says why in its reading. `trial(effect, searched)` is the
/// effect's trial with the delay searched or kept.
pub(super) fn keep_delay_if_search_raises(
    first: &mut Candidate,
    delay: usize,
    trial: impl Fn(&Effect, bool) -> Option<Tried>,
) {
    let Remedy::Add(added) = &first.change else {
        return;
    };
    if matches!(added, Effect::Delay { .. }) {
        return;
    }
    let Some(searched) = trial(added, true) else {
        return;
    };
    if searched.delay == delay || !error_rose(first.nrmse_after, searched.after) {
        return;
    }
    let Some(kept) = trial(added, false) else {
        return;
    };
    if kept.after >= searched.after {
        return;
    }
    first.reading.push_str(&format!(
        "; refitted with the delay searched again it moves to {} samples and the held-out \
         error is {:.3} % against {:.3} % at {delay}: the change keeps the delay",
        searched.delay,
        100.0 * searched.after,
        100.0 * kept.after
    ));
    first.change = Remedy::AddKeepingDelay {
        effect: added.clone(),
        samples: delay,
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectKind;
    use crate::modelling::diagnose::{Evidence, Finding};

    /// A leak's candidate whose trial (at the model's delay) leaves 0.711 %.
    fn leak() -> Candidate {
        Candidate::new(
            Finding::Missing(EffectKind::Leak),
            0.3,
            (
                Evidence::Nothing {
                    noise_floor: 0.005,
                    nrmse: 0.00963,
                    white: true,
                },
                "a leak".into(),
            ),
            Remedy::Add(Effect::Leak),
            (0.00963, 0.00711),
        )
    }

    /// A trial that leaves `searched` at `delay` samples with the delay searched, and `kept`
    /// at 6 with it kept.
    fn trials(
        (searched, delay): (f64, usize),
        kept: f64,
    ) -> impl Fn(&Effect, bool) -> Option<Tried> {
        move |e: &Effect, search: bool| {
            Some(Tried {
                after: if search { searched } else { kept },
                effects: vec![e.clone()],
                nrmse: Vec::new(),
                delay: if search { delay } else { 6 },
                model: Model {
                    fs: 1000.0,
                    delay: if search { delay } else { 6 },
                    a: vec![-0.5],
                    b: vec![0.5, 0.0],
                },
            })
        }
    }

    #[test]
    fn a_trial_adds_its_effect_as_the_fit_does_a_mode_beside_the_models_own() {
        let mode = Effect::Mode { near_hz: None };
        let model = [mode.clone(), Effect::Offset { value: 0.1 }];
        let kinds = |fx: Vec<Effect>| fx.iter().map(Effect::kind).collect::<Vec<_>>();
        assert_eq!(
            kinds(adding(&model, &mode)),
            [EffectKind::Mode, EffectKind::Offset, EffectKind::Mode]
        );
        assert_eq!(
            adding(&model, &Effect::Offset { value: 0.0 }),
            [mode, Effect::Offset { value: 0.0 }]
        );
        // As `unlag fit --add` adds them (the same rule, one function).
        let mut fitted = model.to_vec();
        crate::pipeline::add_effects(&mut fitted, &["mode".to_string()]).unwrap();
        assert_eq!(fitted, adding(&model, &Effect::Mode { near_hz: None }));
    }

    #[test]
    fn a_first_change_keeps_the_delay_only_where_searching_it_raises_the_held_out_error() {
        // A leak: searched again, the delay moves to 8 and the error rises.
        let mut c = leak();
        keep_delay_if_search_raises(&mut c, 6, trials((0.011, 8), 0.00711));
        assert_eq!(
            c.change,
            Remedy::AddKeepingDelay {
                effect: Effect::Leak,
                samples: 6
            }
        );
        assert!(
            c.reading.ends_with("the change keeps the delay"),
            "{}",
            c.reading
        );
        let unchanged = |(searched, delay): (f64, usize), kept: f64| {
            let mut c = leak();
            keep_delay_if_search_raises(&mut c, 6, trials((searched, delay), kept));
            c.change == Remedy::Add(Effect::Leak) && c.reading == "a leak"
        };
        // The search finds the same delay: the fit will do what the trial did.
        assert!(unchanged((0.011, 6), 0.00711));
        // Searched again it does better, or worse by no more than the fit warns of.
        assert!(unchanged((0.006, 8), 0.00711));
        assert!(unchanged((0.00711 * 1.009, 8), 0.00711));
        // The delay kept does no better than the search.
        assert!(unchanged((0.011, 8), 0.012));
        // A change that is not an effect added is left alone.
        let mut c = leak();
        c.change = Remedy::SetDelay { samples: 8 };
        keep_delay_if_search_raises(&mut c, 6, trials((0.011, 8), 0.00711));
        assert_eq!(c.change, Remedy::SetDelay { samples: 8 });
    }

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
