//! What a model says about the probe: poles and zeros, stability and minimum-phase verdicts with
//! their margins, DC gain, resonances, delay, and the frequency response (the paper's eq. 6).
//!
//! This module owns [`Analysis`] (everything computed once from a [`Model`], serialisable to
//! JSON for `unlag inspect --json`) and the frequency response: [`frequency_response`], its
//! points in dB and degrees ([`response_points`]) and the default grid
//! ([`default_frequencies`]). It does not own the
//! continuous-time equivalent with its residues and fractional delay: that is
//! [`crate::fit::continuous`].
//!
//! # Conventions
//!
//! The model is `y[k] = sum_{i=0..m} b[i] u[k-i-d] - sum_{i=1..m} a[i] y[k-i]`, so
//! `H(z) = z^-d B(z^-1) / A(z^-1)` with `A = 1 + a1 z^-1 + ... + am z^-m`. Each discrete pole `p`
//! is mapped to the continuous-time pole `s = fs ln p` (principal logarithm); a resonance's
//! natural frequency is `|s| / 2 pi` and its damping `-Re(s) / |s|`. A pole on the negative real
//! axis has no continuous-time equivalent (its sequence alternates in sign every sample): it is
//! reported as oscillating at Nyquist, never as NaN.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fit::model::Model;
use crate::poly::{self, Complex};
use crate::trace::unit::{duration, hz, significant};

/// Poles closer to the origin than this are reported as poles at `z = 0` (a pure FIR part).
pub const ORIGIN_RADIUS: f64 = 1e-9;

/// A pole with `|Im p| <= REAL_AXIS_TOLERANCE * |p|` is treated as real.
pub const REAL_AXIS_TOLERANCE: f64 = 1e-10;

/// A complex number in a serialisable form, with its magnitude.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Root {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
    /// Magnitude `|z|`.
    pub magnitude: f64,
}

impl From<Complex> for Root {
    fn from(z: Complex) -> Self {
        Self {
            re: z.re,
            im: z.im,
            magnitude: z.norm(),
        }
    }
}

/// What one pole (or complex pole pair) of the model means in continuous time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ModeKind {
    /// A complex pole pair: a resonance.
    Resonance {
        /// Natural frequency `|s| / 2 pi` in Hz.
        natural_frequency_hz: f64,
        /// Damping ratio `-Re(s) / |s|` (negative for an unstable pair).
        damping: f64,
        /// Damped (ringing) frequency `Im(s) / 2 pi` in Hz.
        damped_frequency_hz: f64,
        /// Continuous-time pole `s = fs ln p` (the one with `Im s > 0`), real part in 1/s.
        s_re: f64,
        /// Imaginary part of `s` in rad/s.
        s_im: f64,
    },
    /// A real pole on the positive axis: a first-order lag (or growth, when `p > 1`).
    Real {
        /// Continuous-time pole `s = fs ln p` in 1/s.
        s_re: f64,
        /// Time constant `-1 / s` in seconds: positive for a decaying pole, negative for a
        /// growing one, `None` for `p = 1` (an integrator).
        time_constant_s: Option<f64>,
    },
    /// A real pole on the negative axis: it alternates in sign every sample, so it oscillates
    /// at Nyquist and has no continuous-time equivalent.
    Nyquist {
        /// The Nyquist frequency `fs / 2` in Hz.
        frequency_hz: f64,
        /// Time constant of its envelope `-1 / (fs ln |p|)` in seconds (`None` for `|p| = 1`).
        envelope_time_constant_s: Option<f64>,
    },
    /// A pole at `z = 0`: a finite-impulse-response part, no continuous-time equivalent.
    Origin,
}

/// One pole, or one complex pole pair, and its continuous-time meaning.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mode {
    /// The discrete pole (for a pair, the one with positive imaginary part).
    pub pole: Root,
    /// What it is.
    #[serde(flatten)]
    pub kind: ModeKind,
    /// One line for people, e.g. `resonance 95.00 Hz, damping 0.120`.
    pub description: String,
}

