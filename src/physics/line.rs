//! Bergh-Tijdeman (1965) lines: tubes, volumes and series impedances chained as ABCD
//! (transfer-matrix) two-ports, from the measuring point (input, `p_in`) to a closed end
//! (the transducer, `p_end`).
//!
//! # Model
//! Time dependence `e^{st}`; `p` is the pressure perturbation \[Pa\], `Q` the volume flow
//! [m³/s], positive towards the closed end. For a tube of radius `R`, area `A = πR²`,
//! length `L` in a gas of density `ρ`, viscosity `μ`, `ν = μ/ρ`, mean pressure `p_s`:
//!
//! * shear wave number squared `α² = −sR²/ν` (on the frequency axis `α = i^{3/2} R √(ρω/μ)`);
//! * `B(w) = J₂(√w)/J₀(√w)` ([`super::bessel::j2_over_j0_of_square`]);
//! * series impedance per length `Z_s = −sρ/(A B(α²)) = (μ/(A R²)) α²/B(α²)`
//!   (Poiseuille `8μ/(πR⁴)` at DC, inertance `ρ/A` at high frequency);
//! * polytropic factor `n = [1 + ((γ−1)/γ) B(α² Pr)]⁻¹` (1 isothermal … γ adiabatic);
//! * shunt admittance per length `Y_p = sA/(n p_s)`;
//! * `Γ = φL` with `Γ² = Z_s Y_p L²`, and the tube two-port
//!   `[[cosh Γ, Z_s L sinhc Γ], [Y_p L sinhc Γ, cosh Γ]]`, `sinhc x = sinh x / x` — which is
//!   `[[cosh Γ, Z_c sinh Γ], [sinh Γ / Z_c, cosh Γ]]` with `Z_c = Z_s/φ`, written with even
//!   functions of `Γ` only, so no square-root branch enters and `s = 0` is regular;
//! * a volume is the shunt `Y = sV(σ + 1/k)/p_s + G_leak` (`σ`: diaphragm compliance,
//!   `ΔV/V = σ Δp/p_s`; `k`: polytropic constant of the cavity gas, or a thermally relaxing
//!   cylindrical cavity whose `1/k` goes from 1 to `1/γ` with the same Bessel ratio as `n`);
//! * a series impedance is `Z = R + sM` (orifice resistance, end-correction inertance `ρδ/A`).
//!
//! With the chain `[p_in, Q_in]ᵀ = M [p_end, Q_end]ᵀ` and `Q_end = 0`, the response is
//! `p_end/p_in = 1/M₁₁`. This equals the literal BT recursion (checked in the host tests)
//! and is a meromorphic function of `s`: it can be evaluated anywhere in the complex plane
//! ([`Line::response`]), which the pole finder in [`super::modes`] uses.
//!
//! Valid for low reduced frequency `ωR/a ≪ 1` (Tijdeman 1975); no mean flow, no branches.

use num_complex::Complex64;

use super::bessel::j2_over_j0_of_square;
use super::gas::Gas;
use crate::error::{Error, Result};

/// A circular tube of the line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tube {
    /// Length `L` \[m\].
    pub length_m: f64,
    /// Inner radius `R` \[m\] (half the inner diameter).
    pub radius_m: f64,
}

impl Tube {
    /// A tube of length `length_m` \[m\] and inner radius `radius_m` \[m\].
    #[must_use]
    pub fn with_radius(length_m: f64, radius_m: f64) -> Self {
        Self { length_m, radius_m }
    }

    /// A tube of length `length_m` \[m\] and inner diameter `diameter_m` \[m\].
    #[must_use]
    pub fn with_diameter(length_m: f64, diameter_m: f64) -> Self {
        Self::with_radius(length_m, 0.5 * diameter_m)
    }

    /// Cross-section `A = πR²` \[m²\].
    #[must_use]
    pub fn area_m2(&self) -> f64 {
        core::f64::consts::PI * self.radius_m * self.radius_m
    }

    /// Internal volume `V_t = πR²L` \[m³\].
    #[must_use]
    pub fn volume_m3(&self) -> f64 {
        self.area_m2() * self.length_m
    }

