//! Host-side errors: one enum, one clear message each, naming the file, line and column
//! where the problem is. The CLI prints the message and exits non-zero; nothing panics.
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
    /// Fitting a model failed (the fit room's error).
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// Designing or realising a compensator failed (the design room's error).
    #[error(transparent)]
    Design(#[from] crate::design::DesignError),
    /// A physical prediction or simulation failed (the physics room's error).
    #[error(transparent)]
    Physics(#[from] crate::physics::PhysicsError),
    /// A polynomial's roots could not be found.
    #[error(transparent)]
    Poly(#[from] crate::poly::PolyError),
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
        error: crate::blob::BlobError,
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
    /// A fitted or loaded model is unstable (a pole on or outside the unit circle).
    #[error("{context}: the model is unstable: pole {pole} has |z| = {radius:.6} >= 1")]
    UnstableModel {
        /// Which model.
        context: String,
        /// The pole, as text.
        pole: String,
        /// Its magnitude.
        radius: f64,
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
    /// A numerical step failed.
    #[error("{context}: {message}")]
    Numerical {
        /// Where.
        context: String,
        /// What happened.
        message: String,
    },
    /// The model has an effect the chosen board arithmetic does not run (the nonlinear-damping
    /// correction is `f32` only).
    #[error(
        "{path}: the model has {effect}, which the {arithmetic} compensator does not run: {hint}"
    )]
    UnsupportedOnBoard {
        /// The model file.
        path: PathBuf,
        /// The effect's kind.
        effect: &'static str,
        /// The arithmetic asked for.
        arithmetic: &'static str,
        /// What to do instead.
        hint: &'static str,
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
    /// The kind of problem, one stable kebab-case word per variant (for `--json`).
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Trace(e) => e.kind(),
            Self::Io { .. } => "io",
            Self::TooShort { .. } => "too-short",
            Self::NoStep { .. } => "no-step",
            Self::Mismatch { .. } => "mismatch",
            Self::InvalidArgument { .. } | Self::InvalidParameter { .. } => "invalid-argument",
            Self::Model { .. } | Self::ModelAt { .. } => "model",
            Self::UnstableModel { .. } => "unstable-model",
            Self::UnstableInverse { .. } => "unstable-inverse",
            Self::Numerical { .. }
            | Self::Fit(_)
            | Self::Design(_)
            | Self::Physics(_)
            | Self::Poly(_) => "numerical",
            Self::UnsupportedOnBoard { .. } => "unsupported-on-board",
            Self::Plot { .. } => "plot",
            Self::Overwrite { .. } => "overwrite",
            Self::Blob { .. } => "blob",
        }
    }

    /// The file, line and column the problem is at, as far as they are known.
    #[must_use]
    pub fn location(&self) -> (Option<&std::path::Path>, Option<u64>, Option<u64>) {
        match self {
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
            | Self::Overwrite { output: path, .. } => (Some(path), None, None),
            Self::InvalidArgument { .. }
            | Self::InvalidParameter { .. }
            | Self::UnstableModel { .. }
            | Self::UnstableInverse { .. }
            | Self::Numerical { .. }
            | Self::Fit(_)
            | Self::Design(_)
            | Self::Physics(_)
            | Self::Poly(_)
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
    /// The gas temperature a design is retargeted to.
    Temperature,
    /// The temperature table of a bank.
    Temperatures,
    /// The offline (non-causal, host-only) reconstruction.
    Offline,
    /// The arithmetic a record is compensated in.
    Arithmetic,
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
        })
    }
}

/// Host-side result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
