//! Give pressure probes back the bandwidth their tubing, holes and cavities take away.
//!
//! A step test records a fast reference pressure `u` and a slow probe's output `y`. This crate
//! fits a discrete model of the probe to it, designs a compensator that reconstructs the
//! pressure from the probe signal with the least error the noise allows, and exports that
//! compensator to an acquisition board, where it runs on every ADC sample. The `unlag` command
//! line drives the host side; its use is described in the
//! [README](https://github.com/unlag-rs/unlag/blob/main/README.md).
//!
//! # Two sides
//!
//! - **The host** (feature `std`, on by default): reading traces, fitting, designing,
//!   exporting, the modelling loop, the HTML report and the command line.
//! - **The board** (`no_std`, no allocation, no panic in the per-sample path): the
//!   compensators, in `f32` ([`board::compensator`]) and 32-bit fixed point ([`board::fixed`]),
//!   and the parser of the coefficient blob ([`board::blob`]). Firmware depends on the crate with
//!   `default-features = false` and gets only this side.
//!
//! # Data flow
//!
//! ```text
//! trace -> fit -> design -> export -> board
//! ```
//!
//! 1. [`trace`] reads and checks a step test from CSV.
//! 2. [`fit`] finds the step, the delay and the order, and fits the model
//!    ([`fit::model::Model`]) with its uncertainty.
//! 3. [`design`] builds the compensator from the model and the measured noise, and plans its
//!    fixed-point version.
//! 4. [`export`] writes the compensator as Rust constants, a C header or a binary blob.
//! 5. [`board`] runs it per sample: [`board::compensator`], [`board::fixed`], [`board::blob`], and
//!    [`board::process`], which makes the compensators `dsp_process` processors.
//!
//! Beside the flow, the modelling loop: [`evidence`] measures where a model fails on a test
//! (the residual's correlations, spectrum, level and trend), [`effects`] holds the physical
//! effects a model can carry (a mode, a leak, a temperature law, a quadratic loss, ...) and
//! fits a model with them, and [`modelling`] names the effect a model misses, ranked, with the
//! change that adds it. [`physics`] predicts a probe from its geometry and simulates step
//! tests. [`file`](mod@crate::file) reads and writes the model file, [`pipeline`] runs the
//! stages in order for the command line (its plain fit goes to [`effects`] and [`fit`], never
//! through [`modelling`]), [`report`] writes the HTML report, [`cli`] is the command line,
//! [`poly`] holds the polynomial arithmetic and [`error`] the host's error type ([`Error`]).
//!
//! # Example: the per-sample call on the board
//!
//! ```
//! use unlag::board::compensator::{CascadeCoefficients, CascadeState};
//! // gain and sections [b0, b1, b2, a1, a2] from `unlag export`; checked once, here.
//! let c = CascadeCoefficients::<f32, 4>::new(2.0, &[[1.0, -0.5, 0.0, -0.3, 0.0]]).unwrap();
//! let mut state = CascadeState::default();
//! let u_hat = c.process(&mut state, 0.3); // one ADC sample in, the pressure out
//! # let _ = u_hat;
//! ```
//!
//! # Features
//!
//! - `std` (default): the host side and the `unlag` binary.
//! - `defmt`: `defmt::Format` for the board-side types, for firmware that logs with defmt.
//!
//! # Guides
//!
//! - [Firmware](https://github.com/unlag-rs/unlag/blob/main/docs/firmware.md): from
//!   `unlag export` to a running board.
//! - [Method](https://github.com/unlag-rs/unlag/blob/main/docs/method.md): the identification
//!   and the optimal reconstruction, with references.
//! - [Modelling](https://github.com/unlag-rs/unlag/blob/main/docs/modelling.md): the modelling
//!   loop and the effects it names.
//! - [Files](https://github.com/unlag-rs/unlag/blob/main/docs/files.md): the CSV traces, the
//!   model file and the blob.
//! - [Command line](https://github.com/unlag-rs/unlag/blob/main/docs/cli.md): every command and
//!   option.
//! - [Benchmarks](https://github.com/unlag-rs/unlag/blob/main/BENCHMARKS.md).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]

// Data flow, one room per stage: trace -> fit -> design -> export -> board. Beside it the
// modelling loop: `evidence` measures a model's residual, `effects` fits a model with the
// physical effects it carries (the plain fit is its case of no effect), `modelling` diagnoses
// the missing one; `file` composes the stage outputs into the model file; `pipeline` runs the
// stages in order (fit a probe, design its compensator, retarget it, compensate a record),
// resamples a model and diagnoses one against its tests; export and the report read them; the
// CLI parses, asks the pipeline and prints. Imports go in the order board, trace, error, poly,
// fit, physics, design, evidence, effects, file, modelling, pipeline, export, report, cli,
// each room importing only rooms before it, and no two modules of a room importing each other
// round a circle (host-tests/imports.rs reads the code and fails on an upward arrow or a
// circle). The board's modules are reached through `board`: the crate root re-exports none of
// them. Errors: trace, fit, design, physics, effects and export each have their own enum,
// which `error::Error` carries (as `Error::Trace` or `Error::Stage`) without importing the
// stages; the CLI adds the flag that fixes a problem (`cli::describe`).
// Everything but `board` is host side, behind the `std` feature.

pub mod board;

#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod cli;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod design;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod effects;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod error;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod evidence;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod export;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod file;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod fit;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod modelling;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod physics;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod pipeline;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod poly;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod report;
#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub mod trace;

#[cfg(feature = "std")]
#[cfg_attr(docsrs, doc(cfg(feature = "std")))]
pub use error::Error;
#[cfg(all(test, feature = "std"))]
pub(crate) mod testing;
