//! The verdicts beside the candidates: `unexplained` (the residual above the floor and no
//! trial lowers it) and `none` (nothing is missing).

use super::super::{Candidate, Evidence, Finding, Remedy};
use super::{Ranking, FLOOR_OVERRULED, MIN_IMPROVEMENT};

/// Puts `unexplained` first when the residual is above the floor and no candidate was offered.
///
/// Nothing is missing when the residual is what both channels' noise leaves (at the floor,
/// correlated only as that noise is), or at the floor with no effect's trial lowering it.
/// A residual above the floor that no effect's trial lowers is not "none": something
/// outside the catalogue is missing, and the diagnosis says so.
pub(super) fn unexplained(out: &mut Vec<Candidate>, r: &Ranking<'_>) {
    let (current, evidence, before, at_floor) = (r.current, r.evidence, r.before, r.at_floor);
    let (floor, white) = (r.floor, r.white);
    if !at_floor && out.is_empty() {
        let worst = evidence
            .iter()
            .map(|e| e.judged_nrmse() / e.judged_floor().max(f64::MIN_POSITIVE))
            .fold(0.0f64, f64::max);
        let reading = format!(
            "the residual is up to {worst:.2}x what both channels' noise leaves{}, but no \
             effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x: something outside \
             the catalogue is missing (a higher order, or physics the effects do not describe); \
             the model is not at its noise floor",
            if white {
                ""
            } else {
                " and correlated beyond that noise"
            },
        );
        let unexplained = Evidence::Unexplained {
            noise_floor: floor,
            nrmse: before,
            white,
            worst_over_floor: worst,
        };
        out.insert(
            0,
            Candidate {
                uncertainty_before: current.uncertainty.cloned(),
                ..Candidate::new(
                    Finding::Unexplained,
                    0.0,
                    (unexplained, reading),
                    Remedy::RaiseOrder,
                    (before, before),
                )
            },
        );
    }
}

/// Puts `none` first when every test is at its noise floor, white, and no trial cuts the
/// error by [`FLOOR_OVERRULED`], or when nothing was offered at the floor.
///
/// A trial that cuts the error by [`FLOOR_OVERRULED`] or more shows the floor was measured too
/// high (a noisy pre-step segment): the candidates then stand.
pub(super) fn nothing(out: &mut Vec<Candidate>, r: &Ranking<'_>) {
    let (current, evidence, before, at_floor) = (r.current, r.evidence, r.before, r.at_floor);
    let (floor, white) = (r.floor, r.white);
    let best_fall = out
        .iter()
        .map(|c| c.nrmse_before / c.nrmse_after)
        .fold(0.0f64, f64::max);
    if at_floor && ((white && best_fall < FLOOR_OVERRULED) || out.is_empty()) {
        let reading = format!(
            "the residuals are consistent with noise ({}error {:.3} % against a floor of {:.3} \
             %{}); no effect's trial lowers the held-out error by {MIN_IMPROVEMENT}x",
            if evidence.iter().any(|e| e.prediction.is_some()) {
                "one-step-ahead prediction "
            } else {
                ""
            },
            100.0 * before,
            100.0 * floor,
            if white { ", white" } else { "" }
        );
        let nothing = Evidence::Nothing {
            noise_floor: floor,
            nrmse: before,
            white,
        };
        let none = Candidate {
            uncertainty_before: current.uncertainty.cloned(),
            ..Candidate::new(
                Finding::Nothing,
                0.0,
                (nothing, reading),
                Remedy::Nothing,
                (before, before),
            )
        };
        out.insert(0, none);
    }
}
