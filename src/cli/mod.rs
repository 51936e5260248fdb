//! The `unlag` command line: the commands, their shared arguments and helpers, and the guard
//! that no output replaces an input.
//!
//! Owns what the user sees on the terminal: tables, one-line errors, `--json` output (one JSON
//! object on stdout). All files are written atomically. Each command parses its arguments into
//! a request of the library ([`crate::pipeline`] and the modules behind it), runs it, and
//! prints what comes back; one module per command (or pair of commands).

use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand};
use serde_json::json;

use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::fit::Test;
use crate::trace::{Columns, Trace};

pub mod compensate;
pub mod console;
pub mod export;
pub mod fit;
pub mod inspect;
pub mod invert;
pub mod modelling;
pub mod physics;
pub mod predict;
pub mod reference;
mod replace;
pub mod report;
pub mod signals;
pub mod simulate;

pub use compensate::{Arithmetic, CompensateArgs};
pub use fit::{FitArgs, MethodArg};
pub use invert::{FixedFormArg, InverseArgs, InvertArgs, LowpassArg};
pub use simulate::SimulateArgs;

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
    /// Simulate a step test of a physical probe (Bergh-Tijdeman lines, hole, cavity,
    /// diaphragm, leak, minor losses) under a facility's excitation; writes t,u,y as CSV.
    SimulateTest(Box<physics::SimulateTestArgs>),
    /// Predict a physical probe's exact first modes, front delay and lumped approximation,
    /// and compare them with a fitted model (--model).
    Predict(predict::PredictArgs),
    /// Write an HTML report of a model against step tests: traces, residuals, spectra,
    /// correlations, Bode and pole-zero plots, error history and the ranked candidates.
    Report(report::ReportArgs),
}

/// Column names and sample rate of the input CSV.
#[derive(Debug, Clone, Args)]
pub struct ColumnArgs {
    /// Time column, in seconds unless its name gives the unit: `t_ms`, `time_us`, `t[ns]`.
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
    /// The character between fields: one ASCII character, or `tab` (also `\t`).
    #[arg(long, value_name = "CHAR", default_value = ",", value_parser = parse_delimiter)]
    pub delimiter: u8,
    /// Read a comma in a number as its decimal point (`0,5`); needs a --delimiter other than
    /// ','. Results are written back the same way.
    #[arg(long)]
    pub decimal_comma: bool,
}

/// A delimiter from the command line: one ASCII character that cannot be part of a number, a
/// name's quote or a comment, or `tab`.
fn parse_delimiter(text: &str) -> std::result::Result<u8, String> {
    let byte = match text {
        "tab" | "\\t" | "\t" => b'\t',
        _ => match text.as_bytes() {
            [b] => *b,
            _ => return Err(format!("'{text}' is not one character (give one, or tab)")),
        },
    };
    if byte.is_ascii_alphanumeric()
        || matches!(byte, b'.' | b'-' | b'+' | b'"' | b'#' | b'\n' | b'\r')
        || !byte.is_ascii()
    {
        return Err(format!(
            "'{}' cannot separate fields (it can be part of a number, a quote or a comment)",
            text.escape_debug()
        ));
    }
    Ok(byte)
}

impl ColumnArgs {
    /// The columns and dialect to read a CSV file with (the Python package reads files as the
    /// command line does); `require_input`: the reference column must be there.
    #[must_use]
    pub fn columns(&self, require_input: bool) -> Columns {
        Columns {
            time: self.time_column.clone(),
            input: self.input_column.clone(),
            output: self.output_column.clone(),
            sample_rate_hz: self.fs,
            require_input,
            delimiter: self.delimiter,
            decimal_comma: self.decimal_comma,
        }
    }
}

