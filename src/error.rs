//! Host-side errors: one enum, one clear message each, naming the file, line and column
//! where the problem is. The CLI prints the message and exits non-zero; nothing panics.
//!
//! The trace room's error is a variant ([`Error::Trace`]); every later stage's own enum
//! travels as [`Error::Stage`], so this module imports no stage that imports it. Library
//! messages name no command-line flag: a [`Parameter`] or an [`Advice`] is typed, and the
//! CLI spells it.
//!
//! Line numbers are 1-based lines of the file (the header is line 1); column numbers are
//! 1-based field positions, given with the column's name.

use std::path::PathBuf;

/// Everything that can go wrong on the host side.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A trace file is not a usable step test (the trace room's error).
    #[error(transparent)]
    Trace(#[from] crate::trace::TraceError),
    /// A stage's own error: fitting (`fit::FitError`), designing (`design::DesignError`),
    /// physics (`physics::PhysicsError`), polynomial roots (`poly::PolyError`), the
    /// effects (`effects::EffectError`) or export (`export::ExportError`). Each stage
    /// converts its enum into this one, so the stages import this module and never the
    /// reverse; [`Error::stage`] gets the stage's error back.
    #[error("{0}")]
    Stage(Box<dyn StageError>),
    /// The file could not be read or written.
    #[error("{path}: {action}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read", "cannot write").
        action: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The trace has too few samples for what was asked.
    #[error("{path}: {samples} samples is too short for order {order} and delay {delay}: at least {needed} are needed")]
    TooShort {
        /// The file.
        path: PathBuf,
        /// Samples in the trace.
        samples: usize,
        /// Model order asked for.
        order: usize,
        /// Delay in samples.
        delay: usize,
        /// Samples needed.
        needed: usize,
    },
    /// No step was found in the reference.
    #[error("{path}: no step found in column {column} ('{name}'): {reason}")]
    NoStep {
        /// The file.
        path: PathBuf,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// Why.
        reason: String,
    },
    /// Traces that must match do not.
    #[error("{path}: {message}")]
    Mismatch {
        /// The file that does not match.
        path: PathBuf,
        /// What differs.
        message: String,
    },
    /// A request's parameter is out of range or does not fit the model (the CLI names the
    /// flag that sets it).
    #[error("invalid {parameter}: {message}")]
    InvalidParameter {
        /// Which parameter.
        parameter: Parameter,
        /// Why.
        message: String,
    },
    /// A value is out of range.
    #[error("invalid {what}: {message}")]
    InvalidArgument {
        /// Which argument.
        what: &'static str,
        /// Why.
        message: String,
    },
    /// The model file is not valid.
    #[error("{path}: {message}")]
    Model {
        /// The model file.
        path: PathBuf,
        /// What is wrong (for TOML syntax errors, with line and column).
        message: String,
    },
    /// A model file's field at a line and column is wrong (syntax, type, unknown name or a
    /// value out of its limits).
    #[error("{path}:{line}:{column}: {message}")]
    ModelAt {
        /// The model file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column (characters).
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A coefficient blob the board's parser refuses.
    #[error("{path}: not a valid coefficient blob (the board's parser says: {error})")]
    Blob {
        /// The blob file.
        path: PathBuf,
        /// The board parser's error.
        error: crate::board::blob::BlobError,
    },
    /// An output would replace one of the command's inputs.
    #[error("{output}: refused: this output is the input {input} ({what}); writing it would destroy the input, so give another output path")]
    Overwrite {
        /// The output asked for.
        output: PathBuf,
        /// The input it names.
        input: PathBuf,
        /// What the input is.
        what: &'static str,
    },
    /// An existing file the output would replace, refused: read-only, or (without `--force`)
    /// not one of the command's own outputs.
    #[error("{path}: refused: {reason}")]
    NotReplaced {
        /// The output asked for.
        path: PathBuf,
        /// Why, and what to do instead.
        reason: String,
    },
    /// A fitted or loaded model is unstable (a pole on or outside the unit circle).
    #[error("{context}: the model is unstable: pole {pole} has |z| = {radius:.6} >= 1{note}")]
    UnstableModel {
        /// Which model.
        context: String,
        /// The pole, as text.
        pole: String,
        /// Its magnitude.
        radius: f64,
        /// What the record says about it (`; the record ends ... after the step ...`), or
        /// empty.
        note: String,
    },
    /// The model cannot be inverted directly.
    #[error("{context}: the direct inverse is unstable: zero {zero} of B(z) has |z| = {radius:.6} >= 1 (a non-minimum-phase model; a stable inverse design is needed)")]
    UnstableInverse {
        /// Which model.
        context: String,
        /// The zero, as text.
        zero: String,
        /// Its magnitude.
        radius: f64,
    },
    /// The model has an effect the chosen board arithmetic does not run (the nonlinear-damping
    /// correction is `f32` only). What to do instead comes with it ([`Error::Advised`]).
    #[error("{path}: the model has {effect}, which the {arithmetic} compensator does not run")]
    UnsupportedOnBoard {
        /// The model file.
        path: PathBuf,
        /// The effect's kind.
        effect: &'static str,
        /// The arithmetic asked for.
        arithmetic: &'static str,
    },
    /// The board's code refused coefficients the host built for it (it does not for a design
    /// that passed its checks).
    #[error("{during}: {refusal}")]
    BoardRefused {
        /// What the host was doing.
        during: &'static str,
        /// The board's error.
        refusal: BoardRefusal,
    },
    /// Something could not be serialised (it cannot for finite values).
    #[error("{what}: {message}")]
    Serialise {
        /// What was being written (`model file`, `json`).
        what: &'static str,
        /// The serialiser's reason.
        message: String,
    },
    /// An error with what to do about it. The library says it in its own words; the command
    /// line spells the command and flags that do it.
    #[error("{error}: {advice}")]
    Advised {
        /// What went wrong.
        error: Box<Error>,
        /// What to do.
        advice: Advice,
    },
    /// A plot of the HTML report could not be drawn (`unlag report`).
    #[error("report: plot '{plot}' could not be drawn: {message}")]
    Plot {
        /// Which plot.
        plot: String,
        /// What the plotting library said.
        message: String,
    },
}

impl Error {
    /// This error with what to do about it.
    #[must_use]
    pub fn advised(self, advice: Advice) -> Self {
        Self::Advised {
            error: Box::new(self),
            advice,
        }
    }

    /// The stage's error of type `E` (under any advice), when this is one.
    ///
    /// ```
    /// use unlag::design::DesignError;
    /// use unlag::error::Error;
    ///
    /// let e = Error::from(DesignError::NoSections);
    /// assert!(matches!(e.stage::<DesignError>(), Some(DesignError::NoSections)));
    /// assert!(e.stage::<unlag::fit::FitError>().is_none());
    /// ```
    #[must_use]
    pub fn stage<E: StageError>(&self) -> Option<&E> {
        match self.unadvised() {
            Self::Stage(e) => {
                let e: &dyn StageError = &**e;
                e.as_any().downcast_ref::<E>()
            }
            _ => None,
        }
    }

    /// Whether the request itself is wrong (an argument or parameter out of range, under any
    /// advice), not the data or the arithmetic: a search over designs stops at it instead of
    /// trying the next candidate.
    #[must_use]
    pub fn is_the_callers(&self) -> bool {
        matches!(
            self.unadvised(),
            Self::InvalidArgument { .. } | Self::InvalidParameter { .. }
        )
    }

    /// The error under any advice.
    #[must_use]
    pub fn unadvised(&self) -> &Self {
        match self {
            Self::Advised { error, .. } => error.unadvised(),
            e => e,
        }
    }

    /// The kind of problem, one stable kebab-case word per variant (for `--json`).
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Advised { error, .. } => error.kind(),
            Self::Trace(e) => e.kind(),
            Self::Stage(e) => e.kind(),
            Self::Io { .. } => "io",
            Self::TooShort { .. } => "too-short",
            Self::NoStep { .. } => "no-step",
            Self::Mismatch { .. } => "mismatch",
            Self::InvalidArgument { .. } | Self::InvalidParameter { .. } => "invalid-argument",
            Self::Model { .. } | Self::ModelAt { .. } => "model",
            Self::UnstableModel { .. } => "unstable-model",
            Self::UnstableInverse { .. } => "unstable-inverse",
            Self::BoardRefused { .. } | Self::Serialise { .. } => "numerical",
            Self::UnsupportedOnBoard { .. } => "unsupported-on-board",
            Self::Plot { .. } => "plot",
            Self::Overwrite { .. } => "overwrite",
            Self::NotReplaced { .. } => "not-replaced",
            Self::Blob { .. } => "blob",
        }
    }

    /// The file, line and column the problem is at, as far as they are known.
    #[must_use]
    pub fn location(&self) -> (Option<&std::path::Path>, Option<u64>, Option<u64>) {
        match self {
            Self::Advised { error, .. } => error.location(),
            Self::Trace(e) => e.location(),
            Self::ModelAt {
                path, line, column, ..
            } => (Some(path), Some(*line as u64), Some(*column as u64)),
            Self::Io { path, .. }
            | Self::TooShort { path, .. }
            | Self::NoStep { path, .. }
            | Self::Mismatch { path, .. }
            | Self::Model { path, .. }
            | Self::UnsupportedOnBoard { path, .. }
            | Self::Blob { path, .. }
            | Self::Overwrite { output: path, .. }
            | Self::NotReplaced { path, .. } => (Some(path), None, None),
            Self::InvalidArgument { .. }
            | Self::InvalidParameter { .. }
            | Self::Stage(_)
            | Self::UnstableModel { .. }
            | Self::UnstableInverse { .. }
            | Self::BoardRefused { .. }
            | Self::Serialise { .. }
            | Self::Plot { .. } => (None, None, None),
        }
    }

    /// A plot of the HTML report could not be drawn.
    pub(crate) fn plot(plot: &str, e: impl std::fmt::Display) -> Self {
        Self::Plot {
            plot: plot.to_string(),
            message: e.to_string(),
        }
    }
}

