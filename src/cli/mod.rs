//! The `unlag` command line: argument parsing and one function per subcommand.
//!
//! Owns what the user sees on the terminal: tables, one-line errors, `--json` output (one JSON
//! object on stdout). All files are written atomically. The numerical work lives in the
//! library modules; this module only wires them together.

use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand, ValueEnum};
use serde_json::json;

use crate::design::inverse;
use crate::error::{Error, Result};
use crate::file::{ModelFile, FORMAT_VERSION};
use crate::fit::model::Source;
use crate::fit::{self, Method, Options, Order, Test};
use crate::trace::{Columns, Trace};

pub mod console;
pub mod export;
pub mod inspect;
pub mod modelling;
pub mod physics;
pub mod report;

/// Give pressure probes back their bandwidth: fit a model from a step test, compensate.
#[derive(Debug, Parser)]
#[command(name = "unlag", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit a model to a step test. The first FILE is the estimation test; any others are
    /// held-out validation tests (used to choose the order and reported).
    Fit(FitArgs),
    /// Reconstruct the reference from the probe signal with the board's compensator; adds
    /// column `u_hat` (the reference, delayed by the model's delay).
    Compensate(CompensateArgs),
    /// Simulate the model's probe output from the reference; adds column `y_model`.
    Simulate(SimulateArgs),
    /// Design the board's compensator for a model: a stable, band-limited inverse in
    /// second-order sections, with its bandwidth, noise gain and latency.
    Invert(InvertArgs),
    /// Analyse a model: poles and zeros, stability and minimum-phase margins, DC gain,
    /// resonances, delay, continuous-time equivalent and frequency response.
    Inspect(inspect::InspectArgs),
    /// Re-discretise a model at another sample rate (step invariant, fractional delay kept).
    Resample(inspect::ResampleArgs),
    /// Write the board's compensator as Rust consts, a C header or a binary blob.
    Export(export::ExportArgs),
    /// The model against step tests: fit %, error against the noise floor, and the residual
    /// evidence (autocorrelation, input cross-correlation, spectrum peaks, level and trend).
    Compare(modelling::LoopArgs),
    /// Name the missing physical effect: candidates ranked by evidence and a trial refit, each
    /// with the change that adds it (`unlag fit --add KIND`).
    Diagnose(modelling::LoopArgs),
    // physics subcommands (issue 6)
    /// Simulate a step test of a physical probe (Bergh-Tijdeman lines, hole, cavity,
    /// diaphragm, leak, minor losses) under a facility's excitation; writes t,u,y as CSV.
    SimulateTest(Box<physics::SimulateTestArgs>),
    /// Predict a physical probe's exact first modes, front delay and lumped approximation,
    /// and compare them with a fitted model (--model).
    Predict(physics::PredictArgs),
    /// Write an HTML report of a model against step tests: traces, residuals, spectra,
    /// correlations, Bode and pole-zero plots, error history and the ranked candidates.
    Report(report::ReportArgs),
}

/// Column names and sample rate of the input CSV.
#[derive(Debug, Clone, Args)]
pub struct ColumnArgs {
    /// Time column (seconds).
    #[arg(long = "t", default_value = "t", value_name = "NAME")]
    pub time_column: String,
    /// Reference column.
    #[arg(long = "u", default_value = "u", value_name = "NAME")]
    pub input_column: String,
    /// Probe column.
    #[arg(long = "y", default_value = "y", value_name = "NAME")]
    pub output_column: String,
    /// Sample rate in Hz, for files without a time column.
    #[arg(long, value_name = "HZ")]
    pub fs: Option<f64>,
}

impl ColumnArgs {
    fn columns(&self, require_input: bool) -> Columns {
        Columns {
            time: self.time_column.clone(),
            input: self.input_column.clone(),
            output: self.output_column.clone(),
            sample_rate_hz: self.fs,
            require_input,
        }
    }
}

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

/// How to design the compensator (shared by `fit` and `invert`).
#[derive(Debug, Clone, Args)]
pub struct InverseArgs {
    /// Instead of the noise-aware optimum (the default), a stable inverse times a low-pass at
    /// this corner in Hz, or `auto`: the corner that reconstructs the tests' references best.
    #[arg(long, value_name = "HZ|auto")]
    pub bandwidth: Option<String>,
    /// Longest latency of `u_hat` behind the true pressure the optimum may take (the model's
    /// delay included): `3ms`, `250us`, `0.002s` or a number of samples. Default: the
    /// shortest within 2 % of the best error the board's 16 sections allow.
    #[arg(long, value_name = "TIME|SAMPLES")]
    pub max_latency: Option<String>,
    /// Largest -3 dB band in Hz the optimum may take (a quieter prior narrows it to this).
    #[arg(long, value_name = "HZ")]
    pub max_band: Option<f64>,
    /// The user's own recorded runs (CSV, repeatable) to learn the pressure's prior from,
    /// instead of the step tests: from their reference column the increments' level and
    /// correlation (steps and ramps), else a random walk's level from the probe signal.
    #[arg(long = "signal", value_name = "RUN.csv")]
    pub signal: Vec<PathBuf>,
    /// Low-pass family of the band limit.
    #[arg(long, value_enum, default_value_t = LowpassArg::Bessel)]
    pub lowpass: LowpassArg,
    /// Low-pass order.
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub lowpass_order: usize,
    /// Use the paper's direct inverse A/B (times the low-pass) instead of the stable one; fails
    /// for a non-minimum-phase model.
    #[arg(long)]
    pub direct: bool,
    /// The ADC's full scale in the probe's units (inputs within +-FS never overflow the
    /// fixed-point compensator). Default: the largest |y| of the tests, plus 25 %.
    #[arg(long, value_name = "FS")]
    pub full_scale: Option<f64>,
    /// The fixed-point form: `normal` (coupled sections: no limit cycles, 100 dB at
    /// fs/fn = 1000, about 115 instructions a sample for m = 4 on a Cortex-M4) or `direct`
    /// (direct form I with error feedback: about 33, limit cycles of a few codes possible,
    /// about 90 dB at fs/fn = 1000). See BENCHMARKS.md, "Fixed point: the two forms".
    #[arg(long, value_enum, default_value_t = FixedFormArg::Normal)]
    pub fixed_form: FixedFormArg,
}

