//! `unlag compensate`: its arguments, the recording compensated through the library's pipeline,
//! its error against the recorded reference printed, and the warnings that keep a worse run or a
//! clamped input from passing in silence.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use serde_json::json;

use super::{check_rate, console, name, pct, ColumnArgs};
use crate::error::Result;
use crate::file::{BoardArithmetic, ModelFile};
use crate::pipeline::{self, CompensateRequest, Compensated, Compensation, ReferenceError};
use crate::trace::{Columns, Trace};

/// Arithmetic of the compensator run on the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Arithmetic {
    /// 32-bit float, as on a Cortex-M4F board.
    F32,
    /// 64-bit float.
    F64,
    /// 32-bit fixed point, bit for bit what a board without an FPU computes (the model file's
    /// fixed-point plan, from `unlag invert` or `unlag fit`).
    Fixed,
}

/// Arguments of `unlag compensate`.
#[derive(Debug, Args)]
pub struct CompensateArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// The probe recording (CSV). A file is read in passes, each row written as it is
    /// compensated, so that memory does not grow with the recording; a pipe or a device,
    /// which cannot be read twice, is held in memory.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Output CSV: the input columns plus `u_hat`.
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: PathBuf,
    /// Replace an existing file at the output's path that is not an output of this command
    /// (a read-only file is never replaced).
    #[arg(long)]
    pub force: bool,
    /// Arithmetic of the compensator. Default: the board's, from the model file's `[board]`
    /// (`unlag fit --board`): f32, or fixed point bit for bit as the board computes it.
    #[arg(long, value_enum)]
    pub arithmetic: Option<Arithmetic>,
    /// Use the paper's direct inverse (eq. 7) even when the model file has a compensator.
    #[arg(long)]
    pub direct: bool,
    /// Host only: the non-causal optimum on the whole recorded run (no latency, the least
    /// error a linear filter can reach), from the model and the noise and prior stored with
    /// its optimal compensator. A board cannot run it. Holds the whole recording in memory
    /// (about 45 bytes a row).
    #[arg(long, conflicts_with_all = ["direct", "arithmetic", "adapt_to_run"])]
    pub offline: bool,
    /// Host only: when the run's own probe spectrum predicts the model file's compensator not
    /// to beat the raw probe, run in f64 the design predicted best for this run instead (the
    /// delay alone, the probe passed through, or the optimum under a quieter prior). A board
    /// given the model file runs the stored one; for a board, design with such runs: `unlag
    /// invert MODEL TEST.csv --signal RUN.csv`. Holds the whole recording in memory (about 45
    /// bytes a row).
    #[arg(long, conflicts_with_all = ["direct", "arithmetic"])]
    pub adapt_to_run: bool,
    /// Gas temperature of the recording (K): the model (with a `temperature` effect) is scaled
    /// to it and its compensator designed anew, as a board given that temperature runs it.
    #[arg(long, value_name = "K")]
    pub temperature: Option<f64>,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

impl From<Arithmetic> for pipeline::Arithmetic {
    fn from(a: Arithmetic) -> Self {
        match a {
            Arithmetic::F32 => Self::F32,
            Arithmetic::F64 => Self::F64,
            Arithmetic::Fixed => Self::Fixed,
        }
    }
}

/// The run as the messages name it.
struct Run {
    path: PathBuf,
    len: usize,
}

/// A write that returned without its result: never, since the write fills it or fails.
fn unreachable_written(output: &Path) -> Result<pipeline::Compensated> {
    Err(crate::error::Error::Io {
        path: output.to_path_buf(),
        action: "cannot write",
        source: std::io::Error::other("the output was written without a result"),
    })
}

/// `unlag compensate`.
///
/// # Errors
/// The model file's, the trace's and the compensator's errors.
pub fn run_compensate(args: &CompensateArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    let (arithmetic, compensation) = compensation_asked(args, &file);
    let columns = args.columns.columns(false);
    // A regular file is read in passes; a pipe or a device, which cannot be read twice, is
    // held (within the reader's limits), as the host-only compensators hold any run.
    let rereadable = std::fs::metadata(&args.file).is_ok_and(|m| m.is_file());
    let (run, c) = if pipeline::streams(compensation) && rereadable {
        compensate_streaming(args, &file, &columns, compensation)?
    } else {
        compensate_whole(args, &file, &columns, compensation)?
    };
    warn_about_run(args, &file, &run, &c);
    print_compensated(args, &file, arithmetic, &run, &c);
    Ok(())
}

