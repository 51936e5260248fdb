//! The temperature candidate: every natural frequency of the tests fitted alone moved by one
//! factor ([`super::temperature_evidence`]), or, where no test fitted alone can show it, the
//! trial alone, held to the noise floor both channels leave.

use super::trial::{held_out_floor, Tried};
use super::{
    temperature_evidence, temperature_reading, temperature_shift, Current, Evidence, Remedy,
    ScaleEstimate, TemperatureRow, TemperatureShift, MIN_IMPROVEMENT,
};
use crate::effects::{self, Effect, EffectKind, TemperatureDamping};
use crate::evidence::TestEvidence;
use crate::fit::{Options, Test};

/// A temperature read from its trial alone must lower the held-out error by this much,
/// counted down to the floor both channels' noise leaves and no further: the square of the
/// diagnosis' threshold ([`MIN_IMPROVEMENT`]), for no test fitted alone stands behind it.
///
/// The floor matters here. A free time scale fitted to each held-out test can pass less of
/// the reference's noise through a light resonance and beat the true model on the test it
/// is fitted to (errors in variables): on a flush probe with nothing hidden, a scale can
/// lower a traverse's error well below what both channels' noise leaves. Counted to the
/// floor, that is no fall at all.
pub const TRIAL_ALONE_FALL: f64 = MIN_IMPROVEMENT * MIN_IMPROVEMENT;

/// A temperature read from its trial alone needs a model resonance damped below this. A pair
/// short of critical damping has two time scales, its ringing's and its decay's, and a
/// temperature moves them together, as no loss does; near critical damping the pair acts as
/// one time scale, which an amplitude-dependent resistance moves too: capillaries and lines
/// with a quadratic loss, their plain models damped 0.94 to 1, read as a temperature by their
/// trials alone. A bound at `1/sqrt(2)`, where the response peaks, would also keep from their
/// trials the hidden temperatures whose plain models are damped 0.71 to 0.91; the bound sits
/// in the gap between the two groups (the bench's loop tables show both).
pub const TRIAL_ALONE_DAMPING_BELOW: f64 = 0.93;

/// Whether a quadratic loss could move a held-out test's time scale by `k` (above 1: faster)
/// against the estimation test, `swing_ratio` the held-out test's swing over the estimation
/// test's (from the 0.5th to the 99.5th percentile). A loss fitted on the estimation test
/// damps a smaller test less, so it runs faster (`k > 1`), and a larger one slower: it cannot
/// move the time scale the other way. A temperature moves it either way.
///
/// This is what a temperature read from its trial alone on a model with no resonance short of
/// [`TRIAL_ALONE_DAMPING_BELOW`] (the last resort before `unexplained`) must show. How far one
/// time scale fitted to the held-out test brings its error down does not tell them apart: it
/// takes hidden losses' and hidden temperatures' alike to between the floor and twice it.
/// The direction does: a loss validated on a test smaller than the estimation step (a step,
/// a valve or a traverse), a capillary's too, runs faster; a temperature can run slower.
#[must_use]
pub fn loss_could_move(k: f64, swing_ratio: f64) -> bool {
    (k > 1.0) == (swing_ratio < 1.0)
}

/// Whether the trial's time scale on the test that shows the signature, `file`, lies on the
/// other side of 1 from the signature's `ratio` (that test's natural frequencies fitted alone
/// over the model's). With the damping kept (the law of a lightly damped probe), a gas
/// temperature moves every natural frequency by the one factor the trial fits, so the two
/// agree; a signature its own trial contradicts is not a temperature's, but may be a
/// nonlinear damping's (its frequencies fitted alone below the model's, its trial's time
/// scale above 1), a mode's, a leak's or a sensor resonance's. Under the viscous law hidden
/// temperatures too can disagree, so it is not asked there.
fn trial_contradicts(estimated: &[ScaleEstimate], file: &str, ratio: f64) -> bool {
    estimated
        .iter()
        .find(|e| e.test == file)
        .is_some_and(|e| (e.scale - 1.0) * (ratio - 1.0) < 0.0)
}

