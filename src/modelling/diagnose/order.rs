//! The order of the candidates: by score, then the physics that decides between two that
//! score within [`CLOSE_MARGIN`] of each other.

use serde::Serialize;

use super::{separating_test, Candidate, Evidence, NonlinearDamping, CLOSE_MARGIN};
use crate::effects::EffectKind;
use crate::evidence::Trend;

/// A leak lowers the probe's static gain (`1 / (1 + R G)` for a leaking cavity, below 1 for a
/// leaking side volume too); a thermal creep, the other slow pole the `leak` effect models,
/// does not. A model whose DC gain is below this shows a leaking volume: 0.2 % under 1, twice
/// the scatter of a DC gain fitted on a 0.1 % noise step (a leaking volume lowers it by
/// percents: its resistance against the line's, `R G`, is a few hundredths or more).
pub const LEAK_DC_GAIN_BELOW: f64 = 0.998;

/// A residual slope before the step this many standard errors from a drift's fitted rate, and
/// not of its sign, contradicts the drift.
pub const DRIFT_CONTRADICTED_STANDARD_ERRORS: f64 = 4.0;

/// Whether the tests show a leak's signature, which gates its trial: the current model's DC
/// gain (`dc_gain`) below [`LEAK_DC_GAIN_BELOW`] (a leaking volume lowers the static gain),
/// or a creep after the step [`CREEP_SEEN_STANDARD_ERRORS`] or more out of the noise
/// (`creep_z`) that has settled by the end of the estimation test (`slope_kept` below
/// [`CREEP_SETTLED_BELOW`], [`slope_kept`]): a thermal creep approaches its level
/// exponentially. Without either, a leak's pole and zero would only lend their shape to
/// something else (a mode's ringing, the probe's own higher-order dynamics, a sensor's drift,
/// which runs on at its rate), and its trial is not run.
#[must_use]
pub fn leak_shown(dc_gain: f64, creep_z: f64, slope_kept: Option<f64>) -> bool {
    dc_gain < LEAK_DC_GAIN_BELOW
        || creep_z.abs() >= CREEP_SEEN_STANDARD_ERRORS
            && slope_kept.is_some_and(|k| k.abs() < CREEP_SETTLED_BELOW)
}

/// Whether the residual's slope before the step (`pre`, standard error `pre_se`, per second)
/// contradicts a drift at `rate` per second: a sensor's drift runs in time, before the step as
/// after it, so its slope there is the rate; one [`DRIFT_CONTRADICTED_STANDARD_ERRORS`] away
/// that does not share its sign may be a ramp the dynamics leave after the step. The reading
/// says so; the order does not rank on it: it can contradict real drifts that score best,
/// and would put them behind another candidate.
#[must_use]
pub fn drift_contradicted(pre: f64, pre_se: f64, rate: f64) -> bool {
    pre_se.is_finite()
        && (pre - rate).abs() > DRIFT_CONTRADICTED_STANDARD_ERRORS * pre_se
        && pre * rate <= 0.0
}

/// A ramp whose level at the end of the record keeps less than this fraction of what the
/// straight line through the residual puts there has come back: a hump the dynamics leave
/// after the step, not a drift ([`ramp_kept`]).
pub const RAMP_KEPT_BELOW: f64 = 0.25;

/// How much of a straight line through a test's residual its level keeps at the end: the
/// residual's mean over the last 30 % of the record less its mean before the step, over what
/// the line (slope `trend.slope_per_s`) rises between the two segments' centres; and that
/// difference less the line's rise, in standard errors of the two means under the noise both
/// channels leave. The test is `samples` long with its step at `onset`, sampled at `fs`.
///
/// A sensor's drift runs on to the end of the record: about 1, less where the fit took part of
/// it into its dynamics (0.34 to 1.27 over the drifting probes the bench draws). A hump the
/// dynamics leave after a step returns to the level before it (-0.18 to 0.22 where a
/// capillary's tail after a step of another size or temperature reads as a drift), though
/// the line through it climbs. `None` without a segment before the step, or a line that does
/// not rise.
#[must_use]
pub fn ramp_kept(trend: &Trend, samples: usize, onset: usize, fs: f64) -> Option<(f64, f64)> {
    let late = (3 * samples / 10).max(1);
    if onset == 0 || onset + late > samples || fs.is_nan() || fs <= 0.0 {
        return None;
    }
    // Centres of the segment before the step and of the last 30 %, in seconds.
    let pre_centre = 0.5 * (onset as f64 - 1.0) / fs;
    let late_centre = (samples as f64 - 0.5 * late as f64 - 0.5) / fs;
    let rise = trend.slope_per_s * (late_centre - pre_centre);
    let moved = trend.late_mean - trend.pre_mean;
    let se = trend.late_mean_se.hypot(trend.pre_mean_se);
    let kept = moved / rise;
    let z = (moved - rise) / se;
    (kept.is_finite() && z.is_finite()).then_some((kept, z))
}

