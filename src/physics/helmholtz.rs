//! The hole-cavity (Helmholtz) resonator of a recessed (sub-surface) sensor: a short hole of
//! length `L` and diameter `D` from the probe surface into a small cavity `V` in front of the
//! diaphragm (README 1.5).
//!
//! * Closed form: `f_H = (a/2π)√(A/(V L_eff))`, `A = πD²/4`, `L_eff = L + δ_out + δ_in`, with the
//!   end corrections `δ = 8r/(3π) ≈ 0.85r` for a flanged end (hole flush with the surface,
//!   Rayleigh; also used for the inner end opening into a larger cavity) and `δ = 0.61r` for an
//!   unflanged end (Levine & Schwinger); Poiseuille damping `ζ = (R_ac/2)√(C/M)` with
//!   `R_ac = 8μL/(πr⁴)`, `C = V/(ρa²)`, `M = c_I ρL_eff/A`.
//! * Better ([`HoleCavity::line`]): the hole as a Bergh-Tijdeman tube between two lumped
//!   end-correction inertances `ρδ/A`, ending in the cavity. Its exact modes
//!   ([`super::modes::find_modes`]) hold when the neck volume approaches the cavity volume (the
//!   hole then becomes a quarter-wave tube) and at the high Womersley numbers of such holes,
//!   where the Poiseuille damping is far too low.

use super::gas::Gas;
use super::line::{Element, Line, SeriesImpedance, Tube, Volume};
use super::lumped::POISEUILLE_INERTANCE;
use crate::error::{Error, Result};

/// Largest neck/cavity volume ratio ([`HoleCavity::neck_volume_ratio`]) at which the closed
/// form is trusted [-].
pub const CLOSED_FORM_MAX_NECK_RATIO: f64 = 0.3;

/// How an end of the hole meets the space beyond it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndKind {
    /// Flush with a wall (a flange): `δ = 8r/(3π) ≈ 0.85r` (Rayleigh).
    Flanged,
    /// A free pipe end: `δ = 0.61r` (Levine & Schwinger).
    Unflanged,
    /// No end correction.
    None,
}

impl EndKind {
    /// End correction `δ` \[m\] for a hole of radius `radius_m` \[m\].
    #[must_use]
    pub fn correction_m(self, radius_m: f64) -> f64 {
        match self {
            Self::Flanged => 8.0 * radius_m / (3.0 * core::f64::consts::PI),
            Self::Unflanged => 0.61 * radius_m,
            Self::None => 0.0,
        }
    }
}

/// A hole of length `hole_length_m` and diameter `hole_diameter_m` into a cavity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoleCavity {
    /// Hole length `L` \[m\].
    pub hole_length_m: f64,
    /// Hole diameter `D` \[m\].
    pub hole_diameter_m: f64,
    /// Cavity volume `V` \[m³\].
    pub cavity_volume_m3: f64,
    /// The outer end (at the probe surface).
    pub outer_end: EndKind,
    /// The inner end (into the cavity).
    pub inner_end: EndKind,
}

impl HoleCavity {
    /// A flush hole (flanged both ends) into a cavity.
    #[must_use]
    pub fn flush(hole_length_m: f64, hole_diameter_m: f64, cavity_volume_m3: f64) -> Self {
        Self {
            hole_length_m,
            hole_diameter_m,
            cavity_volume_m3,
            outer_end: EndKind::Flanged,
            inner_end: EndKind::Flanged,
        }
    }

