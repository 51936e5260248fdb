//! Time-domain step tests simulated from the physical models: the excitations of real
//! facilities, a reference channel and a probe channel, measurement noise, ADC quantisation,
//! and delays that need not be whole samples.
//!
//! # Method: padded, tapered inverse FFT, then linear convolution
//! The Bergh-Tijdeman response is not rational, so it has no state-space form. It is turned into
//! an impulse response at an internal rate `f_int = oversample × f_s` (default 32×, README 1.6):
//!
//! 1. `H(i2πf)` of the whole probe (line × diaphragm × anti-alias filter × `e^{−sτ_skew}`) is
//!    sampled on the FFT grid `f_k = k f_int/N` and multiplied by a raised-cosine taper from
//!    `0.8 f_int/2` to `f_int/2`, which removes the Gibbs ringing of the cut-off (content above
//!    `0.8 f_int/2` is lost: raise the oversampling if the diaphragm resonance is above it);
//! 2. the inverse FFT gives the periodised impulse response; `N` doubles until the energy in
//!    `[N/2, 7N/8)` is below [`TAIL_ENERGY`] of the total, i.e. until the response has decayed,
//!    so the periodisation (wrap-around) error is below that level (a slow real pole that
//!    outlasts [`MAX_FFT_LENGTH`] at the asked rate halves the oversampling, down to
//!    [`MIN_OVERSAMPLE`]; the rate used is reported). The taps `[0, N/2)` are kept;
//!    the taper's small non-causal part sits in `[7N/8, N)` and is dropped (its energy is
//!    reported as [`ImpulseResponse::noncausal_energy`]);
//! 3. the excitation, evaluated analytically on the internal grid and starting with a pre-roll
//!    as long as the impulse response (so the system is in its steady state when the record
//!    starts, even under a periodic excitation), is convolved *linearly* with the taps by a
//!    zero-padded FFT (never circularly: a plain inverse FFT of `H(f)U(f)` would wrap the step
//!    around the record);
//! 4. both channels are sampled every `oversample`-th internal sample, then noise and ADC
//!    quantisation are added.
//!
//! The error of the method is measured in the host tests (`host-tests/physics.rs`): against
//! the closed-form step response of a second-order system with a delay of 7.37 internal samples
//! (max error 2.8e-5 of the step), against the exact Bergh-Tijdeman step response from its poles
//! and residues (1.8e-4 after seven front delays, where the check's own truncation to eight
//! modes dominates; 9e-7 after 25 ms), and for causality (below 1e-10 of the step before the
//! front).
//!
//! This module owns the excitations ([`Excitation`]), the probe as a whole ([`Probe`]), the
//! acquisition settings ([`Acquisition`], with the ADC policy [`Quantisation`]), the impulse
//! response ([`impulse_response`]) and the simulated test ([`simulate`]).

use num_complex::Complex64;

use super::fft::{convolve, fft_in_place};
use super::gas::Gas;
use super::line::Line;
use super::sensor::{Butterworth, Diaphragm};
use super::PhysicsError;
use crate::error::{Error, Result};

mod band;
mod csv;
mod excitation;
pub use band::{ReducedRate, ResonanceAboveBand};
pub use excitation::{
    Excitation, Facility, FacilitySettings, BALLOON_FALL_S, SHOCK_RISE_S, TUNNEL_FRACTION,
    VALVE_CHAMBER, VALVE_OPENING_S,
};

/// Lowest oversampling [`simulate`] falls back to when the response outlasts the longest FFT
/// at the asked one.
pub const MIN_OVERSAMPLE: usize = 4;

/// Relative energy of the impulse response allowed in `[N/2, 7N/8)` of the FFT buffer.
pub const TAIL_ENERGY: f64 = 1e-14;

/// Largest FFT length tried for an impulse response (`2^22`).
pub const MAX_FFT_LENGTH: usize = 1 << 22;

