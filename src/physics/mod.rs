//! Physics of pressure-measuring lines, holes and cavities: what a probe's tubing,
//! recessed holes, cavities and transducer do to a pressure signal, predicted from geometry
//! and gas properties, and step tests simulated from it.
//!
//! This module owns:
//!
//! * [`gas`]: air properties versus temperature and mean pressure;
//! * [`bessel`]: the complex Bessel ratio `J₂/J₀` of the viscothermal boundary layers;
//! * [`fft`]: the radix-2 FFT behind the time-domain simulation;
//! * [`line`](mod@line): the Bergh-Tijdeman (1965) response of tubes, volumes and series impedances,
//!   as an ABCD chain (leaks, diaphragm compliance, thermally relaxing cavities);
//! * [`lumped`](mod@lumped): the low-Womersley second-order approximation (natural frequency, damping);
//! * [`modes`]: the exact poles of the Bergh-Tijdeman response and the front delay;
//! * [`helmholtz`]: the hole-cavity resonator of a recessed sensor, with end corrections;
//! * [`sensor`]: the transducer's diaphragm resonance and the DAQ anti-alias filter;
//! * [`nonlinear`]: amplitude-dependent (quadratic orifice) losses, by describing function;
//! * [`simulate`](mod@simulate): time-domain step tests (excitations, channels, noise, ADC, delay);
//! * [`system`]: a probe described by its parts, checked and assembled into its line;
//! * [`compare`](mod@compare): the physical prediction of a probe, and how a fitted model disagrees with it.
//!
//! SI units throughout: m, m², m³, s, Hz, rad/s, Pa, K, kg/m³, Pa s. Time dependence is
//! `e^{st}`; responses are `p_end/p_in`, phase negative for a lag. The line model and the
//! curves it is validated against (the host tests, digitised from its Figs. 9-20) are from
//! H. Bergh and H. Tijdeman, *Theoretical and experimental results for the dynamic response of
//! pressure measuring systems*, NLR-TR F.238, NLR Amsterdam, 1965.

pub mod bessel;
pub mod compare;
mod error;
pub mod fft;
pub mod gas;
pub mod helmholtz;
pub mod line;
pub mod lumped;
pub mod modes;
pub mod nonlinear;
pub mod sensor;
pub mod simulate;
pub mod system;

pub use compare::{
    check_mode_count, compare, predict, predict_and_compare, Comparison, PredictRequest, Predicted,
    Prediction, MAX_MODES,
};
pub use error::PhysicsError;
pub use gas::Gas;
pub use helmholtz::{EndKind, HoleCavity};
pub use line::{CavityThermal, Element, Line, SeriesImpedance, Tube, Volume};
pub use lumped::{lumped, Lumped, POISEUILLE_INERTANCE};
pub use modes::{find_modes, Mode, ModeAnalysis};
pub use sensor::{Butterworth, Diaphragm};
pub use simulate::{
    simulate, Acquisition, Excitation, Probe, ReducedRate, ResonanceAboveBand, SimulatedTest,
};
pub use system::{ProbeSpec, ProbeSystem, MAX_LINE_LENGTH_M};
