//! From a designed compensator (f64 second-order sections) to the board's fixed-point one:
//! realisation, scaling and quantisation, chosen once on the host.
//!
//! This module owns [`FixedPlan`]: the integer coefficients of [`crate::board::fixed::FixedCascade`],
//! the scaling that keeps every state and output inside `i32` for inputs within the ADC's full
//! scale, the headroom that leaves, and the conversion between physical units and the board's
//! integers. `unlag invert` stores the plan in the model file; `unlag compensate --arithmetic
//! fixed` runs it with the board's code.
//!
//! # Scaling
//!
//! Inputs are Q1.31 codes of the full scale `F` (`y = F` is `2^31`). For each section, in
//! order, the impulse responses from the cascade's input to the section's two states and to its
//! output are computed in f64; their L1 norms bound the largest value each can take for any
//! input with `|y| <= F` (a bound that is reached by the worst-case input, so it is safe, not
//! statistical). The input vector `b` (and, for two real poles, the coupling `g`) scales each
//! state to at most [`TARGET`] of the `i32` range, and the output coefficients scale the
//! section's output to the same, which is then the next section's input. The last section's
//! output scale is a power of two, so the board's output is the reconstructed pressure in
//! Q1.31 of `F 2^e`. Where a coefficient cannot be represented, the plan is refused.

use serde::{Deserialize, Serialize};

use crate::board::fixed::{FixedCascade, FixedSection, FixedState, MAX_COEFFICIENT, STATE_BITS};
use crate::design::DesignError;
use crate::error::{Error, Result};

mod direct;
pub use direct::{DirectPlan, DirectPlanSection};

/// What a fixed-point plan quantises: a cascade's input gain and its second-order sections
/// `[b0, b1, b2, a1, a2]`, as a compensator design holds them (`&Design` converts into it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cascade<'a> {
    /// The gain in front of the first section.
    pub gain: f64,
    /// The sections, in the order the signal passes them.
    pub sections: &'a [[f64; 5]],
}

/// Which fixed-point form the board runs: the choice between the guarantees of the normal
/// form and the instruction budget of the direct form (the trade table is in BENCHMARKS.md,
/// "Fixed point: the two forms").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FixedForm {
    /// Normal (coupled) state-space sections, [`FixedPlan`] and [`crate::board::fixed::FixedCascade`]:
    /// no limit cycles, every state saturates with the flag, 100 dB at fs/fn = 1000; about
    /// 115 instructions a sample for m = 4 on a Cortex-M4. The default.
    #[default]
    Normal,
    /// Direct-form-I sections with first-order error feedback, [`DirectPlan`] and
    /// [`crate::board::fixed::direct::DirectCascade`]: about 33 instructions a sample for m = 4;
    /// limit cycles of a few codes not excluded, about 90 dB at fs/fn = 1000.
    Direct,
}

/// Largest value, as a fraction of the `i32` range, any state or output may reach by the L1
/// bound: one bit of headroom.
pub const TARGET: f64 = 0.5;

/// Largest number of samples of an impulse response summed for an L1 norm.
pub const MAX_IMPULSE: usize = 20_000_000;

/// One section of a plan: the board's integers and the bounds behind them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanSection {
    /// `[a11, a12, a21, a22]`, Q2.30.
    pub a: [i32; 4],
    /// `[b1, b2]`, Q2.30.
    pub b: [i32; 2],
    /// `[c1, c2]`, `shift` fractional bits.
    pub c: [i32; 2],
    /// Direct term, `shift` fractional bits.
    pub d: i32,
    /// Fractional bits of `c` and `d`.
    pub shift: u8,
    /// `"rotation"` (complex pole pair) or `"real"` (two real poles, cascaded).
    pub form: String,
    /// Largest possible `|state|` as a fraction of the `i32` range (L1 bound).
    pub state_bound: f64,
    /// Largest possible `|output|` as a fraction of the `i32` range (L1 bound).
    pub output_bound: f64,
}

