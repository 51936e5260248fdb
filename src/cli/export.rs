//! `unlag export`: the designed compensator from a model file to a file the board builds in
//! (`rust`, `c`) or receives over a serial link (`bin`).
//!
//! Owns only the arguments, the writing of the file and what is printed; the export's policy
//! (which compensator may be exported, in which fixed-point form, at which temperatures), the
//! rendering and the checks live in [`crate::export`] and [`crate::board::blob`].

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde_json::json;

use crate::error::{Error, Result};
use crate::export::{self, ExportRequest, ExportSummary, Format, NumberFormat, Sets};
use crate::file::BoardArithmetic;

/// Arguments of `unlag export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// The model file, with an `[inverse]` design (from `unlag fit` or `unlag invert`).
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// What to write: `rust` (const items to `include!`), `c` (a header) or `bin` (the
    /// versioned, CRC-32-protected blob for a running board).
    #[arg(long, value_enum)]
    pub format: FormatArg,
    /// The board's arithmetic: `f32`, or `fixed` (the fixed-point compensator: the model
    /// file's plan, or one planned for the full scale). Default: the model file's `[board]`
    /// arithmetic (`unlag fit --board`), else f32.
    #[arg(long, value_enum)]
    pub number_format: Option<NumberFormatArg>,
    /// ADC full scale in the probe's units for the fixed-point format (plans anew). Default:
    /// the range stated in the model file's `[board]`, else the full scale of the stored plan.
    #[arg(long, value_name = "VALUE")]
    pub full_scale: Option<f64>,
    /// The fixed-point form for `--number-format fixed`: `normal` or `direct` (see `unlag
    /// invert --fixed-form`). Default: the form of the plan stored in the model file (normal
    /// when it holds none, or both).
    #[arg(long, value_enum, value_name = "FORM")]
    pub fixed_form: Option<super::FixedFormArg>,
    /// Gas temperature (K) the board will measure at: the model (with a `temperature` effect)
    /// is scaled to it through its continuous-time equivalent and the compensator designed
    /// anew; a running board swaps to the new set as a blob.
    #[arg(long, value_name = "K", conflicts_with = "temperatures")]
    pub temperature: Option<f64>,
    /// A bank of sets, one per gas temperature FROM, FROM+STEP, ... up to TO (K, e.g.
    /// 253:353:10), for a board that measures the temperature and picks the set itself
    /// (`unlag::board::compensator::TemperatureBank`); a model with a `temperature` effect,
    /// `--format rust` or `c`, f32.
    #[arg(long, value_name = "FROM:TO:STEP")]
    pub temperatures: Option<String>,
    /// Export a compensator that the check marked not better than the raw probe, and replace
    /// an existing file at the output's path that is not an export (a read-only file is never
    /// replaced).
    #[arg(long)]
    pub force: bool,
    /// Where to write it (written atomically).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Output format on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    /// Rust `const` items for `include!`.
    Rust,
    /// A C header.
    C,
    /// The binary blob (magic, version, number format, fs, delay, sections, CRC-32).
    Bin,
}

/// Number format on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum NumberFormatArg {
    /// IEEE single precision.
    F32,
    /// 32-bit fixed point (`unlag::board::fixed`).
    Fixed,
}

/// Runs `unlag export`: the arguments as an [`export::ExportRequest`], the bytes it returns
/// written atomically, and what they hold printed.
///
/// # Errors
/// Flags that do not go together, the model file's errors, [`export::prepare`]'s, and writing.
pub fn run_export(args: &ExportArgs) -> Result<()> {
    let name = match args.format {
        FormatArg::Rust => "rust",
        FormatArg::C => "c",
        FormatArg::Bin => "bin",
    };
    let file = crate::file::ModelFile::load(&args.model)?;
    let exported = exported(args, &file)?;
    crate::file::write_atomically(&args.output, &exported.bytes)?;
    match &exported.summary {
        ExportSummary::One(c) => print_one(args, name, c, file.board.unit),
        ExportSummary::Bank(c) => print_bank(args, name, c),
    }
    Ok(())
}

