//! Designing the compensator the board runs: a stable, band-limited inverse of the model,
//! stored as second-order sections, with honest numbers about what it does.
//!
//! The paper's inverse `A/B` (eq. 7) divides by `B(z)`: it is unstable when `B` has a zero on
//! or outside the unit circle, and where it is stable it amplifies noise without limit. This
//! module owns the fix:
//!
//! 1. **Stable inverse.** Zeros of `B` outside the unit circle are reflected to `1/z*` (same
//!    magnitude response; the phase difference is the all-pass `B/B_r`, which becomes extra
//!    latency), zeros on or just inside it are pulled in to [`ZERO_RADIUS_MAX`]. The gain is
//!    fixed so that `B_r(1) = B(1)`: the DC gain of the correction is exactly `1/H(1)`.
//! 2. **Band limit.** The inverse is multiplied by a low-pass (Bessel by default: the step
//!    response of a Bessel filter barely overshoots, which matters for step-like pressures),
//!    designed by the bilinear transform with prewarping. Its corner is chosen by the user, or
//!    automatically as the one that reconstructs the reference of the given tests best (the
//!    trade between bandwidth and noise, judged on data, not on a rule of thumb).
//! 3. **Sections.** Poles and zeros are paired into second-order sections (poles nearest the
//!    unit circle first, each with its nearest zeros), as the board's
//!    [`CascadeCoefficients`] runs them.
//! 4. **Numbers.** Corrected bandwidth (where the compensated response `H C` leaves +/-1 dB and
//!    +/-5 degrees of a pure delay), noise gain (RMS output for unit white input noise),
//!    latency, the worst in-band error against the target `LP / H`, and the pole margin.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::board::compensator::{CascadeCoefficients, CascadeState, Sample, MIN_POLE_MARGIN};
use crate::design::DesignError;
use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::fit::Test;
use crate::poly::{self, Complex};

pub mod check;
mod filter;
pub mod method;
pub mod optimal;
mod reconstruct;

pub(crate) use filter::cascade_response_at_inverse;
pub(crate) use filter::{c, noise_gain, unit, unwrap};
pub use filter::{cascade_response, lowpass, model_response, to_sections, Zpk};
#[cfg(test)]
use reconstruct::FFT_ALIGNMENT_WORK;
pub use reconstruct::{
    aligned_error, comparison_lags, reconstruct, reconstruct_with, AlignedErrorStream,
};

pub use method::{DesignMethod, MethodKind};

/// Largest radius a zero of `B` may keep in the stable inverse (it becomes a pole of the
/// compensator); zeros between this and the unit circle are pulled in to it. A zero inside it
/// is physics (a leak or a thermal creep puts a real zero next to `z = 1`) and is inverted as
/// it is: moving it would change the inverse's gain below its corner by the ratio of the
/// distances to `z = 1`. The margin is ten times the board's [`MIN_POLE_MARGIN`].
pub const ZERO_RADIUS_MAX: f64 = 1.0 - 10.0 * MIN_POLE_MARGIN;

/// Low-pass family of the band limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LowpassKind {
    /// Maximally flat group delay: a step passes with almost no overshoot (default).
    #[default]
    Bessel,
    /// Maximally flat magnitude: sharper, but a step rings.
    Butterworth,
}

/// How to build the inverse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Low-pass corner in Hz; `None` chooses it from the data (or the noise gain).
    pub bandwidth_hz: Option<f64>,
    /// Low-pass family.
    pub lowpass: LowpassKind,
    /// Low-pass order (1..=8).
    pub lowpass_order: usize,
    /// `true`: stable inverse (reflect and pull in zeros). `false`: the paper's direct inverse
    /// `A/B` times the same low-pass, for comparison (unstable when `B` is not minimum phase).
    pub stabilise: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            bandwidth_hz: None,
            lowpass: LowpassKind::Bessel,
            lowpass_order: 4,
            stabilise: true,
        }
    }
}

/// One candidate corner of the automatic bandwidth choice.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BandwidthRow {
    /// Low-pass corner in Hz.
    pub lowpass_hz: f64,
    /// Mean reconstruction error over the tests (RMS / range of the reference).
    pub nrmse: f64,
    /// Noise gain of the compensator at this corner.
    pub noise_gain: f64,
}

