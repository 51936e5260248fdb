//! Naming the missing physical effect from the evidence.
//!
//! This module owns the catalogue's decision: for a model and its tests it ranks candidate
//! effects ([`Candidate`]), each with the numbers behind it, a physical reading, and the exact
//! change that adds it. Two kinds of evidence are combined:
//!
//! 1. the residual's signature on each test ([`crate::evidence`]): a narrow spectral peak for
//!    a mode, a level before the step for an offset, a ramp for a drift, a slow creep after
//!    the step for a leak, correlation in time for coloured noise where the probe's own noise
//!    before the step is coloured (without a quiet segment: no cause in the input), a peak in
//!    the reference's own increments after the estimation step for a sensor resonance (a
//!    diaphragm rings in a step; a reference ringing only in another test is the pressure), at
//!    the frequency where the probe's residual peaks or at one frequency in every step whose
//!    reference rings (a line or cavity mode never shows in the reference, so a sensor
//!    resonance goes before a `mode` that ties with it), and natural frequencies of
//!    the tests fitted alone that all move by one common factor against the model's, with the
//!    damping about the same, for a temperature ([`temperature_evidence`]; where no test
//!    fitted alone can show it, its trial alone, counted down to the noise floor; both damping laws
//!    of [`crate::effects::TemperatureDamping`] are tried and the better offered, its `change`
//!    adding `temperature`, `temperature-viscous` or `temperature-diffusive`); and across tests
//!    ([`amplitude_signature`]), a damping that rises with the step's amplitude and a residual
//!    that grows faster than the step, for nonlinear damping;
//! 2. a trial: the model is refitted on the estimation test with the effect added
//!    ([`crate::effects::fit_with`]) and judged on the held-out tests. A candidate whose
//!    signature is present but whose trial does not lower the held-out error is not offered.
//!
//! The score is `ln(error before / error after)` on the held-out tests (the estimation test
//! when there is none). `none` is the verdict when every test is at its noise floor with white
//! residuals, or when no candidate's trial helps. A residual above the floor that no trial
//! lowers is `unexplained`, after two last resorts ([`diagnose`]): the trials with the delay
//! searched again, and a temperature read from its trial alone on any model, where no loss
//! could have moved the time scale that way.

use crate::effects::{self, EffectKind, FitChanges};
use crate::error::Result;
use crate::evidence::TestEvidence;
pub use crate::file::Current;
use crate::fit::{Test, TestRole};

mod across;
mod beside;
mod evidence;
mod finding;
mod order;
mod rank;
mod remedy;
mod sensor;
mod temperature;
mod trial;

pub use across::{
    amplitude_signature, per_test, temperature_evidence, AmplitudeSignature, PerTest,
    TemperatureEvidence, TemperatureRow, MIN_AMPLITUDE_RATIO, MIN_DAMPING_RISE,
    MIN_FREQUENCY_SHIFT, MIN_RESIDUAL_EXPONENT,
};
use across::{
    creep_in_standard_errors, drift_before_step, joint_loss_evidence, pre_step_slope,
    temperature_reading, temperature_shift,
};
pub use beside::Beside;
pub use evidence::{
    Evidence, JointLoss, ModeEvidence, NonlinearDamping, ProbePeak, ScaleEstimate, SensorResonance,
    Spectrum, TemperatureShift, COLOURED_NOISE_FIT, SENSOR_RESONANCE_REMEDY,
};
pub use finding::{
    separating_test, Candidate, Finding, SeparatingTest, TestToRecord, CLOSE_MARGIN,
};
pub use order::{
    drift_contradicted, leak_shown, margin, on_one_footing, over_all_tests, ramp_kept,
    ramp_returns, slope_kept, OrderRule, CREEP_SEEN_STANDARD_ERRORS, CREEP_SETTLED_BELOW,
    DRIFT_CONTRADICTED_STANDARD_ERRORS, LEAK_DC_GAIN_BELOW, RAMP_KEPT_BELOW,
};
pub use rank::{
    effective_samples, parameter_penalty, FLOOR_OVERRULED, MIN_IMPROVEMENT, SAME_FREQUENCY,
};
pub use remedy::Remedy;
pub use temperature::{loss_could_move, TRIAL_ALONE_DAMPING_BELOW, TRIAL_ALONE_FALL};
pub use trial::TRIAL_WINDOW;