/// The taper starts at this fraction of the internal Nyquist frequency.
pub const TAPER_START: f64 = 0.8;

/// The physical probe: a line (tubes, holes, cavities) in a gas, the transducer's diaphragm,
/// the DAQ's anti-alias filter and an extra delay of the probe channel (timing skew).
#[derive(Debug, Clone, PartialEq)]
pub struct Probe {
    /// Tubes, volumes, series impedances from the measuring point to the transducer.
    pub line: Line,
    /// The gas at its mean temperature and pressure.
    pub gas: Gas,
    /// Diaphragm resonance of the transducer, if modelled.
    pub diaphragm: Option<Diaphragm>,
    /// Analog anti-alias filter of the acquisition (applied to both channels), if any.
    pub anti_alias: Option<Butterworth>,
    /// Extra delay of the probe channel \[s\] (timing skew; may be any fraction of a sample).
    pub skew_s: f64,
}

impl Probe {
    /// A probe that is only `line` in `gas`.
    #[must_use]
    pub fn new(line: Line, gas: Gas) -> Self {
        Self {
            line,
            gas,
            diaphragm: None,
            anti_alias: None,
            skew_s: 0.0,
        }
    }

    /// Checks line, gas, diaphragm, filter and skew.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        self.gas.validate()?;
        self.line.validate()?;
        if let Some(d) = &self.diaphragm {
            d.validate()?;
        }
        if let Some(b) = &self.anti_alias {
            b.validate()?;
        }
        if !(self.skew_s.is_finite() && self.skew_s >= 0.0) {
            return Err(Error::InvalidArgument {
                what: "skew",
                message: format!("{} s must be finite and non-negative", self.skew_s),
            });
        }
        Ok(())
    }

    /// Response `p_probe/p_in` [-] at complex frequency `s` [rad/s].
    #[must_use]
    pub fn response(&self, s: Complex64) -> Complex64 {
        let mut h = self.line.response(&self.gas, s);
        if let Some(d) = &self.diaphragm {
            h *= d.response(s);
        }
        if let Some(b) = &self.anti_alias {
            h *= b.response(s);
        }
        if self.skew_s > 0.0 {
            h *= (-s * self.skew_s).exp();
        }
        h
    }
}

/// An ADC: `bits` over `[min_pa, max_pa]`, rounding to the nearest level and clipping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Adc {
    /// Resolution \[bits\] (1..=32).
    pub bits: u32,
    /// Lowest level \[Pa\].
    pub min_pa: f64,
    /// Highest level \[Pa\].
    pub max_pa: f64,
}

impl Adc {
    /// Checks the resolution and range.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        let range_ok =
            self.min_pa.is_finite() && self.max_pa.is_finite() && self.max_pa > self.min_pa;
        if !((1..=32).contains(&self.bits) && range_ok) {
            return Err(Error::InvalidArgument {
                what: "ADC",
                message: format!(
                    "{} bits over [{}, {}] Pa: need 1..=32 bits and min < max",
                    self.bits, self.min_pa, self.max_pa
                ),
            });
        }
        Ok(())
    }

    /// Step between levels \[Pa\].
    #[must_use]
    pub fn lsb_pa(&self) -> f64 {
        (self.max_pa - self.min_pa) / 2f64.powi(i32::try_from(self.bits).unwrap_or(32))
    }

    /// `x` \[Pa\] quantised and clipped to the range.
    #[must_use]
    pub fn quantise(&self, x: f64) -> f64 {
        let q = self.lsb_pa();
        let levels = 2f64.powi(i32::try_from(self.bits).unwrap_or(32)) - 1.0;
        let k = ((x - self.min_pa) / q).round().clamp(0.0, levels);
        self.min_pa + k * q
    }

    /// A `bits` ADC over the range of `signals` widened by [`ADC_RANGE_MARGIN`] of their span
    /// on each side (a span below 1e-9 Pa counts as 1e-9 Pa). Not validated.
    #[must_use]
    pub fn spanning(bits: u32, signals: &[&[f64]]) -> Self {
        let all = signals.iter().flat_map(|s| s.iter().copied());
        let lo = all.clone().fold(f64::INFINITY, f64::min);
        let hi = all.fold(f64::NEG_INFINITY, f64::max);
        let span = (hi - lo).max(1e-9);
        Self {
            bits,
            min_pa: lo - ADC_RANGE_MARGIN * span,
            max_pa: hi + ADC_RANGE_MARGIN * span,
        }
    }
}

