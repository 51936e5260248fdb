#![doc = include_str!("../README.md")]
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]

// Data flow: trace -> fit -> model -> (inverse) -> export -> board; `pipeline` runs these
// steps in order for the CLI.
// Everything but `board` is host side, behind the `std` feature.

pub mod board;
pub use board::{blob, compensator, fixed};

#[cfg(feature = "std")]
pub mod analysis;
#[cfg(feature = "std")]
pub mod cli;
#[cfg(feature = "std")]
pub mod continuous;
#[cfg(feature = "std")]
pub mod diagnose;
#[cfg(feature = "std")]
pub mod effects;
#[cfg(feature = "std")]
pub mod error;
#[cfg(feature = "std")]
pub mod evidence;
#[cfg(feature = "std")]
pub mod export;
#[cfg(feature = "std")]
pub mod fit;
#[cfg(feature = "std")]
pub mod inverse;
#[cfg(feature = "std")]
pub mod model;
#[cfg(feature = "std")]
pub mod physics;
#[cfg(feature = "std")]
pub mod pipeline;
#[cfg(feature = "std")]
pub mod poly;
#[cfg(feature = "std")]
pub mod quantise;
#[cfg(feature = "std")]
pub mod report;
#[cfg(feature = "std")]
pub mod trace;

#[cfg(feature = "std")]
pub use error::Error;
#[cfg(all(test, feature = "std"))]
pub(crate) mod testing;