    /// Poiseuille (DC) resistance `8μL/(πR⁴)` [Pa s/m³] in `gas`.
    #[must_use]
    pub fn poiseuille_resistance(&self, gas: &Gas) -> f64 {
        8.0 * gas.viscosity_pa_s * self.length_m / (core::f64::consts::PI * self.radius_m.powi(4))
    }

    /// Womersley number `R√(ω/ν)` [-] at angular frequency `omega_rad_s` [rad/s].
    #[must_use]
    pub fn womersley(&self, gas: &Gas, omega_rad_s: f64) -> f64 {
        self.radius_m * (omega_rad_s / gas.kinematic_viscosity()).sqrt()
    }

    /// Series impedance per length `Z_s` [Pa s/m⁴] and shunt admittance per length `Y_p`
    /// [m⁴/(Pa s) per m², i.e. m³/(Pa s) per m] at complex frequency `s` [rad/s].
    #[must_use]
    pub fn per_length(&self, gas: &Gas, s: Complex64) -> (Complex64, Complex64) {
        let r2 = self.radius_m * self.radius_m;
        let area = core::f64::consts::PI * r2;
        let alpha2 = -s * r2 / gas.kinematic_viscosity();
        let z_s = gas.viscosity_pa_s / (area * r2) * w_over_b(alpha2);
        let n = polytropic_factor_of(gas, alpha2 * gas.prandtl);
        let y_p = s * area / (n * gas.pressure_pa);
        (z_s, y_p)
    }

    /// Polytropic factor `n` [-] of the gas in this tube at complex frequency `s` [rad/s]:
    /// 1 (isothermal) at low frequency, `γ` (adiabatic) at high frequency.
    #[must_use]
    pub fn polytropic_factor(&self, gas: &Gas, s: Complex64) -> Complex64 {
        let alpha2 = -s * self.radius_m * self.radius_m / gas.kinematic_viscosity();
        polytropic_factor_of(gas, alpha2 * gas.prandtl)
    }

    /// Shear wave number squared `α² = −sR²/ν` [-] at complex frequency `s` [rad/s].
    #[must_use]
    pub fn shear_wave_number_squared(&self, gas: &Gas, s: Complex64) -> Complex64 {
        -s * self.radius_m * self.radius_m / gas.kinematic_viscosity()
    }
}

/// `w / B(w)`, regular at `w = 0` (value 8).
fn w_over_b(w: Complex64) -> Complex64 {
    if w.norm() < 1e-6 {
        // B = (w/8)(1 + w/6 + 11w²/384 + …): w/B = 8(1 − w/6 − w²/1152 + …)
        8.0 * (1.0 - w / 6.0 - w * w / 1152.0)
    } else {
        w / j2_over_j0_of_square(w)
    }
}

/// `n = [1 + ((γ−1)/γ) B(w_pr)]⁻¹` with `w_pr = α² Pr`.
fn polytropic_factor_of(gas: &Gas, w_pr: Complex64) -> Complex64 {
    let b = j2_over_j0_of_square(w_pr);
    1.0 / (1.0 + (gas.gamma - 1.0) / gas.gamma * b)
}

/// How the gas in a volume responds thermally.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CavityThermal {
    /// A constant polytropic constant `k` [-] (BT: 1.4 isentropic or 1.0 isothermal).
    Polytropic(f64),
    /// A cylindrical cavity of this radius \[m\] whose gas exchanges heat with the wall:
    /// `1/k` goes from 1 (slow) to `1/γ` (fast) as `1/n` of a tube of the same radius.
    Relaxing {
        /// Cavity radius \[m\].
        radius_m: f64,
    },
}

/// A volume (cavity, transducer volume) at a junction or at the closed end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Volume {
    /// Volume `V` \[m³\].
    pub volume_m3: f64,
    /// Diaphragm compliance `σ` [-]: `ΔV/V = σ Δp/p_s`; behaves as extra volume.
    pub sigma: f64,
    /// Thermal behaviour of the gas in the volume.
    pub thermal: CavityThermal,
    /// Leak conductance `G` [m³/(s Pa)] to the (constant) reference pressure: `Q = G p`.
    pub leak_m3_per_s_pa: f64,
}

impl Volume {
    /// An isentropic (`k = 1.4`), rigid (`σ = 0`), tight volume of `volume_m3` \[m³\].
    #[must_use]
    pub fn new(volume_m3: f64) -> Self {
        Self {
            volume_m3,
            sigma: 0.0,
            thermal: CavityThermal::Polytropic(1.4),
            leak_m3_per_s_pa: 0.0,
        }
    }

