//! The modelling loop: where a model fails on a test, which physical effect is missing, and
//! the model with that effect added.
//!
//! [`evidence`] measures the residual on each test, [`diagnose`] ranks the candidate effects
//! from that evidence, and [`effects`] adds one (a line resonance, a temperature law, a
//! nonlinear damping, ...) and refits. The loop reads the fit and design stages' outputs;
//! the model file ([`crate::file`]) stores its effects.

pub mod diagnose;
pub mod effects;
mod error;
pub mod evidence;

pub use error::ModellingError;