/// What `unlag export` writes for the model file `file` (read from `args.model`), its flags
/// checked as the command line checks them; nothing is written (the Python package returns
/// the bytes).
///
/// # Errors
/// [`Error::InvalidArgument`] for a `--full-scale` or `--fixed-form` without fixed point;
/// [`export::prepare`]'s.
pub fn exported(args: &ExportArgs, file: &crate::file::ModelFile) -> Result<export::Exported> {
    let format = match args.format {
        FormatArg::Rust => Format::Rust,
        FormatArg::C => Format::C,
        FormatArg::Bin => Format::Bin,
    };
    // The board's arithmetic and range unless others are asked for.
    let asked = args.number_format.unwrap_or(match file.board.arithmetic {
        BoardArithmetic::F32 => NumberFormatArg::F32,
        BoardArithmetic::Fixed => NumberFormatArg::Fixed,
    });
    let planned = file.inverse.as_ref().and_then(|d| {
        d.fixed
            .as_ref()
            .map(|p| p.full_scale)
            .or(d.fixed_direct.as_ref().map(|p| p.full_scale))
    });
    let stated = file.board.full_scale.filter(|&fs| Some(fs) != planned);
    let number_format = match (asked, args.full_scale) {
        (NumberFormatArg::F32, None) => NumberFormat::F32,
        (NumberFormatArg::F32, Some(_)) => {
            return Err(Error::InvalidArgument {
                what: "--full-scale",
                message: "only applies to --number-format fixed".into(),
            })
        }
        (NumberFormatArg::Fixed, full_scale) => NumberFormat::Fixed {
            full_scale: full_scale.or(stated),
        },
    };
    if args.fixed_form.is_some() && asked != NumberFormatArg::Fixed {
        return Err(Error::InvalidArgument {
            what: "--fixed-form",
            message: "only applies to --number-format fixed".into(),
        });
    }
    export::prepare(&ExportRequest {
        file,
        model: &args.model,
        format,
        number_format,
        fixed_form: args.fixed_form.map(Into::into),
        sets: match &args.temperatures {
            Some(range) => Sets::Bank(range),
            None => Sets::One {
                temperature_k: args.temperature,
            },
        },
        force: args.force,
    })
}

/// What `unlag export` wrote: one set.
fn print_one(
    args: &ExportArgs,
    name: &str,
    c: &export::Summary,
    unit: Option<crate::trace::PressureUnit>,
) {
    if args.json {
        crate::outln!(
            "{}",
            json!({
                "output": args.output.display().to_string(),
                "format": name,
                "bytes": c.bytes,
                "sample_rate_hz": c.sample_rate_hz,
                "delay_samples": c.delay_samples,
                "latency_samples": c.latency_samples,
                "sections": c.sections,
                "number_format": c.number_format,
                "full_scale": c.full_scale,
            })
        );
    } else {
        let full_scale = c.full_scale.map_or_else(String::new, |fs| {
            format!(
                ", full scale +-{} (inputs are Q1.31 of it: readings beyond it clamp)",
                super::console::pressure(fs, unit)
            )
        });
        crate::outln!(
            "wrote {} ({name}, {} bytes): {} sections, {}{full_scale}, fs {} Hz, delay {} samples, latency {:.2} samples",
            args.output.display(),
            c.bytes,
            c.sections,
            c.number_format,
            c.sample_rate_hz,
            c.delay_samples,
            c.latency_samples
        );
    }
}

/// What `unlag export --temperatures FROM:TO:STEP` wrote: the temperature bank.
fn print_bank(args: &ExportArgs, name: &str, c: &export::bank::BankSummary) {
    if args.json {
        crate::outln!(
            "{}",
            json!({
                "output": args.output.display().to_string(),
                "format": name,
                "bytes": c.bytes,
                "sample_rate_hz": c.sample_rate_hz,
                "temperatures_k": c.temperatures_k,
                "delay_samples": c.delay_samples,
                "sections": c.sections,
                "number_format": "f32",
            })
        );
    } else {
        crate::outln!(
            "wrote {} ({name}, {} bytes): {} sets from {} K to {} K, {} sections each, f32, fs {} Hz",
            args.output.display(),
            c.bytes,
            c.temperatures_k.len(),
            c.temperatures_k.first().copied().unwrap_or(0.0),
            c.temperatures_k.last().copied().unwrap_or(0.0),
            c.sections,
            c.sample_rate_hz
        );
    }
}
