//! `unlag simulate`: the model's probe output, its effects included, from a recording's
//! reference, against the recorded probe. Owns the arguments, the files and what is printed;
//! the simulation is [`crate::pipeline::simulate`]'s.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::{check_rate, name, pct, ColumnArgs};
use crate::error::Result;
use crate::file::ModelFile;
use crate::pipeline::{self, SimulateRequest};
use crate::trace::Trace;

/// Arguments of `unlag simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// A recording with the reference column (CSV).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Output CSV: the input columns plus `y_model`.
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: PathBuf,
    /// Replace an existing file at the output's path that is not an output of this command
    /// (a read-only file is never replaced).
    #[arg(long)]
    pub force: bool,
    /// Gas temperature of the recording (K), for a model with a `temperature` effect; without
    /// it the time-scale factor is estimated from the recording.
    #[arg(long, value_name = "K")]
    pub temperature: Option<f64>,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `unlag simulate`: the recording and the model file read, [`pipeline::simulate`] asked,
/// the simulated probe written beside the recording's columns and its error printed.
///
/// # Errors
/// The model file's and the trace's errors, and [`pipeline::simulate`]'s (a `--temperature`
/// the model has no law for).
pub fn run_simulate(args: &SimulateArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    let trace = Trace::read(&args.file, &args.columns.columns(true))?;
    check_rate(&file, &trace)?;
    let simulated = pipeline::simulate(&SimulateRequest {
        file: &file,
        u: trace.input()?,
        y: &trace.y,
        temperature_k: args.temperature,
    })?;
    crate::file::write_atomically_with(&args.output, |out| {
        Ok(trace.write_csv_with(out, &[("y_model", &simulated.y_model)])?)
    })?;
    if args.json {
        let v = json!({
            "output": name(&args.output),
            "samples": trace.len(),
            "nrmse": simulated.nrmse,
        });
        crate::outln!("{v}");
        return Ok(());
    }
    crate::outln!(
        "simulated {} samples of {}: model against measurement nrmse {}",
        trace.len(),
        trace.path.display(),
        pct(simulated.nrmse)
    );
    crate::outln!("wrote {}", args.output.display());
    Ok(())
}
