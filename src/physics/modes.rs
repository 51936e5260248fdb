//! Exact modes of a Bergh-Tijdeman line: the poles of the meromorphic response
//! `H(s) = 1/M₁₁(s)` ([`super::line`]), found by Newton iteration in the complex `s` plane,
//! and the front delay `ΣL/a`.
//!
//! # Method
//! 1. Lossless guesses: with a vanishing viscosity `M₁₁(iω)` is real; its sign changes on a
//!    frequency grid give the organ-pipe / Helmholtz modes `ω_m` (`x tan x = V_t/V` for one
//!    tube, `x = ωL/a`).
//! 2. Homotopy in viscosity: each guess is followed by Newton's method (central-difference
//!    derivative) while `μ` grows geometrically from `10⁻⁴ μ` to `μ` in 16 steps, so every pole
//!    keeps its identity. A pole that reaches the real axis has become overdamped.
//! 3. Real poles: sign changes of the real function `M₁₁(−σ)` on a logarithmic grid, refined by
//!    bisection up to four times the highest mode searched, past the accumulation points of
//!    the Bessel ratios' poles (a narrow tube in series has creeps beyond a wide one's);
//!    candidates where `|M₁₁|` is not small are poles of the Bessel ratio, not zeros, and
//!    zeros with a negligible residue are dropped (below 0.1 % of the step; beyond the widest
//!    tube's accumulation point, where zeros crowd, below 1 %).
//!
//! A complex pole `s = −ζω_n + iω_n√(1−ζ²)` gives the mode `(ω_n = |s|, ζ = −Re s/|s|)`. When the
//! two slowest real poles `σ₁ < σ₂` are slower than every oscillatory mode (an overdamped line),
//! they are reported first as the equivalent pair `ω_n = √(σ₁σ₂)`, `ζ = (σ₁+σ₂)/(2ω_n) ≥ 1`; for
//! very overdamped lines compare only the slowest pole (README 2.C): it is in
//! [`ModeAnalysis::real_poles_rad_s`].

use num_complex::Complex64;

use super::gas::Gas;
use super::line::Line;
use super::PhysicsError;
use crate::error::{Error, Result};

/// One mode (a pole pair) of the line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency `f_n = ω_n/2π` \[Hz\].
    pub natural_frequency_hz: f64,
    /// Damping ratio `ζ` [-] (≥ 1 for an overdamped pair of real poles).
    pub damping: f64,
    /// The pole in the upper half plane `s` [rad/s] (for an overdamped pair: the slower real
    /// pole).
    pub pole: Complex64,
    /// `true` when the mode is an equivalent pair of two real poles.
    pub overdamped: bool,
}

impl Mode {
    /// Damped frequency `f_d = Im s / 2π` \[Hz\] (0 for an overdamped pair).
    #[must_use]
    pub fn damped_frequency_hz(&self) -> f64 {
        self.pole.im / (2.0 * core::f64::consts::PI)
    }

    fn from_pole(pole: Complex64) -> Self {
        let wn = pole.norm();
        Self {
            natural_frequency_hz: wn / (2.0 * core::f64::consts::PI),
            damping: -pole.re / wn,
            pole,
            overdamped: false,
        }
    }
}

/// The exact modes of a line, slowest first, and its front delay.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeAnalysis {
    /// Modes in order of natural frequency.
    pub modes: Vec<Mode>,
    /// Real poles found, `−σ` [rad/s], slowest first.
    pub real_poles_rad_s: Vec<f64>,
    /// The real axis is searched from `0` to `−σ_max` [rad/s]: `σ_max` is four times the
    /// highest mode searched (a real pole beyond it is not found).
    pub real_search_limit_rad_s: f64,
    /// Front delay `ΣL/a` \[s\].
    pub delay_s: f64,
}

/// Square of the first zero of `J₀`.
const J01_SQUARED: f64 = 2.404_825_557_695_773 * 2.404_825_557_695_773;

/// Real poles whose step-response amplitude `|Res/σ|` is below this are ignored.
const MIN_REAL_POLE_WEIGHT: f64 = 1e-3;

/// Beyond the widest tube's accumulation point, where zeros crowd at every pole of the Bessel
/// ratios, a real pole is listed only from this step-response amplitude (1 % of the step).
const MIN_FAR_REAL_POLE_WEIGHT: f64 = 1e-2;

