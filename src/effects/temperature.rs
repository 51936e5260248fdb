//! The `temperature` effect: the model's time scale at another gas temperature, the damping
//! laws that go with it, and the scale factor of a test estimated from the test.

use serde::{Deserialize, Serialize};

use super::{Effect, EffectKind};
use crate::error::Result;
use crate::fit::continuous::Continuous;
use crate::fit::model::Model;
use crate::poly::Complex;

/// How a `temperature` effect moves the model with the gas temperature: the time-scale factor
/// `k` at `T` ([`TemperatureDamping::scale`]) and the damping ratio of every mode with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TemperatureDamping {
    /// Every natural frequency by `k = sqrt(T / T_ref)` (the speed of sound); the damping
    /// ratios are kept.
    #[default]
    Constant,
    /// The viscous law of a tube-volume system (`zeta = (4 / c_I) nu / (R^2 w_n)`, the
    /// physics module's lumped model): `k = sqrt(T / T_ref)` and every damping ratio
    /// multiplied by `(nu(T) / nu(T_ref)) / k` ([`viscous_damping_factor`]), with
    /// `nu = mu / rho` of air, `mu` by Sutherland's law and `rho = p / (R_g T)` at one fixed
    /// mean pressure.
    Viscous,
    /// An overdamped line (a capillary), where the pressure diffuses along the tube: every time
    /// scale, the delay included, goes as the gas viscosity, `k = mu(T_ref) / mu(T)`
    /// ([`diffusive_scale`]), the damping ratios kept. The diffusivity of a Poiseuille line,
    /// `r^2 p / (8 mu)`, has no speed of sound in it, so a hotter gas makes a capillary slower,
    /// not faster.
    Diffusive,
}

impl TemperatureDamping {
    /// Whether it is [`TemperatureDamping::Constant`] (not written to the model file then).
    #[must_use]
    pub fn is_constant(&self) -> bool {
        *self == Self::Constant
    }

    /// The factor on every damping ratio at time-scale factor `k` for a model at
    /// `reference_k` (the temperature is `reference_k k^2`): 1 for `constant` and `diffusive`;
    /// for `viscous` [`viscous_damping_factor`], 1 when the temperatures are not positive
    /// numbers.
    #[must_use]
    pub fn factor(self, k: f64, reference_k: f64) -> f64 {
        match self {
            Self::Constant | Self::Diffusive => 1.0,
            Self::Viscous => {
                viscous_damping_factor(reference_k * k * k, reference_k).unwrap_or(1.0)
            }
        }
    }

    /// The time-scale factor `k` at gas temperature `temperature_k` for a model at
    /// `reference_k`: [`scale_for`] (the speed of sound) for `constant` and `viscous`,
    /// [`diffusive_scale`] (the viscosity) for `diffusive`.
    ///
    /// # Errors
    /// As [`scale_for`].
    pub fn scale(self, temperature_k: f64, reference_k: f64) -> Result<f64> {
        match self {
            Self::Constant | Self::Viscous => scale_for(temperature_k, reference_k),
            Self::Diffusive => diffusive_scale(temperature_k, reference_k),
        }
    }