    /// Checks the dimensions are positive.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        for (what, v) in [
            ("hole length", self.hole_length_m),
            ("hole diameter", self.hole_diameter_m),
            ("cavity volume", self.cavity_volume_m3),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::InvalidArgument {
                    what,
                    message: format!("{v} must be finite and positive"),
                });
            }
        }
        Ok(())
    }

    fn radius(&self) -> f64 {
        0.5 * self.hole_diameter_m
    }

    /// Hole cross-section `A = πD²/4` \[m²\].
    #[must_use]
    pub fn area_m2(&self) -> f64 {
        core::f64::consts::PI * self.radius() * self.radius()
    }

    /// Effective length `L_eff = L + δ_out + δ_in` \[m\].
    #[must_use]
    pub fn effective_length_m(&self) -> f64 {
        self.hole_length_m
            + self.outer_end.correction_m(self.radius())
            + self.inner_end.correction_m(self.radius())
    }

    /// Ratio of the hole's own volume to the cavity volume [-]; the closed form needs it ≪ 1.
    #[must_use]
    pub fn neck_volume_ratio(&self) -> f64 {
        self.area_m2() * self.hole_length_m / self.cavity_volume_m3
    }

    /// Whether the neck is too large for the closed form ([`Self::helmholtz_frequency_hz`],
    /// [`Self::poiseuille_damping`]): its volume is more than [`CLOSED_FORM_MAX_NECK_RATIO`]
    /// of the cavity's. Then trust the exact modes of [`Self::line`].
    #[must_use]
    pub fn neck_too_large_for_closed_form(&self) -> bool {
        self.neck_volume_ratio() > CLOSED_FORM_MAX_NECK_RATIO
    }

    /// Closed-form Helmholtz frequency `f_H = (a/2π)√(A/(V L_eff))` \[Hz\].
    #[must_use]
    pub fn helmholtz_frequency_hz(&self, gas: &Gas) -> f64 {
        gas.speed_of_sound() / (2.0 * core::f64::consts::PI)
            * (self.area_m2() / (self.cavity_volume_m3 * self.effective_length_m())).sqrt()
    }

    /// Closed-form Poiseuille damping `ζ = (R_ac/2)√(C/M)` [-] with the Poiseuille inertance
    /// `c_I = 4/3`; far too low at the high Womersley numbers of real holes (README 1.5).
    #[must_use]
    pub fn poiseuille_damping(&self, gas: &Gas) -> f64 {
        let r = self.radius();
        let rho = gas.density();
        let a = gas.speed_of_sound();
        let r_ac =
            8.0 * gas.viscosity_pa_s * self.hole_length_m / (core::f64::consts::PI * r.powi(4));
        let c = self.cavity_volume_m3 / (rho * a * a);
        let m = POISEUILLE_INERTANCE * rho * self.effective_length_m() / self.area_m2();
        0.5 * r_ac * (c / m).sqrt()
    }

    /// The hole as a Bergh-Tijdeman line: outer end-correction inertance `ρδ_out/A`, the hole
    /// tube, inner end-correction inertance, then the cavity (isentropic, rigid, tight; append
    /// further elements or replace the volume through [`Line::elements`]).
    #[must_use]
    pub fn line(&self, gas: &Gas) -> Line {
        let r = self.radius();
        let inertance = |kind: EndKind| SeriesImpedance {
            resistance_pa_s_per_m3: 0.0,
            inertance_kg_per_m4: gas.density() * kind.correction_m(r) / self.area_m2(),
        };
        Line::new()
            .with(Element::Series(inertance(self.outer_end)))
            .with(Element::Tube(Tube::with_radius(self.hole_length_m, r)))
            .with(Element::Series(inertance(self.inner_end)))
            .with(Element::Volume(Volume::new(self.cavity_volume_m3)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn end_corrections() {
        assert!((EndKind::Flanged.correction_m(1.0) - 0.8488).abs() < 1e-4);
        assert!((EndKind::Unflanged.correction_m(1.0) - 0.61).abs() < 1e-12);
        assert_eq!(EndKind::None.correction_m(1.0), 0.0);
    }

    #[test]
    fn textbook_helmholtz_resonator() {
        // A = 1 cm², L_eff = 5 cm, V = 1 L at a = 343 m/s: f = (343/2π)√(1e-4/(1e-3·0.05)).
        let gas = Gas::standard_air();
        let r = (1e-4 / core::f64::consts::PI).sqrt();
        let hc = HoleCavity {
            hole_length_m: 0.05,
            hole_diameter_m: 2.0 * r,
            cavity_volume_m3: 1e-3,
            outer_end: EndKind::None,
            inner_end: EndKind::None,
        };
        let want = gas.speed_of_sound() / (2.0 * core::f64::consts::PI) * 2.0_f64.sqrt();
        assert!((hc.helmholtz_frequency_hz(&gas) / want - 1.0).abs() < 1e-12);
        // Neck 1e-4 · 0.05 = 5e-6 m³ of a 1e-3 m³ cavity: the closed form holds.
        assert!(!hc.neck_too_large_for_closed_form());
        let small = HoleCavity {
            cavity_volume_m3: 1e-5,
            ..hc
        };
        assert!(small.neck_too_large_for_closed_form());
    }
}
