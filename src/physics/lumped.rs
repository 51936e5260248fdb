//! The lumped ("low Womersley") second-order approximation of a line:
//! `p_end/p_in ≈ 1/(1 + a₁s + a₂s²)`, natural frequency `ω_n = 1/√a₂`, damping
//! `ζ = a₁/(2√a₂)`.
//!
//! # Model (README 1.3)
//! Each tube keeps the first terms of its two-port: `cosh Γ ≈ 1 + Γ²/2`, `sinhc Γ ≈ 1`, with
//! series impedance per length `R' + sM'` (Poiseuille `R' = 8μ/(πR⁴)`, inertance
//! `M' = c_I ρ/A`, `c_I = 4/3` for the Poiseuille profile, the exact BT limit; 1 for plug flow)
//! and shunt `sC'`, `C' = A/(n p_s)`. Volumes are `sV(σ + 1/k)/p_s + G`. The chain product is
//! truncated at `s²`. For one tube and an end volume this is exactly
//!
//! `a₁ = Λ 8ν/R²`, `a₂ = c_I Λ`, `Λ = (L/a)² γ [1/(2n) + (V/V_t)(σ + 1/k)]`,
//!
//! so `ω_n = 1/√(c_I Λ)` and `ζ = (4/c_I) ν/(R² ω_n)`; with `V ≫ V_t` and `n = k = γ` it is
//! Doebelin's `ω_n = √(3πR²a²/(4LV))`, `ζ = (2√3 ν/(R³a))√(LV/π)`.
//!
//! `n` (and `1/k` of a thermally relaxing cavity) is taken at the approximation's own natural
//! frequency by a short fixed-point iteration (`n → 1` at low Womersley number).
//!
//! # Validity
//! Within a few % of the exact first pole ([`super::modes`]) while the Womersley number
//! `R√(ω_n/ν)` is below about 2; above that it under-predicts damping (by 23-70 % at
//! `Wo = 4-10`) and it never has the higher modes or the transport delay `ΣL/a`.

use num_complex::Complex64;

use super::gas::Gas;
use super::line::{CavityThermal, Element, Line};
use super::PhysicsError;
use crate::error::Result;

/// Inertance factor of the Poiseuille velocity profile (exact BT low-frequency limit).
pub const POISEUILLE_INERTANCE: f64 = 4.0 / 3.0;

/// The lumped second-order approximation of a line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lumped {
    /// Natural frequency `f_n` \[Hz\].
    pub natural_frequency_hz: f64,
    /// Damping ratio `ζ` [-].
    pub damping: f64,
    /// Static gain `1/(1 + R_line G)` [-] (1 without leaks).
    pub dc_gain: f64,
    /// First-order coefficient `a₁` \[s\] of `1 + a₁s + a₂s²` (normalised to DC gain 1).
    pub a1_s: f64,
    /// Second-order coefficient `a₂` \[s²\].
    pub a2_s2: f64,
    /// Womersley number `R√(ω_n/ν)` [-] of the narrowest tube at `ω_n`: the approximation
    /// holds while this is below about 2.
    pub womersley: f64,
}

type Poly = [f64; 3];

fn pmul(a: Poly, b: Poly) -> Poly {
    [
        a[0] * b[0],
        a[0] * b[1] + a[1] * b[0],
        a[0] * b[2] + a[1] * b[1] + a[2] * b[0],
    ]
}