/// A record's swing: the spread of its samples from the 0.5th to the 99.5th percentile (a
/// step's size, a traverse's range), not moved by a few wild samples.
fn swing(x: &[f64]) -> f64 {
    let mut v: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let at = |v: &mut Vec<f64>, q: f64| {
        let i = ((n - 1) as f64 * q).round() as usize;
        let (_, x, _) = v.select_nth_unstable_by(i.min(n - 1), f64::total_cmp);
        *x
    };
    let hi = at(&mut v, 0.995);
    hi - at(&mut v, 0.005)
}

/// The models a temperature may be read from by its trial alone, where no test fitted alone
/// shows the signature.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TrialAlone {
    /// A model with a resonance damped below [`TRIAL_ALONE_DAMPING_BELOW`].
    Resonant,
    /// Any model, where no loss could have moved the time scale that way
    /// ([`loss_could_move`]): the last resort before `unexplained`.
    AnyModel,
    /// Any model, beside a loss fitted on the tests together; each is then fitted on all the
    /// tests and the one that leaves less goes first (`LessOverAllTests` in
    /// [`super::order`]). Where the test that moved is a traverse (no quiet segment), the
    /// direction a loss could have moved it is not asked: a traverse has no step to fit
    /// alone, so no test can show a temperature's signature, and its rates, not its swing,
    /// set what a loss damps. On overdamped capillaries validated by a traverse in a colder
    /// gas, the loss was offered alone and named, where the temperature fitted on both tests
    /// leaves less. A test with a step keeps the direction's test: a capillary's loss
    /// validated by a valve ran slower, as a loss moves a larger test, and was named a
    /// temperature without it.
    BesideJointLoss,
}

/// What the temperature candidate offers: its kind (the damping law is part of it), the
/// held-out error after its trial, the evidence, the reading and the change.
pub(super) struct Offer {
    pub kind: EffectKind,
    pub after: f64,
    pub evidence: Evidence,
    pub reading: String,
    pub change: Remedy,
}

/// A trial: what adding `effect`, fitted with the options, leaves ([`Tried`]).
pub(super) type Trial<'t> = dyn Fn(Effect, &Options) -> Option<Tried> + 't;