/// Margin of an ADC range taken from the signals ([`Quantisation::FromSignals`]), as a
/// fraction of their span on each side.
pub const ADC_RANGE_MARGIN: f64 = 0.1;

/// How both channels are quantised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Quantisation {
    /// By this ADC.
    Fixed(Adc),
    /// By a `bits` ADC over the range of both recorded channels (noise and probe-channel
    /// errors included) plus [`ADC_RANGE_MARGIN`] of their span each side ([`Adc::spanning`]);
    /// the ADC is checked once its range is known.
    FromSignals {
        /// Resolution \[bits\] (1..=32).
        bits: u32,
    },
}

impl From<Adc> for Quantisation {
    fn from(adc: Adc) -> Self {
        Self::Fixed(adc)
    }
}

/// How the step test is recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Acquisition {
    /// Sample rate `f_s` \[Hz\].
    pub sample_rate_hz: f64,
    /// Record length \[s\].
    pub duration_s: f64,
    /// Time of the event after the record starts \[s\] (need not be on a sample).
    pub event_time_s: f64,
    /// Internal rate as a multiple of `f_s` (README: 32).
    pub oversample: usize,
    /// Standard deviation of the white noise on the probe channel \[Pa\].
    pub probe_noise_pa: f64,
    /// Standard deviation of the white noise on the reference channel \[Pa\].
    pub reference_noise_pa: f64,
    /// ADC of both channels, if quantised.
    pub adc: Option<Quantisation>,
    /// The reference transducer's own resonance, if modelled.
    pub reference_sensor: Option<Diaphragm>,
    /// Seed of the noise generator.
    pub seed: u64,
    /// Static gain error of the probe channel [-] (`y → (1 + e) y`; 0: none).
    pub probe_gain_error: f64,
    /// Mains hum on the probe channel: amplitude \[Pa\] (0: none) ...
    pub hum_pa: f64,
    /// ... and frequency \[Hz\].
    pub hum_hz: f64,
    /// Zero drift of the probe channel after the event [Pa/s] (a ramp; 0: none).
    pub drift_pa_per_s: f64,
}

impl Acquisition {
    /// Where the event falls when no time is given, as a fraction of the record: at 10 %,
    /// leaving a stretch before it for the level and the noise to be measured on.
    pub const DEFAULT_EVENT_FRACTION: f64 = 0.1;

    /// No mains hum, as (amplitude \[Pa\], frequency \[Hz\]): amplitude 0, at the 50 Hz of
    /// the mains (without effect at zero amplitude).
    pub const NO_HUM: (f64, f64) = (0.0, 50.0);

    /// The event's time \[s\] in a record of `duration_s` when none is given
    /// ([`Self::DEFAULT_EVENT_FRACTION`] of it).
    #[must_use]
    pub fn default_event_time_s(duration_s: f64) -> f64 {
        Self::DEFAULT_EVENT_FRACTION * duration_s
    }