/// Whether a ramp keeps so little of its rise at the end of the record ([`ramp_kept`]: less
/// than [`RAMP_KEPT_BELOW`] of it, and [`DRIFT_CONTRADICTED_STANDARD_ERRORS`] or more from the
/// line) that it is a hump the dynamics leave, not a drift.
#[must_use]
pub fn ramp_returns(kept: Option<(f64, f64)>) -> bool {
    kept.is_some_and(|(k, z)| k < RAMP_KEPT_BELOW && z.abs() >= DRIFT_CONTRADICTED_STANDARD_ERRORS)
}

/// A creep after the step this many standard errors of the two levels' means out of the noise
/// is seen (the leak's other signature, beside a DC gain below 1).
pub const CREEP_SEEN_STANDARD_ERRORS: f64 = 3.0;

/// A residual whose slope over the last 30 % of the record keeps less than this fraction of a
/// straight line's through the whole of it has settled: a leak's creep, which approaches its
/// level exponentially, and not a sensor's drift, which runs on at its rate ([`slope_kept`]).
pub const CREEP_SETTLED_BELOW: f64 = 0.5;

/// How much of the slope of a straight line through a test's whole residual, `seconds` long,
/// its slope over the last 30 % of the record keeps (`None` where either slope is not finite
/// or the line is flat: its rise over the record within the standard error of the late
/// segment's mean, where a ratio to it is noise over noise and can read -5e13 once a drift
/// is fitted). A leak's creep settles: near 0 (-0.1 to 0.2) for a leak whose volume fills
/// before the record ends. A sensor's drift runs on to the end: 1.4 to 6.8 for drifts whose
/// DC gain and creep read as a leak's (above 1 where the fit took part of the ramp into its
/// dynamics).
#[must_use]
pub fn slope_kept(trend: &Trend, seconds: f64) -> Option<f64> {
    let kept = trend.late_slope_per_s / trend.slope_per_s;
    let rise = (trend.slope_per_s * seconds).abs();
    (rise > trend.late_mean_se && kept.is_finite()).then_some(kept)
}

/// The rule of the order that put a candidate where its score alone would not
/// ([`Candidate::ordered_by`]). In `--json`, kebab-case: `settled-leak-before-mode`, ...
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum OrderRule {
    /// A resonance the reference shows too is the transducers', before a mode.
    ResonanceInTheReference,
    /// A leak with both its signatures, its creep settled, before a mode that ties with it.
    SettledLeakBeforeMode,
    /// An effect whose signature was seen before a nonlinear damping read from its trial alone.
    SignatureBeforeLossTrial,
    /// A loss the tests show before a temperature read from its trial alone.
    LossBeforeTemperatureTrial,
    /// A temperature and a loss, both fitted on all the tests, in the order of what each leaves.
    LessOverAllTests,
}

impl OrderRule {
    /// The rule in words.
    #[must_use]
    pub const fn as_str(self) -> &'static str {
        match self {
            Self::ResonanceInTheReference => {
                "a resonance the reference shows too is the transducers', not a line's mode"
            }
            Self::SettledLeakBeforeMode => {
                "a leak whose DC gain is below 1 and whose creep settles goes before a mode \
                 that ties with it"
            }
            Self::SignatureBeforeLossTrial => {
                "an effect whose signature was seen goes before a nonlinear damping read from \
                 its trial alone"
            }
            Self::LossBeforeTemperatureTrial => {
                "a loss the tests show goes before a temperature read from its trial alone"
            }
            Self::LessOverAllTests => {
                "a temperature and a loss, both fitted on all the tests, go in the order of \
                 the error each leaves over them"
            }
        }
    }
}

impl core::fmt::Display for OrderRule {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Sorts the candidates by score, best first, then applies the rules in the order of
/// [`OrderRule::IN_ORDER`]: a sensor resonance the reference shows before a mode that would
/// only model it (at any margin where the probe peaks beside it, else when they tie); a leak
/// with both its signatures and a creep that settles before a mode that ties with it; an
/// effect whose signature was seen before a nonlinear damping read from its trial alone that
/// ties with it; a loss the tests show before a temperature read from its trial alone; a
/// temperature and a loss both fitted on all the tests in the order of what each leaves
/// ([`temperature_or_loss`]). The signatures that decide whether a trial is run at all
/// ([`leak_shown`]) are read before scoring, where the candidates are offered.
pub(super) fn order(out: &mut Vec<Candidate>) {
    out.sort_by(|a, b| b.score.total_cmp(&a.score));
    for rule in OrderRule::IN_ORDER {
        rule.apply(out);
    }
}

impl OrderRule {
    /// Every rule, in the order they apply: each decides between the candidates the ones
    /// before it left.
    pub const IN_ORDER: [Self; 5] = [
        Self::ResonanceInTheReference,
        Self::SettledLeakBeforeMode,
        Self::SignatureBeforeLossTrial,
        Self::LossBeforeTemperatureTrial,
        Self::LessOverAllTests,
    ];