impl PlanSection {
    /// The board's section.
    #[must_use]
    pub fn section(&self) -> FixedSection {
        FixedSection {
            a: self.a,
            b: self.b,
            c: self.c,
            d: self.d,
            shift: self.shift,
        }
    }
}

/// The fixed-point compensator for one design and one ADC full scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixedPlan {
    /// The ADC's full scale in the probe's units: `y = full_scale` is the code `2^31`.
    pub full_scale: f64,
    /// The output is the reconstructed pressure in Q1.31 of `full_scale * 2^output_exponent`.
    pub output_exponent: i32,
    /// L1 norm of the whole compensator's impulse response: the largest output for a
    /// full-scale input, in units of the full scale.
    pub l1_gain: f64,
    /// Smallest headroom over all states and outputs, in bits, by the L1 bound.
    pub headroom_bits: f64,
    /// The sections.
    pub sections: Vec<PlanSection>,
}

/// The output of a fixed-point run, in the probe's units, and whether anything saturated.
#[derive(Debug, Clone, PartialEq)]
pub struct FixedRun {
    /// Reconstructed pressure.
    pub u_hat: Vec<f64>,
    /// Samples whose input was outside the full scale (clamped before the compensator).
    pub clipped_inputs: usize,
    /// `true` when a state or output saturated inside the compensator.
    pub overflowed: bool,
}

/// The Q1.31 code of `y` for the full scale `full_scale`, clamped; `true` when clamped.
fn code_of(y: f64, full_scale: f64) -> (i32, bool) {
    let v = (y / full_scale * 2f64.powi(31)).round();
    if v >= f64::from(i32::MAX) {
        (i32::MAX, true)
    } else if v < f64::from(i32::MIN) {
        (i32::MIN, true)
    } else {
        // In range.
        #[allow(clippy::cast_possible_truncation)]
        (v as i32, false)
    }
}

/// Checks what both fixed-point plans need (a positive, finite full scale; a design with
/// sections, every pole inside the unit circle) and returns the length of impulse response
/// the plan traces: long enough for the slowest pole to decay by e^-40, the tail then
/// negligible.
pub(super) fn impulse_len(design: &Cascade<'_>, full_scale: f64) -> Result<usize> {
    if !(full_scale.is_finite() && full_scale > 0.0) {
        return Err(Error::InvalidParameter {
            parameter: crate::error::Parameter::FullScale,
            message: format!("must be a positive number, not {full_scale}"),
        });
    }
    if design.sections.is_empty() {
        return Err(DesignError::NoSections.into());
    }
    let radius = design
        .sections
        .iter()
        .fold(0.0f64, |r, &[_, _, _, a1, a2]| {
            r.max(crate::board::compensator::section_pole_radius(a1, a2))
        });
    if radius.is_nan() || radius >= 1.0 {
        return Err(DesignError::SectionPoleRadius { radius }.into());
    }
    Ok(((40.0 / (1.0 - radius)).ceil() as usize).clamp(2_000, MAX_IMPULSE))
}

/// Rounds `v * 2^bits` to an integer coefficient, refusing what does not fit.
fn quantise(v: f64, bits: u32, what: &'static str) -> Result<i32> {
    let q = (v * f64::from(bits).exp2()).round();
    if !q.is_finite() || q.abs() > f64::from(MAX_COEFFICIENT) {
        return Err(DesignError::CoefficientRange {
            what,
            value: v,
            bits,
        }
        .into());
    }
    // In range, checked above.
    #[allow(clippy::cast_possible_truncation)]
    Ok(q as i32)
}