/// Everything computed once from a model (see the module documentation for the conventions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Analysis {
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Model order `m`.
    pub order: usize,
    /// Delay `d` in samples.
    pub delay_samples: usize,
    /// Delay `d / fs` in seconds.
    pub delay_s: f64,
    /// Poles (roots of `A`), largest magnitude first.
    pub poles: Vec<Root>,
    /// Zeros (roots of `B`, without the delay's zeros at the origin), largest magnitude first.
    pub zeros: Vec<Root>,
    /// Whether every pole is strictly inside the unit circle.
    pub stable: bool,
    /// `1 - max |pole|` (1 without poles); negative when unstable.
    pub stability_margin: f64,
    /// Whether every zero is strictly inside the unit circle (the direct inverse `A/B` is
    /// then stable).
    pub minimum_phase: bool,
    /// `1 - max |zero|` (1 without zeros); negative when non-minimum-phase.
    pub minimum_phase_margin: f64,
    /// Steady-state gain `sum b / (1 + sum a)`.
    pub dc_gain: f64,
    /// `dc_gain - 1`: how far the model is from a calibrated transducer (the paper: 1).
    pub dc_gain_deviation: f64,
    /// One entry per real pole and per complex pole pair, in the order of [`Self::poles`].
    pub modes: Vec<Mode>,
}

impl Analysis {
    /// Each resonance (complex pole pair) as `(natural frequency in Hz, damping)`, in the
    /// order of [`Self::modes`].
    #[must_use]
    pub fn resonance_pairs(&self) -> Vec<(f64, f64)> {
        self.resonances()
            .filter_map(|m| match m.kind {
                ModeKind::Resonance {
                    natural_frequency_hz,
                    damping,
                    ..
                } => Some((natural_frequency_hz, damping)),
                _ => None,
            })
            .collect()
    }

    /// Analyses `model`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a model with a non-positive sample rate, non-finite
    /// coefficients or an empty `b`; [`crate::poly::PolyError`] if the eigenvalue solver fails.
    pub fn new(model: &Model) -> Result<Self> {
        validate(model)?;
        let fs = model.fs;
        let poles = model.poles()?;
        let zeros = if model.b.iter().all(|&c| c == 0.0) {
            Vec::new()
        } else {
            model.zeros()?
        };
        let max_pole = poles.first().map_or(0.0, |p| p.norm());
        let max_zero = zeros.first().map_or(0.0, |z| z.norm());
        let dc_gain = model.dc_gain();
        let modes = poles
            .iter()
            .filter(|p| p.im >= -REAL_AXIS_TOLERANCE * p.norm())
            .map(|&p| mode(p, fs))
            .collect();
        Ok(Self {
            sample_rate_hz: fs,
            order: model.order(),
            delay_samples: model.delay,
            delay_s: model.delay as f64 / fs,
            poles: poles.iter().copied().map(Root::from).collect(),
            zeros: zeros.iter().copied().map(Root::from).collect(),
            stable: max_pole < 1.0,
            stability_margin: 1.0 - max_pole,
            minimum_phase: max_zero < 1.0,
            minimum_phase_margin: 1.0 - max_zero,
            dc_gain,
            dc_gain_deviation: dc_gain - 1.0,
            modes,
        })
    }

    /// The resonances only (complex pole pairs).
    pub fn resonances(&self) -> impl Iterator<Item = &Mode> {
        self.modes
            .iter()
            .filter(|m| matches!(m.kind, ModeKind::Resonance { .. }))
    }
}

/// Rejects models no analysis can make sense of.
pub(crate) fn validate(model: &Model) -> Result<()> {
    let bad = |message: String| Error::InvalidArgument {
        what: "model",
        message,
    };
    if !(model.fs.is_finite() && model.fs > 0.0) {
        return Err(bad(format!(
            "the sample rate must be a positive number of Hz, not {}",
            model.fs
        )));
    }
    if model.b.is_empty() {
        return Err(bad("b is empty".into()));
    }
    if model.a.iter().chain(&model.b).any(|c| !c.is_finite()) {
        return Err(bad("a coefficient in a or b is not finite".into()));
    }
    Ok(())
}