/// Fixed-point form on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FixedFormArg {
    /// Normal (coupled) state-space sections (`unlag::fixed::FixedCascade`).
    Normal,
    /// Direct-form-I sections with error feedback (`unlag::fixed::direct::DirectCascade`).
    Direct,
}

impl From<FixedFormArg> for crate::design::quantise::FixedForm {
    fn from(v: FixedFormArg) -> Self {
        match v {
            FixedFormArg::Normal => Self::Normal,
            FixedFormArg::Direct => Self::Direct,
        }
    }
}

/// Low-pass family on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LowpassArg {
    /// Bessel: maximally flat delay, a step barely overshoots.
    Bessel,
    /// Butterworth: maximally flat magnitude.
    Butterworth,
}

impl InverseArgs {
    /// Adds the fixed-point plan to `design` for the given full scale, or the largest `|y|` of
    /// `tests` plus 25 %. A plan that cannot be made is reported and left out: the f32
    /// compensator does not depend on it.
    fn plan_fixed(&self, design: &mut inverse::Design, tests: &[Test<'_>]) -> Result<()> {
        let full_scale = match self.full_scale {
            Some(fs) => fs,
            None => {
                let peak = tests
                    .iter()
                    .flat_map(|t| t.y.iter())
                    .fold(0.0f64, |m, v| m.max(v.abs()));
                if peak > 0.0 {
                    1.25 * peak
                } else {
                    1.0
                }
            }
        };
        let planned = match crate::design::quantise::FixedForm::from(self.fixed_form) {
            crate::design::quantise::FixedForm::Normal => {
                crate::design::quantise::FixedPlan::new(design, full_scale)
                    .map(|p| design.fixed = Some(p))
            }
            crate::design::quantise::FixedForm::Direct => {
                crate::design::quantise::DirectPlan::new(design, full_scale)
                    .map(|p| design.fixed_direct = Some(p))
            }
        };
        match planned {
            Ok(()) => {}
            // A full scale the user gave that makes no sense is their error.
            Err(e @ Error::InvalidArgument { .. }) => return Err(e),
            Err(e) => crate::errln!("warning: no fixed-point compensator: {e}"),
        }
        Ok(())
    }

    /// The design asked for: the noise-aware optimum unless `--bandwidth` or `--direct` asks
    /// for the band-limited inverse. The probe noise is measured on the `raw` tests (a sensor
    /// resonance's prefilter would hide its level in band), the signal prior on the `designed`
    /// ones (prefiltered where the model has a prefilter).
    fn request(
        &self,
        model: &crate::fit::model::Model,
        effects: &[crate::modelling::effects::Effect],
        columns: &ColumnArgs,
        raw: &[Test<'_>],
        designed: &[Test<'_>],
        stored: Option<&inverse::Design>,
    ) -> Result<inverse::check::Request> {
        let lowpass = self.lowpass_kind();
        let band_limited = |bandwidth_hz| {
            inverse::check::Request::BandLimited(inverse::Options {
                bandwidth_hz,
                lowpass,
                lowpass_order: self.lowpass_order,
                stabilise: !self.direct,
            })
        };
        match self.bandwidth.as_deref() {
            None if !self.direct => {
                let (mut noise, prior) =
                    self.noise_and_prior(model, columns, raw, designed, stored)?;
                // A record with no quiet segment shows no coloured probe noise by itself: the
                // noise model fitted beside the dynamics (`coloured-noise`) supplies it.
                if noise.probe_ar_std == 0.0 {
                    if let Some(ar) = crate::modelling::effects::noise_model(effects) {
                        noise.take_ar_part(ar, crate::modelling::effects::innovation_std(effects));
                    }
                }
                self.optimal(model.fs, noise, prior)
            }
            None | Some("auto") => Ok(band_limited(None)),
            Some(text) => match text.parse::<f64>() {
                Ok(f) if f.is_finite() && f > 0.0 => Ok(band_limited(Some(f))),
                _ => Err(Error::InvalidArgument {
                    what: "--bandwidth",
                    message: format!("expected 'auto' or a frequency in Hz, got '{text}'"),
                }),
            },
        }
    }

    /// The probe noise, measured on the `raw` tests (a sensor resonance's prefilter would hide
    /// its level in band), and the signal prior, from `--signal` runs or the `designed` tests
    /// (prefiltered where the model has a prefilter); without tests, those `stored` with the
    /// model's last design.
    fn noise_and_prior(
        &self,
        model: &crate::fit::model::Model,
        columns: &ColumnArgs,
        raw: &[Test<'_>],
        designed: &[Test<'_>],
        stored: Option<&inverse::Design>,
    ) -> Result<(inverse::optimal::NoiseModel, inverse::optimal::SignalPrior)> {
        let stored = stored.and_then(|d| d.noise.zip(d.prior));
        let noise = match (raw.is_empty(), stored) {
            (true, Some((noise, _))) => noise,
            (true, None) => {
                return Err(Error::InvalidArgument {
                    what: "FILE",
                    message: "the optimal compensator needs a step test to measure the noise on \
                              (or a model file designed from one): give one, or ask for a \
                              band-limited inverse with --bandwidth HZ"
                        .into(),
                })
            }
            _ => inverse::optimal::estimate_noise(raw),
        };
        let prior = if self.signal.is_empty() {
            match (designed.is_empty(), stored) {
                (true, Some((_, prior))) => prior,
                _ => inverse::optimal::estimate_prior(
                    designed,
                    &inverse::optimal::estimate_noise(designed),
                ),
            }
        } else {
            let runs = self
                .signal
                .iter()
                .map(|f| Trace::read(f, &columns.columns(false)))
                .collect::<Result<Vec<_>>>()?;
            let pairs: Vec<(Option<&[f64]>, &[f64])> = runs
                .iter()
                .map(|r| (r.u.as_deref(), r.y.as_slice()))
                .collect();
            // The probe's response time: the slowest pole's time constant, at least 8 samples.
            let scale = model
                .poles()
                .ok()
                .and_then(|p| {
                    p.first()
                        .map(|p| (1.0 / (1.0 - p.norm()).max(1e-6)).min(1e5))
                })
                .unwrap_or(8.0) as usize;
            inverse::optimal::prior_from_runs(&pairs, model.dc_gain(), &noise, scale.max(8))
        };
        Ok((noise, prior))
    }

    /// The optimum's request with the user's latency and band caps.
    fn optimal(
        &self,
        fs: f64,
        noise: inverse::optimal::NoiseModel,
        prior: inverse::optimal::SignalPrior,
    ) -> Result<inverse::check::Request> {
        let lowpass = self.lowpass_kind();
        Ok(inverse::check::Request::Optimal {
            options: inverse::optimal::OptimalOptions {
                max_band_hz: match self.max_band {
                    Some(f) if !(f.is_finite() && f > 0.0) => {
                        return Err(Error::InvalidArgument {
                            what: "--max-band",
                            message: format!("expected a frequency in Hz, got {f}"),
                        })
                    }
                    other => other,
                },
                max_latency_samples: self
                    .max_latency
                    .as_deref()
                    .map(|v| parse_latency(v, fs))
                    .transpose()?,
                lowpass,
                lowpass_order: self.lowpass_order,
            },
            noise: Some(noise),
            prior: Some(prior),
        })
    }

    /// The low-pass family asked for.
    fn lowpass_kind(&self) -> inverse::LowpassKind {
        match self.lowpass {
            LowpassArg::Bessel => inverse::LowpassKind::Bessel,
            LowpassArg::Butterworth => inverse::LowpassKind::Butterworth,
        }
    }
}

/// `3ms`, `250us`, `0.002s` or a number of samples, as samples at `fs`.
fn parse_latency(text: &str, fs: f64) -> Result<usize> {
    let t = text.trim();
    let seconds = |v: &str, unit: f64| v.trim().parse::<f64>().ok().map(|x| x * unit * fs);
    let samples = if let Some(v) = t.strip_suffix("ms") {
        seconds(v, 1e-3)
    } else if let Some(v) = t.strip_suffix("us") {
        seconds(v, 1e-6)
    } else if let Some(v) = t.strip_suffix('s') {
        seconds(v, 1.0)
    } else {
        t.parse::<f64>().ok()
    };
    match samples {
        Some(n) if (0.0..1e9).contains(&n) => Ok(n.floor() as usize),
        _ => Err(Error::InvalidArgument {
            what: "--max-latency",
            message: format!(
                "expected a time such as 3ms, 250us or 0.002s, or a number of samples, got '{text}'"
            ),
        }),
    }
}

/// Arguments of `unlag invert`.
#[derive(Debug, Args)]
pub struct InvertArgs {
    /// The model file.
    #[arg(value_name = "MODEL.toml")]
    pub model: PathBuf,
    /// Tests with a reference, to choose the bandwidth on and to report the reconstruction.
    #[arg(value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Where to write the model with its compensator (may be MODEL.toml itself).
    #[arg(short = 'o', long = "output", value_name = "OUT.toml")]
    pub output: PathBuf,
    /// Compensator design.
    #[command(flatten)]
    pub inverse: InverseArgs,
    /// Column names.
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
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
    /// (the estimation test's gas temperature). Effects already in the output model file are
    /// kept.
    #[arg(long = "add", value_name = "KIND")]
    pub add: Vec<String>,
    /// Start afresh: ignore the effects and history of an existing output model file.
    #[arg(long)]
    pub fresh: bool,
    /// Also write the HTML report of the fitted model against the tests (as `unlag report`).
    #[arg(long, value_name = "REPORT.html")]
    pub report: Option<PathBuf>,
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

/// Runs a parsed command line.
///
/// # Errors
/// Any [`Error`]; the caller prints it and exits non-zero.
pub fn run(cli: Cli) -> Result<()> {
    cli.command.guard_files()?;
    match cli.command {
        Command::Fit(a) => run_fit(&a),
        Command::Compensate(a) => run_compensate(&a),
        Command::Simulate(a) => run_simulate(&a),
        Command::Invert(a) => run_invert(&a),
        Command::Inspect(a) => inspect::run_inspect(&a),
        Command::Compare(a) => modelling::run_compare(&a),
        Command::Diagnose(a) => modelling::run_diagnose(&a),
        Command::Resample(a) => inspect::run_resample(&a),
        Command::SimulateTest(a) => physics::run_simulate_test(&a),
        Command::Predict(a) => physics::run_predict(&a),
        Command::Export(a) => export::run_export(&a),
        Command::Report(a) => report::run_report(&a),
    }
}

/// Step tests for the library, one per trace (`names[i]` names `traces[i]`).
///
/// # Errors
/// [`Error::MissingColumn`] when a trace has no reference column.
pub(crate) fn as_tests<'a>(traces: &'a [Trace], names: &'a [String]) -> Result<Vec<Test<'a>>> {
    traces
        .iter()
        .zip(names)
        .map(|(t, n)| {
            Ok(Test {
                name: n,
                u: t.input()?,
                y: &t.y,
            })
        })
        .collect()
}

/// Reads a test the model is fitted or judged on: a trace whose reference moves above its
/// noise (a step, or another change). A record with no excitation tells nothing about the
/// probe and would only mislead the order and band choices, so it is refused.
///
/// # Errors
/// The trace's errors, and [`Error::NoStep`] for a reference without excitation.
pub(crate) fn read_test(path: &Path, columns: &Columns) -> Result<Trace> {
    let t = Trace::read(path, columns)?;
    if let Ok(u) = t.input() {
        let e = fit::step::excitation(u);
        if e < fit::step::MIN_EXCITATION {
            return Err(Error::NoStep {
                path: t.path.clone(),
                column: t.u_column.unwrap_or(0),
                name: columns.input.clone(),
                reason: format!(
                    "the reference does not move above its noise (its spread is {e:.2} times \
                     the noise; at least {} is needed): a test without a step or other change \
                     tells nothing about the probe",
                    fit::step::MIN_EXCITATION
                ),
            });
        }
    }
    Ok(t)
}

/// A number for a table: one decimal, or a power of ten when it would not fit.
pub(crate) fn number(x: f64) -> String {
    if x.is_finite() && x.abs() < 1e7 {
        format!("{x:.1}")
    } else {
        format!("{x:.3e}")
    }
}

pub(crate) fn name(p: &Path) -> String {
    p.display().to_string()
}

/// A fraction as a percentage a table can hold: three decimals in the ordinary range,
/// powers of ten for a diverged candidate or a noise-free fit, `n/a` for no number.
pub(crate) fn pct(x: f64) -> String {
    let p = 100.0 * x;
    if !p.is_finite() {
        "n/a".into()
    } else if p.abs() >= 1e4 || (p != 0.0 && p.abs() < 1e-3) {
        format!("{p:.1e} %")
    } else {
        format!("{p:.3} %")
    }
}

fn run_fit(args: &FitArgs) -> Result<()> {
    let order = if args.order == "auto" {
        Order::Auto {
            max: args.max_order,
        }
    } else {
        match args.order.parse::<usize>() {
            Ok(m) if (1..=crate::fit::model::MAX_ORDER).contains(&m) => Order::Fixed(m),
            _ => {
                return Err(Error::InvalidArgument {
                    what: "--order",
                    message: format!(
                        "expected 'auto' or a number 1..={}, got '{}'",
                        crate::fit::model::MAX_ORDER,
                        args.order
                    ),
                })
            }
        }
    };
    if args.max_order == 0 || args.max_order > crate::fit::model::MAX_ORDER {
        return Err(Error::InvalidArgument {
            what: "--max-order",
            message: format!("must be 1..={}", crate::fit::model::MAX_ORDER),
        });
    }
    let method = match args.method {
        MethodArg::Oe => Method::Oe,
        MethodArg::Bj => Method::Bj,
        MethodArg::Sm => Method::Sm,
        MethodArg::Arx => Method::Arx,
    };
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
    let traces = args
        .files
        .iter()
        .map(|f| read_test(f, &columns))
        .collect::<Result<Vec<_>>>()?;
    let Some((est, val)) = traces.split_first() else {
        return Err(Error::InvalidArgument {
            what: "FILE",
            message: "give at least one step test".into(),
        });
    };
    for t in val {
        let rel = (t.sample_rate_hz - est.sample_rate_hz).abs() / est.sample_rate_hz;
        if rel > crate::trace::MAX_JITTER {
            return Err(Error::Mismatch {
                path: t.path.clone(),
                message: format!(
                    "sampled at {:.6} Hz but the estimation test {} at {:.6} Hz: resample one of them",
                    t.sample_rate_hz,
                    est.path.display(),
                    est.sample_rate_hz
                ),
            });
        }
    }
    let names: Vec<String> = traces.iter().map(|t| name(&t.path)).collect();
    let tests = as_tests(&traces, &names)?;
    let (est_test, val_tests) = tests.split_first().ok_or_else(|| Error::InvalidArgument {
        what: "FILE",
        message: "give at least one step test".into(),
    })?;
    let options = Options {
        method,
        order,
        delay: args.delay,
    };
    // The modelling loop: the output file's effects and history carry over.
    // A file in the way that is not a model is never replaced silently; --fresh replaces a
    // model (even a broken one), never a file that is not TOML at all (a recorded test).
    if args.fresh && args.output.is_file() {
        let text = std::fs::read(&args.output).unwrap_or_default();
        let is_toml = std::str::from_utf8(&text)
            .ok()
            .is_some_and(|t| t.parse::<toml::Table>().is_ok());
        if !is_toml {
            return Err(Error::InvalidArgument {
                what: "output",
                message: format!(
                    "{} exists and is not a model file (not TOML): refusing to replace it; \
                     give another path",
                    args.output.display()
                ),
            });
        }
    }
    let previous = if args.fresh || args.output == Path::new("-") || !args.output.exists() {
        None
    } else {
        Some(
            ModelFile::load(&args.output).map_err(|e| Error::InvalidArgument {
                what: "output",
                message: format!(
                    "{} exists and is not a model this fit can continue ({e}); give another path, \
                 or --fresh to replace it",
                    args.output.display()
                ),
            })?,
        )
    };
    let mut effects: Vec<crate::modelling::effects::Effect> = previous
        .as_ref()
        .map(|p| p.effects.clone())
        .unwrap_or_default();
    if let Some(p) = &previous {
        // An explicit order is the order asked for: a carried-over mode (two more poles)
        // would silently override it.
        let explicit_order = matches!(order, Order::Fixed(_));
        let dropped = if explicit_order {
            let before = effects.len();
            effects.retain(|e| e.kind() != crate::modelling::effects::EffectKind::Mode);
            before - effects.len()
        } else {
            0
        };
        if !p.effects.is_empty() || !p.history.is_empty() {
            let kept: Vec<&str> = effects.iter().map(|e| e.kind().as_str()).collect();
            let msg = format!(
                "continuing {}: keeping its effects [{}] and {} history row(s){} (--fresh starts over)",
                args.output.display(),
                kept.join(", "),
                p.history.len(),
                if dropped > 0 {
                    format!("; {dropped} mode effect(s) dropped because --order is given")
                } else {
                    String::new()
                }
            );
            console::note(args.json, &msg);
        }
    }
    // `--add delay` (what a diagnosis names `delay`): the delay searched again, as the
    // diagnosis did, and kept as the model's from then on.
    let mut search_delay = false;
    for kind in &args.add {
        if kind.parse() == Ok(crate::modelling::effects::EffectKind::Delay) {
            effects.retain(|x| x.kind() != crate::modelling::effects::EffectKind::Delay);
            search_delay = true;
            continue;
        }
        let e = crate::modelling::effects::Effect::parse(kind).ok_or_else(|| Error::InvalidArgument {
            what: "--add",
            message: format!(
                "unknown effect '{kind}': one of {}, or delay=N, sensor-resonance=HZ, sensor-resonance-prefilter[=HZ], temperature=K, temperature-viscous[=K]",
                crate::modelling::effects::KINDS
                    .iter()
                    .map(|k| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
        effects.retain(|x| {
            x.kind() != e.kind() || e.kind() == crate::modelling::effects::EffectKind::Mode
        });
        effects.push(e);
    }
    // A later `delay=N` among the additions fixes it: nothing to search then.
    search_delay &= !effects
        .iter()
        .any(|e| e.kind() == crate::modelling::effects::EffectKind::Delay);
    progress.step("fitting (orders on a window, then the whole record)");
    let fitted = crate::modelling::effects::fit_with(
        est_test,
        val_tests,
        est.sample_rate_hz,
        &options,
        &effects,
    )
    .map(|(f, fx)| {
        effects = fx;
        if search_delay {
            effects.push(crate::modelling::effects::Effect::Delay {
                samples: f.model.delay,
            });
        }
        f
    })
    .map_err(|e| match e {
        // The library does not know the column's position in the file; the trace does.
        Error::NoStep { path, reason, .. } => Error::NoStep {
            column: est.u_column.unwrap_or(0),
            name: columns.input.clone(),
            path,
            reason,
        },
        e => e,
    })?;
    // Errors with the effects included (an offset or a drift is estimated on each test).
    let mut sources = Vec::new();
    for (i, (t, test)) in traces.iter().zip(&tests).enumerate() {
        let quiet = fit::step::quiet_until(test.u);
        sources.push(Source {
            file: name(&t.path),
            sha256: t.sha256.clone(),
            role: if i == 0 { "estimation" } else { "validation" }.into(),
            // With a noise model, the one-step-ahead prediction error (said when printed).
            nrmse: crate::modelling::effects::judged_nrmse(&fitted.model, &effects, test.u, test.y),
            noise_floor: fit::noise_floor(&t.y, quiet),
        });
    }
    // The probe's geometry describes the hardware, not the fit: kept even with --fresh.
    let probe = if args.fresh {
        ModelFile::load(&args.output).ok().and_then(|p| p.probe)
    } else {
        previous.as_ref().and_then(|p| p.probe.clone())
    };
    let mut history = previous.map(|p| p.history).unwrap_or_default();
    history.push(crate::file::HistoryRow {
        effects: effects.iter().map(|e| e.kind().to_string()).collect(),
        order: fitted.model.order(),
        delay: fitted.model.delay,
        tests: sources
            .iter()
            .map(|s| crate::file::HistoryTest {
                file: s.file.clone(),
                role: s.role.clone(),
                nrmse: s.nrmse,
            })
            .collect(),
    });
    // With a sensor resonance the inverse is designed on the prefiltered tests, and the
    // prefilter runs in front of it: each test prefiltered once.
    let filtered = prefiltered_tests(&tests, &effects, est.sample_rate_hz);
    let filtered: Vec<Test<'_>> = filtered
        .iter()
        .zip(&tests)
        .map(|((u, y), t)| Test { name: t.name, u, y })
        .collect();
    let (est_filtered, val_filtered) = filtered.split_at(1.min(filtered.len()));
    // The check judges on the held-out tests, or the estimation test when it is alone.
    let judge = if val_filtered.is_empty() {
        est_filtered
    } else {
        val_filtered
    };
    // The noise and the prior come from the step tests: the estimation test and the held-out
    // ones that are clean steps with a quiet segment before them. A held-out run of another
    // kind (a balloon, a traverse) is what the check judges on, not what the design learns
    // from: a compensator learnt from the very run it is checked on passes its own check.
    let is_step: Vec<bool> = tests
        .iter()
        .enumerate()
        .map(|(i, t)| i == 0 || fit::step::quiet_until(t.u) >= inverse::optimal::MIN_QUIET)
        .collect();
    let raw_steps = kept(&tests, &is_step);
    let designed = kept(&filtered, &is_step);
    // The fit stands on its own: if no compensator can be designed, say why and keep the model.
    progress.step("designing the compensator");
    let design = match inverse::check::design_checked(
        &fitted.model,
        judge,
        &args.inverse.request(
            &fitted.model,
            &effects,
            &args.columns,
            &raw_steps,
            &designed,
            None,
        )?,
        crate::modelling::effects::nonlinear_gain(&effects),
    )
    .and_then(|mut d| {
        crate::modelling::effects::with_prefilter(&mut d, &effects, est.sample_rate_hz)?;
        Ok(d)
    }) {
        Ok(mut d) => {
            args.inverse.plan_fixed(&mut d, judge)?;
            Some(d)
        }
        Err(e) => {
            crate::errln!("warning: no compensator designed: {e}");
            None
        }
    };
    let file = ModelFile {
        format_version: FORMAT_VERSION,
        model: fitted.model.clone(),
        fit: Some(fitted.report.clone()),
        sources,
        inverse: design,
        effects,
        history,
        probe,
    };
    progress.step("writing the model");
    file.save(&args.output)?;
    let report_bytes = match &args.report {
        Some(path) => Some(report::write_report(
            path,
            &name(&args.output),
            &file,
            &tests,
            &progress,
        )?),
        None => None,
    };
    progress.finish();
    if args.json {
        let mut v = serde_json::to_value(&file).map_err(json_err)?;
        v["output"] = json!(name(&args.output));
        v["dc_gain"] = json!(file.model.dc_gain());
        if let Some(path) = &args.report {
            v["report"] = json!(name(path));
        }
        crate::outln!("{v}");
        return Ok(());
    }
    print_fit(&file, est);
    if let Some(d) = &file.inverse {
        print_inverse(d, file.model.fs);
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

/// Both channels of each test through the sensor-resonance prefilter of `effects` (unchanged
/// without one).
/// The tests whose `keep` flag is set.
fn kept<'t>(tests: &[Test<'t>], keep: &[bool]) -> Vec<Test<'t>> {
    tests
        .iter()
        .zip(keep)
        .filter_map(|(t, k)| k.then_some(*t))
        .collect()
}

fn prefiltered_tests(
    tests: &[Test<'_>],
    effects: &[crate::modelling::effects::Effect],
    fs: f64,
) -> Vec<(Vec<f64>, Vec<f64>)> {
    tests
        .iter()
        .map(|t| {
            (
                crate::modelling::effects::prefiltered(effects, fs, t.u),
                crate::modelling::effects::prefiltered(effects, fs, t.y),
            )
        })
        .collect()
}

fn print_inverse(d: &inverse::Design, fs: f64) {
    crate::outln!("compensator: {}", d.method);
    if !d.reflected_zeros.is_empty() {
        crate::outln!(
            "  zeros of B reflected into the unit circle: {}",
            d.reflected_zeros.join(", ")
        );
    }
    if !d.pulled_zeros.is_empty() {
        crate::outln!(
            "  zeros of B pulled in to |z| = {}: {}",
            inverse::ZERO_RADIUS_MAX,
            d.pulled_zeros.join(", ")
        );
    }
    if !d.candidates.is_empty() {
        crate::outln!("  bandwidth search ({}):", d.bandwidth_selection);
        for row in d.candidates.chunks(3) {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    let mark = if (c.lowpass_hz - d.lowpass_hz).abs() < 1e-9 {
                        '*'
                    } else {
                        ' '
                    };
                    format!(
                        "{mark}{:>9.1} Hz {:>9} (noise x{:<8.3})",
                        c.lowpass_hz,
                        pct(c.nrmse),
                        c.noise_gain
                    )
                })
                .collect();
            crate::outln!("   {}", cells.join(" "));
        }
    }
    // The smoother has no low-pass of its own: its band is where H C falls by 3 dB.
    let smoother = d.is_smoother();
    if smoother {
        crate::outln!(
            "  -3 dB band of the corrected probe {:.1} Hz; {} sections",
            d.lowpass_hz,
            d.sections.len()
        );
    } else {
        crate::outln!(
            "  {:?} low-pass, order {}, corner {:.1} Hz; {} sections",
            d.lowpass,
            d.lowpass_order,
            d.lowpass_hz,
            d.sections.len()
        );
    }
    crate::outln!(
        "  corrected bandwidth {:.1} Hz (+/-1 dB, +/-5 deg); noise gain {:.3}; latency {:.2} samples ({:.6} s)",
        d.corrected_bandwidth_hz, d.noise_gain, d.latency_samples, d.latency_s
    );
    crate::outln!(
        "  in band ({}): worst magnitude error {:.3} dB, worst phase error {:.2} deg; pole margin {:.4}",
        if smoother {
            "to half the -3 dB band, against a pure delay"
        } else {
            "to the corner"
        },
        d.in_band_magnitude_error_db,
        d.in_band_phase_error_deg,
        d.pole_margin
    );
    if let Some(p) = &d.fixed {
        let forms: Vec<&str> = p.sections.iter().map(|s| s.form.as_str()).collect();
        crate::outln!(
            "  fixed point: inputs within +-{} (Q1.31), output Q1.31 of {} x 2^{}; L1 gain {:.3}; headroom {:.2} bits by the L1 bound (no overflow possible); sections {}",
            p.full_scale,
            p.full_scale,
            p.output_exponent,
            p.l1_gain,
            p.headroom_bits,
            forms.join(", ")
        );
    }
    if let Some(p) = &d.fixed_direct {
        crate::outln!(
            "  fixed point (direct form with error feedback): inputs within +-{} (Q1.31), output Q1.31 of {} x 2^{}; L1 gain {:.3}; headroom {:.2} bits by the L1 bound (no overflow possible); {} sections",
            p.full_scale,
            p.full_scale,
            p.output_exponent,
            p.l1_gain,
            p.headroom_bits,
            p.sections.len()
        );
    }
    if let Some(b) = &d.budget {
        crate::outln!(
            "  predicted error of u_hat (RMS, pressure units): {:.4} = noise {:.4} + band limit {:.4} (in quadrature); a noisy reference adds {:.4}",
            b.total, b.noise, b.band_limit, b.reference
        );
    }
    if let Some(n) = &d.noise {
        crate::outln!(
            "  noise ({:?}): probe {:.3e} white{}, reference {:.3e}",
            n.source,
            n.probe_white_std,
            if n.probe_ar_std > 0.0 {
                format!(
                    " + {:.3e} AR(1) pole {:.4}",
                    n.probe_ar_std, n.probe_ar_pole
                )
            } else {
                String::new()
            },
            n.reference_std
        );
    }
    if let Some(p) = &d.prior {
        let from = match p.source {
            inverse::optimal::PriorSource::StepTests => "the step tests' references",
            inverse::optimal::PriorSource::Runs => "the --signal runs",
            inverse::optimal::PriorSource::Given => "given",
        };
        if p.increment_pole > 0.0 {
            // The increments' pole as a corner: rho = exp(-2 pi f / fs).
            let corner = -p.increment_pole.ln() * fs / (2.0 * std::f64::consts::PI);
            crate::outln!(
                "  signal prior (from {from}): steps and ramps, increments correlated {:.4} (its spectrum falls as 1/f^4 above {corner:.1} Hz), innovation {:.3e}",
                p.increment_pole, p.increment_std
            );
        } else {
            crate::outln!(
                "  signal prior (from {from}): steps, a random walk of increment {:.3e} per sample (its spectrum falls as 1/f^2)",
                p.increment_std
            );
        }
    }
    crate::outln!(
        "  realised as {} sections: about {} multiply-adds per sample",
        d.sections.len(),
        5 * d.sections.len() + 1
    );
    for r in &d.reconstruction {
        let expected = match (&d.budget, r.range) {
            (Some(b), Some(range)) if range > 0.0 => format!(
                "; expected {} from noise and band limit{}",
                pct(b.total.hypot(b.reference) / range),
                match r.model_part {
                    Some(m) => format!(", the rest ({}) is the model's", pct(m)),
                    None => String::new(),
                }
            ),
            _ => String::new(),
        };
        crate::outln!(
            "  reconstruction of {}: u_hat {} against the reference, raw probe {} ({:.1}x better){expected}",
            r.file,
            pct(r.nrmse_u_hat),
            pct(r.nrmse_raw),
            r.nrmse_raw / r.nrmse_u_hat
        );
    }
    if let Some(c) = &d.check {
        match c.verdict {
            inverse::check::Verdict::Better | inverse::check::Verdict::Unchecked => {}
            inverse::check::Verdict::FellBack => crate::errln!(
                "warning: fell back to {}: {}",
                d.method.short(),
                c.rejected.join("; ")
            ),
            inverse::check::Verdict::NotBetter => crate::errln!(
                "warning: no compensator is better than the raw probe on these tests ({}); stored marked not-better, `unlag export` refuses it without --force",
                c.rejected.join("; ")
            ),
        }
    }
}

fn run_invert(args: &InvertArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    let columns = args.columns.columns(true);
    let traces = args
        .files
        .iter()
        .map(|f| read_test(f, &columns))
        .collect::<Result<Vec<_>>>()?;
    for t in &traces {
        check_rate(&file, t)?;
    }
    let names: Vec<String> = traces.iter().map(|t| name(&t.path)).collect();
    let tests = as_tests(&traces, &names)?;
    let raw_tests = tests;
    let filtered = prefiltered_tests(&raw_tests, &file.effects, file.model.fs);
    let tests: Vec<Test<'_>> = filtered
        .iter()
        .zip(&raw_tests)
        .map(|((u, y), t)| Test { name: t.name, u, y })
        .collect();
    let mut design = inverse::check::design_checked(
        &file.model,
        &tests,
        &args.inverse.request(
            &file.model,
            &file.effects,
            &args.columns,
            &raw_tests,
            &tests,
            file.inverse.as_ref(),
        )?,
        crate::modelling::effects::nonlinear_gain(&file.effects),
    )?;
    crate::modelling::effects::with_prefilter(&mut design, &file.effects, file.model.fs)?;
    design.check_exportable()?;
    args.inverse.plan_fixed(&mut design, &tests)?;
    let out = ModelFile {
        inverse: Some(design),
        ..file
    };
    out.save(&args.output)?;
    if args.json {
        let mut v = serde_json::to_value(&out.inverse).map_err(json_err)?;
        v["output"] = json!(name(&args.output));
        crate::outln!("{v}");
        return Ok(());
    }
    if let Some(d) = &out.inverse {
        print_inverse(d, out.model.fs);
    }
    crate::outln!("wrote {}", args.output.display());
    Ok(())
}

pub(crate) fn json_err(e: serde_json::Error) -> Error {
    Error::Numerical {
        context: "json".into(),
        message: e.to_string(),
    }
}

fn print_fit(file: &ModelFile, est: &Trace) {
    let m = &file.model;
    let Some(r) = &file.fit else { return };
    crate::outln!(
        "estimation test {}: {} samples at {} Hz, step onset at sample {} (t = {:.6} s)",
        est.path.display(),
        est.len(),
        est.sample_rate_hz,
        r.step_onset,
        r.step_onset as f64 / est.sample_rate_hz
    );
    for note in &r.notes {
        crate::outln!("note: {note}");
    }
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
        let crit = if r.order_selection.contains("held-out") {
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
    crate::outln!(
        "model: order {}, delay {} samples ({:.6} s), method {}",
        m.order(),
        m.delay,
        m.delay as f64 / m.fs,
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
    match file.effects.iter().find_map(|e| match e {
        crate::modelling::effects::Effect::ColouredNoise { ar, innovation_std } => {
            Some((ar, innovation_std))
        }
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
    }
}

fn run_compensate(args: &CompensateArgs) -> Result<()> {
    let file = ModelFile::load(&args.model)?;
    // A board given the gas temperature runs the coefficient set rescaled to it.
    let file = match args.temperature {
        Some(t) => file.at_temperature(t)?,
        None => file,
    };
    let trace = Trace::read(&args.file, &args.columns.columns(false))?;
    check_rate(&file, &trace)?;
    let m = &file.model;
    // Offset and drift are the probe's, not the pressure's: removed before compensation.
    let additive = crate::modelling::effects::Additive::of(&file.effects);
    let y_probe = additive.removed_from(&trace.y, m.fs);
    let design = if args.direct {
        None
    } else {
        file.inverse.as_ref()
    };
    // Quadratic losses: the board adds gain * lowpass(|dy| dy) to the linear inverse.
    let nonlinear = crate::modelling::effects::nonlinear_gain(&file.effects);
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
            let y_in = crate::modelling::effects::prefiltered(&file.effects, m.fs, &y_probe);
            (
                inverse::optimal::offline(m, noise, prior, &y_in)?,
                crate::modelling::effects::prefilter_delay(&file.effects, m.fs),
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
            let y_probe = crate::modelling::effects::prefiltered(&file.effects, m.fs, &y_probe);
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
        let u = &crate::modelling::effects::observed(&file.effects, m.fs, u);
        let prefilter = if design.is_some() {
            crate::modelling::effects::prefilter_delay(&file.effects, m.fs)
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

pub(crate) fn check_rate(file: &ModelFile, trace: &Trace) -> Result<()> {
    let rel = (trace.sample_rate_hz - file.model.fs).abs() / file.model.fs;
    if rel > crate::trace::MAX_JITTER {
        return Err(Error::Mismatch {
            path: trace.path.clone(),
            message: format!(
                "sampled at {:.6} Hz but the model is for {:.6} Hz",
                trace.sample_rate_hz, file.model.fs
            ),
        });
    }
    Ok(())
}

fn run_simulate(args: &SimulateArgs) -> Result<()> {
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
    crate::trace::write_atomically_with(&args.output, |out| {
        trace.write_csv_with(out, &[("y_model", &y_model)])
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

/// Prints a failed command's error as one JSON object on standard output (`--json`):
/// `{"error": {"kind", "message", "path", "line", "column"}}`, the location fields only where
/// known.
pub fn print_json_error(
    kind: &str,
    message: &str,
    path: Option<&Path>,
    line: Option<u64>,
    column: Option<u64>,
) {
    use std::io::Write as _;
    let mut e = serde_json::Map::new();
    e.insert("kind".into(), json!(kind));
    e.insert("message".into(), json!(message.trim_end()));
    if let Some(p) = path {
        e.insert("path".into(), json!(p.display().to_string()));
    }
    if let Some(l) = line {
        e.insert("line".into(), json!(l));
    }
    if let Some(c) = column {
        e.insert("column".into(), json!(c));
    }
    let _ = writeln!(std::io::stdout().lock(), "{}", json!({ "error": e }));
}

/// What an input file is to a command, for the message that refuses to overwrite it.
const DATA: &str = "a recorded test";
const MODEL: &str = "the model file";

impl Command {
    /// Whether the command prints one JSON object (`--json`).
    #[must_use]
    pub fn json(&self) -> bool {
        match self {
            Self::Fit(a) => a.json,
            Self::Compensate(a) => a.json,
            Self::Simulate(a) => a.json,
            Self::Invert(a) => a.json,
            Self::Inspect(a) => a.json,
            Self::Resample(a) => a.json,
            Self::Export(a) => a.json,
            Self::Compare(a) | Self::Diagnose(a) => a.json,
            Self::SimulateTest(a) => a.json,
            Self::Predict(a) => a.json,
            Self::Report(a) => a.json,
        }
    }

    /// The files the command writes, and those it reads with what each is. A model that the
    /// command exists to update (`invert -o MODEL.toml`, `fit -o` onto the model it refits)
    /// is not listed as an input: rewriting it is the point.
    fn files(&self) -> (Vec<&Path>, Vec<(&Path, &'static str)>) {
        fn data(v: &[PathBuf]) -> Vec<(&Path, &'static str)> {
            v.iter().map(|p| (p.as_path(), DATA)).collect()
        }
        match self {
            Self::Fit(a) => {
                let mut inputs = data(&a.files);
                inputs.extend(data(&a.inverse.signal));
                // The report must not replace the model just written either: see guard_files.
                let outputs = std::iter::once(a.output.as_path())
                    .chain(a.report.as_deref())
                    .collect();
                (outputs, inputs)
            }
            Self::Invert(a) => {
                let mut inputs = data(&a.files);
                inputs.extend(data(&a.inverse.signal));
                (vec![a.output.as_path()], inputs)
            }
            Self::Compensate(a) => (
                vec![a.output.as_path()],
                vec![(a.model.as_path(), MODEL), (a.file.as_path(), DATA)],
            ),
            Self::Simulate(a) => (
                vec![a.output.as_path()],
                vec![(a.model.as_path(), MODEL), (a.file.as_path(), DATA)],
            ),
            Self::Resample(a) => (vec![a.output.as_path()], vec![(a.model.as_path(), MODEL)]),
            Self::Export(a) => (vec![a.output.as_path()], vec![(a.model.as_path(), MODEL)]),
            Self::Report(a) => {
                let mut inputs = data(&a.files);
                inputs.push((a.model.as_path(), MODEL));
                (vec![a.output.as_path()], inputs)
            }
            Self::Compare(a) | Self::Diagnose(a) => {
                let mut inputs = data(&a.files);
                inputs.push((a.model.as_path(), MODEL));
                (a.report.iter().map(PathBuf::as_path).collect(), inputs)
            }
            Self::SimulateTest(a) => (vec![a.output.as_path()], Vec::new()),
            Self::Inspect(_) | Self::Predict(_) => (Vec::new(), Vec::new()),
        }
    }

    /// Before any work: refuses an output that is one of the inputs (by the file it names,
    /// through links), and routes the command's text to standard error when an output is
    /// `-` (standard output), which `--json` cannot share.
    fn guard_files(&self) -> Result<()> {
        // `fit -o MODEL --report PAGE`: two outputs of one run, which must differ. The model
        // may already exist (a refit onto it is the point), so it is not an input.
        if let Self::Fit(FitArgs {
            output,
            report: Some(page),
            ..
        }) = self
        {
            if page == output || same_file::is_same_file(page, output).unwrap_or(false) {
                return Err(Error::Overwrite {
                    output: page.clone(),
                    input: output.clone(),
                    what: "the model file this fit writes",
                });
            }
        }
        let (outputs, inputs) = self.files();
        for out in &outputs {
            if *out == Path::new("-") {
                if self.json() {
                    return Err(Error::InvalidArgument {
                        what: "output",
                        message: "`-o -` writes the data to standard output, where --json \
                                  writes its object too: give a file, or drop --json"
                            .into(),
                    });
                }
                console::data_on_stdout();
                continue;
            }
            for (input, what) in &inputs {
                if same_file::is_same_file(out, input).unwrap_or(false) {
                    return Err(Error::Overwrite {
                        output: out.to_path_buf(),
                        input: input.to_path_buf(),
                        what,
                    });
                }
            }
        }
        Ok(())
    }
}
