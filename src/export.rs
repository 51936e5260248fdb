//! Export of the designed compensator from the PC to the board (`unlag export`).
//!
//! This module owns the step from a model file's `[inverse]` design (f64, host) to what a
//! firmware builds in: the coefficients rounded once to the board's numbers, checked again
//! after the rounding as the board checks them, and written. What is written is one
//! [`BoardImage`] ([`image`]): the `f32` cascade (with the nonlinear-damping correction when
//! the model has it), the fixed-point cascade of [`crate::board::fixed`] in normal form (the integers
//! of [`crate::design::quantise::FixedPlan`], [`NumberFormat::Fixed`]) or direct form
//! ([`crate::design::quantise::DirectPlan`], [`NumberFormat::FixedDirect`]), or a table of `f32` sets,
//! one per gas temperature, for a board that measures it ([`bank`], `--temperatures`). One
//! writer per format renders every kind:
//!
//! * [`Format::Rust`] ([`BoardImage::to_rust`]): `const` items a Rust firmware `include!`s and
//!   hands to [`crate::board::compensator::CascadeCoefficients::new`] (or the kind's own
//!   constructor);
//! * [`Format::C`] ([`BoardImage::to_c`]): a header for C firmware (`static const` arrays);
//! * [`Format::Bin`] ([`BoardImage::to_bin`]): the versioned, CRC-protected blob of
//!   [`crate::board::blob`], for updating a running board over a serial link (one set: not a bank).
//!
//! All three carry the same values, so a board gets bit-identical coefficients whichever way
//! they arrive. The output file is written atomically. Every `f32` section is
//! `[b0, b1, b2, a1, a2]` in the crate's sign convention (see [`crate::board::compensator`]);
//! CMSIS-DSP's biquad functions want `a1`, `a2` negated, which the C header says.

use std::path::Path;

pub mod bank;
mod bin;
mod c;
mod error;
pub mod image;
mod request;
mod rust;
pub mod verify;

pub use error::ExportError;
pub use image::{
    BoardCoefficients, BoardImage, BoardNonlinear, DirectBoardCoefficients, FixedBoardCoefficients,
    SetTiming,
};
pub use request::{prepare, ExportRequest, ExportSummary, Exported, Sets};

use crate::error::{Error, Result};
use crate::file::write_atomically;
use crate::file::ModelFile;

/// Largest section count `unlag export` writes: as many as a design may have.
pub const MAX_EXPORT_SECTIONS: usize = crate::design::inverse::optimal::MAX_SECTIONS;

/// What `unlag export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Rust `const` items for `include!`.
    Rust,
    /// A C header.
    C,
    /// The binary blob of [`crate::board::blob`].
    Bin,
}

/// The board's number format for [`export_with`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NumberFormat {
    /// `f32` (the default).
    F32,
    /// Fixed point: the model file's plan, or a new one for this full scale.
    Fixed {
        /// ADC full scale in the probe's units; `None` takes the plan stored in the model file.
        full_scale: Option<f64>,
    },
    /// Fixed point in the direct form ([`DirectBoardCoefficients`]): the model file's plan, or
    /// a new one for this full scale.
    FixedDirect {
        /// ADC full scale in the probe's units; `None` takes the plan stored in the model file.
        full_scale: Option<f64>,
    },
}

/// What [`export`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// `"f32"` or `"fixed"`.
    pub number_format: &'static str,
    /// Sample rate in Hz.
    pub sample_rate_hz: f64,
    /// Model delay in samples.
    pub delay_samples: u32,
    /// Reconstruction latency in samples.
    pub latency_samples: f64,
    /// Sections exported.
    pub sections: usize,
    /// Bytes written.
    pub bytes: usize,
    /// The fixed-point set's full scale in the probe's units (the input code `2^31`).
    pub full_scale: Option<f64>,
}

/// Loads `model`, exports its `f32` compensator in `format` and writes `output` atomically.
///
/// # Errors
/// Loading the model file, [`BoardCoefficients::from_model_file`], or writing the output.
pub fn export(model: &Path, format: Format, output: &Path) -> Result<Summary> {
    export_with(model, format, NumberFormat::F32, output)
}

/// Loads `model`, exports its compensator in `format` and `number_format`, and writes
/// `output` atomically (nothing is written on error).
///
/// # Errors
/// Loading the model file, [`BoardCoefficients::from_model_file`] or
/// [`FixedBoardCoefficients::from_model_file`], or writing the output.
pub fn export_with(
    model: &Path,
    format: Format,
    number_format: NumberFormat,
    output: &Path,
) -> Result<Summary> {
    let file = ModelFile::load(model)?;
    export_file(&file, model, format, number_format, output)
}

/// Exports the compensator of an already loaded (or derived, e.g. rescaled to a temperature)
/// model file `file` that came from `model`, and writes `output` atomically.
///
/// # Errors
/// As [`export_with`], less the loading.
pub fn export_file(
    file: &ModelFile,
    model: &Path,
    format: Format,
    number_format: NumberFormat,
    output: &Path,
) -> Result<Summary> {
    let (bytes, summary) = render(file, model, format, number_format)?;
    write_atomically(output, &bytes)?;
    Ok(summary)
}

/// The compensator of `file` (from `model`) in `format` and `number_format`, rendered, and
/// what it holds.
fn render(
    file: &ModelFile,
    model: &Path,
    format: Format,
    number_format: NumberFormat,
) -> Result<(Vec<u8>, Summary)> {
    // What the export itself refuses (the board's code, the blob's read-back, a plan) names
    // the model file it came from.
    let in_file = |e: Error| match e.location() {
        (None, _, _)
            if e.stage::<ExportError>().is_some()
                || e.stage::<crate::design::DesignError>().is_some() =>
        {
            Error::Model {
                path: model.to_path_buf(),
                message: e.to_string(),
            }
        }
        _ => e,
    };
    let image = BoardImage::from_model_file(file, model, number_format).map_err(in_file)?;
    let bytes = image.render(format, &source_name(model)).map_err(in_file)?;
    let timing = image.timing();
    let summary = Summary {
        number_format: image.number_format(),
        sample_rate_hz: timing.sample_rate_hz,
        delay_samples: timing.delay_samples,
        latency_samples: timing.latency_samples,
        sections: image.section_count(),
        bytes: bytes.len(),
        full_scale: match &image {
            BoardImage::Fixed(c) => Some(c.full_scale),
            BoardImage::Direct(c) => Some(c.full_scale),
            BoardImage::F32(_) | BoardImage::Bank(_) => None,
        },
    };
    Ok((bytes, summary))
}

/// The model file's name as the exported files' comments give it.
fn source_name(model: &Path) -> String {
    model.file_name().map_or_else(
        || model.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
