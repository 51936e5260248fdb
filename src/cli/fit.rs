//! `unlag fit`: its arguments, the fit and its compensator through the library's pipeline, and
//! the fit printed.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use serde_json::json;

use super::invert::{full_scale_json, print_board, print_inverse, warn_unplanned, InverseArgs};
use super::{as_tests, console, json_err, name, number, pct, read_test, report, ColumnArgs};
use crate::effects::EffectKind;
use crate::error::{Error, Result};
use crate::file::{Board, HeldOutChange, HistoryRow, ModelFile};
use crate::fit::model::{FitReport, Model};
use crate::fit::Test;
use crate::fit::{Method, Options, Order};
use crate::pipeline::{self, FitDesignRequest, FitDesigned, FitStage, FullScale};
use crate::trace::{Columns, Trace};

/// Identification method on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Output error (default): unbiased under measurement noise.
    Oe,
    /// Box-Jenkins: output error with an autoregressive noise model, for coloured probe noise.
    Bj,
    /// Steiglitz-McBride iterations.
    Sm,
    /// The paper's direct least squares (biased by noise).
    Arx,
}

/// Arguments of `unlag fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Step-test CSV files: estimation first, then validation tests.
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Where to write the model (TOML).
    #[arg(short = 'o', long = "output", value_name = "MODEL.toml")]
    pub output: PathBuf,
    /// Model order: a number, or `auto` to choose.
    #[arg(long, default_value = "auto", value_name = "N|auto")]
    pub order: String,
    /// Largest order tried by `--order auto`.
    #[arg(long, default_value_t = 6, value_name = "N")]
    pub max_order: usize,
    /// Identification method.
    #[arg(long, value_enum, default_value_t = MethodArg::Bj)]
    pub method: MethodArg,
    /// Known delay in samples (skips the delay search).
    #[arg(long, value_name = "SAMPLES")]
    pub delay: Option<usize>,
    /// Add a physical effect to the model (repeatable): mode, leak, offset, drift,
    /// coloured-noise, nonlinear-damping, delay (searched again, then kept) or delay=N,
    /// sensor-resonance (the transducers' modes;
    /// frequency found in the reference) or sensor-resonance=HZ, sensor-resonance-prefilter[=HZ]
    /// (the paper's prefilter instead), temperature (reference 293.15 K) or temperature=K
    /// (the estimation test's gas temperature), temperature-viscous[=K] (the damping by the
    /// viscous law) or temperature-diffusive[=K] (a capillary: every time scale by the
    /// viscosity). Effects already in the output model file are kept.
    #[arg(long = "add", value_name = "KIND")]
    pub add: Vec<String>,
    /// Another estimation test fitted together with the first (repeatable): one model for
    /// several runs of the same probe (each test's error counted alike; an offset or a drift
    /// is each test's own). With nonlinear-damping, the quadratic loss too: one step cannot
    /// tell it from a linear damping, two steps (or runs) of different size can. Its error is
    /// then not held out, nor is the compensator judged on it.
    #[arg(long = "also", value_name = "FILE")]
    pub also: Vec<PathBuf>,
    /// Start afresh: ignore the effects and history of an existing output model file.
    #[arg(long)]
    pub fresh: bool,
    /// Also write the HTML report of the fitted model against the tests (as `unlag report`).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
    /// Replace an existing file at --report's path that is not an unlag report (a read-only
    /// file is never replaced). The model output is replaced only when it is a model file.
    #[arg(long, requires = "report")]
    pub force: bool,
    /// Compensator design (on the validation tests, or the estimation test if there are none).
    #[command(flatten)]
    pub inverse: InverseArgs,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
}