/// Reconstruction of one test's reference by the compensator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reconstruction {
    /// The test.
    pub file: String,
    /// Error of `u_hat` against the recorded reference (RMS / range, best alignment).
    pub nrmse_u_hat: f64,
    /// Error of the raw probe against the reference (RMS / range, best alignment).
    pub nrmse_raw: f64,
    /// The alignment found for `u_hat`, in samples.
    pub lag: usize,
    /// Range of the reference (what the errors are normalised by).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<f64>,
    /// The part of `u_hat`'s measured error that neither the predicted noise and band-limit
    /// parts nor the reference's own noise explain (RMS / range): the model's error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_part: Option<f64>,
}

/// A designed compensator: what the board runs, and what it does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Design {
    /// The [`Model::fingerprint`](crate::fit::model::Model::fingerprint) of the model this
    /// compensator was designed for, stamped when a model file is written: a file whose model
    /// no longer has it is refused ([`crate::file::ModelFile::load`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_sha256: Option<String>,
    /// How it was built (the words the CLI prints and the model file stores).
    pub method: DesignMethod,
    /// Low-pass family.
    pub lowpass: LowpassKind,
    /// Low-pass order.
    pub lowpass_order: usize,
    /// Low-pass corner (-3 dB) in Hz.
    pub lowpass_hz: f64,
    /// How the corner was chosen.
    pub bandwidth_selection: String,
    /// Input gain of the cascade.
    pub gain: f64,
    /// Sections `[b0, b1, b2, a1, a2]` in the crate's sign convention.
    pub sections: Vec<[f64; 5]>,
    /// Total latency of `u_hat` behind the true pressure, in samples (model delay + all-pass
    /// delay of reflected zeros + low-pass group delay at DC).
    pub latency_samples: f64,
    /// The same in seconds.
    pub latency_s: f64,
    /// Where the compensated response leaves +/-1 dB or +/-5 degrees of a pure delay, in Hz.
    pub corrected_bandwidth_hz: f64,
    /// RMS output noise for unit white input noise (`sqrt(sum h^2)` of the compensator).
    pub noise_gain: f64,
    /// Worst magnitude error of `H C` against the target low-pass up to the corner, in dB
    /// (for the optimal smoother, which has no low-pass: against a pure delay up to half its
    /// -3 dB band).
    pub in_band_magnitude_error_db: f64,
    /// Worst phase error of `H C` against the target low-pass and latency up to the corner, in
    /// degrees.
    pub in_band_phase_error_deg: f64,
    /// `1 - max |pole|` of the compensator.
    pub pole_margin: f64,
    /// Zeros of `B` reflected into the unit circle (non-minimum-phase part).
    #[serde(default)]
    pub reflected_zeros: Vec<String>,
    /// Zeros of `B` pulled in to [`ZERO_RADIUS_MAX`].
    #[serde(default)]
    pub pulled_zeros: Vec<String>,
    /// The automatic corner choice, when it was made.
    #[serde(default)]
    pub candidates: Vec<BandwidthRow>,
    /// Reconstruction on the tests it was judged on.
    #[serde(default)]
    pub reconstruction: Vec<Reconstruction>,
    /// The fixed-point version for the board (`--arithmetic fixed`): integer coefficients,
    /// scaling and headroom for the ADC's full scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed: Option<crate::design::quantise::FixedPlan>,
    /// The direct-form fixed-point version (`--fixed-form direct`), instead of `fixed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_direct: Option<crate::design::quantise::DirectPlan>,
    /// The noise both channels showed, as the design used it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<optimal::NoiseModel>,
    /// The pressure's prior.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prior: Option<optimal::SignalPrior>,
    /// The predicted error (noise and band-limit parts) of `u_hat` against the true pressure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<optimal::Budget>,
    /// The check against the raw probe on the tests, and any fall-back it forced.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub check: Option<check::Check>,
}

/// `v` rounded to `T` and widened back: the coefficient a board given the exported set holds.
/// A compensator run one sample at a time ([`Design::runner`]): a probe sample in, the
/// reconstructed pressure out.
pub type Runner = Box<dyn FnMut(f64) -> f64>;

fn exported<T: Sample>(v: f64) -> f64 {
    T::from_f64(v).to_f64()
}

