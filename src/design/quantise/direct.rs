//! From a designed compensator (f64 second-order sections) to the board's direct-form
//! fixed-point one ([`crate::board::fixed::direct::DirectCascade`]): scaling and quantisation, chosen
//! once on the host.
//!
//! This module owns [`DirectPlan`]. Each section keeps the design's denominator, quantised to
//! Q2.30 (`-a1`, `-a2`), and gets its numerator scaled so that its output, by the L1 norm of
//! the impulse response from the cascade's input (computed with the quantised denominators and
//! numerators actually used), stays within [`TARGET`] of the `i32` range; the last section's
//! scale is a power of two, so the output is Q1.31 of `full_scale * 2^output_exponent`. The
//! numerator is rounded so that its sum, the section's DC gain times the quantised `A(1)`, is
//! the nearest integer to the exact one (DC matched to within half a unit of `B(1)`).
//!
//! The no-overflow bound adds the error feedback's contribution: each section's truncation
//! error reaches its output through `(1 - z^-1) / A(z)` with an amplitude below one code per
//! sample, and the earlier sections' through the later ones; the plan is refused unless signal
//! and noise bounds together stay below the `i32` range.

use serde::{Deserialize, Serialize};

use super::{impulse_len, Cascade, TARGET};
use crate::board::fixed::direct::{
    DirectCascade, DirectSection, DirectState, COEFFICIENT_BITS, MAX_COEFFICIENT_SUM,
};
use crate::design::DesignError;
use crate::error::Result;

/// One section of a direct-form plan: the board's integers and the bounds behind them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectPlanSection {
    /// Numerator `[b0, b1, b2]`, Q2.30.
    pub b: [i32; 3],
    /// Negated denominator `[-a1, -a2]`, Q2.30.
    pub neg_a: [i32; 2],
    /// Largest possible `|output|` as a fraction of the `i32` range (L1 bound, signal only).
    pub output_bound: f64,
    /// Largest possible contribution of the truncation errors to the output, in codes.
    pub noise_bound: f64,
}

impl DirectPlanSection {
    /// The board's section.
    #[must_use]
    pub fn section(&self) -> DirectSection {
        DirectSection {
            b: self.b,
            neg_a: self.neg_a,
        }
    }
}

/// The direct-form fixed-point compensator for one design and one ADC full scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectPlan {
    /// The ADC's full scale in the probe's units: `y = full_scale` is the code `2^31`.
    pub full_scale: f64,
    /// The output is the reconstructed pressure in Q1.31 of `full_scale * 2^output_exponent`.
    pub output_exponent: i32,
    /// L1 norm of the whole compensator's impulse response, in units of the full scale.
    pub l1_gain: f64,
    /// Smallest headroom over all section outputs, in bits, by the L1 bound (noise included).
    pub headroom_bits: f64,
    /// The sections.
    pub sections: Vec<DirectPlanSection>,
}

/// Rounds `v * 2^30` to a coefficient, refusing what does not fit `i32`.
fn coefficient(v: f64, what: &'static str) -> Result<i32> {
    let q = (v * f64::from(COEFFICIENT_BITS).exp2()).round();
    if !q.is_finite() || q >= f64::from(i32::MAX) || q < f64::from(i32::MIN) {
        return Err(DesignError::DirectCoefficientRange { what, value: v }.into());
    }
    // In range, checked above.
    #[allow(clippy::cast_possible_truncation)]
    Ok(q as i32)
}

/// `y = B(z) / A(z) x` in f64, crate sign convention (`a = [a1, a2]`).
fn filter(b: [f64; 3], a: [f64; 2], x: &[f64]) -> Vec<f64> {
    let [b0, b1, b2] = b;
    let [a1, a2] = a;
    let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
    x.iter()
        .map(|&x0| {
            let y = b0 * x0 + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
            (x2, x1, y2, y1) = (x1, x0, y1, y);
            y
        })
        .collect()
}

fn l1(h: &[f64]) -> f64 {
    h.iter().map(|v| v.abs()).sum()
}