    /// Applies the rule to `out`, sorted by score and by the rules before it.
    fn apply(self, out: &mut Vec<Candidate>) {
        match self {
            Self::ResonanceInTheReference => resonance_in_the_reference(out),
            Self::SettledLeakBeforeMode => settled_leak_before_mode(out),
            Self::SignatureBeforeLossTrial => signature_before_loss_trial(out),
            Self::LossBeforeTemperatureTrial => loss_before_temperature_trial(out),
            Self::LessOverAllTests => temperature_or_loss(out),
        }
    }
}

/// A resonance that shows in the reference as well is the transducers', not the line's:
/// the sensor resonance goes before a mode that would only model it, at any margin where
/// the probe peaks beside the reference's ringing, and where the two tie when the probe
/// shows no peak there (the line before its transducer filters the diaphragm out).
fn resonance_in_the_reference(out: &mut Vec<Candidate>) {
    let s = out
        .iter()
        .position(|c| c.kind == EffectKind::SensorResonance);
    let m = out.iter().position(|c| c.kind == EffectKind::Mode);
    if let (Some(s), Some(m)) = (s, m) {
        let (sensor, mode) = (&out[s], &out[m]);
        let in_probe =
            matches!(&sensor.evidence, Evidence::SensorResonance(e) if e.probe.is_some());
        if m < s && (in_probe || mode.score - sensor.score < CLOSE_MARGIN) {
            let mut c = out.remove(s);
            c.ordered_by = Some(OrderRule::ResonanceInTheReference);
            out.insert(m, c);
        }
    }
}

/// A leak with both its signatures, a leaking volume's DC gain below LEAK_DC_GAIN_BELOW and
/// a creep after the step, goes before a mode that ties with it when the creep has settled
/// by the end of the estimation test: the mode's two poles and zeros can take a slow pole's
/// shape, but a line's acoustic mode lowers no static gain. A sensor's drift lowers the
/// fitted DC gain and leaves a creep too, but runs on to the end of the record (its slope
/// over the last 30 % several times the line's), so a creep that keeps its rate is no leak's,
/// and one with a small fraction of the line's slope left at the end is.
fn settled_leak_before_mode(out: &mut Vec<Candidate>) {
    yield_first(
        out,
        OrderRule::SettledLeakBeforeMode,
        |c| c.kind == EffectKind::Mode,
        |c| {
            matches!(
                c.evidence,
                Evidence::Leak { dc_gain, creep_in_standard_errors: z, creep_slope_kept: Some(k), .. }
                    if dc_gain < LEAK_DC_GAIN_BELOW
                        && z.abs() >= CREEP_SEEN_STANDARD_ERRORS
                        && k.abs() < CREEP_SETTLED_BELOW
            )
        },
    );
}

/// Nonlinear damping read from its trial alone (no amplitude signature, no fit of the tests
/// together) goes after an effect
/// whose own signature was seen: a quadratic loss refitted on one step can take the shape
/// of a slower effect too.
fn signature_before_loss_trial(out: &mut Vec<Candidate>) {
    let trial_alone = |c: &Candidate| {
        matches!(
            c.evidence,
            Evidence::NonlinearDamping(NonlinearDamping {
                amplitude_signature: false,
                joint: None,
                ..
            })
        )
    };
    yield_first(out, OrderRule::SignatureBeforeLossTrial, trial_alone, |c| {
        !trial_alone(c) && c.kind != EffectKind::ColouredNoise
    });
}

/// A temperature read from its trial alone (no test fitted alone showed the shift) fitted
/// one free time scale to each held-out test: any effect that differs between the tests
/// can lend it a fall. A nonlinear damping whose signature the tests show (the damping
/// rising with the step, or one model with a loss explaining the tests together) is such an
/// effect, and goes before it at any margin (a flush probe's quadratic loss can lend a
/// traverse's free time scale a larger fall than the loss's own fit on both tests).
fn loss_before_temperature_trial(out: &mut Vec<Candidate>) {
    yield_first_within(
        out,
        OrderRule::LossBeforeTemperatureTrial,
        |c| matches!(&c.evidence, Evidence::Temperature(t) if !t.signature),
        |c| {
            matches!(
                &c.evidence,
                Evidence::NonlinearDamping(n) if n.amplitude_signature || n.joint.is_some()
            )
        },
        f64::INFINITY,
    );
}

/// A temperature and a nonlinear damping fitted on the tests together each add one parameter
/// and each explain why the tests differ, and their held-out falls are not measured alike:
/// the loss's against one linear model fitted to all the tests, the temperature's against the
/// model fitted on the estimation test. Where the temperature was fitted on all the tests
/// too (one model, each test its own time scale), the one that leaves less over all the tests
/// ([`JointLoss::rms`](super::JointLoss::rms) against
/// [`TemperatureShift::joint_rms`](super::TemperatureShift::joint_rms)) goes before the other
/// at any margin. Against the trial alone, whose dynamics keep the estimation test's, the
/// loss's refit of the dynamics on every test decided where the plain model misses the
/// probe's own dynamics (a temperature's trial can leave more than the loss, and less once
/// fitted on both tests).
fn temperature_or_loss(out: &mut Vec<Candidate>) {
    // The first temperature (`true`) or loss with its RMS over all the tests, and where it is.
    let find = |temperature: bool| {
        out.iter().enumerate().find_map(|(i, c)| {
            over_all_tests(c).and_then(|(t, r)| (t == temperature).then_some((i, r)))
        })
    };
    let (Some((t, tr)), Some((l, lr))) = (find(true), find(false)) else {
        return;
    };
    let (better, worse) = if lr < tr { (l, t) } else { (t, l) };
    if better > worse {
        let mut c = out.remove(better);
        c.ordered_by = Some(OrderRule::LessOverAllTests);
        out.insert(worse, c);
    }
}

/// A temperature's or a quadratic loss's RMS error over all the tests, each fitted on them
/// all (the footing the order sets the two on, [`OrderRule::LessOverAllTests`]), and whether
/// it is the temperature; `None` for any other candidate, or one not fitted so.
#[must_use]
pub fn over_all_tests(c: &Candidate) -> Option<(bool, f64)> {
    match &c.evidence {
        Evidence::Temperature(t) => t.joint_rms().map(|r| (true, r)),
        Evidence::NonlinearDamping(n) => n.joint.as_ref().map(|j| (false, j.rms())),
        _ => None,
    }
}

/// For a temperature and a loss both fitted on all the tests, `c` first: the log of the ratio
/// of what `next` leaves over them to what `c` leaves, the footing they are ordered on (their
/// scores are not on one: the loss's is in-sample, the temperature's held out with each
/// test's own time scale); `None` for any other pair.
#[must_use]
pub fn on_one_footing(c: &Candidate, next: &Candidate) -> Option<f64> {
    match (over_all_tests(c), over_all_tests(next)) {
        (Some((a, ra)), Some((b, rb))) if a != b => Some((rb / ra).ln()),
        _ => None,
    }
}

/// The margin of `c` over `next`: [`on_one_footing`] where that applies, else their score
/// difference; `c`'s score when it is the last.
#[must_use]
pub fn margin(c: &Candidate, next: Option<&Candidate>) -> f64 {
    next.map_or(c.score, |n| {
        on_one_footing(c, n).unwrap_or(c.score - n.score)
    })
}

/// Sets each candidate's margin over the next ([`margin`]) and, where the next is within
/// [`CLOSE_MARGIN`] or scores more (a rule of the order put this one first), the test that
/// would tell the two apart.
pub fn set_margins(out: &mut [Candidate]) {
    for i in 0..out.len() {
        let next = out.get(i + 1);
        let Some(c) = out.get(i) else { continue };
        let m = margin(c, next);
        let separated_by = next
            .filter(|n| m < CLOSE_MARGIN || n.score > c.score)
            .map(|n| separating_test(c.kind, n.kind));
        if let Some(c) = out.get_mut(i) {
            c.margin = m;
            c.separated_by = separated_by;
        }
    }
}

/// When the first candidate is one `first` picks, the first candidate `before` picks that
/// scores within [`CLOSE_MARGIN`] of it goes before it; the others keep their order.
fn yield_first(
    out: &mut Vec<Candidate>,
    rule: OrderRule,
    first: impl Fn(&Candidate) -> bool,
    before: impl Fn(&Candidate) -> bool,
) {
    yield_first_within(out, rule, first, before, CLOSE_MARGIN);
}

/// As [`yield_first`], within `margin` of the first's score (infinite: at any margin).
fn yield_first_within(
    out: &mut Vec<Candidate>,
    rule: OrderRule,
    first: impl Fn(&Candidate) -> bool,
    before: impl Fn(&Candidate) -> bool,
    margin: f64,
) {
    if !out.first().is_some_and(&first) {
        return;
    }
    let top = out.first().map_or(0.0, |c| c.score);
    if let Some(i) = out
        .iter()
        .position(|c| before(c) && c.score >= top - margin)
    {
        let mut c = out.remove(i);
        c.ordered_by = Some(rule);
        out.insert(0, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modelling::diagnose::{Finding, ModeEvidence, NonlinearDamping, Remedy, Spectrum};

    fn candidate(kind: EffectKind, score: f64, evidence: Evidence) -> Candidate {
        Candidate::new(
            Finding::Missing(kind),
            score,
            (evidence, String::new()),
            Remedy::Nothing,
            (1.0, 1.0),
        )
    }

    fn peak(above_floor_db: f64) -> Evidence {
        Evidence::Mode(ModeEvidence::Peak {
            spectrum: Spectrum::Residual,
            frequency_hz: 50.0,
            above_floor_db,
            q: 3.0,
            test: "t.csv".into(),
        })
    }

    #[test]
    fn a_leak_is_shown_by_a_gain_below_one_or_by_a_creep_out_of_the_noise_that_settles() {
        // A leaking volume: the DC gain below 1, whatever the creep.
        assert!(leak_shown(0.97, 0.0, None));
        assert!(leak_shown(0.9979, 1.0, Some(3.0)));
        // At unit gain, a creep 12 standard errors out that keeps 0.05 of the line's slope at
        // the end (a thermal creep), of either sign.
        assert!(leak_shown(1.0, 12.0, Some(0.05)));
        assert!(leak_shown(1.0, -3.0, Some(-0.49)));
        // At unit gain: no creep out of the noise, a creep that runs on as a drift does, or
        // one whose slope cannot be read: nothing of a leak.
        assert!(!leak_shown(0.998, 2.9, Some(0.05)));
        assert!(!leak_shown(1.0, 12.0, Some(0.5)));
        assert!(!leak_shown(1.0, 12.0, Some(-3.2)));
        assert!(!leak_shown(1.0, 12.0, None));
        assert!(!leak_shown(f64::NAN, f64::NAN, Some(0.0)));
    }

    #[test]
    fn a_leak_whose_creep_settles_goes_before_a_mode_it_ties_with_and_a_drift_does_not() {
        // A settled creep: the mode 0.11 ahead, the DC gain 0.948, the creep 47 standard
        // errors out, 0.04 of the line's slope left at the end of the record.
        let first = |dc_gain: f64, z: f64, kept: Option<f64>, leak_score: f64| {
            let mut out = vec![
                candidate(EffectKind::Mode, 1.30, peak(37.0)),
                candidate(
                    EffectKind::Leak,
                    leak_score,
                    Evidence::Leak {
                        dc_gain,
                        late_residual_over_step: -0.0058,
                        creep_in_standard_errors: z,
                        creep_slope_kept: kept,
                    },
                ),
            ];
            order(&mut out);
            out[0].kind
        };
        let mode = Finding::Missing(EffectKind::Mode);
        let leak = Finding::Missing(EffectKind::Leak);
        assert_eq!(first(0.948, -46.7, Some(0.04), 1.19), leak);
        assert_eq!(first(0.948, -46.7, Some(-0.3), 1.19), leak);
        // A creep that runs on at its rate is a drift's (3.2 times the line's slope at the
        // end), or one whose shape is unknown: the mode keeps its place.
        assert_eq!(first(0.948, -46.7, Some(3.17), 1.19), mode);
        assert_eq!(first(0.948, -46.7, Some(0.6), 1.19), mode);
        assert_eq!(first(0.948, -46.7, None, 1.19), mode);
        // Either signature missing, or the mode well ahead: the mode keeps its place.
        assert_eq!(first(0.999, -46.7, Some(0.04), 1.19), mode);
        assert_eq!(first(0.948, -2.0, Some(0.04), 1.19), mode);
        assert_eq!(first(0.948, -46.7, Some(0.04), 0.90), mode);
    }

    #[test]
    fn a_ringing_reference_puts_the_transducers_before_a_mode_they_tie_with() {
        // The reference rings at 2.3 kHz in both tests, the probe shows
        // no peak there, and the mode's trial (two free poles and zeros) scores as the
        // transducers' does.
        let sensor = |probe: Option<f64>| {
            Evidence::SensorResonance(crate::modelling::diagnose::SensorResonance {
                probe: probe.map(|db| crate::modelling::diagnose::ProbePeak {
                    above_floor_db: db,
                    frequency_hz: 2.29e3,
                    source: Spectrum::Residual,
                }),
                reference_above_floor_db: 16.0,
                reference_peak_hz: 2.29e3,
                reference_q: 9.8,
                reference_test: "est.csv".into(),
                remedy: String::new(),
            })
        };
        let first = |mode: f64, probe: Option<f64>| {
            let mut out = vec![
                candidate(EffectKind::Mode, mode, peak(16.0)),
                candidate(EffectKind::SensorResonance, 0.11, sensor(probe)),
            ];
            order(&mut out);
            out[0].kind
        };
        let (sensor_first, mode_first) = (
            Finding::Missing(EffectKind::SensorResonance),
            Finding::Missing(EffectKind::Mode),
        );
        assert_eq!(first(0.112, None), sensor_first);
        // The mode well ahead: it keeps its place, unless the probe peaks beside the ringing.
        assert_eq!(first(0.9, None), mode_first);
        assert_eq!(first(0.9, Some(12.0)), sensor_first);
    }

    #[test]
    fn nonlinear_damping_from_its_trial_alone_goes_after_a_close_effect_with_a_signature() {
        // Seen: the amplitude signature, or one model with the loss fitted to the tests
        // together where no linear one explains them.
        let loss = |signature: bool, joint: bool| {
            let joint = joint.then(|| crate::modelling::diagnose::JointLoss {
                tests: vec!["step.csv".into(), "traverse.csv".into()],
                linear_nrmse: vec![0.012, 0.010],
                nrmse: vec![0.004, 0.007],
                gain_s2_per_unit: 1e-9,
                fall: 2.1,
            });
            Evidence::NonlinearDamping(NonlinearDamping::of(None, signature, 1e-9, joint))
        };
        let drift = Evidence::Drift {
            pre_step_slope_per_s: 0.05,
            pre_step_slope_se_per_s: 0.01,
            ramp_in_standard_errors: 12.0,
            rate_per_s: 0.05,
            ramp_kept_at_end: Some(1.0),
        };
        for (signature, joint, first) in [
            (false, false, EffectKind::Drift),
            (true, false, EffectKind::NonlinearDamping),
            (false, true, EffectKind::NonlinearDamping),
        ] {
            let mut out = vec![
                candidate(EffectKind::Drift, 1.67, drift.clone()),
                candidate(EffectKind::NonlinearDamping, 1.70, loss(signature, joint)),
            ];
            order(&mut out);
            assert_eq!(
                out[0].kind,
                Finding::Missing(first),
                "signature {signature}, joint {joint}"
            );
        }
    }

    #[test]
    fn slope_kept_is_the_late_slope_over_the_line_and_none_for_a_flat_line() {
        let trend = |late: f64, line: f64| Trend {
            pre_mean: 0.0,
            pre_slope_per_s: 0.0,
            pre_slope_se_per_s: 1.0,
            late_mean: 1.0,
            late_slope_per_s: late,
            slope_per_s: line,
            pre_mean_se: 0.1,
            late_mean_se: 0.1,
        };
        assert_eq!(slope_kept(&trend(-2.0, -40.0), 1.0), Some(0.05));
        assert_eq!(slope_kept(&trend(-80.0, -40.0), 1.0), Some(2.0));
        assert_eq!(slope_kept(&trend(1.0, 0.0), 1.0), None);
        assert_eq!(slope_kept(&trend(f64::NAN, 1.0), 1.0), None);
        // A line that rises 0.04 over the record, less than the late mean's standard error
        // (0.1): flat, whatever the ratio.
        assert_eq!(slope_kept(&trend(-2.0, -40.0), 1e-3), None);
        assert_eq!(slope_kept(&trend(-2.0, -40.0), 0.01), Some(0.05));
    }

    #[test]
    fn a_temperature_from_its_trial_alone_goes_after_a_nonlinear_damping_the_tests_show() {
        let temperature = |signature: bool| {
            Evidence::Temperature(crate::modelling::diagnose::TemperatureShift {
                add: EffectKind::Temperature,
                common_ratio: 1.165,
                damping: crate::effects::TemperatureDamping::Constant,
                damping_ratio: 1.0,
                estimated_scale: Vec::new(),
                per_test: Vec::new(),
                reference_k: 293.15,
                temperature_ratio: 1.357,
                signature,
                test: "traverse.csv".into(),
                trial_nrmse: Vec::new(),
                joint_nrmse: None,
                viscous_damping_ratio: 1.0,
            })
        };
        let joint = crate::modelling::diagnose::JointLoss {
            tests: vec!["step.csv".into(), "traverse.csv".into()],
            linear_nrmse: vec![0.0074, 0.0041],
            nrmse: vec![0.0020, 0.0033],
            gain_s2_per_unit: 2e-15,
            fall: 2.21,
        };
        let loss = |joint: Option<crate::modelling::diagnose::JointLoss>| {
            Evidence::NonlinearDamping(NonlinearDamping::of(None, false, 2e-15, joint))
        };
        // A flush probe's loss: the temperature 1.08, the loss 0.76, beyond the close margin.
        for (signature, joint, first) in [
            (false, Some(joint.clone()), EffectKind::NonlinearDamping),
            // The tests showed the temperature: the scores decide.
            (true, Some(joint), EffectKind::Temperature),
            // The loss from its trial alone is no signature either.
            (false, None, EffectKind::Temperature),
        ] {
            let mut out = vec![
                candidate(EffectKind::Temperature, 1.08, temperature(signature)),
                candidate(EffectKind::NonlinearDamping, 0.76, loss(joint.clone())),
            ];
            order(&mut out);
            assert_eq!(
                out[0].kind,
                Finding::Missing(first),
                "signature {signature}, joint {}",
                joint.is_some()
            );
        }
    }

    #[test]
    fn a_temperature_and_a_loss_both_fitted_on_all_the_tests_go_in_the_order_of_what_each_leaves() {
        let temperature = |signature: bool, trial: [f64; 2], joint: Option<[f64; 2]>| {
            Evidence::Temperature(crate::modelling::diagnose::TemperatureShift {
                add: EffectKind::TemperatureViscous,
                common_ratio: 0.86,
                damping: crate::effects::TemperatureDamping::Viscous,
                damping_ratio: 1.0,
                estimated_scale: Vec::new(),
                per_test: Vec::new(),
                reference_k: 293.15,
                temperature_ratio: 0.74,
                signature,
                test: "val.csv".into(),
                trial_nrmse: trial.to_vec(),
                joint_nrmse: joint.map(|j| j.to_vec()),
                viscous_damping_ratio: 0.68,
            })
        };
        let loss = |nrmse: [f64; 2]| {
            Evidence::NonlinearDamping(NonlinearDamping::of(
                None,
                false,
                1e-9,
                Some(crate::modelling::diagnose::JointLoss {
                    tests: vec!["est.csv".into(), "val.csv".into()],
                    linear_nrmse: vec![0.0067, 0.0059],
                    nrmse: nrmse.to_vec(),
                    gain_s2_per_unit: 1e-9,
                    fall: 1.21,
                }),
            ))
        };
        let first = |t: (f64, Evidence), l: (f64, Evidence)| {
            let mut out = vec![
                candidate(EffectKind::TemperatureViscous, t.0, t.1),
                candidate(EffectKind::NonlinearDamping, l.0, l.1),
            ];
            order(&mut out);
            if out[0].score < out[1].score {
                // Put ahead by the rule, and marked so.
                assert!(matches!(
                    out[0].ordered_by,
                    Some(OrderRule::LessOverAllTests | OrderRule::LossBeforeTemperatureTrial)
                ));
            }
            out[0].kind
        };
        let (t_first, l_first) = (
            Finding::Missing(EffectKind::TemperatureViscous),
            Finding::Missing(EffectKind::NonlinearDamping),
        );
        // A temperature, scores swapped: the trial leaves 0.60 % over both tests, the
        // loss 0.53 %, but fitted on both tests the temperature leaves 0.45 %.
        let (trial, joint, lossy) = ([0.0049, 0.0070], [0.00495, 0.00394], [0.00541, 0.00511]);
        assert_eq!(
            first(
                (0.16, temperature(true, trial, Some(joint))),
                (0.41, loss(lossy))
            ),
            t_first
        );
        // Until the temperature is fitted on all the tests, the scores decide.
        assert_eq!(
            first((0.16, temperature(true, trial, None)), (0.41, loss(lossy))),
            l_first
        );
        // The loss leaves 0.39 % over both tests, the temperature 0.55 %
        // either way; it goes first though it scores less.
        let (trial, joint, lossy) = ([0.0036, 0.0069], [0.0040, 0.0067], [0.0030, 0.0046]);
        assert_eq!(
            first(
                (0.81, temperature(true, trial, Some(joint))),
                (0.43, loss(lossy))
            ),
            l_first
        );
        // A temperature from its trial alone, which yields to a loss fitted
        // on the tests together at any margin, leaves less (0.28 % against 0.35 %) and goes
        // first again: the lesser of its trial's and its fit on all the tests counts.
        let (trial, joint, lossy) = ([0.0015, 0.0036], [0.0030, 0.0042], [0.0029, 0.0040]);
        assert_eq!(
            first(
                (0.82, temperature(false, trial, Some(joint))),
                (0.28, loss(lossy))
            ),
            t_first
        );
        assert_eq!(
            first((0.82, temperature(false, trial, None)), (0.28, loss(lossy))),
            l_first
        );
        // On that footing the margin is the log of the ratio of what each leaves over the
        // tests (0.35 % against 0.28 %), not the scores' difference (0.54).
        let t = candidate(
            EffectKind::TemperatureViscous,
            0.82,
            temperature(false, trial, Some(joint)),
        );
        let l = candidate(EffectKind::NonlinearDamping, 0.28, loss(lossy));
        let ratio = crate::effects::rms(&lossy) / crate::effects::rms(&trial);
        assert!((margin(&t, Some(&l)) - ratio.ln()).abs() < 1e-12);
        assert!((margin(&l, Some(&t)) + ratio.ln()).abs() < 1e-12);
        // Until both are fitted so, and for any other pair, the scores' difference; the last
        // candidate's margin is its score.
        let alone = candidate(
            EffectKind::TemperatureViscous,
            0.82,
            temperature(false, trial, None),
        );
        assert!((margin(&alone, Some(&l)) - 0.54).abs() < 1e-12);
        let mode = candidate(EffectKind::Mode, 0.5, peak(10.0));
        assert!((margin(&l, Some(&mode)) + 0.22).abs() < 1e-12);
        assert!((margin(&l, None) - 0.28).abs() < 1e-12);
    }

    #[test]
    fn a_drift_keeps_its_place_where_the_slope_before_the_step_contradicts_it() {
        // A ramp the dynamics leave: -31 +/- 22 per second before the step, the rate +103.
        assert!(drift_contradicted(-31.0, 22.0, 103.0));
        // A real drift: the slope before the step is its rate, within the noise, or of its
        // sign (101 +/- 13 against 125).
        assert!(!drift_contradicted(101.0, 13.0, 125.0));
        assert!(!drift_contradicted(20.0, 1.0, 125.0));
        // No segment before the step: nothing to contradict.
        assert!(!drift_contradicted(0.0, f64::INFINITY, 125.0));
        // The slope before the step is said, not ranked on: ranked on, it put hidden drifts
        // that scored best behind a mode and an offset, and moved no other first name.
        let drift = |pre: f64| Evidence::Drift {
            pre_step_slope_per_s: pre,
            pre_step_slope_se_per_s: 22.0,
            ramp_in_standard_errors: 190.0,
            rate_per_s: 103.0,
            ramp_kept_at_end: Some(0.9),
        };
        for pre in [-31.0, 95.0] {
            let mut out = vec![
                candidate(EffectKind::Drift, 0.9, drift(pre)),
                candidate(EffectKind::Mode, 0.3, peak(10.0)),
            ];
            order(&mut out);
            assert_eq!(out[0].kind, Finding::Missing(EffectKind::Drift), "{pre}");
            assert_eq!(out[0].ordered_by, None, "{pre}");
        }
    }

    /// A capillary's probe after a step at sample 1000 of 8000, `extra` added to its output.
    fn residual_evidence(extra: impl Fn(f64) -> f64) -> crate::evidence::TestEvidence {
        crate::testing::capillary_evidence(8000, 1000, extra)
    }

    #[test]
    fn a_drift_keeps_its_ramp_to_the_end_and_a_hump_after_the_step_does_not() {
        let kept = |e: &crate::evidence::TestEvidence| {
            ramp_kept(&e.trend, e.samples, e.step_onset, 8000.0)
        };
        // A sensor drifting at 20 units per second, from the record's start.
        let drift = residual_evidence(|t| 20.0 * t);
        let (k, z) = kept(&drift).expect("a line and a segment before the step");
        assert!((k - 1.0).abs() < 0.05 && z.abs() < 4.0, "{k} {z}");
        assert!(!ramp_returns(Some((k, z))));
        // A tail the model misses: 30 units low just after the step, gone by the end. The line
        // through it climbs, but the level at the end is the level before the step.
        let hump = residual_evidence(|t| {
            if t < 0.125 {
                0.0
            } else {
                -30.0 * (-(t - 0.125) / 0.1).exp()
            }
        });
        assert!(hump.trend.slope_per_s > 5.0, "{:?}", hump.trend);
        let (k, z) = kept(&hump).expect("a line and a segment before the step");
        assert!(k.abs() < 0.1 && z.abs() > 10.0, "{k} {z}");
        assert!(ramp_returns(Some((k, z))));
        // Without a segment before the step there is nothing to compare.
        assert_eq!(ramp_kept(&hump.trend, hump.samples, 0, 8000.0), None);
    }
}
