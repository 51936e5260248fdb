//! Amplitude-dependent (quadratic) losses: minor (orifice) losses `Δp = K ρ u|u|/2` at the
//! ends of a line (README 1.7), by an equal-dissipation describing function.
//!
//! # Model
//! For a volume flow `Q = Q₀ sin ωt` through an area `A`, the quadratic loss dissipates per
//! cycle what a linear resistance `R_eq = (4/(3π)) K ρ U/A` does, `U = Q₀/A`. A step of size
//! `Δp` drives a peak flow `Q₀` that is found from the lumped second-order model of the line
//! ([`super::lumped`](mod@super::lumped)) *including* `R_eq`, by a fixed-point iteration (`R_eq` raises the
//! damping, which lowers `Q₀`). `R_eq` is then placed as a series resistance at the inlet of
//! the line, so every other model (exact modes, simulation) sees it.
//!
//! `K` is the sum over one stroke of the entry and exit coefficients (sharp-edged entry
//! `K ≈ 0.5`, exit into a large space `K ≈ 1.0`; both ends see one of each per direction), plus
//! `1/C_d²` for an extra pinhole.
//!
//! # Limits
//! A quasi-linearisation: it gives the damping's growth with step amplitude (the signature of
//! row 4 in README section 3), not the waveform distortion or the rise/fall asymmetry of the
//! real nonlinearity. Mean-pressure effects of large steps (row 5) are captured by simulating
//! at the mid-step mean pressure ([`super::gas::Gas::with_pressure`]). Not modelled: turbulent
//! wall friction, shock formation.

use super::gas::Gas;
use super::line::{CavityThermal, Element, Line, SeriesImpedance};
use super::lumped::{lumped, POISEUILLE_INERTANCE};
use crate::error::{Error, Result};

/// Typical sharp-edged entry loss coefficient.
pub const K_ENTRY: f64 = 0.5;
/// Typical exit loss coefficient (into a large space).
pub const K_EXIT: f64 = 1.0;

/// Minor losses of a line, applied by describing function.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MinorLosses {
    /// Total loss coefficient `K` [-] per stroke (e.g. `K_ENTRY + K_EXIT = 1.5`).
    pub k: f64,
    /// Step amplitude `|Δp|` \[Pa\] that sets the flow amplitude.
    pub step_amplitude_pa: f64,
}

/// Result of [`equivalent_resistance`].
#[derive(Debug, Clone, PartialEq)]
pub struct Quasilinear {
    /// Equivalent linear resistance `R_eq` [Pa s/m³].
    pub resistance_pa_s_per_m3: f64,
    /// Peak mean velocity `U` [m/s] in the first tube.
    pub velocity_m_s: f64,
    /// The line with `R_eq` inserted at its inlet.
    pub line: Line,
}

/// Largest `|dy/dt|/ω_n` of the unit step response of `1/(1 + 2ζ s/ω_n + s²/ω_n²)` [-].
fn peak_rate(zeta: f64) -> f64 {
    if zeta < 1.0 {
        let wd = (1.0 - zeta * zeta).sqrt();
        // y' = (ω_n/√(1−ζ²)) e^{−ζω_n t} sin(ω_d t): maximum at ω_d t = atan(√(1−ζ²)/ζ).
        let phi = wd.atan2(zeta);
        (-zeta * phi / wd).exp()
    } else {
        // Two real poles p1 < p2 (in units of ω_n): y' ∝ e^{−p1 t} − e^{−p2 t}.
        let root = (zeta * zeta - 1.0).max(1e-12).sqrt();
        let (p1, p2) = (zeta - root, zeta + root);
        let t = (p2 / p1).ln() / (p2 - p1);
        p1 * p2 / (p2 - p1) * ((-p1 * t).exp() - (-p2 * t).exp())
    }
}

