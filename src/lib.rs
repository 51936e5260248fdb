#![doc = include_str!("../README.md")]
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]

// Data flow, one room per stage: trace -> fit -> design -> export -> board. The modelling loop
// reads what fit and design produce; `file` composes the stage outputs into the model file;
// `pipeline` runs the stages in order (fit a probe, design its compensator, retarget it,
// compensate a record), resamples a model and diagnoses one against its tests; export and the report read them; the CLI
// parses, asks the pipeline and prints. Imports go one way: in the order board, trace, error, poly, fit, physics,
// design, modelling, file, pipeline, export, report, cli, each room imports only rooms before
// it. Errors: trace, fit, design, physics, modelling and export each have their own enum,
// which `error::Error` carries (as `Error::Trace` or `Error::Stage`) without importing the
// stages; the CLI adds the flag that fixes a problem (`cli::describe`).
// Everything but `board` is host side, behind the `std` feature.

pub mod board;
pub use board::{blob, compensator, fixed};

#[cfg(feature = "std")]
pub mod cli;
#[cfg(feature = "std")]
pub mod design;
#[cfg(feature = "std")]
pub mod error;
#[cfg(feature = "std")]
pub mod export;
#[cfg(feature = "std")]
pub mod file;
#[cfg(feature = "std")]
pub mod fit;
#[cfg(feature = "std")]
pub mod modelling;
#[cfg(feature = "std")]
pub mod physics;
#[cfg(feature = "std")]
pub mod pipeline;
#[cfg(feature = "std")]
pub mod poly;
#[cfg(feature = "std")]
pub mod report;
#[cfg(feature = "std")]
pub mod trace;

#[cfg(feature = "std")]
pub use error::Error;
#[cfg(all(test, feature = "std"))]
pub(crate) mod testing;
