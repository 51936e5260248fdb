//! The evidence across tests: each test fitted alone ([`PerTest`]), and what those fits show
//! together, a damping that rises with the step's amplitude ([`AmplitudeSignature`]) or
//! natural frequencies that all move by one factor ([`TemperatureEvidence`]).

use serde::Serialize;

use super::Current;
use crate::effects::{Effect, FitChanges, TemperatureDamping};
use crate::evidence::TestEvidence;
use crate::fit::{Options, Order, Test};

use super::JointLoss;

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
    /// The time scales of the test's own fit that move with the temperature of an overdamped
    /// probe (a capillary) that has no resonance, as frequencies in Hz: its dominant corner and
    /// the corner of its whole lag at DC (`time_scales`).
    pub time_scales: Vec<f64>,
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

impl AmplitudeSignature {
    /// What it says, with the loss a trial fitted (`gain`, s^2 per probe unit), for a
    /// candidate's reading.
    #[must_use]
    pub fn reading(&self, gain: f64) -> String {
        let ends = |v: &[f64]| {
            (
                v.first().copied().unwrap_or(0.0),
                v.last().copied().unwrap_or(0.0),
            )
        };
        let ((a0, a1), (z0, z1)) = (ends(&self.amplitudes), ends(&self.damping));
        format!(
            "the damping fitted to each test alone rises from {z0:.3} at a step of {a0:.3} to \
             {z1:.3} at {a1:.3} ({:+.3} per unit step), and what a linear fit leaves grows as \
             |step|^{:.2} (a linear probe: 1): amplitude-dependent losses, orifice or turbulent \
             flow at large steps (quadratic loss {gain:.3e} s^2 per unit)",
            self.damping_slope, self.residual_exponent
        )
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

/// A test's natural frequencies must move by at least this factor (3 %) together to point at
/// a temperature.
pub const MIN_FREQUENCY_SHIFT: f64 = 1.03;

/// Largest common factor of the frequencies a temperature can explain: the speed of sound goes
/// as the root of the gas temperature, so 2 is a gas four times hotter (or colder) than the
/// model's. A larger shift is another probe or another structure, and a temperature trial
/// would only lend its free time scale to it (a leak's slow corner, 0.14 times the model's on
/// a drawn case, read as T/T_ref = 0.02).
pub const MAX_FREQUENCY_SHIFT: f64 = 2.0;

/// Whether a common frequency factor is one a temperature can explain: at least
/// [`MIN_FREQUENCY_SHIFT`] away from 1 and at most [`MAX_FREQUENCY_SHIFT`].
#[must_use]
pub fn temperature_shift(ratio: f64) -> bool {
    let shift = ratio.ln().abs();
    shift >= MIN_FREQUENCY_SHIFT.ln() && shift <= MAX_FREQUENCY_SHIFT.ln()
}

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
    /// The probe has no resonance: the rows compare its time scales (dominant corner and whole lag, `time_scales`).
    pub overdamped: bool,
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
    let mut model_modes = crate::fit::analysis::Analysis::new(current.model)
        .ok()?
        .resonance_pairs();
    // An overdamped probe has no resonance: its time scales move with the temperature
    // instead, each as a mode of damping 1 ([`time_scales`]).
    let overdamped = model_modes.is_empty();
    if overdamped {
        model_modes = time_scales(current.model)
            .into_iter()
            .map(|f| (f, 1.0))
            .collect();
    }
    if model_modes.is_empty() {
        return None;
    }
    let rows: Vec<TemperatureRow> = per_test(current, tests, evidence)
        .into_iter()
        .map(|p| {
            let modes: Vec<(f64, f64)> = if overdamped {
                p.time_scales.iter().map(|f| (*f, 1.0)).collect()
            } else {
                p.resonances.clone()
            };
            (p.file, modes)
        })
        .filter(|(_, modes)| !modes.is_empty())
        .map(|(file, modes)| {
            // An overdamped probe's time scales pair in order; a resonance with the model's
            // nearest.
            let pairs: Vec<((f64, f64), (f64, f64))> = if overdamped {
                modes
                    .iter()
                    .copied()
                    .zip(model_modes.iter().copied())
                    .collect()
            } else {
                modes
                    .iter()
                    .filter_map(|&(f, z)| {
                        model_modes
                            .iter()
                            .min_by(|a, b| (a.0 / f).ln().abs().total_cmp(&(b.0 / f).ln().abs()))
                            .map(|&m| ((f, z), m))
                    })
                    .collect()
            };
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
                file,
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
    let ok = temperature_shift(strongest.ratio)
        && strongest.spread <= shift / 3.0 + 0.005
        && strongest.damping_ratio.ln().abs() <= 2.0 * shift + 0.1;
    ok.then(|| TemperatureEvidence {
        spread: strongest.spread,
        damping_ratio: strongest.damping_ratio,
        rows: rows.clone(),
        overdamped,
    })
}

/// The time scales of an overdamped `model` that a gas temperature moves by one factor, as
/// frequencies in Hz: its dominant corner ([`dominant_corner`]) and the corner of its whole
/// lag at DC, `fs / (2 pi tau)` with `tau` the group delay at zero frequency (delay, every
/// pole and zero). A capillary's fast corner is not among them: it trades with the delay
/// within the noise (a held-out test in a colder gas read 0.49 times the model's fast corner
/// and 0.86 times its slow one, the delay taking the rest), while the whole lag, the area
/// between the reference's step and the probe's, is what a step determines best. Empty
/// without a corner or a positive lag.
fn time_scales(model: &crate::fit::Model) -> Vec<f64> {
    let lag = model.dc_group_delay().map(|d| d / model.fs);
    match (dominant_corner(model), lag) {
        (Some(f), Some(t)) if t > 0.0 => vec![f, 1.0 / (2.0 * std::f64::consts::PI * t)],
        _ => Vec::new(),
    }
}

/// The corner frequency in Hz of the real pole in `(0, 1)` that carries the largest share of
/// `model`'s step response (the coefficient `C_i` of `p_i^n` in it): a capillary's slow
/// corner, not a leak's slower one, which carries only the few per cent the leak takes from
/// the DC gain, nor a fast corner next to the delay. `None` without such a pole (or with a
/// repeated one).
fn dominant_corner(model: &crate::fit::Model) -> Option<f64> {
    let poles = model.poles().ok()?;
    let coefficients = crate::fit::continuous::step_coefficients(&model.b, &poles);
    poles
        .iter()
        .zip(coefficients)
        .filter(|(p, _)| p.im.abs() < 1e-9 && p.re > 0.0 && p.re < 1.0)
        .map(|(p, c)| (c.norm(), p.re))
        .filter(|(c, _)| c.is_finite())
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p)| -p.ln() * model.fs / (2.0 * std::f64::consts::PI))
}

/// The residual's slope before the step (units per second), the tests' weighted by their
/// standard errors, and its standard error: a sensor drifts in time, before the step too, so
/// this is a drift's rate measured apart from the dynamics. `(0, infinity)` when no test has a
/// segment before its step.
#[must_use]
pub fn pre_step_slope(evidence: &[TestEvidence]) -> (f64, f64) {
    let (sw, swx) = evidence
        .iter()
        .map(|e| (e.trend.pre_slope_per_s, e.trend.pre_slope_se_per_s))
        .filter(|(x, se)| x.is_finite() && se.is_finite() && *se > 0.0)
        .fold((0.0, 0.0), |(sw, swx), (x, se)| {
            (sw + 1.0 / (se * se), swx + x / (se * se))
        });
    if sw > 0.0 {
        (swx / sw, 1.0 / sw.sqrt())
    } else {
        (0.0, f64::INFINITY)
    }
}

/// What a drift's reading says of the slope before the step (`pre +/- pre_se` per second)
/// against its fitted `rate`.
#[must_use]
pub fn drift_before_step(pre: f64, pre_se: f64, rate: f64) -> String {
    if super::drift_contradicted(pre, pre_se, rate) {
        format!(
            "but not before the step, where a sensor's drift runs too and the residual moves \
             at {pre:.3e} +/- {pre_se:.1e} per second: the ramp may be one the dynamics leave \
             (a longer quiet record before the step would tell)"
        )
    } else {
        "already before the step: the sensor drifts in time (thermal drift)".to_string()
    }
}

/// The residual's level at the end of the record less its level before the step, in standard
/// errors of the two means under the noise both channels leave: the largest in size over the
/// tests (0 without a finite one).
#[must_use]
pub fn creep_in_standard_errors(evidence: &[TestEvidence]) -> f64 {
    evidence
        .iter()
        .map(|e| {
            let t = &e.trend;
            (t.late_mean - t.pre_mean) / t.late_mean_se.hypot(t.pre_mean_se).max(1e-300)
        })
        .filter(|z| z.is_finite())
        .fold(0.0f64, |m, v| if v.abs() > m.abs() { v } else { m })
}

/// The reading of a temperature found in `t` and offered with `damping`, for the test `file`
/// of its strongest shift, and the `T / T_ref` it implies under that law (the speed of sound
/// goes as the root of temperature; the viscosity rises with it).
#[must_use]
pub fn temperature_reading(
    t: &TemperatureEvidence,
    damping: TemperatureDamping,
    file: &str,
    reference_k: f64,
) -> (String, f64) {
    let ratio = t.strongest().1;
    let temperature_ratio = damping.temperature(ratio, reference_k) / reference_k;
    let (law, why) = match damping {
        TemperatureDamping::Constant => (
            "damping kept".to_string(),
            "speed of sound goes as the root of temperature",
        ),
        TemperatureDamping::Viscous => (
            format!(
                "damping x{:.2} by the viscous law nu(T)/nu(T_ref)/k of a tube-volume system",
                TemperatureDamping::Viscous.factor(ratio, reference_k)
            ),
            "speed of sound goes as the root of temperature",
        ),
        TemperatureDamping::Diffusive => (
            "every time scale by the viscosity, mu(T_ref)/mu(T), of a line where the pressure \
             diffuses"
                .to_string(),
            "an overdamped line's time scales go as the gas viscosity",
        ),
    };
    let (what, verb, across) = if t.overdamped {
        (
            "the dominant corner and the whole lag's frequency",
            "are",
            "the two",
        )
    } else {
        ("every natural frequency", "is", "modes")
    };
    let reading = format!(
        "{what} of {file} fitted alone {verb} {ratio:.3} times the model's (spread across \
         {across} {:.1} %, damping x{:.2}): the same probe at another gas temperature, T/T_ref = \
         {temperature_ratio:.3} ({why}); {law}",
        100.0 * t.spread,
        t.damping_ratio,
    );
    (reading, temperature_ratio)
}

/// One model fitted to all `tests` at once, with a quadratic loss and without, from the
/// current model ([`crate::effects::joint_loss`]); `None` with one test, or a model
/// that has a quadratic loss already or effects that change each test differently (a sensor
/// resonance's prefilter, a temperature's scale). An offset or a drift in the model is left in
/// both fits' errors alike.
#[must_use]
pub fn joint_loss_evidence(current: &Current<'_>, tests: &[Test<'_>]) -> Option<JointLoss> {
    let changed = current.effects.iter().any(|e| {
        matches!(
            e,
            Effect::NonlinearDamping { .. }
                | Effect::SensorResonance { .. }
                | Effect::Temperature { .. }
        )
    });
    if tests.len() < 2 || changed {
        return None;
    }
    let (linear, joint) = crate::effects::joint_loss(current.model, tests)?;
    Some(JointLoss {
        tests: tests.iter().map(|t| t.name.to_string()).collect(),
        fall: linear.rms() / joint.rms(),
        linear_nrmse: linear.nrmse,
        nrmse: joint.nrmse,
        gain_s2_per_unit: joint.gain,
    })
}