impl FitArgs {
    /// Method, order and delay, checked as the command line checks them (the Python package
    /// parses its keyword arguments into these same flags).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for an `--order` or `--max-order` out of range.
    pub fn options(&self) -> Result<Options> {
        let order = if self.order == "auto" {
            Order::Auto {
                max: self.max_order,
            }
        } else {
            match self.order.parse::<usize>() {
                Ok(m) if (1..=crate::fit::model::MAX_ORDER).contains(&m) => Order::Fixed(m),
                _ => {
                    return Err(Error::InvalidArgument {
                        what: "--order",
                        message: format!(
                            "expected 'auto' or a number 1..={}, got '{}'",
                            crate::fit::model::MAX_ORDER,
                            self.order
                        ),
                    })
                }
            }
        };
        if self.max_order == 0 || self.max_order > crate::fit::model::MAX_ORDER {
            return Err(Error::InvalidArgument {
                what: "--max-order",
                message: format!("must be 1..={}", crate::fit::model::MAX_ORDER),
            });
        }
        let method = match self.method {
            MethodArg::Oe => Method::Oe,
            MethodArg::Bj => Method::Bj,
            MethodArg::Sm => Method::Sm,
            MethodArg::Arx => Method::Arx,
        };
        Ok(Options {
            method,
            order,
            delay: self.delay,
        })
    }

    /// The model the fit replaces: the output file's, if there is one (under `--fresh`, only
    /// if it loads; the library keeps only its probe geometry then). A
    /// file in the way that is not a model is never replaced silently; `--fresh` replaces a
    /// model (even a broken one), never a file that is not TOML at all (a recorded test).
    fn previous(&self) -> Result<Option<ModelFile>> {
        // Only a regular file can hold a model to continue: a device (`/dev/null`, `/dev/full`)
        // or a pipe is written to, never read from.
        if self.output == Path::new("-") || !self.output.is_file() {
            return Ok(None);
        }
        if self.fresh {
            // Read as a model file is, within its size limit: a recording in the way is
            // refused without being read whole.
            let is_toml = crate::file::read_model_text(&self.output)
                .is_ok_and(|t| t.parse::<toml::Table>().is_ok());
            if !is_toml {
                return Err(Error::InvalidArgument {
                    what: "output",
                    message: format!(
                        "{} exists and is not a model file (not TOML): refusing to replace it; \
                         give another path",
                        self.output.display()
                    ),
                });
            }
            // A fresh fit still keeps the probe's geometry of the model it replaces.
            return Ok(ModelFile::load_for_redesign(&self.output)
                .ok()
                .map(|(f, _)| f));
        }
        // The fit designs the compensator anew: one stored for another model (or naming none)
        // is dropped, not refused.
        ModelFile::load_for_redesign(&self.output)
            .map(|(f, _)| Some(f))
            .map_err(|e| Error::InvalidArgument {
                what: "output",
                message: format!(
                    "{} exists and is not a model this fit can continue ({e}); give another path, \
                 or --fresh to replace it",
                    self.output.display()
                ),
            })
    }
}