/// Fractional bits for coefficients of largest magnitude `max`: as many as fit under 2^30.
fn shift_for(max: f64) -> Result<u8> {
    if !(max.is_finite()) {
        return Err(DesignError::OutputCoefficientNotFinite.into());
    }
    if max == 0.0 {
        return Ok(30);
    }
    // max * 2^shift <= 2^30 (minus rounding room).
    let bits = (30.0 - (max * (1.0 + 1e-9)).log2()).floor();
    if bits < 1.0 {
        return Err(DesignError::OutputCoefficientRange { max }.into());
    }
    // bits >= 1 here; at most 62.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    Ok(bits.min(62.0) as u8)
}

/// One section of the plan, realised as `r`: its state scales `(beta, g)` and output
/// coefficients `[c1, c2, d]` quantised at the shift their largest needs, with its state and
/// output bounds.
fn plan_section(
    r: &Realisation,
    (beta, g): (f64, f64),
    [c1, c2, d]: [f64; 3],
    (state_bound, output_bound): (f64, f64),
) -> Result<PlanSection> {
    let shift = shift_for(c1.abs().max(c2.abs()).max(d.abs()))?;
    let bits = u32::from(shift);
    let a = if r.rotation {
        let s = quantise(r.s, STATE_BITS, "sigma")?;
        let w = quantise(r.w, STATE_BITS, "omega")?;
        [s, w.wrapping_neg(), w, s]
    } else {
        [
            quantise(r.a[0], STATE_BITS, "p1")?,
            0,
            quantise(g, STATE_BITS, "g")?,
            quantise(r.a[3], STATE_BITS, "p2")?,
        ]
    };
    Ok(PlanSection {
        a,
        b: [quantise(beta, STATE_BITS, "beta")?, 0],
        c: [quantise(c1, bits, "c1")?, quantise(c2, bits, "c2")?],
        d: quantise(d, bits, "d")?,
        shift,
        form: if r.rotation { "rotation" } else { "real" }.into(),
        state_bound,
        output_bound,
    })
}

/// A section's realisation in f64 before scaling: state matrix, and how to get `c` from the
/// input scale `beta` (and coupling `g`).
struct Realisation {
    a: [f64; 4],
    rotation: bool,
    d: f64,
    n1: f64,
    n2: f64,
    /// `sigma` (rotation) or `p2` (real).
    s: f64,
    /// `omega` (rotation), unused for real.
    w: f64,
}

fn realise(section: [f64; 5]) -> Realisation {
    let [b0, b1, b2, a1, a2] = section;
    let (d, n1, n2) = (b0, b1 - b0 * a1, b2 - b0 * a2);
    let disc = a1 * a1 - 4.0 * a2;
    if disc < 0.0 {
        let (s, w) = (-a1 / 2.0, (-disc).sqrt() / 2.0);
        Realisation {
            a: [s, -w, w, s],
            rotation: true,
            d,
            n1,
            n2,
            s,
            w,
        }
    } else {
        let r = disc.sqrt();
        // The larger pole first: it is the slow one, excited first.
        let (p1, p2) = if a1 <= 0.0 {
            ((-a1 + r) / 2.0, (-a1 - r) / 2.0)
        } else {
            ((-a1 - r) / 2.0, (-a1 + r) / 2.0)
        };
        Realisation {
            a: [p1, 0.0, 1.0, p2],
            rotation: false,
            d,
            n1,
            n2,
            s: p2,
            w: 0.0,
        }
    }
}

/// Impulse responses of a section's two states (with `b = [1, 0]` and coupling 1) driven by
/// `input`.
fn state_responses(a: [f64; 4], input: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let [a11, a12, a21, a22] = a;
    let (mut x1, mut x2) = (0.0, 0.0);
    let mut h1 = Vec::with_capacity(input.len());
    let mut h2 = Vec::with_capacity(input.len());
    for &u in input {
        h1.push(x1);
        h2.push(x2);
        (x1, x2) = (a11 * x1 + a12 * x2 + u, a21 * x1 + a22 * x2);
    }
    (h1, h2)
}

fn l1(h: &[f64]) -> f64 {
    h.iter().map(|v| v.abs()).sum()
}