    /// `duration_s` at `sample_rate_hz`, event at [`Self::DEFAULT_EVENT_FRACTION`] of the
    /// record, 32× oversampling, no noise, no ADC, ideal reference sensor, no hum.
    #[must_use]
    pub fn new(sample_rate_hz: f64, duration_s: f64) -> Self {
        Self {
            sample_rate_hz,
            duration_s,
            event_time_s: Self::default_event_time_s(duration_s),
            oversample: 32,
            probe_noise_pa: 0.0,
            reference_noise_pa: 0.0,
            adc: None,
            reference_sensor: None,
            seed: 1,
            probe_gain_error: 0.0,
            hum_pa: Self::NO_HUM.0,
            hum_hz: Self::NO_HUM.1,
            drift_pa_per_s: 0.0,
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        let bad =
            |what: &'static str, message: String| Err(Error::InvalidArgument { what, message });
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return bad(
                "sample rate",
                format!("{} Hz must be positive", self.sample_rate_hz),
            );
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return bad(
                "duration",
                format!("{} s must be positive", self.duration_s),
            );
        }
        let samples = self.duration_s * self.sample_rate_hz;
        if !(2.0..=1e7).contains(&samples) {
            return bad(
                "duration",
                format!("{samples:.0} samples: need 2 to 10 million"),
            );
        }
        if !(1..=256).contains(&self.oversample) || samples * self.oversample as f64 > 2e8 {
            return bad(
                "oversample",
                format!(
                    "{} must be 1..=256 and the internal record at most 2e8 samples",
                    self.oversample
                ),
            );
        }
        if !(self.event_time_s.is_finite()
            && self.event_time_s >= 0.0
            && self.event_time_s < self.duration_s)
        {
            return bad(
                "event time",
                format!(
                    "{} s must be inside the record [0, {}) s",
                    self.event_time_s, self.duration_s
                ),
            );
        }
        let noise_ok = [self.probe_noise_pa, self.reference_noise_pa]
            .iter()
            .all(|x| x.is_finite() && *x >= 0.0);
        if !noise_ok {
            return bad("noise", "must be finite and non-negative".into());
        }
        if let Some(Quantisation::Fixed(a)) = &self.adc {
            a.validate()?;
        }
        let errors_ok = [self.probe_gain_error, self.hum_pa, self.drift_pa_per_s]
            .iter()
            .all(|x| x.is_finite())
            && self.hum_hz.is_finite()
            && self.hum_hz > 0.0
            && self.probe_gain_error > -1.0;
        if !errors_ok {
            return bad(
                "probe channel errors",
                format!(
                    "gain error {} (> -1), hum {} Pa at {} Hz (> 0), drift {} Pa/s must be finite",
                    self.probe_gain_error, self.hum_pa, self.hum_hz, self.drift_pa_per_s
                ),
            );
        }
        if let Some(d) = &self.reference_sensor {
            d.validate()?;
        }
        Ok(())
    }
}

/// A sampled impulse response: `y[n] = Σ taps[k] u[n−k]` at `rate_hz`.
#[derive(Debug, Clone, PartialEq)]
pub struct ImpulseResponse {
    /// Sample rate \[Hz\].
    pub rate_hz: f64,
    /// Taps (the impulse response times the sample interval) [-].
    pub taps: Vec<f64>,
    /// FFT length used.
    pub fft_length: usize,
    /// Energy in `[N/2, 7N/8)` relative to the total: bounds the wrap-around error.
    pub tail_energy: f64,
    /// Energy in `[7N/8, N)` relative to the total: the taper's non-causal part, dropped.
    pub noncausal_energy: f64,
    /// Start of the raised-cosine taper \[Hz\].
    pub taper_start_hz: f64,
}

