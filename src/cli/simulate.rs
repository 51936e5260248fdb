//! `unlag simulate`: the model's probe output, its effects included, from a recording's
//! reference, against the recorded probe.

use std::path::PathBuf;

use clap::Args;
use serde_json::json;

use super::{check_rate, name, pct, ColumnArgs};
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit;
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

/// `unlag simulate`.
///
/// # Errors
/// The model file's and the trace's errors, and a `--temperature` the model has no law for.
pub fn run_simulate(args: &SimulateArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    let trace = Trace::read(&args.file, &args.columns.columns(true))?;
    check_rate(&file, &trace)?;
    let u = trace.input()?;
    // The whole model: dynamics plus effects (an offset or drift estimated on this test).
    let scale = match (
        args.temperature,
        crate::modelling::effects::reference_k(&file.effects),
    ) {
        (Some(t), Some(reference)) => Some(crate::modelling::effects::scale_for(t, reference)?),
        (Some(_), None) => {
            return Err(Error::InvalidArgument {
                what: "--temperature",
                message: "the model file has no temperature effect, so no reference \
                          temperature: refit with `unlag fit ... --add temperature`"
                    .into(),
            })
        }
        (None, _) => None,
    };
    let y_model =
        crate::modelling::effects::predict_with(&file.model, &file.effects, u, &trace.y, scale);
    let observed = crate::modelling::effects::observed(&file.effects, file.model.fs, &trace.y);
    let error = fit::nrmse_of(&observed, &y_model);
    crate::file::write_atomically_with(&args.output, |out| {
        Ok(trace.write_csv_with(out, &[("y_model", &y_model)])?)
    })?;
    if args.json {
        let v = json!({
            "output": name(&args.output),
            "samples": trace.len(),
            "nrmse": error,
        });
        crate::outln!("{v}");
        return Ok(());
    }
    crate::outln!(
        "simulated {} samples of {}: model against measurement nrmse {}",
        trace.len(),
        trace.path.display(),
        pct(error)
    );
    crate::outln!("wrote {}", args.output.display());
    Ok(())
}