impl FixedPlan {
    /// Plans the fixed-point compensator for `design` and inputs within `+-full_scale`.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a full scale that is not positive and finite;
    /// [`DesignError`] when the design has no sections or a pole on or outside the unit circle,
    /// a coefficient cannot be represented, a bound is not finite, or the quantised cascade is
    /// refused by the board's validation.
    pub fn new<'a>(design: impl Into<Cascade<'a>>, full_scale: f64) -> Result<Self> {
        let design = design.into();
        let len = impulse_len(&design, full_scale)?;
        // The input to the current section in the fixed-point domain: the impulse response
        // from the cascade input (a full-scale unit) to it, times its scale.
        let mut input = vec![0.0; len];
        if let Some(first) = input.first_mut() {
            *first = 1.0;
        }
        // Scale of the current section's input relative to the true signal.
        let mut scale_in = 1.0;
        let mut sections = Vec::with_capacity(design.sections.len());
        let mut headroom = f64::INFINITY;
        let last = design.sections.len() - 1;
        let mut l1_gain = f64::NAN;
        let mut output_exponent = 0;
        for (k, &sec) in design.sections.iter().enumerate() {
            // The cascade's gain goes into the first section's numerator.
            let sec = if k == 0 {
                let [b0, b1, b2, a1, a2] = sec;
                [b0 * design.gain, b1 * design.gain, b2 * design.gain, a1, a2]
            } else {
                sec
            };
            let r = realise(sec);
            let (h1, h2) = state_responses(r.a, &input);
            let (l1_x1, l1_x2_unit) = (l1(&h1), l1(&h2));
            // States: x1 = beta h1, x2 = beta g h2 (real) or beta h2 (rotation).
            let beta = if l1_x1 > 0.0 {
                (TARGET / l1_x1).min(1.0)
            } else {
                1.0
            };
            let (g, coupling_scale) = if r.rotation {
                (0.0, beta)
            } else {
                let g = if l1_x2_unit > 0.0 {
                    (TARGET / (beta * l1_x2_unit)).min(1.0)
                } else {
                    1.0
                };
                (g, beta * g)
            };
            let state_bound = (beta * l1_x1).max(coupling_scale * l1_x2_unit);
            // The section's true output (in the fixed-point input domain) = d u + (H - d) u.
            let c1_true = r.n1 / beta;
            let c2_true = if r.rotation {
                (r.n2 + r.s * r.n1) / (r.w * beta)
            } else {
                (r.n2 + r.s * r.n1) / (g * beta)
            };
            let out: Vec<f64> = input
                .iter()
                .zip(h1.iter().zip(&h2))
                .map(|(&u, (&x1, &x2))| {
                    r.d * u + c1_true * beta * x1 + c2_true * coupling_scale * x2
                })
                .collect();
            let out_l1 = l1(&out);
            if !(out_l1.is_finite() && state_bound.is_finite()) {
                return Err(DesignError::L1Bound { section: k }.into());
            }
            // Output scale: TARGET / bound, a power of two for the last section.
            let lambda = if out_l1 > 0.0 { TARGET / out_l1 } else { 1.0 };
            let lambda = if k == last {
                // The whole cascade's scale, input to output, is a power of two 2^-e.
                l1_gain = out_l1 / scale_in;
                let e = -(TARGET / l1_gain).log2().floor();
                if !e.is_finite() || e.abs() > 60.0 {
                    return Err(DesignError::L1Gain { gain: l1_gain }.into());
                }
                // |e| <= 60, checked above.
                #[allow(clippy::cast_possible_truncation)]
                {
                    output_exponent = e as i32;
                }
                (-e).exp2() / scale_in
            } else {
                lambda
            };
            let plan = plan_section(
                &r,
                (beta, g),
                [c1_true * lambda, c2_true * lambda, r.d * lambda],
                (state_bound, out_l1 * lambda),
            )?;
            headroom = headroom
                .min(-plan.state_bound.log2())
                .min(-plan.output_bound.log2());
            sections.push(plan);
            input = out.iter().map(|v| v * lambda).collect();
            scale_in *= lambda;
        }
        let plan = Self {
            full_scale,
            output_exponent,
            l1_gain,
            headroom_bits: headroom,
            sections,
        };
        plan.check()?;
        Ok(plan)
    }

    /// The board's sections.
    #[must_use]
    pub fn board_sections(&self) -> Vec<FixedSection> {
        self.sections.iter().map(PlanSection::section).collect()
    }

    /// Validates the integers as the board does.
    ///
    /// # Errors
    /// [`DesignError::FixedBoard`] with the board's reason.
    pub fn check(&self) -> Result<()> {
        FixedCascade::<16>::new(&self.board_sections())
            .map(|_| ())
            .map_err(|error| DesignError::FixedBoard { error }.into())
    }

    /// The Q1.31 code of a probe value, clamped to the full scale; `true` when clamped.
    #[must_use]
    pub fn to_code(&self, y: f64) -> (i32, bool) {
        code_of(y, self.full_scale)
    }

    /// The probe's units of an output code.
    #[must_use]
    pub fn from_code(&self, code: i32) -> f64 {
        f64::from(code) * 2f64.powi(self.output_exponent - 31) * self.full_scale
    }

    /// Runs the board's fixed-point code on `y`, starting in equilibrium with `y[0]`.
    ///
    /// # Errors
    /// [`DesignError::FixedBoard`] when the plan does not validate.
    pub fn run(&self, y: &[f64]) -> Result<FixedRun> {
        let mut runner = self.runner(y.first().copied().unwrap_or(0.0))?;
        let u_hat = y.iter().map(|&v| runner.step(v)).collect();
        Ok(runner.finish(u_hat))
    }

    /// [`FixedPlan::run`] one sample at a time, for a run streamed from its file: the board's
    /// code started in equilibrium with `first` (the run's first sample).
    ///
    /// # Errors
    /// As [`FixedPlan::run`].
    pub fn runner(&self, first: f64) -> Result<FixedRunner> {
        let sections = self.board_sections();
        let (first, _) = self.to_code(first);
        let cascade: Box<dyn FixedStep> = match sections.len() {
            0..=2 => Box::new(Fixed::<2>::new(&sections, first)?),
            3..=4 => Box::new(Fixed::<4>::new(&sections, first)?),
            5..=8 => Box::new(Fixed::<8>::new(&sections, first)?),
            _ => Box::new(Fixed::<16>::new(&sections, first)?),
        };
        Ok(FixedRunner::new(
            cascade,
            self.full_scale,
            self.output_exponent,
        ))
    }
}