/// The temperature candidate for `current` on `tests`, if any: both damping laws are tried and
/// the one that lowers the held-out error more is offered. With the tests' signature
/// ([`super::temperature_evidence`]) the trial need only pass the diagnosis' threshold, as
/// every candidate's; without it (a valve's slow rise or a traverse cannot pin a light
/// resonance, and a traverse has no step to fit alone), with the residual above the floor
/// (`at_floor` false) and a model resonance damped below [`TRIAL_ALONE_DAMPING_BELOW`] (or
/// any model, as `alone` says: [`TrialAlone`]), it must move some
/// held-out test's time scale by a factor a gas temperature explains, inside the searched
/// range, and lower the held-out error by [`TRIAL_ALONE_FALL`] counted to the floor.
pub(super) fn candidate(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
    trial: &Trial<'_>,
    (base, alone): (&Options, TrialAlone),
    before: f64,
    at_floor: bool,
) -> Option<Offer> {
    if tests.len() < 2 || effects::reference_k(current.effects).is_some() {
        return None;
    }
    let signature = temperature_evidence(current, tests, evidence);
    // The model's resonances, `(Hz, damping)`: none for an overdamped probe.
    let resonances = crate::fit::analysis::Analysis::new(current.model)
        .ok()
        .map(|a| a.resonance_pairs());
    let overdamped = signature.as_ref().map_or_else(
        || resonances.as_ref().is_some_and(Vec::is_empty),
        |t| t.overdamped,
    );
    // The trial alone reads a temperature only where the model has a resonance clearly short
    // of critical damping ([`TRIAL_ALONE_DAMPING_BELOW`]).
    let resonant = resonances
        .iter()
        .flatten()
        .any(|&(_, z)| z < TRIAL_ALONE_DAMPING_BELOW);
    if signature.is_none() && (at_floor || !(resonant || alone != TrialAlone::Resonant)) {
        return None;
    }
    // A model with a pole on the negative real axis cannot be scaled: its trial searches
    // the delay again, which lets the fit step back to a model that can
    // ([`effects::fit_with`]).
    let scalable = crate::fit::continuous::Continuous::from_model(current.model).is_ok();
    let options = Options {
        delay: if scalable { base.delay } else { None },
        ..*base
    };
    let (tried, damping) = best_law(trial, &options, overdamped)?;
    let (after, fx) = (tried.after, &tried.effects);
    let reference_k = effects::reference_k(fx).unwrap_or(effects::DEFAULT_REFERENCE_K);
    // Each test's time scale, read on the model the temperature scales: the current one, or
    // the trial's where the current one cannot be scaled (the trial stepped back to a delay or
    // an order that can be; read on the current model, every scale would be 1).
    let scaled_model = if scalable {
        current.model
    } else {
        &tried.model
    };
    let estimated = scales(tests, scaled_model, damping, reference_k);
    let spelling = damping.spelling();
    let seen = signature.is_some();
    let change = Remedy::Add(Effect::Temperature {
        reference_k: effects::DEFAULT_REFERENCE_K,
        damping,
    });
    let Read {
        file,
        ratio,
        per_test,
        damping_ratio,
        reading,
        temperature_ratio,
    } = match signature {
        Some(t) => {
            let (file, ratio) = t.strongest();
            if damping == TemperatureDamping::Constant
                && trial_contradicts(&estimated, &file, ratio)
            {
                return None;
            }
            let (reading, temperature_ratio) = temperature_reading(&t, damping, &file, reference_k);
            Read {
                file,
                ratio,
                per_test: t.rows.clone(),
                damping_ratio: t.damping_ratio,
                reading,
                temperature_ratio,
            }
        }
        None => read_alone(
            &estimated,
            tests,
            evidence,
            (alone, resonant),
            (before, after),
            (damping, reference_k),
        )?,
    };
    Some(Offer {
        kind: spelling,
        after,
        evidence: Evidence::Temperature(TemperatureShift {
            add: spelling,
            common_ratio: ratio,
            damping,
            damping_ratio,
            estimated_scale: estimated,
            per_test,
            reference_k,
            temperature_ratio,
            signature: seen,
            test: file,
            trial_nrmse: tried.nrmse,
            joint_nrmse: None,
            viscous_damping_ratio: TemperatureDamping::Viscous.factor(ratio, reference_k),
        }),
        reading,
        change,
    })
}

/// The trial of the temperature with each damping law (the speed of sound's, or the
/// diffusive one for an overdamped probe, and the viscous one), the one of least held-out
/// error kept, with its law.
///
/// An overdamped probe's time scales go as the viscosity where the pressure diffuses along
/// a capillary: the diffusive law is tried in place of the speed of sound's, which scales
/// time the same way but reads the temperature the wrong way round (a hotter gas slows a
/// capillary).
fn best_law(
    trial: &Trial<'_>,
    options: &Options,
    overdamped: bool,
) -> Option<(Tried, TemperatureDamping)> {
    [
        if overdamped {
            TemperatureDamping::Diffusive
        } else {
            TemperatureDamping::Constant
        },
        TemperatureDamping::Viscous,
    ]
    .into_iter()
    .filter_map(|damping| {
        let added = Effect::Temperature {
            reference_k: effects::DEFAULT_REFERENCE_K,
            damping,
        };
        trial(added, options).map(|t| (t, damping))
    })
    .min_by(|a, b| a.0.after.total_cmp(&b.0.after))
}

/// What the temperature candidate reads: the test it is strongest on, the time-scale ratio
/// there, each test's row (with the tests' signature), the damping's ratio, the reading and the
/// temperature ratio.
struct Read {
    file: String,
    ratio: f64,
    per_test: Vec<TemperatureRow>,
    damping_ratio: f64,
    reading: String,
    temperature_ratio: f64,
}

