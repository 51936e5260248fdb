//! The probe described by its parts ([`ProbeSpec`]: tubes, a recessed hole, the end volume,
//! gas, leak, diaphragm, minor losses), checked and assembled into the line the physics
//! predicts and simulates ([`ProbeSystem`]).
//!
//! A recessed hole goes in front of everything else, without its own cavity: the end volume
//! is its cavity. All tubes together may be at most [`MAX_LINE_LENGTH_M`] long. Quadratic
//! (minor) losses are linearised for the step amplitude
//! ([`equivalent_resistance`]).

use super::gas::Gas;
use super::helmholtz::{EndKind, HoleCavity};
use super::line::{CavityThermal, Element, Line, Tube, Volume};
use super::nonlinear::{equivalent_resistance, MinorLosses};
use super::sensor::Diaphragm;
use super::PhysicsError;
use crate::error::{Error, Parameter, Result};

/// Longest tubing, all tubes together, that a probe may have \[m\] (a longer line rings for
/// minutes of simulated time).
pub const MAX_LINE_LENGTH_M: f64 = 50.0;

/// A probe by its parts, as a request: lengths and diameters in m, volumes in m^3,
/// temperature in K, pressures in Pa.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSpec {
    /// Tubes in series from the measuring point on, each `(length, diameter)` \[m\].
    pub tubes: Vec<(f64, f64)>,
    /// Volume at the closed end \[m^3\] (transducer volume, sensor cavity, or the hole's cavity).
    pub volume_m3: f64,
    /// A recessed hole `(length, diameter)` \[m\] in front of everything else.
    pub hole: Option<(f64, f64)>,
    /// End corrections of the hole (both ends).
    pub hole_end: EndKind,
    /// Mean gas temperature \[K\].
    pub temperature_k: f64,
    /// Mean absolute pressure \[Pa\].
    pub pressure_pa: f64,
    /// Diaphragm compliance sigma of the end volume [-].
    pub sigma: f64,
    /// Polytropic constant of the gas in the end volume [-] (unless `cavity_radius_m`).
    pub cavity_k: f64,
    /// Radius of a cylindrical end cavity whose gas relaxes thermally \[m\].
    pub cavity_radius_m: Option<f64>,
    /// Leak conductance of the end volume \[m^3/(s Pa)\].
    pub leak_m3_per_s_pa: f64,
    /// Quadratic (minor) loss coefficient K per stroke [-], if modelled.
    pub minor_loss_k: Option<f64>,
    /// Step amplitude \[Pa\] the minor losses are linearised for (its magnitude is used).
    pub step_amplitude_pa: f64,
    /// The transducer's diaphragm resonance, if modelled.
    pub diaphragm: Option<Diaphragm>,
}

/// A probe assembled from a [`ProbeSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSystem {
    /// The line: the hole's elements (without its cavity), the tubes, the end volume; with
    /// the minor losses linearised in, if any.
    pub line: Line,
    /// The gas.
    pub gas: Gas,
    /// The hole and its cavity, if any.
    pub hole: Option<HoleCavity>,
    /// The diaphragm, if any.
    pub diaphragm: Option<Diaphragm>,
    /// The linearised minor-loss resistance \[Pa s/m^3\], if minor losses are modelled.
    pub minor_loss_resistance: Option<f64>,
}

/// `value` if finite and positive.
fn positive(value: f64, parameter: Parameter) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::InvalidParameter {
            parameter,
            message: format!("{value} must be finite and positive"),
        })
    }
}

