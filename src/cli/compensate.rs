//! `unlag compensate`: the model file's compensator (or the paper's direct inverse, or the
//! offline optimum) run on a recording, its error against the recorded reference, and the
//! warnings that keep a worse run or a clamped input from passing in silence.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use serde_json::json;

use super::{check_rate, console, name, pct, ColumnArgs};
use crate::error::{Error, Result};
use crate::fit;
use crate::inverse;
use crate::model::ModelFile;
use crate::trace::Trace;

/// Arithmetic of the compensator run on the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Arithmetic {
    /// 32-bit float, as on a Cortex-M4F board (default).
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
    /// The probe recording (CSV).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Output CSV: the input columns plus `u_hat`.
    #[arg(short = 'o', long = "output", value_name = "OUT.csv")]
    pub output: PathBuf,
    /// Arithmetic of the compensator.
    #[arg(long, value_enum, default_value_t = Arithmetic::F32)]
    pub arithmetic: Arithmetic,
    /// Use the paper's direct inverse (eq. 7) even when the model file has a compensator.
    #[arg(long)]
    pub direct: bool,
    /// Host only: the non-causal optimum on the whole recorded run (no latency, the least
    /// error a linear filter can reach), from the model and the noise and prior stored with
    /// its optimal compensator. A board cannot run it.
    #[arg(long, conflicts_with_all = ["direct", "arithmetic"])]
    pub offline: bool,
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