/// Each test's time scale under `damping`, read on `model`.
fn scales(
    tests: &[Test<'_>],
    model: &crate::fit::Model,
    damping: TemperatureDamping,
    reference_k: f64,
) -> Vec<ScaleEstimate> {
    tests
        .iter()
        .map(|t| {
            let k = effects::estimate_scale_with(model, damping, reference_k, t.u, t.y);
            ScaleEstimate {
                damping_factor: damping.factor(k, reference_k),
                scale: k,
                temperature_k: damping.temperature(k, reference_k),
                test: t.name.to_string(),
            }
        })
        .collect()
}

/// The temperature read from the trial alone (no test fitted alone shows the signature): the
/// held-out test whose time scale moved most, if the move is inside the searched range, one a
/// gas temperature explains, lowers the held-out error by [`TRIAL_ALONE_FALL`] counted to the
/// floor, and (for a model without a light resonance) is not one a quadratic loss could make.
fn read_alone(
    estimated: &[ScaleEstimate],
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
    (alone, resonant): (TrialAlone, bool),
    (before, after): (f64, f64),
    (damping, reference_k): (TemperatureDamping, f64),
) -> Option<Read> {
    let (i, strongest) = estimated
        .iter()
        .enumerate()
        .skip(1)
        .max_by(|a, b| a.1.scale.ln().abs().total_cmp(&b.1.scale.ln().abs()))?;
    let k = strongest.scale;
    // Only where no loss could have moved the time scale this way; beside a joint
    // loss, a traverse's direction is not asked ([`TrialAlone::BesideJointLoss`]).
    let loss = || {
        let traverse = tests
            .get(i)
            .is_some_and(|t| crate::fit::step::quiet_until(t.u) == 0);
        if alone == TrialAlone::BesideJointLoss && traverse {
            return false;
        }
        let swing_ratio = match (tests.first(), tests.get(i)) {
            (Some(e), Some(t)) => swing(t.u) / swing(e.u),
            _ => f64::NAN,
        };
        !swing_ratio.is_finite() || loss_could_move(k, swing_ratio)
    };
    let (lo, hi) = effects::SCALE_RANGE;
    let inside = k > lo * 1.001 && k < hi / 1.001;
    let floor = held_out_floor(evidence);
    let fall = before / after.max(floor);
    if !(inside && temperature_shift(k) && fall >= TRIAL_ALONE_FALL) || (!resonant && loss()) {
        return None;
    }
    let temperature_ratio = damping.temperature(k, reference_k) / reference_k;
    let reading = format!(
        "no test fitted alone shows its natural frequencies moved by one factor (a \
         valve's slow rise or a traverse cannot pin a light resonance, and a traverse has \
         no step to fit alone), but the model's one time scale fitted to each test \
         moves by {k:.3} on {} and lowers the held-out error {:.2}x counted to the \
         noise floor ({:.3} % -> {:.3} %, floor {:.3} %): the same probe at another gas \
         temperature, T/T_ref = {temperature_ratio:.3}, read from the trial alone; a \
         step at that temperature would confirm it",
        strongest.test,
        fall,
        100.0 * before,
        100.0 * after,
        100.0 * floor,
    );
    Some(Read {
        file: strongest.test.clone(),
        ratio: k,
        per_test: Vec::new(),
        damping_ratio: damping.factor(k, reference_k),
        reading,
        temperature_ratio,
    })
}

#[cfg(test)]
mod tests {
    use crate::effects::EffectKind;
    use crate::fit::{Method, Test};
    use crate::modelling::diagnose::{self, Candidate, Current, Evidence, Finding};
    use crate::testing::{second_order, traverse, with_noise};

    #[test]
    fn a_loss_moves_a_smaller_test_faster_and_a_larger_one_slower() {
        use super::loss_could_move;
        assert!(loss_could_move(1.1, 0.5));
        assert!(!loss_could_move(0.9, 0.5));
        assert!(loss_could_move(0.9, 2.0));
        assert!(!loss_could_move(1.1, 2.0));
    }

    #[test]
    fn a_trial_contradicts_a_signature_on_the_other_side_of_one() {
        use super::trial_contradicts;
        let at = |scale: f64| crate::modelling::diagnose::ScaleEstimate {
            damping_factor: 1.0,
            scale,
            temperature_k: 293.15 * scale * scale,
            test: "val.csv".to_string(),
        };
        // Frequencies fitted alone 0.79x, the trial 1.06x: on either side of 1.
        assert!(trial_contradicts(&[at(1.055)], "val.csv", 0.788));
        assert!(trial_contradicts(&[at(0.9)], "val.csv", 1.1));
        // A temperature: both the same way.
        assert!(!trial_contradicts(&[at(0.92)], "val.csv", 0.9));
        assert!(!trial_contradicts(&[at(1.08)], "val.csv", 1.1));
        // Only the test that shows the signature is asked, and an unmoved trial says nothing.
        assert!(!trial_contradicts(&[at(1.055)], "est.csv", 0.788));
        assert!(!trial_contradicts(&[at(1.0)], "val.csv", 0.788));
    }

    #[test]
    fn a_swing_is_a_steps_size_not_moved_by_a_wild_sample() {
        use super::swing;
        let mut step: Vec<f64> = (0..2000).map(|k| f64::from(u8::from(k >= 500))).collect();
        step[1000] = 50.0;
        step[1500] = f64::NAN;
        assert!((swing(&step) - 1.0).abs() < 1e-12, "{}", swing(&step));
        assert!(swing(&[]).abs() < f64::EPSILON);
    }

    /// A resonant probe (500 Hz, damping 0.05, 20 kHz) fitted on a step, diagnosed with a
    /// wake traverse whose tunnel runs at 300 Hz, measured through the same probe with its
    /// time scale `hot` times the model's (a gas `hot^2` times hotter): a traverse has no step
    /// to fit alone, so no test can show the frequencies moved.
    fn diagnosed(hot: f64) -> Vec<Candidate> {
        let (model, _) = second_order(500.0, 0.05, 20_000.0, 2);
        let model = &model;
        let fs = model.fs;
        let step: Vec<f64> = (0..4000)
            .map(|k| if k < 400 { 0.0 } else { 100.0 })
            .collect();
        let (est_u, est_y) = (
            with_noise(&step, 0.05, 1),
            with_noise(&model.simulate(&step), 0.05, 2),
        );
        let probe = crate::effects::scaled(model, hot).unwrap();
        // The record starts in the middle of the traverse: 2000 samples came before it.
        let lead = 2000;
        let pressure: Vec<f64> = traverse(fs, 300.0, lead, 12_000)
            .iter()
            .map(|v| 100.0 * v)
            .collect();
        let (val_u, val_y) = (
            with_noise(&pressure[lead..], 0.05, 3),
            with_noise(&probe.simulate(&pressure)[lead..], 0.05, 4),
        );
        let tests = [
            Test {
                name: "step.csv",
                u: &est_u,
                y: &est_y,
            },
            Test {
                name: "traverse.csv",
                u: &val_u,
                y: &val_y,
            },
        ];
        let current = Current {
            model,
            effects: &[],
            method: Method::Oe,
            uncertainty: None,
            order_given: true,
        };
        let evidence = diagnose::evidence(&current, &tests);
        diagnose::diagnose(&current, &tests, &evidence).unwrap()
    }

    fn temperature(c: &Candidate) -> bool {
        matches!(c.kind, Finding::Missing(k) if k.family() == EffectKind::Temperature)
    }

    #[test]
    fn a_traverse_in_a_hotter_gas_names_a_temperature_from_its_trial_alone() {
        let found = diagnosed(1.12);
        let first = found.first().expect("a candidate");
        assert!(temperature(first), "{found:?}");
        let Evidence::Temperature(t) = &first.evidence else {
            panic!("{first:?}")
        };
        assert!(!t.signature && t.per_test.is_empty(), "{t:?}");
        assert_eq!(t.test, "traverse.csv");
        assert!((t.common_ratio / 1.12 - 1.0).abs() < 0.03, "{t:?}");
        assert!(
            first.nrmse_before / first.nrmse_after >= super::TRIAL_ALONE_FALL,
            "{first:?}"
        );
        // The same probe as the model has it: the traverse is at its floor, nothing to read.
        let found = diagnosed(1.0);
        assert!(!found.iter().any(temperature), "{found:?}");
    }
}