/// `gain` and `sections` as [`exported`]: what a board builds its cascade from.
fn as_exported<T: Sample>(gain: f64, sections: &[[f64; 5]]) -> (f64, Vec<[f64; 5]>) {
    (
        exported::<T>(gain),
        sections.iter().map(|s| s.map(exported::<T>)).collect(),
    )
}

/// Group delay at DC, in samples, of `prod (1 - from z^-1) / (1 - to z^-1)` times `lp`: the
/// phase slope over a small step from `omega = 0`, measured from the phase at DC (a zero
/// reflected from the positive real axis makes the product negative there).
fn group_delay_at_dc(moved: &[(Complex, Complex)], lp: &Zpk) -> f64 {
    let value = |z: Complex| {
        let zi = c(1.0) / z;
        moved.iter().fold(lp.eval(z), |acc, (from, to)| {
            acc * (c(1.0) - *from * zi) / (c(1.0) - *to * zi)
        })
    };
    let eps: f64 = 1e-6;
    let at_dc = value(c(1.0));
    let near = value(Complex::new(eps.cos(), eps.sin()));
    let turn = near / at_dc;
    -turn.im.atan2(turn.re) / eps
}

/// The model's numerator after its leading zero coefficients, which are delay: `(count, b)`.
///
/// # Errors
/// [`DesignError::ZeroNumerator`] naming `context` when `b` is zero.
pub(crate) fn numerator_after_delay<'m>(
    model: &'m Model,
    context: &'static str,
) -> Result<(usize, &'m [f64])> {
    let scale = model.b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let lead = model
        .b
        .iter()
        .position(|v| v.abs() > 1e-12 * scale)
        .ok_or(DesignError::ZeroNumerator { context })?;
    Ok((lead, model.b.get(lead..).unwrap_or(&[])))
}

/// Designs the compensator for `model` with the low-pass corner `fc` (Hz).
///
/// # Errors
/// [`Error::InvalidArgument`] for a bad corner or order, [`Error::UnstableInverse`] when
/// `stabilise` is off and `B` is not minimum phase, [`DesignError`] when `B(1) = 0` (the
/// probe does not pass DC), [`crate::poly::PolyError`] when root finding fails.
pub fn design(model: &Model, fc: f64, options: &Options) -> Result<Design> {
    Ok(design_core(model, fc, options)?.finish(model, fc, options))
}

/// The part of a [`design`] a corner search scores by: the cascade, its latency and pole
/// margin, before the responses on a frequency grid and the noise gain that only the chosen
/// corner's [`Design`] reports ([`Core::finish`]).
pub(crate) struct Core {
    pub(crate) gain: f64,
    pub(crate) sections: Vec<[f64; 5]>,
    pub(crate) latency: f64,
    pub(crate) pole_margin: f64,
    lp: Zpk,
    reflected: Vec<String>,
    pulled: Vec<String>,
}

