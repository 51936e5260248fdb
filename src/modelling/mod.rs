//! The modelling loop: where a model fails on a test, which physical effect is missing, and
//! the model with that effect added.
//!
//! [`evidence`] measures the residual on each test, [`diagnose`] ranks the candidate effects
//! from that evidence, and [`effects`] adds one (a line resonance, a temperature law, a
//! nonlinear damping, ...) and refits. The loop reads the fit and design stages' outputs;
//! the model file stores its effects.

pub mod diagnose;
pub mod effects;
mod error;
pub mod evidence;

pub use error::ModellingError;

/// Whether a held-out error went from `before` to `after` by a rise of more than
/// [`ERROR_RISE_NOTED`]: the change made the model worse on data it was not fitted to.
#[must_use]
pub fn error_rose(before: f64, after: f64) -> bool {
    after > before * (1.0 + ERROR_RISE_NOTED)
}

/// A held-out error that rises by more than this share has risen ([`error_rose`]): a refit of
/// the same model on the same data moves it by far less.
pub const ERROR_RISE_NOTED: f64 = 0.01;
