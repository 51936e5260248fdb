//! Calibration: whether a fitted DC gain is taken as 1, the probe read against the same static
//! pressure as the reference.
//!
//! [`super::fit`] calls [`calibrate_fitted`] after the fit as found
//! ([`super::fit_as_found`]); a model whose physics lowers the static gain (a leak) skips it.

use super::model::Model;
use super::{nrmse, Fitted, Test};

/// A fitted DC gain within this many of its standard deviations of 1 is not evidence that the
/// probe's static calibration differs from the reference's.
pub const CALIBRATED_SIGMAS: f64 = 3.0;

/// The calibration is judged only when the DC gain is known to this standard deviation (2 %):
/// a less certain one is a model whose slow part the record does not determine (a slow
/// pole-zero pair that a drift or a leak leaves), not a level read through noise.
pub const CALIBRATION_MAX_STD: f64 = 0.02;

/// Takes the DC gain as 1 when the fit cannot tell it from 1 ([`CALIBRATED_SIGMAS`] of
/// `dc_gain_std`, itself at most [`CALIBRATION_MAX_STD`]): the numerator is scaled by
/// `1 / G(1)`, the poles and zeros kept, and the note says so. A compensator made for a DC gain that is noise (a level read through
/// low-frequency noise before the step) rescales every run's level by it, where the probe,
/// calibrated against the same static pressure as the reference, reads it right. `None`
/// (the model untouched) when the gain is exactly 1, clearly not 1, or not known.
pub fn calibrate(model: &mut Model, dc_gain_std: f64) -> Option<String> {
    let dc = model.dc_gain();
    if !taken_as_one(dc, dc_gain_std) {
        return None;
    }
    model.b.iter_mut().for_each(|b| *b /= dc);
    Some(format!(
        "the fitted DC gain {dc:.6} is within {CALIBRATED_SIGMAS} standard deviations ({dc_gain_std:.1e}) of 1: taken as 1 (a probe calibrated against the reference), the numerator scaled by {:.6}",
        1.0 / dc
    ))
}

/// Whether a DC gain `dc` known to `dc_gain_std` is taken as 1 ([`calibrate`]): not exactly 1,
/// within [`CALIBRATED_SIGMAS`] of it, and known to [`CALIBRATION_MAX_STD`] or better.
fn taken_as_one(dc: f64, dc_gain_std: f64) -> bool {
    let off = (dc - 1.0).abs();
    dc.is_finite()
        && dc_gain_std.is_finite()
        && off > 0.0
        && off <= CALIBRATED_SIGMAS * dc_gain_std
        && dc_gain_std <= CALIBRATION_MAX_STD
}

/// Whether [`calibrate`] would take the gain of `fitted`'s model as 1: the fit cannot tell it
/// from 1 and knows it well enough to say so.
pub(crate) fn would_calibrate(fitted: &Fitted) -> bool {
    fitted
        .report
        .uncertainty
        .as_ref()
        .is_some_and(|u| taken_as_one(fitted.model.dc_gain(), u.dc_gain_std))
}

/// Applies [`calibrate`] to a fit with its own uncertainty: where the gain is taken as 1, the
/// note is added, the gain fitted kept in `calibrated_from`, and the errors computed again on
/// the `estimation` and `validation` tests. Returns whether it was taken as 1.
pub fn calibrate_fitted(
    fitted: &mut Fitted,
    estimation: &Test<'_>,
    validation: &[Test<'_>],
) -> bool {
    let fitted_dc = fitted.model.dc_gain();
    let Some(note) = fitted
        .report
        .uncertainty
        .as_ref()
        .and_then(|u| calibrate(&mut fitted.model, u.dc_gain_std))
    else {
        return false;
    };
    fitted.report.notes.push(note);
    fitted.report.calibrated_from = Some(fitted_dc);
    fitted.nrmse_estimation = nrmse(&fitted.model, estimation.u, estimation.y);
    fitted.nrmse_validation = validation
        .iter()
        .map(|t| nrmse(&fitted.model, t.u, t.y))
        .collect();
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dc_gain_the_fit_cannot_tell_from_one_is_taken_as_one() {
        let model = Model {
            fs: 1000.0,
            delay: 2,
            a: vec![-0.9],
            b: vec![0.101, 0.0],
        };
        assert!((model.dc_gain() - 1.01).abs() < 1e-12);
        // 1 % off with a standard deviation of 0.5 %: two sigma, taken as 1.
        let mut near = model.clone();
        let note = calibrate(&mut near, 0.005).unwrap();
        assert!((near.dc_gain() - 1.0).abs() < 1e-12, "{}", near.dc_gain());
        assert_eq!((near.a.clone(), near.delay), (model.a.clone(), model.delay));
        assert!(note.contains("1.010000"), "{note}");
        // 1 % off with 0.1 %: ten sigma, a real calibration difference, kept.
        let mut far = model.clone();
        assert!(calibrate(&mut far, 0.001).is_none());
        assert_eq!(far, model);
        // A DC gain known to 10 %: the record does not determine the slow part.
        let mut vague = model.clone();
        assert!(calibrate(&mut vague, 0.1).is_none());
        assert_eq!(vague, model);
        // No uncertainty: nothing to judge by.
        let mut unknown = model.clone();
        assert!(calibrate(&mut unknown, f64::NAN).is_none());
        assert!(calibrate(&mut unknown, 0.0).is_none());
        assert_eq!(unknown, model);
    }
}