/// [`design`] up to its [`Core`].
///
/// # Errors
/// As [`design`] (the rest of it cannot fail).
pub(crate) fn design_core(model: &Model, fc: f64, options: &Options) -> Result<Core> {
    let fs = model.fs;
    let (lead, b) = numerator_after_delay(model, "inverse")?;
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let b0 = b.first().copied().unwrap_or(1.0);
    let b_at_1: f64 = b.iter().sum();
    if b_at_1.abs() < 1e-14 * scale {
        return Err(DesignError::NoSteadyGain.into());
    }
    let zeros = poly::roots(b)?;
    let poles = model.poles()?;
    let mut inv_poles = Vec::with_capacity(zeros.len());
    let mut reflected = Vec::new();
    let mut pulled = Vec::new();
    // Zeros moved (reflected or pulled in) as (from, to): `H C` keeps `(1 - from z^-1) /
    // (1 - to z^-1)` of each, whose phase adds to the latency.
    let mut moved: Vec<(Complex, Complex)> = Vec::new();
    for z in &zeros {
        let r = z.norm();
        if !options.stabilise {
            if r >= 1.0 {
                return Err(Error::UnstableInverse {
                    context: "direct inverse".into(),
                    zero: poly::format_root(*z),
                    radius: r,
                });
            }
            inv_poles.push(*z);
        } else if r > 1.0 + 1e-9 {
            let w = c(1.0) / z.conj();
            let to = if w.norm() > ZERO_RADIUS_MAX {
                pulled.push(poly::format_root(*z));
                w * (ZERO_RADIUS_MAX / w.norm())
            } else {
                reflected.push(poly::format_root(*z));
                w
            };
            inv_poles.push(to);
            moved.push((*z, to));
        } else if r > ZERO_RADIUS_MAX {
            pulled.push(poly::format_root(*z));
            let to = *z * (ZERO_RADIUS_MAX / r);
            inv_poles.push(to);
            moved.push((*z, to));
        } else {
            inv_poles.push(*z);
        }
    }
    // A/B_r, with B_r(1) = B(1): gain = A(1)/B(1) over the product form at z = 1.
    let lp = lowpass(options.lowpass, options.lowpass_order, fc, fs)?;
    let mut inv = Zpk {
        zeros: poles.clone(),
        poles: inv_poles,
        gain: 1.0 / b0,
    };
    let a_at_1: f64 = 1.0 + model.a.iter().sum::<f64>();
    let target_dc = a_at_1 / b_at_1;
    let raw_dc = inv.eval(c(1.0)).re;
    inv.gain *= target_dc / raw_dc;
    let mut all = inv.clone();
    all.zeros.extend(lp.zeros.iter().copied());
    all.poles.extend(lp.poles.iter().copied());
    all.gain *= lp.gain;
    let (gain, sections) = to_sections(&all);
    let pole_margin = 1.0 - all.poles.iter().map(|p| p.norm()).fold(0.0, f64::max);
    // Latency: `H C = z^-d (B / B_moved) LP`, so the model's delay (leading zeros of b
    // included) plus the group delay at DC of the moved zeros' ratio and of the low-pass. The
    // model's own slow dynamics (a leak's pole and zero next to z = 1) cancel in `H C` and
    // never enter it.
    let latency = (model.delay + lead) as f64 + group_delay_at_dc(&moved, &lp);
    Ok(Core {
        gain,
        sections,
        latency,
        pole_margin,
        lp,
        reflected,
        pulled,
    })
}

impl Core {
    /// The whole [`Design`] at the corner `fc` this core was made for.
    pub(crate) fn finish(self, model: &Model, fc: f64, options: &Options) -> Design {
        let Self {
            gain,
            sections,
            latency,
            pole_margin,
            lp,
            reflected,
            pulled,
        } = self;
        let fs = model.fs;
        // Numbers on a frequency grid up to Nyquist.
        let n = 4000;
        let freqs: Vec<f64> = (1..=n).map(|i| 0.5 * fs * i as f64 / n as f64).collect();
        let h: Vec<Complex> = freqs
            .iter()
            .map(|&f| model_response(model, unit(f, fs)))
            .collect();
        let cc: Vec<Complex> = freqs
            .iter()
            .map(|&f| cascade_response(gain, &sections, unit(f, fs)))
            .collect();
        let lpr: Vec<Complex> = freqs.iter().map(|&f| lp.eval(unit(f, fs))).collect();
        let t: Vec<Complex> = h.iter().zip(&cc).map(|(a, b)| *a * *b).collect();
        let phase_t = unwrap(&t);
        let f_ref = (fs * 1e-4).min(fc * 0.01);
        let mut bandwidth = 0.5 * fs;
        for ((f, tv), ph) in freqs.iter().zip(&t).zip(&phase_t) {
            let mag_db = 20.0 * tv.norm().log10();
            let ph_err = (ph + 2.0 * PI * f / fs * latency).to_degrees();
            if mag_db.abs() > 1.0 || ph_err.abs() > 5.0 {
                bandwidth = *f;
                break;
            }
        }
        // Error against the target LP (magnitude) and LP with the latency of model + all-pass.
        let lp_latency = {
            let v = lp.eval(unit(f_ref, fs));
            -v.im.atan2(v.re) / (2.0 * PI * f_ref / fs)
        };
        let mut worst_db: f64 = 0.0;
        let mut worst_deg: f64 = 0.0;
        let ratio: Vec<Complex> = t.iter().zip(&lpr).map(|(a, b)| *a / *b).collect();
        let phase_r = unwrap(&ratio);
        for ((f, r), ph) in freqs.iter().zip(&ratio).zip(&phase_r) {
            if *f > fc {
                break;
            }
            worst_db = worst_db.max((20.0 * r.norm().log10()).abs());
            let err = (ph + 2.0 * PI * f / fs * (latency - lp_latency)).to_degrees();
            worst_deg = worst_deg.max(err.abs());
        }
        let method = if options.stabilise {
            MethodKind::StableInverse
        } else {
            MethodKind::DirectInverse
        };
        Design {
            method: DesignMethod::of(method),
            lowpass: options.lowpass,
            lowpass_order: options.lowpass_order,
            lowpass_hz: fc,
            bandwidth_selection: "given".into(),
            gain,
            noise_gain: noise_gain(gain, &sections),
            sections,
            latency_samples: latency,
            latency_s: latency / fs,
            corrected_bandwidth_hz: bandwidth,
            in_band_magnitude_error_db: worst_db,
            in_band_phase_error_deg: worst_deg,
            pole_margin,
            reflected_zeros: reflected,
            pulled_zeros: pulled,
            candidates: Vec::new(),
            reconstruction: Vec::new(),
            fixed: None,
            fixed_direct: None,
            noise: None,
            prior: None,
            budget: None,
            check: None,
            model_sha256: None,
        }
    }
}