/// The impulse response of `response(s)` at `rate_hz`, by padded, tapered inverse FFT (see the
/// module documentation), at least `min_taps` long.
///
/// # Errors
/// [`PhysicsError::ResponseNotFinite`] if the response is not finite on the frequency grid,
/// [`PhysicsError::NoDecay`] if it does not decay within [`MAX_FFT_LENGTH`] samples.
pub fn impulse_response(
    response: &dyn Fn(Complex64) -> Complex64,
    rate_hz: f64,
    min_taps: usize,
) -> Result<ImpulseResponse> {
    let nyquist = 0.5 * rate_hz;
    let taper_start = TAPER_START * nyquist;
    let taper = |f: f64| {
        if f <= taper_start {
            1.0
        } else {
            0.5 * (1.0
                + (core::f64::consts::PI * (f - taper_start) / (nyquist - taper_start)).cos())
        }
    };
    let mut n = (2 * min_taps).max(1024).next_power_of_two();
    loop {
        let half: Vec<Complex64> = (0..=n / 2)
            .map(|k| {
                let f = k as f64 * rate_hz / n as f64;
                let h = response(Complex64::new(0.0, 2.0 * core::f64::consts::PI * f));
                if k == n / 2 {
                    Complex64::new(0.0, 0.0) // the taper is zero at Nyquist
                } else {
                    h * taper(f)
                }
            })
            .collect();
        if let Some((k, _)) = half.iter().enumerate().find(|(_, h)| !h.is_finite()) {
            return Err(PhysicsError::ResponseNotFinite {
                frequency_hz: k as f64 * rate_hz / n as f64,
            }
            .into());
        }
        let mut spec: Vec<Complex64> = half
            .iter()
            .copied()
            .chain(
                half.iter()
                    .skip(1)
                    .take(n / 2 - 1)
                    .rev()
                    .map(Complex64::conj),
            )
            .collect();
        fft_in_place(&mut spec, true)?;
        let energy = |from: usize, to: usize| -> f64 {
            spec.iter()
                .skip(from)
                .take(to - from)
                .map(|c| c.re * c.re)
                .sum()
        };
        let total = energy(0, n);
        let tail = energy(n / 2, n - n / 8) / total.max(f64::MIN_POSITIVE);
        let noncausal = energy(n - n / 8, n) / total.max(f64::MIN_POSITIVE);
        if tail < TAIL_ENERGY {
            return Ok(ImpulseResponse {
                rate_hz,
                taps: spec.iter().take(n / 2).map(|c| c.re).collect(),
                fft_length: n,
                tail_energy: tail,
                noncausal_energy: noncausal,
                taper_start_hz: taper_start,
            });
        }
        n *= 2;
        if n > MAX_FFT_LENGTH {
            return Err(PhysicsError::NoDecay {
                seconds: (MAX_FFT_LENGTH / 2) as f64 / rate_hz,
                rate_hz,
            }
            .into());
        }
    }
}

/// The unit step response of `probe` sampled at `rate_hz` \[Hz\], `n` samples from `t = 0`
/// (the step at `t = 0`), by [`impulse_response`]. The step is sampled by cell averages, as in
/// [`simulate`] (the first sample of the step is 1/2): `y[k] = Σ_{j<k} h[j] + h[k]/2`.
///
/// # Errors
/// As [`impulse_response`], and [`Probe::validate`].
pub fn step_response(probe: &Probe, rate_hz: f64, n: usize) -> Result<Vec<f64>> {
    probe.validate()?;
    let ir = impulse_response(&|s| probe.response(s), rate_hz, 0)?;
    let dc = probe.response(Complex64::new(0.0, 0.0)).re;
    let mut acc = 0.0;
    Ok((0..n)
        .map(|k| match ir.taps.get(k) {
            Some(h) => {
                acc += h;
                acc - 0.5 * h
            }
            None => dc,
        })
        .collect())
}

/// A simulated step test.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedTest {
    /// Sample times \[s\] from the record start.
    pub t: Vec<f64>,
    /// Reference channel \[Pa\] (the excitation through the reference sensor, with noise and ADC).
    pub reference: Vec<f64>,
    /// Probe channel \[Pa\] (with noise and ADC).
    pub probe: Vec<f64>,
    /// The excitation itself at the sample times \[Pa\].
    pub excitation: Vec<f64>,
    /// Probe channel without noise and ADC \[Pa\].
    pub probe_clean: Vec<f64>,
    /// The probe's impulse response used, with its error measures.
    pub impulse: ImpulseResponse,
    /// The ADC that quantised both channels, if any (its range resolved).
    pub adc: Option<Adc>,
}