/// A stage's own error enum, carried by [`Error::Stage`]. A stage implements it and
/// `From<ItsError> for Error` (with [`Error::Stage`]) beside its enum.
pub trait StageError: std::error::Error + Send + Sync + AsAny + 'static {
    /// The kind of problem for `--json` ([`Error::kind`]): `numerical` unless the stage says
    /// otherwise.
    fn kind(&self) -> &'static str {
        "numerical"
    }
}

/// The concrete error behind a `dyn StageError`, for [`Error::stage`]'s downcast (without
/// trait upcasting, which needs Rust 1.86 where the crate's `rust-version` is 1.85).
pub trait AsAny {
    /// This value as `Any`.
    fn as_any(&self) -> &dyn std::any::Any;
}

impl<T: std::any::Any> AsAny for T {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// `From<$t> for Error`, through [`Error::Stage`], for a stage's error enum `$t` (which
/// implements [`StageError`]).
macro_rules! stage_error {
    ($t:ty) => {
        impl From<$t> for $crate::error::Error {
            fn from(e: $t) -> Self {
                Self::Stage(Box::new(e))
            }
        }
    };
}
pub(crate) use stage_error;

/// A parameter of a library request that an error can be about, in the library's words
/// (`Display`); the command line names the flag that sets it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Parameter {
    /// The model order of a fit.
    Order,
    /// The effects added to a fit.
    Effect,
    /// The order of the band-limited inverse's low-pass.
    LowpassOrder,
    /// The band-limited inverse's corner.
    Bandwidth,
    /// The ADC's full scale, for a fixed-point plan.
    FullScale,
    /// A gas temperature: a probe's, or the one a design is retargeted to.
    Temperature,
    /// The temperature table of a bank.
    Temperatures,
    /// The offline (non-causal, host-only) reconstruction.
    Offline,
    /// The arithmetic a record is compensated in.
    Arithmetic,
    /// The step tests a request is given.
    Tests,
    /// The sample rate a model is resampled to.
    SampleRate,
    /// A probe's mean gas pressure.
    MeanPressure,
    /// The volume at a probe's closed end.
    EndVolume,
    /// The length of a probe's recessed hole.
    HoleLength,
    /// The diameter of a probe's recessed hole.
    HoleDiameter,
    /// The end volume as the cavity of a probe's recessed hole.
    HoleCavity,
    /// The length of one of a probe's tubes.
    TubeLength,
    /// The diameter of one of a probe's tubes.
    TubeDiameter,
    /// A probe's tubes together.
    Tubes,
    /// The radius of a probe's thermally relaxing end cavity.
    CavityRadius,
    /// The rise (or fall, or opening) time of an excitation.
    RiseTime,
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Order => "model order",
            Self::Effect => "effect",
            Self::LowpassOrder => "low-pass order",
            Self::Bandwidth => "bandwidth",
            Self::FullScale => "full scale",
            Self::Temperature => "temperature",
            Self::Temperatures => "temperature table",
            Self::Offline => "offline reconstruction",
            Self::Arithmetic => "arithmetic",
            Self::Tests => "step tests",
            Self::SampleRate => "sample rate",
            Self::MeanPressure => "mean pressure",
            Self::EndVolume => "end volume",
            Self::HoleLength => "hole length",
            Self::HoleDiameter => "hole diameter",
            Self::HoleCavity => "hole cavity volume",
            Self::TubeLength => "tube length",
            Self::TubeDiameter => "tube diameter",
            Self::Tubes => "tubing",
            Self::CavityRadius => "cavity radius",
            Self::RiseTime => "rise time",
        })
    }
}

