//! The export request: what an export of a loaded model file asks for, and the policy that
//! turns it into the bytes to write (the compensator the check found not better refused
//! unless forced, the fixed-point form chosen, a temperature retargeted, a bank checked).
//!
//! [`prepare`] writes nothing: the caller writes [`Exported::bytes`] where it wants them
//! (`unlag export` atomically to its output) and reports the summary.

use std::path::Path;

use crate::design::inverse::check::Verdict;
use crate::design::quantise::FixedForm;
use crate::error::{Advice, Error, Parameter, Result};
use crate::export::bank::{self, BankSummary, TemperatureRange};
use crate::export::{ExportError, Format, NumberFormat, Summary};
use crate::file::ModelFile;

/// The coefficient sets an export writes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sets<'a> {
    /// One set: the model file's design, or with `temperature_k`, the design retargeted to
    /// that gas temperature (K) by [`crate::pipeline::at_temperature`].
    One {
        /// The gas temperature (K) the board will measure at, if not the file's.
        temperature_k: Option<f64>,
    },
    /// A bank of `f32` sets over the temperatures `FROM:TO:STEP` (K), as
    /// [`TemperatureRange::parse`] reads them (read after the compensator is accepted).
    Bank(&'a str),
}

/// One export of a loaded model file.
#[derive(Debug, Clone, Copy)]
pub struct ExportRequest<'a> {
    /// The model file, loaded.
    pub file: &'a ModelFile,
    /// Where it was loaded from (for messages and the written file's comments).
    pub model: &'a Path,
    /// What to write.
    pub format: Format,
    /// The board's arithmetic. [`NumberFormat::Fixed`] takes the fixed-point form from
    /// `fixed_form`.
    pub number_format: NumberFormat,
    /// The fixed-point form for [`NumberFormat::Fixed`]; `None` takes the form of the plan
    /// stored in the model file (normal when it holds none, or both).
    pub fixed_form: Option<FixedForm>,
    /// One set or a bank.
    pub sets: Sets<'a>,
    /// Export a compensator that its check found not better than the raw probe.
    pub force: bool,
}

/// What an export wrote, as its summary says.
#[derive(Debug, Clone, PartialEq)]
pub enum ExportSummary {
    /// One set.
    One(Summary),
    /// A temperature bank.
    Bank(BankSummary),
}

/// The bytes to write and what they hold.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// The rendered file.
    pub bytes: Vec<u8>,
    /// What it holds (its `bytes` is `bytes.len()`).
    pub summary: ExportSummary,
}

/// The number format `request` is exported in: [`NumberFormat::Fixed`] becomes
/// [`NumberFormat::FixedDirect`] when the direct form is asked for, or when none is and the
/// model file holds a direct plan only.
fn number_format(request: &ExportRequest<'_>) -> NumberFormat {
    match (request.number_format, request.fixed_form) {
        (NumberFormat::Fixed { full_scale }, Some(FixedForm::Direct)) => {
            NumberFormat::FixedDirect { full_scale }
        }
        (NumberFormat::Fixed { full_scale }, None)
            if request
                .file
                .inverse
                .as_ref()
                .is_some_and(|d| d.fixed_direct.is_some() && d.fixed.is_none()) =>
        {
            NumberFormat::FixedDirect { full_scale }
        }
        (n, _) => n,
    }
}

/// Refuses the compensator of `file` (read from `model`) when its check found it not better
/// than the raw probe and the export is not forced.
///
/// # Errors
/// [`ExportError::NotBetter`].
fn refuse_not_better(file: &ModelFile, model: &Path, force: bool) -> Result<()> {
    match file.inverse.as_ref().and_then(|d| d.check.as_ref()) {
        Some(check) if check.verdict == Verdict::NotBetter && !force => {
            Err(ExportError::NotBetter {
                model: model.to_path_buf(),
                worst_ratio: check.worst_ratio,
            }
            .into())
        }
        _ => Ok(()),
    }
}

/// The export `request` asks for, rendered: the compensator accepted (a compensator whose
/// check found it not better than the raw probe only when forced), its fixed-point form
/// chosen, then one set (retargeted to a temperature when asked) or a bank.
///
/// # Errors
/// [`ExportError::NotBetter`]; for a bank, [`TemperatureRange::parse`]'s errors, a number
/// format other than `f32` ([`Error::InvalidParameter`], advised), a bank asked for as
/// [`Format::Bin`] and [`bank::BoardBank::from_model_file`]'s; for one set,
/// [`crate::pipeline::at_temperature`]'s and [`super::BoardImage::from_model_file`]'s.
pub fn prepare(request: &ExportRequest<'_>) -> Result<Exported> {
    let number_format = number_format(request);
    refuse_not_better(request.file, request.model, request.force)?;
    match request.sets {
        Sets::Bank(text) => {
            let range = TemperatureRange::parse(text)?;
            if number_format != NumberFormat::F32 {
                return Err(Error::InvalidParameter {
                    parameter: Parameter::Temperatures,
                    message: "a temperature bank is f32 only".into(),
                }
                .advised(Advice::FixedOnePerTemperature));
            }
            let (bytes, summary) =
                bank::render_bank(request.file, request.model, &range, request.format)?;
            Ok(Exported {
                bytes,
                summary: ExportSummary::Bank(summary),
            })
        }
        Sets::One { temperature_k } => {
            let retargeted;
            let file = match temperature_k {
                Some(t) => {
                    retargeted = crate::pipeline::at_temperature(request.file, t)?;
                    &retargeted
                }
                None => request.file,
            };
            let (bytes, summary) =
                super::render(file, request.model, request.format, number_format)?;
            Ok(Exported {
                bytes,
                summary: ExportSummary::One(summary),
            })
        }
    }
}