/// The equivalent linear resistance of the minor losses of `line` for a step of the given
/// amplitude, and the line with it inserted at the inlet.
///
/// # Errors
/// [`Error::InvalidArgument`] for a negative `K` or amplitude, a line without tubes; errors of
/// [`lumped`].
pub fn equivalent_resistance(line: &Line, gas: &Gas, losses: &MinorLosses) -> Result<Quasilinear> {
    let ok = [losses.k, losses.step_amplitude_pa]
        .iter()
        .all(|x| x.is_finite() && *x >= 0.0);
    if !ok {
        return Err(Error::InvalidArgument {
            what: "minor losses",
            message: format!(
                "K {} and step amplitude {} Pa must be finite and non-negative",
                losses.k, losses.step_amplitude_pa
            ),
        });
    }
    let area = line
        .tubes()
        .next()
        .map(super::line::Tube::area_m2)
        .ok_or_else(|| Error::InvalidArgument {
            what: "line",
            message: "minor losses need a tube".into(),
        })?;
    // Total compliance seen by the flow through the inlet at low frequency.
    let compliance: f64 = line
        .elements
        .iter()
        .map(|e| match e {
            Element::Tube(t) => t.volume_m3() / gas.pressure_pa,
            Element::Volume(v) => {
                let inv_k = match v.thermal {
                    CavityThermal::Polytropic(k) => 1.0 / k,
                    CavityThermal::Relaxing { .. } => 1.0 / gas.gamma,
                };
                v.volume_m3 * (v.sigma + inv_k) / gas.pressure_pa
            }
            Element::Series(_) => 0.0,
        })
        .sum();
    let rho = gas.density();
    let mut r_eq = 0.0;
    let mut velocity = 0.0;
    for _ in 0..50 {
        let with = with_inlet_resistance(line, r_eq);
        let lp = lumped(&with, gas, POISEUILLE_INERTANCE)?;
        let wn = 2.0 * core::f64::consts::PI * lp.natural_frequency_hz;
        let q0 = compliance * losses.step_amplitude_pa * wn * peak_rate(lp.damping);
        velocity = q0 / area;
        let next = 4.0 / (3.0 * core::f64::consts::PI) * losses.k * rho * velocity / area;
        let converged = (next - r_eq).abs() <= 1e-9 * next.abs().max(1e-30);
        // Damped update: the map is a contraction near the fixed point but can overshoot.
        r_eq = 0.5 * (r_eq + next);
        if converged {
            break;
        }
    }
    Ok(Quasilinear {
        resistance_pa_s_per_m3: r_eq,
        velocity_m_s: velocity,
        line: with_inlet_resistance(line, r_eq),
    })
}

fn with_inlet_resistance(line: &Line, r: f64) -> Line {
    let mut elements = Vec::with_capacity(line.elements.len() + 1);
    elements.push(Element::Series(SeriesImpedance {
        resistance_pa_s_per_m3: r,
        inertance_kg_per_m4: 0.0,
    }));
    elements.extend(line.elements.iter().copied());
    Line { elements }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_rate_limits() {
        // Undamped: max of sin is 1. Critically damped: ω_n t e^{−ω_n t} peaks at 1/e.
        assert!((peak_rate(0.0) - 1.0).abs() < 1e-12);
        assert!((peak_rate(1.0 + 1e-7) - (-1.0_f64).exp()).abs() < 1e-4);
        assert!((peak_rate(1.0 - 1e-7) - (-1.0_f64).exp()).abs() < 1e-4);
    }

    #[test]
    fn resistance_grows_with_amplitude() {
        let gas = Gas::standard_air();
        let line = Line::new().tube(0.2, 0.55e-3).volume(1000e-9);
        let mut last = -1.0;
        for dp in [100.0, 1e3, 1e4, 3e4] {
            let q = equivalent_resistance(
                &line,
                &gas,
                &MinorLosses {
                    k: K_ENTRY + K_EXIT,
                    step_amplitude_pa: dp,
                },
            )
            .expect("quasilinear");
            assert!(q.resistance_pa_s_per_m3 > last);
            last = q.resistance_pa_s_per_m3;
        }
    }
}