/// Runs a parsed command line.
///
/// # Errors
/// Any [`Error`]; the caller prints it and exits non-zero.
pub fn run(cli: Cli) -> Result<()> {
    cli.command.guard_files()?;
    match cli.command {
        Command::Fit(a) => fit::run_fit(&a),
        Command::Compensate(a) => compensate::run_compensate(&a),
        Command::Simulate(a) => simulate::run_simulate(&a),
        Command::Invert(a) => invert::run_invert(&a),
        Command::Inspect(a) => inspect::run_inspect(&a),
        Command::Compare(a) => modelling::run_compare(&a),
        Command::Diagnose(a) => modelling::run_diagnose(&a),
        Command::Resample(a) => inspect::run_resample(&a),
        Command::SimulateTest(a) => physics::run_simulate_test(&a),
        Command::Predict(a) => predict::run_predict(&a),
        Command::Export(a) => export::run_export(&a),
        Command::Report(a) => report::run_report(&a),
    }
}

/// The error as the command line says it: the library's message, and where the library
/// names a parameter, the flag that sets it.
#[must_use]
pub fn describe(e: &Error) -> String {
    use crate::error::Parameter;
    use crate::trace::{ColumnRole, TraceError};
    if let Error::Advised { error, advice } = e {
        return format!("{}: {}", describe(error), spell(advice));
    }
    if let Error::InvalidParameter { parameter, message } = e {
        let flag = match parameter {
            Parameter::Order => "--order",
            Parameter::Effect => "--add",
            Parameter::LowpassOrder => "--lowpass-order",
            Parameter::Bandwidth => "--bandwidth",
            Parameter::FullScale => "--full-scale",
            Parameter::Temperature => "--temperature",
            Parameter::Temperatures => "--temperatures",
            Parameter::Offline => "--offline",
            Parameter::Arithmetic => "--arithmetic",
            Parameter::Tests => "FILE",
            Parameter::SampleRate => "--fs",
            Parameter::MeanPressure => "--pressure",
            Parameter::EndVolume => "--volume",
            Parameter::HoleLength => "--hole length",
            Parameter::HoleDiameter => "--hole diameter",
            Parameter::HoleCavity => "--volume (the hole's cavity)",
            Parameter::TubeLength => "--line length",
            Parameter::TubeDiameter => "--line diameter",
            Parameter::Tubes => "--line",
            Parameter::CavityRadius => "--cavity-radius",
            Parameter::RiseTime => "--rise",
        };
        return format!("invalid {flag}: {message}");
    }
    if let Some(crate::physics::PhysicsError::NoTube) = e.stage() {
        return "invalid --line: give at least one --line LENGTH,DIAMETER (or a --hole)".into();
    }
    if let Some(crate::physics::PhysicsError::ModeCount { count }) = e.stage() {
        return format!(
            "invalid --modes: {count} must be 1..={}",
            crate::physics::MAX_MODES
        );
    }
    if let Some(crate::effects::EffectError::NoSensorResonance) = e.stage() {
        return "invalid sensor-resonance: the estimation test's reference shows no resonance to \
                filter below; give the transducer's natural frequency: --add sensor-resonance=HZ"
            .into();
    }
    if let Some(crate::export::ExportError::NotBetter { .. }) = e.stage() {
        // The library refuses "unless forced"; the command line forces with a flag.
        let text = e.to_string();
        return match text.strip_suffix("unless forced") {
            Some(head) => format!("{head}without --force"),
            None => text,
        };
    }
    if let Some(crate::design::DesignError::NoUsableBandwidth) = e.stage() {
        // The library says "give a bandwidth"; the command line gives it with a flag.
        let text = e.to_string();
        return match text.strip_suffix("give a bandwidth") {
            Some(head) => format!("{head}give --bandwidth"),
            None => text,
        };
    }
    match e {
        Error::Trace(TraceError::WrongDelimiter {
            found,
            decimal_comma,
            ..
        }) => {
            let flag = match found {
                b'\t' => "tab".to_string(),
                d => format!("'{}'", char::from(*d)),
            };
            let comma = if *decimal_comma {
                " --decimal-comma"
            } else {
                ""
            };
            return format!("{e} (--delimiter {flag}{comma})");
        }
        Error::Trace(TraceError::ImplausibleTime { .. }) => {
            return format!("{e} (--fs HZ, or rename the column t_ms and give --t t_ms)");
        }
        _ => {}
    }
    let flag = match e {
        Error::Trace(TraceError::DecimalComma { .. }) => Some("--decimal-comma"),
        Error::Trace(TraceError::DecimalCommaDelimiter) => {
            Some("--decimal-comma with --delimiter ';' or tab")
        }
        Error::Trace(TraceError::MissingColumn { role, .. }) => Some(match role {
            ColumnRole::Probe => "--y",
            ColumnRole::Reference => "--u",
            ColumnRole::Time => "--t, or --fs",
        }),
        Error::Trace(
            TraceError::SampleRate { .. }
            | TraceError::NoSampleRate { .. }
            | TraceError::NonUniformTime { .. },
        ) => Some("--fs"),
        _ => None,
    };
    match flag {
        Some(flag) => format!("{e} ({flag})"),
        None => e.to_string(),
    }
}