/// Newton's method for a zero of `f` from `s0`, with a step limit. `None` if it fails.
fn newton(f: &dyn Fn(Complex64) -> Complex64, s0: Complex64) -> Option<Complex64> {
    let mut s = s0;
    for _ in 0..80 {
        let v = f(s);
        if !v.is_finite() {
            return None;
        }
        let h = 1e-6 * s.norm().max(1e-3);
        let d = (f(s + h) - f(s - h)) / (2.0 * h);
        if !d.is_finite() || d.norm() == 0.0 {
            return None;
        }
        let mut step = v / d;
        let limit = 0.3 * s.norm().max(1e-3);
        if step.norm() > limit {
            step *= limit / step.norm();
        }
        s -= step;
        if step.norm() < 1e-13 * s.norm().max(1e-9) {
            return Some(s);
        }
    }
    None
}

/// Lossless mode estimates `ω_m` [rad/s] below `omega_max`.
fn lossless_guesses(line: &Line, gas: &Gas, omega_max: f64) -> Vec<f64> {
    let inviscid = gas.with_viscosity(gas.viscosity_pa_s * 1e-9);
    let n = 6000;
    let f = |w: f64| line.inverse_response(&inviscid, Complex64::new(0.0, w)).re;
    let mut out = Vec::new();
    let mut w_prev = omega_max / n as f64 * 0.5;
    let mut v_prev = f(w_prev);
    for i in 1..=n {
        let w = omega_max * i as f64 / n as f64;
        let v = f(w);
        if v.signum() != v_prev.signum() && v.is_finite() && v_prev.is_finite() {
            let (mut lo, mut hi, mut vlo) = (w_prev, w, v_prev);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                let vm = f(mid);
                if vm.signum() == vlo.signum() {
                    lo = mid;
                    vlo = vm;
                } else {
                    hi = mid;
                }
            }
            out.push(0.5 * (lo + hi));
        }
        w_prev = w;
        v_prev = v;
    }
    out
}

/// Real zeros `σ > 0` of `M₁₁(−σ)` in `[sigma_min, sigma_max]` [1/s], each with its weight in
/// the step response `|Res/σ|` (at least [`MIN_REAL_POLE_WEIGHT`]).
fn real_poles(line: &Line, gas: &Gas, sigma_min: f64, sigma_max: f64) -> Vec<(f64, f64)> {
    let f = |sig: f64| line.inverse_response(gas, Complex64::new(-sig, 0.0)).re;
    let n = 3000;
    let ratio = (sigma_max / sigma_min).ln() / n as f64;
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut s_prev = sigma_min;
    let mut v_prev = f(s_prev);
    for i in 1..=n {
        let sig = sigma_min * (ratio * i as f64).exp();
        let v = f(sig);
        if v.is_finite() && v_prev.is_finite() && v.signum() != v_prev.signum() {
            let (mut lo, mut hi, mut vlo) = (s_prev, sig, v_prev);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                let vm = f(mid);
                if vm.signum() == vlo.signum() {
                    lo = mid;
                    vlo = vm;
                } else {
                    hi = mid;
                }
            }
            let root = 0.5 * (lo + hi);
            // A zero, not a pole of the Bessel ratio: |M11| is small there compared with the
            // bracket ends.
            let scale = v.abs().max(v_prev.abs());
            if f(root).abs() < 1e-6 * scale.max(1.0) {
                // Keep only poles that matter: the step-response term of a simple pole −σ is
                // Res/(−σ) e^{−σt} with Res = 1/M₁₁'(−σ). Zeros accumulating at a pole of the
                // Bessel ratio (thermal and viscous diffusion modes) have tiny residues.
                let h = 1e-7 * root;
                let slope = (f(root + h) - f(root - h)) / (2.0 * h); // d M11/dσ
                let weight = 1.0 / (slope * root).abs();
                if weight > MIN_REAL_POLE_WEIGHT {
                    out.push((root, weight));
                }
            }
        }
        s_prev = sig;
        v_prev = v;
    }
    out
}