    /// The gas temperature (K) at which the model at `reference_k` has time-scale factor `k`:
    /// the inverse of [`TemperatureDamping::scale`]. `reference_k k^2` for `constant` and
    /// `viscous`; for `diffusive` the temperature whose Sutherland viscosity is
    /// `mu(reference_k) / k` (NaN outside 1 K to 10 000 K).
    #[must_use]
    pub fn temperature(self, k: f64, reference_k: f64) -> f64 {
        match self {
            Self::Constant | Self::Viscous => reference_k * k * k,
            Self::Diffusive => {
                let mu = crate::physics::gas::sutherland_viscosity;
                let target = mu(reference_k) / k;
                let (mut lo, mut hi) = (1.0f64, 10_000.0f64);
                if !(target > mu(lo) && target < mu(hi)) {
                    return f64::NAN;
                }
                // Sutherland's viscosity rises with temperature: bisect on a log scale.
                for _ in 0..100 {
                    let mid = (lo * hi).sqrt();
                    if mu(mid) < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                (lo * hi).sqrt()
            }
        }
    }

    /// The `--add` spelling of a `temperature` effect with this law.
    #[must_use]
    pub fn spelling(self) -> EffectKind {
        match self {
            Self::Constant => EffectKind::Temperature,
            Self::Viscous => EffectKind::TemperatureViscous,
            Self::Diffusive => EffectKind::TemperatureDiffusive,
        }
    }
}

/// The time-scale factor of an overdamped line at `temperature_k` for a model at
/// `reference_k`: `mu(reference_k) / mu(T)` (Sutherland's law for air), the ratio of the
/// diffusivities `r^2 p / (8 mu)` of a Poiseuille line at one mean pressure. 0.887 from
/// 293.15 K to 343.15 K: the capillary slows by 13 % where the speed of sound rises by 8 %.
///
/// # Errors
/// As [`scale_for`].
pub fn diffusive_scale(temperature_k: f64, reference_k: f64) -> Result<f64> {
    scale_for(temperature_k, reference_k)?;
    let mu = crate::physics::gas::sutherland_viscosity;
    Ok(mu(reference_k) / mu(temperature_k))
}

/// Mean pressure (Pa) at which [`viscous_damping_factor`] evaluates the air: one standard
/// atmosphere. The factor depends on it only through the density, which is proportional to
/// the pressure at both temperatures, so the ratio `nu(T) / nu(T_ref)` is the same at any
/// fixed mean pressure; this is only where the two gases are built.
pub const VISCOUS_PRESSURE_PA: f64 = crate::physics::gas::STANDARD_PRESSURE;

/// The factor on a tube-volume system's damping ratio from `reference_k` to `temperature_k`:
/// `zeta = (4 / c_I) nu / (R^2 w_n)` (the lumped limit of Bergh and Tijdeman's 1965 line
/// model, `c_I = 4/3` the Poiseuille inertance) with `w_n`
/// scaling as the speed of sound, so `(nu(T) / nu(T_ref)) / sqrt(T / T_ref)`, air at
/// [`VISCOUS_PRESSURE_PA`] ([`crate::physics::Gas::air`]: Sutherland viscosity, ideal-gas
/// density). About 1.22 from 293.15 K to 343.15 K.
///
/// # Errors
/// As [`scale_for`].
pub fn viscous_damping_factor(temperature_k: f64, reference_k: f64) -> Result<f64> {
    let k = scale_for(temperature_k, reference_k)?;
    let nu = |t: f64| crate::physics::Gas::air(t, VISCOUS_PRESSURE_PA).kinematic_viscosity();
    Ok(nu(temperature_k) / nu(reference_k) / k)
}

/// Reference temperature when the user gives none (K): 20 degrees Celsius.
pub const DEFAULT_REFERENCE_K: f64 = 293.15;

pub(super) fn default_reference_k() -> f64 {
    DEFAULT_REFERENCE_K
}

/// Range of the time-scale factor `k` searched per test (temperatures from about 0.5 to 2
/// times the reference).
pub const SCALE_RANGE: (f64, f64) = (0.7, 1.4);

/// The reference temperature of `effects` (K), when they have a `temperature`.
#[must_use]
pub fn reference_k(effects: &[Effect]) -> Option<f64> {
    temperature_law(effects).map(|(t, _)| t)
}

/// The reference temperature (K) and damping law of `effects`' `temperature`, if any.
#[must_use]
pub fn temperature_law(effects: &[Effect]) -> Option<(f64, TemperatureDamping)> {
    effects.iter().find_map(|e| match e {
        Effect::Temperature {
            reference_k,
            damping,
        } => Some((*reference_k, *damping)),
        _ => None,
    })
}

/// The time-scale factor at gas temperature `temperature_k` for a model at `reference_k`:
/// `sqrt(T / T_ref)`, the ratio of the speeds of sound of an ideal gas.
///
/// # Errors
/// [`crate::error::Error::InvalidParameter`] for a temperature that is not a positive number
/// of kelvin.
pub fn scale_for(temperature_k: f64, reference_k: f64) -> Result<f64> {
    if !(temperature_k.is_finite()
        && temperature_k > 0.0
        && reference_k.is_finite()
        && reference_k > 0.0)
    {
        return Err(crate::error::Error::InvalidParameter {
            parameter: crate::error::Parameter::Temperature,
            message: format!(
                "temperatures must be positive numbers of kelvin, not {temperature_k} K (model at {reference_k} K)"
            ),
        });
    }
    Ok((temperature_k / reference_k).sqrt())
}

/// Damping ratios closer to 1 than this after scaling are moved to `1 + this` (two real poles
/// that stay apart: the modal form has no repeated poles).
const CRITICAL_GAP: f64 = 1e-3;

/// The pole `s` (of a resonance: `s = -zeta w + j w sqrt(1 - zeta^2)`) with its damping ratio
/// times `factor` and its natural frequency `w = |s|` kept. A real pole is kept; a resonance
/// damped past critical becomes two real poles `-w (zeta -+ sqrt(zeta^2 - 1))` (the upper pole
/// of the pair takes the slower one).
fn damped_pole(s: Complex, factor: f64) -> Complex {
    let w = s.norm();
    if s.im == 0.0 || s.im.abs() <= 1e-12 * w || factor == 1.0 {
        return s;
    }
    let zeta = (-s.re / w) * factor;
    if zeta < 1.0 - CRITICAL_GAP {
        return Complex::new(-zeta * w, s.im.signum() * w * (1.0 - zeta * zeta).sqrt());
    }
    let zeta = zeta.max(1.0 + CRITICAL_GAP);
    let root = (zeta * zeta - 1.0).sqrt();
    Complex::new(-w * (zeta - s.im.signum() * root), 0.0)
}

/// The poles `old` (already time-scaled) with the damping ratio of every mode times
/// `factor`, its natural frequency kept. A complex pair moves as [`damped_pole`]. Real poles
/// are the modes of an overdamped probe (a capillary): two of them, and no more, are one mode
/// `w_n = sqrt(s1 s2)`, `zeta = -(s1 + s2) / (2 w_n)`, whose slow corner (about `w_n / 2 zeta`)
/// moves by `1 / factor` and fast one by `factor`; a lone real pole is that slow corner in the
/// limit of large damping and moves by `1 / factor` (a first-order capillary's `RC`, with `R`
/// the Poiseuille resistance, which goes as the viscosity). Three or more real poles cannot be
/// paired and are kept, as are the real poles of a probe that also resonates.
fn moved_poles(old: &[Complex], factor: f64) -> Vec<Complex> {
    let mut new: Vec<Complex> = old.iter().map(|&s| damped_pole(s, factor)).collect();
    if factor == 1.0 {
        return new;
    }
    let real: Vec<usize> = (0..old.len())
        .filter(|&i| old[i].im.abs() <= 1e-12 * old[i].norm() && old[i].re < 0.0)
        .collect();
    if real.len() < old.len() {
        // A resonant probe: its real poles (a leak, a fitted lag) are not an overdamped mode.
        return new;
    }
    match real[..] {
        [i] => new[i] = old[i] / factor,
        [i, j] => {
            let (slow, fast) = if old[i].re.abs() <= old[j].re.abs() {
                (i, j)
            } else {
                (j, i)
            };
            let w = (old[i].re * old[j].re).sqrt();
            let zeta = -(old[i].re + old[j].re) / (2.0 * w) * factor;
            if zeta < 1.0 - CRITICAL_GAP {
                let wd = w * (1.0 - zeta * zeta).sqrt();
                new[slow] = Complex::new(-zeta * w, wd);
                new[fast] = Complex::new(-zeta * w, -wd);
            } else {
                let zeta = zeta.max(1.0 + CRITICAL_GAP);
                let root = (zeta * zeta - 1.0).sqrt();
                new[slow] = Complex::new(-w * (zeta - root), 0.0);
                new[fast] = Complex::new(-w * (zeta + root), 0.0);
            }
        }
        _ => {}
    }
    new
}

fn scale_continuous(ct: &Continuous, k: f64, damping_factor: f64, fs: f64) -> Result<Model> {
    let mut out = ct.clone();
    let one = Complex::new(1.0, 0.0);
    // Time scaled by k: H(s / k) has the poles k s_i and the residues k r_i.
    let old: Vec<Complex> = ct
        .poles
        .iter()
        .map(|r| Complex::new(k * r.re, k * r.im))
        .collect();
    let res: Vec<Complex> = ct
        .residues
        .iter()
        .map(|r| Complex::new(k * r.re, k * r.im))
        .collect();
    let new = moved_poles(&old, damping_factor);
    // The damping moved: H'(s) = H(s / k) Q(s), Q(s) = C prod_j (s - old_j) / (s - new_j) with
    // C = prod_j new_j / old_j (Q(0) = 1: the DC gain kept; the zeros of H(s / k) kept). Its
    // residue at new_i, written so that it is k r_i when nothing moved.
    let c = new.iter().zip(&old).fold(one, |acc, (n, o)| acc * *n / *o);
    let residues: Vec<Complex> = (0..new.len())
        .map(|i| {
            let (ni, mut rest, mut ratio) = (new[i], Complex::new(ct.feedthrough, 0.0), one);
            for j in (0..new.len()).filter(|&j| j != i) {
                rest += res[j] / (ni - old[j]);
                ratio = ratio * (ni - old[j]) / (ni - new[j]);
            }
            c * (rest * (ni - old[i]) + res[i]) * ratio
        })
        .collect();
    if residues
        .iter()
        .any(|r| !(r.re.is_finite() && r.im.is_finite()))
    {
        return Err(crate::effects::EffectError::CoincidentPoles { damping_factor }.into());
    }
    out.poles = new
        .into_iter()
        .map(crate::fit::analysis::Root::from)
        .collect();
    out.residues = residues
        .into_iter()
        .map(crate::fit::analysis::Root::from)
        .collect();
    out.feedthrough = ct.feedthrough * c.re;
    out.delay_s /= k;
    Ok(out.discretise(fs)?.model)
}

/// The model with time scaled by `k`: `H_k(s) = H(s / k)`, every pole (natural frequency) times
/// `k` and the delay over `k`, re-discretised at the model's rate (step invariant, through
/// [`Continuous`]). The damping ratios are kept ([`scaled_with`] moves them too).
///
/// # Errors
/// As [`Continuous::from_model`] and [`Continuous::discretise`].
pub fn scaled(model: &Model, k: f64) -> Result<Model> {
    scaled_with(model, k, 1.0)
}

/// As [`scaled`], and the damping ratio of every resonance (complex pole pair) multiplied by
/// `damping_factor`, its natural frequency kept: the poles `s = -zeta w +- j w sqrt(1 - zeta^2)`
/// move to `zeta' = damping_factor zeta` (two real poles beyond critical damping). An
/// overdamped probe's one or two real poles move as its mode's damping does (see
/// `moved_poles`); other real poles only scale by `k`. The zeros of `H(s / k)` and the DC gain are kept, the feedthrough (if
/// any) is multiplied by the product of the new poles over the old.
///
/// # Errors
/// As [`scaled`]; [`crate::effects::EffectError::CoincidentPoles`] when two moved poles coincide.
pub fn scaled_with(model: &Model, k: f64, damping_factor: f64) -> Result<Model> {
    let ct = Continuous::from_model(model)?;
    scale_continuous(&ct, k, damping_factor, model.fs)
}

/// The time-scale factor `k` in [`SCALE_RANGE`] that makes the scaled model fit the test best
/// (least squares of the residual about its mean: a log grid, then a golden-section search
/// between the best point's neighbours). 1 when the model has no continuous-time equivalent.
/// The damping is kept ([`estimate_scale_with`] follows a law).
#[must_use]
pub fn estimate_scale(model: &Model, u: &[f64], y: &[f64]) -> f64 {
    estimate_scale_with(
        model,
        TemperatureDamping::Constant,
        DEFAULT_REFERENCE_K,
        u,
        y,
    )
}

/// As [`estimate_scale`], with the damping following `damping` for a model at `reference_k`:
/// still one parameter, the damping factor follows from `k` through `T = reference_k k^2`.
#[must_use]
pub fn estimate_scale_with(
    model: &Model,
    damping: TemperatureDamping,
    reference_k: f64,
    u: &[f64],
    y: &[f64],
) -> f64 {
    let Ok(ct) = Continuous::from_model(model) else {
        return 1.0;
    };
    // Whether the record starts at rest is its reference's, the same at every scale.
    let at_rest = crate::fit::step::quiet_until(u) != 0;
    let cost = |ln_k: f64| -> f64 {
        let k = ln_k.exp();
        let Ok(m) = scale_continuous(&ct, k, damping.factor(k, reference_k), model.fs) else {
            return f64::INFINITY;
        };
        let r: Vec<f64> = y
            .iter()
            .zip(m.simulate_matched_from(u, y, at_rest))
            .map(|(a, b)| a - b)
            .collect();
        let mean = r.iter().sum::<f64>() / r.len().max(1) as f64;
        let sse: f64 = r.iter().map(|v| (v - mean) * (v - mean)).sum();
        if sse.is_finite() {
            sse
        } else {
            f64::INFINITY
        }
    };
    let (lo, hi) = (SCALE_RANGE.0.ln(), SCALE_RANGE.1.ln());
    let n = 29;
    let grid: Vec<f64> = (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect();
    let costs: Vec<f64> = grid.iter().map(|&x| cost(x)).collect();
    let best = costs
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(n - 1)]);
    let g = 0.5 * (5.0f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (cost(x1), cost(x2));
    for _ in 0..30 {
        if f1 < f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = cost(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = cost(x2);
        }
    }
    let x = 0.5 * (a + b);
    if cost(x) <= costs[best] {
        x.exp()
    } else {
        grid[best].exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::second_order;
    use std::f64::consts::PI;

    /// Scaling a second-order probe by `k` moves its poles to `exp(k s / fs)`, keeps its DC
    /// gain and divides its delay; scaling back by `1 / k` returns its step response.
    #[test]
    fn scaling_multiplies_every_pole_and_divides_the_delay() {
        let fs = 10_000.0;
        let (m, s) = second_order(95.0, 0.3, fs, 17);
        let k = 1.08;
        let scaled_model = scaled(&m, k).unwrap();
        let want = (s * k / fs).exp();
        let got = scaled_model.poles().unwrap();
        assert!(
            got.iter().any(|p| (*p - want).norm() < 1e-9)
                && got.iter().any(|p| (*p - want.conj()).norm() < 1e-9),
            "{got:?} against {want:?}"
        );
        assert!((scaled_model.dc_gain() - 1.0).abs() < 1e-9);
        // 17 samples plus the fraction the b coefficients carry, over 1.08.
        assert!(
            scaled_model.delay <= 17 && scaled_model.delay >= 15,
            "{}",
            scaled_model.delay
        );
        // And back: scaling by 1/k returns the model's step response.
        let back = scaled(&scaled_model, 1.0 / k).unwrap();
        let (s0, s1) = (
            crate::fit::continuous::step_response(&m, 400),
            crate::fit::continuous::step_response(&back, 400),
        );
        let worst = s0
            .iter()
            .zip(&s1)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{worst}");
        assert!((scale_for(343.15, 293.15).unwrap() - (343.15f64 / 293.15).sqrt()).abs() < 1e-15);
        assert!(scale_for(-1.0, 293.15).is_err());
    }

    #[test]
    fn the_viscous_damping_factor_follows_the_kinematic_viscosity_of_air() {
        use crate::physics::Gas;
        // Independently: nu = mu / rho of the physics module's air at both temperatures, and
        // the natural frequency's ratio from the speeds of sound.
        let zeta_ratio = |t0: f64, t1: f64, p: f64| {
            let (g0, g1) = (Gas::air(t0, p), Gas::air(t1, p));
            let nu = (g1.viscosity_pa_s / g1.density()) / (g0.viscosity_pa_s / g0.density());
            nu / (g1.speed_of_sound() / g0.speed_of_sound())
        };
        for (t0, t1) in [(293.15, 343.15), (293.15, 253.15), (310.0, 400.0)] {
            let got = viscous_damping_factor(t1, t0).unwrap();
            let want = zeta_ratio(t0, t1, 101_325.0);
            assert!(
                (got / want - 1.0).abs() < 1e-12,
                "{t0} -> {t1}: {got} against {want}"
            );
            // The mean pressure cancels in the ratio.
            let low = zeta_ratio(t0, t1, 20_000.0);
            assert!((got / low - 1.0).abs() < 1e-12, "{got} against {low}");
        }
        // About +22 % from 20 to 70 degrees Celsius (the brief's "about +20 %"), below 1 colder.
        let hot = viscous_damping_factor(343.15, 293.15).unwrap();
        assert!(hot > 1.19 && hot < 1.25, "{hot}");
        assert!(viscous_damping_factor(253.15, 293.15).unwrap() < 0.9);
        // Through the law, from k: the temperature is reference k^2.
        let k = (343.15f64 / 293.15).sqrt();
        assert!((TemperatureDamping::Viscous.factor(k, 293.15) / hot - 1.0).abs() < 1e-12);
        assert_eq!(TemperatureDamping::Constant.factor(k, 293.15), 1.0);
        assert!(viscous_damping_factor(0.0, 293.15).is_err());
    }

    #[test]
    fn damping_scaling_moves_every_pole_to_the_expected_place() {
        let fs = 10_000.0;
        let (m, s) = second_order(95.0, 0.3, fs, 17);
        let (k, f) = (1.08, 1.2);
        let w = s.norm();
        // zeta 0.3 -> 0.36 at natural frequency k w.
        let want_s = Complex::new(-0.36 * k * w, k * w * (1.0 - 0.36f64 * 0.36).sqrt());
        let want = (want_s / fs).exp();
        let got = scaled_with(&m, k, f).unwrap();
        let poles = got.poles().unwrap();
        assert!(
            poles.iter().any(|p| (*p - want).norm() < 1e-9)
                && poles.iter().any(|p| (*p - want.conj()).norm() < 1e-9),
            "{poles:?} against {want:?}"
        );
        assert!((got.dc_gain() - 1.0).abs() < 1e-9, "{}", got.dc_gain());
        // More damping: a smaller overshoot of the step response than the frequency-only scaling.
        let peak = |m: &Model| {
            crate::fit::continuous::step_response(m, 600)
                .into_iter()
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let frequency_only = scaled(&m, k).unwrap();
        assert!(peak(&got) < peak(&frequency_only) - 0.01);
        // A factor of 1 is the frequency-only scaling.
        let same = scaled_with(&m, k, 1.0).unwrap();
        assert_eq!(same, frequency_only);
        // Past critical damping: two real poles -k w (zeta -+ sqrt(zeta^2 - 1)), zeta = 1.2.
        let over = scaled_with(&m, k, 4.0).unwrap();
        let mut got: Vec<f64> = over.poles().unwrap().iter().map(|p| p.re).collect();
        got.sort_by(f64::total_cmp);
        let root = (1.2f64 * 1.2 - 1.0).sqrt();
        let mut want: Vec<f64> = [1.2 - root, 1.2 + root]
            .iter()
            .map(|z| (-k * w * z / fs).exp())
            .collect();
        want.sort_by(f64::total_cmp);
        assert!(
            got.iter().zip(&want).all(|(a, b)| (a - b).abs() < 1e-9),
            "{got:?} against {want:?}"
        );
        assert!((over.dc_gain() - 1.0).abs() < 1e-9);
    }

    /// Continuous poles of `m` (`fs ln z`), real parts, sorted.
    fn real_poles(m: &Model) -> Vec<f64> {
        let mut s: Vec<f64> = m
            .poles()
            .unwrap()
            .iter()
            .map(|z| {
                assert!(z.im.abs() < 1e-12 && z.re > 0.0, "{z:?}");
                z.re.ln() * m.fs
            })
            .collect();
        s.sort_by(f64::total_cmp);
        s
    }

    #[test]
    fn an_overdamped_probes_two_real_poles_move_as_one_mode() {
        // A capillary: corners 4 Hz and 100 Hz, one overdamped mode w_n = sqrt(s1 s2),
        // 2 zeta w_n = -(s1 + s2).
        let m = crate::testing::overdamped(4.0, 100.0, 3000.0, 12);
        let (k, f) = (1.09, 1.3);
        let (old, new) = (real_poles(&m), real_poles(&scaled_with(&m, k, f).unwrap()));
        // w_n goes as k, zeta as f: the product of the poles by k^2, their sum by k f.
        let (p0, p1) = (old[0] * old[1], new[0] * new[1]);
        let (s0, s1) = (old[0] + old[1], new[0] + new[1]);
        assert!((p1 / p0 / (k * k) - 1.0).abs() < 1e-9, "{old:?} -> {new:?}");
        assert!((s1 / s0 / (k * f) - 1.0).abs() < 1e-9, "{old:?} -> {new:?}");
        // The slow corner slows (a viscosity up 30 % more than the sound speed), the fast one
        // speeds up.
        assert!(new[1].abs() < old[1].abs() && new[0].abs() > old[0].abs());
        assert!((scaled_with(&m, k, f).unwrap().dc_gain() - 1.0).abs() < 1e-9);
        // Damping kept: every pole by k.
        let same = real_poles(&scaled_with(&m, k, 1.0).unwrap());
        assert!(same
            .iter()
            .zip(&old)
            .all(|(n, o)| (n / o / k - 1.0).abs() < 1e-9));
    }

    #[test]
    fn a_first_order_capillarys_time_constant_goes_as_the_viscosity() {
        let fs = 3000.0;
        let p = (-2.0 * PI * 5.0 / fs).exp();
        let m = Model {
            fs,
            delay: 3,
            a: vec![-p],
            b: vec![0.0, 1.0 - p],
        };
        let (k, f) = (1.09, 1.3);
        let (old, new) = (real_poles(&m), real_poles(&scaled_with(&m, k, f).unwrap()));
        assert!(
            (new[0] / old[0] / (k / f) - 1.0).abs() < 1e-9,
            "{old:?} -> {new:?}"
        );
    }
}