/// What to do about an error, spelled as the commands and flags that do it.
fn spell(advice: &crate::error::Advice) -> String {
    use crate::error::{Advice, TEMPERATURE_BY_HAND};
    match advice {
        Advice::DesignOptimal => {
            "design its compensator with `unlag invert` (without --bandwidth)".into()
        }
        Advice::DesignSections => "drop --direct, or run `unlag invert`".into(),
        Advice::PlanFixedPoint { model } => format!(
            "run `unlag invert {} --full-scale FS -o ...`",
            model.display()
        ),
        Advice::GiveFullScale => {
            "give --full-scale (the ADC's full scale in the probe's units)".into()
        }
        Advice::GiveTestOrBandwidth => {
            "give one, or ask for a band-limited inverse with --bandwidth HZ".into()
        }
        Advice::BankAsSource => "write --format rust or c, or send a running board one set at \
                                 a time with --temperature K --format bin"
            .into(),
        Advice::AddTemperature { by_hand } => format!(
            "refit with `unlag fit ... --add temperature`{}",
            if *by_hand { TEMPERATURE_BY_HAND } else { "" }
        ),
        Advice::UseF32 => "use --arithmetic f32".into(),
        Advice::OnePerTemperature => "export one set per temperature with --temperature K".into(),
        Advice::FixedOnePerTemperature => {
            "export fixed-point sets one at a time with --temperature K".into()
        }
        Advice::DesignCompensator => "run `unlag invert`".into(),
        // Said the same way in both.
        Advice::ExportF32 => advice.to_string(),
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
/// noise ([`pipeline::check_excitation`]), refused as soon as it is read.
///
/// # Errors
/// The trace's errors, and [`Error::NoStep`] for a reference without excitation.
pub(crate) fn read_test(path: &Path, columns: &Columns) -> Result<Trace> {
    let t = Trace::read(path, columns)?;
    if let Ok(u) = t.input() {
        crate::pipeline::check_excitation(&t.path, u).map_err(|e| match e {
            // The library does not know the column's position in the file; the trace does.
            Error::NoStep { path, reason, .. } => Error::NoStep {
                path,
                column: t.u_column.unwrap_or(0),
                name: columns.input.clone(),
                reason,
            },
            e => e,
        })?;
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

/// A JSON serialisation error as the crate's error.
pub(crate) fn json_err(e: serde_json::Error) -> Error {
    Error::Serialise {
        what: "json",
        message: e.to_string(),
    }
}

/// Refuses a trace sampled at another rate than the model's
/// ([`pipeline::check_model_rate`]).
pub(crate) fn check_rate(file: &ModelFile, trace: &Trace) -> Result<()> {
    crate::pipeline::check_model_rate(file, &trace.path, trace.sample_rate_hz)
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
        // An existing file in the way is replaced only when it is the command's own output
        // (or under --force), and never when read-only.
        type Own = fn(&[u8]) -> bool;
        const REPORT: &str = "an unlag report (its page title)";
        let replaces: Option<(&Path, Own, &str, bool)> = match self {
            Self::Compensate(a) => Some((
                &a.output,
                replace::compensate_csv,
                "an output of unlag compensate (a CSV whose last column is u_hat)",
                a.force,
            )),
            Self::Simulate(a) => Some((
                &a.output,
                replace::simulate_csv,
                "an output of unlag simulate (a CSV whose last column is y_model)",
                a.force,
            )),
            Self::Export(a) => Some((
                &a.output,
                replace::export,
                "an output of unlag export (its banner comment or blob magic)",
                a.force,
            )),
            Self::Report(a) => Some((&a.output, replace::report_html, REPORT, a.force)),
            Self::Fit(a) => a
                .report
                .as_deref()
                .map(|page| (page, replace::report_html as Own, REPORT, a.force)),
            Self::Compare(a) | Self::Diagnose(a) => a
                .report
                .as_deref()
                .map(|page| (page, replace::report_html as Own, REPORT, a.force)),
            _ => None,
        };
        if let Some((path, own, what, force)) = replaces {
            crate::file::check_replace(path, own, what, force)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Parameter;
    use crate::trace::{ColumnRole, TraceError};

    /// The library says what is wrong in its own words; the command line adds the flag.
    #[test]
    fn the_library_names_parameters_and_the_command_line_names_flags() {
        let e = Error::InvalidParameter {
            parameter: Parameter::FullScale,
            message: "must be positive".into(),
        };
        assert_eq!(e.to_string(), "invalid full scale: must be positive");
        assert_eq!(describe(&e), "invalid --full-scale: must be positive");
        let rate = crate::pipeline::check_sample_rate(-3.0).unwrap_err();
        assert_eq!(
            rate.to_string(),
            "invalid sample rate: must be a sample rate in Hz above 0 and at most 1e9, not -3.0"
        );
        assert_eq!(
            describe(&rate),
            "invalid --fs: must be a sample rate in Hz above 0 and at most 1e9, not -3.0"
        );
        let missing = Error::from(TraceError::MissingColumn {
            path: "a.csv".into(),
            column: "p".into(),
            found: "t, u".into(),
            role: ColumnRole::Probe,
            needed: false,
        });
        assert!(!missing.to_string().contains("--"), "{missing}");
        assert!(
            describe(&missing).ends_with("name the probe column (--y)"),
            "{}",
            describe(&missing)
        );
        assert_eq!(missing.kind(), "missing-column");
        assert_eq!(missing.location().1, Some(1));
    }

    /// Advice is said in the library's words and spelled as commands by the command line,
    /// which prints what it printed when the library wrote the flags itself.
    #[test]
    fn advice_is_spelled_as_commands_only_on_the_command_line() {
        use crate::error::Advice;
        let unsupported = Error::UnsupportedOnBoard {
            path: "m.toml".into(),
            effect: "nonlinear damping",
            arithmetic: "fixed-point",
        }
        .advised(Advice::UseF32);
        assert_eq!(
            describe(&unsupported),
            "m.toml: the model has nonlinear damping, which the fixed-point compensator does not \
             run: use --arithmetic f32"
        );
        assert_eq!(unsupported.kind(), "unsupported-on-board");
        assert_eq!(
            unsupported.location().0,
            Some(std::path::Path::new("m.toml"))
        );
        let no_plan = Error::InvalidParameter {
            parameter: Parameter::Arithmetic,
            message: "m.toml has no fixed-point plan".into(),
        }
        .advised(Advice::PlanFixedPoint {
            model: "m.toml".into(),
        });
        assert_eq!(
            describe(&no_plan),
            "invalid --arithmetic: m.toml has no fixed-point plan: run `unlag invert m.toml \
             --full-scale FS -o ...`"
        );
        let no_test = Error::InvalidParameter {
            parameter: Parameter::Tests,
            message: "give at least one step test".into(),
        };
        assert_eq!(
            describe(&no_test),
            "invalid FILE: give at least one step test"
        );
        let every = [
            Advice::DesignOptimal,
            Advice::DesignSections,
            Advice::PlanFixedPoint {
                model: "m.toml".into(),
            },
            Advice::GiveFullScale,
            Advice::GiveTestOrBandwidth,
            Advice::BankAsSource,
            Advice::AddTemperature { by_hand: true },
            Advice::UseF32,
            Advice::ExportF32,
            Advice::OnePerTemperature,
            Advice::FixedOnePerTemperature,
            Advice::DesignCompensator,
        ];
        for advice in every {
            let e = Error::InvalidParameter {
                parameter: Parameter::Tests,
                message: "give at least one step test".into(),
            }
            .advised(advice);
            assert!(!e.to_string().contains("--"), "{e}");
            assert!(!e.to_string().contains("unlag "), "{e}");
            let said = describe(&e);
            assert!(
                said.starts_with("invalid FILE: give at least one step test: "),
                "{said}"
            );
        }
    }

    /// The export's refusals say what the command line said when it refused them itself: a
    /// compensator not better than the probe "without --force", a fixed-point bank with
    /// `--temperature K`.
    #[test]
    fn the_export_refusals_read_as_before() {
        use crate::error::Advice;
        let not_better: Error = crate::export::ExportError::NotBetter {
            model: "m.toml".into(),
            worst_ratio: 1.234,
        }
        .into();
        assert!(!not_better.to_string().contains("--"), "{not_better}");
        assert_eq!(
            describe(&not_better),
            "invalid compensator: m.toml: it is not better than the raw probe on the tests it \
             was checked on (worst error ratio 1.23); refusing to export it without --force"
        );
        assert_eq!(not_better.kind(), "invalid-argument");
        assert_eq!(not_better.location(), (None, None, None));
        let fixed_bank = Error::InvalidParameter {
            parameter: Parameter::Temperatures,
            message: "a temperature bank is f32 only".into(),
        }
        .advised(Advice::FixedOnePerTemperature);
        assert_eq!(
            describe(&fixed_bank),
            "invalid --temperatures: a temperature bank is f32 only: export fixed-point sets one \
             at a time with --temperature K"
        );
        assert_eq!(fixed_bank.kind(), "invalid-argument");
    }

    /// A model file with no design: the library advises designing one, the command line says
    /// `unlag invert` as it did when the library named it.
    #[test]
    fn a_missing_design_is_spelled_as_unlag_invert() {
        use crate::pipeline::{compensate, CompensateRequest, Compensation};
        let path = std::path::Path::new("m.toml");
        let mut file = crate::file::ModelFile::parse(
            path,
            include_str!("../../examples/data/board_model.toml"),
        )
        .unwrap();
        file.inverse = None;
        let e = crate::export::image::BoardCoefficients::from_model_file(&file, path).unwrap_err();
        assert!(!e.to_string().contains("unlag "), "{e}");
        assert_eq!(
            describe(&e),
            "m.toml: no [inverse] compensator design to export: run `unlag invert`"
        );
        let e = compensate(&CompensateRequest {
            file: &file,
            model_path: path,
            probe: &[0.0; 64],
            reference: None,
            compensation: Compensation::Offline,
            temperature_k: None,
        })
        .unwrap_err();
        assert!(!e.to_string().contains("unlag "), "{e}");
        assert_eq!(
            describe(&e),
            "invalid --offline: m.toml has no compensator design to take the noise and prior \
             from: run `unlag invert`"
        );
    }

    /// The design asks for a bandwidth in words; the command line names `--bandwidth`, as it
    /// did when the library named it.
    #[test]
    fn the_command_line_names_the_bandwidth_flag() {
        let e = Error::from(crate::design::DesignError::NoUsableBandwidth);
        assert!(!e.to_string().contains("--"), "{e}");
        assert_eq!(
            describe(&e),
            "inverse: no low-pass corner gave a usable compensator (noise gain above 10 \
             everywhere); give --bandwidth"
        );
        assert_eq!(e.kind(), "numerical");
    }
}
