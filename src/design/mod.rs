//! The design stage: from a fitted model to the compensator the board runs.
//!
//! [`inverse`] designs it in f64 (band-limited inverse, optimal reconstruction, the check
//! against the raw probe); [`quantise`] realises a design for the board's fixed-point
//! kernels. This room reads the fit stage's [`Model`](crate::fit::Model) and the board's
//! types, nothing above.

mod error;
pub mod inverse;
pub mod quantise;

pub use error::DesignError;
pub use inverse::Design;