/// A board's integer cascade with its state: one code in, one code out.
pub(crate) trait FixedStep {
    /// One input code through the cascade.
    fn step(&mut self, code: i32) -> i32;
    /// Whether a state or the output saturated.
    fn overflowed(&self) -> bool;
}

/// The normal form's cascade of `N` sections and its state.
struct Fixed<const N: usize> {
    cascade: FixedCascade<N>,
    state: FixedState<N>,
}

impl<const N: usize> Fixed<N> {
    fn new(sections: &[FixedSection], first: i32) -> Result<Self> {
        let cascade =
            FixedCascade::<N>::new(sections).map_err(|error| DesignError::FixedBoard { error })?;
        // Start in equilibrium with the first sample, as the f32 compensator does.
        let state = cascade.equilibrium(first);
        Ok(Self { cascade, state })
    }
}

impl<const N: usize> FixedStep for Fixed<N> {
    fn step(&mut self, code: i32) -> i32 {
        self.cascade.process(&mut self.state, code)
    }
    fn overflowed(&self) -> bool {
        self.state.overflowed()
    }
}

/// A fixed-point compensator run one sample at a time ([`FixedPlan::runner`]): probe values
/// clamped to the full scale and coded, the board's integers run, the output decoded; with the
/// count of clamped inputs.
pub struct FixedRunner {
    cascade: Box<dyn FixedStep>,
    full_scale: f64,
    output_exponent: i32,
    clipped_inputs: usize,
}