fn padd(a: Poly, b: Poly) -> Poly {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn mmul(a: [[Poly; 2]; 2], b: [[Poly; 2]; 2]) -> [[Poly; 2]; 2] {
    let [[a00, a01], [a10, a11]] = a;
    let [[b00, b01], [b10, b11]] = b;
    [
        [
            padd(pmul(a00, b00), pmul(a01, b10)),
            padd(pmul(a00, b01), pmul(a01, b11)),
        ],
        [
            padd(pmul(a10, b00), pmul(a11, b10)),
            padd(pmul(a10, b01), pmul(a11, b11)),
        ],
    ]
}

/// Lumped approximation of `line` in `gas` with inertance factor `c_i` (use
/// [`POISEUILLE_INERTANCE`]; 1 gives the plug-flow Helmholtz form).
///
/// # Errors
/// [`crate::Error::InvalidArgument`] for an invalid line or gas; [`PhysicsError::NoSecondOrder`] if
/// the line has no inertance or no compliance (no second-order dynamics).
pub fn lumped(line: &Line, gas: &Gas, c_i: f64) -> Result<Lumped> {
    gas.validate()?;
    line.validate()?;
    let rho = gas.density();
    let p_s = gas.pressure_pa;
    let mut omega = 0.0_f64;
    let mut out = None;
    for _ in 0..6 {
        let s_eval = Complex64::new(0.0, omega);
        let one: Poly = [1.0, 0.0, 0.0];
        let zero: Poly = [0.0; 3];
        let mut m = [[one, zero], [zero, one]];
        for e in &line.elements {
            let b = match e {
                Element::Tube(t) => {
                    let area = t.area_m2();
                    let r1 = t.poiseuille_resistance(gas) / t.length_m;
                    let m1 = c_i * rho / area;
                    let n = if omega > 0.0 {
                        t.polytropic_factor(gas, s_eval).re
                    } else {
                        1.0
                    };
                    let c1 = area / (n * p_s);
                    let l = t.length_m;
                    let cosh = [1.0, 0.5 * l * l * c1 * r1, 0.5 * l * l * c1 * m1];
                    [[cosh, [l * r1, l * m1, 0.0]], [[0.0, l * c1, 0.0], cosh]]
                }
                Element::Volume(v) => {
                    let inv_k = match v.thermal {
                        CavityThermal::Polytropic(k) => 1.0 / k,
                        CavityThermal::Relaxing { .. } => {
                            let y = v.admittance(gas, s_eval) - v.leak_m3_per_s_pa;
                            if omega > 0.0 {
                                (y / s_eval).re * p_s / v.volume_m3.max(f64::MIN_POSITIVE) - v.sigma
                            } else {
                                1.0
                            }
                        }
                    };
                    let y = [
                        v.leak_m3_per_s_pa,
                        v.volume_m3 * (v.sigma + inv_k) / p_s,
                        0.0,
                    ];
                    [[one, zero], [y, one]]
                }
                Element::Series(z) => [
                    [one, [z.resistance_pa_s_per_m3, z.inertance_kg_per_m4, 0.0]],
                    [zero, one],
                ],
            };
            m = mmul(m, b);
        }
        let [c0, c1, c2] = m[0][0];
        if !(c2 > 0.0 && c0 > 0.0 && c1 >= 0.0) {
            return Err(PhysicsError::NoSecondOrder.into());
        }
        let (a1, a2) = (c1 / c0, c2 / c0);
        omega = 1.0 / a2.sqrt();
        out = Some((a1, a2, 1.0 / c0));
    }
    let (a1, a2, dc) = out.ok_or(PhysicsError::NoIteration)?;
    let nu = gas.kinematic_viscosity();
    let r_min = line
        .tubes()
        .map(|t| t.radius_m)
        .fold(f64::INFINITY, f64::min);
    Ok(Lumped {
        natural_frequency_hz: omega / (2.0 * core::f64::consts::PI),
        damping: a1 / (2.0 * a2.sqrt()),
        dc_gain: dc,
        a1_s: a1,
        a2_s2: a2,
        womersley: r_min * (omega / nu).sqrt(),
    })
}

/// Doebelin's classical tube-volume formula `(ω_n [rad/s], ζ [-])` for a tube of radius
/// `radius_m` \[m\] and length `length_m` \[m\] ending in a volume `volume_m3` \[m³\] (valid for
/// `V ≫ V_t`, adiabatic gas): `ω_n = √(3πR²a²/(4LV))`, `ζ = (2√3 ν/(R³a))√(LV/π)`.
#[must_use]
pub fn doebelin(gas: &Gas, length_m: f64, radius_m: f64, volume_m3: f64) -> (f64, f64) {
    let a = gas.speed_of_sound();
    let nu = gas.kinematic_viscosity();
    let pi = core::f64::consts::PI;
    let wn = (3.0 * pi * radius_m * radius_m * a * a / (4.0 * length_m * volume_m3)).sqrt();
    let zeta = 2.0 * 3f64.sqrt() * nu / (radius_m.powi(3) * a) * (length_m * volume_m3 / pi).sqrt();
    (wn, zeta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduces_to_doebelin_for_large_volume() {
        // V ≫ V_t, adiabatic tube (n = γ is what Doebelin assumes; our n → 1 only changes
        // the tube's own compliance term, negligible here).
        let gas = Gas::standard_air();
        let (l, r, v) = (0.3, 0.5e-3, 50e-6);
        let lump = lumped(
            &Line::new().tube(l, r).volume(v),
            &gas,
            POISEUILLE_INERTANCE,
        )
        .expect("lumped");
        let (wn, z) = doebelin(&gas, l, r, v);
        let wl = 2.0 * core::f64::consts::PI * lump.natural_frequency_hz;
        assert!((wl / wn - 1.0).abs() < 2e-3, "{wl} vs {wn}");
        assert!(
            (lump.damping / z - 1.0).abs() < 2e-3,
            "{} vs {z}",
            lump.damping
        );
    }

    #[test]
    fn closed_form_damping_grows_with_length() {
        // ζ = (2√3 νL/(R²a)) √(1/2 + V/V_t) (with n = k = γ): monotonic in L at fixed R, V.
        let gas = Gas::standard_air();
        let mut last = 0.0;
        for l in [0.1, 0.2, 0.4, 0.8] {
            let z = lumped(
                &Line::new().tube(l, 0.55e-3).volume(1e-6),
                &gas,
                POISEUILLE_INERTANCE,
            )
            .expect("lumped")
            .damping;
            assert!(z > last);
            last = z;
        }
    }

    #[test]
    fn a_line_without_a_tube_has_no_second_order_dynamics() {
        let gas = Gas::standard_air();
        let e = lumped(&Line::new().volume(50e-6), &gas, POISEUILLE_INERTANCE).unwrap_err();
        assert!(
            matches!(e.stage(), Some(PhysicsError::NoSecondOrder)),
            "{e:?}"
        );
        assert_eq!(
            e.to_string(),
            "lumped approximation: the line has no second-order dynamics (no tube, or no compliance)"
        );
    }
}