impl SimulatedTest {
    /// Quantises both channels (noise included) as `quantisation` says and records the ADC
    /// in [`Self::adc`]; for a test simulated without an ADC ([`simulate`] calls it when the
    /// acquisition has one).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an invalid ADC (for [`Quantisation::FromSignals`], with
    /// the range taken from the signals).
    pub fn quantise(&mut self, quantisation: Quantisation) -> Result<Adc> {
        let adc = match quantisation {
            Quantisation::Fixed(adc) => adc,
            Quantisation::FromSignals { bits } => {
                Adc::spanning(bits, &[&self.reference, &self.probe])
            }
        };
        adc.validate()?;
        for v in self.reference.iter_mut().chain(self.probe.iter_mut()) {
            *v = adc.quantise(*v);
        }
        self.adc = Some(adc);
        Ok(adc)
    }
}

/// A deterministic Gaussian noise source (SplitMix64 and Box-Muller).
#[derive(Debug, Clone)]
struct Noise {
    state: u64,
}

impl Noise {
    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn gauss(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (2.0 * core::f64::consts::PI * u2).cos()
    }
}

/// Output of a linear system with impulse response `ir` to the input `u` (which is taken to be
/// constant at `u[0]` before it starts), with DC gain `dc`.
fn filter_from_rest(ir: &ImpulseResponse, dc: f64, u: &[f64]) -> Result<Vec<f64>> {
    let u0 = u.first().copied().unwrap_or(0.0);
    let du: Vec<f64> = u.iter().map(|v| v - u0).collect();
    let mut y = convolve(&ir.taps, &du, u.len())?;
    for v in &mut y {
        *v += dc * u0;
    }
    Ok(y)
}