impl<'a> From<&'a Design> for crate::design::quantise::Cascade<'a> {
    fn from(d: &'a Design) -> Self {
        Self {
            gain: d.gain,
            sections: &d.sections,
        }
    }
}

impl Design {
    /// Whether this is the fixed-lag Kalman smoother (which has no low-pass of its own).
    #[must_use]
    pub fn is_smoother(&self) -> bool {
        // Not after a prefilter: the smoother's band is then told as a low-pass's, as always.
        !self.method.is_prefiltered() && self.method.kind() == MethodKind::Smoother
    }

    /// Its band in words: `Bessel low-pass at 300 Hz`, or the smoother's -3 dB band.
    #[must_use]
    pub fn band_text(&self) -> String {
        if self.is_smoother() {
            format!("optimal smoother, -3 dB band {:.0} Hz", self.lowpass_hz)
        } else {
            format!("{:?} low-pass at {:.0} Hz", self.lowpass, self.lowpass_hz)
        }
    }

    /// Runs the compensator on `y` in arithmetic `T` with the board's code, starting in
    /// equilibrium with `y[0]`: built, as the board builds it, from the coefficients rounded
    /// to `T` (what `unlag export` writes), so that its start in equilibrium is the board's
    /// too.
    ///
    /// # Errors
    /// [`DesignError::Cascade`] when the sections do not validate (too many, or a pole too
    /// close to the unit circle).
    pub fn run<T: Sample + 'static>(&self, y: &[f64]) -> Result<Vec<f64>> {
        let mut step = self.runner::<T>(y.first().copied().unwrap_or(0.0))?;
        Ok(y.iter().map(|&v| step(v)).collect())
    }

    /// [`Design::run`] one sample at a time, for a run streamed from its file: the compensator
    /// started in equilibrium with `first` (the run's first sample), each call one sample in
    /// and one out.
    ///
    /// # Errors
    /// As [`Design::run`].
    pub fn runner<T: Sample + 'static>(&self, first: f64) -> Result<Runner> {
        match self.sections.len() {
            0..=2 => self.runner_with::<T, 2>(first),
            3..=4 => self.runner_with::<T, 4>(first),
            5..=8 => self.runner_with::<T, 8>(first),
            _ => self.runner_with::<T, 16>(first),
        }
    }

    fn runner_with<T: Sample + 'static, const N: usize>(&self, first: f64) -> Result<Runner> {
        let (gain, sections) = as_exported::<T>(self.gain, &self.sections);
        let c = CascadeCoefficients::<T, N>::new(gain, &sections)
            .map_err(|error| DesignError::Cascade { error })?;
        let mut st: CascadeState<T, N> = c.equilibrium(T::from_f64(first));
        Ok(Box::new(move |v| {
            c.process(&mut st, T::from_f64(v)).to_f64()
        }))
    }

    /// The design's own low-pass as `(gain, sections)`, which the board's
    /// nonlinear-damping correction runs too
    /// ([`NonlinearDampingCoefficients`](crate::board::compensator::NonlinearDampingCoefficients)).
    ///
    /// # Errors
    /// As [`lowpass`].
    pub fn lowpass_sections(&self, fs: f64) -> Result<(f64, Vec<[f64; 5]>)> {
        let lp = lowpass(self.lowpass, self.lowpass_order, self.lowpass_hz, fs)?;
        Ok(to_sections(&lp))
    }

    /// The nonlinear-damping correction `gain fs^2 lowpass(|dy| dy)` for the probe signal `y`
    /// (quadratic loss `gain` in s^2 per probe unit, see [`crate::effects`]), in arithmetic
    /// `T` with the board's code, starting in equilibrium with `y[0]`: what the board adds to
    /// [`Design::run`]'s output.
    ///
    /// # Errors
    /// As [`Design::lowpass_sections`]; [`DesignError::NonlinearCorrection`] when the
    /// correction's coefficients do not validate.
    pub fn run_nonlinear_correction<T: Sample + 'static>(
        &self,
        fs: f64,
        gain: f64,
        y: &[f64],
    ) -> Result<Vec<f64>> {
        let mut step = self.nonlinear_runner::<T>(fs, gain, y.first().copied().unwrap_or(0.0))?;
        Ok(y.iter().map(|&v| step(v)).collect())
    }

    /// [`Design::run_nonlinear_correction`] one sample at a time, started in equilibrium with
    /// `first`.
    ///
    /// # Errors
    /// As [`Design::run_nonlinear_correction`].
    pub fn nonlinear_runner<T: Sample + 'static>(
        &self,
        fs: f64,
        gain: f64,
        first: f64,
    ) -> Result<Runner> {
        let (lp_gain, lp) = self.lowpass_sections(fs)?;
        let (lp_gain, lp) = as_exported::<T>(lp_gain, &lp);
        let c = crate::board::compensator::NonlinearDampingCoefficients::<T, 4>::new(
            exported::<T>(gain * fs * fs),
            lp_gain,
            &lp,
        )
        .map_err(|error| DesignError::NonlinearCorrection { error })?;
        let mut st = c.equilibrium(T::from_f64(first));
        Ok(Box::new(move |v| {
            c.process(&mut st, T::from_f64(v)).to_f64()
        }))
    }

    /// Whether the design passes the probe signal through unchanged but for its gain (every
    /// section the identity): the delay-only design. Its output is then compared with the
    /// reference over the raw probe's lags, since it is the raw probe.
    #[must_use]
    pub fn passes_probe(&self) -> bool {
        self.sections
            .iter()
            .all(|s| *s == [1.0, 0.0, 0.0, 0.0, 0.0])
    }

    /// Checks that the board may run it: every pole inside the unit circle by
    /// [`MIN_POLE_MARGIN`].
    ///
    /// # Errors
    /// [`DesignError::PoleMargin`] naming the margin.
    pub fn check_exportable(&self) -> Result<()> {
        if self.pole_margin.is_nan() || self.pole_margin < MIN_POLE_MARGIN {
            return Err(DesignError::PoleMargin {
                margin: self.pole_margin,
            }
            .into());
        }
        Ok(())
    }
}