    /// Shunt admittance `Y = sV(σ + 1/k)/p_s + G` [m³/(s Pa)] at complex frequency `s`.
    #[must_use]
    pub fn admittance(&self, gas: &Gas, s: Complex64) -> Complex64 {
        let inv_k = match self.thermal {
            CavityThermal::Polytropic(k) => Complex64::new(1.0 / k, 0.0),
            CavityThermal::Relaxing { radius_m } => {
                let w = -s * radius_m * radius_m / gas.kinematic_viscosity() * gas.prandtl;
                1.0 / polytropic_factor_of(gas, w)
            }
        };
        s * self.volume_m3 * (self.sigma + inv_k) / gas.pressure_pa + self.leak_m3_per_s_pa
    }
}

/// A lumped series impedance `Z = R + sM`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesImpedance {
    /// Resistance `R` [Pa s/m³].
    pub resistance_pa_s_per_m3: f64,
    /// Inertance `M` [kg/m⁴] (an end correction `δ` of a hole of area `A` is `ρδ/A`).
    pub inertance_kg_per_m4: f64,
}

/// One element of a [`Line`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Element {
    /// A Bergh-Tijdeman tube.
    Tube(Tube),
    /// A volume (shunt to ground).
    Volume(Volume),
    /// A lumped series impedance.
    Series(SeriesImpedance),
}

/// A 2×2 complex matrix times `e^{log_scale}`, so long lossy tubes do not overflow.
#[derive(Debug, Clone, Copy)]
struct Abcd {
    m: [[Complex64; 2]; 2],
    log_scale: f64,
}

impl Abcd {
    fn identity() -> Self {
        let (o, z) = (Complex64::new(1.0, 0.0), Complex64::new(0.0, 0.0));
        Self {
            m: [[o, z], [z, o]],
            log_scale: 0.0,
        }
    }

    fn then(self, b: [[Complex64; 2]; 2], log_scale: f64) -> Self {
        let a = self.m;
        let mut m = [
            [
                a[0][0] * b[0][0] + a[0][1] * b[1][0],
                a[0][0] * b[0][1] + a[0][1] * b[1][1],
            ],
            [
                a[1][0] * b[0][0] + a[1][1] * b[1][0],
                a[1][0] * b[0][1] + a[1][1] * b[1][1],
            ],
        ];
        let mut log_scale = self.log_scale + log_scale;
        // Keep the entries moderate (the scale factor carries the magnitude). Row 0 is in
        // pressure units, row 1 in flow units; normalise by the first row only, which is
        // what the response needs.
        let big = m[0][0].norm().max(m[0][1].norm() * 1e-12);
        if big > 1e100 {
            for row in &mut m {
                for e in row.iter_mut() {
                    *e /= big;
                }
            }
            log_scale += big.ln();
        }
        Self { m, log_scale }
    }
}

/// `(cosh Γ, sinhc Γ, scale)` from `Γ²`, with `cosh Γ = c e^{scale}`, `sinhc Γ = sc e^{scale}`.
fn cosh_sinhc(gamma2: Complex64) -> (Complex64, Complex64, f64) {
    if gamma2.norm() < 1e-2 {
        let g = gamma2;
        let c = 1.0 + g / 2.0 * (1.0 + g / 12.0 * (1.0 + g / 30.0 * (1.0 + g / 56.0)));
        let sc = 1.0 + g / 6.0 * (1.0 + g / 20.0 * (1.0 + g / 42.0 * (1.0 + g / 72.0)));
        return (c, sc, 0.0);
    }
    let gamma = gamma2.sqrt(); // Re Γ ≥ 0; both functions are even in Γ
    if gamma.re < 30.0 {
        return (gamma.cosh(), gamma.sinh() / gamma, 0.0);
    }
    // cosh Γ = e^{Re Γ} e^{i Im Γ} (1 + e^{−2Γ})/2, sinh likewise with (1 − e^{−2Γ}).
    let phase = Complex64::from_polar(1.0, gamma.im);
    let e2 = (-2.0 * gamma).exp();
    (
        phase * (1.0 + e2) / 2.0,
        phase * (1.0 - e2) / (2.0 * gamma),
        gamma.re,
    )
}