/// `unlag fit`: the model fitted to the tests (continuing the output model file's modelling
/// loop), its compensator designed, the model file written, and the optional report.
///
/// # Errors
/// The arguments', the traces', the fit's and the files' errors; a compensator that cannot be
/// designed is a warning (the fit stands on its own).
pub fn run_fit(args: &FitArgs) -> Result<()> {
    let options = args.options()?;
    let columns = args.columns.columns(true);
    // Reading, fitting, designing, writing, and the report's stages.
    let progress = report::Progress::start(
        args.json,
        4 + if args.report.is_some() {
            report::REPORT_STAGES
        } else {
            0
        },
    );
    progress.step("reading the tests");
    let (traces, names, rates) = read_tests(args, &columns)?;
    let est = estimation_test(&traces)?;
    let tests = as_tests(&traces, &names)?;
    // The modelling loop: the output file's effects and history carry over.
    let previous = args.previous()?;
    // The board carries over from the model the fit replaces, as its probe geometry does.
    let board = args.inverse.board(
        previous.as_ref().map_or_else(Board::default, |p| p.board),
        &args.columns,
    );
    let digests: Vec<String> = traces.iter().map(|t| t.sha256.clone()).collect();
    // Modes named in this fit: a dropped mode named again needs no hint.
    let named_again = args
        .add
        .iter()
        .filter(|a| a.parse() == Ok(crate::effects::EffectKind::Mode))
        .count();
    let on_stage = |stage: FitStage| match stage {
        FitStage::Continuing {
            kept,
            history_rows,
            dropped_modes,
        } => continuing_note(args, &kept, history_rows, dropped_modes, named_again),
        FitStage::Fitting => progress.step("fitting (orders on a window, then the whole record)"),
        FitStage::Designing => progress.step("designing the compensator"),
    };
    let FitDesigned {
        mut file,
        no_compensator,
        unplanned,
        full_scale,
    } = pipeline::fit_and_design(&FitDesignRequest {
        tests: &tests,
        estimation_tests: 1 + args.also.len(),
        digests: &digests,
        sample_rates_hz: &rates,
        options,
        previous: previous.as_ref(),
        fresh: args.fresh,
        add: &args.add,
        reference_column: (est.u_column.unwrap_or(0), &columns.input),
        spec: &|fs| args.inverse.spec(&args.columns, fs, &board),
        on_stage: &on_stage,
    })?;
    // The fit stands on its own: if no compensator can be designed, say why and keep the model.
    if let Some(e) = no_compensator {
        crate::errln!("warning: no compensator designed: {e}");
    }
    warn_unplanned(&unplanned);
    file.board = board;
    progress.step("writing the model");
    file.save(&args.output)?;
    let changes = file.held_out_changes();
    let rises: Vec<&HeldOutChange> = changes.iter().filter(|c| c.rose()).collect();
    warn_error_rises(&rises, &file);
    let report_bytes = write_report_if_asked(args, &file, &tests, &progress)?;
    progress.finish();
    if args.json {
        return print_fit_json(args, &file, &full_scale, &rises);
    }
    print_fit(&file, est);
    print_held_out_changes(&changes, &file);
    if let Some(d) = &file.inverse {
        print_inverse(d, file.model.fs, file.board.unit);
        print_board(&file.board, &full_scale);
    }
    crate::outln!("wrote {}", args.output.display());
    if let (Some(path), Some(bytes)) = (&args.report, report_bytes) {
        crate::outln!(
            "wrote the report {} ({:.0} kB): open it in a browser",
            path.display(),
            bytes as f64 / 1e3
        );
    }
    Ok(())
}

/// The tests read (estimation, fitted together, held out), their rates checked alike and the `--signal` runs checked readable; with their names and rates.
fn read_tests(args: &FitArgs, columns: &Columns) -> Result<(Vec<Trace>, Vec<String>, Vec<f64>)> {
    // The estimation test, the ones fitted together with it, then the held-out ones.
    let traces = args
        .files
        .iter()
        .take(1)
        .chain(&args.also)
        .chain(args.files.iter().skip(1))
        .map(|f| read_test(f, columns))
        .collect::<Result<Vec<_>>>()?;
    estimation_test(&traces)?;
    let names: Vec<String> = traces.iter().map(|t| name(&t.path)).collect();
    let rates: Vec<f64> = traces.iter().map(|t| t.sample_rate_hz).collect();
    // Refused before the model file and the effects are looked at.
    pipeline::check_same_rate(
        &names
            .iter()
            .map(String::as_str)
            .zip(rates.iter().copied())
            .collect::<Vec<_>>(),
    )?;
    // The `--signal` runs are read again when the compensator is designed, after the fit: a
    // bad run is refused here, before minutes of fitting.
    if args.inverse.bandwidth.is_none() && !args.inverse.direct {
        for run in &args.inverse.signal {
            Trace::read(run, &args.columns.columns(false))?;
        }
    }
    Ok((traces, names, rates))
}

/// The estimation test: the first one read, refused when there is none.
fn estimation_test(traces: &[Trace]) -> Result<&Trace> {
    let Some((est, _)) = traces.split_first() else {
        return Err(Error::InvalidArgument {
            what: "FILE",
            message: "give at least one step test".into(),
        });
    };
    Ok(est)
}

/// The note that the fit continues an existing model file: the effects and history it keeps, the modes it drops.
fn continuing_note(
    args: &FitArgs,
    kept: &[EffectKind],
    history_rows: usize,
    dropped_modes: usize,
    named_again: usize,
) {
    let kept: Vec<&str> = kept.iter().map(|k| k.as_str()).collect();
    let msg = format!(
        "continuing {}: keeping its effects [{}] and {history_rows} history row(s){} \
         (--fresh starts over)",
        args.output.display(),
        kept.join(", "),
        match (dropped_modes, named_again) {
            (0, _) => String::new(),
            (d, again) if again >= d => {
                format!("; {d} mode effect(s) dropped because --order is given")
            }
            (d, _) => format!(
                "; {d} mode effect(s) dropped because --order is given (each \
                 `--add mode` names one again)"
            ),
        }
    );
    console::note(args.json, &msg);
}