fn mode(p: Complex, fs: f64) -> Mode {
    let r = p.norm();
    let tc = |s: f64| (s != 0.0).then(|| -1.0 / s);
    let (kind, description) = if r < ORIGIN_RADIUS {
        (
            ModeKind::Origin,
            "pole at z = 0: a finite-impulse-response part, no continuous-time equivalent".into(),
        )
    } else if p.im.abs() <= REAL_AXIS_TOLERANCE * r {
        if p.re > 0.0 {
            let s = fs * p.re.ln();
            let t = tc(s);
            let text = match t {
                Some(t) if t > 0.0 => format!("real pole, time constant {}", duration(t)),
                Some(t) => format!(
                    "real pole outside the unit circle, grows with time constant {}",
                    duration(-t)
                ),
                None => "real pole at z = 1: an integrator".into(),
            };
            (
                ModeKind::Real {
                    s_re: s,
                    time_constant_s: t,
                },
                text,
            )
        } else {
            let t = tc(fs * r.ln());
            let envelope = t.map_or_else(
                || "constant envelope".to_string(),
                |t| format!("envelope time constant {}", duration(t)),
            );
            (
                ModeKind::Nyquist {
                    frequency_hz: fs / 2.0,
                    envelope_time_constant_s: t,
                },
                format!(
                    "negative real pole: oscillates at Nyquist ({}), no continuous-time equivalent; {envelope}",
                    hz(fs / 2.0)
                ),
            )
        }
    } else {
        // Upper member of a complex pair: s = fs (ln|p| + j arg p).
        let s = Complex::new(fs * r.ln(), fs * p.im.atan2(p.re));
        let wn = s.norm();
        let fn_hz = wn / (2.0 * std::f64::consts::PI);
        let zeta = -s.re / wn;
        (
            ModeKind::Resonance {
                natural_frequency_hz: fn_hz,
                damping: zeta,
                damped_frequency_hz: s.im / (2.0 * std::f64::consts::PI),
                s_re: s.re,
                s_im: s.im,
            },
            format!("resonance {}, damping {}", hz(fn_hz), significant(zeta)),
        )
    };
    Mode {
        pole: Root::from(p),
        kind,
        description,
    }
}

/// The model's complex frequency response at `f_hz` (the paper's eq. 6, delay included):
/// `H = (l1 + j l2) / (h1 + j h2)` with `l = sum b_i e^{-j w (i + d)}`,
/// `h = 1 + sum a_i e^{-j w i}`, `w = 2 pi f / fs`.
#[must_use]
pub fn response(model: &Model, f_hz: f64) -> Complex {
    let w = 2.0 * std::f64::consts::PI * f_hz / model.fs;
    let z = Complex::new(w.cos(), w.sin());
    let num = poly::eval(&model.b, z) * Complex::new(0.0, -w * model.delay as f64).exp();
    num / poly::eval(&model.denominator(), z)
}

/// Magnitude and phase (radians) of the model at each frequency in `freqs_hz` (the paper's
/// eq. 6, the delay's `-2 pi f d / fs` included).
///
/// The phase is unwrapped exactly, independently of how coarse the grid is: it is the
/// continuous phase along the unit circle from 0 Hz, built from the phase of each pole and zero
/// factor (so a resonance between two grid points cannot cause a 2 pi slip), and is 0 at 0 Hz
/// for a positive DC gain. Magnitude and the phase modulo 2 pi come from the direct evaluation
/// of eq. 6. If the roots cannot be computed, the phase is unwrapped along the grid instead.
#[must_use]
pub fn frequency_response(model: &Model, freqs_hz: &[f64]) -> Vec<(f64, f64)> {
    let values: Vec<Complex> = freqs_hz.iter().map(|&f| response(model, f)).collect();
    let tau = 2.0 * std::f64::consts::PI;
    let near =
        |principal: f64, estimate: f64| principal + tau * ((estimate - principal) / tau).round();
    match Factored::new(model) {
        Some(factored) => {
            let offset = tau * (factored.phase(0.0) / tau).round();
            freqs_hz
                .iter()
                .zip(&values)
                .map(|(&f, h)| {
                    let w = tau * f / model.fs;
                    (h.norm(), near(h.arg(), factored.phase(w) - offset))
                })
                .collect()
        }
        None => {
            let mut previous: Option<f64> = None;
            values
                .iter()
                .map(|h| {
                    let phase = previous.map_or(h.arg(), |p| near(h.arg(), p));
                    previous = Some(phase);
                    (h.norm(), phase)
                })
                .collect()
        }
    }
}

/// `H` as `lead * z^-(d + shift) * prod (1 - z_i z^-1) / prod (1 - p_i z^-1)`, for the phase.
struct Factored {
    lead_negative: bool,
    delay: f64,
    zeros: Vec<Complex>,
    poles: Vec<Complex>,
}

impl Factored {
    fn new(model: &Model) -> Option<Self> {
        let shift = model.b.iter().position(|&c| c != 0.0)?;
        let lead = model.b.get(shift).copied()?;
        Some(Self {
            lead_negative: lead < 0.0,
            delay: (model.delay + shift) as f64,
            zeros: poly::roots(&model.b).ok()?,
            poles: model.poles().ok()?,
        })
    }

    /// Continuous phase of `H(e^{jw})` in `w`, up to a constant multiple of `2 pi`.
    fn phase(&self, w: f64) -> f64 {
        let lead = if self.lead_negative {
            std::f64::consts::PI
        } else {
            0.0
        };
        let zeros: f64 = self.zeros.iter().map(|&r| factor_phase(r, w)).sum();
        let poles: f64 = self.poles.iter().map(|&r| factor_phase(r, w)).sum();
        lead - w * self.delay + zeros - poles
    }
}