/// A pressure-measuring line: elements from the measuring point (input) to the closed end.
///
/// ```
/// use unlag::physics::{gas::Gas, line::Line};
/// // 0.5 m of 1.5 mm bore tube ending in a 300 mm³ transducer volume.
/// let line = Line::new().tube(0.5, 0.75e-3).volume(300e-9);
/// let h = line.frequency_response(&Gas::standard_air(), 1.0);
/// assert!((h.norm() - 1.0).abs() < 1e-3);
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Line {
    /// The elements in order from the input.
    pub elements: Vec<Element>,
}

impl Line {
    /// An empty line (response 1).
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a tube of length `length_m` \[m\] and inner radius `radius_m` \[m\].
    #[must_use]
    pub fn tube(mut self, length_m: f64, radius_m: f64) -> Self {
        self.elements
            .push(Element::Tube(Tube::with_radius(length_m, radius_m)));
        self
    }

    /// Appends an isentropic, rigid, tight volume of `volume_m3` \[m³\] (see [`Volume::new`]).
    #[must_use]
    pub fn volume(mut self, volume_m3: f64) -> Self {
        self.elements.push(Element::Volume(Volume::new(volume_m3)));
        self
    }

    /// Appends any element.
    #[must_use]
    pub fn with(mut self, element: Element) -> Self {
        self.elements.push(element);
        self
    }

    /// The tubes of the line, in order.
    pub fn tubes(&self) -> impl Iterator<Item = &Tube> {
        self.elements.iter().filter_map(|e| match e {
            Element::Tube(t) => Some(t),
            _ => None,
        })
    }

