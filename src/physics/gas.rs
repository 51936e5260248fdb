//! Gas properties versus temperature and mean (static) pressure: density, isentropic speed of
//! sound, Sutherland viscosity, kinematic viscosity and Prandtl number.
//!
//! The defaults are dry air (`R_g = 287.05 J/(kg K)`, `γ = 1.4`, `Pr = 0.71`,
//! Sutherland `μ_ref = 1.716e-5 Pa s` at `T_ref = 273.15 K`, `S = 110.4 K`, White,
//! *Viscous Fluid Flow*). Every quantity is SI: kelvin, pascal, kg/m³, m/s, Pa s, m²/s.

use crate::error::{Error, Result};

/// Specific gas constant of dry air [J/(kg K)].
pub const AIR_GAS_CONSTANT: f64 = 287.05;
/// Ratio of specific heats of air [-].
pub const AIR_GAMMA: f64 = 1.4;
/// Prandtl number of air [-] (almost independent of temperature).
pub const AIR_PRANDTL: f64 = 0.71;
/// Sutherland reference viscosity of air [Pa s] at [`SUTHERLAND_T_REF`].
pub const SUTHERLAND_MU_REF: f64 = 1.716e-5;
/// Sutherland reference temperature \[K\].
pub const SUTHERLAND_T_REF: f64 = 273.15;
/// Sutherland constant of air \[K\].
pub const SUTHERLAND_S: f64 = 110.4;
/// Standard atmosphere \[Pa\].
pub const STANDARD_PRESSURE: f64 = 101_325.0;
/// 20 °C \[K\].
pub const ROOM_TEMPERATURE: f64 = 293.15;

/// Dynamic viscosity of air by Sutherland's law \[Pa s\] at temperature `temperature_k` \[K\]:
/// `μ = μ_ref (T/T_ref)^{3/2} (T_ref + S)/(T + S)`.
#[must_use]
pub fn sutherland_viscosity(temperature_k: f64) -> f64 {
    SUTHERLAND_MU_REF
        * (temperature_k / SUTHERLAND_T_REF).powf(1.5)
        * (SUTHERLAND_T_REF + SUTHERLAND_S)
        / (temperature_k + SUTHERLAND_S)
}

/// The gas in the lines and cavities, at its mean temperature and mean absolute pressure.
///
/// Build it with [`Gas::air`] (Sutherland viscosity) and override single properties with the
/// `with_*` methods (the Bergh-Tijdeman report, for instance, uses `μ = 1.82e-5 Pa s`,
/// `Pr = 0.707`). All fields are SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gas {
    /// Mean temperature \[K\].
    pub temperature_k: f64,
    /// Mean (static) absolute pressure `p_s` \[Pa\].
    pub pressure_pa: f64,
    /// Ratio of specific heats `γ` [-].
    pub gamma: f64,
    /// Specific gas constant `R_g` [J/(kg K)].
    pub gas_constant: f64,
    /// Dynamic viscosity `μ` [Pa s].
    pub viscosity_pa_s: f64,
    /// Prandtl number `Pr` [-].
    pub prandtl: f64,
}

impl Gas {
    /// Dry air at `temperature_k` \[K\] and mean absolute pressure `pressure_pa` \[Pa\], viscosity
    /// from [`sutherland_viscosity`].
    #[must_use]
    pub fn air(temperature_k: f64, pressure_pa: f64) -> Self {
        Self {
            temperature_k,
            pressure_pa,
            gamma: AIR_GAMMA,
            gas_constant: AIR_GAS_CONSTANT,
            viscosity_pa_s: sutherland_viscosity(temperature_k),
            prandtl: AIR_PRANDTL,
        }
    }

    /// Air at 20 °C and one standard atmosphere.
    #[must_use]
    pub fn standard_air() -> Self {
        Self::air(ROOM_TEMPERATURE, STANDARD_PRESSURE)
    }

    /// The same gas with the dynamic viscosity set to `viscosity_pa_s` [Pa s].
    #[must_use]
    pub fn with_viscosity(self, viscosity_pa_s: f64) -> Self {
        Self {
            viscosity_pa_s,
            ..self
        }
    }

    /// The same gas with the Prandtl number set to `prandtl` [-].
    #[must_use]
    pub fn with_prandtl(self, prandtl: f64) -> Self {
        Self { prandtl, ..self }
    }