/// The HTML report when `--report` asks for one: its size in bytes.
fn write_report_if_asked(
    args: &FitArgs,
    file: &ModelFile,
    tests: &[Test<'_>],
    progress: &report::Progress,
) -> Result<Option<usize>> {
    Ok(match &args.report {
        Some(path) => {
            let diagnosis = report::diagnosis(file, tests, false, progress)?;
            Some(report::write_report(
                path,
                &name(&args.output),
                file,
                tests,
                &diagnosis,
                progress,
            )?)
        }
        None => None,
    })
}

/// The fitted model file as one JSON object, with the output's name, DC gain, full scale, error rises and report.
fn print_fit_json(
    args: &FitArgs,
    file: &ModelFile,
    full_scale: &FullScale,
    rises: &[&HeldOutChange],
) -> Result<()> {
    let mut v = serde_json::to_value(file).map_err(json_err)?;
    v["output"] = json!(name(&args.output));
    v["dc_gain"] = json!(file.model.dc_gain());
    v["full_scale"] = full_scale_json(full_scale);
    v["error_rises"] = json!(rises);
    if let Some(path) = &args.report {
        v["report"] = json!(name(path));
    }
    crate::outln!("{v}");
    Ok(())
}

/// Warns of each held-out test whose error this fit raised over the fit the model file had
/// ([`HeldOutChange::rose`]): the loop's change made the model worse there, which must not
/// pass silently. Where the delay, searched again, moved, `--add delay=N` keeps the one
/// before.
fn warn_error_rises(rises: &[&HeldOutChange], file: &ModelFile) {
    let [.., before, after] = file.history.as_slice() else {
        return;
    };
    for r in rises {
        let delay = if r.delay_after == r.delay_before {
            String::new()
        } else {
            format!(
                "; the delay, searched again, moved from {} to {} samples: `--add delay={}` \
                 keeps the one before, in the model file for the fits after too",
                r.delay_before, r.delay_after, r.delay_before
            )
        };
        crate::errln!(
            "warning: the held-out error of {} rose from {} to {} with this fit ({}; before: \
             {}): the change does not help on data it was not fitted to{delay}",
            r.file,
            pct(r.before),
            pct(r.after),
            described(after),
            described(before),
        );
    }
}

/// A history row as the loop's messages name a fit: `order 2, delay 6, effects [leak]`.
fn described(row: &HistoryRow) -> String {
    format!(
        "order {}, delay {}, effects [{}]",
        row.order,
        row.delay,
        row.effect_names(", ")
    )
}

/// Where the fit continues a model file, each held-out test's error against the fit before
/// ([`ModelFile::held_out_changes`]): the loop's "watch the error fall", in the fit's own
/// output.
fn print_held_out_changes(changes: &[HeldOutChange], file: &ModelFile) {
    let [.., before, _] = file.history.as_slice() else {
        return;
    };
    if changes.is_empty() {
        return;
    }
    let each: Vec<String> = changes
        .iter()
        .map(|c| {
            let ratio = c.before / c.after;
            let verdict = if c.rose() {
                "rose".to_string()
            } else if ratio > 1.0 + crate::fit::ERROR_RISE_NOTED {
                format!("{ratio:.2}x lower")
            } else {
                "about the same".to_string()
            };
            format!(
                "{} {} -> {} ({verdict})",
                c.file,
                pct(c.before),
                pct(c.after)
            )
        })
        .collect();
    crate::outln!(
        "held-out errors against the fit before ({}): {}",
        described(before),
        each.join(", ")
    );
}

/// The fit as `unlag fit` prints it: the step, the delay and order searches, the model, its
/// uncertainty and noise model, and the errors on each test.
fn print_fit(file: &ModelFile, est: &Trace) {
    let m = &file.model;
    let Some(r) = &file.fit else { return };
    crate::outln!(
        "estimation test {}: {} samples at {} Hz, step onset at sample {} (t = {})",
        est.path.display(),
        est.len(),
        est.sample_rate_hz,
        r.step_onset,
        super::console::duration(r.step_onset as f64 / est.sample_rate_hz)
    );
    for note in &r.notes {
        crate::outln!("note: {note}");
    }
    print_delay_search(r, m);
    print_order_selection(r, m);
    print_model(r, m);
    print_errors(file);
}

/// The delay search's table: the simulation error per candidate delay, the chosen one marked.
fn print_delay_search(r: &FitReport, m: &Model) {
    if !r.delay_candidates.is_empty() {
        crate::outln!(
            "delay search, simulation nrmse per candidate delay ({}):",
            r.delay_selection
        );
        for row in r.delay_candidates.chunks(6) {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    let mark = if c.delay == m.delay { '*' } else { ' ' };
                    format!("{mark}{:>4} {:>8}", c.delay, pct(c.nrmse))
                })
                .collect();
            crate::outln!("  {}", cells.join("  "));
        }
    }
}