/// Continuous phase of `1 - r e^{-jw}` in `w`. Inside the unit circle the factor never leaves
/// the right half plane; outside it winds once per turn:
/// `1 - r e^{-jw} = -r e^{-jw} (1 - e^{jw} / r)`.
fn factor_phase(r: Complex, w: f64) -> f64 {
    let e = Complex::new(w.cos(), -w.sin());
    let one = Complex::new(1.0, 0.0);
    if r.norm() <= 1.0 {
        (one - r * e).arg()
    } else {
        (-r).arg() - w + (one - one / (e * r)).arg()
    }
}

/// The frequencies a model's response is shown at unless others are asked for: 0 Hz, then
/// [`DEFAULT_POINTS_PER_DECADE`] points per decade, log-spaced, from `fs`/1000 to `fs`/2
/// (both included).
#[must_use]
pub fn default_frequencies(fs: f64) -> Vec<f64> {
    let (lo, hi) = (fs / 1000.0, fs / 2.0);
    let n = (DEFAULT_POINTS_PER_DECADE * (hi / lo).log10()).ceil() as usize;
    let mut f = Vec::with_capacity(n + 2);
    f.push(0.0);
    f.extend((0..=n).map(|k| lo * (hi / lo).powf(k as f64 / n as f64)));
    f
}

/// Points per decade of [`default_frequencies`].
pub const DEFAULT_POINTS_PER_DECADE: f64 = 4.0;

/// One point of a frequency response ([`response_points`]), in linear and table units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ResponsePoint {
    /// Frequency \[Hz\].
    pub frequency_hz: f64,
    /// `|H|` [-].
    pub magnitude: f64,
    /// `20 log10 |H|` \[dB\].
    pub magnitude_db: f64,
    /// Unwrapped phase \[rad\] (as [`frequency_response`]).
    pub phase_rad: f64,
    /// The same phase in degrees.
    pub phase_deg: f64,
}