/// Designs the compensator, choosing the low-pass corner when `options.bandwidth_hz` is
/// `None`: with tests, the corner whose compensator reconstructs their references best (mean
/// error, best alignment, on a log grid from fs/1000 to 0.4 fs); without tests, the highest
/// corner whose noise gain stays below 10.
///
/// # Errors
/// As [`design`].
pub fn design_auto(model: &Model, tests: &[Test<'_>], options: &Options) -> Result<Design> {
    design_auto_with(model, tests, options, 0.0)
}

/// [`design_auto`] for a model with the `nonlinear-damping` effect: the corner is chosen, and
/// the reconstructions are measured, with the board's correction for the quadratic loss
/// `nonlinear_gain` added ([`reconstruct_with`]); with `nonlinear_gain = 0` exactly
/// [`design_auto`].
///
/// # Errors
/// As [`design_auto`].
pub fn design_auto_with(
    model: &Model,
    tests: &[Test<'_>],
    options: &Options,
    nonlinear_gain: f64,
) -> Result<Design> {
    let reconstruct =
        |d: &Design, model: &Model, t: &Test<'_>| reconstruct_with(d, model, t, nonlinear_gain);
    let fs = model.fs;
    if let Some(fc) = options.bandwidth_hz {
        let mut d = design(model, fc, options)?;
        for t in tests {
            d.reconstruction.push(reconstruct(&d, model, t)?);
        }
        return Ok(d);
    }
    let n = 30;
    let (lo, hi) = (fs / 1000.0, 0.4 * fs);
    let grid: Vec<f64> = (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect();
    let mut rows = Vec::new();
    let mut best: Option<(f64, Design)> = None;
    for &fc in &grid {
        let d = design(model, fc, options)?;
        let score = if tests.is_empty() {
            if d.noise_gain <= 10.0 {
                -fc
            } else {
                f64::INFINITY
            }
        } else {
            let mut sum = 0.0;
            for t in tests {
                sum += reconstruct(&d, model, t)?.nrmse_u_hat;
            }
            sum / tests.len() as f64
        };
        rows.push(BandwidthRow {
            lowpass_hz: fc,
            nrmse: if tests.is_empty() { f64::NAN } else { score },
            noise_gain: d.noise_gain,
        });
        if score.is_finite() && best.as_ref().is_none_or(|(s, _)| score < *s) {
            best = Some((score, d));
        }
    }
    let Some((best_score, mut d)) = best else {
        return Err(DesignError::NoUsableBandwidth.into());
    };
    if !tests.is_empty() {
        // Refine between the neighbours of the best grid corner (golden-section search on
        // log frequency; the error is smooth and unimodal there).
        let i = grid
            .iter()
            .position(|&f| (f - d.lowpass_hz).abs() < 1e-9 * f)
            .unwrap_or(0);
        let mut a = grid.get(i.saturating_sub(1)).copied().unwrap_or(lo).ln();
        let mut b = grid.get(i + 1).copied().unwrap_or(hi).min(hi).ln();
        let score = |fc: f64| -> Result<(f64, Design)> {
            let d = design(model, fc, options)?;
            let mut sum = 0.0;
            for t in tests {
                sum += reconstruct(&d, model, t)?.nrmse_u_hat;
            }
            Ok((sum / tests.len() as f64, d))
        };
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let mut best_score = best_score;
        for _ in 0..12 {
            let x1 = b - g * (b - a);
            let x2 = a + g * (b - a);
            let (s1, d1) = score(x1.exp())?;
            let (s2, d2) = score(x2.exp())?;
            for (s, dd) in [(s1, d1), (s2, d2)] {
                if s < best_score {
                    best_score = s;
                    d = dd;
                }
            }
            if s1 < s2 {
                b = x2;
            } else {
                a = x1;
            }
        }
    }
    d.bandwidth_selection = if tests.is_empty() {
        "auto: the highest corner with noise gain at most 10 (no test to judge on)".into()
    } else {
        format!(
            "auto: the corner with the lowest mean reconstruction error on {} test(s)",
            tests.len()
        )
    };
    for t in tests {
        d.reconstruction.push(reconstruct(&d, model, t)?);
    }
    d.candidates = rows;
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The FFT search of a long record finds the lag and the error the direct sums find.
    #[test]
    fn aligned_error_of_a_long_record_is_the_direct_search() {
        let n: usize = 200_000;
        let reference: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64;
                (t / 900.0).sin() + 0.3 * (t / 97.0).sin() + if k > 5000 { 1.0 } else { 0.0 }
            })
            .collect();
        let estimate: Vec<f64> = (0..n)
            .map(|k| {
                reference.get(k.wrapping_sub(37)).copied().unwrap_or(0.0)
                    + 1e-3 * (k as f64 * 1.7).sin()
            })
            .collect();
        let lags = 0..=120;
        assert!(121 * (n - 120) > FFT_ALIGNMENT_WORK);
        let (e, lag) = aligned_error(&reference, &estimate, lags.clone());
        let direct = lags
            .map(|l| {
                let sse: f64 = (120..n)
                    .map(|k| (estimate[k] - reference[k - l]).powi(2))
                    .sum();
                (sse, l)
            })
            .fold((f64::INFINITY, 0), |b, x| if x.0 < b.0 { x } else { b });
        assert_eq!(lag, 37);
        assert_eq!(lag, direct.1);
        let (lo, hi) = reference
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        let want = (direct.0 / (n - 120) as f64).sqrt() / (hi - lo);
        assert!((e / want - 1.0).abs() < 1e-12, "{e} against {want}");
    }

    #[test]
    fn lowpass_has_unit_dc_and_minus_3db_at_the_corner() {
        for kind in [LowpassKind::Bessel, LowpassKind::Butterworth] {
            for order in [1, 2, 4, 6] {
                let lp = lowpass(kind, order, 300.0, 10_000.0).unwrap();
                assert!((lp.eval(c(1.0)).norm() - 1.0).abs() < 1e-12);
                let m = lp.eval(unit(300.0, 10_000.0)).norm();
                assert!(
                    (20.0 * m.log10() + 3.0103).abs() < 0.01,
                    "{kind:?} {order}: {m}"
                );
                assert!(lp.poles.iter().all(|p| p.norm() < 1.0));
            }
        }
    }

    #[test]
    fn sections_reproduce_the_zpk() {
        let zpk = Zpk {
            zeros: vec![
                c(0.5),
                Complex::new(0.3, 0.4),
                Complex::new(0.3, -0.4),
                c(-0.9),
            ],
            poles: vec![c(0.8), Complex::new(0.6, 0.7), Complex::new(0.6, -0.7)],
            gain: 2.0,
        };
        let (g, s) = to_sections(&zpk);
        for f in [0.0, 0.01, 0.1, 0.3, 0.49] {
            let z = unit(f, 1.0);
            assert!((cascade_response(g, &s, z) - zpk.eval(z)).norm() < 1e-12);
        }
    }

    #[test]
    fn non_minimum_phase_model_gets_a_stable_accurate_inverse() {
        // B has a zero at 2.1 (non-minimum phase); A a resonance.
        let model = Model {
            fs: 10_000.0,
            delay: 3,
            a: vec![-1.8, 0.85],
            b: vec![-0.05, 0.05 * 2.1],
        };
        let d = design(&model, 500.0, &Options::default()).unwrap();
        assert_eq!(d.reflected_zeros.len(), 1);
        assert!(d.pole_margin > 0.0);
        assert!(
            d.in_band_magnitude_error_db < 0.5,
            "{}",
            d.in_band_magnitude_error_db
        );
        // The direct inverse is refused.
        let direct = Options {
            stabilise: false,
            ..Options::default()
        };
        assert!(design(&model, 500.0, &direct).is_err());
    }

    /// A probe with a tiny gain has no corner whose noise gain is at most 10; the library
    /// asks for a bandwidth in words, the command line names the flag.
    #[test]
    fn no_usable_corner_asks_for_a_bandwidth_without_naming_a_flag() {
        // DC gain 1e-3: the inverse amplifies the noise a thousandfold.
        let model = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-0.5],
            b: vec![0.5e-3],
        };
        let e = design_auto(&model, &[], &Options::default()).unwrap_err();
        assert!(
            matches!(e.stage(), Some(DesignError::NoUsableBandwidth)),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "inverse: no low-pass corner gave a usable compensator (noise gain above 10 \
             everywhere); give a bandwidth"
        );
        assert!(!e.to_string().contains("--"));
        assert_eq!(e.kind(), "numerical");
    }

    #[test]
    fn a_model_that_does_not_pass_a_steady_pressure_cannot_be_inverted() {
        let model = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![-0.5],
            b: vec![0.5, -0.5],
        };
        let e = design(&model, 100.0, &Options::default()).unwrap_err();
        assert!(
            matches!(e.stage(), Some(DesignError::NoSteadyGain)),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "inverse: B(1) = 0: the model does not pass a steady pressure, it cannot be inverted"
        );
        let zero = Model {
            b: vec![0.0, 0.0],
            ..model
        };
        let e = design(&zero, 100.0, &Options::default()).unwrap_err();
        assert_eq!(e.to_string(), "inverse: the model's numerator b is zero");
        assert_eq!(
            DesignError::PoleMargin { margin: 1.5e-6 }.to_string(),
            format!(
                "inverse: the compensator's poles are 1.50e-6 from the unit circle, less than the \
                 required margin {MIN_POLE_MARGIN:.0e}: refusing to export it"
            )
        );
    }
}