/// The order selection's table: each order's delay, error, criterion and stability, the chosen one marked.
fn print_order_selection(r: &FitReport, m: &Model) {
    crate::outln!("order selection ({}):", r.order_selection);
    crate::outln!(
        "  {:>5} {:>6} {:>14} {:>14} {:>7}",
        "order",
        "delay",
        "nrmse (est)",
        "criterion",
        "stable"
    );
    for o in &r.orders {
        let crit = if r.order_selection.rule() == Some(crate::fit::OrderRule::HeldOut) {
            pct(o.criterion)
        } else {
            number(o.criterion)
        };
        let mark = if o.order == m.order() {
            "  <- chosen"
        } else {
            ""
        };
        crate::outln!(
            "  {:>5} {:>6} {:>14} {:>14} {:>7}{mark}",
            o.order,
            o.delay,
            pct(o.nrmse_estimation),
            crit,
            if o.stable { "yes" } else { "no" }
        );
    }
}

/// The model: order, delay, coefficients, DC gain, uncertainty and a zero outside the unit circle.
fn print_model(r: &FitReport, m: &Model) {
    crate::outln!(
        "model: order {}, delay {} samples ({}), method {}",
        m.order(),
        m.delay,
        super::console::duration(m.delay as f64 / m.fs),
        r.method
    );
    crate::outln!("  a = {:?}", m.a);
    crate::outln!("  b = {:?}", m.b);
    crate::outln!("  DC gain {:.6} (1 for a calibrated probe)", m.dc_gain());
    if let Some(u) = &r.uncertainty {
        crate::outln!(
            "  uncertainty (1 sigma, from {}): {}",
            u.noise_text(),
            u.summary()
        );
    }
    if let Ok(z) = m.zeros() {
        if let Some(z) = z.first() {
            if z.norm() >= 1.0 {
                crate::outln!(
                    "  note: zero {} of B is outside the unit circle (|z| = {:.4}); the direct inverse is unstable",
                    crate::poly::format_root(*z),
                    z.norm()
                );
            }
        }
    }
}

/// The errors per test against their noise floors, under the noise model beside the dynamics if any.
fn print_errors(file: &ModelFile) {
    match file.effects.iter().find_map(|e| match e {
        crate::effects::Effect::ColouredNoise { ar, innovation_std } => Some((ar, innovation_std)),
        _ => None,
    }) {
        Some((ar, innovation)) => {
            crate::outln!(
                "noise model beside the dynamics: AR({}) D = [1, {}], innovation std {:.4e}",
                ar.len(),
                ar.iter()
                    .map(|d| format!("{d:.4}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                innovation
            );
            crate::outln!(
                "errors (one-step-ahead prediction D(q)(y - G u), RMS / range of y; the simulation error is in `unlag compare`):"
            );
        }
        None => crate::outln!("errors (simulation, RMS / range of y):"),
    }
    for s in &file.sources {
        crate::outln!(
            "  {:<11} {:<40} nrmse {:>10}   noise floor {:>10}",
            s.role,
            s.file,
            pct(s.nrmse),
            pct(s.noise_floor)
        );
        if let Some(p) = &s.prediction_floor {
            crate::outln!(
                "  {:<11} {:<40} the floor of a prediction error {:>10} ({})",
                "",
                "",
                pct(p.value),
                p.origin()
            );
        }
    }
}