/// [`frequency_response`] at `freqs_hz`, each point also in dB and degrees.
#[must_use]
pub fn response_points(model: &Model, freqs_hz: &[f64]) -> Vec<ResponsePoint> {
    frequency_response(model, freqs_hz)
        .into_iter()
        .zip(freqs_hz)
        .map(|((magnitude, phase_rad), &frequency_hz)| ResponsePoint {
            frequency_hz,
            magnitude,
            magnitude_db: 20.0 * magnitude.log10(),
            phase_rad,
            phase_deg: phase_rad.to_degrees(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn second_order(fs: f64, fn_hz: f64, zeta: f64, delay: usize) -> Model {
        // Poles exp(s/fs) of s^2 + 2 zeta wn s + wn^2, numerator scaled for unit DC gain.
        let wn = 2.0 * PI * fn_hz;
        let s = Complex::new(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt());
        let p = (s / fs).exp();
        let a = vec![-2.0 * p.re, p.norm_sqr()];
        let g = 1.0 + a[0] + a[1];
        Model {
            fs,
            delay,
            a,
            b: vec![0.5 * g, 0.3 * g, 0.2 * g],
        }
    }

    #[test]
    fn default_grid_and_points_in_db_and_degrees() {
        let f = default_frequencies(10_000.0);
        // 0 Hz, then 4 per decade over 10 Hz .. 5 kHz (2.7 decades: 11 steps, 12 points).
        assert_eq!(f.len(), 13);
        assert_eq!(f[0], 0.0);
        assert!((f[1] - 10.0).abs() < 1e-9 && (f[12] - 5000.0).abs() < 1e-9);
        let m = second_order(10_000.0, 500.0, 0.3, 2);
        let p = response_points(&m, &[0.0, 400.0]);
        assert!(p[0].magnitude_db.abs() < 1e-9);
        let (mag, phase) = frequency_response(&m, &[400.0])[0];
        assert_eq!(p[1].magnitude_db, 20.0 * mag.log10());
        assert_eq!(p[1].phase_deg, phase.to_degrees());
    }

    #[test]
    fn resonance_of_a_known_pair() {
        let m = second_order(10_000.0, 95.0, 0.12, 3);
        let an = Analysis::new(&m).unwrap();
        assert!(an.stable && an.minimum_phase);
        assert!((an.dc_gain - 1.0).abs() < 1e-12);
        assert!(an.dc_gain_deviation.abs() < 1e-12);
        assert_eq!(an.modes.len(), 1);
        let ModeKind::Resonance {
            natural_frequency_hz,
            damping,
            ..
        } = an.modes[0].kind
        else {
            panic!("{:?}", an.modes)
        };
        assert!(
            (natural_frequency_hz - 95.0).abs() < 1e-9,
            "{natural_frequency_hz}"
        );
        assert!((damping - 0.12).abs() < 1e-12, "{damping}");
        assert!((an.delay_s - 3e-4).abs() < 1e-15);
        assert!((an.stability_margin - (1.0 - an.poles[0].magnitude)).abs() < 1e-15);
    }

    #[test]
    fn verdicts_and_margins() {
        // Zero at 2.1, poles 0.5 and 1.05.
        let m = Model {
            fs: 100.0,
            delay: 0,
            a: vec![-1.55, 0.525],
            b: vec![1.0, -2.1],
        };
        let an = Analysis::new(&m).unwrap();
        assert!(!an.stable && !an.minimum_phase);
        assert!((an.stability_margin + 0.05).abs() < 1e-12);
        assert!((an.minimum_phase_margin + 1.1).abs() < 1e-12);
        // The growing real pole has a negative time constant.
        let ModeKind::Real {
            time_constant_s: Some(t),
            ..
        } = an.modes[0].kind
        else {
            panic!()
        };
        assert!(t < 0.0);
    }

    #[test]
    fn negative_real_pole_is_nyquist_not_nan() {
        let m = Model {
            fs: 1000.0,
            delay: 1,
            a: vec![0.6],
            b: vec![1.6],
        };
        let an = Analysis::new(&m).unwrap();
        let ModeKind::Nyquist {
            frequency_hz,
            envelope_time_constant_s: Some(t),
        } = an.modes[0].kind
        else {
            panic!("{:?}", an.modes)
        };
        assert_eq!(frequency_hz, 500.0);
        assert!((t - (-1.0 / (1000.0 * 0.6f64.ln()))).abs() < 1e-12);
        assert!(an.modes[0].description.contains("Nyquist"));
        let json = serde_json::to_string(&an).unwrap();
        assert!(
            !json.contains("NaN") && !json.contains("null,\"desc"),
            "{json}"
        );
        assert!(json.contains("\"kind\":\"nyquist\""), "{json}");
    }

    #[test]
    fn bad_models_are_refused() {
        let mut m = second_order(1000.0, 10.0, 0.5, 0);
        m.fs = 0.0;
        assert!(Analysis::new(&m).is_err());
        m.fs = 1000.0;
        m.b = vec![];
        assert!(Analysis::new(&m).is_err());
    }

    #[test]
    fn phase_includes_the_delay_and_is_unwrapped_on_a_coarse_grid() {
        // A pure delay of 7 samples: phase -2 pi f 7 / fs, far past -pi.
        let m = Model {
            fs: 1000.0,
            delay: 7,
            a: vec![],
            b: vec![1.0],
        };
        let f = [0.0, 100.0, 230.0, 499.0];
        for ((mag, ph), f) in frequency_response(&m, &f).into_iter().zip(f) {
            assert!((mag - 1.0).abs() < 1e-12);
            assert!((ph + 2.0 * PI * f * 7.0 / 1000.0).abs() < 1e-9, "{f}: {ph}");
        }
        // A sharp resonance between two grid points: phase goes from ~0 to ~-pi (plus delay).
        let m = second_order(10_000.0, 95.0, 0.01, 0);
        let r = frequency_response(&m, &[0.0, 10.0, 1000.0]);
        assert!(r[0].1.abs() < 1e-12);
        let rational = r[2].1; // 1000 Hz: the pair has turned by ~-pi, the zeros add a little
        assert!(rational < -2.5 && rational > -4.0, "{rational}");
    }

    #[test]
    fn phase_of_a_zero_outside_winds() {
        // H = 1 - 2 z^-1: DC gain -1 (phase +-pi at 0), at Nyquist 3 (phase 0 or 2 pi
        // consistently with continuity: arg goes from pi to 2 pi or -pi to -2 pi).
        let m = Model {
            fs: 2.0,
            delay: 0,
            a: vec![],
            b: vec![1.0, -2.0],
        };
        let freqs: Vec<f64> = (0..=100).map(|k| k as f64 / 100.0).collect();
        let r = frequency_response(&m, &freqs);
        for w in r.windows(2) {
            assert!((w[1].1 - w[0].1).abs() < 0.2, "{w:?}");
        }
        assert!(((r[100].1 - r[0].1).abs() - PI).abs() < 1e-9);
    }
}