/// The arithmetic and the compensator asked for: the board's arithmetic unless another is given.
fn compensation_asked(args: &CompensateArgs, file: &ModelFile) -> (Arithmetic, Compensation) {
    // The board's arithmetic unless another is asked for.
    let arithmetic = args.arithmetic.unwrap_or(match file.board.arithmetic {
        BoardArithmetic::F32 => Arithmetic::F32,
        BoardArithmetic::Fixed => Arithmetic::Fixed,
    });
    let compensation = if args.offline {
        Compensation::Offline
    } else if args.adapt_to_run {
        Compensation::AdaptedToRun
    } else if args.direct {
        Compensation::Direct(arithmetic.into())
    } else {
        Compensation::Designed(arithmetic.into())
    };
    (arithmetic, compensation)
}

/// A regular file compensated in passes, each row written as it is compensated.
fn compensate_streaming(
    args: &CompensateArgs,
    file: &ModelFile,
    columns: &Columns,
    compensation: Compensation,
) -> Result<(Run, Compensated)> {
    // The run read in passes, each row written as it is compensated: memory does not
    // grow with the run.
    let prepared = pipeline::prepare(&pipeline::StreamRequest {
        file,
        model_path: &args.model,
        run: &args.file,
        columns,
        compensation,
        temperature_k: args.temperature,
    })?;
    let run = Run {
        path: prepared.info().path.clone(),
        len: prepared.info().len,
    };
    // An output that cannot be taken back gets nothing from a clipped run.
    let output = &args.output;
    if output == Path::new("-") || std::fs::metadata(output).is_ok_and(|m| !m.is_file()) {
        prepared.check_clipping()?;
    }
    let mut done = None;
    crate::file::write_atomically_with(&args.output, |out| {
        done = Some(prepared.write(out)?);
        Ok(())
    })?;
    let c = match done {
        Some(c) => c,
        None => unreachable_written(&args.output)?,
    };
    Ok((run, c))
}

/// The whole run read at once (the host-only compensators, a pipe), compensated and written.
fn compensate_whole(
    args: &CompensateArgs,
    file: &ModelFile,
    columns: &Columns,
    compensation: Compensation,
) -> Result<(Run, Compensated)> {
    // The host-only compensators see the whole run at once; so does a piped run.
    let trace = Trace::read(&args.file, columns)?;
    check_rate(file, &trace)?;
    let c = pipeline::compensate(&CompensateRequest {
        file,
        model_path: &args.model,
        probe: &trace.y,
        reference: trace.u.as_deref(),
        compensation,
        temperature_k: args.temperature,
    })?;
    // A host-only u_hat says so in the file itself, where it cannot be separated from it.
    let metadata = c.host_only.then(|| {
        format!(
            "# unlag compensate: u_hat is from {} and is not what a board given {} computes\n",
            c.compensator,
            name(&args.model)
        )
    });
    crate::file::write_atomically_with(&args.output, |out| {
        if let Some(line) = &metadata {
            out.write_all(line.as_bytes())?;
        }
        Ok(trace.write_csv_with(out, &[("u_hat", &c.u_hat)])?)
    })?;
    let run = Run {
        path: trace.path.clone(),
        len: trace.len(),
    };
    Ok((run, c))
}

/// The run's warnings and notes: clamps and saturation, a still reference, a fall-back, a predicted loss.
fn warn_about_run(args: &CompensateArgs, file: &ModelFile, run: &Run, c: &Compensated) {
    // A clamped input or a saturation is never hidden.
    if let Some(f) = &c.fixed {
        if f.clamped_inputs > 0 {
            crate::errln!(
                "warning: {} samples of {} lie outside the fixed-point full scale +-{} and were clamped",
                f.clamped_inputs,
                run.path.display(),
                console::pressure(f.full_scale, file.board.unit)
            );
        }
        if f.overflowed {
            crate::errln!("warning: the fixed-point compensator saturated (overflow flag set)");
        }
    }
    if c.still_reference {
        let msg = format!(
            "note: the reference of {} does not move above its noise: no error against it is reported",
            name(&args.file)
        );
        console::note(args.json, &msg);
    }
    if let (Some(f), Some(stored)) = (&c.fall_back, &c.predicted) {
        let msg = format!(
            "note: on {} the model file's compensator is predicted to leave {:.2}x the raw probe's error \
             (from the run's own probe spectrum and the stored noise), so {} ran instead ({:.2}x, host only: \
             a board given {} runs the stored one); for a board running runs like this one: \
             `unlag invert {} TEST.csv --signal {} -o ...`",
            name(&args.file),
            stored.ratio(),
            f.what,
            f.chosen.ratio(),
            name(&args.model),
            args.model.display(),
            args.file.display()
        );
        console::note(args.json, &msg);
    }
    // The board's compensator predicted not to beat the raw probe: one line, unless the run's
    // reference measures it (then `warn_if_worse` says what was measured).
    let predicted_worse = c.predicted.filter(|p| {
        c.fall_back.is_none()
            && !c.host_only
            && c.error.is_none()
            && p.ratio() >= crate::design::inverse::check::RUN_MARGIN
    });
    if let Some(p) = predicted_worse {
        crate::errln!(
            "warning: on {} the model file's compensator is predicted not to beat the raw probe: it \
             leaves {:.2}x its error (from the run's own probe spectrum and the stored noise): its design assumed signals \
             like its tests'. For a board running runs like this one, design with them: `unlag invert {} \
             TEST.csv --signal {} -o ...` (`--adapt-to-run` shows what the host can do on it)",
            name(&args.file),
            p.ratio(),
            args.model.display(),
            args.file.display()
        );
    }
}