/// `unlag compensate`.
///
/// # Errors
/// The model file's, the trace's and the compensator's errors.
pub fn run_compensate(args: &CompensateArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    // A board given the gas temperature runs the coefficient set rescaled to it.
    let file = match args.temperature {
        Some(t) => crate::effects::at_temperature(&file, t)?,
        None => file,
    };
    let trace = Trace::read(&args.file, &args.columns.columns(false))?;
    check_rate(&file, &trace)?;
    let m = &file.model;
    // Offset and drift are the probe's, not the pressure's: removed before compensation.
    let additive = crate::effects::Additive::of(&file.effects);
    let y_probe = additive.removed_from(&trace.y, m.fs);
    let design = if args.direct {
        None
    } else {
        file.inverse.as_ref()
    };
    // Quadratic losses: the board adds gain * lowpass(|dy| dy) to the linear inverse.
    let nonlinear = crate::effects::nonlinear_gain(&file.effects);
    if args.offline && design.is_none() {
        return Err(Error::InvalidArgument {
            what: "--offline",
            message: format!(
                "{} has no compensator design to take the noise and prior from: run `unlag invert`",
                args.model.display()
            ),
        });
    }
    let (mut u_hat, latency, what) = match design {
        Some(d) if args.offline => {
            let (Some(noise), Some(prior)) = (&d.noise, &d.prior) else {
                return Err(Error::InvalidArgument {
                    what: "--offline",
                    message: format!(
                        "{} has no stored noise and prior: design its compensator with `unlag invert` (without --bandwidth)",
                        args.model.display()
                    ),
                });
            };
            let y_in = crate::effects::prefiltered(&file.effects, m.fs, &y_probe);
            (
                inverse::optimal::offline(m, noise, prior, &y_in)?,
                crate::effects::prefilter_delay(&file.effects, m.fs),
                "the non-causal optimum (offline, host only)",
            )
        }
        Some(d) => {
            d.check_exportable()?;
            let mut u_hat = match args.arithmetic {
                Arithmetic::F32 => d.run::<f32>(&y_probe)?,
                Arithmetic::F64 => d.run::<f64>(&y_probe)?,
                Arithmetic::Fixed if nonlinear != 0.0 => {
                    return Err(Error::UnsupportedOnBoard {
                        path: args.model.clone(),
                        effect: "nonlinear damping",
                        arithmetic: "fixed-point",
                        hint: "use --arithmetic f32",
                    })
                }
                Arithmetic::Fixed => run_fixed(d, &args.model, &trace, &y_probe)?,
            };
            if nonlinear != 0.0 {
                let correction = match args.arithmetic {
                    Arithmetic::F64 => {
                        d.run_nonlinear_correction::<f64>(m.fs, nonlinear, &y_probe)?
                    }
                    _ => d.run_nonlinear_correction::<f32>(m.fs, nonlinear, &y_probe)?,
                };
                for (u, c) in u_hat.iter_mut().zip(correction) {
                    *u += c;
                }
            }
            (u_hat, d.latency_samples, "the model file's compensator")
        }
        None => {
            m.check_invertible(&name(&args.model))?;
            // The direct inverse of a model fitted below a sensor resonance gets the prefilter.
            let y_probe = crate::effects::prefiltered(&file.effects, m.fs, &y_probe);
            let u_hat = match args.arithmetic {
                Arithmetic::F32 => m.compensate::<f32>(&y_probe)?,
                Arithmetic::F64 => m.compensate::<f64>(&y_probe)?,
                Arithmetic::Fixed => {
                    return Err(Error::InvalidArgument {
                        what: "--arithmetic",
                        message: "fixed point runs the designed compensator in sections, not \
                                  the paper's direct inverse: drop --direct, or run `unlag invert`"
                            .into(),
                    })
                }
            };
            (u_hat, m.delay as f64, "the paper's direct inverse (eq. 7)")
        }
    };
    if design.is_none() && nonlinear != 0.0 {
        // The direct inverse has no band limit: the correction is not filtered either.
        let c = crate::compensator::NonlinearDampingCoefficients::<f64, 1>::new(
            nonlinear * m.fs * m.fs,
            1.0,
            &[],
        )
        .map_err(|e| Error::Numerical {
            context: "nonlinear-damping correction".into(),
            message: e.to_string(),
        })?;
        let mut st = c.equilibrium(y_probe.first().copied().unwrap_or(0.0));
        for (u, y) in u_hat.iter_mut().zip(&y_probe) {
            *u += c.process(&mut st, *y);
        }
    }
    // Error against the recorded reference, at the best alignment near the latency.
    // With a sensor resonance the reference is judged below it (the compensator does not
    // and should not reproduce the reference transducer's own ringing).
    // A reference that does not move above its noise says nothing about u_hat: no error, no
    // verdict (a run without a step is compensated all the same).
    let still = trace
        .u
        .as_ref()
        .filter(|u| fit::step::excitation(u) < fit::step::MIN_EXCITATION)
        .is_some();
    if still {
        let msg = format!(
            "note: the reference of {} does not move above its noise: no error against it is reported",
            name(&args.file)
        );
        console::note(args.json, &msg);
    }
    let error = trace.u.as_ref().filter(|_| !still).map(|u| {
        let u = &crate::effects::observed(&file.effects, m.fs, u);
        let prefilter = if design.is_some() {
            crate::effects::prefilter_delay(&file.effects, m.fs)
        } else {
            0.0
        };
        let nominal = (latency - prefilter).round().max(0.0) as usize;
        // The raw probe is searched over the same lags whatever the compensator's latency
        // (the offline optimum has none), so that its error does not depend on it.
        let causal = design
            .map_or(latency, |d| d.latency_samples)
            .round()
            .max(0.0) as usize;
        let (lags, raw_lags) = inverse::comparison_lags(design, nominal, causal, m.delay);
        let (e, lag) = inverse::aligned_error(u, &u_hat, lags);
        let (raw, _) = inverse::aligned_error(u, &trace.y, raw_lags);
        (e, raw, lag)
    });
    crate::trace::write_atomically_with(&args.output, |out| {
        trace.write_csv_with(out, &[("u_hat", &u_hat)])
    })?;
    let arith = match args.arithmetic {
        _ if args.offline => "f64",
        Arithmetic::F32 => "f32",
        Arithmetic::F64 => "f64",
        Arithmetic::Fixed => "32-bit fixed point",
    };
    if args.json {
        let v = json!({
            "output": name(&args.output),
            "samples": trace.len(),
            "compensator": what,
            "latency_samples": latency,
            "latency_s": latency / m.fs,
            "arithmetic": arith,
            "nrmse_u_hat": error.map(|e| e.0),
            "nrmse_raw": error.map(|e| e.1),
            "alignment_samples": error.map(|e| e.2),
            "verdict": error.map(|(e, raw, _)| if worse(e, raw) { "worse" } else { "better" }),
        });
        crate::outln!("{v}");
        warn_if_worse(args, design, error);
        return Ok(());
    }
    crate::outln!(
        "compensated {} samples of {} with {what} ({arith}); u_hat lags the true pressure by {:.2} samples ({:.6} s)",
        trace.len(),
        trace.path.display(),
        latency,
        latency / m.fs
    );
    if let Some((e, raw, lag)) = error {
        crate::outln!(
            "error against the recorded reference (RMS / range, best alignment): u_hat {} (at {lag} samples), raw probe {}",
            pct(e),
            pct(raw)
        );
    }
    crate::outln!("wrote {}", args.output.display());
    warn_if_worse(args, design, error);
    Ok(())
}