/// Simulates a step test of `probe` under `excitation`, recorded as `acquisition` says.
///
/// # Errors
/// [`Error::InvalidArgument`] for invalid settings; errors of [`impulse_response`].
pub fn simulate(
    probe: &Probe,
    excitation: &Excitation,
    acquisition: &Acquisition,
) -> Result<SimulatedTest> {
    probe.validate()?;
    excitation.validate()?;
    acquisition.validate()?;
    let fs = acquisition.sample_rate_hz;
    let n_rec = (acquisition.duration_s * fs).round().max(2.0) as usize;
    // A slow real pole (series lines, a leak) can outlast the longest FFT at the asked
    // internal rate: the oversampling is halved (to at least MIN_OVERSAMPLE) until the
    // response decays within it. The rate used is in the result's `impulse.rate_hz`.
    let mut over = acquisition.oversample;
    let mut min_taps = 0;
    let ir = loop {
        match impulse_response(&|s| probe.response(s), fs * over as f64, min_taps) {
            Ok(ir) => break ir,
            Err(_) if over / 2 >= MIN_OVERSAMPLE => {
                over /= 2;
                // The shorter lengths failed already at the higher rate: start near the top.
                min_taps = MAX_FFT_LENGTH / 4;
            }
            Err(e) => return Err(e),
        }
    };
    let rate = fs * over as f64;
    let dc = probe.response(Complex64::new(0.0, 0.0)).re;
    // The reference channel: the excitation through the reference sensor and the same
    // anti-alias filter.
    let reference_response = |s: Complex64| {
        let mut h = Complex64::new(1.0, 0.0);
        if let Some(d) = &acquisition.reference_sensor {
            h *= d.response(s);
        }
        if let Some(b) = &probe.anti_alias {
            h *= b.response(s);
        }
        h
    };
    let ir_ref = if acquisition.reference_sensor.is_some() || probe.anti_alias.is_some() {
        Some(impulse_response(&reference_response, rate, 0)?)
    } else {
        None
    };
    let pre = ir
        .taps
        .len()
        .max(ir_ref.as_ref().map_or(0, |r| r.taps.len()));
    let n_int = pre + n_rec * over;
    let u_int: Vec<f64> = (0..n_int)
        .map(|i| {
            let t = (i as f64 - pre as f64) / rate;
            excitation.cell_average(t - acquisition.event_time_s, 1.0 / rate)
        })
        .collect();
    let y_int = filter_from_rest(&ir, dc, &u_int)?;
    let r_int = match &ir_ref {
        Some(r) => filter_from_rest(r, 1.0, &u_int)?,
        None => u_int.clone(),
    };
    let pick = |x: &[f64]| -> Vec<f64> {
        x.iter()
            .skip(pre)
            .step_by(over)
            .take(n_rec)
            .copied()
            .collect()
    };
    let probe_clean = pick(&y_int);
    let reference_clean = pick(&r_int);
    let excitation_samples = pick(&u_int);
    let mut noise = Noise {
        state: acquisition.seed,
    };
    let mut add_noise = |x: &[f64], sigma: f64| -> Vec<f64> {
        x.iter()
            .map(|&v| {
                if sigma > 0.0 {
                    v + sigma * noise.gauss()
                } else {
                    v
                }
            })
            .collect()
    };
    let reference = add_noise(&reference_clean, acquisition.reference_noise_pa);
    // Additive and static errors of the probe channel, before noise and ADC.
    let event = acquisition.event_time_s;
    let with_errors: Vec<f64> = probe_clean
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let t = k as f64 / fs;
            let hum =
                acquisition.hum_pa * (2.0 * core::f64::consts::PI * acquisition.hum_hz * t).sin();
            let drift = acquisition.drift_pa_per_s * (t - event).max(0.0);
            (1.0 + acquisition.probe_gain_error) * v + hum + drift
        })
        .collect();
    let probe_out = add_noise(&with_errors, acquisition.probe_noise_pa);
    let mut test = SimulatedTest {
        t: (0..n_rec).map(|k| k as f64 / fs).collect(),
        reference,
        probe: probe_out,
        excitation: excitation_samples,
        probe_clean,
        impulse: ir,
        adc: None,
    };
    if let Some(q) = acquisition.adc {
        test.quantise(q)?;
    }
    Ok(test)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adc_quantises_and_clips() {
        let adc = Adc {
            bits: 3,
            min_pa: 0.0,
            max_pa: 8.0,
        };
        assert_eq!(adc.lsb_pa(), 1.0);
        assert_eq!(adc.quantise(2.4), 2.0);
        assert_eq!(adc.quantise(2.6), 3.0);
        assert_eq!(adc.quantise(100.0), 7.0);
        assert_eq!(adc.quantise(-5.0), 0.0);
    }

    #[test]
    fn adc_range_from_the_signals_has_a_margin() {
        let adc = Adc::spanning(8, &[&[0.0, 1.0], &[-1.0, 9.0]]);
        assert_eq!((adc.min_pa, adc.max_pa), (-2.0, 10.0));
        let flat = Adc::spanning(8, &[&[3.0]]);
        assert!(flat.max_pa > flat.min_pa);
    }

    #[test]
    fn noise_is_standard_normal() {
        let mut n = Noise { state: 7 };
        let x: Vec<f64> = (0..20_000).map(|_| n.gauss()).collect();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }

    #[test]
    fn excitation_levels() {
        let b = Excitation::balloon(1000.0);
        assert_eq!(b.value(-1.0), 1000.0);
        assert_eq!(b.value(1.0), 0.0);
        assert!((b.value(350e-6) - 500.0).abs() < 1e-9);
        let s = Excitation::shock_tube(1.0);
        assert_eq!(s.value(0.0), 0.0);
        assert_eq!(s.value(2e-6), 1.0);
    }
}