impl FixedRunner {
    pub(crate) fn new(cascade: Box<dyn FixedStep>, full_scale: f64, output_exponent: i32) -> Self {
        Self {
            cascade,
            full_scale,
            output_exponent,
            clipped_inputs: 0,
        }
    }

    /// One probe sample in, the reconstructed pressure out.
    pub fn step(&mut self, y: f64) -> f64 {
        let (code, clipped) = code_of(y, self.full_scale);
        self.clipped_inputs += usize::from(clipped);
        let out = self.cascade.step(code);
        f64::from(out) * 2f64.powi(self.output_exponent - 31) * self.full_scale
    }

    /// Samples clamped so far.
    #[must_use]
    pub fn clipped_inputs(&self) -> usize {
        self.clipped_inputs
    }

    /// Whether a state or the output saturated so far.
    #[must_use]
    pub fn overflowed(&self) -> bool {
        self.cascade.overflowed()
    }

    /// The run's summary with its output.
    #[must_use]
    pub fn finish(&self, u_hat: Vec<f64>) -> FixedRun {
        FixedRun {
            u_hat,
            clipped_inputs: self.clipped_inputs,
            overflowed: self.overflowed(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::inverse::{self, Options};
    use crate::fit::model::Model;

    fn line_design(fs: f64, fn_hz: f64, zeta: f64, bandwidth: f64) -> inverse::Design {
        let wn = 2.0 * std::f64::consts::PI * fn_hz / fs;
        let (re, im) = (-zeta * wn, wn * (1.0 - zeta * zeta).sqrt());
        let a = vec![-2.0 * re.exp() * im.cos(), (2.0 * re).exp()];
        let dc = 1.0 + a[0] + a[1];
        let model = Model {
            fs,
            delay: 2,
            a,
            b: vec![0.6 * dc, 0.4 * dc],
        };
        inverse::design(&model, bandwidth, &Options::default()).unwrap()
    }

    #[test]
    fn fixed_point_follows_the_f64_cascade() {
        for (fs, fn_hz, bw) in [(1e6, 80e3, 150e3), (1e4, 95.0, 300.0), (5e6, 5e3, 15e3)] {
            let design = line_design(fs, fn_hz, 0.2, bw);
            let plan = FixedPlan::new(&design, 2.0).unwrap();
            assert!(plan.headroom_bits >= 1.0 - 1e-9, "{plan:?}");
            let n = 20_000;
            let y: Vec<f64> = (0..n)
                .map(|k| {
                    let t = k as f64 / fs;
                    0.5 * (2.0 * std::f64::consts::PI * fn_hz * 0.3 * t).sin()
                        + if k > n / 3 { 0.4 } else { -0.2 }
                })
                .collect();
            let fixed = plan.run(&y).unwrap();
            assert!(!fixed.overflowed && fixed.clipped_inputs == 0);
            // The f64 reference from a zero state.
            let c = crate::board::compensator::CascadeCoefficients::<f64, 8>::new(
                design.gain,
                &design.sections,
            )
            .unwrap();
            let mut st = c.equilibrium(y[0]);
            let reference: Vec<f64> = y.iter().map(|&v| c.process(&mut st, v)).collect();
            let signal = reference.iter().map(|v| v * v).sum::<f64>();
            let noise = reference
                .iter()
                .zip(&fixed.u_hat)
                .map(|(r, f)| (r - f).powi(2))
                .sum::<f64>();
            let snr = 10.0 * (signal / noise).log10();
            assert!(snr > 90.0, "fs/fn {}: SNR {snr:.1} dB", fs / fn_hz);
        }
    }

    /// The typed sample path (`process_q`, `equilibrium_q`) computes the board's integers
    /// bit for bit on planned cascades of both forms, and its Q1.31 means what the plans say:
    /// the input a fraction of the full scale, the output of `full_scale * 2^output_exponent`.
    #[test]
    fn typed_samples_run_the_board_integers_bit_for_bit() {
        use crate::board::fixed::direct::{DirectCascade, DirectState};
        use crate::board::fixed::I1F31;

        let design = line_design(1e6, 80e3, 0.2, 150e3);
        let full_scale = 2.0;
        let y: Vec<f64> = (0..400)
            .map(|k| 0.9 * (0.05 * f64::from(k)).sin() + if k > 150 { 0.5 } else { -0.3 })
            .map(|v: f64| v.clamp(-full_scale, full_scale))
            .collect();
        let codes: Vec<i32> = y
            .iter()
            .map(|&v| I1F31::saturating_from_num(v / full_scale).to_bits())
            .collect();
        let start = I1F31::from_bits(codes[0]);

        let plan = FixedPlan::new(&design, full_scale).unwrap();
        let c = FixedCascade::<8>::new(&plan.board_sections()).unwrap();
        let (mut typed, mut plain): (FixedState<8>, _) =
            (c.equilibrium_q(start), c.equilibrium(codes[0]));
        assert_eq!(typed, plain);
        let mut moved = 0.0f64;
        for &u in &codes {
            let out = c.process_q(&mut typed, I1F31::from_bits(u));
            assert_eq!(out.to_bits(), c.process(&mut plain, u));
            assert_eq!(typed, plain);
            let meaning = out.to_num::<f64>() * full_scale * 2f64.powi(plan.output_exponent);
            assert_eq!(meaning, plan.from_code(out.to_bits()));
            moved = moved.max(meaning.abs());
        }
        assert!(moved > 0.1 && !typed.overflowed());

        let plan = direct::DirectPlan::new(&design, full_scale).unwrap();
        let c = DirectCascade::<8>::new(&plan.board_sections()).unwrap();
        let (mut typed, mut plain): (DirectState<8>, _) =
            (c.equilibrium_q(start), c.equilibrium(codes[0]));
        assert_eq!(typed, plain);
        for &u in &codes {
            let out = c.process_q(&mut typed, I1F31::from_bits(u));
            assert_eq!(out.to_bits(), c.process(&mut plain, u));
            assert_eq!(typed, plain);
            let meaning = out.to_num::<f64>() * full_scale * 2f64.powi(plan.output_exponent);
            assert_eq!(meaning, plan.from_code(out.to_bits()));
        }
        assert!(!typed.overflowed());
    }

    #[test]
    fn refuses_a_bad_full_scale() {
        let design = line_design(1e4, 95.0, 0.2, 300.0);
        assert!(FixedPlan::new(&design, 0.0).is_err());
        assert!(FixedPlan::new(&design, f64::NAN).is_err());
    }

    #[test]
    fn a_design_without_sections_has_no_plan() {
        let mut design = line_design(1e4, 95.0, 0.2, 300.0);
        design.sections.clear();
        for e in [
            FixedPlan::new(&design, 1.0).unwrap_err(),
            direct::DirectPlan::new(&design, 1.0).unwrap_err(),
        ] {
            assert!(matches!(e.stage(), Some(DesignError::NoSections)), "{e:?}");
            assert_eq!(e.to_string(), "fixed point: the design has no sections");
        }
        let mut design = line_design(1e4, 95.0, 0.2, 300.0);
        design.sections[0][4] = 1.5;
        let e = FixedPlan::new(&design, 1.0).unwrap_err();
        assert!(
            matches!(e.stage(), Some(DesignError::SectionPoleRadius { radius }) if *radius > 1.0),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .starts_with("fixed point: a section pole has radius 1.2247"),
            "{e}"
        );
    }
}