    /// The same gas at mean absolute pressure `pressure_pa` \[Pa\] (the viscosity is kept).
    #[must_use]
    pub fn with_pressure(self, pressure_pa: f64) -> Self {
        Self {
            pressure_pa,
            ..self
        }
    }

    /// Checks that every property is finite and positive (and `γ > 1`).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the first bad property.
    pub fn validate(&self) -> Result<()> {
        let checks: [(&'static str, f64); 5] = [
            ("temperature", self.temperature_k),
            ("pressure", self.pressure_pa),
            ("gas constant", self.gas_constant),
            ("viscosity", self.viscosity_pa_s),
            ("Prandtl number", self.prandtl),
        ];
        for (what, value) in checks {
            if !(value.is_finite() && value > 0.0) {
                return Err(Error::InvalidArgument {
                    what,
                    message: format!("{value} must be finite and positive"),
                });
            }
        }
        if !(self.gamma.is_finite() && self.gamma > 1.0) {
            return Err(Error::InvalidArgument {
                what: "gamma",
                message: format!("{} must be finite and above 1", self.gamma),
            });
        }
        Ok(())
    }

    /// Density `ρ = p_s/(R_g T)` [kg/m³].
    #[must_use]
    pub fn density(&self) -> f64 {
        self.pressure_pa / (self.gas_constant * self.temperature_k)
    }

    /// Isentropic speed of sound `a = √(γ R_g T)` [m/s].
    #[must_use]
    pub fn speed_of_sound(&self) -> f64 {
        (self.gamma * self.gas_constant * self.temperature_k).sqrt()
    }

    /// Kinematic viscosity `ν = μ/ρ` [m²/s] (depends on temperature and pressure).
    #[must_use]
    pub fn kinematic_viscosity(&self) -> f64 {
        self.viscosity_pa_s / self.density()
    }
}

impl Default for Gas {
    fn default() -> Self {
        Self::standard_air()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rtol: f64) -> bool {
        (a - b).abs() <= rtol * b.abs()
    }

    #[test]
    fn speed_of_sound_of_air() {
        // README 1.1: a = 343.2 m/s at 293.15 K; 331.3 m/s at 0 °C is the textbook value.
        assert!(close(
            Gas::air(293.15, 101_325.0).speed_of_sound(),
            343.2,
            2e-4
        ));
        assert!(close(
            Gas::air(273.15, 101_325.0).speed_of_sound(),
            331.3,
            1e-3
        ));
    }

    #[test]
    fn density_of_air() {
        // 1.204 kg/m³ at 20 °C, 1.225 kg/m³ at 15 °C (ISA sea level), 1 atm.
        assert!(close(Gas::air(293.15, 101_325.0).density(), 1.204, 1e-3));
        assert!(close(Gas::air(288.15, 101_325.0).density(), 1.225, 1e-3));
    }

    #[test]
    fn sutherland_viscosity_of_air() {
        // Tabulated air viscosity: 1.716e-5 at 273 K, 1.81e-5 at 293 K, 1.789e-5 at 288 K
        // (ISA), 2.08e-5 at 350 K, 1.33e-5 at 200 K.
        assert!(close(sutherland_viscosity(273.15), 1.716e-5, 1e-12));
        assert!(close(sutherland_viscosity(293.15), 1.813e-5, 3e-3));
        assert!(close(sutherland_viscosity(288.15), 1.789e-5, 3e-3));
        assert!(close(sutherland_viscosity(350.0), 2.08e-5, 5e-3));
        assert!(close(sutherland_viscosity(200.0), 1.33e-5, 5e-3));
    }

    #[test]
    fn kinematic_viscosity_scales_with_pressure() {
        let g1 = Gas::air(293.15, 101_325.0);
        let g2 = g1.with_pressure(2.0 * 101_325.0);
        assert!(close(g1.kinematic_viscosity(), 1.506e-5, 3e-3));
        assert!(close(
            g1.kinematic_viscosity() / g2.kinematic_viscosity(),
            2.0,
            1e-12
        ));
    }

    #[test]
    fn validate_rejects_nonsense() {
        assert!(Gas::standard_air().validate().is_ok());
        assert!(Gas::air(-1.0, 1e5).validate().is_err());
        assert!(Gas::air(293.0, 0.0).validate().is_err());
        assert!(Gas {
            gamma: 1.0,
            ..Gas::standard_air()
        }
        .validate()
        .is_err());
    }
}