/// The board-side error behind [`Error::BoardRefused`]: each board constructor's and
/// parser's own `Copy` error.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BoardRefusal {
    /// The `f32` cascade's or nonlinear correction's constructor.
    #[error(transparent)]
    Inverse(#[from] crate::board::compensator::InverseError),
    /// The fixed-point normal form's constructor.
    #[error(transparent)]
    Fixed(#[from] crate::board::fixed::FixedError),
    /// The fixed-point direct form's constructor.
    #[error(transparent)]
    Direct(#[from] crate::board::fixed::direct::DirectError),
    /// The blob encoder.
    #[error(transparent)]
    Blob(#[from] crate::board::blob::BlobError),
}

/// What to do about an error ([`Error::Advised`]), in the library's words (`Display`); the
/// command line spells each as the command and flags that do it.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Advice {
    /// Design the compensator from the measured noise and the signal prior, with no band limit
    /// (the optimal design).
    DesignOptimal,
    /// Run the model file's designed compensator, or design one.
    DesignSections,
    /// Design the model file's compensator again with the ADC's full scale, which plans the
    /// fixed-point arithmetic.
    PlanFixedPoint {
        /// The model file.
        model: PathBuf,
    },
    /// Give the ADC's full scale.
    GiveFullScale,
    /// Give a step test, or ask for the band-limited inverse (it needs a bandwidth, not a
    /// noise measurement).
    GiveTestOrBandwidth,
    /// Write a bank as source code, or send a running board one set at a time.
    BankAsSource,
    /// Refit with the temperature effect (which sets the reference temperature).
    AddTemperature {
        /// Also say how to write it into the model file by hand.
        by_hand: bool,
    },
    /// Run the compensator in `f32`.
    UseF32,
    /// Export the compensator in `f32`.
    ExportF32,
    /// Export one coefficient set per temperature instead of a bank.
    OnePerTemperature,
    /// Export the fixed-point sets one temperature at a time (a bank is `f32` only).
    FixedOnePerTemperature,
    /// Design the model file's compensator (it has none).
    DesignCompensator,
}

/// The model-file line that adds a temperature effect by hand.
pub const TEMPERATURE_BY_HAND: &str =
    " (or add effects = [{ kind = \"temperature\", reference_k = K }])";

impl std::fmt::Display for Advice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::DesignOptimal => f.write_str(
                "design its compensator from the measured noise and the signal prior, \
                 with no band limit (the optimal design)",
            ),
            Self::DesignSections => {
                f.write_str("run the model file's designed compensator, or design one")
            }
            Self::PlanFixedPoint { model } => write!(
                f,
                "design the compensator of {} again with the ADC's full scale",
                model.display()
            ),
            Self::GiveFullScale => f.write_str("give the ADC's full scale, in the probe's units"),
            Self::GiveTestOrBandwidth => {
                f.write_str("give one, or ask for a band-limited inverse with its bandwidth")
            }
            Self::BankAsSource => f.write_str(
                "write it as Rust or C source, or send a running board one set at a time",
            ),
            Self::AddTemperature { by_hand } => {
                f.write_str("refit with the temperature effect")?;
                if *by_hand {
                    f.write_str(TEMPERATURE_BY_HAND)?;
                }
                Ok(())
            }
            Self::UseF32 => f.write_str("run it in f32"),
            Self::ExportF32 => f.write_str("export it as f32"),
            Self::OnePerTemperature => f.write_str("export one set per temperature"),
            Self::FixedOnePerTemperature => {
                f.write_str("export the fixed-point sets one temperature at a time")
            }
            Self::DesignCompensator => f.write_str("design its compensator"),
        }
    }
}

/// Host-side result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// `v` for a message: six significant digits, in powers of ten outside `1e-4..1e7` (`1e300`,
/// not three hundred digits). The trace room's formatter, shared.
#[must_use]
pub fn number(v: f64) -> String {
    crate::trace::short(v)
}

#[cfg(test)]
mod number_tests {
    use super::number;

    #[test]
    fn numbers_in_messages_are_short() {
        assert_eq!(number(6_561.849_999_999_999), "6561.85");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(-1.234_567_89e-300), "-1.23457e-300");
        assert_eq!(number(20_000.0), "20000");
        assert_eq!(number(-1.0), "-1");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(number(2.5e7), "2.5e7");
    }
}