/// Rounds the scaled numerator `t` (in coefficient units) so that the sum of the integers is
/// `sum`: the nearest integers, then single steps where they cost the least.
fn round_to_sum(t: [f64; 3], sum: i64) -> [i64; 3] {
    // In range: the caller checked the magnitudes.
    #[allow(clippy::cast_possible_truncation)]
    let mut r = t.map(|v| v.round() as i64);
    let mut deficit = sum - r.iter().sum::<i64>();
    // At most a few steps: |sum - sum(t)| <= 1/2 and each rounding moved by at most 1/2.
    for _ in 0..8 {
        if deficit == 0 {
            break;
        }
        let step = deficit.signum();
        let best = (0..3)
            .min_by(|&i, &j| {
                let ci = ((r[i] + step) as f64 - t[i]).abs();
                let cj = ((r[j] + step) as f64 - t[j]).abs();
                ci.total_cmp(&cj)
            })
            .unwrap_or(0);
        r[best] += step;
        deficit -= step;
    }
    r
}

impl DirectPlan {
    /// Plans the direct-form compensator for `design` and inputs within `+-full_scale`.
    ///
    /// # Errors
    /// [`crate::error::Error::InvalidParameter`] for a full scale that is not positive and finite;
    /// [`DesignError`] when the design has no sections or a pole on or outside the unit circle,
    /// a coefficient cannot be represented, a bound is not finite or leaves no headroom, or the
    /// quantised cascade is refused by the board's validation.
    pub fn new<'a>(design: impl Into<Cascade<'a>>, full_scale: f64) -> Result<Self> {
        let design = design.into();
        let len = impulse_len(&design, full_scale)?;
        let mut input = vec![0.0; len];
        if let Some(first) = input.first_mut() {
            *first = 1.0;
        }
        let mut impulse = vec![0.0; len];
        if let Some(first) = impulse.first_mut() {
            *first = 1.0;
        }
        let one = f64::from(COEFFICIENT_BITS).exp2();
        let mut scale_in = 1.0;
        // Bound of the accumulated truncation noise at the current section's input, in codes.
        let mut noise_in = 0.0;
        let mut sections = Vec::with_capacity(design.sections.len());
        let mut headroom = f64::INFINITY;
        let last = design.sections.len() - 1;
        let mut l1_gain = f64::NAN;
        let mut output_exponent = 0;
        for (k, &sec) in design.sections.iter().enumerate() {
            let g = if k == 0 { design.gain } else { 1.0 };
            let [b0, b1, b2, a1, a2] = sec;
            let b = [b0 * g, b1 * g, b2 * g];
            let neg_a = [coefficient(-a1, "-a1")?, coefficient(-a2, "-a2")?];
            let aq = neg_a.map(|v| -f64::from(v) / one);
            let out = filter(b, aq, &input);
            let out_l1 = l1(&out);
            if !(out_l1.is_finite() && out_l1 > 0.0) {
                return Err(DesignError::DirectL1Bound { section: k }.into());
            }
            // The accumulator's bound: the coefficient magnitudes must sum below 2^32 (with
            // room for the rounding of the numerator), which caps the numerator's scale (the
            // section's output then uses less of the i32 range than TARGET).
            let room = (MAX_COEFFICIENT_SUM as f64
                - 16.0
                - f64::from(neg_a[0].unsigned_abs())
                - f64::from(neg_a[1].unsigned_abs()))
                / one;
            let b_sum = b.iter().map(|v| v.abs()).sum::<f64>();
            // And each numerator coefficient must fit Q2.30.
            let b_max = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let lambda_max = (room / b_sum).min((f64::from(i32::MAX) - 8.0) / one / b_max);
            let lambda = if k == last {
                l1_gain = out_l1 / scale_in;
                // Output scale 2^-e of the whole cascade, no larger than the cap allows.
                let e = -(TARGET / l1_gain).log2().floor();
                let e = e.max(-(lambda_max * scale_in).log2().floor());
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
                (TARGET / out_l1).min(lambda_max)
            };
            // The numerator, DC-matched to the quantised denominator.
            let t = b.map(|v| v * lambda * one);
            if t.iter()
                .any(|v| !v.is_finite() || v.abs() >= f64::from(i32::MAX) - 2.0)
            {
                return Err(DesignError::ScaledNumeratorRange { section: k }.into());
            }
            let a_q1 = one - f64::from(neg_a[0]) - f64::from(neg_a[1]);
            let dc = (b[0] + b[1] + b[2]) * lambda / (1.0 + a1 + a2);
            // |dc * A_q(1)| is about |sum(t)| < 3 * 2^31: in i64.
            #[allow(clippy::cast_possible_truncation)]
            let sum = (dc * a_q1).round() as i64;
            let bq = round_to_sum(t, sum);
            let mut bi = [0i32; 3];
            for (dst, v) in bi.iter_mut().zip(bq) {
                *dst =
                    i32::try_from(v).map_err(|_| DesignError::NumeratorOverflow { section: k })?;
            }
            let bf = bi.map(|v| f64::from(v) / one);
            // Bounds with the integers the board uses.
            let out = filter(bf, aq, &input);
            let output_bound = l1(&out);
            let feedback = {
                let mut h = filter([1.0, -1.0, 0.0], aq, &impulse);
                h.truncate(len);
                l1(&h)
            };
            let gain = l1(&filter(bf, aq, &impulse));
            let noise = feedback + gain * noise_in;
            let total = output_bound + noise / 2f64.powi(31);
            if !(total.is_finite() && total < 0.99) {
                return Err(DesignError::NoHeadroom {
                    section: k,
                    bound: total,
                }
                .into());
            }
            headroom = headroom.min(-total.log2());
            sections.push(DirectPlanSection {
                b: bi,
                neg_a,
                output_bound,
                noise_bound: noise,
            });
            input = out;
            scale_in *= lambda;
            noise_in = noise;
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
    pub fn board_sections(&self) -> Vec<DirectSection> {
        self.sections
            .iter()
            .map(DirectPlanSection::section)
            .collect()
    }

    /// Validates the integers as the board does.
    ///
    /// # Errors
    /// [`DesignError::DirectBoard`] with the board's reason.
    pub fn check(&self) -> Result<()> {
        DirectCascade::<16>::new(&self.board_sections())
            .map(|_| ())
            .map_err(|error| DesignError::DirectBoard { error }.into())
    }

    /// The Q1.31 code of a probe value, clamped to the full scale; `true` when clamped.
    #[must_use]
    pub fn to_code(&self, y: f64) -> (i32, bool) {
        super::code_of(y, self.full_scale)
    }

    /// The probe's units of an output code.
    #[must_use]
    pub fn from_code(&self, code: i32) -> f64 {
        f64::from(code) * 2f64.powi(self.output_exponent - 31) * self.full_scale
    }

    /// Runs the board's direct-form code on `y`, starting in equilibrium with `y[0]`.
    ///
    /// # Errors
    /// [`DesignError::DirectBoard`] when the plan does not validate.
    pub fn run(&self, y: &[f64]) -> Result<super::FixedRun> {
        let mut runner = self.runner(y.first().copied().unwrap_or(0.0))?;
        let u_hat = y.iter().map(|&v| runner.step(v)).collect();
        Ok(runner.finish(u_hat))
    }

    /// [`DirectPlan::run`] one sample at a time, started in equilibrium with `first`.
    ///
    /// # Errors
    /// As [`DirectPlan::run`].
    pub fn runner(&self, first: f64) -> Result<super::FixedRunner> {
        let sections = self.board_sections();
        let (first, _) = self.to_code(first);
        let cascade: Box<dyn super::FixedStep> = match sections.len() {
            0..=2 => Box::new(Direct::<2>::new(&sections, first)?),
            3..=4 => Box::new(Direct::<4>::new(&sections, first)?),
            5..=8 => Box::new(Direct::<8>::new(&sections, first)?),
            _ => Box::new(Direct::<16>::new(&sections, first)?),
        };
        Ok(super::FixedRunner::new(
            cascade,
            self.full_scale,
            self.output_exponent,
        ))
    }
}

/// The direct form's cascade of `N` sections and its state.
struct Direct<const N: usize> {
    cascade: DirectCascade<N>,
    state: DirectState<N>,
}

impl<const N: usize> Direct<N> {
    fn new(sections: &[DirectSection], first: i32) -> Result<Self> {
        let cascade = DirectCascade::<N>::new(sections)
            .map_err(|error| DesignError::DirectBoard { error })?;
        let state = cascade.equilibrium(first);
        Ok(Self { cascade, state })
    }
}

impl<const N: usize> super::FixedStep for Direct<N> {
    fn step(&mut self, code: i32) -> i32 {
        self.cascade.process(&mut self.state, code)
    }
    fn overflowed(&self) -> bool {
        self.state.overflowed()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_to_a_sum_moves_the_cheapest_coefficient() {
        assert_eq!(round_to_sum([1.3, 2.45, 3.0], 7), [1, 3, 3]);
        assert_eq!(round_to_sum([1.6, 2.4, 3.0], 6), [1, 2, 3]);
        assert_eq!(round_to_sum([1.0, 2.0, 3.0], 6), [1, 2, 3]);
    }
}