    /// Checks every dimension is finite and positive (volumes and leaks may be zero).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the element.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |what: &'static str, message: String| Err(Error::InvalidArgument { what, message });
        for (i, e) in self.elements.iter().enumerate() {
            match e {
                Element::Tube(t) => {
                    if !(t.length_m.is_finite() && t.length_m > 0.0) {
                        return bad(
                            "line",
                            format!("tube {}: length {} m must be positive", i + 1, t.length_m),
                        );
                    }
                    if !(t.radius_m.is_finite() && t.radius_m > 0.0) {
                        return bad(
                            "line",
                            format!("tube {}: radius {} m must be positive", i + 1, t.radius_m),
                        );
                    }
                }
                Element::Volume(v) => {
                    let k_ok = match v.thermal {
                        CavityThermal::Polytropic(k) => k.is_finite() && k >= 1.0,
                        CavityThermal::Relaxing { radius_m } => {
                            radius_m.is_finite() && radius_m > 0.0
                        }
                    };
                    let ok = [v.volume_m3, v.sigma, v.leak_m3_per_s_pa]
                        .iter()
                        .all(|x| x.is_finite() && *x >= 0.0);
                    if !(ok && k_ok) {
                        return bad(
                            "volume",
                            format!("element {}: volume, sigma and leak must be finite and non-negative, k >= 1 ({v:?})", i + 1),
                        );
                    }
                }
                Element::Series(z) => {
                    let ok = [z.resistance_pa_s_per_m3, z.inertance_kg_per_m4]
                        .iter()
                        .all(|x| x.is_finite() && *x >= 0.0);
                    if !ok {
                        return bad(
                            "series impedance",
                            format!("element {}: must be finite and non-negative ({z:?})", i + 1),
                        );
                    }
                }
            }
        }
        Ok(())
    }

    /// Front delay `ΣL/a` \[s\]: the time the first wave front needs to reach the closed end.
    #[must_use]
    pub fn front_delay_s(&self, gas: &Gas) -> f64 {
        self.tubes().map(|t| t.length_m).sum::<f64>() / gas.speed_of_sound()
    }

    /// DC resistance of the whole line [Pa s/m³]: Poiseuille resistances plus series
    /// resistances.
    #[must_use]
    pub fn dc_resistance(&self, gas: &Gas) -> f64 {
        self.elements
            .iter()
            .map(|e| match e {
                Element::Tube(t) => t.poiseuille_resistance(gas),
                Element::Series(z) => z.resistance_pa_s_per_m3,
                Element::Volume(_) => 0.0,
            })
            .sum()
    }

    /// `M₁₁` of the chain as `(mantissa, log_scale)`: `p_in/p_end = mantissa · e^{log_scale}`.
    fn m11(&self, gas: &Gas, s: Complex64) -> (Complex64, f64) {
        let zero = Complex64::new(0.0, 0.0);
        let one = Complex64::new(1.0, 0.0);
        let mut abcd = Abcd::identity();
        for e in &self.elements {
            abcd = match e {
                Element::Tube(t) => {
                    let (z_s, y_p) = t.per_length(gas, s);
                    let l = t.length_m;
                    let (c, sc, scale) = cosh_sinhc(z_s * y_p * l * l);
                    abcd.then([[c, z_s * l * sc], [y_p * l * sc, c]], scale)
                }
                Element::Volume(v) => abcd.then([[one, zero], [v.admittance(gas, s), one]], 0.0),
                Element::Series(z) => {
                    let imp = z.resistance_pa_s_per_m3 + s * z.inertance_kg_per_m4;
                    abcd.then([[one, imp], [zero, one]], 0.0)
                }
            };
        }
        (abcd.m[0][0], abcd.log_scale)
    }

    /// `p_in/p_end = M₁₁(s)` [-] at complex frequency `s` [rad/s] (the reciprocal of the
    /// response; entire where the Bessel ratios are, which the pole finder uses). Can
    /// overflow to infinity far into the right half plane or at very high frequency.
    #[must_use]
    pub fn inverse_response(&self, gas: &Gas, s: Complex64) -> Complex64 {
        let (m, log) = self.m11(gas, s);
        m * log.exp()
    }

    /// Response `H(s) = p_end/p_in` [-] at complex frequency `s` [rad/s].
    #[must_use]
    pub fn response(&self, gas: &Gas, s: Complex64) -> Complex64 {
        let (m, log) = self.m11(gas, s);
        (1.0 / m) * (-log).exp()
    }

    /// Frequency response `H(i 2π f)` [-] (amplitude ratio and phase, negative = lag) at
    /// frequency `frequency_hz` \[Hz\].
    #[must_use]
    pub fn frequency_response(&self, gas: &Gas, frequency_hz: f64) -> Complex64 {
        self.response(
            gas,
            Complex64::new(0.0, 2.0 * core::f64::consts::PI * frequency_hz),
        )
    }

    /// Static (DC) gain `H(0)` [-]: 1 without leaks, `1/(1 + R_line G)` with one leak `G` at
    /// the end.
    #[must_use]
    pub fn dc_gain(&self, gas: &Gas) -> f64 {
        self.response(gas, Complex64::new(0.0, 0.0)).re
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inviscid_limit_of_characteristic_impedance() {
        // Wide tube, high frequency: Z_c = sqrt(Z_s/Y_p) -> ρa/A (README 1.2).
        let gas = Gas::standard_air();
        let t = Tube::with_radius(1.0, 10e-3);
        let s = Complex64::new(0.0, 2.0 * core::f64::consts::PI * 2000.0);
        let (z_s, y_p) = t.per_length(&gas, s);
        let zc = (z_s / y_p).sqrt();
        let want = gas.density() * gas.speed_of_sound() / t.area_m2();
        assert!((zc.norm() / want - 1.0).abs() < 0.01, "{zc} vs {want}");
        // and n -> γ
        assert!((t.polytropic_factor(&gas, s).re - 1.4).abs() < 0.02);
    }

    #[test]
    fn dc_series_impedance_is_poiseuille() {
        let gas = Gas::standard_air();
        let t = Tube::with_radius(2.0, 0.4e-3);
        let (z_s, y_p) = t.per_length(&gas, Complex64::new(0.0, 0.0));
        let want = 8.0 * gas.viscosity_pa_s / (core::f64::consts::PI * 0.4e-3_f64.powi(4));
        assert!((z_s.re / want - 1.0).abs() < 1e-12 && z_s.im.abs() < 1e-6 * want);
        assert_eq!(y_p, Complex64::new(0.0, 0.0));
    }

    #[test]
    fn long_lossy_line_does_not_overflow() {
        let gas = Gas::standard_air();
        let line = Line::new().tube(20.0, 0.2e-3).volume(1e-6);
        for f in [1e3, 1e5, 1e7] {
            let h = line.frequency_response(&gas, f);
            assert!(h.is_finite() && h.norm() < 1e-10, "{f}: {h}");
        }
    }
}
