//! What can be wrong with a recorded trace: one variant per problem, each naming the file,
//! line and column where it is, in the trace room's own words (no command-line flags).

use std::path::PathBuf;

/// The role of a column in a step test, for messages that say which one is missing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnRole {
    /// The time column ([`crate::trace::Columns::time`]).
    Time,
    /// The reference pressure ([`crate::trace::Columns::input`]).
    Reference,
    /// The probe's output ([`crate::trace::Columns::output`]).
    Probe,
}

impl std::fmt::Display for ColumnRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Time => "time",
            Self::Reference => "reference",
            Self::Probe => "probe",
        })
    }
}

/// Everything that can be wrong with a trace file, found once, when it is read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TraceError {
    /// The file could not be read.
    #[error("{path}: {action}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read").
        action: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The sample rate given for a file without a time column is not a rate.
    #[error("invalid sample rate: the sample rate must be a positive number of Hz up to {max:e}, not {given:?}")]
    SampleRate {
        /// What was given.
        given: f64,
        /// The largest accepted ([`crate::trace::MAX_SAMPLE_RATE_HZ`]).
        max: f64,
    },
    /// A file without a time column was read without a sample rate.
    #[error("invalid sample rate: {path}: no time column and no sample rate")]
    NoSampleRate {
        /// The file.
        path: PathBuf,
    },
    /// The file has no header, or a header and no data rows.
    #[error("{path}:{line}: the file is empty ({what})")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Where the data should have started.
        line: u64,
        /// What is missing.
        what: &'static str,
    },
    /// A required column is not in the header.
    #[error("{path}:1: missing column '{column}' (the header has: {found}); {}", missing_hint(*.role, *.needed))]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The column asked for.
        column: String,
        /// The header's column names, comma-separated.
        found: String,
        /// Which column it is.
        role: ColumnRole,
        /// Whether it was asked for by a step that needs it after reading (the reference of
        /// a file read without one).
        needed: bool,
    },
    /// A field is not a number.
    #[error("{path}:{line}:{column}: '{value}' in column '{name}' is not a number")]
    NotANumber {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// The text found.
        value: String,
    },
    /// A field is NaN or infinite.
    #[error("{path}:{line}:{column}: value '{value}' in column '{name}' is not finite")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// The text found.
        value: String,
    },
    /// A row has the wrong number of fields, or the CSV is malformed.
    #[error("{path}:{line}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// What the CSV reader said.
        message: String,
    },
    /// Time does not increase from one row to the next.
    #[error("{path}:{line}:{column}: time in column '{name}' does not increase ({previous} then {value})")]
    TimeNotIncreasing {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// The previous time.
        previous: f64,
        /// This row's time.
        value: f64,
    },
    /// The time step varies by more than 1 %.
    #[error("{path}:{line}:{column}: time step {step:.6e} s in column '{name}' differs from the mean step {nominal:.6e} s by {percent:.2} % (more than 1 % jitter: resample the trace or give the sample rate)")]
    NonUniformTime {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// The offending step.
        step: f64,
        /// The mean step.
        nominal: f64,
        /// Relative deviation in percent.
        percent: f64,
    },
    /// Fewer than two samples: no time step.
    #[error("{path}: {samples} samples is too short: a trace needs at least 2")]
    TooShort {
        /// The file.
        path: PathBuf,
        /// Samples in the trace.
        samples: usize,
    },
    /// The ADC saturated: the signal sits flat at its extreme value, entered with a jump.
    #[error("{path}:{line}:{column}: column '{name}' looks clipped: {run} samples flat at its {which} value {value} from this line on (the ADC saturated; re-record with more range)")]
    Clipped {
        /// The file.
        path: PathBuf,
        /// 1-based line where the flat run starts.
        line: u64,
        /// 1-based field position.
        column: usize,
        /// The column's name.
        name: String,
        /// Length of the flat run.
        run: usize,
        /// "largest" or "smallest".
        which: &'static str,
        /// The clipped value.
        value: f64,
    },
    /// Columns written beside the trace do not fit it, or the file changed since it was read.
    #[error("{path}: {message}")]
    Mismatch {
        /// The trace's file.
        path: PathBuf,
        /// What differs.
        message: String,
    },
}

fn missing_hint(role: ColumnRole, needed: bool) -> String {
    match (role, needed) {
        (ColumnRole::Reference, true) => "this step needs the reference column (name it)".into(),
        (ColumnRole::Time, _) => "name the time column, or give the sample rate".into(),
        (role, _) => format!("name the {role} column"),
    }
}

impl TraceError {
    /// The kind of problem, one stable kebab-case word per variant (for `--json`).
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Io { .. } => "io",
            Self::SampleRate { .. } | Self::NoSampleRate { .. } => "invalid-argument",
            Self::Empty { .. } => "empty",
            Self::MissingColumn { .. } => "missing-column",
            Self::NotANumber { .. } => "not-a-number",
            Self::NonFinite { .. } => "non-finite",
            Self::Malformed { .. } => "malformed",
            Self::TimeNotIncreasing { .. } => "time-not-increasing",
            Self::NonUniformTime { .. } => "non-uniform-time",
            Self::TooShort { .. } => "too-short",
            Self::Clipped { .. } => "clipped",
            Self::Mismatch { .. } => "mismatch",
        }
    }

    /// The file, line and column the problem is at, as far as they are known.
    #[must_use]
    pub fn location(&self) -> (Option<&std::path::Path>, Option<u64>, Option<u64>) {
        match self {
            Self::NotANumber {
                path, line, column, ..
            }
            | Self::NonFinite {
                path, line, column, ..
            }
            | Self::TimeNotIncreasing {
                path, line, column, ..
            }
            | Self::NonUniformTime {
                path, line, column, ..
            }
            | Self::Clipped {
                path, line, column, ..
            } => (Some(path), Some(*line), Some(*column as u64)),
            Self::Empty { path, line, .. } | Self::Malformed { path, line, .. } => {
                (Some(path), Some(*line), None)
            }
            Self::MissingColumn { path, .. } => (Some(path), Some(1), None),
            Self::Io { path, .. } | Self::TooShort { path, .. } | Self::Mismatch { path, .. } => {
                (Some(path), None, None)
            }
            Self::SampleRate { .. } | Self::NoSampleRate { .. } => (None, None, None),
        }
    }
}

/// What stops [`crate::trace::Trace::write_csv_with`]: the output failed, or the trace did.
#[derive(Debug)]
pub enum CopyFailure {
    /// Writing to the output failed.
    Output(std::io::Error),
    /// The trace's own problem (its error names its file).
    Trace(TraceError),
}

impl From<std::io::Error> for CopyFailure {
    fn from(e: std::io::Error) -> Self {
        Self::Output(e)
    }
}

impl From<TraceError> for CopyFailure {
    fn from(e: TraceError) -> Self {
        Self::Trace(e)
    }
}