impl ProbeSpec {
    /// The probe, its parts checked and assembled.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a part out of range (tubes longer than
    /// [`MAX_LINE_LENGTH_M`] together among them), [`PhysicsError::NoTube`] for a probe with
    /// neither a tube nor a hole; the errors of the gas, the line, the minor losses and the
    /// diaphragm.
    pub fn build(&self) -> Result<ProbeSystem> {
        positive(self.temperature_k, Parameter::Temperature)?;
        positive(self.pressure_pa, Parameter::MeanPressure)?;
        let gas = Gas::air(self.temperature_k, self.pressure_pa);
        gas.validate()?;
        if self.tubes.is_empty() && self.hole.is_none() {
            return Err(PhysicsError::NoTube.into());
        }
        if !(self.volume_m3.is_finite() && self.volume_m3 >= 0.0) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::EndVolume,
                message: format!("{} m^3 must be finite and non-negative", self.volume_m3),
            });
        }
        let mut line = Line::new();
        let mut hole = None;
        if let Some((l, d)) = self.hole {
            positive(l, Parameter::HoleLength)?;
            positive(d, Parameter::HoleDiameter)?;
            positive(self.volume_m3, Parameter::HoleCavity)?;
            let hc = HoleCavity {
                hole_length_m: l,
                hole_diameter_m: d,
                cavity_volume_m3: self.volume_m3,
                outer_end: self.hole_end,
                inner_end: self.hole_end,
            };
            // The hole's elements without its cavity (the end volume below is the cavity).
            line.elements.extend(
                hc.line(&gas)
                    .elements
                    .into_iter()
                    .filter(|e| !matches!(e, Element::Volume(_))),
            );
            hole = Some(hc);
        }
        let mut total = 0.0;
        for &(l, d) in &self.tubes {
            positive(l, Parameter::TubeLength)?;
            positive(d, Parameter::TubeDiameter)?;
            total += l;
            line.elements.push(Element::Tube(Tube::with_diameter(l, d)));
        }
        if total > MAX_LINE_LENGTH_M {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Tubes,
                message: format!(
                    "the lines add up to {total} m; the simulator takes up to {MAX_LINE_LENGTH_M} m \
                     of tubing (a longer line rings for minutes of simulated time)"
                ),
            });
        }
        let thermal = match self.cavity_radius_m {
            Some(r) => CavityThermal::Relaxing {
                radius_m: positive(r, Parameter::CavityRadius)?,
            },
            None => CavityThermal::Polytropic(self.cavity_k),
        };
        line.elements.push(Element::Volume(Volume {
            volume_m3: self.volume_m3,
            sigma: self.sigma,
            thermal,
            leak_m3_per_s_pa: self.leak_m3_per_s_pa,
        }));
        line.validate()?;
        let mut minor_loss_resistance = None;
        if let Some(k) = self.minor_loss_k {
            let q = equivalent_resistance(
                &line,
                &gas,
                &MinorLosses {
                    k,
                    step_amplitude_pa: self.step_amplitude_pa.abs(),
                },
            )?;
            minor_loss_resistance = Some(q.resistance_pa_s_per_m3);
            line = q.line;
        }
        if let Some(d) = &self.diaphragm {
            d.validate()?;
        }
        Ok(ProbeSystem {
            line,
            gas,
            hole,
            diaphragm: self.diaphragm,
            minor_loss_resistance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> ProbeSpec {
        ProbeSpec {
            tubes: vec![(0.6, 1e-3)],
            volume_m3: 1e-6,
            hole: None,
            hole_end: EndKind::Flanged,
            temperature_k: 293.15,
            pressure_pa: 101_325.0,
            sigma: 0.0,
            cavity_k: 1.4,
            cavity_radius_m: None,
            leak_m3_per_s_pa: 0.0,
            minor_loss_k: None,
            step_amplitude_pa: 1000.0,
            diaphragm: None,
        }
    }

    #[test]
    fn a_hole_goes_in_front_without_its_cavity() {
        let mut s = spec();
        s.hole = Some((1e-3, 0.5e-3));
        let sys = s.build().unwrap();
        let volumes = sys
            .line
            .elements
            .iter()
            .filter(|e| matches!(e, Element::Volume(_)))
            .count();
        assert_eq!(volumes, 1);
        assert!(matches!(sys.line.elements.last(), Some(Element::Volume(_))));
        assert!(sys.hole.is_some());
    }

    #[test]
    fn refuses_too_much_tubing_and_no_tube() {
        let mut s = spec();
        s.tubes = vec![(30.0, 1e-3), (25.0, 1e-3)];
        let e = s.build().unwrap_err();
        assert!(matches!(
            e,
            Error::InvalidParameter {
                parameter: Parameter::Tubes,
                ..
            }
        ));
        s.tubes.clear();
        let e = s.build().unwrap_err();
        assert!(matches!(e.stage(), Some(PhysicsError::NoTube)));
        assert_eq!(e.kind(), "invalid-argument");
    }

    #[test]
    fn minor_losses_add_a_resistance() {
        let mut s = spec();
        s.minor_loss_k = Some(1.5);
        let r = s.build().unwrap().minor_loss_resistance.unwrap();
        assert!(r > 0.0);
    }
}