/// The compensated signal's error `e` is not below the raw probe's `raw`: a tie within f32
/// rounding (the probe passed through) is not better, and a NaN counts as worse: neither
/// passes silently.
fn worse(e: f64, raw: f64) -> bool {
    e.partial_cmp(&(raw * (1.0 - 1e-6))) != Some(std::cmp::Ordering::Less)
}

/// A compensated run further from its recorded reference than the raw probe is never passed
/// over in silence: one line on stderr with both errors and the remedy. A design the fit's
/// check already found no better than the raw probe (the delay alone, or the probe passed
/// through) says so instead of a remedy.
fn warn_if_worse(
    args: &CompensateArgs,
    design: Option<&inverse::Design>,
    error: Option<(f64, f64, usize)>,
) {
    let Some((e, raw, _)) = error else { return };
    if !worse(e, raw) {
        return;
    }
    let not_better = design
        .and_then(|d| d.check.as_ref())
        .is_some_and(|c| c.verdict == inverse::check::Verdict::NotBetter);
    if not_better {
        crate::errln!(
            "warning: on {} u_hat is no closer to the recorded reference than the raw probe ({} against {}): \
             {}'s compensator is {}, stored marked not-better (no design beat the raw probe on the fit's tests)",
            args.file.display(),
            pct(e),
            pct(raw),
            args.model.display(),
            design.map_or("", |d| d.method.short())
        );
        return;
    }
    crate::errln!(
        "warning: on {} u_hat is further from the recorded reference than the raw probe ({} against {}): \
         the compensator makes this run worse. Its design assumed signals like its tests'; \
         for runs like this one, learn the signal from them: `unlag invert {} TEST.csv --signal {} -o ...`",
        args.file.display(),
        pct(e),
        pct(raw),
        args.model.display(),
        args.file.display()
    );
}

/// The fixed-point compensator on the trace, refusing to hide a saturation.
fn run_fixed(d: &inverse::Design, model: &Path, trace: &Trace, y: &[f64]) -> Result<Vec<f64>> {
    if let Some(plan) = &d.fixed_direct {
        let run = plan.run(y)?;
        if run.clipped_inputs > 0 {
            crate::errln!(
                "warning: {} samples of {} lie outside the fixed-point full scale +-{} and were clamped",
                run.clipped_inputs,
                trace.path.display(),
                plan.full_scale
            );
        }
        if run.overflowed {
            crate::errln!("warning: the fixed-point compensator saturated (overflow flag set)");
        }
        return Ok(run.u_hat);
    }
    let plan = d.fixed.as_ref().ok_or_else(|| Error::InvalidArgument {
        what: "--arithmetic",
        message: format!(
            "{} has no fixed-point plan: run `unlag invert {} --full-scale FS -o ...`",
            model.display(),
            model.display()
        ),
    })?;
    let run = plan.run(y)?;
    if run.clipped_inputs > 0 {
        crate::errln!(
            "warning: {} samples of {} lie outside the fixed-point full scale +-{} and were clamped",
            run.clipped_inputs,
            trace.path.display(),
            plan.full_scale
        );
    }
    if run.overflowed {
        crate::errln!("warning: the fixed-point compensator saturated (overflow flag set)");
    }
    Ok(run.u_hat)
}