fn mean(x: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = x.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// Measures the evidence on every test (the first is the estimation test).
#[must_use]
pub fn evidence(current: &Current<'_>, tests: &[Test<'_>]) -> Vec<TestEvidence> {
    // With a noise model the model is judged by its prediction error, against that error's
    // floor.
    let floors = if effects::noise_model(current.effects).is_some() {
        crate::fit::noise::prediction_floors(tests, current.model)
    } else {
        Vec::new()
    };
    tests
        .iter()
        .enumerate()
        .map(|(i, t)| {
            // With a sensor resonance the model is judged below it: on the prefiltered signals.
            let fs = current.model.fs;
            let ym = effects::predict(current.model, current.effects, t.u, t.y);
            TestEvidence::measure(
                t.name,
                TestRole::of_index(i),
                current.model,
                (
                    &effects::observed(current.effects, fs, t.u),
                    &effects::observed(current.effects, fs, t.y),
                ),
                &ym,
            )
            .with_prediction(
                effects::judged_nrmse(current.model, current.effects, t.u, t.y),
                floors.get(i).cloned().flatten(),
            )
        })
        .collect()
}

/// Ranks the candidates, best first; `none` alone when nothing is missing.
///
/// The trials refit at the model's delay. Where none of them lowers the held-out error
/// (`unexplained`), two last resorts are tried, each kept only if it names an effect:
///
/// 1. the trials again with the delay searched in each, as `unlag fit --add` will (unless the
///    model file fixes the delay): a slow pole an effect adds trades with the delay (a
///    capillary's leak: its slow pole takes up part of the lag the plain model's longer delay
///    stood for);
/// 2. a temperature read from its trial alone on a model with no resonance short of critical
///    damping ([`TRIAL_ALONE_DAMPING_BELOW`] keeps losses from it while another effect is
///    offered), where no loss could have moved the time scale that way ([`loss_could_move`]):
///    an overdamped capillary validated by a smaller traverse at another gas temperature, which
///    runs slower, which a loss cannot make a smaller test do.
///
/// Where the first candidate's effect alone leaves the model short of its own estimation
/// test, and a mode beside it lowers that test's error and the held-out error further, its
/// change adds both ([`Beside`]).
///
/// The trials add each effect as `unlag fit --add` does ([`effects::add`]): a mode beside the
/// model's modes. Where the model's order was given and it carries modes, which a refit with an
/// order given drops, every change names them again ([`Remedy::KeepingModes`]), so that it
/// fits what its trial fitted.
///
/// # Errors
/// Only when the current model cannot be evaluated; a trial that fails is simply not
/// offered.
pub fn diagnose(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
) -> Result<Vec<Candidate>> {
    let mut found = ranked(current, tests, evidence)?;
    beside::mode_beside(current, tests, evidence, &mut found);
    let modes = current
        .effects
        .iter()
        .filter(|e| e.kind() == EffectKind::Mode)
        .count();
    if current.order_given && modes > 0 {
        for c in &mut found {
            if !matches!(c.change, Remedy::Nothing | Remedy::RaiseOrder) {
                let change = Box::new(std::mem::replace(&mut c.change, Remedy::Nothing));
                c.change = Remedy::KeepingModes { change, modes };
            }
        }
    }
    Ok(found)
}

/// The candidates [`diagnose`] ranks, with its last resorts, before a mode is set beside the
/// first.
fn ranked(
    current: &Current<'_>,
    tests: &[Test<'_>],
    evidence: &[TestEvidence],
) -> Result<Vec<Candidate>> {
    let kept = rank::rank_at(current, tests, evidence, Some(current.model.delay), false)?;
    if !kept
        .first()
        .is_some_and(|c| matches!(c.kind, Finding::Unexplained))
    {
        return Ok(kept);
    }
    let delay = current.model.delay;
    let delay_fixed = FitChanges::of(current.effects).delay.is_some();
    for resort in [LastResort::DelaySearched, LastResort::TemperatureOnAnyModel] {
        let (at, any_damping) = match resort {
            LastResort::DelaySearched if delay_fixed => continue,
            LastResort::DelaySearched => (None, false),
            LastResort::TemperatureOnAnyModel => (Some(delay), true),
        };
        let mut found = rank::rank_at(current, tests, evidence, at, any_damping)?;
        if found
            .first()
            .is_some_and(|c| matches!(c.kind, Finding::Missing(_)))
        {
            let how = resort.reading(delay);
            for c in &mut found {
                c.reading.push_str("; ");
                c.reading.push_str(&how);
            }
            return Ok(found);
        }
    }
    Ok(kept)
}

/// A last resort [`diagnose`] tries before it says `unexplained`.
#[derive(Debug, Clone, Copy)]
enum LastResort {
    /// The trials again, with the delay searched in each.
    DelaySearched,
    /// A temperature read from its trial alone on any model, where no loss could have moved
    /// the time scale that way.
    TemperatureOnAnyModel,
}

impl LastResort {
    /// What a candidate it found adds to its reading, for a model at `delay` samples.
    fn reading(self, delay: usize) -> String {
        match self {
            Self::DelaySearched => format!(
                "found with the delay searched again in the trial (at the model's {delay} samples \
                 no effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x)"
            ),
            Self::TemperatureOnAnyModel => {
                "found as a last resort: no other effect's trial lowers the held-out error".into()
            }
        }
    }
}