/// The first `count` modes of `line` in `gas`, with the real poles and the front delay.
///
/// # Errors
/// [`Error::InvalidArgument`] for an invalid line or gas, or a line without tubes;
/// [`PhysicsError::NoMode`] if no mode could be found.
pub fn find_modes(line: &Line, gas: &Gas, count: usize) -> Result<ModeAnalysis> {
    gas.validate()?;
    line.validate()?;
    let total_length: f64 = line.tubes().map(|t| t.length_m).sum();
    if total_length <= 0.0 {
        return Err(Error::InvalidArgument {
            what: "line",
            message: "needs at least one tube".into(),
        });
    }
    let a = gas.speed_of_sound();
    let quarter = 2.0 * core::f64::consts::PI * a / (4.0 * total_length);
    let count = count.max(1);
    let mut omega_max = quarter * (2.0 * count as f64 + 2.0);
    let mut guesses = lossless_guesses(line, gas, omega_max);
    if guesses.len() < count + 1 {
        omega_max *= 4.0;
        guesses = lossless_guesses(line, gas, omega_max);
    }

    let mut complex_poles: Vec<Complex64> = Vec::new();
    let steps = 16;
    for &w0 in guesses.iter().take(count + 2) {
        let mut s = Complex64::new(-1e-3 * w0, w0);
        let mut alive = true;
        for k in 0..=steps {
            let scale = 10f64.powf(-4.0 * (1.0 - k as f64 / steps as f64));
            let g = gas.with_viscosity(gas.viscosity_pa_s * scale);
            let f = |z: Complex64| line.inverse_response(&g, z);
            match newton(&f, s) {
                Some(root) => s = root,
                None => {
                    alive = false;
                    break;
                }
            }
            if s.im.abs() < 1e-7 * s.norm() {
                alive = false; // reached the real axis: overdamped
                break;
            }
        }
        if alive {
            let s = Complex64::new(s.re, s.im.abs());
            if !complex_poles
                .iter()
                .any(|p| (p - s).norm() < 1e-6 * s.norm())
            {
                complex_poles.push(s);
            }
        }
    }
    complex_poles.sort_by(|x, y| x.norm().total_cmp(&y.norm()));

    // Zeros of M11 crowd at the poles of the Bessel ratios (σ = j₀ₖ²ν/R² and j₀ₖ²ν/(R² Pr) of
    // each tube), with tiny residues: `real_poles` drops those and the singular points
    // themselves, so the search runs past them. In lines in series a wide tube's accumulation
    // point can lie below a real pole of a narrow one that shapes the response.
    let sigma_max = 4.0 * omega_max;
    let all_reals = real_poles(line, gas, 1e-4 * quarter, sigma_max);
    let mut modes: Vec<Mode> = complex_poles.iter().map(|&p| Mode::from_pole(p)).collect();
    // An overdamped line's pair lies below 6ν/R² (lumped: σ₁ + σ₂ = 6ν/R²), under the widest
    // tube's thermal accumulation point j₀₁²ν/(R² Pr); real poles beyond it are creeps of
    // narrower tubes, listed but not paired into a mode.
    let nu = gas.kinematic_viscosity();
    let sigma_pair = line
        .tubes()
        .map(|t| J01_SQUARED * nu / (t.radius_m * t.radius_m * gas.prandtl))
        .fold(f64::INFINITY, f64::min);
    let reals: Vec<f64> = all_reals
        .iter()
        .filter(|(s, w)| *s < sigma_pair || *w >= MIN_FAR_REAL_POLE_WEIGHT)
        .map(|(s, _)| *s)
        .collect();
    let paired: Vec<f64> = reals.iter().copied().filter(|s| *s < sigma_pair).collect();
    if let [s1, s2, ..] = paired.as_slice() {
        let wn = (s1 * s2).sqrt();
        if modes.first().is_none_or(|m| wn < m.pole.norm()) {
            modes.insert(
                0,
                Mode {
                    natural_frequency_hz: wn / (2.0 * core::f64::consts::PI),
                    damping: (s1 + s2) / (2.0 * wn),
                    pole: Complex64::new(-s1, 0.0),
                    overdamped: true,
                },
            );
        }
    }
    modes.truncate(count);
    if modes.is_empty() {
        return Err(PhysicsError::NoMode.into());
    }
    Ok(ModeAnalysis {
        modes,
        real_poles_rad_s: reals.iter().map(|s| -s).collect(),
        real_search_limit_rad_s: -sigma_max,
        delay_s: line.front_delay_s(gas),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poles_are_zeros_of_m11() {
        let gas = Gas::standard_air();
        let line = Line::new().tube(0.6, 0.55e-3).volume(20e-9);
        let an = find_modes(&line, &gas, 3).expect("modes");
        assert_eq!(an.modes.len(), 3);
        for m in &an.modes {
            let h = line.response(&gas, m.pole + Complex64::new(0.0, 1e-9 * m.pole.norm()));
            assert!(h.norm() > 1e6, "{m:?}: |H| {}", h.norm());
        }
    }

    /// Lines in series: two independent Bergh-Tijdeman implementations find real
    /// poles at -11.05 and -67.93 rad/s; the second lies beyond the wide tube's thermal
    /// accumulation point (52.9 rad/s), where the search used to stop.
    #[test]
    fn finds_real_poles_beyond_a_wide_tubes_accumulation_point() {
        let gas = Gas::air(288.15, 101_325.0);
        let line = Line::new()
            .tube(0.1, 0.25e-3)
            .tube(1.0, 1.5e-3)
            .tube(0.3, 0.5e-3)
            .volume(3e-7);
        let an = find_modes(&line, &gas, 3).expect("modes");
        for want in [-11.05, -67.93] {
            assert!(
                an.real_poles_rad_s
                    .iter()
                    .any(|p| (p - want).abs() < 0.01 * want.abs()),
                "{want} not in {:?}",
                an.real_poles_rad_s
            );
        }
        // Beyond the accumulation point only poles of at least 1 % of the step are listed:
        // -292 rad/s (0.3 %) is not.
        assert_eq!(an.real_poles_rad_s.len(), 2, "{:?}", an.real_poles_rad_s);
        // Poles of the Bessel ratios are not zeros of M11: none is listed.
        let nu = gas.kinematic_viscosity();
        for t in line.tubes() {
            let sigma = J01_SQUARED * nu / (t.radius_m * t.radius_m * gas.prandtl);
            assert!(an
                .real_poles_rad_s
                .iter()
                .all(|p| (p + sigma).abs() > 1e-3 * sigma));
        }
    }

    /// Two lines in series: the real poles against an independent mpmath computation
    /// of the same chain (`bench/bt_series_real_poles.py`, 20 digits, a 0.01 rad/s scan with
    /// bisection). The references, -11.55 and -11.25 rad/s, are the slow pole of two
    /// different configurations at the CLI's default 293.15 K — a rigid closed end (`V = 0`) and
    /// the three-line case's `V = 3e-7` — not two poles of one line: each configuration has
    /// exactly one zero of `M₁₁` near -11 rad/s (argument principle) and a second real pole near
    /// -70 rad/s. Our -11.37/-68.71 are the 288.15 K, `V = 3e-7` row.
    #[test]
    fn two_line_real_poles_match_an_independent_computation() {
        // (temperature K, end volume m³, slow pole, second pole) [rad/s]
        let cases = [
            (293.15, 0.0, -11.5542, -71.3741),
            (293.15, 3e-7, -11.2475, -70.6587),
            (288.15, 3e-7, -11.3727, -68.7136),
            (288.15, 0.0, -11.6808, -69.4212),
        ];
        for (temperature, volume, slow, second) in cases {
            let gas = Gas::air(temperature, 101_325.0);
            let line = Line::new()
                .tube(0.1, 0.25e-3)
                .tube(1.0, 1.5e-3)
                .volume(volume);
            let an = find_modes(&line, &gas, 3).expect("modes");
            let got = &an.real_poles_rad_s;
            assert_eq!(got.len(), 2, "{temperature} K, {volume} m³: {got:?}");
            for (g, want) in got.iter().zip([slow, second]) {
                // The reference is rounded to 1e-4 rad/s.
                assert!(
                    (g - want).abs() < 2e-4,
                    "{temperature} K, {volume} m³: {g} against {want}"
                );
            }
        }
    }

    #[test]
    fn rejects_a_line_without_tubes() {
        assert!(find_modes(&Line::new().volume(1e-6), &Gas::standard_air(), 1).is_err());
    }
}