/// The result, as JSON or as text, and the warning when u_hat is worse than the raw probe.
fn print_compensated(
    args: &CompensateArgs,
    file: &ModelFile,
    arithmetic: Arithmetic,
    run: &Run,
    c: &Compensated,
) {
    let (latency, what, error) = (c.latency_samples, c.compensator, c.error);
    let not_better = c.stored_not_better.as_ref().map(|m| m.short());
    let arith = match arithmetic {
        _ if args.offline || c.host_only => "f64",
        Arithmetic::F32 => "f32",
        Arithmetic::F64 => "f64",
        Arithmetic::Fixed => "32-bit fixed point",
    };
    let fs = file.model.fs;
    if args.json {
        let v = json!({
            "output": name(&args.output),
            "samples": run.len,
            "compensator": what,
            "latency_samples": latency,
            "latency_s": latency / fs,
            "arithmetic": arith,
            "host_only": c.host_only,
            "clamped_inputs": c.fixed.map(|f| f.clamped_inputs),
            "full_scale": c.fixed.map(|f| f.full_scale),
            "nrmse_u_hat": error.map(|e| e.u_hat),
            "nrmse_raw": error.map(|e| e.raw),
            "alignment_samples": error.map(|e| e.lag),
            "verdict": error.map(|e| if e.worse() { "worse" } else { "better" }),
            "predicted_on_run": c.predicted.map(|p| json!({"u_hat": p.design, "raw": p.raw})),
            "run_fall_back": c.fall_back.as_ref().map(|f| json!({
                "what": f.what,
                "predicted_u_hat": f.chosen.design,
            })),
        });
        crate::outln!("{v}");
        warn_if_worse(args, not_better, error);
        return;
    }
    crate::outln!(
        "compensated {} samples of {} with {what} ({arith}); u_hat lags the true pressure by {} samples ({})",
        run.len,
        run.path.display(),
        console::significant(latency),
        super::console::duration(latency / fs)
    );
    if let Some(e) = error {
        crate::outln!(
            "error against the recorded reference (RMS / range, best alignment): u_hat {} (at {} samples), raw probe {}",
            pct(e.u_hat),
            e.lag,
            pct(e.raw)
        );
    }
    crate::outln!("wrote {}", args.output.display());
    warn_if_worse(args, not_better, error);
}

/// A compensated run further from its recorded reference than the raw probe is never passed
/// over in silence: one line on stderr with both errors and the remedy. A design the fit's
/// check already found no better than the raw probe (the delay alone, or the probe passed
/// through; `not_better` is its method) says so instead of a remedy.
fn warn_if_worse(args: &CompensateArgs, not_better: Option<&str>, error: Option<ReferenceError>) {
    let Some(error) = error.filter(ReferenceError::worse) else {
        return;
    };
    let (e, raw) = (error.u_hat, error.raw);
    if let Some(method) = not_better {
        crate::errln!(
            "warning: on {} u_hat is no closer to the recorded reference than the raw probe ({} against {}): \
             {}'s compensator is {}, stored marked not-better (no design beat the raw probe on the fit's tests)",
            args.file.display(),
            pct(e),
            pct(raw),
            args.model.display(),
            method
        );
        return;
    }
    crate::errln!(
        "warning: on {} u_hat is further from the recorded reference than the raw probe ({} against {}): \
         the compensator makes this run worse. Its design assumed signals like its tests'; \
         for runs like this one, learn the signal from them: `unlag invert {} TEST.csv --signal {} -o ...` \
         (`--adapt-to-run` shows what the host can do on it)",
        args.file.display(),
        pct(e),
        pct(raw),
        args.model.display(),
        args.file.display()
    );
}