impl JointLoss {
    /// What it says, for a candidate's reading.
    #[must_use]
    pub fn reading(&self) -> String {
        let pct = |v: &[f64]| {
            v.iter()
                .map(|e| format!("{:.3} %", 100.0 * e))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "one model fitted to {} together leaves {} with a quadratic loss of {:.3e} s^2 per \
             unit, where the best single linear model leaves {} ({:.2}x in all): \
             amplitude-dependent losses, orifice or turbulent flow at large rates, which one \
             step cannot tell from a linear damping. The remedy fits the loss on these tests \
             together; hold out a further test to judge it{}",
            self.tests.join(" and "),
            pct(&self.nrmse),
            self.gain_s2_per_unit,
            pct(&self.linear_nrmse),
            self.fall,
            crate::effects::rises_with_loss(
                &self.tests.iter().map(String::as_str).collect::<Vec<_>>(),
                &self.linear_nrmse,
                &self.nrmse
            )
            .map_or_else(String::new, |r| format!(" ({r})"))
        )
    }
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
                let ym = f.model.simulate_matched(t.u, t.y);
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
            let time_scales = own
                .as_ref()
                .map(|f| time_scales(&f.model))
                .unwrap_or_default();
            PerTest {
                file: e.file.clone(),
                step_size: e.step_size,
                residual_per_step: e.residual_rms / e.step_size.abs().max(1e-300),
                resonances,
                time_scales,
                own_residual_per_step: excess / e.step_size.abs().max(1e-300),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Model;

    #[test]
    fn a_temperature_moves_frequencies_by_a_plausible_factor() {
        assert!(!temperature_shift(1.01));
        assert!(temperature_shift(1.05) && temperature_shift(1.0 / 1.05));
        assert!(temperature_shift(1.9) && temperature_shift(0.55));
        // A leak's corner at 0.14 times the model's: T/T_ref = 0.02 is no gas temperature.
        assert!(!temperature_shift(0.14) && !temperature_shift(2.5));
        assert!(!temperature_shift(f64::NAN));
    }

    /// An overdamped probe ([`crate::testing::overdamped`]) with a leak's pole-zero pair at
    /// `leak_hz` taking `leak_share` of the DC gain.
    fn leaking(fs: f64, f1: f64, f2: f64, delay: usize, (leak_hz, share): (f64, f64)) -> Model {
        let a = crate::testing::overdamped(f1, f2, fs, delay).a;
        // (1 - z0 z^-1) / (1 - q z^-1), DC gain (1 - z0) / (1 - q) = 1 - share.
        let q = (-2.0 * std::f64::consts::PI * leak_hz / fs).exp();
        let z0 = 1.0 - (1.0 - share) * (1.0 - q);
        let a = vec![a[0] - q, a[1] - q * a[0], -q * a[1]];
        let b = [0.0, 0.6, 0.4 - 0.6 * z0, -0.4 * z0];
        let g = (1.0 + a.iter().sum::<f64>()) / b.iter().sum::<f64>();
        Model {
            fs,
            delay,
            a,
            b: b.iter().map(|v| v * g).collect(),
        }
    }

    #[test]
    fn the_dominant_corner_is_the_capillarys_slow_one_not_a_leaks() {
        let plain = crate::testing::overdamped(4.0, 100.0, 3000.0, 20);
        let f = dominant_corner(&plain).unwrap();
        assert!((f / 4.0 - 1.0).abs() < 1e-9, "{f}");
        // A leak at 0.3 Hz taking 5 % of the gain: slower, but a small share of the step.
        let leaky = leaking(3000.0, 4.0, 100.0, 20, (0.3, 0.05));
        let f = dominant_corner(&leaky).unwrap();
        assert!((f / 4.0 - 1.0).abs() < 1e-9, "{f}");
        // The whole lag: the delay and both time constants (no zero away from the origin).
        let [_, lag] = time_scales(&plain)[..] else {
            panic!("two time scales")
        };
        let tau = 20.0 / 3000.0 + (1.0 / 4.0 + 1.0 / 100.0) / (2.0 * std::f64::consts::PI);
        assert!(
            (lag * 2.0 * std::f64::consts::PI * tau - 1.0).abs() < 0.01,
            "{lag}"
        );
    }

    #[test]
    fn both_time_scales_move_by_the_factor_that_scales_time() {
        let model = crate::testing::overdamped(4.0, 100.0, 3000.0, 20);
        for k in [0.8, 1.15] {
            let scaled = crate::effects::scaled(&model, k).unwrap();
            let (a, b) = (time_scales(&model), time_scales(&scaled));
            assert_eq!((a.len(), b.len()), (2, 2));
            for (x, y) in a.iter().zip(&b) {
                assert!((y / x / k - 1.0).abs() < 0.02, "k {k}: {x} -> {y}");
            }
        }
    }
}
